"""Unit conversions, checked on messages encoded by pymavlink itself."""

from __future__ import annotations

import math
from dataclasses import replace

import pytest

from mavnav.atmosphere import height_from_pressure_m, pressure_at_height_pa
from mavnav.frames import quat_from_euler
from mavnav.samples import AutopilotHeight, BaroHeight, GnssHeight, RangeHeight, SpecificForceUp
from tests.support.flightlog import (
    MAV_AUTOPILOT_ARDUPILOTMEGA, P_GROUND_PA, FlightLog, collect, of, rejected,
)

G = 9.80665


def _imu_log(tmp_path, imu_writer, roll=0.0, pitch=0.0, autopilot=12, quaternion=False, n=20):
    f = FlightLog(tmp_path / "imu.tlog", autopilot=autopilot)
    f.heartbeat(0.0)
    for k in range(n):
        t = k * 0.02
        if quaternion:
            f.attitude_q(t, quat_from_euler(roll, pitch, 0.4))
        else:
            f.attitude(t, roll, pitch, 0.4)
        imu_writer(f, t + 0.01)
    return f.close()


def test_highres_imu_at_rest_is_plus_g(tmp_path):
    path = _imu_log(tmp_path, lambda f, t: f.highres(t, (0.0, 0.0, -G)))
    items, st = collect(path)
    fs = of(items, SpecificForceUp)
    assert st.imu_source == "HIGHRES_IMU" and len(fs) >= 15
    assert all(s.source == "HIGHRES_IMU" for s in fs)
    assert all(s.f_up_mps2 == pytest.approx(G, abs=1e-5) for s in fs)


@pytest.mark.parametrize("roll,pitch", [(0.5, 0.0), (0.0, -0.4), (0.3, 0.2)])
def test_tilted_gravity_reaction_stays_vertical(tmp_path, roll, pitch):
    # body specific force of a vehicle at rest, tilted: -g expressed in the body frame
    fb = (G * math.sin(pitch), -G * math.sin(roll) * math.cos(pitch), -G * math.cos(roll) * math.cos(pitch))
    for quaternion in (False, True):
        path = _imu_log(tmp_path, lambda f, t: f.highres(t, fb), roll, pitch, quaternion=quaternion)
        fs = of(collect(path)[0], SpecificForceUp)
        assert fs and all(s.f_up_mps2 == pytest.approx(G, abs=1e-4) for s in fs)


def test_body_z_force_is_projected_by_tilt(tmp_path):
    roll = math.radians(60)
    path = _imu_log(tmp_path, lambda f, t: f.highres(t, (0.0, 0.0, -G)), roll)
    fs = of(collect(path)[0], SpecificForceUp)
    assert fs and all(s.f_up_mps2 == pytest.approx(G * math.cos(roll), abs=1e-4) for s in fs)


@pytest.mark.parametrize("which", ["scaled_imu", "scaled_imu2", "scaled_imu3"])
def test_scaled_imu_is_milli_g(tmp_path, which):
    path = _imu_log(tmp_path, lambda f, t: f.scaled_imu(t, (0, 0, -1000), which=which))
    items, st = collect(path)
    fs = of(items, SpecificForceUp)
    assert st.imu_source == which.upper()
    assert fs and all(s.f_up_mps2 == pytest.approx(G, abs=1e-9) for s in fs)


def test_raw_imu_is_milli_g_on_ardupilot_only(tmp_path):
    path = _imu_log(tmp_path, lambda f, t: f.raw_imu(t, (0, 0, -500)), autopilot=MAV_AUTOPILOT_ARDUPILOTMEGA)
    items, st = collect(path)
    fs = of(items, SpecificForceUp)
    assert st.imu_source == "RAW_IMU"
    assert fs and all(s.f_up_mps2 == pytest.approx(G / 2, abs=1e-9) for s in fs)
    # on PX4 RAW_IMU carries raw sensor counts: not an input
    path = _imu_log(tmp_path, lambda f, t: f.raw_imu(t, (0, 0, -500)), autopilot=12)
    items, st = collect(path)
    assert not of(items, SpecificForceUp) and st.filtered["raw_imu_not_ardupilot"] > 0


def test_imu_auto_prefers_highres_and_never_mixes(tmp_path):
    def both(f, t):
        f.scaled_imu(t, (0, 0, -500), which="scaled_imu2")
        f.highres(t + 0.001, (0.0, 0.0, -G))
    items, st = collect(_imu_log(tmp_path, both))
    fs = of(items, SpecificForceUp)
    assert st.imu_source == "HIGHRES_IMU"
    assert fs and {s.source for s in fs} == {"HIGHRES_IMU"}
    items, st = collect(_imu_log(tmp_path, both), imu_source="SCALED_IMU2")
    assert {s.source for s in of(items, SpecificForceUp)} == {"SCALED_IMU2"}


