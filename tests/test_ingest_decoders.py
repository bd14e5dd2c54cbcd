"""The per-message decoders on their own (mavnav.ingest.decoders), on messages
encoded by pymavlink and decoded back (pymavlink's CRC-checked parse, then the
normaliser's own payload decoder), and the HIGHRES_IMU hot path of the
normaliser against its decoder."""

from __future__ import annotations

import math
import struct
from pathlib import Path

import pytest
from pymavlink.dialects.v20 import ardupilotmega as dialect

from mavnav.config import IngestConfig
from mavnav.constants import G0_MPS2
from mavnav.ingest import TlogSource, wire
from mavnav.frames import down_row_from_euler, down_row_from_quat
from mavnav.ingest.decoders import (
    GNSS_NO_ELLIPSOID_ALT,
    GNSS_NO_FIX,
    IMU_ACCEL_NOT_UPDATED,
    RAW_IMU_NOT_ARDUPILOT,
    HOME_UNSET_MM,
    AttitudeReading,
    BaroReading,
    DatumReading,
    GlobalPositionReading,
    GnssReading,
    ImuReading,
    LocalPositionReading,
    Refusal,
    Skipped,
    decode_attitude,
    decode_attitude_quaternion,
    decode_global_position_int,
    decode_gps_global_origin,
    decode_gps_raw_int,
    decode_highres_imu,
    decode_home_position,
    decode_local_position_ned,
    decode_pressure,
    decode_raw_imu,
    decode_scaled_imu,
)
from mavnav.ingest.normaliser import Normaliser
from tests.support.flightlog import MAV_AUTOPILOT_ARDUPILOTMEGA, MAV_AUTOPILOT_PX4, FlightLog

MAV = dialect.MAVLink(None, srcSystem=1, srcComponent=1)
MG = G0_MPS2 / 1000.0


def fields(msg) -> dict:
    """``msg`` packed into a MAVLink 2 frame, parsed back by pymavlink (CRC checked),
    and its payload decoded as the normaliser decodes it."""
    frame = bytes(msg.pack(MAV))
    back = MAV.decode(bytearray(frame))
    assert back.get_type() == msg.get_type()
    f = wire.make_decoder(back.get_msgId())(frame[10:10 + frame[1]])
    for name in back.get_fieldnames():  # the two decodes agree
        a, b = getattr(back, name), f[name]
        if isinstance(a, list):  # an array field: a list from pymavlink, a tuple from the wire decoder
            a = tuple(a)
        assert a == b or (isinstance(a, float) and math.isnan(a) and math.isnan(b)), name
    return f


# ------------------------------------------------------------------ barometer


def _pressure(hpa, t_ms=12_345, which="scaled_pressure"):
    return fields(getattr(MAV, which + "_encode")(t_ms, hpa, 0.0, 2500))


@pytest.mark.parametrize("which", ["scaled_pressure", "scaled_pressure2", "scaled_pressure3"])
def test_pressure_reading_in_pa_with_its_boot_time(which):
    r = decode_pressure(_pressure(1013.25, 12_345, which))
    assert type(r) is BaroReading
    assert r.p_pa == pytest.approx(101325.0, abs=0.01)  # float32 hPa
    assert r.t_boot_us == 12_345_000 and type(r.t_boot_us) is int


@pytest.mark.parametrize("hpa", [math.nan, math.inf, -math.inf])
def test_pressure_not_finite_is_nan(hpa):
    # the text names SCALED_PRESSURE for every instance, as it always has
    for which in ("scaled_pressure", "scaled_pressure3"):
        assert decode_pressure(_pressure(hpa, which=which)) == Refusal("nan", "SCALED_PRESSURE with a non-finite pressure")


@pytest.mark.parametrize("hpa,text", [(0.0, "static pressure 0 Pa"), (-5.0, "static pressure -500 Pa"),
                                      (200_000.0, "static pressure 2e+07 Pa"),
                                      (250_000.0, "static pressure 2.5e+07 Pa")])
