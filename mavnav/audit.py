"""Headless audit of one recorded log: what happened, and whether it can be trusted.

:func:`audit_file` runs the same pipeline as ``run`` and ``replay`` over a
tlog and returns a JSON-ready dict (the ``files[]`` entry of ``mavnav audit
--json``), with a stable core::

    {"path", "duration_s",
     "alarms": [{"t_s", "source", "state", "reason", "cleared_t_s", "boot"}],
     "rates_hz": {...}, "availability": {...}, "fused_vs_autopilot_rms_m"}

and more keys beside it (``inputs``, ``notes``, ``ingest``...). ``t_s`` is
vehicle time, on the same clock as the CSV.
"""

from __future__ import annotations

import math
from collections import Counter
from pathlib import Path
from typing import Iterable, Optional, Sequence

from .config import Config
from .errors import MavnavError
from .ingest import open_log
from .ingest.vehicle_class import notice_text
from .pipeline import run
from .report import SOURCES, AlarmEvent, EpochReport, RunSummary
from .samples import BaroHeight, GnssHeight, RangeHeight, SpecificForceUp
from .sensors import BARO, CHANNELS, GNSS, IMU, INPUTS, RANGEFINDER
from .sim.effects import FaultedSource
from .sim.faults import describe_fault, parse_faults
from .sinks.base import Sink

INPUT_KINDS = {SpecificForceUp: IMU, BaroHeight: BARO, GnssHeight: GNSS, RangeHeight: RANGEFINDER}


def required_rates_hz(cfg: Config) -> dict[str, float]:
    """Input rates the time-to-alarm needs (the monitor's own rule)."""
    m = cfg.monitor
    aux = max(m.alarm_rejections, 1) / m.time_to_alarm_s
    return {IMU: m.min_imu_rate_hz, BARO: m.min_baro_rate_hz, GNSS: aux, RANGEFINDER: aux}


class AuditSink(Sink):
    """Collects what the audit reports while the pipeline runs."""

    name = "audit"

    def __init__(self) -> None:
        self.epochs = 0
        self.state_counts: dict[str, Counter] = {s: Counter() for s in SOURCES}
        self.used_counts: Counter = Counter()
        self.overall: Counter = Counter()
        self.alarms: list[dict] = []
        self._open: dict[tuple[int, str], list[dict]] = {}
        self.sq_err = 0.0
        self.sum_err = 0.0
        self.n_err = 0
        self.max_abs_err = 0.0
        self.input_counts: Counter = Counter()

    def sample(self, s) -> None:
        kind = INPUT_KINDS.get(type(s))
        if kind is not None:
            self.input_counts[kind] += 1

    def imu_run(self, run, i: int, j: int) -> None:
        """``sample`` of IMU samples ``i .. j - 1`` of an onboard log's run (see :mod:`mavnav.sinks.base`)."""
        self.input_counts[IMU] += j - i

    def epoch(self, r: EpochReport) -> None:
        self.epochs += 1
        counts = self.state_counts
        for name, st in r.sources.items():
            counts[name][st.state] += 1
        used = self.used_counts
        for ch in r.channels:
            if ch.used:
                used[ch.name] += 1
        self.overall[r.overall] += 1
        d = r.height_fused_m - r.autopilot_height_ref_m
        if d == d:
            self.sq_err += d * d
            self.sum_err += d
            self.n_err += 1
            self.max_abs_err = max(self.max_abs_err, abs(d))

    def alarm(self, ev: AlarmEvent) -> None:
        key = (ev.boot, ev.source)
        if ev.state in ("caution", "alarm"):
            entry = {"t_s": round(ev.t_s, 6), "source": ev.source, "state": ev.state, "reason": ev.reason,
                     "cleared_t_s": None, "boot": ev.boot}
            self.alarms.append(entry)
            self._open.setdefault(key, []).append(entry)
        elif ev.state == "nominal":
            for entry in self._open.pop(key, []):
                entry["cleared_t_s"] = round(ev.t_s, 6)

    def availability(self) -> dict:
        out = {}
        n = max(self.epochs, 1)
        for name, c in self.state_counts.items():
            out[name] = {st: round(c[st] / n, 4) for st in ("nominal", "caution", "unavailable", "alarm")}
        out["channels_used"] = {ch: round(self.used_counts[ch] / n, 4) for ch in CHANNELS}
        out["overall"] = {st: round(self.overall[st] / n, 4) for st in ("nominal", "caution", "unavailable", "alarm")}
        return out


