"""Memory over a long replay at max speed: resident set size growth.

A one-hour simulated PX4-style flight (``bench/audit.py``'s scenario,
HIGHRES_IMU at ``--imu-hz``, ATTITUDE 50 Hz, baro 25 Hz, GNSS 10 Hz,
rangefinder 20 Hz; a scenario lasts at most an hour) is written by ``mavnav
simulate``'s engine in a child process (so the simulator's memory is not
counted here) and looped ``--loops`` times into one tlog (each loop's
vehicle clock restarts: the source reports a reboot and the monitor starts
again, while the sinks, the run summary and the source keep going), then
replayed as ``mavnav replay
--speed max --csv FILE`` does (the tlog source, the monitor, the console,
CSV and audit sinks) while the RSS of this process (``/proc/self/statm``) is
sampled every ``--every-s`` of vehicle time. The baseline is the RSS after
the first ``--warm-min`` minutes (imports, numba, the first buffers filled);
growth is the RSS at the end minus that. Goal (issue 15): under 20 MB over
a 2-hour replay.

    .venv/bin/python bench/memory.py [--loops 2] [--imu-hz 50]
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from preamble import announce  # bench/preamble.py (this script's own directory)
from mavnav.audit import AuditSink
from mavnav.cli.run import AlarmPrinter
from mavnav.config import load_config
from mavnav.ingest import open_log
from mavnav.pipeline import run
from mavnav.sinks.base import Sink
from mavnav.sinks.csv_sink import CsvSink

GEN = """
import sys
from pathlib import Path
sys.path.insert(0, {bench!r})
import audit
import yaml
d = yaml.safe_load((audit.REPO / "config/scenarios/px4_hover_gnss_step.yaml").read_text())
d["duration_s"] = {seconds!r}
d.setdefault("rates_hz", {{}})["HIGHRES_IMU"] = {imu_hz!r}
for f in d.get("faults", []):
    f["onset_s"] = min(f["onset_s"], d["duration_s"] / 2)
audit.simulate(audit.scenario_from_dict(d, "bench"), seed=7).write(Path({path!r}))
"""

PAGE = os.sysconf("SC_PAGE_SIZE")


def rss_mb() -> float:
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * PAGE / 1e6


class RssProbe(Sink):
    """Samples the RSS every ``every_us`` of vehicle time (a sink: no change to the fold)."""

    name = "rss"

    def __init__(self, every_us: int):
        self.every_us = every_us
        self.next_us = None
        self.boot = None
        self.offset_s = 0.0  # the vehicle time of the loops before (the clock restarts at each)
        self.last_s = 0.0
        self.points: list[tuple[float, float]] = []

    def epoch(self, r) -> None:
        if r.boot != self.boot:
            self.offset_s, self.boot, self.next_us = self.last_s, r.boot, None
        self.last_s = self.offset_s + r.t_us * 1e-6
        if self.next_us is None or r.t_us >= self.next_us:
            self.points.append((self.last_s, rss_mb()))
            self.next_us = r.t_us + self.every_us


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--loops", type=int, default=2, help="hours: the one-hour flight this many times")
    ap.add_argument("--imu-hz", type=float, default=50.0)
    ap.add_argument("--every-s", type=float, default=300.0)
    ap.add_argument("--warm-min", type=float, default=10.0)
    args = ap.parse_args()
    announce("memory.py")
    cfg = load_config(None)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "long.tlog"
        t0 = time.perf_counter()
        one = Path(tmp) / "hour.tlog"
        code = GEN.format(bench=str(Path(__file__).resolve().parent), seconds=3600.0,
                          imu_hz=args.imu_hz, path=str(one))
        subprocess.run([sys.executable, "-c", code], check=True)
        data = one.read_bytes()
        one.unlink()
        with open(path, "wb") as f:
            for _ in range(args.loops):
                f.write(data)
        del data
        print(f"log: {args.loops} x 1 h simulated, IMU {args.imu_hz:g} Hz, {path.stat().st_size / 1e6:.0f} MB, "
              f"written in {time.perf_counter() - t0:.0f} s")
        probe = RssProbe(int(args.every_s * 1e6))
        start_rss = rss_mb()
        t0 = time.perf_counter()
        sinks = [AlarmPrinter(), CsvSink(str(Path(tmp) / "est.csv")), AuditSink(), probe]
        import contextlib
        import io

        with contextlib.redirect_stderr(io.StringIO()):  # the console sink's alarms
            summary = run(open_log(path, cfg.ingest), cfg, sinks, info={"source": str(path), "live": False})
        wall = time.perf_counter() - t0
    probe.points.append((probe.last_s, rss_mb()))  # after the run, the sinks closed
    pts = probe.points
    base = next((m for t, m in pts if t - pts[0][0] >= args.warm_min * 60.0), pts[0][1])
    end = pts[-1][1]
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024 / 1e6
    print(f"replay: {summary.epochs} epochs, {summary.reboots} reboots, in {wall:.0f} s "
          f"({args.loops * 3600 / wall:.0f}x real time)")
    print("RSS MB by vehicle time: " + ", ".join(f"{t / 60:.0f} min {m:.1f}" for t, m in pts))
    print(f"RSS before the replay {start_rss:.1f} MB; after {args.warm_min:g} min {base:.1f} MB; "
          f"at the end {end:.1f} MB; peak {peak:.1f} MB")
    growth = end - base
    print(f"growth after warm-up: {growth:+.1f} MB   (goal < 20 MB: {'met' if growth < 20 else 'MISSED'})")
    print(f"load average after: {', '.join(f'{x:.2f}' for x in os.getloadavg())}")


if __name__ == "__main__":
    main()
