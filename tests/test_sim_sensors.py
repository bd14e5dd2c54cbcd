"""The simulator's sensors match their configuration, measured from decoded MAVLink.

Every statistic is estimated from the tlog as pymavlink decodes it (not from
the simulator's internal arrays) against the analytic truth, with tolerances
of four standard errors derived from the sample sizes. Fixed seeds.
"""

from __future__ import annotations

import math
from collections import defaultdict

import numpy as np
import pytest
from pymavlink import mavutil

from mavnav.atmosphere import height_from_pressure_m, isa_pressure_at_msl_alt_pa
from mavnav.frames import down_row_from_euler
from tests.support.frames_reference import body_rates_from_euler_rates, mat_nb_from_euler
from mavnav.sim import scenario_from_dict, simulate
from mavnav.sim.sensors import gauss_markov, mat_nb, body_rates

pytestmark = [pytest.mark.simulation]

G = 9.80665


def decode(tmp_path, tlog: bytes, name: str = "sim.tlog"):
    """All messages by type, as pymavlink decodes the tlog: {type: [msg, ...]}."""
    p = tmp_path / name
    p.write_bytes(tlog)
    conn = mavutil.mavlink_connection(str(p), robust_parsing=True)
    out = defaultdict(list)
    while True:
        m = conn.recv_msg()
        if m is None:
            break
        out[m.get_type()].append(m)
    conn.close()
    return out


def _scenario(**over):
    base = {
        "duration_s": 120,
        "seed": 11,
        "profile": "px4",
        "link": {"sample_jitter": 0.0},
        "trajectory": {"kind": "steps", "heights_m": [12, 30, 6, 0], "hold_s": 15},
    }
    base.update(over)
    return scenario_from_dict(base)


# ---------------------------------------------------------------- models, closed form


def test_gauss_markov_is_exact_at_irregular_sample_times():
    rng = np.random.default_rng(5)
    n = 60000
    dt = np.where(np.arange(n) % 2 == 0, 0.02, 0.6)  # alternating short and long gaps
    t = np.concatenate([[0.0], np.cumsum(dt[:-1])])
    sigma, gamma = 0.7, 1.5
    u = gauss_markov(t, sigma, gamma, rng)
    se_sd = sigma / math.sqrt(2 * n) * 4 * 3  # generous: the chain is correlated
    assert abs(u.std() - sigma) < se_sd
    prev, cur, gaps = u[:-1], u[1:], np.diff(t)
    for gap in (0.02, 0.6):
        sel = np.isclose(gaps, gap)
        phi = math.exp(-gamma * gap)
        slope = np.dot(prev[sel], cur[sel]) / np.dot(prev[sel], prev[sel])
        se = math.sqrt((1 - phi * phi) / sel.sum())
        assert abs(slope - phi) < 4 * se, (gap, slope, phi)
        resid = cur[sel] - phi * prev[sel]
        assert abs(resid.std() / (sigma * math.sqrt(1 - phi * phi)) - 1) < 4 / math.sqrt(2 * sel.sum())


def test_rotation_helpers_agree_with_frames():
    rng = np.random.default_rng(1)
    r, p, y = rng.uniform(-0.6, 0.6, 3)
    m = mat_nb(np.array([r]), np.array([p]), np.array([y]))[0]
    assert np.allclose(m, np.array(mat_nb_from_euler(r, p, y)), atol=1e-12)
    assert np.allclose(m[2], down_row_from_euler(r, p), atol=1e-12)
    assert np.allclose(m @ m.T, np.eye(3), atol=1e-12)
    rates = body_rates(r, p, 0.1, -0.2, 0.3)
    assert np.allclose(rates, body_rates_from_euler_rates(r, p, 0.1, -0.2, 0.3))


# ---------------------------------------------------------------- INS


