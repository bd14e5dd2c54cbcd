"""bench/ins_stats.py: the INS's acceleration error measured against the
GNSS Doppler on real flights (the numbers behind ``sensors.ins.sigma_a_mps2``,
docs/error_models.md)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bench import ins_stats as ins
from tests.support.paths import SHARED_FLIGHTLOGS


def test_the_integrated_gauss_markov_variance_has_both_limits():
    sigma, alpha = 0.1, 1.0
    # short windows: the error is a constant over the window, sigma^2 W^2
    w = 1e-3
    assert ins.gm_var(sigma, alpha, w) == pytest.approx(sigma * sigma * w * w, rel=1e-3)
    # long windows: a random walk in velocity, 2 sigma^2 W / alpha less its start-up
    w = 1e3
    assert ins.gm_var(sigma, alpha, w) == pytest.approx(2 * sigma * sigma * (w - 1 / alpha) / alpha, rel=1e-9)


@pytest.mark.parametrize("sigma_a, sigma_d", [(0.035, 0.05), (0.08, 0.02), (0.0, 0.06)])
def test_the_fit_recovers_the_model_it_is_given(sigma_a, sigma_d):
    sd = {w: math.sqrt(ins.gm_var(sigma_a, 1.0, w) + 2 * sigma_d * sigma_d) for w in ins.WINDOWS_S}
    got_a, got_d = ins.fit(sd, 1.0)
    assert got_a == pytest.approx(sigma_a, abs=1e-6)
    assert got_d == pytest.approx(sigma_d, abs=1e-6)


def test_the_robust_spread_ignores_a_few_outliers():
    rng = np.random.default_rng(3)
    x = rng.normal(0.0, 0.2, 5000)
    x[:50] = 40.0  # a manoeuvre the Doppler lagged
    assert ins.robust_sd(x) == pytest.approx(0.2, rel=0.06)


@pytest.mark.realdata
@pytest.mark.slow
def test_a_real_flight_shows_an_ins_error_that_grows_with_the_window():
    """dkla_log171: ArduCopter 3.3, IMU at 49 Hz, GNSS with its Doppler at
    5 Hz. The INS's velocity error against the Doppler grows with the window
    (it is an integral), and its size is that of a consumer MEMS IMU."""
    r = ins.flight(str(SHARED_FLIGHTLOGS / "dkla_log171.bin"), 20.0)
    assert r is not None and 40 < r["imu_hz"] < 60
    sds = [r["sd"][w] for w in ins.WINDOWS_S]
    assert all(b > a for a, b in zip(sds, sds[1:]))
    sigma_a, sigma_d = ins.fit(r["sd"], 1.0)
    assert 0.02 < sigma_a < 0.15 and sigma_d < 0.2


@pytest.mark.realdata
def test_a_slow_imu_is_left_out():
    assert ins.flight(str(SHARED_FLIGHTLOGS / "dkla_log171.bin"), 100.0) is None
