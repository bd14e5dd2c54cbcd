"""Covariance analysis: the filter's covariance recursion with no data.

Every channel is stepped at a constant ``T = filter.step_s`` with every one of
its measurements present at every step (as in the paper's covariance study),
starting from ``P0``. The recursion does not depend on the measured values, so
it uses the channel's own code (:func:`mavnav.channel.step`) on zero inputs:
there is no second implementation to drift from the filter.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .channel import (CHANNELS, DA, DH, H, N_PAPER, N_STATES, VZ, AuxMeasurement, ChannelState, EpochInputs, Model,
                      prior_covariance, step)
from .config import Config


@dataclass(frozen=True)
class CovarianceSeries:
    t_s: np.ndarray
    rms_height_m: np.ndarray
    rms_vel_mps: np.ndarray
    rms_baro_bias_m: np.ndarray
    rms_acc_bias_mps2: np.ndarray
    min_eig: np.ndarray  # smallest eigenvalue of P at each step (PD check)

    def as_json(self) -> dict:
        return {
            "t_s": [round(float(v), 6) for v in self.t_s],
            "rms_height_m": [float(v) for v in self.rms_height_m],
            "rms_vel_mps": [float(v) for v in self.rms_vel_mps],
            "rms_baro_bias_m": [float(v) for v in self.rms_baro_bias_m],
            "rms_acc_bias_mps2": [float(v) for v in self.rms_acc_bias_mps2],
        }


def covariance_series(cfg: Config, kind: str, duration_s: float) -> CovarianceSeries:
    model = Model.from_config(cfg)
    T = cfg.filter.step_s
    n = int(math.floor(duration_s / T + 1e-9))
    dt_us = int(round(T * 1e6))
    gnss = AuxMeasurement(height_m=0.0, sigma_m=cfg.sensors.gnss.sigma_z_m, age_s=0.0)
    rng = AuxMeasurement(height_m=0.0, sigma_m=cfg.sensors.rangefinder.sigma_m, age_s=0.0)
    state = ChannelState(x=np.zeros(N_STATES), P=prior_covariance(model), t_us=0, baro_prev_m=0.0)
    Ps = [state.P]
    for k in range(1, n + 1):
        ep = EpochInputs(t_us=k * dt_us, dt_s=T, dp_m=0.0, dv_mps=0.0, baro_m=0.0, gnss=gnss, rng=rng)
        state, _ = step(kind, state, ep, model)
        Ps.append(state.P)
    P = np.array(Ps)
    # with the GNSS error state off, b_g has exactly zero variance: PD is for the rest
    n_pd = N_STATES if model.gnss_gm_sigma_m > 0 else N_PAPER
    d = np.sqrt(np.maximum(np.einsum("kii->ki", P), 0.0))
    return CovarianceSeries(
        t_s=np.arange(n + 1) * T,
        rms_height_m=d[:, H],
        rms_vel_mps=d[:, VZ],
        rms_baro_bias_m=d[:, DH],
        rms_acc_bias_mps2=d[:, DA],
        min_eig=np.linalg.eigvalsh(P[:, :n_pd, :n_pd])[:, 0],
    )


def covariance_analysis(cfg: Config, duration_s: float) -> dict[str, CovarianceSeries]:
    return {kind: covariance_series(cfg, kind, duration_s) for kind in CHANNELS}
