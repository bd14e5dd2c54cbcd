"""Per-message decoders: one MAVLink message's fields -> a reading in SI units, or why not.

Each decoder is a pure function of the message's fields (the dict of
:func:`.wire.make_decoder`) and of the settings passed in: no clock, no
reference, no state. It returns one of

* a reading, with the message's own time field still raw (the normaliser
  places it on the vehicle clock):

  - :class:`BaroReading`: SCALED_PRESSURE, SCALED_PRESSURE2, SCALED_PRESSURE3;
  - :class:`GnssReading`: GPS_RAW_INT;
  - :class:`ImuReading`: HIGHRES_IMU, RAW_IMU, SCALED_IMU, SCALED_IMU2, SCALED_IMU3;
  - :class:`AttitudeReading` (a unit quaternion): ATTITUDE, ATTITUDE_QUATERNION;
  - :class:`GlobalPositionReading`: GLOBAL_POSITION_INT (its MSL and home
    altitudes ``None`` where the message cannot give them);
  - :class:`LocalPositionReading`: LOCAL_POSITION_NED;
  - :class:`DatumReading`: HOME_POSITION, GPS_GLOBAL_ORIGIN (never refused:
    their altitude is an integer of mm);

* a :class:`Refusal`: the message carries a reading but it is unusable; the
  normaliser turns it into a :class:`~mavnav.samples.Rejected` of that
  ``kind`` and ``detail``;
* a :class:`Skipped`: the message carries no reading of this kind (no fix, no
  new accelerometer sample, raw sensor counts); not an error, counted in
  ``stats.filtered[counter]``.

What the rules are, and why, is in the :mod:`.normaliser` module docstring;
the rangefinder's decoder is :func:`.rangecheck.decode_reading`. The
normaliser keeps the clock, the references (with :mod:`.heightref`), the
source choice and the stream discipline: which datum the autopilot's heights
are taken in, and whether a home moved, are decided there, not here.

The IMU's hot path (HIGHRES_IMU, every frame of a PX4 log) does the same
arithmetic inline in :meth:`.normaliser.Normaliser._highres_imu`;
``tests/test_ingest_decoders.py`` checks the two agree. ATTITUDE (50 Hz
against HIGHRES_IMU's 200 Hz in ``bench/audit.py``'s log) calls its decoder:
about 0.25 us more per message than the arithmetic inline, 0.4 % of that
log's ingest.
"""
from __future__ import annotations

import math
from typing import NamedTuple, Optional, Union

from ..constants import G0_MPS2
from ..frames import quat_from_euler
from .systems import MAV_AUTOPILOT_ARDUPILOTMEGA

MILLI_G_MPS2 = G0_MPS2 / 1000.0
MAX_SPECIFIC_FORCE_MPS2 = 50 * G0_MPS2  # beyond any airframe IMU range
MAX_PRESSURE_PA = 2.0e7  # 200 bar: deeper than any ROV depth sensor reads
UINT32_MAX = 0xFFFFFFFF
HIGHRES_IMU_ACCEL_BITS = 0b111  # fields_updated: xacc, yacc, zacc


class Refusal(NamedTuple):
    """Why a reading is refused: a ``Rejected`` kind, in words, and the reading
    and its valid range where known (NaN otherwise)."""

    kind: str
    detail: str
    value_m: float = math.nan
    min_m: float = math.nan
    max_m: float = math.nan


class Skipped(NamedTuple):
    """The message carries no reading of its kind: counted as ``stats.filtered[counter]``."""

    counter: str


GNSS_NO_FIX = Skipped("gnss_no_fix")
GNSS_NO_ELLIPSOID_ALT = Skipped("gnss_no_ellipsoid_alt")
IMU_ACCEL_NOT_UPDATED = Skipped("imu_accel_not_updated")
RAW_IMU_NOT_ARDUPILOT = Skipped("raw_imu_not_ardupilot")

# ------------------------------------------------------------------ barometer


class BaroReading(NamedTuple):
    """SCALED_PRESSURE(2/3): the static pressure and the message's boot time."""

    p_pa: float
    t_boot_us: int  # time_boot_ms in us, on the sender's boot clock


def decode_pressure(f: dict) -> Union[BaroReading, Refusal]:
    """SCALED_PRESSURE, SCALED_PRESSURE2 or SCALED_PRESSURE3 (the same fields)."""
    p_pa = f["press_abs"] * 100.0  # hPa -> Pa
    if not math.isfinite(p_pa):
        return Refusal("nan", "SCALED_PRESSURE with a non-finite pressure")
    if not 0.0 < p_pa < MAX_PRESSURE_PA:
        return Refusal("impossible", f"static pressure {p_pa:.6g} Pa")
    return BaroReading(p_pa, f["time_boot_ms"] * 1000)


