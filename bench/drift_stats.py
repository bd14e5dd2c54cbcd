"""The GNSS altitude's drift rate against the baro on every real flight with a
GNSS: the statistic of ``mavnav/monitor/drift.py``.

    python bench/drift_stats.py [--window 10] [--workers 2] [paths...]

For each flight, at every GNSS sample with ``window`` seconds of continuous
data behind it (samples further apart than 1.5 s restart it), the
least-squares slope of ``d = GNSS - baro`` (the baro interpolated to the GNSS
sample's time) over the window. Printed per flight: the GNSS rate, whether
the receiver logs a Doppler velocity (where it does, the monitor uses the
Doppler tests instead), the 50th, 99th and 99.9th percentiles and the maximum
of ``|slope|`` (m/s), and the white noise of ``d`` from its second
differences (m). These size ``monitor.gnss_drift_sigma_mps``.
"""

from __future__ import annotations

import argparse
import math
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent))

from realflights import find_flights  # noqa: E402

from mavnav.config import config_from_dict  # noqa: E402
from mavnav.errors import MavnavError  # noqa: E402
from mavnav.ingest import open_log  # noqa: E402
from mavnav.monitor.drift import MAD_TO_SIGMA, SECOND_DIFF_GAIN, DriftCheck  # noqa: E402
from mavnav.samples import BaroHeight, GnssHeight  # noqa: E402

MAX_GAP_S = 1.5


def flight(args: tuple):
    path, window_s = args
    cfg = config_from_dict({})
    g, b, doppler = [], [], False
    try:
        for s in open_log(path, cfg.ingest):
            if getattr(s, "boot", 0) != 0:
                continue
            if isinstance(s, GnssHeight) and s.height_ref_m is not None:
                g.append((s.t_us, s.height_ref_m))
                doppler |= s.vel_up_mps is not None and math.isfinite(s.vel_up_mps)
            elif isinstance(s, BaroHeight) and s.height_ref_m is not None:
                b.append((s.t_us, s.height_ref_m))
    except MavnavError as e:
        return path, f"unreadable: {e}"
    if len(g) < 30 or len(b) < 30:
        return path, None
    g, b = np.asarray(g, dtype=float), np.asarray(b, dtype=float)
    d = g[:, 1] - np.interp(g[:, 0], b[:, 0], b[:, 1])
    check = DriftCheck(window_s, MAX_GAP_S)
    slopes = [check.push(int(t), float(x)) for t, x in zip(g[:, 0], d)]
    slopes = np.abs([s for s in slopes if s is not None])
    if slopes.size == 0:
        return path, None
    d2 = d[2:] - 2 * d[1:-1] + d[:-2]
    white = float(np.median(np.abs(d2))) * MAD_TO_SIGMA / SECOND_DIFF_GAIN
    hz = len(g) / max((g[-1, 0] - g[0, 0]) * 1e-6, 1e-9)
    return path, (hz, doppler, np.percentile(slopes, [50, 99, 99.9]), float(slopes.max()), white)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("paths", nargs="*")
    ap.add_argument("--window", type=float, default=10.0)
    ap.add_argument("--workers", type=int, default=2)
    a = ap.parse_args(argv)
    paths = a.paths or [str(p) for group in find_flights().values() for p in group]
    print(f"GNSS - baro slope over {a.window:g} s, |m/s|")
    print(f"{'flight':42s} {'GNSS Hz':>7s} {'Doppler':>7s} {'p50':>6s} {'p99':>6s} {'p99.9':>6s} {'max':>6s} "
          f"{'white m':>7s}")
    with ProcessPoolExecutor(a.workers) as ex:
        for path, r in ex.map(flight, [(p, a.window) for p in paths]):
            if r is None:
                continue
            if isinstance(r, str):
                print(f"{Path(path).name[:42]:42s} {r}")
                continue
            hz, dop, pc, mx, white = r
            print(f"{Path(path).name[:42]:42s} {hz:7.1f} {'yes' if dop else 'no':>7s} {pc[0]:6.3f} {pc[1]:6.3f} "
                  f"{pc[2]:6.3f} {mx:6.3f} {white:7.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
