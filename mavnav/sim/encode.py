"""MAVLink encoding of simulated sensor streams into tlog bytes (pymavlink's encoder).

Every record is written through ``pymavlink.dialects.v20.ardupilotmega.MAVLink``
into a file-like sink that prefixes the 8-byte big-endian receive time in
microseconds. Conversions to wire units live here and only here: milli-g,
mrad/s and milligauss (RAW_IMU, SCALED_IMU*), hPa and centi-degC
(SCALED_PRESSURE), mm, degE7, cm/s, cdeg (GPS_RAW_INT, GLOBAL_POSITION_INT),
cm (DISTANCE_SENSOR), m (RANGEFINDER, LOCAL_POSITION_NED).
"""

from __future__ import annotations

import math
import struct
from typing import Callable, Dict, List

import numpy as np
from pymavlink.dialects.v20 import ardupilotmega as mav2

from ..constants import G0_MPS2
from .scenario import MESSAGE_TYPES, LandingTrajectory, Scenario


# HEARTBEAT fields of a real autopilot (MAV_TYPE_QUADROTOR = 2)
_HB = {
    # MAV_AUTOPILOT_PX4 = 12; base_mode CUSTOM|AUTO|GUIDED|STABILIZE|ARMED; custom_mode main<<16|sub<<24
    "px4": dict(autopilot=12, base_mode=1 | 4 | 8 | 16 | 128, land=(4 << 16) | (6 << 24), hold=(4 << 16) | (3 << 24)),
    # MAV_AUTOPILOT_ARDUPILOTMEGA = 3; base_mode CUSTOM|GUIDED|STABILIZE|MANUAL_INPUT|ARMED; LAND=9, GUIDED=4
    "ardupilot": dict(autopilot=3, base_mode=1 | 8 | 16 | 64 | 128, land=9, hold=4),
}


class TlogSink:
    """File-like sink for ``MAVLink.send``: each write becomes one tlog record."""

    __slots__ = ("parts", "recv_us")

    def __init__(self) -> None:
        self.parts: List[bytes] = []
        self.recv_us = 0

    def write(self, buf: bytes) -> None:
        self.parts.append(struct.pack(">Q", self.recv_us))
        self.parts.append(bytes(buf))

    def getvalue(self) -> bytes:
        return b"".join(self.parts)


def _i16(a) -> List[int]:
    return np.clip(np.round(a), -32768, 32767).astype(np.int64).tolist()


def _deg_e7(a) -> List[int]:
    return np.round(np.asarray(a) * 1e7).astype(np.int64).tolist()


def _u16(a) -> List[int]:
    return np.clip(np.round(a), 0, 65535).astype(np.int64).tolist()


def _latlon_fn(scn: Scenario):
    lat0, lon0 = scn.home.lat_deg, scn.home.lon_deg
    r_earth = 6378137.0

    def latlon(n, e):
        lat = lat0 + np.degrees(np.asarray(n) / r_earth)
        lon = lon0 + np.degrees(np.asarray(e) / (r_earth * math.cos(math.radians(lat0))))
        return _deg_e7(lat), _deg_e7(lon)

    return latlon


def _enc_heartbeat(scn, s):
    hb = _HB[scn.profile]
    custom = hb["land"] if isinstance(scn.trajectory, LandingTrajectory) else hb["hold"]
    # MAV_TYPE_QUADROTOR = 2, MAV_STATE_ACTIVE = 4, mavlink_version = 3
    return lambda i, ms, us, ux: mav2.MAVLink_heartbeat_message(2, hb["autopilot"], hb["base_mode"], custom, 4, 3)


def _enc_system_time(scn, s):
    return lambda i, ms, us, ux: mav2.MAVLink_system_time_message(ux, ms)


def _enc_home_position(scn, s):
    hlat, hlon = _latlon_fn(scn)([0.0], [0.0])
    halt = int(round(scn.home.alt_msl_m * 1000))  # mm MSL
    return lambda i, ms, us, ux: mav2.MAVLink_home_position_message(
        hlat[0], hlon[0], halt, 0.0, 0.0, 0.0, (1.0, 0.0, 0.0, 0.0), 0.0, 0.0, 0.0, us)


