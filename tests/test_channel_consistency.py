"""Seeded Monte Carlo: every channel's errors and innovations are consistent
with its own covariances (NEES, NIS, whiteness), for constant and irregular
steps and for multi-rate sensors with gaps."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from mavnav.channel import CHANNELS
from tests.support.synthetic import Schedule, TrueSensors, paper_flight

from tests.support.estimator import config_for, run_channels, state_errors

pytestmark = [pytest.mark.simulation, pytest.mark.slow]

SENSORS = TrueSensors(sigma_a_mps2=0.2, alpha_a_per_s=1.0, sigma_bb_m=1.0, gamma_bb_per_s=2.0, sigma_z_m=1.5)
RUNS = 24

SCHEDULES = {
    "constant": Schedule(duration_s=16.0, imu_dt_s=0.02),
    "irregular": Schedule(duration_s=16.0, imu_dt_s=0.02, irregular=0.5),
    "multirate_gaps": Schedule(
        duration_s=16.0,
        imu_dt_s=0.01,
        baro_every=3,
        gnss_every=20,
        rng_every=5,
        gaps={"gnss": [(5.0, 8.0)], "baro": [(10.0, 10.7)], "rng": [(12.0, 14.0)]},
    ),
}


def flight_from_prior(seed, schedule, cfg):
    """Truth drawn from the filter's own prior N(0, P0), as NEES requires."""
    p0 = cfg.filter.p0
    rng = np.random.default_rng(seed)
    h0, v0, dh, da = rng.standard_normal(4) * np.sqrt(
        [p0.height_m2, p0.vel_m2ps2, p0.baro_bias_m2, p0.acc_bias_m2ps4]
    )
    sensors = TrueSensors(**{**SENSORS.__dict__, "baro_bias_m": dh, "acc_bias_mps2": da})
    return paper_flight(seed=seed, sensors=sensors, schedule=schedule, h0_m=h0, v0_mps=v0)


def monte_carlo(schedule, kind):
    cfg = config_for(SENSORS)
    nees, nis, whites, dofs = [], [], [], []
    for seed in range(RUNS):
        flight = flight_from_prior(1000 + seed, schedule, cfg)
        hist, builder = run_channels(flight, cfg, kinds=(kind,))
        rows = hist[kind]
        e, P = state_errors(flight, rows)
        nees.append(np.einsum("ki,kij,kj->k", e, np.linalg.inv(P), e))
        nis.append([out.nis for *_, out in rows[1:]])
        dofs.append([out.dof for *_, out in rows[1:]])
        whites.append(np.concatenate([out.whitened for *_, out in rows[1:]]))
    return np.array(nees), np.array(nis), np.array(dofs), whites, builder


@pytest.mark.parametrize("schedule_name", list(SCHEDULES))
@pytest.mark.parametrize("kind", CHANNELS)
def test_nees_and_innovations_are_consistent(schedule_name, kind):
    schedule = SCHEDULES[schedule_name]
    nees, nis, dofs, whites, builder = monte_carlo(schedule, kind)
    if schedule_name == "multirate_gaps":
        assert builder.counters["forced_epochs"] > 0 and builder.counters["baro_restarts"] > 0
    # Average NEES over runs at sampled epochs: each ~ chi2(4 RUNS) / RUNS.
    anees = nees.mean(axis=0)
    epochs = np.arange(10, anees.size, 25)
    lo, hi = stats.chi2.ppf([0.0025, 0.9975], 4 * RUNS) / RUNS
    outside = np.mean((anees[epochs] < lo) | (anees[epochs] > hi))
    assert outside <= 0.06, f"{outside:.0%} of sampled epochs outside [{lo:.2f}, {hi:.2f}]"
    # Over everything, mean NEES within 10 % of the state dimension.
    assert abs(nees[:, 10:].mean() - 4.0) < 0.6
    # Normalised innovations: mean NIS per degree of freedom ~ 1.
    assert abs(nis.sum() / dofs.sum() - 1.0) < 0.05
    # Whitened innovations: unit variance, zero mean, white (lag-1 correlation).
    w = np.concatenate(whites)
    assert abs(w.mean()) < 4.0 / np.sqrt(w.size)
    r1 = np.mean([np.corrcoef(x[:-1], x[1:])[0, 1] for x in whites])
    assert abs(r1) < 0.05


def test_consistency_check_detects_a_mistuned_filter():
    """Same data, filter told the GNSS is 3x better than it is: NIS blows up."""
    schedule = SCHEDULES["constant"]
    bad = config_for(TrueSensors(**{**SENSORS.__dict__, "sigma_z_m": SENSORS.sigma_z_m / 3}))
    flight = paper_flight(seed=5, sensors=SENSORS, schedule=schedule)
    hist, _ = run_channels(flight, bad, kinds=("gnss",))
    nis = np.array([out.nis for *_, out in hist["gnss"][1:]])
    dof = np.array([out.dof for *_, out in hist["gnss"][1:]])
    assert nis.sum() / dof.sum() > 1.5