# ------------------------------------------------------------------ GNSS


class GnssReading(NamedTuple):
    """GPS_RAW_INT with a fix: the altitude in the configured datum."""

    alt_m: float  # MSL or above the WGS84 ellipsoid (ingest.gnss_altitude)
    sigma_m: Optional[float]  # v_acc, None when unknown
    fix: int
    sats: int
    time_usec: int  # 0: not filled (placed by receive time)
    geoid_sep_m: Optional[float]  # alt_ellipsoid - alt, None without alt_ellipsoid


def decode_gps_raw_int(f: dict, min_fix_type: int, altitude: str) -> Union[GnssReading, Skipped]:
    """``min_fix_type``: ``ingest.min_fix_type``; ``altitude``: ``ingest.gnss_altitude``
    (``"msl"`` or ``"ellipsoid"``)."""
    fix = f["fix_type"]
    if fix < min_fix_type:
        return GNSS_NO_FIX
    alt_ell = f["alt_ellipsoid"]
    geoid_sep_m = (alt_ell - f["alt"]) / 1000.0 if alt_ell != 0 else None
    if altitude == "msl":
        alt_m = f["alt"] / 1000.0  # mm MSL
    else:
        if alt_ell == 0:
            return GNSS_NO_ELLIPSOID_ALT
        alt_m = alt_ell / 1000.0  # mm above WGS84
    v_acc = f["v_acc"]
    sigma_m = v_acc / 1000.0 if 0 < v_acc < UINT32_MAX else None  # mm, 0 = unknown
    return GnssReading(alt_m, sigma_m, fix, f["satellites_visible"], f["time_usec"], geoid_sep_m)


# ------------------------------------------------------------------ IMU


class ImuReading(NamedTuple):
    """An accelerometer sample: specific force in the body frame and the message's time."""

    name: str  # the message it came in
    fb: tuple  # specific force, body FRD, m/s^2
    t_raw: int  # time_usec (usec True) or time_boot_ms in us (usec False)
    usec: bool  # t_raw is a time_usec (placed through that stream's offset)


def _checked(name: str, fb: tuple, t_raw: int, usec: bool) -> Union[ImuReading, Refusal]:
    x, y, z = fb
    if not (math.isfinite(x) and math.isfinite(y) and math.isfinite(z)):
        return Refusal("nan", f"{name} with a non-finite acceleration")
    if max(abs(x), abs(y), abs(z)) > MAX_SPECIFIC_FORCE_MPS2:
        return Refusal("impossible", f"{name} acceleration beyond 50 g")
    return ImuReading(name, fb, t_raw, usec)


def decode_highres_imu(f: dict) -> Union[ImuReading, Refusal, Skipped]:
    """HIGHRES_IMU, m/s^2; with ``fields_updated`` set but no accelerometer bit it
    is not a new accelerometer sample (0: the sender does not say, taken as new)."""
    upd = f["fields_updated"]
    if upd and not (upd & HIGHRES_IMU_ACCEL_BITS):
        return IMU_ACCEL_NOT_UPDATED
    return _checked("HIGHRES_IMU", (f["xacc"], f["yacc"], f["zacc"]), f["time_usec"], True)


def decode_raw_imu(f: dict, autopilot: Optional[int]) -> Union[ImuReading, Refusal, Skipped]:
    """RAW_IMU: milli-g on ArduPilot (``autopilot``: the vehicle heartbeat's), raw
    sensor counts elsewhere (skipped)."""
    if autopilot != MAV_AUTOPILOT_ARDUPILOTMEGA:
        return RAW_IMU_NOT_ARDUPILOT
    fb = (f["xacc"] * MILLI_G_MPS2, f["yacc"] * MILLI_G_MPS2, f["zacc"] * MILLI_G_MPS2)  # milli-g
    return _checked("RAW_IMU", fb, f["time_usec"], True)


def decode_scaled_imu(name: str, f: dict) -> Union[ImuReading, Refusal]:
    """SCALED_IMU, SCALED_IMU2 or SCALED_IMU3 (``name``): milli-g, boot time in ms."""
    fb = (f["xacc"] * MILLI_G_MPS2, f["yacc"] * MILLI_G_MPS2, f["zacc"] * MILLI_G_MPS2)  # milli-g
    return _checked(name, fb, f["time_boot_ms"] * 1000, False)


# ------------------------------------------------------------------ attitude