def _enc_highres_imu(scn, s):
    f = s["f_b"].tolist()  # m/s^2 FRD
    w = s["gyro"].tolist()  # rad/s
    m = s["mag_gauss"].tolist()
    p = (s["pressure_pa"] / 100.0).tolist()  # hPa
    palt = s["pressure_alt_m"].tolist()
    temp = s["temperature_c"].tolist()
    upd = s["fields_updated"].tolist()
    return lambda i, ms, us, ux: mav2.MAVLink_highres_imu_message(
        us, f[i][0], f[i][1], f[i][2], w[i][0], w[i][1], w[i][2], m[i][0], m[i][1], m[i][2],
        p[i], 0.0, palt[i], temp[i], upd[i], 0)


def _int_imu(s):
    fa = _i16(s["f_b"] / G0_MPS2 * 1000.0)  # milli-g
    wa = _i16(s["gyro"] * 1000.0)  # mrad/s
    ma = _i16(s["mag_gauss"] * 1000.0)  # mgauss
    tc = int(round(s["temperature_c"] * 100))  # cdegC
    return fa, wa, ma, tc


def _enc_raw_imu(scn, s):
    fa, wa, ma, tc = _int_imu(s)
    return lambda i, ms, us, ux: mav2.MAVLink_raw_imu_message(us, *fa[i], *wa[i], *ma[i], 0, tc)


def _enc_scaled_imu(scn, s):
    fa, wa, ma, tc = _int_imu(s)
    return lambda i, ms, us, ux: mav2.MAVLink_scaled_imu_message(ms, *fa[i], *wa[i], *ma[i], tc)


def _enc_scaled_imu2(scn, s):
    fa, wa, ma, tc = _int_imu(s)
    return lambda i, ms, us, ux: mav2.MAVLink_scaled_imu2_message(ms, *fa[i], *wa[i], *ma[i], tc)


def _enc_attitude(scn, s):
    e = s["euler"].tolist()
    r = s["rates"].tolist()
    return lambda i, ms, us, ux: mav2.MAVLink_attitude_message(ms, *e[i], *r[i])


def _enc_attitude_quaternion(scn, s):
    q = s["quat"].tolist()
    r = s["rates"].tolist()
    return lambda i, ms, us, ux: mav2.MAVLink_attitude_quaternion_message(ms, *q[i], *r[i], (0.0, 0.0, 0.0, 0.0))


def _enc_scaled_pressure(scn, s):
    p = (s["pressure_pa"] / 100.0).tolist()  # hPa
    tc = _i16(s["temperature_c"] * 100.0)  # cdegC
    return lambda i, ms, us, ux: mav2.MAVLink_scaled_pressure_message(ms, p[i], 0.0, tc[i], 0)


def _enc_gps_raw_int(scn, s):
    lat, lon = _latlon_fn(scn)(s["pos_n_m"], s["pos_e_m"])
    alt = np.round(s["alt_msl_m"] * 1000).astype(np.int64).tolist()  # mm MSL
    alt_e = np.round((s["alt_msl_m"] + scn.sensors.gnss.geoid_separation_m) * 1000).astype(np.int64).tolist()
    fix, sats = s["fix_type"].tolist(), s["satellites"].tolist()
    eph, epv = s["eph"].tolist(), s["epv"].tolist()
    vel = _u16(s["ground_speed_mps"] * 100)  # cm/s
    cog = _u16(s["cog_deg"] * 100)  # cdeg
    h_acc, v_acc = s["h_acc_mm"].tolist(), s["v_acc_mm"].tolist()
    unix = scn.sensors.gnss.time_base == "unix"
    return lambda i, ms, us, ux: mav2.MAVLink_gps_raw_int_message(
        ux if unix else us, fix[i], lat[i], lon[i], alt[i], eph[i], epv[i], vel[i], cog[i], sats[i],
        alt_e[i], h_acc[i], v_acc[i], 300, 0, 0)


def _enc_distance_sensor(scn, s):
    rf = scn.sensors.rangefinder
    dmin, dmax = int(round(rf.min_m * 100)), int(round(rf.max_m * 100))  # cm
    cur = _u16(s["range_m"] * 100)
    q = s["quality"].tolist()
    cov = 0 if scn.profile == "ardupilot" else min(254, int(round((rf.sigma_m * 100) ** 2)))  # cm^2
    # type 0 = MAV_DISTANCE_SENSOR_LASER, orientation 25 = MAV_SENSOR_ROTATION_PITCH_270 (down)
    return lambda i, ms, us, ux: mav2.MAVLink_distance_sensor_message(
        ms, dmin, dmax, cur[i], 0, 0, 25, cov, 0.05, 0.05, (0.0, 0.0, 0.0, 0.0), q[i])


