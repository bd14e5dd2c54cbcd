"""Ingestion throughput: mavnav's TlogSource against a bare pymavlink loop on the same file.

Generates a long synthetic tlog in a temporary directory (PX4-like rates:
HIGHRES_IMU 200 Hz, ATTITUDE 50 Hz, SCALED_PRESSURE 50 Hz, GPS_RAW_INT
10 Hz, DISTANCE_SENSOR 20 Hz, plus heartbeats and messages mavnav does not
use), then times

* ``mavutil.mavlink_connection(path)`` + ``recv_match(type=[...])`` over the
  message types mavnav uses (decoded, CRC-checked by pymavlink), and
* iterating :class:`mavnav.ingest.TlogSource` (every sample and event),

and prints both rates and the ratio. Then, for onboard logs (every .bin and
.ulg in ``../shared/flightlogs`` and in the directories given with
``--onboard-dir``), the whole ``mavnav audit`` of each file (decode, samples,
monitor) against the bare library pass over the same file: a pymavlink
``DFReader_binary`` + ``recv_msg()`` loop to the end, or ``pyulog.ULog(path)``;
and the audit's two halves, each timed alone: *ingest* (decode the file and
build every sample and event: ``read_record`` + the ``OnboardSource``
stream, its IMU samples as runs of columns as the audit reads them) and
*estimator* (the same pipeline as the audit over those samples, already
built: epochs, the three filters, the monitor, the audit sink).
Usage::

    .venv/bin/python bench/ingest.py [--minutes 10] [--repeat 3] [--onboard-dir ~/.cache/mavnav-flightlogs]
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
import time
from pathlib import Path

from pymavlink import mavutil

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the repository: tests.support

from mavnav.config import IngestConfig  # noqa: E402
from mavnav.ingest import TlogSource  # noqa: E402
from tests.support.tlog_writer import TlogWriter  # noqa: E402

USED = [
    "HIGHRES_IMU", "ATTITUDE", "SCALED_PRESSURE", "GPS_RAW_INT", "DISTANCE_SENSOR", "HEARTBEAT",
]


def generate(path: Path, minutes: float) -> int:
    """Write the synthetic log; returns the number of frames."""
    t0_unix = 1_700_000_000.0
    n = 0
    with TlogWriter(path) as w:
        mav = w.mav
        steps = int(minutes * 60 * 200)
        for k in range(steps):  # 200 Hz base tick
            t_s = k / 200.0
            t_us = int(t_s * 1e6) + 1_000_000
            recv = t0_unix + t_s + 0.002
            h = 10.0 + 5.0 * math.sin(0.05 * t_s)
            roll, pitch = 0.05 * math.sin(0.7 * t_s), 0.04 * math.cos(0.5 * t_s)
            w.write(mav.highres_imu_encode(t_us, 0.1, -0.2, -9.8, 0, 0, 0, 0.2, 0, 0.4, 1000.0, 0, h, 25.0, 0b111), recv)
            n += 1
            if k % 4 == 0:
                w.write(mav.attitude_encode(t_us // 1000, roll, pitch, 0.3, 0, 0, 0), recv)
                p_hpa = 1013.25 * (1 - 2.25577e-5 * h) ** 5.25588
                w.write(mav.scaled_pressure_encode(t_us // 1000, p_hpa, 0.0, 2500), recv)
                n += 2
            if k % 10 == 0:
                w.write(mav.distance_sensor_encode(t_us // 1000, 20, 4000, int(h * 100), 0, 0, 25, 255), recv)
                n += 1
            if k % 20 == 0:
                w.write(mav.gps_raw_int_encode(t_us, 3, 473977000, 85455000, int((488 + h) * 1000), 80, 120, 0, 0, 12,
                                               int((536 + h) * 1000), 500, 800), recv)
                w.write(mav.sys_status_encode(0, 0, 0, 500, 12000, 100, 80, 0, 0, 0, 0, 0, 0), recv)
                w.write(mav.vfr_hud_encode(5.0, 5.0, 90, 50, 500 + h, 0.1), recv)
                w.write(mav.servo_output_raw_encode(t_us & 0xFFFFFFFF, 0, 1500, 1500, 1500, 1500, 0, 0, 0, 0), recv)
                n += 4
            if k % 200 == 0:
                w.write(mav.heartbeat_encode(2, 12, 0, 0, 4, 3), recv)  # quadrotor, PX4
                n += 1
    return n


def bench_pymavlink(path: Path) -> int:
    m = mavutil.mavlink_connection(str(path))
    count = 0
    while m.recv_match(type=USED) is not None:
        count += 1
    m.close()
    return count


def bench_mavnav(path: Path) -> int:
    count = 0
    for _ in TlogSource(path, IngestConfig()):
        count += 1
    return count


def best_of(fn, path, repeat):
    best, out = math.inf, None
    for _ in range(repeat):
        t = time.perf_counter()
        out = fn(path)
        best = min(best, time.perf_counter() - t)
    return best, out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--minutes", type=float, default=10.0)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--onboard-dir", action="append", default=[],
                    help="more directories of .bin/.ulg logs (besides ../shared/flightlogs)")
    ap.add_argument("--onboard-only", action="store_true")
    args = ap.parse_args(argv)
    if not args.onboard_only:
        tlog_part(args)
    onboard_part(args)
    return 0


def bare_dataflash(path: Path) -> int:
    import contextlib
    import io

    from pymavlink import DFReader

    with contextlib.redirect_stderr(io.StringIO()), contextlib.redirect_stdout(io.StringIO()):
        r = DFReader.DFReader_binary(str(path), zero_time_base=True)
        n = 0
        while r.recv_msg() is not None:
            n += 1
    return n


def bare_ulog(path: Path) -> int:
    import pyulog

    u = pyulog.ULog(str(path))
    return sum(len(d.data["timestamp"]) for d in u.data_list)


def mavnav_audit(path: Path) -> int:
    from mavnav.audit import audit_file
    from mavnav.config import config_from_dict

    return audit_file(path, config_from_dict({}))["epochs"]


def mavnav_ingest(path: Path) -> list:
    """Decode and every sample and event, as the audit's source makes them
    (the IMU samples as runs of columns, as the audit reads them)."""
    from mavnav.config import config_from_dict
    from mavnav.ingest.onboard.source import OnboardSource, read_record

    return list(OnboardSource(path, config_from_dict({}).ingest, record=read_record(path)).runs())


class _Built:
    """Samples already built, offered as the audit's source offers them (``runs``)."""

    def __init__(self, items: list):
        self.items = items

    def __iter__(self):
        return iter(self.items)

    def runs(self):
        return iter(self.items)