def test_pressure_impossible(hpa, text):
    assert decode_pressure(_pressure(hpa)) == Refusal("impossible", text)


def test_pressure_limits_are_exclusive_below_200_bar():
    assert type(decode_pressure(_pressure(199_990.0))) is BaroReading  # an ROV's depth sensor, deep
    assert type(decode_pressure(_pressure(0.01))) is BaroReading


# ------------------------------------------------------------------ GNSS


def _gps(fix=3, alt_mm=488_123, alt_ell_mm=536_123, v_acc=800, sats=12, time_usec=7_000_000):
    return fields(MAV.gps_raw_int_encode(time_usec, fix, 473977000, 85455000, alt_mm, 80, 120, 0, 0, sats,
                                         alt_ell_mm, 500, v_acc, 0, 0, 0))


def test_gnss_reading_msl():
    r = decode_gps_raw_int(_gps(), 3, "msl")
    assert r == GnssReading(488.123, 0.8, 3, 12, 7_000_000, 48.0)


def test_gnss_reading_ellipsoid():
    r = decode_gps_raw_int(_gps(fix=6), 3, "ellipsoid")
    assert r == GnssReading(536.123, 0.8, 6, 12, 7_000_000, 48.0)


def test_gnss_without_alt_ellipsoid():
    r = decode_gps_raw_int(_gps(alt_ell_mm=0), 3, "msl")
    assert type(r) is GnssReading and r.alt_m == 488.123 and r.geoid_sep_m is None  # no separation seen
    assert decode_gps_raw_int(_gps(alt_ell_mm=0), 3, "ellipsoid") is GNSS_NO_ELLIPSOID_ALT
    assert GNSS_NO_ELLIPSOID_ALT == Skipped("gnss_no_ellipsoid_alt")


@pytest.mark.parametrize("fix,min_fix", [(0, 3), (1, 3), (2, 3), (3, 4), (5, 6)])
def test_gnss_no_fix(fix, min_fix):
    for datum in ("msl", "ellipsoid"):
        assert decode_gps_raw_int(_gps(fix=fix), min_fix, datum) is GNSS_NO_FIX
    assert GNSS_NO_FIX == Skipped("gnss_no_fix")
    assert type(decode_gps_raw_int(_gps(fix=min_fix), min_fix, "msl")) is GnssReading


@pytest.mark.parametrize("v_acc,sigma", [(0, None), (0xFFFFFFFF, None), (1, 0.001), (2500, 2.5)])
def test_gnss_v_acc(v_acc, sigma):
    assert decode_gps_raw_int(_gps(v_acc=v_acc), 3, "msl").sigma_m == sigma


def test_gnss_time_usec_unfilled_is_kept_as_zero():
    assert decode_gps_raw_int(_gps(time_usec=0), 3, "msl").time_usec == 0


# ------------------------------------------------------------------ IMU


def _highres(acc=(0.1, -0.2, -9.8), updated=0b111, t_us=9_000_000):
    return fields(MAV.highres_imu_encode(t_us, *acc, 0, 0, 0, 0, 0, 0, 1000.0, 0, 0, 20.0, updated))


@pytest.mark.parametrize("updated", [0, 0b1, 0b111, 0xFFFF])
def test_highres_imu_reading_in_mps2(updated):
    r = decode_highres_imu(_highres(updated=updated))
    assert type(r) is ImuReading and (r.name, r.t_raw, r.usec) == ("HIGHRES_IMU", 9_000_000, True)
    assert r.fb == pytest.approx((0.1, -0.2, -9.8), abs=1e-6)


@pytest.mark.parametrize("updated", [0b1000, 0b111000, 0b1000000000000])
def test_highres_imu_without_an_accelerometer_bit_is_skipped(updated):
    assert decode_highres_imu(_highres(updated=updated)) is IMU_ACCEL_NOT_UPDATED
    assert IMU_ACCEL_NOT_UPDATED == Skipped("imu_accel_not_updated")