def _enc_rangefinder(scn, s):
    d = s["range_m"].tolist()  # m
    return lambda i, ms, us, ux: mav2.MAVLink_rangefinder_message(d[i], 0.0)


def _enc_global_position_int(scn, s):
    lat, lon = _latlon_fn(scn)(s["pos_n_m"], s["pos_e_m"])
    alt = np.round((scn.home.alt_msl_m + s["height_m"]) * 1000).astype(np.int64).tolist()  # mm MSL
    rel = np.round(s["height_m"] * 1000).astype(np.int64).tolist()  # mm above home
    vn, ve = _i16(s["vel_n_mps"] * 100), _i16(s["vel_e_mps"] * 100)  # cm/s NED
    vd = _i16(-s["vel_up_mps"] * 100)
    hdg = (np.round(np.degrees(s["yaw_rad"]) * 100).astype(np.int64) % 36000).tolist()
    return lambda i, ms, us, ux: mav2.MAVLink_global_position_int_message(
        ms, lat[i], lon[i], alt[i], rel[i], vn[i], ve[i], vd[i], hdg[i])


def _enc_local_position_ned(scn, s):
    n, e, d = s["pos_n_m"].tolist(), s["pos_e_m"].tolist(), (-s["height_m"]).tolist()
    vn, ve, vd = s["vel_n_mps"].tolist(), s["vel_e_mps"].tolist(), (-s["vel_up_mps"]).tolist()
    return lambda i, ms, us, ux: mav2.MAVLink_local_position_ned_message(ms, n[i], e[i], d[i], vn[i], ve[i], vd[i])


_FACTORIES = {
    "HEARTBEAT": _enc_heartbeat,
    "SYSTEM_TIME": _enc_system_time,
    "HOME_POSITION": _enc_home_position,
    "HIGHRES_IMU": _enc_highres_imu,
    "RAW_IMU": _enc_raw_imu,
    "SCALED_IMU": _enc_scaled_imu,
    "SCALED_IMU2": _enc_scaled_imu2,
    "ATTITUDE": _enc_attitude,
    "ATTITUDE_QUATERNION": _enc_attitude_quaternion,
    "SCALED_PRESSURE": _enc_scaled_pressure,
    "GPS_RAW_INT": _enc_gps_raw_int,
    "DISTANCE_SENSOR": _enc_distance_sensor,
    "RANGEFINDER": _enc_rangefinder,
    "GLOBAL_POSITION_INT": _enc_global_position_int,
    "LOCAL_POSITION_NED": _enc_local_position_ned,
}


def build_encoders(scn: Scenario, streams: Dict[str, dict]) -> Dict[str, Callable]:
    """For each message type, ``f(i, time_boot_ms, time_us, t_unix_us) -> MAVLink message``."""
    return {name: _FACTORIES[name](scn, s) for name, s in streams.items()}


def encode_tlog(scn: Scenario, streams: Dict[str, dict], order_type: np.ndarray, order_index: np.ndarray) -> bytes:
    """Encode the records ``(type index into MESSAGE_TYPES, index in stream)`` in order.

    Each stream carries ``t_sim``, ``t_vehicle_s``, ``recv_unix_us`` and ``seq``.
    """
    encoders = build_encoders(scn, streams)
    names = list(MESSAGE_TYPES)
    sink = TlogSink()
    mav = mav2.MAVLink(sink, srcSystem=scn.link.sysid, srcComponent=scn.link.compid)
    start_us = int(round(scn.link.start_unix_s * 1e6))
    per_type = {}
    for name, s in streams.items():
        tv = s["t_vehicle_s"]
        per_type[name] = (
            encoders[name],
            np.floor(tv * 1000.0 + 1e-6).astype(np.int64).tolist(),
            np.floor(tv * 1e6 + 1e-3).astype(np.int64).tolist(),
            (start_us + np.floor(s["t_sim"] * 1e6)).astype(np.int64).tolist(),
            s["recv_unix_us"].tolist(),
            s["seq"].tolist(),
        )
    for ti, i in zip(order_type.tolist(), order_index.tolist()):
        fn, ms, us, ux, rv, sq = per_type[names[ti]]
        msg = fn(i, ms[i], us[i], ux[i])
        sink.recv_us = rv[i]
        mav.seq = sq[i]
        mav.send(msg)
    return sink.getvalue()
