"""The baro's noise measured at run time, and the sudden-jump rule on the
measured scatter of sample-to-sample innovation changes.

The monitor's sensor model is sized from real flights (baro ``u`` 0.2 m). A
user auditing a flight does not tell it the sensors' noise: with the
simulator's baro (``u`` 0.5 m at 1 s, which the noisiest real baro matches on
the baro/INS test) the simulated families scored 71/99 right with 16 false
alarms. :class:`~mavnav.monitor.baronoise.BaroNoiseMeter` measures ``u`` from a
1 s baro/INS second difference, which a ramp or a step does not move.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from mavnav.monitor.baronoise import BaroNoiseMeter
from mavnav.monitor.scale import MedianScale

SEEDS = (1, 2, 3)
MODEL_SIGMA_BB_M = 0.2
GAMMA_PER_S = 1.0


# ---------------------------------------------------------------- MedianScale


def test_median_scale_reads_a_normal_sigma_and_ignores_a_burst():
    rng = np.random.default_rng(3)
    ms = MedianScale(memory_s=30.0, min_samples=50, update_s=1.0)
    t = np.arange(0.0, 30.0, 0.05)
    x = 0.7 * rng.standard_normal(t.size)
    x[200:260] = 50.0  # a tenth of the window: a fault's onset, a spike train
    for ti, xi in zip(t, x):
        ms.push(int(ti * 1e6), abs(xi))
    assert ms.sd == pytest.approx(0.7 * 1.15, rel=0.1)  # the burst moves the median a little
    clean = MedianScale(30.0, 50, 1.0)
    for ti, xi in zip(t, 0.7 * rng.standard_normal(t.size)):
        clean.push(int(ti * 1e6), abs(xi))
    assert clean.sd == pytest.approx(0.7, rel=0.1)


def test_median_scale_waits_for_its_samples_and_forgets():
    ms = MedianScale(memory_s=5.0, min_samples=10, update_s=0.0)
    for k in range(9):
        assert ms.push(k * 100_000, 1.0) is False
    assert ms.sd is None
    assert ms.push(9 * 100_000, 1.0) is True and ms.sd == pytest.approx(1.0 / 0.6744897501960817)
    for k in range(10, 200):  # 19 s of readings ten times smaller: the old ones fall out
        ms.push(k * 100_000, 0.1)
    assert ms.sd == pytest.approx(0.1 / 0.6744897501960817)
    assert len(ms.x) <= 51


# ---------------------------------------------------------------- BaroNoiseMeter


def _baro(seed: int, u_sigma_m: float, duration_s: float = 120.0, rate_hz: float = 10.0, white_m: float = 0.05):
    """A hovering vehicle's baro: Gauss-Markov ``u`` at 1 s and white noise."""
    rng = np.random.default_rng(seed)
    dt = 1.0 / rate_hz
    n = int(duration_s * rate_hz)
    phi = math.exp(-GAMMA_PER_S * dt)
    u = np.empty(n)
    u[0] = u_sigma_m * rng.standard_normal()
    for k in range(1, n):
        u[k] = phi * u[k - 1] + u_sigma_m * math.sqrt(1 - phi * phi) * rng.standard_normal()
    return np.arange(n) * dt, u + white_m * rng.standard_normal(n)


def _measure(t_s, baro_m, white_m: float = 0.05) -> BaroNoiseMeter:
    meter = BaroNoiseMeter(MODEL_SIGMA_BB_M, GAMMA_PER_S, window_s=1.0, memory_s=60.0, min_samples=50,
                           outlier_sigma=6.0, significance_sigma=2.0, update_s=1.0)
    x, P = np.zeros(4), np.zeros((4, 4))
    psd = 2.0 * 0.05 ** 2 / 1.0  # a quiet INS
    prev = t_s[0]
    for ti, b in zip(t_s, baro_m):
        t_us = int(round(ti * 1e6))
        meter.push(t_us, ti - prev, 0.0, 0.0, float(b), x, P)
        meter.observe(t_us, white_m ** 2, psd, 1e-8)
        prev = ti
    return meter


@pytest.mark.parametrize("seed", SEEDS)
def test_a_baro_noisier_than_the_model_is_measured(seed):
    t, b = _baro(seed, 0.5)
    u = math.sqrt(_measure(t, b).u_var_m2)
    assert 0.4 <= u <= 0.65  # the simulator's 0.5 m, from a minute of a 1 s correlation


