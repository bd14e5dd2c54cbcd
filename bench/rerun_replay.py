"""The Rerun sink's cost on a replay or audit with ``--rrd`` (and a viewer).

The samples of ``bench/audit.py``'s high-rate simulated flight are decoded
once, then run through :func:`mavnav.pipeline.run` (the fold ``replay`` and
``audit`` use) three ways, each ``--repeat`` times (the best time counts):

* alone: the monitor, no sink;
* rrd: the Rerun sink writing an ``.rrd`` (``--rrd FILE``: replay columns);
* rrd + viewer: the same and a running viewer's gRPC server
  (``--rrd FILE --connect PORT``; a ``rerun --serve-grpc`` child on
  127.0.0.1 that nobody watches).

The sink's cost is the time over the monitor alone, per epoch: wall clock,
and the process's CPU time (every thread: Rerun encodes and writes in its
own), the steadier of the two on a shared machine.

    .venv/bin/python bench/rerun_replay.py [--minutes 2] [--repeat 3]
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from preamble import announce, simulated_samples  # noqa: E402

from mavnav.cli.viewer_options import ViewerProcess, free_port, make_viewer_sinks, rerun_executable  # noqa: E402
from mavnav.config import load_config  # noqa: E402
from mavnav.pipeline import run  # noqa: E402


def timed_run(samples: list, cfg, sinks: list) -> tuple[float, float, int]:
    """(wall s, CPU s, epochs) of one run, the sinks closed."""
    t0, c0 = time.perf_counter(), time.process_time()
    res = run(iter(samples), cfg, sinks, info={"source": "bench", "live": False})
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    if res.sink_failures:
        raise SystemExit(f"sinks failed: {res.sink_failures}")
    return wall, cpu, res.epochs


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--minutes", type=float, default=2.0)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    announce("rerun_replay.py")
    cfg = load_config(None)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "replay.tlog"
        samples = simulated_samples(path, args.minutes, cfg)
        port = free_port()
        server = ViewerProcess([rerun_executable(), "--serve-grpc", "--bind", "127.0.0.1", "--port", str(port)],
                               "127.0.0.1", (port,))
        try:
            if server.wait_ready() is not None:
                raise SystemExit(f"the gRPC server did not start: {server.tail()}")
            kinds = {
                "alone": lambda: [],
                "rrd": lambda: make_viewer_sinks(rrd=str(Path(tmp) / "r.rrd"), live=False),
                "rrd + viewer": lambda: make_viewer_sinks(connect=str(port), rrd=str(Path(tmp) / "v.rrd"), live=False),
            }
            best: dict[str, float] = {}
            best_cpu: dict[str, float] = {}
            epochs = 0
            for _ in range(args.repeat):
                for name, sinks in kinds.items():
                    wall, cpu, epochs = timed_run(samples, cfg, sinks())
                    best[name] = min(best.get(name, wall), wall)
                    best_cpu[name] = min(best_cpu.get(name, cpu), cpu)
        finally:
            server.stop()
    print(f"log: {args.minutes:g} min simulated, {len(samples)} samples, {epochs} epochs")
    for name, t in best.items():
        cpu = best_cpu[name]
        extra = "" if name == "alone" else (f"  sink {(t - best['alone']) / epochs * 1e6:6.1f} us wall, "
                                            f"{(cpu - best_cpu['alone']) / epochs * 1e6:6.1f} us CPU per epoch")
        print(f"{name:<14} best of {args.repeat}: {t:6.2f} s wall, {cpu:6.2f} s CPU "
              f"({len(samples) / t:6.0f} samples/s){extra}")
    print(f"load average after: {', '.join(f'{x:.2f}' for x in os.getloadavg())}")


if __name__ == "__main__":
    main()
