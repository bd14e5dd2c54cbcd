"""Fault definitions shared by the simulator and the injector.

A fault is a :class:`~mavnav.sim.scenario.Fault`: a kind, an onset in vehicle
time, an optional duration (none: to the end of the log) and a magnitude
whose unit depends on the kind (:data:`FAULT_MAGNITUDE`). Each kind names the
source it affects: ``gnss``, ``rangefinder``, ``baro_ins`` (barometer or
accelerometer) or ``input`` (message rates, link, reboots).

The command-line form (``mavnav inject``) is ``KIND:key=value,key=value``,
e.g. ``gnss_step:onset=60,duration=20,magnitude=10``; see :func:`parse_fault`.
"""

from __future__ import annotations

import json
import math
from typing import List, Sequence

import numpy as np
from pydantic import ValidationError

from ..errors import ConfigError
from .scenario import FAULT_MAGNITUDE, FAULT_SOURCE, Fault, _describe

_KEY_ALIASES = {
    "onset": "onset_s",
    "onset_s": "onset_s",
    "duration": "duration_s",
    "duration_s": "duration_s",
    "magnitude": "magnitude",
    "probability": "probability",
    "mode": "mode",
    "messages": "messages",
    "seed": "seed",
    "boot": "boot",
}

FAULT_SYNTAX_HELP = (
    "FAULT is KIND:key=value,... with keys onset (s, vehicle time), duration (s; "
    "omit for 'to the end'), magnitude, and for some kinds probability, mode, "
    "messages (A|B), seed, boot (0 = first boot)."
)


def parse_fault(spec: str) -> Fault:
    """Parse ``KIND:key=value,...`` into a validated :class:`Fault` (ConfigError if bad)."""
    kind, sep, rest = spec.partition(":")
    kind = kind.strip()
    if kind not in FAULT_SOURCE:
        raise ConfigError(f"fault '{spec}': unknown kind '{kind}' (known: {', '.join(FAULT_SOURCE)})")
    data: dict = {"kind": kind}
    for item in filter(None, (p.strip() for p in rest.split(","))) if sep else ():
        key, eq, value = item.partition("=")
        key = key.strip()
        if not eq:
            raise ConfigError(f"fault '{spec}': '{item}' is not key=value")
        if key not in _KEY_ALIASES:
            raise ConfigError(f"fault '{spec}': unknown key '{key}'")
        name = _KEY_ALIASES[key]
        if name in data:
            raise ConfigError(f"fault '{spec}': key '{key}' given twice")
        value = value.strip()
        data[name] = tuple(v for v in value.split("|") if v) if name == "messages" else value
    if "onset_s" not in data:
        raise ConfigError(f"fault '{spec}': missing key 'onset'")
    try:
        return Fault.model_validate(data)
    except ValidationError as exc:
        raise ConfigError(f"fault '{spec}': {_describe(exc.errors()[0])}") from None


def parse_faults(specs) -> List[Fault]:
    """Fault specs (strings) or :class:`Fault` objects -> validated faults."""
    return [f if isinstance(f, Fault) else parse_fault(f) for f in specs]


def window_mask(fault: Fault, t_s: np.ndarray) -> np.ndarray:
    """True where ``onset <= t < end`` (times on the fault's clock)."""
    t_s = np.asarray(t_s, dtype=float)
    return (t_s >= fault.onset_s) & (t_s < fault.end_s)


def additive_offset(fault: Fault, t_s: np.ndarray) -> np.ndarray:
    """Offset of a step or ramp fault (metres or m/s^2), 0 outside its window."""
    from .effects import height_error_m

    t_s = np.asarray(t_s, dtype=float)
    inside = window_mask(fault, t_s)
    return np.where(inside, height_error_m(fault, t_s), 0.0)


def describe_fault(fault: Fault) -> dict:
    """A JSON-ready description of a fault (``end_s`` None when open-ended)."""
    end = fault.end_s
    return {
        "kind": fault.kind,
        "source": fault.source,
        "onset_s": fault.onset_s,
        "end_s": None if math.isinf(end) else end,
        "duration_s": fault.duration_s,
        "magnitude": fault.magnitude,
        "magnitude_meaning": FAULT_MAGNITUDE[fault.kind],
        "mode": fault.effective_mode,
        "probability": fault.effective_probability if fault.kind == "rng_spikes" else None,
        "messages": list(fault.messages) if fault.messages else None,
    }


def active_labels(faults: Sequence[Fault], t_s: np.ndarray):
    """Per time: (active 0/1, '+'-joined kinds, '+'-joined sources)."""
    t_s = np.asarray(t_s, dtype=float)
    masks = [window_mask(f, t_s) for f in faults]
    active = np.zeros(t_s.shape, dtype=np.int8)
    kinds: List[str] = []
    sources: List[str] = []
    for i in range(t_s.size):
        ks: List[str] = []
        ss: List[str] = []
        for f, m in zip(faults, masks):
            if m[i]:
                ks.append(f.kind)
                if f.source not in ss:
                    ss.append(f.source)
        active[i] = 1 if ks else 0
        kinds.append("+".join(ks))
        sources.append("+".join(ss))
    return active, kinds, sources


def write_sidecar(path, payload: dict) -> None:
    with open(path, "w", encoding="utf-8") as fh:
        json.dump(payload, fh, indent=2, sort_keys=False, default=_json_default)
        fh.write("\n")


def _json_default(o):
    if isinstance(o, (np.integer,)):
        return int(o)
    if isinstance(o, (np.floating,)):
        return float(o)
    raise TypeError(type(o))


def sidecar_path(tlog_path) -> str:
    """``OUT.tlog`` -> ``OUT.faults.json`` (beside the output)."""
    s = str(tlog_path)
    return (s[: -len(".tlog")] if s.endswith(".tlog") else s) + ".faults.json"


__all__ = [
    "FAULT_SYNTAX_HELP",
    "parse_fault",
    "parse_faults",
    "window_mask",
    "additive_offset",
    "describe_fault",
    "active_labels",
    "write_sidecar",
    "sidecar_path",
]
