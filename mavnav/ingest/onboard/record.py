"""What an onboard log holds for mavnav, as columns: the decoders' common output.

A decoder (:mod:`.dataflash` for ArduPilot DataFlash, :mod:`.ulog` for PX4
ULog) reads one file into an :class:`OnboardRecord`: one time-sorted series
per sensor, in SI units, on the log's own boot clock (``t_us``, integer
microseconds), with the autopilot's height estimate and its datums beside
them. It decides nothing about references, validity windows or filtering:
that is :class:`~mavnav.ingest.onboard.source.OnboardSource`'s job, shared by
both formats. Columns are numpy arrays of one length per series; a missing
value is NaN (floats) and a missing sensor is ``None``.

Conventions (those of :mod:`mavnav.frames`): body FRD, navigation NED,
quaternions (w, x, y, z) rotating body to NED; heights positive up.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Dict, List, Optional

import numpy as np


@dataclass
class ImuSeries:
    """Accelerometer specific force in body FRD axes (m/s^2, about -9.81 on z at rest)."""

    name: str  # the message or topic it came from, e.g. "IMU", "IMU2", "sensor_combined"
    t_us: np.ndarray
    fx_mps2: np.ndarray
    fy_mps2: np.ndarray
    fz_mps2: np.ndarray


@dataclass
class AttitudeSeries:
    """Vehicle attitude, body to NED, as unit quaternions (columns w, x, y, z)."""

    name: str  # "ATT", "AHR2", "vehicle_attitude", ...
    t_us: np.ndarray
    q: np.ndarray  # shape (n, 4)


@dataclass
class BaroSeries:
    """Static pressure of the barometer the autopilot uses (its primary)."""

    name: str  # "BARO[0]", "vehicle_air_data", ...
    t_us: np.ndarray
    pressure_pa: np.ndarray
    instance: int = 0  # 0-based instance of the chosen barometer
    instances: int = 1  # barometers the log holds


@dataclass
class GnssSeries:
    """GNSS altitude above mean sea level (m) with the receiver's reported accuracy."""

    name: str  # "GPS[0]", "vehicle_gps_position", "sensor_gps"
    t_us: np.ndarray
    alt_msl_m: np.ndarray
    sigma_m: np.ndarray  # 1-sigma vertical accuracy (GPA.VAcc, epv); NaN when not reported
    fix_type: np.ndarray  # MAVLink GPS_FIX_TYPE numbering: 3 = 3D fix, 4+ = DGPS/RTK
    satellites: np.ndarray
    vel_up_mps: Optional[np.ndarray] = None  # Doppler vertical velocity, up (NaN: not reported)


@dataclass
class RangeSeries:
    """Downward rangefinder readings (already restricted to downward-facing sensors)."""

    name: str  # "RFND[0]", "distance_sensor", ...
    t_us: np.ndarray
    range_m: np.ndarray  # slant range along the sensor axis, as reported (0 is a reading too)
    min_m: np.ndarray  # the sensor's minimum range, NaN when the log does not say
    max_m: np.ndarray  # the sensor's maximum range, NaN when the log does not say
    valid: np.ndarray  # bool: the autopilot/driver reported the reading good (status, quality)


@dataclass
class AutopilotSeries:
    """The autopilot's own height estimate, for comparison only (never fused)."""

    name: str  # "XKF1", "NKF1", "EKF1", "CTUN", "vehicle_local_position"
    t_us: np.ndarray
    height_up_m: np.ndarray  # up, above ``datum``
    datum: str  # "ekf_origin" (EKF position, add origin_alt_msl_m for MSL) or "home"
    vel_up_mps: Optional[np.ndarray] = None  # its vertical velocity, up (NaN where not logged)


@dataclass
class OnboardRecord:
    """One onboard log, decoded. ``damage`` lists what could not be read, in words."""

    path: str
    format: str  # "dataflash" or "ulog"
    firmware: str = ""  # e.g. "ArduCopter V4.1.3", "PX4 v1.14.0"
    vehicle: str = ""  # "copter", "plane", "rover", "sub", "boat", "" when unknown
    imu: Optional[ImuSeries] = None
    attitude: Optional[AttitudeSeries] = None
    baro: Optional[BaroSeries] = None
    gnss: Optional[GnssSeries] = None
    rangefinder: Optional[RangeSeries] = None
    autopilot: Optional[AutopilotSeries] = None
    home_alt_msl_m: Optional[float] = None  # the autopilot's home altitude (MSL), when logged
    origin_alt_msl_m: Optional[float] = None  # the EKF origin's altitude (MSL), when logged
    messages: Dict[str, int] = field(default_factory=dict)  # records per message type / topic
    damage: List[str] = field(default_factory=list)  # truncation, corruption, unreadable parts
    bytes_read: int = 0

    def missing(self) -> List[str]:
        """Sensors the estimator can use that this log lacks, in words."""
        out = []
        for key, what in (("imu", "IMU"), ("attitude", "attitude"), ("baro", "barometer"),
                          ("gnss", "GNSS altitude"), ("rangefinder", "downward rangefinder"),
                          ("autopilot", "autopilot height estimate")):
            s = getattr(self, key)
            if s is None or len(s.t_us) == 0:
                out.append(what)
        return out