def _notes(result: dict, sink: AuditSink, cfg: Config, stats, counts: dict) -> list[str]:
    notes = [f"log damaged: {d}" for d in stats.damage]
    if stats.not_applicable:
        # the model does not fit this vehicle: that is the whole story
        return notes + [notice_text(stats.not_applicable)]
    for kind, ok in result["inputs"]["supports_time_to_alarm"].items():
        rate = result["inputs"]["rates_hz"][kind]
        if rate == 0:
            notes.append(f"no {kind} samples: its channel is unavailable")
        elif not ok:
            need = required_rates_hz(cfg)[kind]
            notes.append(f"{kind} at {rate:.1f} Hz cannot support a {cfg.monitor.time_to_alarm_s:g} s alarm "
                         f"(needs {need:.0f} Hz)")
    if sink.epochs == 0:
        notes.append("no filter epoch: the log lacks IMU or baro data the estimator needs")
    if result["fused_vs_autopilot_rms_m"] is None:
        notes.append("no autopilot height to compare with")
    n = counts.get("glitch_restarts", 0)
    if n:
        notes.append(f"filters started again {n} time(s) within the warm-up: their first baro difference was a "
                     "glitch, and every baro row after it was gated")
    return notes


def audit_file(path: str | Path, cfg: Config, sysid: Optional[int] = None,
               extra_sinks: Iterable[Sink] = (), faults: Sequence = ()) -> dict:
    """Audit one recorded log (tlog, DataFlash or ULog). Raises :class:`MavnavError`
    (one line) if it is unreadable."""
    src = open_log(path, cfg.ingest, sysid=sysid)
    faults = parse_faults(faults)
    if faults:
        src = FaultedSource(src, faults)
    sink = AuditSink()
    summary: RunSummary = run(src, cfg, [sink, *extra_sinks], info={"source": str(path), "live": False})
    stats = src.stats
    duration = stats.duration_s
    rates = {k: (round(sink.input_counts[k] / duration, 3) if duration > 0 else 0.0)
             for k in INPUTS}
    need = required_rates_hz(cfg)
    result = {
        "path": str(path),
        "duration_s": round(duration, 3),
        "alarms": sink.alarms,
        "rates_hz": {k: round(v, 3) for k, v in sorted(stats.rates_hz.items())},
        "availability": sink.availability(),
        "fused_vs_autopilot_rms_m": (round(math.sqrt(sink.sq_err / sink.n_err), 4) if sink.n_err else None),
        "fused_vs_autopilot_max_m": (round(sink.max_abs_err, 4) if sink.n_err else None),
        # the RMS split into its constant part (the two heights' datums: the
        # autopilot's origin against mavnav's reference) and what varies
        "fused_vs_autopilot_mean_m": (round(sink.sum_err / sink.n_err, 4) if sink.n_err else None),
        "fused_vs_autopilot_sd_m": (round(math.sqrt(max(sink.sq_err / sink.n_err - (sink.sum_err / sink.n_err) ** 2,
                                                        0.0)), 4) if sink.n_err else None),
        "epochs": summary.epochs,
        "reboots": summary.reboots,
        "mode": cfg.monitor.mode,
        "format": stats.format,
        "inputs": {
            "rates_hz": rates,
            "required_hz": need,
            "supports_time_to_alarm": {k: (rates[k] >= cfg.monitor.rate_tolerance_frac * need[k]) for k in rates},
            "time_to_alarm_s": cfg.monitor.time_to_alarm_s,
        },
        "sink_failures": summary.sink_failures,
        "height_integrity_applies": not stats.not_applicable,
        "ingest": stats.to_dict(),
    }
    if faults:
        result["injected"] = [dict(describe_fault(f), **rep) for f, rep in zip(faults, src.injector.report())]
    result["notes"] = _notes(result, sink, cfg, stats, getattr(summary, "monitor_counters", {}))
    return result


def worst_state(result: dict) -> str:
    """The worst alarm state a file reached: 'alarm', 'caution' or 'nominal'."""
    states = {a["state"] for a in result.get("alarms", [])}
    return "alarm" if "alarm" in states else "caution" if "caution" in states else "nominal"


__all__ = ["audit_file", "AuditSink", "worst_state", "required_rates_hz", "MavnavError"]
