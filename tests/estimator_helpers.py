"""Shared helpers for the estimator tests: run channels over synthetic flights."""

from __future__ import annotations

import numpy as np

from mavnav.channel import CHANNELS, Model, initial_state, step
from mavnav.config import config_from_dict
from mavnav.epochs import EpochBuilder, EpochStart
from mavnav.synthetic import TrueSensors


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
                "gnss": {"sigma_z_m": sensors.sigma_z_m, "use_v_acc": False},
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
    """Estimation errors [H, Vz, dH, da] and covariances at each epoch."""
    errs, covs = [], []
    for t_us, x, P, _ in rows:
        h, v = flight.truth_at(t_us)
        truth = np.array([h, v, flight.baro_bias_m, flight.acc_bias_mps2])
        errs.append(x - truth)
        covs.append(P)
    return np.array(errs), np.array(covs)