@pytest.mark.parametrize("acc", [(math.nan, 0, 0), (0, math.inf, 0), (0, 0, -math.inf)])
def test_highres_imu_not_finite(acc):
    assert decode_highres_imu(_highres(acc)) == Refusal("nan", "HIGHRES_IMU with a non-finite acceleration")


@pytest.mark.parametrize("acc", [(491.0, 0, 0), (0, -600.0, 0), (0, 0, 1e6)])
def test_highres_imu_beyond_50_g(acc):
    assert decode_highres_imu(_highres(acc)) == Refusal("impossible", "HIGHRES_IMU acceleration beyond 50 g")
    assert type(decode_highres_imu(_highres((490.0, -490.0, 0.0)))) is ImuReading


def test_raw_imu_is_milli_g_on_ardupilot_only():
    f = fields(MAV.raw_imu_encode(9_000_000, 1000, -500, -32768, 0, 0, 0, 0, 0, 0))
    r = decode_raw_imu(f, MAV_AUTOPILOT_ARDUPILOTMEGA)
    assert (r.name, r.t_raw, r.usec) == ("RAW_IMU", 9_000_000, True)
    assert r.fb == pytest.approx((G0_MPS2, -0.5 * G0_MPS2, -32.768 * G0_MPS2))  # int16: never beyond 50 g
    for other in (MAV_AUTOPILOT_PX4, 0, None):  # raw sensor counts, or no heartbeat yet
        assert decode_raw_imu(f, other) is RAW_IMU_NOT_ARDUPILOT
    assert RAW_IMU_NOT_ARDUPILOT == Skipped("raw_imu_not_ardupilot")


@pytest.mark.parametrize("which", ["SCALED_IMU", "SCALED_IMU2", "SCALED_IMU3"])
def test_scaled_imu_is_milli_g_with_its_boot_time(which):
    f = fields(getattr(MAV, which.lower() + "_encode")(4_321, 0, 250, -1000, 0, 0, 0, 0, 0, 0))
    r = decode_scaled_imu(which, f)
    assert type(r) is ImuReading and (r.name, r.t_raw, r.usec) == (which, 4_321_000, False)
    assert r.fb == pytest.approx((0.0, 0.25 * G0_MPS2, -G0_MPS2))
    assert r.fb[2] == -1000 * MG


# ------------------------------------------------------------------ attitude


def _attitude(roll, pitch, yaw, t_ms=4_321):
    return fields(MAV.attitude_encode(t_ms, roll, pitch, yaw, 0.01, 0.02, 0.03))


def _f32(x: float) -> float:
    """``x`` as it comes back from a float field of the wire."""
    return struct.unpack("<f", struct.pack("<f", x))[0]


def test_attitude_reading_is_a_unit_quaternion_with_its_boot_time():
    r = decode_attitude(_attitude(0.1, -0.05, 0.3))
    assert type(r) is AttitudeReading
    assert r.t_boot_us == 4_321_000 and type(r.t_boot_us) is int
    assert math.fsum(c * c for c in r.q) == pytest.approx(1.0, abs=1e-15)
    # the body's down axis the quaternion gives is the one roll and pitch give (yaw does not enter)
    assert down_row_from_quat(r.q) == pytest.approx(down_row_from_euler(_f32(0.1), _f32(-0.05)), abs=1e-12)
    # ZYX Euler angles: the half-angle products, w first
    cr, sr = math.cos(_f32(0.1) / 2), math.sin(_f32(0.1) / 2)
    cp, sp = math.cos(_f32(-0.05) / 2), math.sin(_f32(-0.05) / 2)
    cy, sy = math.cos(_f32(0.3) / 2), math.sin(_f32(0.3) / 2)
    assert r.q == pytest.approx((cr * cp * cy + sr * sp * sy, sr * cp * cy - cr * sp * sy,
                                 cr * sp * cy + sr * cp * sy, cr * cp * sy - sr * sp * cy), abs=1e-15)


