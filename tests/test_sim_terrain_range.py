"""Simulator: terrain under the rangefinder, out-of-range encoding, slow streams, GNSS wander.

Each test checks the simulated data against the scenario it came from:
the rangefinder over a roof measures height minus ground (truth CSV and the
encoded DISTANCE_SENSOR), readings outside the sensor's limits are encoded
as the autopilots encode them, every stream of the slow-telemetry scenario
comes at its configured rate, and the GNSS error's slow part has the
configured correlation time.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from pymavlink import mavutil

from mavnav.errors import ConfigError
from mavnav.sim import load_scenario, read_truth_csv, scenario_from_dict, simulate
from tests.support.paths import REPO

ROOT = REPO
SCN = ROOT / "config" / "scenarios"


def _distance_sensor(tlog: bytes, tmp_path):
    """(time_boot_s, current_distance_m, min_m, max_m, signal_quality) of every DISTANCE_SENSOR."""
    p = tmp_path / "x.tlog"
    p.write_bytes(tlog)
    m = mavutil.mavlink_connection(str(p), dialect="ardupilotmega")
    rows = []
    while True:
        msg = m.recv_match(type="DISTANCE_SENSOR")
        if msg is None:
            break
        rows.append((msg.time_boot_ms * 1e-3, msg.current_distance / 100.0, msg.min_distance / 100.0,
                     msg.max_distance / 100.0, msg.signal_quality))
    return np.array(rows, dtype=float)


def _messages_per_type(tlog: bytes, tmp_path) -> dict:
    p = tmp_path / "y.tlog"
    p.write_bytes(tlog)
    m = mavutil.mavlink_connection(str(p), dialect="ardupilotmega")
    n: dict = {}
    while True:
        msg = m.recv_match()
        if msg is None:
            break
        n[msg.get_type()] = n.get(msg.get_type(), 0) + 1
    return n


def test_truth_range_over_a_roof_is_height_minus_ground(tmp_path):
    scn = load_scenario(SCN / "px4_roof_terrain.yaml")
    res = simulate(scn, seed=3)
    res.truth.to_csv(tmp_path / "t.csv")
    tr = read_truth_csv(tmp_path / "t.csv")
    t, h, agl, ground = tr["t_s"], tr["true_height_ref_m"], tr["true_range_agl_m"], tr["true_ground_ref_m"]
    roof = (t >= 25.0) & (t < 35.0)
    assert roof.sum() == 100  # 10 s at 10 Hz
    assert np.all(ground[roof] == 5.0) and np.all(ground[~roof] == 0.0)
    np.testing.assert_allclose(agl[roof], h[roof] - 5.0, atol=1e-4)
    np.testing.assert_allclose(agl[~roof], h[~roof], atol=1e-4)
    assert agl[roof].min() > 6.0  # the vehicle hovers at about 12 m over the roof


def test_encoded_rangefinder_reads_the_roof_and_nothing_else_does(tmp_path):
    scn = load_scenario(SCN / "px4_roof_terrain.yaml")
    res = simulate(scn, seed=4)
    ds = _distance_sensor(res.tlog, tmp_path)
    t = ds[:, 0]
    k = res.trajectory.sample(t)  # no reboot, boot offset 0: vehicle time = simulation time
    cos_tilt = np.cos(k.roll_rad) * np.cos(k.pitch_rad)
    ground = np.where((t >= 25.0) & (t < 35.0), 5.0, 0.0)
    air = k.height_m > 1.0
    expect = (k.height_m - ground) / cos_tilt
    err = ds[air, 1] - expect[air]
    assert abs(np.mean(err)) < 0.02 and np.std(err) < 0.08  # sigma_m 0.05, cm rounding
    on_roof = air & (ground > 0)
    assert on_roof.sum() > 150 and np.all(np.abs(ds[on_roof, 1] - expect[on_roof]) < 0.3)
    # the baro and GNSS do not see the roof: the same seed without terrain gives the same values
    flat = simulate(scenario_from_dict(dict(scn.model_dump(), terrain=[])), seed=4)
    for name, key in (("SCALED_PRESSURE", "pressure_pa"), ("GPS_RAW_INT", "alt_msl_m")):
        np.testing.assert_array_equal(res.streams[name][key], flat.streams[name][key])
    assert not np.array_equal(res.streams["DISTANCE_SENSOR"]["range_m"], flat.streams["DISTANCE_SENSOR"]["range_m"])


@pytest.mark.parametrize("patches,needle", [
    ([{"from_s": 10, "to_s": 10, "height_m": 3}], "to_s must exceed from_s"),
    ([{"from_s": 10, "to_s": 20, "height_m": 3}, {"from_s": 15, "to_s": 25, "height_m": 1}], "patches overlap"),
    ([{"from_s": 10, "to_s": 20, "height_m": 3, "heigth_m": 1}], "unknown key .terrain\\[0\\].heigth_m."),
])
def test_bad_terrain_is_refused_by_name(patches, needle):
    with pytest.raises(ConfigError, match=needle):
        scenario_from_dict({"duration_s": 30, "trajectory": {"kind": "hover"}, "terrain": patches})


@pytest.mark.parametrize("oor_quality,in_quality", [pytest.param(1, 100, marks=pytest.mark.slow), (0, 0)])
def test_out_of_range_readings_are_encoded_as_autopilots_do(tmp_path, oor_quality, in_quality):
    """Above max_m (the descent starts at 55 m, max 40 m) and below min_m (touchdown): the
    reading is sent beyond the limit, with signal_quality 1 (invalid) or 0 (unknown)."""
    scn = load_scenario(SCN / "px4_descent_above_rng_max.yaml")
    d = scn.model_dump()
    d["sensors"]["rangefinder"].update(quality=in_quality, out_of_range_quality=oor_quality)
    res = simulate(scenario_from_dict(d), seed=2)
    ds = _distance_sensor(res.tlog, tmp_path)
    t, dist, lo, hi, q = ds.T
    assert np.all(lo == 0.2) and np.all(hi == 40.0)
    h = res.trajectory.sample(t).height_m
    above, below = h > 41.0, h < 0.1
    inside = (h > 1.0) & (h < 38.0)
    assert above.sum() > 100 and below.sum() > 20 and inside.sum() > 300
    assert np.all(dist[above] > hi[above]) and np.all(q[above] == oor_quality)
    assert np.all(dist[below] < lo[below]) and np.all(q[below] == oor_quality)
    assert np.all((dist[inside] >= 0.2) & (dist[inside] <= 40.0)) and np.all(q[inside] == in_quality)


def test_slow_telemetry_sends_every_sensor_stream_at_its_rate(tmp_path):
    scn = load_scenario(SCN / "ardupilot_slow_telemetry.yaml")
    res = simulate(scn, seed=5)
    n = _messages_per_type(res.tlog, tmp_path)
    for name in ("RAW_IMU", "ATTITUDE", "SCALED_PRESSURE", "GPS_RAW_INT", "DISTANCE_SENSOR", "RANGEFINDER",
                 "GLOBAL_POSITION_INT"):
        assert abs(n[name] / scn.duration_s - 3.0) < 0.1, (name, n[name])
    assert "SCALED_IMU2" not in n and "HIGHRES_IMU" not in n


@pytest.mark.slow
def test_gnss_wander_is_gauss_markov_with_the_configured_tau():
    """White noise off, a long flight: the GNSS error's autocorrelation at lag tau is 1/e,
    its spread the configured sigma, and the reported v_acc the scenario's."""
    scn = load_scenario(SCN / "px4_gnss_wander.yaml")
    d = scn.model_dump()
    d["duration_s"] = 3600.0
    d["sensors"]["gnss"]["sigma_z_m"] = 0.0
    res = simulate(scenario_from_dict(d), seed=9, encode=False)
    g = res.streams["GPS_RAW_INT"]
    e, t = g["gnss_error_m"], g["t_sim"]
    tau, sig = scn.sensors.gnss.correlated_tau_s, scn.sensors.gnss.correlated_sigma_m
    assert 0.3 <= sig / scn.sensors.gnss.v_acc_m <= 0.5 and 100 <= tau <= 300
    assert np.all(g["v_acc_mm"] == 1000)
    lag = int(round(tau * 10.0))  # 10 Hz
    x = e - e.mean()
    rho = float(np.dot(x[:-lag], x[lag:]) / np.dot(x, x))
    assert abs(rho - math.exp(-1.0)) < 0.25, rho
    # one hour is 18 correlation times: the spread is the configured sigma within sampling error
    assert 0.6 * sig < np.std(e) < 1.4 * sig
    # and it wanders: the error moves by more than the white noise would in a minute
    assert np.ptp(e[: 600 * 3]) > 0.2