def test_imu_attitude_is_interpolated_between_brackets(tmp_path):
    f = FlightLog(tmp_path / "interp.tlog")
    f.heartbeat(0)
    f.attitude(0.00, 0.0, 0.0)
    f.highres(0.005, (0.0, 0.0, -G))  # 1/4 of the way from roll 0 to roll 0.4
    f.attitude(0.02, 0.4, 0.0)
    f.attitude(0.04, 0.4, 0.0)
    fs = of(collect(f.close())[0], SpecificForceUp)
    assert len(fs) == 1
    assert fs[0].f_up_mps2 == pytest.approx(G * math.cos(0.1), abs=1e-3)


def test_baro_hpa_to_height_against_config_reference(tmp_path):
    f = FlightLog(tmp_path / "baro.tlog")
    f.heartbeat(0)
    heights = [0.0, 10.0, 55.5, -3.0]
    for k, h in enumerate(heights):
        f.pressure(0.1 * k, pressure_at_height_pa(h, P_GROUND_PA))
    items, st = collect(f.close(), baro_reference={"source": "config", "value": P_GROUND_PA})
    bs = of(items, BaroHeight)
    assert [b.height_ref_m for b in bs] == pytest.approx(heights, abs=0.05)  # float32 hPa on the wire
    assert bs[1].pressure_pa == pytest.approx(pressure_at_height_pa(10.0, P_GROUND_PA), rel=1e-6)
    assert st.references["baro"].origin == "config"


def test_baro_instance_selects_scaled_pressure_n(tmp_path):
    f = FlightLog(tmp_path / "baro2.tlog")
    f.heartbeat(0)
    for k in range(5):
        f.pressure(0.1 * k, 101325.0, instance=1)
        f.pressure(0.1 * k + 0.01, 90000.0, instance=2)
    items, _ = collect(f.close(), baro_instance=2)
    bs = of(items, BaroHeight)
    assert len(bs) == 5 and all(b.instance == 2 and b.pressure_pa == pytest.approx(90000.0) for b in bs)


def test_gnss_mm_msl_and_ellipsoid_and_v_acc(tmp_path):
    f = FlightLog(tmp_path / "gps.tlog")
    f.heartbeat(0)
    f.gps(0.0, 512.345, v_acc_mm=800, alt_ell_m=560.0)
    f.gps(0.2, 513.0, v_acc_mm=0, alt_ell_m=560.655)
    f.gps(0.4, 600.0, fix=2)  # 2D fix: not a height
    cfg = {"gnss_reference": {"source": "config", "value": 500.0}}
    items, st = collect(f.path if f.close() else None, **cfg)
    gs = of(items, GnssHeight)
    assert [g.alt_m for g in gs] == pytest.approx([512.345, 513.0])
    assert [g.height_ref_m for g in gs] == pytest.approx([12.345, 13.0])
    assert gs[0].sigma_m == pytest.approx(0.8) and gs[1].sigma_m is None
    assert st.filtered["gnss_no_fix"] == 1
    items, _ = collect(f.path, gnss_altitude="ellipsoid", **cfg)
    assert [g.alt_m for g in of(items, GnssHeight)] == pytest.approx([560.0, 560.655])


def test_distance_sensor_cm_tilt_corrected(tmp_path):
    roll = math.radians(30)
    f = FlightLog(tmp_path / "rng.tlog")
    f.heartbeat(0)
    for k in range(10):
        f.attitude(0.1 * k, roll, 0.0)
        f.dist(0.1 * k + 0.01, 10.0 + k)
    f.dist(1.05, 5.0, orientation=0)  # forward-looking: not a height
    items, st = collect(f.close(), rangefinder_stuck_s=100)
    rs = of(items, RangeHeight)
    assert [r.range_m for r in rs] == pytest.approx([10.0 + k for k in range(10)])
    assert [r.height_agl_m for r in rs] == pytest.approx([(10.0 + k) * math.cos(roll) for k in range(10)], rel=1e-6)
    assert st.filtered["range_not_downward"] == 1 and st.range_source == "DISTANCE_SENSOR"


def test_distance_sensor_invalid_and_out_of_range_are_refused(tmp_path):
    f = FlightLog(tmp_path / "rng2.tlog")
    f.heartbeat(0)
    f.attitude(0.0)
    f.dist(0.01, 5.0, quality=1)
    f.dist(0.02, 45.0)  # above max 40 m
    f.dist(0.03, 0.1)  # below min 20 cm
    f.dist(0.04, 5.0, quality=100)
    items, st = collect(f.close())
    assert len(of(items, RangeHeight)) == 1
    assert st.rejected["invalid_quality"] == 1 and st.rejected["out_of_range"] == 2


def test_rangefinder_metres_and_negative_is_impossible(tmp_path):
    f = FlightLog(tmp_path / "rf.tlog", autopilot=MAV_AUTOPILOT_ARDUPILOTMEGA)
    f.heartbeat(0)
    for k in range(5):
        f.attitude(0.1 * k)
        f.rangefinder(0.1 * k + 0.01, 7.5 + k)
    f.attitude(0.6)
    f.rangefinder(0.61, -1.0)
    items, st = collect(f.close())
    rs = of(items, RangeHeight)
    assert st.range_source == "RANGEFINDER"
    assert [r.range_m for r in rs] == pytest.approx([7.5 + k for k in range(5)])
    assert all(r.source == "RANGEFINDER" for r in rs)
    assert st.rejected["impossible"] == 1