@pytest.mark.slow
def test_imu_noise_and_bias_match_configuration(tmp_path):
    ins = {"sigma_a_mps2": 0.03, "alpha_a_per_s": 2.0, "bias_up_mps2": 0.07}
    scn = _scenario(
        sensors={"ins": ins},
        rates_hz={"HIGHRES_IMU": 100, "ATTITUDE": 0, "SCALED_PRESSURE": 0, "GPS_RAW_INT": 0,
                  "DISTANCE_SENSOR": 0, "GLOBAL_POSITION_INT": 0, "LOCAL_POSITION_NED": 0},
    )
    res = simulate(scn)
    msgs = decode(tmp_path, res.tlog)["HIGHRES_IMU"]
    t = np.array([m.time_usec for m in msgs]) / 1e6 - scn.boot_time_at_start_s
    f_b = np.array([[m.xacc, m.yacc, m.zacc] for m in msgs])
    k = res.trajectory.sample(t)
    m_nb = mat_nb(k.roll_rad, k.pitch_rad, k.yaw_rad)
    # true specific force in NED, then the error rotated back to NED
    f_true_n = np.stack([k.acc_n_mps2, k.acc_e_mps2, -k.acc_up_mps2 - G], axis=1)
    err_n = np.einsum("kij,kj->ki", m_nb, f_b) - f_true_n
    q = ins["sigma_a_mps2"] * math.sqrt(2 / (ins["alpha_a_per_s"] * 0.01))  # T = 1/100 Hz
    n = len(msgs)
    assert n > 11000
    # vertical: f_up = a_up + g + da + w  ->  mean(-err_down) = da
    assert abs(-err_n[:, 2].mean() - ins["bias_up_mps2"]) < 4 * q / math.sqrt(n)
    for axis in range(3):
        sd = err_n[:, axis].std()
        assert abs(sd / q - 1) < 4 / math.sqrt(2 * n), (axis, sd, q)
    # white: no lag-1 correlation
    e = err_n[:, 2] - err_n[:, 2].mean()
    assert abs(np.dot(e[1:], e[:-1]) / np.dot(e, e)) < 4 / math.sqrt(n)
    # at rest on the ground (after the last step) body z reads about -g
    on_ground = k.height_m == 0
    assert on_ground.sum() > 50
    assert abs(f_b[on_ground, 2].mean() + G + ins["bias_up_mps2"]) < 4 * q / math.sqrt(on_ground.sum())


@pytest.mark.slow
def test_attitude_moves_and_yaw_is_not_zero(tmp_path):
    scn = _scenario(duration_s=60)
    res = simulate(scn)
    att = decode(tmp_path, res.tlog)["ATTITUDE"]
    roll = np.array([a.roll for a in att])
    pitch = np.array([a.pitch for a in att])
    yaw = np.array([a.yaw for a in att])
    assert roll.max() - roll.min() > math.radians(8)
    assert pitch.max() - pitch.min() > math.radians(6)
    assert np.abs(yaw).min() > math.radians(10)
    t = np.array([a.time_boot_ms for a in att]) / 1e3
    k = res.trajectory.sample(t)
    sa = scn.sensors.attitude.sigma_rad
    d = roll - k.roll_rad
    assert abs(d.std() / sa - 1) < 4 / math.sqrt(2 * len(att)) + 1e-3  # float32 rounding


# ---------------------------------------------------------------- barometer


@pytest.mark.slow
def test_baro_bias_sigma_and_gauss_markov_correlation(tmp_path):
    baro = {"sigma_bb_m": 0.5, "gamma_bb_per_s": 5.0, "bias_m": 1.7}
    scn = _scenario(
        duration_s=300,
        sensors={"baro": baro},
        rates_hz={"HIGHRES_IMU": 5, "ATTITUDE": 0, "SCALED_PRESSURE": 25, "GPS_RAW_INT": 0,
                  "DISTANCE_SENSOR": 0, "GLOBAL_POSITION_INT": 0, "LOCAL_POSITION_NED": 0},
    )
    res = simulate(scn)
    sp = decode(tmp_path, res.tlog)["SCALED_PRESSURE"]
    t = np.array([m.time_boot_ms for m in sp]) / 1e3
    p_ref = isa_pressure_at_msl_alt_pa(scn.home.alt_msl_m)
    h_baro = np.array([height_from_pressure_m(m.press_abs * 100.0, p_ref) for m in sp])  # hPa on the wire
    # the ms-truncated time: evaluate the truth at the sample's own time (< 1 ms, < 2 mm here)
    err = h_baro - res.trajectory.sample(t).height_m
    n = len(err)
    phi = math.exp(-baro["gamma_bb_per_s"] / 25.0)
    sigma = baro["sigma_bb_m"]
    se_mean = sigma * math.sqrt((1 + phi) / ((1 - phi) * n))
    assert abs(err.mean() - baro["bias_m"]) < 4 * se_mean
    u = err - err.mean()
    n_eff = n * (1 - phi * phi) / (1 + phi * phi)
    assert abs(u.std() / sigma - 1) < 4 / math.sqrt(2 * n_eff)
    for lag in (1, 3, 10):
        r = np.dot(u[lag:], u[:-lag]) / np.dot(u, u)
        expected = phi**lag
        # Bartlett's variance of an AR(1) autocorrelation estimate
        var = ((1 + phi * phi) * (1 - phi ** (2 * lag)) / (1 - phi * phi) - 2 * lag * phi ** (2 * lag)) / n
        assert abs(r - expected) < 4 * math.sqrt(var) + 0.01, (lag, r, expected)


