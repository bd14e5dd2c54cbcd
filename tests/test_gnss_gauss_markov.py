"""GNSS vertical error as white noise plus a first-order Gauss-Markov state.

Seeded Monte Carlo on simulated flights whose GNSS error IS white noise plus
a Gauss-Markov process (added here, exactly discretised): the production
bank with the Gauss-Markov state is consistent (NEES of the GNSS channel's
[H, Vz], NIS of its GNSS row); the same data through the white-only model
(the filter before this state) is far over-confident. A GNSS step is not
absorbed by the slow state: it shows as a large innovation at once.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy import stats

from mavnav.bank import GNSS, ChannelBank
from mavnav.channel import GB, H, VZ, Model
from mavnav.epochs import EpochBuilder, EpochStart
from mavnav.samples import GnssHeight
from tests.support.synthetic import Schedule, TrueSensors, paper_flight

from tests.support.estimator import config_for, with_gnss_gauss_markov

pytestmark = [pytest.mark.simulation, pytest.mark.slow]

GM_SIGMA_M, GM_TAU_S = 3.0, 300.0  # the configuration's defaults
SENSORS = TrueSensors(sigma_a_mps2=0.2, alpha_a_per_s=1.0, sigma_bb_m=1.0, gamma_bb_per_s=0.5, sigma_z_m=0.7)
# 20 Hz IMU and baro, 5 Hz GNSS, long enough for the Gauss-Markov error to wander
SCHEDULE = Schedule(duration_s=400.0, imu_dt_s=0.05, baro_every=1, gnss_every=4, rng_every=10)
RUNS = 24
SAMPLE_EVERY = 100  # epochs between NEES samples (5 s)


def cfg_with(gm_sigma_m: float):
    cfg = config_for(SENSORS)
    gnss = cfg.sensors.gnss.model_copy(update={"gm_sigma_m": gm_sigma_m, "gm_tau_s": GM_TAU_S})
    return cfg.model_copy(update={"sensors": cfg.sensors.model_copy(update={"gnss": gnss})})


CFG_GM, CFG_WHITE = cfg_with(GM_SIGMA_M), cfg_with(0.0)


def flight_from_prior(seed: int):
    """Truth drawn from the filter's own prior, GNSS error white + Gauss-Markov."""
    p0 = CFG_GM.filter.p0
    rng = np.random.default_rng(seed)
    h0, v0, dh, da = rng.standard_normal(4) * np.sqrt([p0.height_m2, p0.vel_m2ps2, p0.baro_bias_m2, p0.acc_bias_m2ps4])
    sensors = TrueSensors(**{**SENSORS.__dict__, "baro_bias_m": dh, "acc_bias_mps2": da})
    flight = paper_flight(seed=seed, sensors=sensors, schedule=SCHEDULE, h0_m=h0, v0_mps=v0)
    samples, b = with_gnss_gauss_markov(flight.samples, GM_SIGMA_M, GM_TAU_S, seed=10_000 + seed)
    return flight, samples, b


def epochs_of(samples, cfg):
    builder = EpochBuilder(cfg)
    return [ep for s in samples for ep in builder.push(s)]


def run_bank(epochs, cfg, flight):
    """NEES of [H, Vz] at sampled epochs and the GNSS row's NIS at every GNSS epoch."""
    bank = ChannelBank(Model.from_config(cfg))
    nees, nis = [], []
    n = 0
    for ep in epochs:
        if isinstance(ep, EpochStart):
            bank.start(ep.t_us, ep.baro_m)
            continue
        out = bank.step(ep)
        n += 1
        if ep.gnss is not None:
            nis.append(out.innovation[GNSS, 1] ** 2 / out.innovation_var[GNSS, 1])
        if n % SAMPLE_EVERY == 0:
            h, v = flight.truth_at(ep.t_us)
            e = np.array([h, v]) - bank.x[GNSS, [H, VZ]]
            P = bank.P[GNSS][np.ix_([H, VZ], [H, VZ])]
            nees.append(float(e @ np.linalg.solve(P, e)))
    return np.array(nees), np.array(nis)


@pytest.fixture(scope="module")
def monte_carlo():
    out = {"gm": ([], []), "white": ([], [])}
    for seed in range(RUNS):
        flight, samples, _ = flight_from_prior(2000 + seed)
        eps = epochs_of(samples, CFG_GM)
        for key, cfg in (("gm", CFG_GM), ("white", CFG_WHITE)):
            nees, nis = run_bank(eps, cfg, flight)
            out[key][0].append(nees)
            out[key][1].append(nis)
    return {k: (np.array(a), np.array(b)) for k, (a, b) in out.items()}


