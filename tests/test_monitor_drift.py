"""The GNSS altitude's drift against the baro where the receiver gives no
Doppler velocity (mavnav/monitor/drift.py), and the GNSS's slow error it
stands beside (the Gauss-Markov state, on from the start in adaptive mode)."""

from __future__ import annotations

import math
import statistics

import numpy as np
import pytest

from mavnav.channel import Model
from mavnav.config import config_from_dict
from mavnav.ingest.tlog import TlogSource
from mavnav.monitor.drift import DriftCheck
from mavnav.pipeline import run
from mavnav.sim import scenario_from_dict, simulate

SEEDS = (1, 2, 3)


def _series(check, t_s, d_m):
    return [check.push(int(round(t * 1e6)), float(d)) for t, d in zip(t_s, d_m)]


@pytest.mark.unit
@pytest.mark.parametrize("seed", SEEDS)
def test_a_ramp_reads_its_rate_and_white_noise_its_own_error(seed):
    """The fitted slope of a 0.5 m/s ramp in white noise is the ramp's rate
    within its own stated error, and that error is what the noise puts through
    the fit (the second differences a ramp does not have)."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, 30.0, 0.2)
    noise_m = 0.8
    check = DriftCheck(window_s=10.0, max_gap_s=1.5)
    slopes = _series(check, t, 0.5 * t + rng.normal(0.0, noise_m, t.size))
    assert slopes[0] is None and slopes[-1] is not None
    sxx = sum((x - 5.0) ** 2 for x in np.arange(0.0, 10.2, 0.2))  # 51 samples over the 10 s window
    expected_sd = noise_m / math.sqrt(sxx)
    assert check.last_white_sd_mps == pytest.approx(expected_sd, rel=0.35)
    assert abs(slopes[-1] - 0.5) < 4.0 * check.last_white_sd_mps
    # over many windows the slopes scatter as the stated error says
    z = np.array([(s - 0.5) for s in slopes[60:] if s is not None]) / expected_sd
    assert 0.4 < np.std(z) < 1.6


@pytest.mark.unit
def _reference_fit(h) -> tuple[float, float]:
    """The slope and its white-noise error over the window ``h`` of ``(t_us, d_m)``,
    written plainly (generators, statistics.median): what DriftCheck.push computes."""
    t_us = h[-1][0]
    ts = [(s[0] - t_us) * 1e-6 for s in h]
    ds = [s[1] for s in h]
    n = len(ts)
    t_mean = sum(ts) / n
    d_mean = sum(ds) / n
    sxx = sum((x - t_mean) ** 2 for x in ts)
    sxy = sum((x - t_mean) * (y - d_mean) for x, y in zip(ts, ds))
    second = [abs(ds[i + 1] - 2.0 * ds[i] + ds[i - 1]) for i in range(1, n - 1)]
    white_m = statistics.median(second) * (1.0 / 0.6745) / math.sqrt(6.0)
    return sxy / sxx, white_m / math.sqrt(sxx)


@pytest.mark.parametrize("seed", range(4))
def test_the_fit_is_the_plain_formula_float_for_float(seed):
    """Odd and even window lengths (the median of the second differences), jittered times."""
    rng = np.random.default_rng(seed)
    d = DriftCheck(window_s=10.0, max_gap_s=2.0)
    t = 1_000_000
    for _ in range(400):
        t += int(rng.integers(80_000, 120_000))
        slope = d.push(t, float(rng.normal(0.0, 0.7)) + 0.05 * t * 1e-6)
        if slope is None:
            continue
        want = _reference_fit(list(d.hist))
        assert (slope, d.last_white_sd_mps) == want


def test_a_gap_or_a_bad_sample_restarts_the_window():
    check = DriftCheck(window_s=10.0, max_gap_s=1.5)
    t = np.arange(0.0, 12.0, 0.2)
    assert _series(check, t, 0.1 * t)[-1] == pytest.approx(0.1)
    assert check.push(int(14.0e6), 1.4) is None  # 2 s after the last sample: a new window
    assert check.push(int(14.2e6), math.nan) is None and math.isnan(check.last_slope_mps)
    assert len(check.hist) == 0


@pytest.mark.unit
def test_the_gnss_slow_error_is_modelled_from_the_start_except_in_paper_mode():
    adaptive = config_from_dict({})
    assert Model.from_config(adaptive).gnss_gm_sigma_m == adaptive.sensors.gnss.gm_sigma_m > 0.0
    assert Model.from_config(config_from_dict({"monitor": {"mode": "paper"}})).gnss_gm_sigma_m == 0.0


# A simulated PX4 telemetry flight (GPS_RAW_INT: no Doppler velocity) whose
# receiver wanders within its reported v_acc, with a 0.5 m/s GNSS ramp.
ONSET_S = 30.0


def _ramp_flight(seed: int, tmp_path) -> tuple:
    scn = scenario_from_dict({
        "duration_s": 60, "seed": seed, "profile": "px4",
        "trajectory": {"kind": "hover", "height_m": 12, "takeoff": False},
        "rates_hz": {"HIGHRES_IMU": 50},
        "sensors": {"gnss": {"sigma_z_m": 0.8, "correlated_sigma_m": 1.0, "correlated_tau_s": 300}},
        "faults": [{"kind": "gnss_ramp", "onset_s": ONSET_S, "duration_s": 20.0, "magnitude": 0.5}],
    })
    path = tmp_path / "ramp.tlog"
    path.write_bytes(simulate(scn, seed=seed).tlog)
    # the monitor told the simulated sensors' noise, as bench/integrity.py does
    return list(TlogSource(path, config_from_dict({}).ingest)), scn.filter_sensors().model_dump()


def _first_alarm(flight, **features):
    samples, sensors = flight
    events = run(samples, config_from_dict({"sensors": sensors, "monitor": {"features": features}}), []).alarms
    hits = [ev for ev in events if ev.source != "input" and ev.state == "alarm" and ev.previous != "alarm"]
    return hits[0] if hits else None


@pytest.mark.simulation
@pytest.mark.slow
@pytest.mark.parametrize("seed", SEEDS)
def test_a_gnss_ramp_without_a_doppler_is_caught_by_its_drift_against_the_baro(seed, tmp_path):
    """The Gauss-Markov state follows the ramp, so the innovation CUSUM alone
    is late or blind; the drift test pins it on the GNSS within 7 s (3.5 m of
    error), and without the drift test the same flight alarms later or not at
    all during the ramp."""
    flight = _ramp_flight(seed, tmp_path)
    ev = _first_alarm(flight)
    assert ev is not None and ev.source == "gnss", ev
    tta_s = ev.t_s - ONSET_S
    assert 0.0 < tta_s < 7.0 and "drifted" in ev.reason
    off = _first_alarm(flight, gnss_drift_check=False)
    assert off is None or off.t_s - ONSET_S > tta_s + 2.0