# ---------------------------------------------------------------- GNSS


def test_gnss_white_noise_correlated_error_and_v_acc(tmp_path):
    gnss = {"sigma_z_m": 0.6, "correlated_sigma_m": 1.2, "correlated_tau_s": 400.0, "geoid_separation_m": 47.5}
    scn = _scenario(
        duration_s=300,
        sensors={"gnss": gnss},
        rates_hz={"HIGHRES_IMU": 5, "ATTITUDE": 0, "SCALED_PRESSURE": 0, "GPS_RAW_INT": 10,
                  "DISTANCE_SENSOR": 0, "GLOBAL_POSITION_INT": 0, "LOCAL_POSITION_NED": 0},
    )
    res = simulate(scn)
    gps = decode(tmp_path, res.tlog)["GPS_RAW_INT"]
    t = np.array([g.time_usec for g in gps]) / 1e6
    alt = np.array([g.alt for g in gps]) / 1000.0  # mm MSL
    err = alt - (scn.home.alt_msl_m + res.trajectory.sample(t).height_m)
    n = len(err)
    # first differences remove the slow error: var = 2 sz^2 + 2 sc^2 (1 - phi)
    phi = math.exp(-0.1 / gnss["correlated_tau_s"])
    var_d = 2 * gnss["sigma_z_m"] ** 2 + 2 * gnss["correlated_sigma_m"] ** 2 * (1 - phi)
    d = np.diff(err)
    assert abs(d.std() / math.sqrt(var_d) - 1) < 4 * math.sqrt(1.5 / (2 * n))
    # the slow part: a 10 s moving average keeps an error of about sc (its RMS about
    # zero, offset and wander together), far above what averaging leaves of white noise
    smooth = np.convolve(err, np.ones(100) / 100, mode="valid")
    rms_smooth = math.sqrt(np.mean(smooth ** 2))
    assert rms_smooth > 0.5 * gnss["correlated_sigma_m"]
    assert rms_smooth > 5 * gnss["sigma_z_m"] / math.sqrt(100)
    assert abs(err.mean()) < 4 * math.hypot(gnss["sigma_z_m"] / math.sqrt(n), gnss["correlated_sigma_m"])
    v_acc = {g.v_acc for g in gps}
    assert v_acc == {round(1000 * math.hypot(0.6, 1.2))}
    assert {g.alt_ellipsoid - g.alt for g in gps} == {47500}
    assert {g.fix_type for g in gps} == {3}


# ---------------------------------------------------------------- rangefinder


