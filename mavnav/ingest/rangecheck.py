"""The downward rangefinder's checks, each its own small piece (the rules are
in the normaliser's docstring, "Rangefinder"):

* :func:`decode_reading`: one message's reading in metres with the valid
  range it holds (DISTANCE_SENSOR in cm with its own limits, ``max_distance``
  0 meaning unknown; RANGEFINDER in m with the configured ones), or why it
  is refused: ``invalid_quality``, ``nan``, ``impossible``, ``out_of_range``;
* :class:`CrossCheck`: where both messages come from one sensor, a reading
  of one that disagrees with the other's recent one (``disagrees``);
* :class:`StuckCheck`: the same raw value for ``rangefinder_stuck_s`` while
  the baro moved (``stuck``).

:class:`RangeChecks` runs them in that order and returns the
:class:`RangeReading` or the first :class:`Refusal`. The checks keep their
state (the other message's latest reading, the current run of one value)
and emit nothing; the normaliser turns a refusal into a
:class:`~mavnav.samples.Rejected`, then applies the stream discipline and
the tilt correction (which need its clock and attitude).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple, Optional, Union

from ..atmosphere import height_from_pressure_m
from ..config import IngestConfig
from .decoders import Refusal

DISTANCE_SENSOR_QUALITY_INVALID = 1
_OTHER = {"DISTANCE_SENSOR": "RANGEFINDER", "RANGEFINDER": "DISTANCE_SENSOR"}


class RangeReading(NamedTuple):
    """A reading that passed the checks so far."""

    name: str  # DISTANCE_SENSOR or RANGEFINDER
    raw: object  # the value as sent (cm or m): the stuck test compares it
    range_m: float  # slant range along the sensor axis
    lo_m: float  # the valid range of the reading
    hi_m: float


def decode_reading(name: str, f: dict, min_m: float, max_m: float) -> Union[RangeReading, Refusal]:
    """The reading of one DISTANCE_SENSOR or RANGEFINDER message (``f``: its fields);
    ``min_m``/``max_m``: the configured limits (a RANGEFINDER's, and a
    DISTANCE_SENSOR's maximum when it says 0)."""
    if name == "DISTANCE_SENSOR":
        raw = f["current_distance"]
        range_m = raw / 100.0  # cm
        lo_m = f["min_distance"] / 100.0
        hi_m = f["max_distance"] / 100.0 if f["max_distance"] > 0 else max_m
        if f["signal_quality"] == DISTANCE_SENSOR_QUALITY_INVALID:
            return Refusal("invalid_quality", f"{name} signal_quality 1 (invalid)")
    else:
        raw = f["distance"]
        range_m = raw  # m
        lo_m, hi_m = min_m, max_m
        if not math.isfinite(range_m):
            return Refusal("nan", f"{name} with a non-finite distance")
        if range_m < 0:
            return Refusal("impossible", f"{name} negative distance {range_m:.3g} m")
    if not lo_m <= range_m <= hi_m:
        return Refusal("out_of_range", f"{name} {range_m:.3f} m outside [{lo_m:g}, {hi_m:g}] m", range_m, lo_m, hi_m)
    return RangeReading(name, raw, range_m, lo_m, hi_m)


class _Latest(NamedTuple):
    recv_s: float
    range_m: float


class CrossCheck:
    """ArduPilot often sends DISTANCE_SENSOR and RANGEFINDER for one sensor: a
    reading of the chosen message is compared with the other's latest, when
    that was received within ``max_age_s``; apart by more than ``max(tol_m,
    tol_frac x the larger)``, it is refused."""

    def __init__(self, max_age_s: float, tol_m: float, tol_frac: float):
        self.max_age_s, self.tol_m, self.tol_frac = max_age_s, tol_m, tol_frac
        self.latest: dict[str, _Latest] = {}  # by message name

    def note(self, name: str, f: dict, recv_s: float) -> None:
        """Every message of either kind as it arrives (chosen or not): its latest valid reading."""
        if name == "DISTANCE_SENSOR":
            if f["signal_quality"] != DISTANCE_SENSOR_QUALITY_INVALID:
                self.latest[name] = _Latest(recv_s, f["current_distance"] / 100.0)
        elif math.isfinite(f["distance"]):
            self.latest[name] = _Latest(recv_s, f["distance"])

    def check(self, r: RangeReading, recv_s: float) -> Optional[Refusal]:
        other_name = _OTHER[r.name]
        other = self.latest.get(other_name)
        if other is None or not abs(recv_s - other.recv_s) <= self.max_age_s:
            return None
        tol = max(self.tol_m, self.tol_frac * max(r.range_m, other.range_m))
        if not abs(r.range_m - other.range_m) > tol:
            return None
        return Refusal("disagrees", f"{r.name} {r.range_m:.2f} m but the same rangefinder's {other_name} "
                                    f"{other.range_m:.2f} m", r.range_m, r.lo_m, r.hi_m)


@dataclass
class _Run:
    """One raw value repeated since ``t_start_us`` (boot ``boot``), with the
    lowest and highest pressure seen meanwhile."""

    raw: object
    t_start_us: int
    p_min: Optional[float]
    p_max: Optional[float]
    boot: int


class StuckCheck:
    """The same raw reading for ``stuck_s`` while the baro moved at least
    ``min_move_m``: the run's later readings are stuck until the value changes
    (the first ``stuck_s`` of a run cannot be told from a steady hover)."""

    def __init__(self, stuck_s: float, min_move_m: float):
        self.stuck_s, self.min_move_m = stuck_s, min_move_m
        self._stuck_us = int(stuck_s * 1e6)
        self.run: Optional[_Run] = None
        self.last_pressure_pa: Optional[float] = None

    def pressure(self, p_pa: float) -> None:
        """Every baro pressure placed on the vehicle clock."""
        self.last_pressure_pa = p_pa
        run = self.run
        if run is not None:
            run.p_min = p_pa if run.p_min is None else min(run.p_min, p_pa)
            run.p_max = p_pa if run.p_max is None else max(run.p_max, p_pa)

    def reset(self) -> None:
        """A reboot: no run goes on across it."""
        self.run = None

    def stuck(self, raw, t_us: int, boot: int) -> bool:
        run = self.run
        p = self.last_pressure_pa
        if run is None or run.raw != raw or run.boot != boot or t_us < run.t_start_us:
            self.run = _Run(raw, t_us, p, p, boot)
            return False
        if t_us - run.t_start_us < self._stuck_us or run.p_min is None:
            return False
        moved_m = height_from_pressure_m(run.p_min, run.p_max)  # p_min above p_max
        return moved_m >= self.min_move_m


class RangeChecks:
    """The checks in order: the reading, the cross-check, stuck."""

    def __init__(self, cfg: IngestConfig):
        self.min_m, self.max_m = cfg.rangefinder_min_m, cfg.rangefinder_max_m
        self.cross = CrossCheck(cfg.range_cross_max_age_s, cfg.range_cross_tol_m, cfg.range_cross_tol_frac)
        self.stuck = StuckCheck(cfg.rangefinder_stuck_s, cfg.rangefinder_stuck_min_move_m)

    def check(self, name: str, f: dict, recv_s: float, t_us: int, boot: int) -> Union[RangeReading, Refusal]:
        r = decode_reading(name, f, self.min_m, self.max_m)
        if type(r) is Refusal:
            return r
        refusal = self.cross.check(r, recv_s)
        if refusal is not None:
            return refusal
        if self.stuck.stuck(r.raw, t_us, boot):
            return Refusal("stuck", f"{name} reads {r.range_m:.3f} m for {self.stuck.stuck_s} s while the baro moved",
                           r.range_m, r.lo_m, r.hi_m)
        return r