@pytest.mark.parametrize("angles,q", [((0.0, 0.0, 0.0), (1.0, 0.0, 0.0, 0.0)),
                                      ((math.pi, 0.0, 0.0), (0.0, 1.0, 0.0, 0.0)),  # upside down
                                      ((0.0, math.pi / 2, 0.0), (math.sqrt(0.5), 0.0, math.sqrt(0.5), 0.0)),
                                      ((0.0, 0.0, -math.pi / 2), (math.sqrt(0.5), 0.0, 0.0, -math.sqrt(0.5)))])
def test_attitude_known_angles(angles, q):
    assert decode_attitude(_attitude(*angles)).q == pytest.approx(q, abs=1e-7)  # float32 angles


@pytest.mark.parametrize("angles", [(math.nan, 0.0, 0.0), (0.0, math.inf, 0.0), (0.0, 0.0, -math.inf),
                                    (math.nan, math.nan, math.nan)])
def test_attitude_not_finite(angles):
    assert decode_attitude(_attitude(*angles)) == Refusal("nan", "ATTITUDE with a non-finite angle")


def _quaternion(q, t_ms=4_321):
    return fields(MAV.attitude_quaternion_encode(t_ms, *q, 0.01, 0.02, 0.03, (0.0, 0.0, 0.0, 0.0)))


def test_attitude_quaternion_reading_is_normalised_with_its_boot_time():
    r = decode_attitude_quaternion(_quaternion((0.9, 0.1, -0.2, 0.3)))
    assert type(r) is AttitudeReading
    assert r.t_boot_us == 4_321_000 and type(r.t_boot_us) is int
    n = math.sqrt(0.9 ** 2 + 0.1 ** 2 + 0.2 ** 2 + 0.3 ** 2)
    assert r.q == pytest.approx((0.9 / n, 0.1 / n, -0.2 / n, 0.3 / n), abs=1e-7)
    assert math.fsum(c * c for c in r.q) == pytest.approx(1.0, abs=1e-15)


@pytest.mark.parametrize("q,unit", [((1.5, 0.0, 0.0, 0.0), (1.0, 0.0, 0.0, 0.0)),
                                    ((0.0, 0.0, 0.0, -0.6), (0.0, 0.0, 0.0, -1.0)),
                                    ((0.9, 0.9, 0.9, 0.9), (0.5, 0.5, 0.5, 0.5)),  # norm 1.8
                                    ((0.36, 0.0, 0.0, -0.36), (math.sqrt(0.5), 0.0, 0.0, -math.sqrt(0.5)))])  # norm 0.509
def test_attitude_quaternion_scaled_within_half_and_twice(q, unit):
    assert decode_attitude_quaternion(_quaternion(q)).q == pytest.approx(unit, abs=1e-7)


@pytest.mark.parametrize("q", [(math.nan, 0.0, 0.0, 1.0), (1.0, math.inf, 0.0, 0.0), (1.0, 0.0, -math.inf, 0.0),
                               (1.0, 0.0, 0.0, math.nan)])
def test_attitude_quaternion_not_finite(q):
    assert decode_attitude_quaternion(_quaternion(q)) == Refusal("nan", "ATTITUDE_QUATERNION with a non-finite component")


@pytest.mark.parametrize("q,text", [((0.0, 0.0, 0.0, 0.0), "ATTITUDE_QUATERNION norm 0"),
                                    ((0.5, 0.0, 0.0, 0.0), "ATTITUDE_QUATERNION norm 0.5"),
                                    ((0.0, 0.3, 0.0, 0.0), "ATTITUDE_QUATERNION norm 0.3"),
                                    ((2.0, 0.0, 0.0, 0.0), "ATTITUDE_QUATERNION norm 2"),
                                    ((1.0, 1.0, 1.0, 1.0), "ATTITUDE_QUATERNION norm 2"),
                                    ((1.0, 1.0, 1.0, 1.5), "ATTITUDE_QUATERNION norm 2.29"),
                                    ((1e30, 0.0, 0.0, 0.0), "ATTITUDE_QUATERNION norm 1e+30")])
