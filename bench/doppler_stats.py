"""GNSS altitude against the receiver's own Doppler vertical velocity, and the
baro against it, on every real flight that logs the velocity.

    python bench/doppler_stats.py [--window 5] [paths...]

For each flight with GNSS samples that carry a Doppler vertical velocity
(ArduPilot GPS.VZ, PX4 vel_d_m_s; MAVLink telemetry has none), at every GNSS
sample with ``window`` seconds of continuous data behind it:

* ``pos-dop``: ``[h(t) - h(t - W)] - integral of v_up`` (the statistic of
  ``mavnav/monitor/doppler.py``);
* ``baro-dop``: the same with the baro's height change, its latest sample
  carried to each GNSS sample;
* ``baro-lvl``: the same as the monitor reads it with ``monitor.baro_doppler_level_span_s``
  (``mavnav/monitor/barolevel.py``; 1 s where that is 0, off): at the window's start the
  median of the baro over the span centred there, at its end the median of its last
  ``baro_doppler_end_samples``;
* ``gnss-baro``: the GNSS height change against the baro's;
* ``scale``: the least-squares slope of ``baro-dop`` on the Doppler's
  integral over the same windows, the fraction of the distance moved by which
  the baro's height change falls short (negative) of the Doppler's or exceeds
  it, on flights that moved at least ``MIN_MOVED_M`` within a window. The RMS
  of these slopes over the modern receivers' flights sizes
  ``monitor.baro_doppler_scale_frac``.

Printed as the 50th, 90th, 99th percentile and the maximum of the absolute
value, per flight and over all flights. These are the numbers that size
``monitor.doppler_sigma_m`` (docs/integrity.md).
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

from realflights import find_flights, is_sitl  # noqa: E402

from mavnav.config import config_from_dict  # noqa: E402
from mavnav.errors import MavnavError  # noqa: E402
from mavnav.ingest import open_log  # noqa: E402
from mavnav.monitor.barolevel import BaroLevel  # noqa: E402
from mavnav.monitor.doppler import DopplerCheck  # noqa: E402
from mavnav.samples import BaroHeight, GnssHeight  # noqa: E402

MAX_GAP_S = 1.5
MIN_MOVED_M = 2.0  # a flight's baro scale is read only if it moved this far within a window
# ...and enters the summary only if its receiver keeps pos-dop within this (99th percentile):
# a Doppler true to its own altitude is the reference the baro's scale is read against
TRUE_RECEIVER_M = 2.5
LEVEL_SPAN_S = 1.0  # baro-lvl's span where monitor.baro_doppler_level_span_s is 0 (off)


def _window_diffs(t, h, v, b, window_s):
    """Per-sample statistics over ``window_s`` within runs without gaps."""
    out = {"pos-dop": [], "baro-dop": [], "gnss-baro": [], "disp": []}
    runs = np.split(np.arange(t.size), np.nonzero(np.diff(t) > MAX_GAP_S)[0] + 1)
    for r in runs:
        if r.size < 3:
            continue
        tt, hh, vv, bb = t[r], h[r], v[r], b[r]
        iv = np.concatenate([[0.0], np.cumsum(0.5 * (vv[1:] + vv[:-1]) * np.diff(tt))])
        j = np.searchsorted(tt, tt - window_s, side="right") - 1
        ok = (j >= 0) & (tt - tt[np.maximum(j, 0)] >= 0.8 * window_s)
        k, j = np.nonzero(ok)[0], j[ok]
        dint = iv[k] - iv[j]
        out["pos-dop"].append((hh[k] - hh[j]) - dint)
        out["baro-dop"].append((bb[k] - bb[j]) - dint)
        out["gnss-baro"].append((hh[k] - hh[j]) - (bb[k] - bb[j]))
        out["disp"].append(dint)
    return {key: np.concatenate(v) if v else np.zeros(0) for key, v in out.items()}


def baro_levels(g: np.ndarray, b: np.ndarray, window_s: float, m) -> np.ndarray:
    """The baro/Doppler reading at every GNSS sample with a full window, the
    baro read through :class:`BaroLevel` as the monitor reads it."""
    level = BaroLevel(m.baro_doppler_level_span_s or LEVEL_SPAN_S, window_s, MAX_GAP_S, m.baro_doppler_end_samples)
    check = DopplerCheck(window_s, MAX_GAP_S)
    events = sorted([(t, 0, h) for t, h in b] + [(t, 1, v) for t, _, v in g])
    out = []
    for t, kind, x in events:
        t_us = int(round(t * 1e6))
        if kind == 0:
            level.push_baro(t_us, x)
            continue
        level.push_gnss(t_us, x)
        end = level.end_m(t_us)
        e = None if end is None else check.push(t_us, end, x, level.centred_m)
        if e is not None:
            out.append(e)
    return np.asarray(out)


def flight(path: str, window_s: float):
    cfg = config_from_dict({})
    g, b = [], []
    for s in open_log(path, cfg.ingest):
        if getattr(s, "boot", 0) != 0:
            continue
        if isinstance(s, GnssHeight) and s.vel_up_mps is not None and math.isfinite(s.vel_up_mps):
            g.append((s.t_us * 1e-6, s.height_ref_m, s.vel_up_mps))
        elif isinstance(s, BaroHeight):
            b.append((s.t_us * 1e-6, s.height_ref_m))
    if len(g) < 10 or len(b) < 10:
        return None
    g, b = np.asarray(g), np.asarray(b)
    bi = np.interp(g[:, 0], b[:, 0], b[:, 1])
    d = _window_diffs(g[:, 0], g[:, 1], g[:, 2], bi, window_s)
    if d["pos-dop"].size < 5:
        return None
    d["baro-lvl"] = baro_levels(g, b, window_s, cfg.monitor)
    return {"hz": len(g) / max(g[-1, 0] - g[0, 0], 1e-9), **d}


def baro_scale(r) -> float:
    """The slope of the baro/Doppler reading on the distance moved (NaN for a
    flight that never moved ``MIN_MOVED_M`` within a window)."""
    e, d = r["baro-dop"], r["disp"]
    if d.size == 0 or np.abs(d).max() < MIN_MOVED_M:
        return math.nan
    return float(np.sum(e * d) / np.sum(d * d))


def _q(e):
    return " ".join(f"{x:5.2f}" for x in np.percentile(np.abs(e), [50, 90, 99, 100]))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("paths", nargs="*")
    ap.add_argument("--window", type=float, default=5.0, help="seconds (monitor.doppler_window_s)")
    args = ap.parse_args(argv)
    paths = args.paths or [str(p) for ps in find_flights().values() for p in ps]
    tot = {"pos-dop": [], "baro-dop": [], "baro-lvl": [], "gnss-baro": []}
    print(f"window {args.window:g} s; |e| percentiles 50/90/99/max (m)")
    print("| flight | GNSS Hz | samples | pos-dop | baro-dop | baro-lvl | gnss-baro | scale |")
    print("|---|---|---|---|---|---|---|---|")
    scales = []
    for p in paths:
        try:
            r = flight(p, args.window)
        except MavnavError:
            continue
        if r is None:
            continue
        print(f"| {Path(p).name} | {r['hz']:.1f} | {r['pos-dop'].size} | {_q(r['pos-dop'])} | "
              f"{_q(r['baro-dop'])} | {_q(r['baro-lvl'])} | {_q(r['gnss-baro'])} | {baro_scale(r):+.3f} |")
        if not is_sitl(Path(p)) and np.percentile(np.abs(r["pos-dop"]), 99) < TRUE_RECEIVER_M:
            scales.append(baro_scale(r))
        for k in tot:
            tot[k].append(r[k])
    scales = np.asarray([x for x in scales if x == x])
    if scales.size:
        print(f"baro scale against the Doppler on {scales.size} real flights whose receiver keeps pos-dop within "
              f"{TRUE_RECEIVER_M:g} m (99th percentile) and that moved {MIN_MOVED_M:g} m or more: RMS {np.sqrt(np.mean(scales ** 2)):.3f}, "
              f"mean {scales.mean():+.3f}, range {scales.min():+.3f} to {scales.max():+.3f}")
    for k, v in tot.items():
        if v:
            print(f"all flights, {k}: {_q(np.concatenate(v))}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
