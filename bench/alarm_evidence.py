"""Every sensor alarm mavnav raises on the real flights as flown, beside the raw
data around it: does the blamed sensor depart from the autopilot's height
there, by more than it does elsewhere on the same flight, and more than the
other sensor does? Issue 13's evidence allows alarms on a real flight only
where a sensor fault shows in the raw data; this is the table that says where
one does (and where none does: a false alarm).

    python bench/alarm_evidence.py [--workers 2] [--window 10]

For each alarm (a source going to ``alarm``), over ``[t - window, t + window]``:

* ``blamed``: the largest change, within ``window`` seconds, of the blamed
  sensor's height less the autopilot's (the baro for ``baro_ins``), and the
  median of that change over the whole flight (its usual scatter);
* ``other``: the same for the other height sensor (the GNSS for the baro, the
  baro for the GNSS and the rangefinder);
* ``raw departs``: ``yes`` where the blamed sensor's change is at least
  ``--factor`` times its usual and at least ``--min-m``, and larger than the
  other sensor's; ``no`` otherwise. An alarm on the INS against the GNSS
  Doppler shows in neither height: it is marked ``INS`` (or ``Doppler`` where
  the GNSS is blamed), to be read from its reason; a rangefinder alarm too.

The autopilot's height follows the baro on ArduPilot logs and the GNSS on
PX4 1.14's, so the columns say which sensor departs from the autopilot, not
which is right; the comparison of the two sensors' changes is what points.
Against a baro that the autopilot follows, the autopilot cannot show the
baro's departure; where the receiver logs a Doppler velocity, the baro is
also set against the Doppler's integral (``baro - Doppler``: the same change
and usual over the window, the integral restarted across gaps), which
neither the baro nor the GNSS altitude enters; ``raw departs`` is then
``yes`` where either yardstick shows the baro departing (against the
Doppler: by ``--factor`` its usual and ``--min-m``, and more than the GNSS
altitude departs from the same integral). A GNSS alarm is not set against
its own Doppler (that is the GNSS/Doppler test itself).
"""

from __future__ import annotations

import argparse
import math
import sys
from concurrent.futures import ProcessPoolExecutor
from functools import partial
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent))

from caution_evidence import _Raw, swings_m  # noqa: E402
from preamble import announce  # noqa: E402
from realflights import find_flights  # noqa: E402

from mavnav.audit import audit_file  # noqa: E402
from mavnav.config import config_from_dict  # noqa: E402
from mavnav.errors import MavnavError  # noqa: E402
from mavnav.ingest import open_log  # noqa: E402
from mavnav.samples import GnssHeight  # noqa: E402

DOPPLER_MAX_GAP_S = 1.5  # the integral restarts across a longer gap (monitor.doppler_max_gap_s)
FACTOR, MIN_M = 3.0, 1.0  # departs: this many times its usual change, and at least this many metres

# the height sensor an alarm blames, and the one it is set against
# (columns of _Raw rows: t, baro, gnss, autopilot; the rangefinder's height is not among them)
BLAMED = {"baro_ins": 1, "gnss": 2, "rangefinder": 2}
OTHER = {"baro_ins": 2, "gnss": 1, "rangefinder": 1}


def departure(t_s: np.ndarray, d_m: np.ndarray, t0_s: float, window_s: float) -> tuple[float, float]:
    """The largest ``window_s`` change of ``d_m`` around ``t0_s`` (from ``t0 - window`` on,
    so the changes end by ``t0 + window``), and the median change over the flight."""
    ts, sw = swings_m(t_s, d_m, window_s)
    if sw.size == 0:
        return math.nan, math.nan
    near = (ts >= t0_s - window_s) & (ts <= t0_s)
    return (float(sw[near].max()) if near.any() else math.nan), float(np.median(sw))


def judge(source: str, reason: str, blamed: tuple[float, float], other: tuple[float, float], factor: float,
          min_m: float) -> str:
    first = reason.split(";")[0]
    if first.startswith("INS velocity"):  # the INS against the Doppler: in neither height
        return "INS" if source == "baro_ins" else "Doppler"
    if source == "rangefinder":
        return "rangefinder: see reason"
    (b, b_usual), (o, _) = blamed, other
    if not b == b:
        return "no data"
    departs = b >= max(factor * b_usual, min_m) and not (o == o and o >= b)
    return "yes" if departs else "no"


def doppler_integral(path: Path, cfg) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The receiver's Doppler vertical velocity integrated (trapezoid) over the
    first boot: ``(t_s, integral_m, segment)``. Across a gap longer than
    ``DOPPLER_MAX_GAP_S`` the integral goes on from an unknown level, so each
    sample carries its segment (changes are read within one). Empty without a
    Doppler."""
    t, v = [], []
    try:
        for s in open_log(str(path), cfg.ingest):
            if type(s) is GnssHeight and s.boot == 0 and s.vel_up_mps is not None and s.vel_up_mps == s.vel_up_mps:
                t.append(s.t_us * 1e-6)
                v.append(s.vel_up_mps)
    except MavnavError:
        pass
    if len(t) < 3:
        return np.zeros(0), np.zeros(0), np.zeros(0)
    t_s, v_mps = np.asarray(t), np.asarray(v)
    dt = np.diff(t_s)
    step = 0.5 * (v_mps[1:] + v_mps[:-1]) * dt
    seg = np.concatenate([[0], np.cumsum(dt > DOPPLER_MAX_GAP_S)])
    integ = np.concatenate([[0.0], np.cumsum(np.where(dt > DOPPLER_MAX_GAP_S, 0.0, step))])
    return t_s, integ, seg


def doppler_yardstick(path: Path, cfg, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The Doppler integral at the epochs ``t`` (NaN in a gap or without a
    Doppler) and each epoch's segment of it."""
    td, hd, sd = doppler_integral(path, cfg)
    if not td.size:
        return np.full_like(t, math.nan), np.zeros(len(t))
    dop = np.interp(t, td, hd, left=math.nan, right=math.nan)
    seg = sd[np.clip(np.searchsorted(td, t, side="right") - 1, 0, len(td) - 1)]
    # an epoch between two samples of different segments is in a gap: no yardstick
    nxt = sd[np.clip(np.searchsorted(td, t, side="left"), 0, len(td) - 1)]
    dop[seg != nxt] = math.nan
    return dop, seg


