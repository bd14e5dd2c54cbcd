"""The real flights with more than 1 % of their time with a sensor in caution,
beside the raw data: which test put them there, and how far each raw sensor
departs from the autopilot's own height (the standard deviation of the
difference over the flight and its largest change within 10 s). Issue 13's
evidence allows cautions only where a sensor fault shows in the raw data; this
is the table that says where one does.

    python bench/caution_evidence.py [--workers 2] [--min-share 0.01]

The autopilot's height follows the baro on ArduPilot logs and the GNSS on
PX4 1.14's, so the columns say which sensor departs from the autopilot, not
which is right. The last column judges each caution of the GNSS or the baro
as ``bench/alarm_evidence.py`` judges an alarm, at the caution's start (the
blamed sensor against the autopilot and the other sensor, a baro also
against the receiver's Doppler integral): the seconds of caution where the
raw data show the sensor departing, of all the flight's seconds of caution.
"""

from __future__ import annotations

import argparse
import collections
import math
import re
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent))

from preamble import announce  # noqa: E402
from realflights import find_flights  # noqa: E402

from mavnav.audit import audit_file  # noqa: E402
from mavnav.config import config_from_dict  # noqa: E402
from mavnav.errors import MavnavError  # noqa: E402
from mavnav.sinks.base import Sink  # noqa: E402

SWING_WINDOW_S = 10.0
NUMBER = re.compile(r"[-+]?\d[\d.]*")


class _Raw(Sink):
    name = "raw"

    def __init__(self):
        self.rows = []

    def epoch(self, r):
        self.rows.append((r.t_s, r.baro_height_ref_m, r.gnss_height_ref_m, r.autopilot_height_ref_m))


def swings_m(t_s: np.ndarray, d_m: np.ndarray, window_s: float = SWING_WINDOW_S) -> tuple[np.ndarray, np.ndarray]:
    """Per finite sample, its time and the change of ``d_m`` to the sample
    ``window_s`` later (empty with fewer than three)."""
    ok = np.isfinite(d_m)
    t_s, d_m = t_s[ok], d_m[ok]
    if len(t_s) < 3:
        return np.zeros(0), np.zeros(0)
    j = np.minimum(np.searchsorted(t_s, t_s + window_s), len(t_s) - 1)
    return t_s, np.abs(d_m[j] - d_m)


def swing_m(t_s: np.ndarray, d_m: np.ndarray, window_s: float = SWING_WINDOW_S) -> float:
    """The largest change of ``d_m`` between a sample and the one ``window_s`` later."""
    _, sw = swings_m(t_s, d_m, window_s)
    return float(sw.max()) if sw.size else math.nan


def _departure(t_s, x_m, ap_m) -> tuple[float, float]:
    d = x_m - ap_m
    ok = np.isfinite(d)
    return (float(np.std(d[ok])) if ok.sum() > 10 else math.nan), swing_m(t_s, d)


def _flight(path: Path):
    import alarm_evidence as ae  # (it imports this module's helpers)

    raw = _Raw()
    cfg = config_from_dict({})
    try:
        res = audit_file(path, cfg, extra_sinks=[raw])
    except MavnavError as e:
        return path.name, None, str(e)
    dur = res["duration_s"]
    by = collections.Counter()
    a = np.array(raw.rows, float).reshape(-1, 4)
    t, b, g, ap = a[:, 0], a[:, 1], a[:, 2], a[:, 3]
    dop, seg = ae.doppler_yardstick(path, cfg, t)
    shown = held_all = 0.0
    for x in res["alarms"]:
        if x["state"] != "caution":
            continue
        held_s = (x.get("cleared_t_s") or dur) - x["t_s"]
        if held_s > 0:
            test = NUMBER.sub("#", x["reason"].split(";")[0].replace("cannot isolate: ", "")).split(" (")[0]
            by[test] += held_s
            if x["source"] in ("gnss", "baro_ins"):
                held_all += held_s
                verdict = ae.evidence_at(x["source"], x["reason"], x["t_s"], a, dop, seg, SWING_WINDOW_S,
                                         ae.FACTOR, ae.MIN_M)[3]
                shown += held_s if verdict.startswith("yes") else 0.0
    return path.name, res, (by.most_common(1)[0][0] if by else "-", _departure(t, g, ap), _departure(t, b, ap),
                            (shown, held_all))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--min-share", type=float, default=0.01, help="caution share of flight time to list")
    args = ap.parse_args(argv)
    announce("caution_evidence.py")
    paths = [p for group in find_flights().values() for p in group]
    print(f"{len(paths)} flights\n")
    print("| flight | alarm events | caution gnss / baro_ins % | the test behind most of it "
          "| GNSS - autopilot sd / 10 s swing m | baro - autopilot sd / 10 s swing m "
          "| caution s at a raw departure / all |")
    print("|---|---|---|---|---|---|---|")
    total = [0.0, 0.0]
    with ProcessPoolExecutor(args.workers) as pool:
        for name, res, ev in pool.map(_flight, paths):
            if res is None:
                continue
            av = res["availability"]
            cg, cb = av["gnss"]["caution"], av["baro_ins"]["caution"]
            if max(cg, cb) <= args.min_share:
                continue
            alarms = sum(1 for x in res["alarms"] if x["state"] == "alarm")
            test, (gsd, gsw), (bsd, bsw), (shown, held) = ev
            total[0] += shown
            total[1] += held
            print(f"| {name} | {alarms} | {100 * cg:.1f} / {100 * cb:.1f} | {test} | {gsd:.2f} / {gsw:.1f} "
                  f"| {bsd:.2f} / {bsw:.1f} | {shown:.1f} / {held:.1f} |")
    print(f"\ncaution of the GNSS and the baro on the flights listed: {total[0]:.0f} s of {total[1]:.0f} s "
          "begin at a raw departure")
    return 0


if __name__ == "__main__":
    sys.exit(main())
