"""The real-flight scorecard: mavnav on every real flight it can find, as it is.

    python bench/realflights.py [--workers 2] [--no-faults] [--limit N] [--json out.json]

Finds flights in ``../shared/tlogs/{real,other}``, ``../shared/flightlogs``
and the local cache that ``../shared/flightlogs/fetch_more.sh`` fills
(``~/.cache/mavnav-flightlogs``, or ``$MAVNAV_FLIGHTLOGS``), says how many of
each it found, and prints:

1. per flight and in total: hours, vehicle, input rates, the share of time
   per state for each source, sensor alarm events per hour, fused height
   against the autopilot's (RMS, max), and the share of epochs each channel
   was used;
2. faults injected (``--inject`` semantics, :mod:`mavnav.sim.effects`) at
   25, 50 and 75 % of every flight whose IMU and baro run at 5 Hz or more:
   GNSS step 10 m, GNSS ramp 0.5 m/s, baro step 5 m, baro ramp 0.5 m/s,
   accelerometer bias 0.5 m/s^2, and rangefinder stuck and reading zero
   where its usable readings come at 5 Hz or more too (a run whose window
   holds no usable reading is skipped, and counted), each for 20 s. For
   each: detected, time-to-alarm, source named, wrong exclusions (a healthy
   source in alarm during the fault) and hazardous output (fused height more
   than 3 m from the same flight's unfaulted fused height while the overall
   state is nominal or caution). Every flight with a downward rangefinder
   is listed with its rates, and why it was or was not faulted;
3. the same runs for ``paper`` mode and ``bench/autopilot_baseline.py``.

Numbers are what mavnav does today, good or bad. The fetched logs have no
licence: they are read from the cache, never copied.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from collections import Counter
from dataclasses import dataclass, field
from multiprocessing import get_context
from pathlib import Path
from typing import Dict, List, Optional, Sequence

import numpy as np
import yaml

HERE = Path(__file__).resolve().parent
if not __package__:  # run as a script, or imported as realflights by another script: siblings by bare name
    sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent))  # the repository's mavnav, before the siblings import it

if __package__:  # imported as bench.realflights (the tests)
    from .autopilot_baseline import BaselineConfig, run_baseline
    from .scoremetrics import STATES, alarm_onsets, departure, detect, tta_stats
else:
    from autopilot_baseline import BaselineConfig, run_baseline
    from scoremetrics import STATES, alarm_onsets, departure, detect, tta_stats

from mavnav.audit import AuditSink, audit_file  # noqa: E402
from mavnav.config import config_from_dict  # noqa: E402
from mavnav.errors import MavnavError  # noqa: E402
from mavnav.ingest import open_log  # noqa: E402
from mavnav.pipeline import run  # noqa: E402
from mavnav.samples import RangeHeight, Rejected  # noqa: E402
from mavnav.sim.effects import SampleFaults  # noqa: E402
from mavnav.sim.faults import parse_fault  # noqa: E402
from mavnav.sinks.base import Sink  # noqa: E402

SHARED = HERE.parent.parent / "shared"
SENSOR_SOURCES = ("gnss", "rangefinder", "baro_ins")
ONSET_FRACS = (0.25, 0.5, 0.75)
FAULT_DURATION_S = 20.0
HAZARD_M = 3.0
MIN_RATE_HZ = 5.0
# the fused height this far from every raw height at once is the monitor's own doing (bench/output_departure.py)
AWAY_MARGIN_M = 2.0
# what a fault leaves: the output against the unfaulted flight's this long after the fault ended (s)
AFTER_S = (10.0, 40.0)

FAULTS = (
    ("gnss_step", "gnss_step:magnitude=10", "gnss"),
    ("gnss_ramp", "gnss_ramp:magnitude=0.5", "gnss"),
    ("baro_step", "baro_step:magnitude=5", "baro_ins"),
    ("baro_ramp", "baro_ramp:magnitude=0.5", "baro_ins"),
    ("rng_stuck", "rng_stuck", "rangefinder"),
    ("rng_zero", "rng_stuck:magnitude=0", "rangefinder"),
    ("accel_bias", "accel_bias_step:magnitude=0.5", "baro_ins"),
)
CONTENDERS = ("adaptive", "paper", "baseline")
# the targets as times from onset: steps within 1 s, a 0.5 m/s ramp before
# 3 m of error (6 s), an accelerometer bias of 0.5 m/s^2 before 3 m (sqrt(2 * 3 / 0.5) s)
ALERT_TARGET_S = {"gnss_step": 1.0, "baro_step": 1.0, "gnss_ramp": 6.0, "baro_ramp": 6.0,
                  "accel_bias": math.sqrt(2 * 3.0 / 0.5), "rng_stuck": 1.0, "rng_zero": 1.0}


# ---------------------------------------------------------------- discovery


def cache_dir() -> Path:
    return Path(os.environ.get("MAVNAV_FLIGHTLOGS", Path.home() / ".cache" / "mavnav-flightlogs"))


def find_flights() -> Dict[str, List[Path]]:
    groups = {
        "shared/tlogs/real": sorted((SHARED / "tlogs" / "real").glob("*.tlog")),
        "shared/tlogs/other": sorted((SHARED / "tlogs" / "other").glob("*.tlog")),
        "shared/flightlogs": sorted(p for p in (SHARED / "flightlogs").glob("*")
                                    if p.suffix.lower() in (".tlog", ".bin", ".ulg")),
        "cache (fetch_more.sh)": sorted(p for p in cache_dir().glob("*")
                                        if p.suffix.lower() in (".tlog", ".bin", ".ulg")),
    }
    return groups


def is_sitl(path: Path) -> bool:
    return path.name.startswith("SITL_") or path.parent.name == "other"


# ---------------------------------------------------------------- one flight


class _Trace(Sink):
    name = "trace"

    def __init__(self):
        self.t: List[float] = []
        self.h: List[float] = []
        self.overall: List[str] = []
        self.used: List[tuple] = []  # per channel (gnss, rangefinder, baro): in the fused output

    def epoch(self, r) -> None:
        self.t.append(r.t_s)
        self.h.append(r.height_fused_m)
        self.overall.append(r.overall)
        self.used.append(tuple(c.used for c in r.channels))


class _Held(Sink):
    """Integrity alerts on a flight as it is: episodes where the evidence holds a
    channel out of the fused output though its sensor has data (an alarm, or a
    failure the monitor cannot pin on one source). On a healthy flight every
    one is a false alert, whether or not a source went to alarm."""

    name = "held"

    def __init__(self):
        self.episodes = 0
        self.held_s = 0.0
        self._on = False
        self._t: Optional[float] = None

    def epoch(self, r) -> None:
        alarm = any(st.state == "alarm" for k, st in r.sources.items() if k in SENSOR_SOURCES)
        held = alarm or any(c.available and not c.used for c in r.channels)
        if self._on and self._t is not None:
            self.held_s += r.t_s - self._t
        if held and not self._on:
            self.episodes += 1
        self._on, self._t = held, r.t_s


class AwaySink(Sink):
    """The fused height against every raw height the flight has (baro, GNSS, the
    autopilot's): seconds more than a margin from all of them at once, by
    overall state (``scoremetrics.departure``; also bench/output_departure.py).
    Away from every sensor, the output is the monitor's own doing."""

    name = "away"

    def __init__(self):
        self.rows: List[tuple] = []

    def epoch(self, r) -> None:
        self.rows.append((r.t_s, r.height_fused_m, r.baro_height_ref_m, r.gnss_height_ref_m,
                          r.autopilot_height_ref_m, r.overall))

    def departure(self, margin_m: float = AWAY_MARGIN_M) -> Optional[tuple]:
        """``scoremetrics.departure`` of the epochs seen (None with fewer than two)."""
        if len(self.rows) < 2:
            return None
        t, f, b, g, ap, st = zip(*self.rows)
        return departure(t, f, [b, g, ap], st, margin_m)

    def summary(self) -> dict:
        got = self.departure()
        secs = got[0] if got is not None else dict.fromkeys(STATES, 0.0)
        return {k: round(v, 2) for k, v in secs.items()}


class _RangeCount(Sink):
    """Downward rangefinder readings the source gave: used, and refused (by why)."""

    name = "rangefinder count"

    def __init__(self):
        self.used = 0
        self.refused: Counter = Counter()

    def sample(self, s) -> None:
        if isinstance(s, RangeHeight):
            self.used += 1
        elif isinstance(s, Rejected) and s.sensor == "range":
            self.refused[s.kind] += 1

    def summary(self, duration_s: float) -> dict:
        n = self.used + sum(self.refused.values())
        per_s = (lambda k: k / duration_s) if duration_s > 0 else (lambda k: 0.0)
        return {"readings": n, "used": self.used, "refused": dict(self.refused),
                "readings_hz": per_s(n), "used_hz": per_s(self.used)}


def _fault_text(spec: str, onset_s: float, duration_s: float) -> str:
    """``spec`` (``kind`` or ``kind:key=value,...``) with its window, as ``--inject`` takes it."""
    return f"{spec}{',' if ':' in spec else ':'}onset={onset_s:.3f},duration={duration_s:.3f}"


_OVERRIDES: dict = {}  # settings from --set, applied to every contender
_SECTIONS = ("sensors", "filter", "ingest")  # --set keys under these are not monitor settings


def parse_set(items: Sequence[str]) -> dict:
    """``KEY=YAML`` settings (dotted keys) as a nested dict."""
    out: dict = {}
    for item in items:
        key, _, value = item.partition("=")
        node = out
        *parents, leaf = key.split(".")
        for k in parents:
            node = node.setdefault(k, {})
        node[leaf] = yaml.safe_load(value)
    return out


def _cfg(mode: str):
    top = {k: v for k, v in _OVERRIDES.items() if k in _SECTIONS}
    monitor = {k: v for k, v in _OVERRIDES.items() if k not in _SECTIONS}
    return config_from_dict({**top, "monitor": {**monitor, "mode": mode}})


def _span(samples) -> tuple:
    ts = [s.t_us for s in samples if getattr(s, "t_us", None) is not None and getattr(s, "boot", 0) == 0]
    return (min(ts) * 1e-6, max(ts) * 1e-6) if ts else (0.0, 0.0)


def _contender(mode: str, samples: list) -> dict:
    if mode == "baseline":
        cfg = _cfg("adaptive")
        b = run_baseline(samples, cfg.sensors, BaselineConfig())
        alarms_on = _alarm_intervals(b.alarms)
        overall = np.array(["alarm" if any(a <= t < z for a, z in alarms_on) else "nominal" for t in b.t_s])
        return {"t": np.asarray(b.t_s, float), "h": np.asarray(b.height_m, float), "overall": overall,
                "used": None, "alarms": list(b.alarms)}
    tr = _Trace()
    summary = run(samples, _cfg(mode), [tr])
    return {"t": np.asarray(tr.t, float), "h": np.asarray(tr.h, float), "overall": np.asarray(tr.overall),
            "used": np.asarray(tr.used, bool).reshape(-1, 3), "alarms": list(summary.alarms)}


def _alarm_intervals(alarms) -> list:
    out, open_ = [], {}
    for ev in alarms:
        if ev.state == "alarm" and ev.previous != "alarm":
            open_[ev.source] = ev.t_s
        elif ev.previous == "alarm" and ev.source in open_:
            out.append((open_.pop(ev.source), ev.t_s))
    out += [(a, math.inf) for a in open_.values()]
    return out


def flight_job(spec: dict) -> dict:
    """Part 1 for one flight, and part 2/3 if asked and the inputs are fast enough."""
    path = spec["path"]
    _OVERRIDES.clear()
    _OVERRIDES.update(spec.get("overrides", {}))
    t0 = time.perf_counter()
    out = {"path": path, "sitl": spec["sitl"]}
    rng = _RangeCount()
    held = _Held()
    away = AwaySink()
    try:
        res = audit_file(path, _cfg("adaptive"), extra_sinks=[rng, held, away])
    except MavnavError as exc:
        out["error"] = str(exc)
        return out
    out["audit"] = _part1(res)
    out["audit"]["rangefinder"] = rng.summary(res["duration_s"])
    out["audit"]["held_episodes"] = held.episodes
    out["audit"]["held_s"] = round(held.held_s, 2)
    out["audit"]["away_s"] = away.summary()
    rates = res["inputs"]["rates_hz"]
    fast = rates["imu"] >= MIN_RATE_HZ and rates["baro"] >= MIN_RATE_HZ
    out["fast"] = fast
    out["rng_faults"] = fast and rates["rangefinder"] >= MIN_RATE_HZ
    if spec["faults"] and fast:
        out["faults"], out["faults_skipped"] = _part2(path, rates)
    out["wall_s"] = round(time.perf_counter() - t0, 2)
    return out


def _part1(res: dict) -> dict:
    ing = res["ingest"]
    dur = res["duration_s"]
    alarm_events = Counter(a["source"] for a in res["alarms"] if a["state"] == "alarm")
    avail = res["availability"]
    return {
        "duration_s": dur,
        "format": res.get("format"),
        "vehicle": ing.get("firmware") or _mav_type(ing.get("vehicle")),
        "rates_hz": res["inputs"]["rates_hz"],
        "states": {s: avail[s] for s in (*SENSOR_SOURCES, "input", "overall") if s in avail},
        "alarms_per_h": {s: (alarm_events[s] / (dur / 3600) if dur > 0 else 0.0) for s in SENSOR_SOURCES},
        "alarm_events": sum(alarm_events[s] for s in SENSOR_SOURCES),
        "caution_share": {s: avail[s]["caution"] for s in SENSOR_SOURCES if s in avail},
        "rms_m": res["fused_vs_autopilot_rms_m"],
        "max_m": res["fused_vs_autopilot_max_m"],
        "mean_m": res["fused_vs_autopilot_mean_m"],
        "sd_m": res["fused_vs_autopilot_sd_m"],
        "used": avail.get("channels_used", {}),
        "samples": {k: ing["samples"].get(k, 0) for k in ("gnss", "baro", "range")},
        "notes": res["notes"],
    }


def _mav_type(v) -> str:
    if not v:
        return ""
    return {1: "plane", 2: "copter", 12: "sub", 13: "copter", 14: "copter", 19: "vtol", 20: "vtol"}.get(
        v.get("mav_type"), f"type {v.get('mav_type')}")


def _part2(path: str, rates: dict, faults=FAULTS, contenders=CONTENDERS) -> tuple:
    """Rows of faulted runs, and the runs skipped (a rangefinder fault whose
    window holds no usable reading: it would change nothing)."""
    cfg = _cfg("adaptive")
    base = list(open_log(path, cfg.ingest))
    t_lo, t_hi = _span(base)
    rng_t = np.array([s.t_us * 1e-6 for s in base if isinstance(s, RangeHeight) and s.boot == 0])
    clean = {m: _contender(m, base) for m in contenders}
    clean_on = {m: [(ev.source, ev.t_s) for ev in alarm_onsets(clean[m]["alarms"])] for m in contenders}
    rows, skipped = [], []
    for name, spec, source in faults:
        if source == "rangefinder" and rates.get("rangefinder", 0.0) < MIN_RATE_HZ:
            continue
        for frac in ONSET_FRACS:
            onset = t_lo + frac * (t_hi - t_lo)
            end = min(onset + FAULT_DURATION_S, t_hi)
            if end - onset < 5.0:
                continue
            if source == "rangefinder" and not ((rng_t >= onset) & (rng_t <= end)).any():
                skipped.append({"fault": name, "onset_s": round(onset, 2), "why": "no usable rangefinder reading"})
                continue
            sf = SampleFaults([parse_fault(_fault_text(spec, onset, end - onset))])
            faulted = list(sf.apply(base))
            changed = sf.report()[0]
            row = {"fault": name, "source": source, "onset_s": round(onset, 2), "end_s": round(end, 2),
                   "samples_changed": changed["samples_modified"] + changed["samples_dropped"]}
            for m in contenders:
                r = _contender(m, faulted)
                d = detect(r["alarms"], onset, end, source, grace_s=2.0)
                wrong = sorted({ev.source for ev in alarm_onsets(r["alarms"])
                                if onset <= ev.t_s <= end + 2.0 and ev.source in SENSOR_SOURCES and ev.source != source})
                alert = _alert_s(r, clean[m], onset, end, source, d)
                own = wrong_by_fault(alarm_onsets(r["alarms"]), clean_on[m], wrong, onset, end)
                row[m] = {"detected": d.detected, "tta_s": d.tta_s, "isolated": d.isolated, "alert_s": alert,
                          "in_use": _in_use(clean[m], onset, source),
                          "blamed": list(d.first_sources), "wrong": wrong, "wrong_by_fault": own,
                          "hazard_s": _hazard_s(r, clean[m], onset, end + 2.0),
                          "hazard_after_s": _hazard_s(r, clean[m], end + 2.0, t_hi),
                          "left_m": _left_m(r, clean[m], end)}
            rows.append(row)
    return rows, skipped


CHANNEL_OF_SOURCE = {"gnss": 0, "rangefinder": 1, "baro_ins": 2}
SAME_ALARM_S = 2.0  # an alarm onset this close to one of the unfaulted flight's is that flight's own


def wrong_by_fault(onsets, clean_onsets, wrong, onset: float, end: float) -> list:
    """The wrongly blamed sources whose alarm in the fault's window the
    unfaulted flight does not also raise within SAME_ALARM_S: the fault's
    doing, not the flight's own alarms falling inside the window."""
    return sorted({ev.source for ev in onsets
                   if onset <= ev.t_s <= end + 2.0 and ev.source in wrong
                   and not any(s == ev.source and abs(t - ev.t_s) <= SAME_ALARM_S for s, t in clean_onsets)})


def _alert_s(r: dict, clean: dict, onset: float, end: float, source: str, d) -> float:
    """Seconds from the onset until the faulty source leaves the fused output
    (by an alarm, or held while the monitor cannot isolate it) where the same
    flight unfaulted had it in; NaN if it never does within the window. The
    baseline has no output set: its alarm time."""
    if r["used"] is None or clean["used"] is None:
        return d.tta_s if d.detected else math.nan
    t, c = r["t"], CHANNEL_OF_SOURCE[source]
    w = np.flatnonzero((t >= onset) & (t <= end + 2.0))
    if w.size == 0 or clean["t"].size == 0:
        return math.nan
    j = np.clip(np.searchsorted(clean["t"], t[w], side="right") - 1, 0, clean["t"].size - 1)
    out = ~r["used"][w, c] & clean["used"][j, c]
    return float(t[w][np.argmax(out)] - onset) if out.any() else math.nan


def _in_use(clean: dict, onset: float, source: str) -> bool:
    """Whether the unfaulted flight, at the onset, had the faulty source in its
    fused output and the monitor available (overall nominal or caution): a
    fault in a source already out, or while the monitor says it cannot
    protect, has nothing left to alert. The baseline has no output set: always."""
    if clean["used"] is None:
        return True
    t = clean["t"]
    if t.size == 0:
        return False
    j = int(np.clip(np.searchsorted(t, onset, side="right") - 1, 0, t.size - 1))
    return bool(clean["used"][j, CHANNEL_OF_SOURCE[source]]) and clean["overall"][j] in ("nominal", "caution")


def _hazard_s(r: dict, clean: dict, t0: float, t1: float) -> float:
    """Seconds of output more than HAZARD_M from the unfaulted output while
    nominal/caution, within [t0, t1]."""
    t, h, st = r["t"], r["h"], r["overall"]
    if t.size == 0 or clean["t"].size == 0:
        return 0.0
    w = (t >= t0) & (t <= t1)
    if not w.any():
        return 0.0
    h0 = np.interp(t[w], clean["t"], clean["h"])
    trusted = np.isin(st[w], ("nominal", "caution"))
    bad = trusted & np.isfinite(h[w]) & (np.abs(h[w] - h0) > HAZARD_M)
    if not bad.any():
        return 0.0
    dt = np.diff(t[w], append=t[w][-1])
    return float(dt[bad].sum())


def _left_m(r: dict, clean: dict, end: float) -> Optional[float]:
    """What a fault leaves once it has ended: the median distance of the fused
    height (whatever the state: it is what a user sees) from the unfaulted
    flight's over AFTER_S after the fault ended, when both have one there."""
    t, h = r["t"], r["h"]
    w = (t >= end + AFTER_S[0]) & (t <= end + AFTER_S[1]) & np.isfinite(h)
    if w.sum() < 5 or clean["t"].size == 0:
        return None
    d = np.abs(h[w] - np.interp(t[w], clean["t"], clean["h"]))
    d = d[np.isfinite(d)]
    return round(float(np.median(d)), 3) if d.size >= 5 else None


def after_lines(faulted: List[dict]) -> str:
    """Once the fault has ended: hazardous output (as in the fault's window)
    and the offset it leaves in the output, per fault kind."""
    out = [f"After the fault ends (its sensor right again): runs with hazardous output from 2 s after its end "
           f"to the end of the flight, and the fused height's median distance from the unfaulted flight's "
           f"{AFTER_S[0]:g}-{AFTER_S[1]:g} s after its end, in any state (runs with an output there: "
           f"median, runs leaving more than 1 m, the largest):", ""]
    out.append("| fault | " + " | ".join(f"{m}: hazardous after / left: median m, > 1 m, max m" for m in CONTENDERS)
               + " |")
    out.append("|---|" + "---|" * len(CONTENDERS))
    for name in [f[0] for f in FAULTS] + ["all"]:
        rows = [x for x in faulted if name == "all" or x["fault"] == name]
        if not rows:
            continue
        cells = []
        for m in CONTENDERS:
            haz = sum(x[m].get("hazard_after_s", 0.0) > 0 for x in rows)
            left = [x[m]["left_m"] for x in rows if x[m].get("left_m") is not None]
            med = float(np.median(left)) if left else math.nan
            cells.append(f"{haz} / {fmt(med)}, {sum(v > 1.0 for v in left)} of {len(left)}, "
                         f"{fmt(max(left) if left else math.nan)}")
        out.append(f"| {name} | " + " | ".join(cells) + " |")
    return "\n".join(out)


# ---------------------------------------------------------------- report


def fmt(v, nd=2) -> str:
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "-"
    return f"{v:.{nd}f}"


def pct(v) -> str:
    return "-" if v is None else f"{100 * v:.0f}"


def report(groups: Dict[str, List[Path]], results: List[dict], wall: float, args) -> str:
    lines = []
    p = lines.append
    p(f"real-flight scorecard: {sum(len(v) for v in groups.values())} logs found "
      + ", ".join(f"{k}: {len(v)}" for k, v in groups.items()) + f"; wall {wall:.0f} s")
    ok = [r for r in results if "audit" in r]
    for r in results:
        if "error" in r:
            p(f"  unreadable: {r['path']}: {r['error']}")
    p("")
    p("## 1. Each flight as it is (adaptive mode)")
    p("")
    p("| flight | kind | min | vehicle | imu/baro/gnss/rng Hz | gnss N/C/U/A % | rng N/C/U/A % | baro N/C/U/A % | "
      "overall N/C/U/A % | alarms/h | fused-AP RMS / max m | fused-AP mean / sd m | used g/r/b % |")
    p("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    tot = Counter()
    for r in ok:
        a = r["audit"]
        rt = a["rates_hz"]
        st = a["states"]

        def ncua(s):
            x = st.get(s)
            return "/".join(pct(x[k]) for k in ("nominal", "caution", "unavailable", "alarm")) if x else "-"

        dur_h = a["duration_s"] / 3600
        tot["h"] += dur_h
        tot["alarms"] += a["alarm_events"]
        for s in SENSOR_SOURCES:
            tot[f"caution_{s}"] += a["caution_share"].get(s, 0.0) * a["duration_s"]
        for k, v in st.get("overall", {}).items():
            tot[f"overall_{k}"] += v * a["duration_s"]
        if a["rms_m"] is not None:
            tot["sq"] += a["rms_m"] ** 2 * a["duration_s"]
            tot["sq_t"] += a["duration_s"]
            tot["var"] += (a.get("sd_m") or 0.0) ** 2 * a["duration_s"]
        u = a["used"]
        p(f"| {Path(r['path']).name} | {'SITL' if r['sitl'] else 'real'} | {a['duration_s'] / 60:.1f} | {a['vehicle']} | "
          f"{rt['imu']:.0f}/{rt['baro']:.0f}/{rt['gnss']:.1f}/{rt['rangefinder']:.0f} | {ncua('gnss')} | "
          f"{ncua('rangefinder')} | {ncua('baro_ins')} | {ncua('overall')} | "
          f"{a['alarm_events'] / dur_h if dur_h > 0 else 0:.1f} | {fmt(a['rms_m'])} / {fmt(a['max_m'])} | "
          f"{fmt(a.get('mean_m'))} / {fmt(a.get('sd_m'))} | "
          f"{pct(u.get('gnss'))}/{pct(u.get('rangefinder'))}/{pct(u.get('baro'))} |")
    hours = tot["h"]
    p("")
    held_n = sum(r["audit"].get("held_episodes", 0) for r in ok)
    held_s = sum(r["audit"].get("held_s", 0.0) for r in ok)
    p(f"Total: {len(ok)} flights, {hours:.2f} h; sensor alarm events {tot['alarms']} "
      f"({tot['alarms'] / hours if hours else 0:.1f}/h); integrity alerts (a source out of the output by "
      f"alarm or unresolved failure) {held_n} ({held_n / hours if hours else 0:.1f}/h, "
      f"{100 * held_s / (hours * 3600) if hours else 0:.2f} % of the time); time in caution: "
      + ", ".join(f"{s} {100 * tot[f'caution_{s}'] / (hours * 3600) if hours else 0:.1f} %" for s in SENSOR_SOURCES)
      + "; overall state " + "/".join(f"{100 * tot[f'overall_{k}'] / (hours * 3600) if hours else 0:.1f}"
                                      for k in ("nominal", "caution", "unavailable", "alarm"))
      + " % nominal/caution/unavailable/alarm"
      + f"; fused vs autopilot RMS (time-weighted) "
      f"{math.sqrt(tot['sq'] / tot['sq_t']) if tot['sq_t'] else float('nan'):.2f} m, of which what varies "
      f"(each flight's own datum offset taken out) {math.sqrt(tot['var'] / tot['sq_t']) if tot['sq_t'] else float('nan'):.2f} m"
      f"; output more than {AWAY_MARGIN_M:g} m from every raw height at once (baro, GNSS, autopilot), s "
      + "/".join(f"{sum(r['audit'].get('away_s', {}).get(k, 0.0) for r in ok):.1f}" for k in STATES)
      + " nominal/caution/unavailable/alarm.")
    p("")
    p(rangefinder_lines(ok, faults=not args.no_faults))
    faulted = [row for r in ok for row in r.get("faults", [])]
    if faulted:
        n_fl = sum(1 for r in ok if r.get("faults"))
        p("")
        p(f"## 2-3. Faults injected into {n_fl} flights with IMU and baro at {MIN_RATE_HZ:g} Hz or more "
          f"({len(faulted)} runs per contender; onsets at {', '.join(f'{int(100 * f)} %' for f in ONSET_FRACS)} "
          f"of the flight, {FAULT_DURATION_S:g} s each)")
        p("")
        p("Alerted: the faulty source left the fused output (alarm, or held while the monitor cannot "
          "isolate it) where the unfaulted flight had it in; in target: alerted within 1 s for steps, "
          "before 3 m of error for ramps and the accelerometer bias.")
        p("")
        p("| fault | runs | " + " | ".join(f"{m}: alarmed / median TTA s / alerted / median time-to-alert s / "
                                         f"in target / isolated / wrong excl. / hazardous"
                                         for m in CONTENDERS) + " |")
        p("|---|---|" + "---|" * len(CONTENDERS))
        for name, _spec, src in FAULTS + (("all", None, None),):
            rows = [x for x in faulted if name == "all" or x["fault"] == name]
            if not rows and src == "rangefinder":
                skipped = sum(1 for r in ok for x in r.get("faults_skipped", []) if x["fault"] == name)
                why = (f"no usable rangefinder reading in any window ({skipped} runs skipped)" if skipped
                       else f"no flight with a rangefinder at ≥{MIN_RATE_HZ:g} Hz")
                p(f"| {name} | 0 | {why} |" + " - |" * (len(CONTENDERS) - 1))
                continue
            if not rows:
                continue
            cells = []
            for m in CONTENDERS:
                det = sum(x[m]["detected"] for x in rows)
                med, _p95 = tta_stats(x[m]["tta_s"] for x in rows if x[m]["detected"])
                iso = sum(x[m]["isolated"] for x in rows)
                wrong = sum(bool(x[m]["wrong"]) for x in rows)
                haz = sum(x[m]["hazard_s"] > 0 for x in rows)
                al = [x[m].get("alert_s", math.nan) for x in rows]
                n_al = sum(a == a for a in al)
                med_al, _ = tta_stats(al)
                in_t = sum(in_target(x, m) for x in rows)
                cells.append(f"{det}/{len(rows)} / {fmt(med)} / {n_al} / {fmt(med_al)} / {in_t} / {iso} / {wrong} / {haz}")
            p(f"| {name} | {len(rows)} | " + " | ".join(cells) + " |")
        p("")
        applicable = [x for x in faulted if x["samples_changed"] > 0]
        p(in_use_lines(applicable))
        p("")
        p(after_lines(applicable))
        p("")
        p(f"Runs whose fault changed any sample (the flight has the sensor): {len(applicable)} of {len(faulted)}. "
          "Wrong exclusions the unfaulted flight does not make within 2 s (the fault's own): "
          + ", ".join(f"{m} {sum(bool(x[m].get('wrong_by_fault', x[m]['wrong'])) for x in faulted)}"
                      for m in CONTENDERS) + ".")
        p("")
        p(isolation_line(applicable))
    return "\n".join(lines) + "\n"


def isolation_line(applicable: List[dict]) -> str:
    """Isolated of alarmed over the runs whose fault changed a sample (issue 13's
    isolation): the table above also counts as alarmed a run whose fault
    changed nothing (a GNSS fault on a flight without GNSS) when the flight's
    own alarm falls in its window, which says nothing of isolation."""
    cells = []
    for m in CONTENDERS:
        det = sum(x[m]["detected"] for x in applicable)
        iso = sum(x[m]["detected"] and x[m]["isolated"] for x in applicable)
        cells.append(f"{m} {iso}/{det}" + (f" ({100.0 * iso / det:.1f} %)" if det else ""))
    return "Isolated of alarmed, over the runs whose fault changed a sample: " + ", ".join(cells) + "."


def in_target(row: dict, contender: str) -> bool:
    """Whether a faulted run's faulty source left the output within its fault's target."""
    a = row[contender].get("alert_s", math.nan)
    return a == a and a <= ALERT_TARGET_S.get(row["fault"], math.inf)


def in_use_lines(applicable: List[dict]) -> str:
    """In target among the runs whose faulty source the unfaulted flight had in
    its output with the monitor available at the onset (the runs a monitor can
    answer for), beside all applicable runs."""
    out = ["In target where the unfaulted flight had the faulty source in its output and the monitor "
           "available (nominal or caution) at the onset, against all runs whose fault changed a sample:", ""]
    out.append("| fault | " + " | ".join(f"{m}: in use at onset / in target there / in target of all"
                                         for m in CONTENDERS) + " |")
    out.append("|---|" + "---|" * len(CONTENDERS))
    for name in [f[0] for f in FAULTS] + ["all"]:
        rows = [x for x in applicable if name == "all" or x["fault"] == name]
        if not rows:
            continue
        cells = []
        for m in CONTENDERS:
            hit = [in_target(x, m) for x in rows]
            use = [x[m].get("in_use", True) for x in rows]
            cells.append(f"{sum(use)} / {sum(h and u for h, u in zip(hit, use))} / {sum(hit)} of {len(rows)}")
        out.append(f"| {name} | " + " | ".join(cells) + " |")
    return "\n".join(out)


def rangefinder_lines(results: List[dict], faults: bool = True) -> str:
    """Which flights have a downward rangefinder, at what rates, and whether
    its faults were injected (and if not, why)."""
    have = [r for r in results if r.get("audit", {}).get("rangefinder", {}).get("readings", 0) > 0]
    n_rng = sum(1 for r in results if r.get("rng_faults"))
    head = (f"Downward rangefinders: {len(have)} of {len(results)} flights have one; "
            f"{n_rng} with IMU, baro and usable rangefinder readings at {MIN_RATE_HZ:g} Hz or more "
            f"{'get' if faults else 'would get'} the rangefinder faults.")
    out = [head]
    for r in have:
        a = r["audit"]
        rf, rt = a["rangefinder"], a["rates_hz"]
        refused = ", ".join(f"{k} {v}" for k, v in sorted(rf["refused"].items(), key=lambda kv: -kv[1]))
        if not r.get("fast"):
            verdict = f"not faulted: IMU or baro below {MIN_RATE_HZ:g} Hz"
        elif not r.get("rng_faults"):
            verdict = f"not faulted: usable readings below {MIN_RATE_HZ:g} Hz"
        elif faults:
            runs = sum(1 for x in r.get("faults", []) if x["source"] == "rangefinder")
            skipped = sum(1 for x in r.get("faults_skipped", []) if x["fault"].startswith("rng"))
            verdict = f"faulted: {runs} runs" + (f", {skipped} skipped (no usable reading in the window)"
                                                 if skipped else "")
        else:
            verdict = "qualifies"
        out.append(f"* {Path(r['path']).name}: {rf['readings_hz']:.1f} Hz of readings, {rf['used_hz']:.1f} Hz usable"
                   + (f" ({refused} refused)" if refused else "")
                   + f"; IMU {rt['imu']:.0f} Hz, baro {rt['baro']:.1f} Hz; {verdict}")
    return "\n".join(out)


def main(argv: Optional[Sequence[str]] = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("paths", nargs="*", help="only these logs (default: every log found)")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--no-faults", action="store_true", help="part 1 only")
    ap.add_argument("--limit", type=int, default=0, help="at most this many flights (0: all)")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=YAML",
                    help="a setting for every contender: a monitor key, e.g. features.kink_isolation=false, or "
                         "one under sensors./filter./ingest., e.g. sensors.gnss.gm_sigma_m=4 (repeatable)")
    ap.add_argument("--json", default=None, help="write every result here")
    ap.add_argument("--out", default=None, help="write the Markdown report here too")
    args = ap.parse_args(argv)
    groups = find_flights()
    for k, v in groups.items():
        print(f"found {len(v):3d} logs in {k}", file=sys.stderr)
    paths = [Path(q) for q in args.paths] or [q for v in groups.values() for q in v]
    if args.limit:
        paths = paths[: args.limit]
    overrides = parse_set(args.set)
    specs = [{"path": str(q), "sitl": is_sitl(q), "faults": not args.no_faults, "overrides": overrides}
             for q in paths]
    t0 = time.perf_counter()
    results: List[dict] = []
    if args.workers > 1:
        with get_context("spawn").Pool(args.workers) as pool:
            for i, r in enumerate(pool.imap(flight_job, specs)):
                results.append(r)
                print(f"[{i + 1}/{len(specs)}] {Path(r['path']).name} {r.get('wall_s', '')}", file=sys.stderr)
    else:
        for i, s in enumerate(specs):
            results.append(flight_job(s))
            print(f"[{i + 1}/{len(specs)}] {Path(s['path']).name}", file=sys.stderr)
    text = report(groups, results, time.perf_counter() - t0, args)
    print(text)
    if args.out:
        Path(args.out).write_text(text)
    if args.json:
        Path(args.json).write_text(json.dumps(results, indent=1, default=str))
    return 0


if __name__ == "__main__":
    sys.exit(main())