def test_rangefinder_slant_noise_and_limits(tmp_path):
    rf = {"sigma_m": 0.04, "min_m": 0.3, "max_m": 25.0}
    scn = _scenario(
        duration_s=150,
        sensors={"rangefinder": rf},
        rates_hz={"HIGHRES_IMU": 5, "ATTITUDE": 0, "SCALED_PRESSURE": 0, "GPS_RAW_INT": 0,
                  "DISTANCE_SENSOR": 20, "GLOBAL_POSITION_INT": 0, "LOCAL_POSITION_NED": 0},
    )
    res = simulate(scn)
    ds = decode(tmp_path, res.tlog)["DISTANCE_SENSOR"]
    assert {d.orientation for d in ds} == {25}
    assert {(d.min_distance, d.max_distance) for d in ds} == {(30, 2500)}
    t = np.array([d.time_boot_ms for d in ds]) / 1e3
    k = res.trajectory.sample(t)
    slant = k.height_m / (np.cos(k.roll_rad) * np.cos(k.pitch_rad))
    reading = np.array([d.current_distance for d in ds]) / 100.0  # cm on the wire
    quality = np.array([d.signal_quality for d in ds])
    inside = (slant > rf["min_m"] + 0.2) & (slant < rf["max_m"] - 0.2)
    outside = (slant < rf["min_m"] - 0.2) | (slant > rf["max_m"] + 0.2)
    assert inside.sum() > 1000 and outside.sum() > 100  # ground at the end, 30 m step above max
    e = reading[inside] - slant[inside]
    sd = math.sqrt(rf["sigma_m"] ** 2 + 0.01**2 / 12)  # plus cm rounding
    assert abs(e.mean()) < 4 * sd / math.sqrt(inside.sum())
    assert abs(e.std() / sd - 1) < 4 / math.sqrt(2 * inside.sum())
    # the tilt matters: the vertical height would be biased low by more than the tolerance
    e_vert = reading[inside] - k.height_m[inside]
    assert e_vert.mean() > 8 * sd / math.sqrt(inside.sum())
    assert set(quality[inside]) == {100}
    assert set(quality[outside]) == {1}
    assert np.all((reading[outside] < rf["min_m"]) | (reading[outside] > rf["max_m"]))


# ---------------------------------------------------------------- wire units, ArduPilot profile