def evidence_at(src: str, reason: str, t0: float, a: np.ndarray, dop: np.ndarray, seg: np.ndarray,
                window_s: float, factor: float, min_m: float):
    """``(blamed, other, baro - Doppler, verdict)`` for a sensor blamed at ``t0``
    (``a``: the epochs' t, baro, GNSS, autopilot columns)."""
    t, ap = a[:, 0], a[:, 3]
    blamed = departure(t, a[:, BLAMED[src]] - ap, t0, window_s)
    other = departure(t, a[:, OTHER[src]] - ap, t0, window_s)
    verdict = judge(src, reason, blamed, other, factor, min_m)
    vs_dop = (math.nan, math.nan)
    if src == "baro_ins" and np.isfinite(dop).sum() > 10:
        vs_dop = departure_within(t, a[:, 1] - dop, seg, t0, window_s)
        gnss_dop = departure_within(t, a[:, 2] - dop, seg, t0, window_s)
        if verdict == "no" and judge(src, reason, vs_dop, gnss_dop, factor, min_m) == "yes":
            verdict = "yes (Doppler)"
    return blamed, other, vs_dop, verdict


def _flight(path: Path, window_s: float, factor: float, min_m: float):
    raw = _Raw()
    cfg = config_from_dict({})
    try:
        res = audit_file(path, cfg, extra_sinks=[raw])
    except MavnavError as e:
        return path.name, [], str(e)
    a = np.array(raw.rows, float).reshape(-1, 4)
    dop, seg = doppler_yardstick(path, cfg, a[:, 0])
    out = []
    for ev in res["alarms"]:
        if ev["state"] != "alarm" or ev["source"] not in BLAMED:
            continue
        src, t0 = ev["source"], ev["t_s"]
        blamed, other, vs_dop, verdict = evidence_at(src, ev["reason"], t0, a, dop, seg, window_s, factor, min_m)
        out.append((t0, src, ev["reason"], blamed, other, vs_dop, verdict))
    return path.name, out, None


def departure_within(t_s: np.ndarray, d_m: np.ndarray, seg: np.ndarray, t0_s: float,
                     window_s: float) -> tuple[float, float]:
    """:func:`departure` with no change spanning two segments of the Doppler
    integral: the largest change near ``t0_s`` within its own segment, the
    median over every segment's own changes."""
    near, usual = [], []
    for k in np.unique(seg):
        m = seg == k
        ts, sw = swings_m(t_s[m], d_m[m], window_s)
        if sw.size == 0:
            continue
        usual.append(sw)
        close = (ts >= t0_s - window_s) & (ts <= t0_s)
        if close.any():
            near.append(float(sw[close].max()))
    if not usual:
        return math.nan, math.nan
    return (max(near) if near else math.nan), float(np.median(np.concatenate(usual)))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--window", type=float, default=10.0, help="seconds either side of the alarm")
    ap.add_argument("--factor", type=float, default=FACTOR, help="times the sensor's usual change")
    ap.add_argument("--min-m", type=float, default=MIN_M, help="and at least this many metres")
    args = ap.parse_args(argv)
    announce("alarm_evidence.py")
    paths = [p for group in find_flights().values() for p in group]
    print(f"{len(paths)} flights; window {args.window:g} s, departs: >= {args.factor:g}x usual and "
          f">= {args.min_m:g} m, more than the other sensor\n")
    print("| flight | t s | source | reason | blamed - autopilot: change / usual m "
          "| other - autopilot: change / usual m | baro - Doppler: change / usual m | raw departs |")
    print("|---|---|---|---|---|---|---|---|")
    tally: dict = {}
    run = partial(_flight, window_s=args.window, factor=args.factor, min_m=args.min_m)
    with ProcessPoolExecutor(args.workers) as pool:
        for name, rows, err in pool.map(run, paths):
            for t0, src, reason, (b, bu), (o, ou), (d, du), verdict in rows:
                tally[verdict] = tally.get(verdict, 0) + 1
                dd = f"{d:.2f} / {du:.2f}" if d == d else "-"
                print(f"| {name} | {t0:.1f} | {src} | {reason.split(';')[0][:90]} | {b:.2f} / {bu:.2f} "
                      f"| {o:.2f} / {ou:.2f} | {dd} | {verdict} |")
    print("\n" + ", ".join(f"{k}: {v}" for k, v in sorted(tally.items())) + f" (of {sum(tally.values())} alarms)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