def test_autopilot_height_above_gnss_reference(tmp_path):
    f = FlightLog(tmp_path / "ap.tlog")
    f.heartbeat(0)
    f.gps(0.0, 500.0)
    for k in range(5):
        f.gpi(0.1 * k, 500.0 + k, rel_m=k + 2.0)  # home 2 m below the GNSS reference
    items, st = collect(f.close(), gnss_reference={"source": "config", "value": 500.0})
    ah = of(items, AutopilotHeight)
    assert [a.height_ref_m for a in ah] == pytest.approx([float(k) for k in range(5)])
    assert st.autopilot_reference == "gnss_reference"
    # with no GNSS at all the home in GLOBAL_POSITION_INT (alt - relative_alt) is the reference at once
    g = FlightLog(tmp_path / "ap2.tlog")
    g.heartbeat(0)
    for k in range(5):
        g.gpi(0.1 * k, 500.0 + k, rel_m=k + 2.0)
    items, st = collect(g.close())
    assert [a.height_ref_m for a in of(items, AutopilotHeight)] == pytest.approx([k + 2.0 for k in range(5)])
    assert st.autopilot_reference == "gnss_reference" and st.references["gnss"].origin == "autopilot_home"
    assert st.references["gnss"].value == pytest.approx(498.0)
    # no position (ArduPilot sends lat = lon = 0 without one): its own datum, relative_alt, after the wait
    h = FlightLog(tmp_path / "ap3.tlog")
    h.heartbeat(0)
    for k in range(5):
        h.put(h.mav.global_position_int_encode(h.ms(0.1 * k), 0, 0, (500 + k) * 1000, (k + 2) * 1000, 0, 0, 0, 0),
              0.1 * k)
    items, st = collect(h.close())
    assert [a.height_ref_m for a in of(items, AutopilotHeight)] == pytest.approx([k + 2.0 for k in range(5)])
    assert st.autopilot_reference == "autopilot_home" and "gnss" not in st.references


def test_local_position_ned_is_up_from_z(tmp_path):
    f = FlightLog(tmp_path / "lpn.tlog")
    f.heartbeat(0)
    for k in range(3):
        f.lpn(0.1 * k, -1.5 * k)
    items, st = collect(f.close())
    assert [a.height_ref_m for a in of(items, AutopilotHeight)] == pytest.approx([0.0, 1.5, 3.0])
    assert st.autopilot_source == "LOCAL_POSITION_NED" and st.autopilot_reference == "ekf_origin"


def test_mavlink1_and_mavlink2_frames_give_the_same_samples(tmp_path):
    outs = []
    for v1 in (True, False):
        f = FlightLog(tmp_path / f"v{int(v1)}.tlog", mavlink1=v1)
        f.fly(0, 3, height_fn=lambda t: 2 * t, imu="scaled_imu")
        # MAVLink 1 has no GPS_RAW_INT extensions, hence no v_acc
        outs.append([replace(s, sigma_m=None) if isinstance(s, GnssHeight) else s for s in collect(f.close())[0]])
    assert outs[0] == outs[1] and len(outs[0]) > 300


def test_isa_reference_roundtrip_matches_atmosphere_module():
    # guard on the formula the normaliser relies on
    assert height_from_pressure_m(pressure_at_height_pa(123.0, 95000.0), 95000.0) == pytest.approx(123.0)


def test_distance_sensor_cross_checked_against_rangefinder(tmp_path):
    """ArduPilot's two messages for one rangefinder: agreeing readings pass,
    a reading the other message contradicts is refused and said."""
    f = FlightLog(tmp_path / "both.tlog", autopilot=MAV_AUTOPILOT_ARDUPILOTMEGA)
    f.heartbeat(0)
    for k in range(10):
        t = 0.1 * k
        f.attitude(t)
        f.rangefinder(t + 0.01, 5.0 + 0.1 * k)
        # from the 6th on, DISTANCE_SENSOR reads 1.5 m less than RANGEFINDER
        f.dist(t + 0.02, 5.0 + 0.1 * k - (1.5 if k >= 5 else 0.0))
    items, st = collect(f.close(), rangefinder_stuck_s=100)
    rs = of(items, RangeHeight)
    assert st.range_source == "DISTANCE_SENSOR"
    assert [r.range_m for r in rs] == pytest.approx([5.0 + 0.1 * k for k in range(5)])
    bad = rejected(items, "disagrees")
    assert len(bad) == 5 and st.rejected["disagrees"] == 5
    assert "RANGEFINDER 5.50 m" in bad[0].detail and bad[0].sensor == "range"
    # without the other message nothing is cross-checked
    g = FlightLog(tmp_path / "one.tlog", autopilot=MAV_AUTOPILOT_ARDUPILOTMEGA)
    g.heartbeat(0)
    for k in range(10):
        g.attitude(0.1 * k)
        g.dist(0.1 * k + 0.02, 5.0 + 0.1 * k - (1.5 if k >= 5 else 0.0))
    items, st = collect(g.close(), rangefinder_stuck_s=100)
    assert len(of(items, RangeHeight)) == 10 and st.rejected["disagrees"] == 0
