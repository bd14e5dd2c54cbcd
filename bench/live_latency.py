"""Live per-message latency of the pipeline with the viewer and MAVLink output on.

The samples of a high-rate simulated flight (``bench/audit.py``'s log:
HIGHRES_IMU 200 Hz, ATTITUDE 50 Hz, baro 25 Hz, GNSS 10 Hz, rangefinder 20
Hz) are decoded first, then pushed as fast as they come through
:func:`mavnav.pipeline.run`, the fold ``mavnav run`` uses on a live link.
A message's latency is the time the pipeline holds it: from handing the
sample over to asking for the next one (monitor, epoch, every sink).
Decoding is left out; ``bench/audit.py`` times it.

Two kinds of run on the same samples, in one process, each ``--repeat``
times in turn (the median p99 is the verdict: on a shared machine a run's
p99 moves by a factor of two with the other processes):

* baseline: the monitor alone (no sink);
* live sinks: the Rerun web viewer as ``run --viewer web`` starts it (its
  gRPC server in this process, live batches, nobody watching) and MAVLink
  output as ``run --emit udpout:127.0.0.1:PORT`` (ALTITUDE at 5 Hz,
  STATUSTEXT on alarms, the debug values too), plus the console printer;
  with ``--rrd``, the recording also saved to an ``.rrd`` (``run --viewer
  web --rrd FILE``).

Goal (issue 15): p99 under 1 ms with the viewer and MAVLink output on.

    .venv/bin/python bench/live_latency.py [--minutes 2] [--repeat 3] [--rrd]
"""

from __future__ import annotations

import argparse
import os
import socket
import statistics
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from preamble import announce, simulated_samples  # noqa: E402

from mavnav.cli.emit_options import make_emit_sinks  # noqa: E402
from mavnav.cli.viewer_options import make_viewer_sinks  # noqa: E402
from mavnav.config import load_config  # noqa: E402
from mavnav.pipeline import run  # noqa: E402


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def timed(samples: list, lat: list):
    """Yield the samples; the time until the next is asked for is the pipeline's."""
    perf = time.perf_counter
    append = lat.append
    for s in samples:
        t0 = perf()
        yield s
        append(perf() - t0)


def summary(name: str, lat: list) -> dict:
    us = sorted(v * 1e6 for v in lat)
    p = lambda q: us[min(len(us) - 1, int(q * len(us)))]  # noqa: E731
    row = {"p50": p(0.5), "p99": p(0.99), "p999": p(0.999), "max": us[-1], "mean": statistics.fmean(us)}
    print(f"{name:<40} p50 {row['p50']:6.1f} us  p99 {row['p99']:7.1f} us  p99.9 {row['p999']:7.1f} us  "
          f"max {row['max']:7.0f} us  mean {row['mean']:6.1f} us  ({len(us)} messages)")
    return row


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--minutes", type=float, default=2.0)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--rrd", action="store_true", help="also save the recording to an .rrd")
    args = ap.parse_args()
    announce("live_latency.py")
    cfg = load_config(None)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "live.tlog"
        samples = simulated_samples(path, args.minutes, cfg)
        print(f"log: {args.minutes:g} min simulated, {len(samples)} samples")
        rows: dict[str, list] = {"base": [], "live": []}
        for _ in range(args.repeat):
            base: list = []
            run(timed(samples, base), cfg, info={"source": "bench", "live": True})
            rows["base"].append(summary("baseline: monitor, no sink", base))
            rx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)  # the ground station's end, drained at the end
            rx.bind(("127.0.0.1", 0))
            rx.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 22)
            rx.setblocking(False)
            rrd = str(Path(tmp) / "live.rrd") if args.rrd else None
            sinks = make_viewer_sinks(viewer="web", rrd=rrd, live=True, web_port=free_port(), grpc_port=free_port(),
                                      viewer_hold=False, echo=lambda text: None)
            sinks += make_emit_sinks(emit=f"udpout:127.0.0.1:{rx.getsockname()[1]}", emit_debug=True,
                                     live_input=True, config=cfg, say=lambda text: None)
            live: list = []
            res = run(timed(samples, live), cfg, sinks, info={"source": "bench", "live": True})
            received = 0
            try:
                while True:
                    received += len(rx.recv(65536))
            except BlockingIOError:
                pass
            rx.close()
            rows["live"].append(summary(f"live: Rerun web viewer{' + .rrd' if rrd else ''} + MAVLink out", live))
            print(f"  ({res.epochs} epochs; MAVLink out: {received} bytes received; "
                  f"sinks failed: {res.sink_failures or 'none'})")
    b = {k: statistics.median(r[k] for r in rows["base"]) for k in ("p50", "p99")}
    s = {k: statistics.median(r[k] for r in rows["live"]) for k in ("p50", "p99")}
    print(f"median of {args.repeat}: baseline p50 {b['p50']:.1f} us p99 {b['p99']:.1f} us; "
          f"live p50 {s['p50']:.1f} us p99 {s['p99']:.1f} us")
    print(f"ratio live / baseline: p50 {s['p50'] / b['p50']:.2f}x, p99 {s['p99'] / b['p99']:.2f}x   "
          f"goal p99 < 1000 us: {'met' if s['p99'] < 1000 else 'MISSED'}")
    print(f"load average after: {', '.join(f'{x:.2f}' for x in os.getloadavg())}")


if __name__ == "__main__":
    main()
