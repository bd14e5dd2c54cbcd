"""Normalised samples: what the ingestion layer hands to the estimator.

Every sample is in SI units, heights positive up with the datum in the name,
and carries two clocks: ``t_us`` (vehicle time, integer microseconds since
the vehicle's boot, from the message's own time field) and ``recv_s`` (Unix
seconds when the ground side received it: the tlog record time, or the wall
clock on a live link). ``boot`` counts reboots seen on this link (0 for the
first boot); vehicle time restarts at each one.

MAVLink field names never appear past this module's producers (the
normaliser); consumers see only these types. Sensors are named by
:mod:`mavnav.sensors`: the stream kinds below (``Gap.kind``,
``Rejected.sensor``) are a :class:`~mavnav.sensors.Sensor`'s ``stream``
spelling (``imu``, ``baro``, ``gnss``, ``range``, ``autopilot``).

Event types (``Reboot``, ``Gap``, ``LinkLost``, ``LinkRecovered``,
``Rejected``, ``ReferenceSet``, ``ReferenceMoved``, ``Notice``) travel in the same stream as the samples so
that one ordered fold sees everything.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal, Optional, Union

from .fastinit import fast_frozen_init

# --------------------------------------------------------------------------
# Measurements


@dataclass(frozen=True, slots=True)
class SpecificForceUp:
    """Vertical specific force from the IMU, rotated to the local vertical.

    ``f_up_mps2 = -(R_nb f_b)_down``: about +9.81 at rest.
    """

    t_us: int
    recv_s: float
    boot: int
    f_up_mps2: float
    source: str  # e.g. "HIGHRES_IMU", "SCALED_IMU2", "RAW_IMU"


@dataclass(frozen=True, slots=True)
class BaroHeight:
    """Barometric height above the reference, from static pressure (ISA)."""

    t_us: int
    recv_s: float
    boot: int
    height_ref_m: float
    pressure_pa: float
    instance: int  # 1, 2, 3 for SCALED_PRESSURE, _2, _3


@dataclass(frozen=True, slots=True)
class GnssHeight:
    """GNSS height above the reference (3D fix or better only)."""

    t_us: int
    recv_s: float
    boot: int
    height_ref_m: float
    alt_m: float  # the receiver's altitude in the configured datum (MSL or ellipsoid)
    sigma_m: Optional[float]  # 1-sigma vertical accuracy (v_acc) when reported, else None
    fix_type: int
    satellites: int
    # the receiver's Doppler vertical velocity (m/s, up), None when not reported:
    # independent of its position solution's slow errors (MAVLink's GPS_RAW_INT
    # has none; onboard logs do: ArduPilot GPS.VZ, PX4 vel_d_m_s)
    vel_up_mps: Optional[float] = None


@dataclass(frozen=True, slots=True)
class RangeHeight:
    """Downward rangefinder: tilt-corrected height above ground."""

    t_us: int
    recv_s: float
    boot: int
    height_agl_m: float
    range_m: float  # raw slant range along the sensor axis
    source: str  # "DISTANCE_SENSOR", "RANGEFINDER", or the onboard log's message ("RFND[0]", "distance_sensor")
    min_m: float = float("nan")  # the sensor's valid range as the reading reports it (NaN: unknown)
    max_m: float = float("nan")


@dataclass(frozen=True, slots=True)
class AutopilotHeight:
    """The autopilot's own height estimate, for comparison only (never fused)."""

    t_us: int
    recv_s: float
    boot: int
    height_ref_m: float
    source: str  # "GLOBAL_POSITION_INT" or "LOCAL_POSITION_NED"
    vel_up_mps: float = float("nan")  # its vertical velocity estimate, up (NaN: not reported)


# --------------------------------------------------------------------------
# Events


