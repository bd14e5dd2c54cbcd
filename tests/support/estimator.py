"""Shared helpers for the estimator tests: run channels over synthetic flights."""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from mavnav.channel import CHANNELS, GB, N_PAPER, Model, initial_state, step
from mavnav.config import config_from_dict
from mavnav.epochs import EpochBuilder, EpochStart
from mavnav.samples import GnssHeight
from tests.support.synthetic import TrueSensors


def config_for(sensors: TrueSensors, **filter_opts):
    return config_from_dict(
        {
            "sensors": {
                # the truth's biases are constants and its noises white: the
                # filter's model must say exactly that (no random walks, no
                # height-proportional rangefinder noise)
                "ins": {"sigma_a_mps2": sensors.sigma_a_mps2, "alpha_a_per_s": sensors.alpha_a_per_s,
                        "bias_rw_mps2_per_sqrt_s": 0.0},
                "baro": {"sigma_bb_m": sensors.sigma_bb_m, "gamma_bb_per_s": sensors.gamma_bb_per_s,
                         "bias_rw_m_per_sqrt_s": 0.0},
                "gnss": {"sigma_z_m": sensors.sigma_z_m, "use_v_acc": False, "gm_sigma_m": 0.0},
                "rangefinder": {"sigma_m": sensors.sigma_rng_m, "scale_sigma_frac": 0.0},
            },
            "filter": {
                "p0": {"height_m2": 100.0, "vel_m2ps2": 1.0, "baro_bias_m2": 100.0, "acc_bias_m2ps4": 0.04},
                **filter_opts,
            },
        }
    )


def run_channels(flight, cfg, kinds=CHANNELS):
    """Run each channel kind over a flight; returns per kind a list of
    (t_us, x, P, output) after every epoch (the start epoch has output None)."""
    model = Model.from_config(cfg)
    builder = EpochBuilder(cfg)
    states = {}
    hist = {k: [] for k in kinds}
    for s in flight.samples:
        for ep in builder.push(s):
            for k in kinds:
                if isinstance(ep, EpochStart):
                    states[k] = initial_state(model, ep.t_us, ep.baro_m)
                    out = None
                else:
                    states[k], out = step(k, states[k], ep, model)
                hist[k].append((states[k].t_us, states[k].x, states[k].P, out))
    return hist, builder


def state_errors(flight, rows):
    """Estimation errors [H, Vz, dH, da] and their covariances at each epoch
    (the synthetic GNSS noise is white: the GNSS error state, off in
    :func:`config_for`, must stay exactly 0 with zero variance)."""
    errs, covs = [], []
    for t_us, x, P, _ in rows:
        h, v = flight.truth_at(t_us)
        truth = np.array([h, v, flight.baro_bias_m, flight.acc_bias_mps2])
        assert x[GB] == 0.0 and not P[GB].any()
        errs.append(x[:N_PAPER] - truth)
        covs.append(P[:N_PAPER, :N_PAPER])
    return np.array(errs), np.array(covs)


def with_gnss_gauss_markov(samples, sigma_m: float, tau_s: float, seed: int):
    """``samples`` with a first-order Gauss-Markov error added to every GNSS
    height: ``b(0) ~ N(0, sigma^2)`` at the first GNSS sample, then exactly
    discretised between samples (``phi = exp(-dt / tau)``, innovation RMS
    ``sigma sqrt(1 - phi^2)``). Returns ``(samples, {t_us: b})``."""
    rng = np.random.default_rng(seed)
    b = sigma_m * rng.standard_normal()
    t_prev = None
    out, truth = [], {}
    for s in samples:
        if isinstance(s, GnssHeight):
            if t_prev is not None:
                phi = math.exp(-(s.t_us - t_prev) * 1e-6 / tau_s)
                b = phi * b + sigma_m * math.sqrt(1.0 - phi * phi) * rng.standard_normal()
            t_prev = s.t_us
            truth[s.t_us] = b
            s = dataclasses.replace(s, height_ref_m=s.height_ref_m + b, alt_m=s.alt_m + b)
        out.append(s)
    return out, truth