def test_attitude_quaternion_impossible_norm(q, text):
    assert decode_attitude_quaternion(_quaternion(q)) == Refusal("impossible", text)


# ------------------------------------------------------------------ the autopilot's own position


def _gpi(lat=473977000, lon=85455000, alt_mm=510_250, rel_mm=22_125, vz_cms=-150, t_ms=65_000):
    return fields(MAV.global_position_int_encode(t_ms, lat, lon, alt_mm, rel_mm, 120, -30, vz_cms, 9000))


def test_global_position_int_reading_in_m_with_home():
    r = decode_global_position_int(_gpi())
    assert r == GlobalPositionReading(510.25, 22.125, 1.5, 488.125, 65_000_000)  # climbing at 1.5 m/s
    assert type(r.t_boot_us) is int


@pytest.mark.parametrize("vz,up", [(0, 0.0), (250, -2.5), (-32768, 327.68), (32767, -327.67)])
def test_global_position_int_vertical_speed_is_up(vz, up):
    v = decode_global_position_int(_gpi(vz_cms=vz)).vel_up
    assert v == up and math.copysign(1.0, v) == math.copysign(1.0, up)  # 0 is +0.0, as it always was


def test_global_position_int_without_a_position():
    # ArduPilot without a fix: lat = lon = 0 and alt its uncorrected baro altitude (or 0): no MSL, no home
    r = decode_global_position_int(_gpi(lat=0, lon=0))
    assert r == GlobalPositionReading(None, 22.125, 1.5, None, 65_000_000)


@pytest.mark.parametrize("lat,lon", [(1, 0), (0, -1), (-335000000, 0)])
def test_global_position_int_on_the_equator_or_the_meridian_has_a_position(lat, lon):
    r = decode_global_position_int(_gpi(lat=lat, lon=lon))
    assert r.alt_msl_m == 510.25 and r.home_msl_m == 488.125


@pytest.mark.parametrize("alt,rel,home", [(510_250, 510_250, None),  # old ArduPilot before arming: home at 0
                                          (510_250, 510_250 - HOME_UNSET_MM + 1, None),
                                          (510_250, 510_250 + HOME_UNSET_MM - 1, None),
                                          (510_250, 510_250 - HOME_UNSET_MM, 0.05),
                                          (510_250, 510_250 + HOME_UNSET_MM, -0.05),
                                          (-12_000, -2_000, -10.0)])  # below sea level
def test_global_position_int_home_not_set(alt, rel, home):
    r = decode_global_position_int(_gpi(alt_mm=alt, rel_mm=rel))
    assert r.home_msl_m == home and r.alt_msl_m == alt / 1000.0 and r.rel_m == rel / 1000.0
    assert HOME_UNSET_MM == 50


def _lpn(z=-12.5, vz=0.75, t_ms=65_000):
    return fields(MAV.local_position_ned_encode(t_ms, 3.0, -4.0, z, 0.5, -0.25, vz))


def test_local_position_ned_reading_is_up():
    r = decode_local_position_ned(_lpn())
    assert r == LocalPositionReading(12.5, -0.75, 65_000_000)  # 12.5 m above the EKF origin, sinking
    assert type(r.t_boot_us) is int


@pytest.mark.parametrize("vz", [math.nan, math.inf, -math.inf])
def test_local_position_ned_vz_not_finite_is_an_unknown_speed(vz):
    r = decode_local_position_ned(_lpn(vz=vz))
    assert type(r) is LocalPositionReading and r.up_m == 12.5 and math.isnan(r.vel_up)


