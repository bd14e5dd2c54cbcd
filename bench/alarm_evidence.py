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


def _flight(path: Path, window_s: float, factor: float, min_m: float):
    raw = _Raw()
    try:
        res = audit_file(path, config_from_dict({}), extra_sinks=[raw])
    except MavnavError as e:
        return path.name, [], str(e)
    a = np.array(raw.rows, float).reshape(-1, 4)
    t, ap = a[:, 0], a[:, 3]
    out = []
    for ev in res["alarms"]:
        if ev["state"] != "alarm" or ev["source"] not in BLAMED:
            continue
        src, t0 = ev["source"], ev["t_s"]
        blamed = departure(t, a[:, BLAMED[src]] - ap, t0, window_s)
        other = departure(t, a[:, OTHER[src]] - ap, t0, window_s)
        out.append((t0, src, ev["reason"], blamed, other, judge(src, ev["reason"], blamed, other, factor, min_m)))
    return path.name, out, None


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--window", type=float, default=10.0, help="seconds either side of the alarm")
    ap.add_argument("--factor", type=float, default=3.0, help="times the sensor's usual change")
    ap.add_argument("--min-m", type=float, default=1.0, help="and at least this many metres")
    args = ap.parse_args(argv)
    announce("alarm_evidence.py")
    paths = [p for group in find_flights().values() for p in group]
    print(f"{len(paths)} flights; window {args.window:g} s, departs: >= {args.factor:g}x usual and "
          f">= {args.min_m:g} m, more than the other sensor\n")
    print("| flight | t s | source | reason | blamed - autopilot: change / usual m "
          "| other - autopilot: change / usual m | raw departs |")
    print("|---|---|---|---|---|---|---|")
    tally: dict = {}
    run = partial(_flight, window_s=args.window, factor=args.factor, min_m=args.min_m)
    with ProcessPoolExecutor(args.workers) as pool:
        for name, rows, err in pool.map(run, paths):
            for t0, src, reason, (b, bu), (o, ou), verdict in rows:
                tally[verdict] = tally.get(verdict, 0) + 1
                print(f"| {name} | {t0:.1f} | {src} | {reason.split(';')[0][:90]} | {b:.2f} / {bu:.2f} "
                      f"| {o:.2f} / {ou:.2f} | {verdict} |")
    print("\n" + ", ".join(f"{k}: {v}" for k, v in sorted(tally.items())) + f" (of {sum(tally.values())} alarms)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
