"""What the monitor reports: one :class:`EpochReport` per filter epoch, and an
:class:`AlarmEvent` at every change of a source's state.

These are the only types sinks (CSV, Rerun, MAVLink out, audit) consume. Times
are vehicle time: ``t_us`` integer microseconds, ``t_s`` the same in seconds
(as in the messages' own time fields; it restarts at a reboot, ``boot``
counts them).

Sources of alarms: ``gnss``, ``rangefinder``, ``baro_ins`` (the barometer or
the INS: the reference channel), and ``input`` (the telemetry itself: too slow
for the time-to-alarm, gaps, link loss). States, from best to worst:
``nominal``, ``caution``, ``unavailable``, ``alarm``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from itertools import combinations
from typing import Literal, Optional

from .fastinit import fast_frozen_init
from .sensors import CHANNELS, SOURCES, Sensor  # noqa: F401 (SOURCES: re-exported)

State = Literal["nominal", "caution", "unavailable", "alarm"]
STATES: tuple[State, ...] = ("nominal", "caution", "unavailable", "alarm")

Source = Sensor  # one of SOURCES (mavnav.sensors): gnss, rangefinder, baro_ins, input

# Channel names, in the bank's order, and the source each one's aux sensor is.
CHANNEL_NAMES = CHANNELS
# the channel pairs, in the bank's order (bank.PAIRS), by the channels' short names
PAIR_NAMES = tuple(f"{a.short}-{b.short}" for a, b in combinations(CHANNELS, 2))  # gnss-rng, gnss-baro, rng-baro

NAN = math.nan


@dataclass(frozen=True, slots=True)
class ChannelReport:
    name: str  # "gnss" | "rangefinder" | "baro"
    height_ref_m: float
    sigma_height_m: float
    vel_up_mps: float
    baro_bias_m: float
    acc_bias_mps2: float
    available: bool  # recent data and a usable covariance
    used: bool  # part of the fused output this epoch
    nis: float  # r^T S^-1 r of this epoch's rows (0 with no rows)
    dof: int
    norm_innov_baro: float  # baro row innovation / its sigma (NaN if unused)
    norm_innov_aux: float  # GNSS / rangefinder row innovation / its sigma (NaN if unused)


@dataclass(frozen=True, slots=True)
class PairReport:
    name: str  # "gnss-rng" | "gnss-baro" | "rng-baro"
    diff_m: float  # H_a - H_b
    threshold_m: float
    exceeded: bool
    valid: bool  # both channels available


@dataclass(frozen=True, slots=True)
class SourceStatus:
    state: State
    since_t_s: float  # vehicle time the state began
    reason: str
    window_stat: float = NAN  # sliding-window sum of squared normalised innovations
    window_low: float = NAN
    window_high: float = NAN
    rejected: int = 0  # samples rejected by the gate in the window


@dataclass(frozen=True, slots=True)
class EpochReport:
    t_us: int
    boot: int
    height_fused_m: float  # NaN when no channel is usable
    sigma_fused_m: float
    channels: tuple[ChannelReport, ...]  # in CHANNEL_NAMES order
    pairs: tuple[PairReport, ...]  # in PAIR_NAMES order
    sources: dict  # Source -> SourceStatus
    overall: State
    vpl_m: float
    alert_limit_m: float
    # Latest raw heights known at this epoch (NaN if none yet)
    baro_height_ref_m: float = NAN
    gnss_height_ref_m: float = NAN
    range_height_agl_m: float = NAN
    autopilot_height_ref_m: float = NAN
    mode: str = "adaptive"

    @property
    def t_s(self) -> float:
        return self.t_us * 1e-6

    def ok(self, source: str) -> bool:
        """Whether a source is usable (nominal or caution)."""
        return self.sources[source].state in ("nominal", "caution")


@dataclass(frozen=True, slots=True)
class AlarmEvent:
    t_us: int
    boot: int
    source: Source
    state: State  # the new state
    previous: State
    reason: str

    @property
    def t_s(self) -> float:
        return self.t_us * 1e-6


# built per epoch: the cheaper __init__ of mavnav.fastinit (same fields, same defaults)
fast_frozen_init(ChannelReport, PairReport, SourceStatus, EpochReport, AlarmEvent)


@dataclass
class RunSummary:
    """Filled by the pipeline while it runs; final when it returns."""

    epochs: int = 0
    alarms: list = field(default_factory=list)  # AlarmEvent
    sink_failures: dict = field(default_factory=dict)  # sink name -> error text
    first_t_us: Optional[int] = None
    last_t_us: Optional[int] = None
    reboots: int = 0
    # (boot, first t_us, last t_us) of the epochs of each boot: vehicle time restarts at a reboot,
    # so first_t_us..last_t_us alone is no time span once there was one
    spans: list = field(default_factory=list)