@pytest.mark.parametrize("z", [math.nan, math.inf, -math.inf])
def test_local_position_ned_z_not_finite(z):
    for vz in (0.75, math.nan):
        assert decode_local_position_ned(_lpn(z=z, vz=vz)) == Refusal("nan", "LOCAL_POSITION_NED with a non-finite z")


# ------------------------------------------------------------------ home and EKF origin


def _home(alt_mm, time_usec=0):
    return fields(MAV.home_position_encode(473977000, 85455000, alt_mm, 1.0, 2.0, -0.5, (1.0, 0.0, 0.0, 0.0),
                                           0.0, 0.0, 0.0, time_usec))


def _origin(alt_mm, time_usec=0):
    return fields(MAV.gps_global_origin_encode(473977000, 85455000, alt_mm, time_usec))


@pytest.mark.parametrize("message,decode", [(_home, decode_home_position), (_origin, decode_gps_global_origin)])
def test_home_and_origin_altitude_in_m_msl(message, decode):
    assert decode(message(488_125, 123_456_789)) == DatumReading(488.125, 123_456_789)
    assert decode(message(-12_000)) == DatumReading(-12.0, 0)  # below sea level; time_usec not sent
    # an int32 of mm: every value is a finite altitude, so there is nothing to refuse
    assert decode(message(2**31 - 1)).alt_msl_m == 2147483.647
    assert decode(message(-2**31)).alt_msl_m == -2147483.648


# ------------------------------------------------------------------ the normaliser's HIGHRES_IMU hot path


def _stream(path: Path) -> tuple[list[str], dict]:
    src = TlogSource(path, IngestConfig())
    return [repr(s) for s in src], src.stats.to_dict()


def _odd_highres_log(tmp_path) -> Path:
    """HIGHRES_IMU of every kind the decoder tells apart, and the source choice
    made while some are refused."""
    f = FlightLog(tmp_path / "odd.tlog")
    f.heartbeat(0.0)
    odd = [(math.nan, 0.0, -9.8), (0.0, 0.0, -600.0), (0.0, math.inf, 0.0), (490.0, 0.0, -9.8), (600.0, 0.0, -9.8),
           (0.0, -491.0, -9.8), (0.0, 0.0, math.nan)]
    for k in range(200):
        t = k * 0.01
        if k % 2 == 0:
            f.attitude(t, 0.1, -0.05, 0.3)
        acc = odd[k // 7 % len(odd)] if k % 7 == 3 else (0.1, 0.2, -9.8)
        updated = 0b111000 if k % 11 == 5 else (0 if k % 13 == 0 else 0b111)
        f.highres(t + 0.005, acc, updated=updated)
        if k % 5 == 0:
            f.pressure(t, 100_000.0 - k)
    return f.close()


REPO = Path(__file__).resolve().parents[1]
PX4_LOGS = sorted((REPO / "sitl_logs").glob("px4_*.tlog"))[:2]


@pytest.mark.parametrize("which", ["odd"] + [p.name for p in PX4_LOGS[:1]]
                         + [pytest.param(p.name, marks=pytest.mark.slow) for p in PX4_LOGS[1:]])
def test_highres_imu_inline_matches_its_decoder(which, tmp_path, monkeypatch):
    path = _odd_highres_log(tmp_path) if which == "odd" else REPO / "sitl_logs" / which
    fast = _stream(path)
    monkeypatch.setattr(Normaliser, "_highres_imu", Normaliser._highres_imu_reference)
    ref = _stream(path)
    assert fast[1]["samples"].get("imu", 0) > 0
    if which == "odd":  # every path was taken
        assert fast[1]["rejected"]["nan"] > 0 and fast[1]["rejected"]["impossible"] > 0
        assert fast[1]["filtered"]["imu_accel_not_updated"] > 0
    assert fast[0] == ref[0]
    assert fast[1] == ref[1]