class AttitudeReading(NamedTuple):
    """ATTITUDE or ATTITUDE_QUATERNION: the attitude and the message's boot time."""

    q: tuple  # unit quaternion (w, x, y, z), body FRD -> NED
    t_boot_us: int  # time_boot_ms in us, on the sender's boot clock


def decode_attitude(f: dict) -> Union[AttitudeReading, Refusal]:
    """ATTITUDE: Euler angles in rad (roll, pitch, yaw) -> a quaternion."""
    roll, pitch, yaw = f["roll"], f["pitch"], f["yaw"]
    if not (math.isfinite(roll) and math.isfinite(pitch) and math.isfinite(yaw)):
        return Refusal("nan", "ATTITUDE with a non-finite angle")
    return AttitudeReading(quat_from_euler(roll, pitch, yaw), f["time_boot_ms"] * 1000)


def decode_attitude_quaternion(f: dict) -> Union[AttitudeReading, Refusal]:
    """ATTITUDE_QUATERNION: (q1..q4) = (w, x, y, z), normalised; a norm outside
    (0.5, 2) is no attitude."""
    q = (f["q1"], f["q2"], f["q3"], f["q4"])
    for c in q:
        if not math.isfinite(c):
            return Refusal("nan", "ATTITUDE_QUATERNION with a non-finite component")
    n = math.sqrt(sum(c * c for c in q))
    if not 0.5 < n < 2.0:
        return Refusal("impossible", f"ATTITUDE_QUATERNION norm {n:.3g}")
    return AttitudeReading(tuple(c / n for c in q), f["time_boot_ms"] * 1000)


# ------------------------------------------------------------------ the autopilot's own position and datums

HOME_UNSET_MM = 50  # GLOBAL_POSITION_INT alt - relative_alt below this: ArduPilot's home not yet set


class GlobalPositionReading(NamedTuple):
    """GLOBAL_POSITION_INT: the autopilot's altitudes and vertical speed, and the message's boot time."""

    alt_msl_m: Optional[float]  # alt, None without a position (lat = lon = 0)
    rel_m: float  # relative_alt: above the autopilot's home
    vel_up: float  # -vz, m/s
    home_msl_m: Optional[float]  # alt - relative_alt, None without a position or with home not set
    t_boot_us: int  # time_boot_ms in us, on the sender's boot clock


def decode_global_position_int(f: dict) -> GlobalPositionReading:
    """GLOBAL_POSITION_INT: mm and cm/s (integers: always finite). Without a
    position ArduPilot sends lat = lon = 0 and in ``alt`` 0 or its uncorrected
    baro altitude; before home is set old ArduPilot reports ``relative_alt ==
    alt`` (home at 0): the home altitude is then unknown."""
    alt, rel = f["alt"], f["relative_alt"]
    has_position = f["lat"] != 0 or f["lon"] != 0
    home_msl_m = (alt - rel) / 1000.0 if has_position and abs(alt - rel) >= HOME_UNSET_MM else None
    return GlobalPositionReading(alt / 1000.0 if has_position else None, rel / 1000.0, -f["vz"] / 100.0,
                                 home_msl_m, f["time_boot_ms"] * 1000)


class LocalPositionReading(NamedTuple):
    """LOCAL_POSITION_NED: the height above the EKF origin and the message's boot time."""

    up_m: float  # -z
    vel_up: float  # -vz, m/s; NaN when not finite
    t_boot_us: int  # time_boot_ms in us, on the sender's boot clock


def decode_local_position_ned(f: dict) -> Union[LocalPositionReading, Refusal]:
    """LOCAL_POSITION_NED: z and vz down, m and m/s; a non-finite z is refused,
    a non-finite vz is an unknown vertical speed (NaN)."""
    z, vz = f["z"], f["vz"]
    if not math.isfinite(z):
        return Refusal("nan", "LOCAL_POSITION_NED with a non-finite z")
    return LocalPositionReading(-z, -vz if math.isfinite(vz) else math.nan, f["time_boot_ms"] * 1000)


class DatumReading(NamedTuple):
    """HOME_POSITION (the autopilot's home) or GPS_GLOBAL_ORIGIN (its EKF origin): the point's altitude."""

    alt_msl_m: float
    time_usec: int  # the message's time_usec (an extension: 0 when not sent); not used by the normaliser


def decode_home_position(f: dict) -> DatumReading:
    """HOME_POSITION: altitude in mm MSL (an integer: always finite)."""
    return DatumReading(f["altitude"] / 1000.0, f["time_usec"])


def decode_gps_global_origin(f: dict) -> DatumReading:
    """GPS_GLOBAL_ORIGIN: altitude in mm MSL (an integer: always finite)."""
    return DatumReading(f["altitude"] / 1000.0, f["time_usec"])