def mavnav_estimator(samples: list) -> int:
    """The audit's pipeline over samples already built."""
    from mavnav.audit import AuditSink
    from mavnav.config import config_from_dict
    from mavnav.pipeline import run

    return run(_Built(samples), config_from_dict({}), [AuditSink()]).epochs


def onboard_part(args) -> None:
    dirs = [Path(__file__).resolve().parents[2] / "shared" / "flightlogs"] + [Path(d).expanduser() for d in args.onboard_dir]
    files = sorted(p for d in dirs if d.is_dir() for p in d.iterdir() if p.suffix.lower() in (".bin", ".ulg"))
    print(f"onboard logs: {len(files)} found in {', '.join(str(d) for d in dirs)}")
    tot = {"dataflash": [0.0, 0.0, 0.0, 0.0, 0], "ulog": [0.0, 0.0, 0.0, 0.0, 0]}
    for p in files:
        kind = "ulog" if p.suffix.lower() == ".ulg" else "dataflash"
        bare = bare_ulog if kind == "ulog" else bare_dataflash
        t_bare, n = best_of(bare, p, args.repeat)
        t_mn, ep = best_of(mavnav_audit, p, args.repeat)
        t_in, samples = best_of(mavnav_ingest, p, args.repeat)
        t_est, _ = best_of(mavnav_estimator, samples, args.repeat)
        for i, t in enumerate((t_bare, t_mn, t_in, t_est)):
            tot[kind][i] += t
        tot[kind][4] += 1
        print(f"  {p.name:48s} bare {t_bare:6.3f} s ({n} records)  mavnav audit {t_mn:6.3f} s ({ep} epochs)  "
              f"ratio audit/bare {t_mn / t_bare:5.2f}  (ingest {t_in / t_bare:4.2f}, estimator {t_est / t_bare:4.2f})")
    for kind, (tb, tm, ti, te, n) in tot.items():
        if n:
            print(f"{kind}: {n} files, bare {tb:.2f} s, mavnav audit {tm:.2f} s: ratio audit/bare {tm / tb:.2f} "
                  f"(goal <= 1.0); alone: ingest {ti:.2f} s = {ti / tb:.2f}x bare, "
                  f"estimator {te:.2f} s = {te / tb:.2f}x bare")


def tlog_part(args) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "bench.tlog"
        t = time.perf_counter()
        frames = generate(path, args.minutes)
        print(f"generated {frames} frames, {path.stat().st_size / 1e6:.1f} MB, {args.minutes:g} min of log "
              f"in {time.perf_counter() - t:.1f} s")
        t_py, n_py = best_of(bench_pymavlink, path, args.repeat)
        t_mn, n_mn = best_of(bench_mavnav, path, args.repeat)
    print(f"pymavlink recv_match loop : {n_py} messages in {t_py:.2f} s = {n_py / t_py:,.0f} msg/s "
          f"({frames / t_py:,.0f} frames/s)")
    print(f"mavnav TlogSource         : {n_mn} samples+events in {t_mn:.2f} s = {n_mn / t_mn:,.0f} samples/s "
          f"({frames / t_mn:,.0f} frames/s)")
    print(f"speed-up (same file, time ratio pymavlink/mavnav): {t_py / t_mn:.1f}x")


if __name__ == "__main__":
    sys.exit(main())
