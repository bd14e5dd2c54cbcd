"""Helpers for the ingest tests (no tests here): synthetic flights encoded by pymavlink."""

from __future__ import annotations

import math
from pathlib import Path
from typing import List, Tuple

from mavnav.atmosphere import pressure_at_height_pa
from mavnav.config import IngestConfig
from mavnav.constants import G0_MPS2
from mavnav.ingest import TlogSource
from tests.support.tlog_writer import TlogWriter

UNIX0 = 1_700_000_000.0
P_GROUND_PA = 100_000.0
MAV_AUTOPILOT_PX4 = 12
MAV_AUTOPILOT_ARDUPILOTMEGA = 3


class FlightLog:
    """A vehicle's telemetry as a tlog; ``t`` is seconds of log, vehicle boot time
    is ``boot0_s + t`` and receive time ``UNIX0 + t + latency_s``."""

    def __init__(self, path: Path, sysid: int = 1, compid: int = 1, mavlink1: bool = False,
                 autopilot: int = MAV_AUTOPILOT_PX4, boot0_s: float = 5.0):
        self.path = Path(path)
        self.w = TlogWriter(self.path, sysid, compid, mavlink1)
        self.mavlink1 = mavlink1
        self.mav = self.w.mav
        self.autopilot = autopilot
        self.boot0_s = boot0_s
        self.latency_s = 0.005

    # clocks
    def recv(self, t):
        return UNIX0 + t + self.latency_s

    def ms(self, t):
        return int(round((t + self.boot0_s) * 1000))

    def us(self, t):
        return int(round((t + self.boot0_s) * 1e6))

    def put(self, msg, t, **kw):
        return self.w.write(msg, self.recv(t), **kw)

    # messages
    def heartbeat(self, t, mav_type=2, autopilot=None, **kw):
        ap = self.autopilot if autopilot is None else autopilot
        return self.put(self.mav.heartbeat_encode(mav_type, ap, 0, 0, 4, 3), t, **kw)

    def attitude(self, t, roll=0.0, pitch=0.0, yaw=0.0, **kw):
        return self.put(self.mav.attitude_encode(self.ms(t), roll, pitch, yaw, 0, 0, 0), t, **kw)

    def attitude_q(self, t, q, **kw):
        return self.put(self.mav.attitude_quaternion_encode(self.ms(t), *q, 0, 0, 0), t, **kw)

    def highres(self, t, f_b=(0.0, 0.0, -G0_MPS2), updated=0b111, t_us=None, **kw):
        tu = self.us(t) if t_us is None else t_us
        return self.put(self.mav.highres_imu_encode(tu, *f_b, 0, 0, 0, 0, 0, 0, 1000.0, 0, 0, 20.0, updated), t, **kw)

    def scaled_imu(self, t, mg=(0, 0, -1000), which="scaled_imu", **kw):
        enc = getattr(self.mav, which + "_encode")
        return self.put(enc(self.ms(t), *mg, 0, 0, 0, 0, 0, 0), t, **kw)

    def raw_imu(self, t, mg=(0, 0, -1000), **kw):
        return self.put(self.mav.raw_imu_encode(self.us(t), *mg, 0, 0, 0, 0, 0, 0), t, **kw)

    def pressure(self, t, p_pa, instance=1, t_ms=None, **kw):
        enc = {1: self.mav.scaled_pressure_encode, 2: self.mav.scaled_pressure2_encode,
               3: self.mav.scaled_pressure3_encode}[instance]
        return self.put(enc(self.ms(t) if t_ms is None else t_ms, p_pa / 100.0, 0.0, 2000), t, **kw)

    def gps(self, t, alt_m, fix=3, v_acc_mm=0, alt_ell_m=None, time_usec=None, **kw):
        tu = self.us(t) if time_usec is None else time_usec
        ell = 0 if alt_ell_m is None else int(round(alt_ell_m * 1000))
        base = (tu, fix, 473977000, 85455000, int(round(alt_m * 1000)), 80, 120, 0, 0, 12)
        if self.mavlink1:  # MAVLink 1 frames carry no extension fields
            msg = self.mav.gps_raw_int_encode(*base)
        else:
            msg = self.mav.gps_raw_int_encode(*base, ell, 500, v_acc_mm)
        return self.put(msg, t, **kw)

    def dist(self, t, range_m, orientation=25, quality=0, min_cm=20, max_cm=4000, **kw):
        base = (self.ms(t), min_cm, max_cm, int(round(range_m * 100)), 0, 0, orientation, 255)
        if self.mavlink1:
            msg = self.mav.distance_sensor_encode(*base)
        else:
            msg = self.mav.distance_sensor_encode(*base, signal_quality=quality)
        return self.put(msg, t, **kw)

    def rangefinder(self, t, d_m, **kw):
        return self.put(self.mav.rangefinder_encode(d_m, 0.0), t, **kw)

    def home(self, t, alt_m, **kw):
        return self.put(self.mav.home_position_encode(473977000, 85455000, int(round(alt_m * 1000)),
                                                      0, 0, 0, [1, 0, 0, 0], 0, 0, 0), t, **kw)

    def gpi(self, t, alt_m, rel_m, **kw):
        return self.put(self.mav.global_position_int_encode(self.ms(t), 473977000, 85455000,
                                                            int(round(alt_m * 1000)), int(round(rel_m * 1000)),
                                                            0, 0, 0, 0), t, **kw)

    def lpn(self, t, z_m, **kw):
        return self.put(self.mav.local_position_ned_encode(self.ms(t), 0, 0, z_m, 0, 0, 0), t, **kw)

    def system_time(self, t, unix_us, **kw):
        return self.put(self.mav.system_time_encode(unix_us, self.ms(t)), t, **kw)

    def fly(self, t0, t1, *, height_fn=lambda t: 0.0, ground_msl_m=500.0, imu_hz=100, att_hz=50, baro_hz=20,
            gps_hz=5, range_hz=10, hb_hz=1, roll=0.0, pitch=0.0, imu="highres", gps_fix=3,
            imu_follows_height=False):
        """Regular streams from ``t0`` to ``t1`` (vehicle time base 100 Hz tick).
        ``imu_follows_height``: the (level) HIGHRES_IMU carries the vertical
        acceleration of ``height_fn`` (its second difference at the IMU tick), so
        the INS agrees with the baro; otherwise it reads 1 g still."""
        k0, k1 = int(round(t0 * 100)), int(round(t1 * 100))
        for k in range(k0, k1):
            t = k / 100.0
            h = height_fn(t)
            if hb_hz and k % int(100 / hb_hz) == 0:
                self.heartbeat(t)
            if att_hz and k % int(100 / att_hz) == 0:
                self.attitude(t, roll, pitch, 0.1)
            if imu_hz and k % int(100 / imu_hz) == 0:
                if imu == "highres" and imu_follows_height:
                    d = 1.0 / imu_hz
                    acc = (height_fn(t + d) - 2.0 * h + height_fn(t - d)) / (d * d)
                    self.highres(t, f_b=(0.0, 0.0, -G0_MPS2 - acc))
                elif imu == "highres":
                    self.highres(t)
                elif imu == "raw":
                    self.raw_imu(t)
                else:
                    self.scaled_imu(t, which=imu)
            if baro_hz and k % int(100 / baro_hz) == 0:
                self.pressure(t, pressure_at_height_pa(h, P_GROUND_PA))
            if gps_hz and k % int(100 / gps_hz) == 0:
                self.gps(t, ground_msl_m + h, fix=gps_fix, v_acc_mm=700)
            if range_hz and k % int(100 / range_hz) == 0:
                self.dist(t, max(0.3, h) / (math.cos(roll) * math.cos(pitch)))
        return self

    def close(self):
        self.w.close()
        return self.path


def collect(path, sysid=None, **cfg) -> Tuple[List[object], object]:
    src = TlogSource(path, IngestConfig(**cfg), sysid=sysid)
    items = list(src)
    return items, src.stats


def of(items, cls) -> list:
    return [s for s in items if isinstance(s, cls)]


def rejected(items, kind=None) -> list:
    from mavnav.samples import Rejected
    return [s for s in items if isinstance(s, Rejected) and (kind is None or s.kind == kind)]