def test_ardupilot_units_on_the_wire(tmp_path):
    scn = scenario_from_dict({
        "duration_s": 90,
        "seed": 4,
        "profile": "ardupilot",
        "home": {"alt_msl_m": 584.0, "lat_deg": -35.363261, "lon_deg": 149.16523},
        "trajectory": {"kind": "hover", "height_m": 12, "ground_s": 5},
        "sensors": {"ins": {"sigma_a_mps2": 0.02, "bias_up_mps2": 0.0}, "baro": {"bias_m": 0.0}},
    })
    res = simulate(scn)
    msgs = decode(tmp_path, res.tlog)
    for name in ("RAW_IMU", "SCALED_IMU2", "ATTITUDE", "SCALED_PRESSURE", "GPS_RAW_INT", "RANGEFINDER",
                 "DISTANCE_SENSOR", "GLOBAL_POSITION_INT", "LOCAL_POSITION_NED", "HEARTBEAT", "HOME_POSITION"):
        assert msgs[name], name
    assert "HIGHRES_IMU" not in msgs
    hb = msgs["HEARTBEAT"]
    assert {(h.type, h.autopilot) for h in hb} == {(2, 3)}  # quadrotor, ArduPilot
    assert len(hb) == pytest.approx(90, abs=1)

    # RAW_IMU: milli-g, time_usec; SCALED_IMU2: milli-g, time_boot_ms
    q = 0.02 * math.sqrt(2 / (1.0 * 0.1))  # 10 Hz messages
    sd = math.sqrt(q * q + (G / 1000) ** 2 / 12)
    for name, tfield, scale in (("RAW_IMU", "time_usec", 1e-6), ("SCALED_IMU2", "time_boot_ms", 1e-3)):
        ms = msgs[name]
        t = np.array([getattr(m, tfield) for m in ms]) * scale
        k = res.trajectory.sample(t)
        f_b = np.array([[m.xacc, m.yacc, m.zacc] for m in ms]) * G / 1000.0
        m_nb = mat_nb(k.roll_rad, k.pitch_rad, k.yaw_rad)
        f_true_n = np.stack([k.acc_n_mps2, k.acc_e_mps2, -k.acc_up_mps2 - G], axis=1)
        f_true_b = np.einsum("kji,kj->ki", m_nb, f_true_n)
        e = f_b - f_true_b
        n = len(ms)
        assert np.all(np.abs(e.mean(axis=0)) < 4 * sd / math.sqrt(n)), name
        assert np.all(np.abs(e.std(axis=0) / sd - 1) < 4 / math.sqrt(2 * n)), name
        ground = k.height_m == 0
        assert np.all(np.abs(np.array([m.zacc for m in ms])[ground] + 1000) < 6 * q / G * 1000)

    # SCALED_PRESSURE: hPa; temperature cdegC
    sp = msgs["SCALED_PRESSURE"]
    t = np.array([m.time_boot_ms for m in sp]) / 1e3
    p_ref = isa_pressure_at_msl_alt_pa(584.0)
    hb_ = np.array([height_from_pressure_m(m.press_abs * 100, p_ref) for m in sp])
    e = hb_ - res.trajectory.sample(t).height_m
    assert abs(e.mean()) < 4 * 0.5 * math.sqrt(2 / (1 - math.exp(-0.1)) / len(sp))
    assert {m.temperature for m in sp} == {2500}

    # GPS_RAW_INT: mm MSL, degE7
    gps = msgs["GPS_RAW_INT"]
    t = np.array([g.time_usec for g in gps]) / 1e6
    alt = np.array([g.alt for g in gps]) / 1000.0
    assert np.abs(alt - 584.0 - res.trajectory.sample(t).height_m).max() < 6 * math.hypot(0.8, 1.0)
    assert abs(gps[0].lat / 1e7 - (-35.363261)) < 1e-3 and abs(gps[0].lon / 1e7 - 149.16523) < 1e-3

    # DISTANCE_SENSOR cm and RANGEFINDER m report the same sample
    ds, rf = msgs["DISTANCE_SENSOR"], msgs["RANGEFINDER"]
    assert len(ds) == len(rf)
    assert all(abs(a.current_distance - b.distance * 100) <= 0.51 for a, b in zip(ds, rf))

    # own estimate: relative_alt mm, alt mm MSL, LOCAL_POSITION_NED z down in m; HOME_POSITION mm
    gp = msgs["GLOBAL_POSITION_INT"]
    t = np.array([g.time_boot_ms for g in gp]) / 1e3
    h = res.trajectory.sample(t).height_m
    rel = np.array([g.relative_alt for g in gp]) / 1000.0
    assert np.abs(rel - h).max() < 6 * scn.sensors.estimate.sigma_m
    assert np.all(np.array([g.alt - g.relative_alt for g in gp]) == 584000)
    lp = msgs["LOCAL_POSITION_NED"]
    t = np.array([g.time_boot_ms for g in lp]) / 1e3
    z = np.array([g.z for g in lp])
    assert np.abs(-z - res.trajectory.sample(t).height_m).max() < 6 * scn.sensors.estimate.sigma_m
    assert {hp.altitude for hp in msgs["HOME_POSITION"]} == {584000}


@pytest.mark.slow
def test_px4_profile_messages_and_rates(tmp_path):
    scn = _scenario(duration_s=30, rates_hz={"HIGHRES_IMU": 200})
    res = simulate(scn)
    msgs = decode(tmp_path, res.tlog)
    hb = msgs["HEARTBEAT"]
    assert {(h.type, h.autopilot) for h in hb} == {(2, 12)}  # quadrotor, PX4
    assert len(msgs["HIGHRES_IMU"]) == pytest.approx(200 * 30, abs=2)
    assert len(msgs["ATTITUDE"]) == pytest.approx(50 * 30, abs=2)
    assert len(msgs["GPS_RAW_INT"]) == pytest.approx(10 * 30, abs=2)
    assert "RAW_IMU" not in msgs and "RANGEFINDER" not in msgs
    # HIGHRES_IMU carries the latest baro sample in hPa, flagged when new
    hi = msgs["HIGHRES_IMU"]
    sp = msgs["SCALED_PRESSURE"]
    press = {round(m.press_abs, 3) for m in sp}
    updated = [m for m in hi if m.fields_updated & 0x200]
    assert len(updated) == pytest.approx(len(sp), abs=2)
    assert all(round(m.abs_pressure, 3) in press for m in updated)
    # SYSTEM_TIME maps boot time to Unix time near the receive time
    st = msgs["SYSTEM_TIME"][5]
    assert abs(st.time_unix_usec / 1e6 - st._timestamp) < 0.2
