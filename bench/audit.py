"""``mavnav audit`` against a bare pymavlink parse of the same long, high-rate
tlog, in the same run; and the per-message latency of the live pipeline.

The log: 10 minutes of PX4-style telemetry from mavnav's simulator
(HIGHRES_IMU 200 Hz, ATTITUDE 50 Hz, SCALED_PRESSURE 25 Hz, GPS_RAW_INT 10 Hz,
DISTANCE_SENSOR 20 Hz, heartbeats, the autopilot's own estimate) with a GNSS
step, written to a temporary directory.

* bare: ``mavutil.mavlink_connection(path)`` then ``recv_msg()`` until the end
  (every message decoded and CRC-checked by pymavlink; nothing else done);
* audit: :func:`mavnav.audit.audit_file` (ingestion, three filters,
  integrity monitor, audit statistics: the whole job);
* its two halves, each timed alone: *ingest* (every sample and event of
  :class:`mavnav.ingest.TlogSource`) and *estimator* (the audit's pipeline
  over those samples, already built: epochs, filters, monitor, audit sink);
* latency: each sample pushed through the monitor (the pipeline's fold, as
  ``run`` does on a live link) with a CSV sink, timed one by one with
  ``perf_counter``; p50, p99 and max over every message of the log.

    .venv/bin/python bench/audit.py [--minutes 10] [--repeat 3]
"""

from __future__ import annotations

import argparse
import io
import statistics
import tempfile
import time
from pathlib import Path

import yaml
from pymavlink import mavutil

from mavnav.audit import AuditSink, audit_file
from mavnav.config import load_config
from mavnav.ingest import TlogSource
from mavnav.monitor import Monitor
from mavnav.pipeline import run
from mavnav.sim import scenario_from_dict, simulate
from mavnav.sinks.csv_sink import csv_row

REPO = Path(__file__).resolve().parents[1]


def generate(path: Path, minutes: float) -> None:
    d = yaml.safe_load((REPO / "config/scenarios/px4_hover_gnss_step.yaml").read_text())
    d["duration_s"] = minutes * 60.0
    d.setdefault("rates_hz", {})["HIGHRES_IMU"] = 200.0
    for f in d.get("faults", []):
        f["onset_s"] = min(f["onset_s"], d["duration_s"] / 2)
    simulate(scenario_from_dict(d, "bench"), seed=7).write(path)


def bare(path: Path) -> int:
    m = mavutil.mavlink_connection(str(path))
    n = 0
    while m.recv_msg() is not None:
        n += 1
    return n


def best(fn, repeat):
    times = []
    out = None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return min(times), out


def latency(path: Path, cfg) -> list[float]:
    mon = Monitor(cfg)
    buf = io.StringIO()
    lat = []
    perf = time.perf_counter
    for s in TlogSource(path, cfg.ingest):
        t0 = perf()
        for report, _events in mon.push(s):
            buf.write(",".join(csv_row(report)))
        lat.append(perf() - t0)
    return lat


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--minutes", type=float, default=10.0)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    cfg = load_config(None)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "long.tlog"
        generate(path, args.minutes)
        size_mb = path.stat().st_size / 1e6
        audit_file(path, cfg)  # JIT (cached on disk) and page-cache warm-up
        t_bare, n_msgs = best(lambda: bare(path), args.repeat)
        t_audit, result = best(lambda: audit_file(path, cfg), args.repeat)
        t_ingest, samples = best(lambda: list(TlogSource(path, cfg.ingest)), args.repeat)
        t_est, _ = best(lambda: run(iter(samples), cfg, [AuditSink()]), args.repeat)
        del samples
        lat = latency(path, cfg)
    lat_us = sorted(v * 1e6 for v in lat)
    p = lambda q: lat_us[min(len(lat_us) - 1, int(q * len(lat_us)))]
    print(f"log: {args.minutes:g} min, {n_msgs} messages, {size_mb:.1f} MB, {result['epochs']} filter epochs")
    print(f"bare pymavlink recv_msg loop : {t_bare:6.2f} s ({n_msgs / t_bare:8.0f} msg/s)")
    print(f"mavnav audit (whole job)     : {t_audit:6.2f} s ({n_msgs / t_audit:8.0f} msg/s)")
    print(f"ratio audit / bare parse     : {t_audit / t_bare:6.2f}x   (goal: <= 0.5x, issue 15)")
    print(f"  alone: ingest {t_ingest:.2f} s = {t_ingest / t_bare:.2f}x bare, "
          f"estimator {t_est:.2f} s = {t_est / t_bare:.2f}x bare ({t_est / result['epochs'] * 1e6:.0f} us per epoch)")
    print(f"live pipeline latency per message over {len(lat_us)} samples: "
          f"p50 {p(0.5):.1f} us, p99 {p(0.99):.1f} us, max {lat_us[-1]:.0f} us "
          f"(mean {statistics.fmean(lat_us):.1f} us)   (goal: p99 < 1000 us)")


if __name__ == "__main__":
    main()