def nees_bounds(runs: int, dof: int = 2, level: float = 0.95):
    """Two-sided bounds of the NEES averaged over ``runs`` independent runs."""
    return stats.chi2.ppf([(1 - level) / 2, (1 + level) / 2], dof * runs) / runs


def test_gnss_channel_is_consistent_with_the_gauss_markov_state(monte_carlo):
    nees, nis = monte_carlo["gm"]
    anees = nees.mean(axis=0)  # average over runs at each sampled epoch
    lo, hi = nees_bounds(RUNS)
    outside = np.mean((anees < lo) | (anees > hi))
    assert outside <= 0.10, f"{outside:.0%} of sampled epochs outside [{lo:.2f}, {hi:.2f}]: {np.round(anees, 2)}"
    # over the whole flight too (the epochs of one run are correlated: each run
    # counts as at least one independent 2-dof sample, so the same bounds hold)
    assert lo <= anees.mean() <= hi, (anees.mean(), lo, hi)
    # the GNSS row's NIS: chi-square with one dof per sample, innovations white
    m = nis.size
    nlo, nhi = stats.chi2.ppf([0.025, 0.975], m) / m
    assert nlo <= nis.mean() <= nhi, (nis.mean(), nlo, nhi)


def test_white_only_model_is_far_over_confident_on_the_same_data(monte_carlo):
    """The point of the state: the same flights through the GNSS-white-only
    filter (gm_sigma_m 0, the filter before this change) give a NEES far above
    its bound."""
    nees, nis = monte_carlo["white"]
    anees = nees.mean(axis=0)
    lo, hi = nees_bounds(RUNS)
    assert np.mean(anees > hi) >= 0.9
    assert anees.mean() > 10 * hi, anees.mean()
    # its GNSS innovations look only mildly too large: the white-only filter
    # follows the wandering GNSS with its height, which is where the error goes
    m = nis.size
    assert nis.mean() > stats.chi2.ppf(0.975, m) / m, nis.mean()


def step_response(seed: int, gm_sigma_m: float, step_t: float = 200.0, step_m: float = 10.0):
    """Normalised GNSS innovation and the moves of H and b_g in the GNSS channel
    at the first GNSS sample of a ``step_m`` GNSS step after ``step_t`` s on
    white + Gauss-Markov GNSS error; also the largest |innovation| / sigma in
    the minute before the step."""
    cfg = cfg_with(gm_sigma_m)
    sched = dataclasses.replace(SCHEDULE, duration_s=step_t + 5.0)
    flight = paper_flight(seed=seed, sensors=SENSORS, schedule=sched)
    samples, _ = with_gnss_gauss_markov(flight.samples, GM_SIGMA_M, GM_TAU_S, seed=seed + 50)
    t_step_us = int(flight.t_us[0]) + int(step_t * 1e6)
    samples = [dataclasses.replace(s, height_ref_m=s.height_ref_m + step_m)
               if isinstance(s, GnssHeight) and s.t_us >= t_step_us else s for s in samples]
    bank = ChannelBank(Model.from_config(cfg))
    z_before = []
    for ep in epochs_of(samples, cfg):
        if isinstance(ep, EpochStart):
            bank.start(ep.t_us, ep.baro_m)
            continue
        if ep.gnss is not None and ep.t_us >= t_step_us:
            r_pred, s_pred = bank.predicted_aux(GNSS, ep, ep.gnss)  # the monitor's gate
            x0 = bank.x[GNSS].copy()
            out = bank.step(ep)
            z = out.innovation[GNSS, 1] / np.sqrt(out.innovation_var[GNSS, 1])
            assert np.isclose(r_pred / np.sqrt(s_pred), z, rtol=1e-9)
            return z, bank.x[GNSS, H] - x0[H], bank.x[GNSS, GB] - x0[GB], max(z_before)
        out = bank.step(ep)
        if ep.gnss is not None and ep.t_us >= t_step_us - int(60e6):
            z_before.append(abs(out.innovation[GNSS, 1]) / np.sqrt(out.innovation_var[GNSS, 1]))
    raise AssertionError("no GNSS sample after the step")


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_gnss_step_is_not_absorbed_by_the_gauss_markov_state(seed):
    """A 10 m GNSS step: its first sample's innovation exceeds 5 sigma (the
    monitor's gate sees the same number), nearly as large as without the
    Gauss-Markov state, and the slow state takes only a small part of it."""
    z, dh, db, z_before = step_response(seed, GM_SIGMA_M)
    z_white, _, db_white, _ = step_response(seed, 0.0)
    assert z_before < 4.0  # nominal before the step
    assert z > 5.0, z
    assert z > 0.9 * z_white, (z, z_white)
    assert db_white == 0.0
    assert 0.0 < db < 1.0, db  # under a tenth of the step into b_g
    assert db < 0.5 * dh, (db, dh)
