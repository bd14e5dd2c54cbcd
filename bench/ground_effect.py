"""The baro against the GNSS Doppler near the ground, against the rest of the
flight: how much more the baro/Doppler test's statistic scatters at take-off
and landing (ground effect), the measurement behind a ground-effect term in
that test (session 14: measured on the scorecard and not taken, BENCHMARKS.md).

    python bench/ground_effect.py [--window 10] [--height 2] [--move 0.5] [paths...]

For every real flight with a Doppler vertical velocity, the statistic of the
baro/Doppler test (the baro's change over ``window`` seconds less the
Doppler's integral, ``mavnav/monitor/doppler.py``) is split in two: windows
that start or end below ``height`` metres above the reference (the take-off
point) while the vehicle moved ``move`` metres or more (take-offs and
landings), and the rest. Printed per flight: the 90th and 99th percentiles
and the maximum of ``|e|`` in each, and the excess of the near-ground 99th
percentile over the rest's, in quadrature.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent))

from preamble import announce  # noqa: E402
from realflights import find_flights  # noqa: E402

from mavnav.config import config_from_dict  # noqa: E402
from mavnav.errors import MavnavError  # noqa: E402
from mavnav.ingest import open_log  # noqa: E402
from mavnav.samples import BaroHeight, GnssHeight  # noqa: E402

MAX_GAP_S = 1.5


def split(t, b, v, window_s: float, height_m: float, move_m: float):
    """``|e|`` of the windows near the ground and of the rest."""
    iv = np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * np.diff(t))])
    j = np.searchsorted(t, t - window_s, side="right") - 1
    span = t - t[np.maximum(j, 0)]
    ok = (j >= 0) & (span >= 0.8 * window_s) & (span <= window_s + MAX_GAP_S)
    k, j = np.nonzero(ok)[0], j[ok]
    moved = iv[k] - iv[j]
    e = np.abs((b[k] - b[j]) - moved)
    near = (np.minimum(b[k], b[j]) < height_m) & (np.abs(moved) >= move_m)
    return e[near], e[~near]


def flight(path: str, window_s: float, height_m: float, move_m: float):
    g, b = [], []
    for s in open_log(path, config_from_dict({}).ingest):
        if getattr(s, "boot", 0) != 0:
            continue
        if isinstance(s, GnssHeight) and s.vel_up_mps is not None and math.isfinite(s.vel_up_mps):
            g.append((s.t_us * 1e-6, s.vel_up_mps))
        elif isinstance(s, BaroHeight):
            b.append((s.t_us * 1e-6, s.height_ref_m))
    if len(g) < 20 or len(b) < 20:
        return None
    g, b = np.asarray(g), np.asarray(b)
    return split(g[:, 0], np.interp(g[:, 0], b[:, 0], b[:, 1]), g[:, 1], window_s, height_m, move_m)


def _q(e) -> str:
    return "{:5.2f} {:5.2f} {:5.2f}".format(*np.percentile(e, [90, 99]), e.max()) if e.size else "  -"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("paths", nargs="*")
    ap.add_argument("--window", type=float, default=10.0, help="seconds (monitor.baro_doppler_window_s)")
    ap.add_argument("--height", type=float, default=2.0, help="m above the reference (the take-off point)")
    ap.add_argument("--move", type=float, default=0.5, help="m moved over the window")
    args = ap.parse_args(argv)
    announce("ground_effect.py")
    paths = args.paths or [str(p) for ps in find_flights().values() for p in ps]
    print(f"window {args.window:g} s, near the ground: below {args.height:g} m, moved {args.move:g} m or more")
    print("| flight | near: n | near: |e| p90 p99 max m | rest: n | rest: |e| p90 p99 max m | excess of p99 m |")
    print("|---|---|---|---|---|---|")
    for p in paths:
        try:
            r = flight(p, args.window, args.height, args.move)
        except MavnavError:
            continue
        if r is None or min(r[0].size, r[1].size) < 3:
            continue
        near, rest = r
        p_near, p_rest = np.percentile(near, 99), np.percentile(rest, 99)
        excess = math.sqrt(max(p_near * p_near - p_rest * p_rest, 0.0))
        print(f"| {Path(p).name} | {near.size} | {_q(near)} | {rest.size} | {_q(rest)} | {excess:.2f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