@dataclass(frozen=True, slots=True)
class ReferenceSet:
    """A height reference was fixed (or changed)."""

    t_us: int
    recv_s: float
    boot: int
    kind: Literal["baro", "gnss"]
    value: float  # baro: reference pressure in Pa; gnss: reference altitude in m
    alt_ref_msl_m: Optional[float]  # the reference point's altitude MSL when known
    # config: configured; home: HOME_POSITION; autopilot_home: the home in GLOBAL_POSITION_INT
    # (alt - relative_alt); ekf_origin: GPS_GLOBAL_ORIGIN with LOCAL_POSITION_NED; startup:
    # the first samples' mean (nothing from the autopilot in time)
    origin: Literal["config", "home", "autopilot_home", "ekf_origin", "startup"]
    # The vehicle was at the reference point when a baro reference was taken
    # (the autopilot's height above it within ``at_datum_max_m``, or an onboard
    # log's start on the ground): the reference ties the baro to the datum
    # within the baro's own noise. False: taken in flight, or not known.
    at_datum: bool = False


@dataclass(frozen=True, slots=True)
class ReferenceMoved:
    """The autopilot's home moved (a new home set at arming, another altitude): heights are
    reported above the new point from here on.

    The references of :class:`ReferenceSet` stay where they were fixed, so the
    filters see no step (a step in every height would be a fault to them); the
    pipeline reports heights ``offset_m`` lower than the filters have them.
    """

    t_us: int  # vehicle time of the message that moved it
    recv_s: float
    boot: int
    alt_ref_msl_m: float  # the new reference point's altitude MSL
    shift_m: float  # how far it moved (up positive) from the previous point
    offset_m: float  # the new point's altitude above the point the references were fixed at
    origin: Literal["home", "autopilot_home"]  # HOME_POSITION, or GLOBAL_POSITION_INT's alt - relative_alt


@dataclass(frozen=True, slots=True)
class Reboot:
    """Vehicle time jumped back: the vehicle rebooted. The pipeline restarts."""

    t_us: int  # first vehicle time after the reboot
    recv_s: float
    boot: int  # the new boot index
    last_t_us: int  # last vehicle time before it


@dataclass(frozen=True, slots=True)
class Gap:
    """A stream of one kind was silent for longer than expected."""

    t_us: int  # vehicle time of the first sample after the gap
    recv_s: float
    boot: int
    kind: str  # the stream that was silent: a Sensor's stream kind ("imu", "baro", "gnss", "range", ...)
    length_s: float


@dataclass(frozen=True, slots=True)
class LinkLost:
    """No message from the vehicle for the configured timeout (receive clock)."""

    recv_s: float
    silent_s: float


@dataclass(frozen=True, slots=True)
class LinkRecovered:
    recv_s: float
    outage_s: float


@dataclass(frozen=True, slots=True)
class Rejected:
    """A message or sample that was refused, with why. Never fed to filters."""

    recv_s: float
    kind: str  # counter key, e.g. "crc", "nan", "out_of_range", "duplicate"
    detail: str
    t_us: Optional[int] = None
    boot: Optional[int] = None
    sensor: Optional[str] = None  # the stream kind refused (Sensor.stream: "range", "imu", ...) when it was one
    # the refused reading and the sensor's valid range, where there is one (NaN: not known)
    value_m: float = float("nan")
    min_m: float = float("nan")
    max_m: float = float("nan")
    # a refused rangefinder reading's tilt, as the cosine of the sensor axis to
    # the vertical (NaN: no attitude then): a slant range at the maximum is a
    # vertical height below it
    cos_tilt: float = float("nan")


@dataclass(frozen=True, slots=True)
class Notice:
    """Something the operator should be told about the input, in words: what the
    source waits for, the vehicle chosen and the systems ignored. Not a
    measurement and not a state change; sinks that speak to a person show it."""

    recv_s: float
    kind: str  # "waiting_reference", "waiting_heartbeat", "vehicle", "ignored", "stale"
    text: str


Measurement = Union[SpecificForceUp, BaroHeight, GnssHeight, RangeHeight, AutopilotHeight]
Event = Union[ReferenceSet, ReferenceMoved, Reboot, Gap, LinkLost, LinkRecovered, Rejected, Notice]
Sample = Union[Measurement, Event]

# built per sample: the cheaper __init__ of mavnav.fastinit (same fields, same defaults)
fast_frozen_init(SpecificForceUp, BaroHeight, GnssHeight, RangeHeight, AutopilotHeight, Rejected)
