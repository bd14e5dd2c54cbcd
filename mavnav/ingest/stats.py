"""What one source saw: counts, rates, gaps, reboots, the vehicle, the choices made."""

from __future__ import annotations

from collections import Counter
from dataclasses import asdict, dataclass, field
from typing import Dict, List, Optional


@dataclass
class VehicleInfo:
    sysid: int
    compid: Optional[int] = None
    mav_type: Optional[int] = None
    autopilot: Optional[int] = None


@dataclass
class GapRecord:
    kind: str
    t_us: int
    boot: int
    length_s: float


@dataclass
class ReferenceRecord:
    value: float  # Pa (baro) or m (gnss)
    origin: str  # "config", "home", "startup"
    alt_ref_msl_m: Optional[float]


@dataclass
class IngestStats:
    """Filled while a source is iterated; final once it is exhausted.

    ``samples``: yielded measurements per kind (``imu``, ``baro``, ``gnss``,
    ``range``, ``autopilot``); ``events``: yielded events per type;
    ``rejected``: refusals per kind (the ``Rejected.kind`` values);
    ``filtered``: messages that were fine but not usable (no fix, not
    downward, other baro instance...); ``messages`` and ``rates_hz``: per
    message type from the selected vehicle, rates over vehicle time;
    ``ignored_by_sysid``: frames from other systems (ground stations,
    other vehicles, radios). Counters grow while the source is iterated;
    ``messages``, ``rates_hz``, ``ignored_by_sysid``, ``frames`` and
    ``duration_s`` are filled when it ends (or a live source is closed).
    """

    source: str = ""
    samples: Counter = field(default_factory=Counter)
    events: Counter = field(default_factory=Counter)
    rejected: Counter = field(default_factory=Counter)
    filtered: Counter = field(default_factory=Counter)
    messages: Dict[str, int] = field(default_factory=dict)
    rates_hz: Dict[str, float] = field(default_factory=dict)
    ignored_by_sysid: Dict[int, int] = field(default_factory=dict)
    gaps: List[GapRecord] = field(default_factory=list)
    reboots: int = 0
    clock_steps: int = 0  # the vehicle clock stepped back (less than a reboot) and was kept on one timeline
    reference_moves: int = 0  # the autopilot's home moved and the reported heights followed it
    duration_s: float = 0.0
    vehicle: Optional[VehicleInfo] = None
    imu_source: Optional[str] = None
    range_source: Optional[str] = None
    autopilot_source: Optional[str] = None
    autopilot_reference: Optional[str] = None  # "gnss_reference", "autopilot_home", "ekf_origin"
    references: Dict[str, ReferenceRecord] = field(default_factory=dict)
    attitude_nearest: int = 0  # IMU samples that used the nearest attitude, not a bracketing pair
    frames: int = 0
    bytes_read: int = 0
    garbage_bytes: int = 0
    link_losses: int = 0
    seq_missing: int = 0  # live: frames the MAVLink sequence numbers say never arrived
    dropped_chunks: int = 0  # live: received chunks dropped because the consumer fell too far behind
    format: str = "tlog"  # "tlog", "live", "dataflash", "ulog"
    firmware: str = ""  # onboard logs: e.g. "ArduCopter V4.1.3", "PX4 v1.14.0"
    vehicle_kind: str = ""  # onboard logs: "copter", "plane", "rover", "sub", ...
    not_applicable: str = ""  # why height integrity does not apply to this vehicle (vehicle_class), "" if it does
    damage: List[str] = field(default_factory=list)  # onboard logs: what could not be read, in words
    missing: List[str] = field(default_factory=list)  # onboard logs: sensors the log lacks

    def to_dict(self) -> dict:
        """Plain JSON-ready dict (string keys, no dataclasses)."""
        d = asdict(self)
        for k in ("samples", "events", "rejected", "filtered"):
            d[k] = dict(sorted(getattr(self, k).items()))
        d["ignored_by_sysid"] = {str(k): v for k, v in sorted(self.ignored_by_sysid.items())}
        return d