@pytest.mark.parametrize("seed", range(1, 9))
def test_a_baro_as_noisy_as_the_model_keeps_the_model(seed):
    # (the ratio read over a minute of 2 s spans scatters by a third)
    t, b = _baro(seed, MODEL_SIGMA_BB_M, duration_s=300.0)
    meter = _measure(t, b)
    assert meter.u_var_m2 == MODEL_SIGMA_BB_M ** 2  # it only ever widens
    t, b = _baro(seed, 0.1)
    assert _measure(t, b).u_var_m2 == MODEL_SIGMA_BB_M ** 2


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("fault", ["ramp", "step"])
def test_a_baro_fault_does_not_teach_the_meter(seed, fault):
    t, b = _baro(seed, 0.5)
    clean = _measure(t, b).u_var_m2
    faulty = b.copy()
    on = t >= 90.0
    faulty[on] += 0.5 * (t[on] - 90.0) if fault == "ramp" else 3.0  # until the end: in the last window
    u = _measure(t, faulty).u_var_m2
    assert math.sqrt(u) == pytest.approx(math.sqrt(clean), rel=0.05)


def test_the_measured_u_is_capped_at_the_scales_limit():
    t, b = _baro(1, 3.0)  # fifteen times the model's sigma
    meter = BaroNoiseMeter(MODEL_SIGMA_BB_M, GAMMA_PER_S, 1.0, 60.0, 50, 6.0, 2.0, 1.0, max_factor=5.0)
    x, P = np.zeros(4), np.zeros((4, 4))
    prev = t[0]
    for ti, bi in zip(t, b):
        meter.push(int(round(ti * 1e6)), ti - prev, 0.0, 0.0, float(bi), x, P)
        meter.observe(int(round(ti * 1e6)), 0.05 ** 2, 0.005, 1e-8)
        prev = ti
    assert meter.ratio > 100.0
    assert math.sqrt(meter.u_var_m2) == pytest.approx(5.0 * MODEL_SIGMA_BB_M)


# ---------------------------------------------------------------- simulated flights, audited as a user does


def _job(family: str, seed: int, **features):
    """One run of ``bench/integrity.py``'s family on mavnav's shipped sensor
    model (the simulator's baro is 2.5 times noisier than it), features as asked."""
    from bench import integrity

    real = integrity.config_from_dict

    def cfg(d):
        d = dict(d)
        d["monitor"] = {**d.get("monitor", {}), "features": features}
        return real(d)

    integrity.config_from_dict = cfg
    try:
        r = integrity.job({"family": family, "seed": seed, "contenders": ["adaptive"], "long_minutes": 5,
                           "baseline_fail_s": 5.0, "sensor_model": "shipped"})
    finally:
        integrity.config_from_dict = real
    return r.scores["adaptive"]


@pytest.mark.slow
def test_fault_free_grid_flights_raise_nothing_on_the_shipped_model():
    # seed 3's take-off: the baro 2.3 m from the just-started rangefinder channel, 9 of the
    # model's sigmas and 3 of the baro's own; a false alarm while the model's u was assumed
    old = _job("fault_free", 3, baro_u_measured=False, sudden_jump_measured=False)
    assert old["false_alarms"] >= 1
    for seed in (1, 2, 3, 4):
        s = _job("fault_free", seed)
        assert s["false_alarms"] == 0 and s["right"], (seed, s)
        # seed 4's GNSS wanders near its drift test's threshold: a suspicion of 1.8 s
        # (3.1 %), 2.8 s (4.7 %) since the baro's first rows carry a white-noise prior
        assert s["caution_frac"] < 0.05


@pytest.mark.slow
@pytest.mark.parametrize("family", ["rng_step3", "rng_step5"])
def test_rangefinder_steps_are_pinned_on_the_rangefinder_on_the_shipped_model(family):
    tta = []
    for seed in SEEDS:
        s = _job(family, seed)
        assert s["right"] and s["blamed"] == ("rangefinder",), (seed, s)
        tta.append(s["tta_s"])
    assert sorted(tta)[1] <= 1.0  # the median within the time-to-alarm
    # the innovations' own sigma (consecutive ones share the channel's error) saw no jump:
    # the step was left to a test that implicates the baro as well
    old = [_job(family, seed, sudden_jump_measured=False) for seed in SEEDS]
    assert sum(o["right"] for o in old) < len(SEEDS)
