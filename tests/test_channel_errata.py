"""The errata of MODEL.md, shown numerically so no one restores the printed forms."""

from __future__ import annotations

import numpy as np

from mavnav.channel import (H_BARO, DH, H, N_PAPER, N_STATES, Model, baro_gauss_markov, prior_covariance,
                            process_noise, transition)
from mavnav.config import load_config
from mavnav.covariance import covariance_series
from mavnav.kalman import posterior_cov_short

PAPER = "config/paper_2015_covariance.yaml"


def _baro_gnss_recursion(model: Model, T: float, sigma_z: float, n: int, published_sign: bool):
    """Channel 1's covariance recursion in the paper's own form (17), with the
    baro entry of Byy either corrected (+gamma_u^2) or as printed (-phi_u^2)."""
    Phi = transition(T)
    Bxx = process_noise(T, model)
    phi_u, gamma_u = baro_gauss_markov(T, model)
    h_b = H_BARO[:N_PAPER]  # the paper's 4 states
    h_g = np.array([1.0, 0.0, 0.0, 0.0])
    Hm = np.array([h_b, h_g])
    Phi_y = np.array([h_b @ Phi - phi_u * h_b, h_g @ Phi])
    Bxy = Bxx @ Hm.T
    baro_term = -(phi_u**2) if published_sign else gamma_u**2
    Byy = Hm @ Bxx @ Hm.T + np.diag([baro_term, sigma_z**2])
    P = np.diag(np.asarray(model.p0_diag, float))
    min_eigs = []
    for _ in range(n):
        P = posterior_cov_short(P, Phi, Bxx, Phi_y, Bxy, Byy)
        P = 0.5 * (P + P.T)
        min_eigs.append(np.linalg.eigvalsh(P)[0])
    return np.array(min_eigs)


def test_published_sign_of_baro_byy_makes_P_indefinite():
    cfg = load_config(PAPER)
    model = Model.from_config(cfg)
    T, sz = cfg.filter.step_s, cfg.sensors.gnss.sigma_z_m
    wrong = _baro_gnss_recursion(model, T, sz, 200, published_sign=True)
    right = _baro_gnss_recursion(model, T, sz, 2000, published_sign=False)
    first_bad = int(np.argmax(wrong < 0)) + 1
    assert wrong.min() < 0 and first_bad <= 100, "the printed -phi_u^2 must break P quickly"
    assert right.min() > 0, "the corrected +gamma_u^2 keeps P positive definite"


def test_channel_3_observes_only_height_plus_bias():
    cfg = load_config(PAPER)
    s = covariance_series(cfg, "baro", duration_s=20.0)
    model = Model.from_config(cfg)
    # P_HH does not converge: it stays near its prior share, far above the baro noise.
    assert s.rms_height_m[-1] > 10.0
    assert s.rms_height_m[-1] > 0.5 * s.rms_height_m[len(s.t_s) // 10]
    # ...while the variance of H + dH collapses (recomputed from the full P).
    from mavnav.channel import ChannelState, EpochInputs, step

    state = ChannelState(x=np.zeros(N_STATES), P=prior_covariance(model), t_us=0, baro_prev_m=0.0)
    for k in range(1, 1001):
        state, _ = step("baro", state, EpochInputs(t_us=k * 20000, dt_s=0.02, dp_m=0.0, dv_mps=0.0, baro_m=0.0), model)
    var_sum = state.P[H, H] + state.P[DH, DH] + 2 * state.P[H, DH]
    assert var_sum < 1.0 < state.P[H, H]
    assert state.P[H, DH] < -0.9 * np.sqrt(state.P[H, H] * state.P[DH, DH])  # strongly anti-correlated


def test_printed_accel_noise_form_starves_the_filter():
    """q_a printed (sqrt(2T/alpha)) is T times smaller than the consistent form."""
    cfg = load_config(PAPER)
    m_printed = Model.from_config(cfg)
    m_cons = Model.from_config(cfg.model_copy(update={"filter": cfg.filter.model_copy(update={"accel_noise_form": "consistent"})}))
    T = 0.02
    ratio = process_noise(T, m_cons)[1, 1] / process_noise(T, m_printed)[1, 1]
    assert np.isclose(ratio, 1.0 / T**2)
