"""The baro's white noise before it is measured: the prior, then the window's
estimate as it fills.

The white noise is measured at run time from the baro's own second
differences (docs/error_models.md). Before five of them exist, and while the
significance test cannot yet tell the estimate from the model's ``u`` (17
samples on flug_1x_wo_Last_5m's 5 Hz PX4 baro), none was passed: the first
differenced baro rows were the surest of the flight exactly when the speed
is least known, and a vehicle at rest took its speed from the baro's
sample-to-sample noise (flug_1x: +0.9 m/s on the ground, every channel 1.2 m
up before the take-off, its fused height 1-1.6 m above the baro, the GNSS
and the autopilot for the whole flight). Now the filters take
``sensors.baro.white_prior_m`` (0.43 m, the noisiest real baros' 90th
percentile) until five second differences exist, then the window's own
estimate while it fills; the significance test decides only once it is full.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from mavnav.bank import BARO, ChannelBank
from mavnav.channel import Model
from mavnav.config import load_config
from mavnav.epochs import EpochBuilder, EpochStart
from mavnav.samples import BaroHeight, SpecificForceUp

G = 9.80665


def _at_rest(seed: int, white_m: float, baro_hz: float = 5.0, seconds: float = 12.0):
    """A vehicle at rest on the ground: a 200 Hz IMU reading gravity with
    0.05 m/s^2 of noise, a baro reading 0 m with ``white_m`` of white noise."""
    r = np.random.default_rng(seed)
    every = int(round(200 / baro_hz))
    items = []
    for k in range(int(seconds * 200)):
        t_us = k * 5000
        items.append(SpecificForceUp(t_us, 0.0, 0, G + 0.05 * r.standard_normal(), "test"))
        if k % every == 0:
            items.append(BaroHeight(t_us, 0.0, 0, white_m * r.standard_normal(), 1e5 - k * 1e-3, 1))
    return items


def _ground_start(seed: int, cfg):
    """The baro channel over a ground start at the datum (the speed's prior of
    a vehicle at rest, as the monitor starts it): its speeds, their variances
    and the white noise each epoch carried."""
    b = EpochBuilder(cfg)
    bank = ChannelBank(Model.from_config(cfg), track_cross=False)
    v, pvv, white = [], [], []
    for s in _at_rest(seed, 0.35):
        for ep in b.push(s):
            if isinstance(ep, EpochStart):
                bank.start(ep.t_us, ep.baro_m, cfg.filter.p0.baro_bias_at_datum_m2, cfg.filter.p0.vel_at_datum_m2ps2)
                continue
            bank.step(ep)
            v.append(float(bank.x[BARO, 1]))
            pvv.append(float(bank.P[BARO, 1, 1]))
            white.append(ep.baro_white_var_m2)
    return np.asarray(v), np.asarray(pvv), np.asarray(white)


def test_the_prior_is_carried_until_five_second_differences_then_the_estimate():
    cfg = load_config(None)
    prior = cfg.sensors.baro.white_prior_m
    _, _, white = _ground_start(1, cfg)
    # the first epoch's baro is the third sample: one second difference
    assert white[0] == pytest.approx(prior ** 2)
    assert white[1] == pytest.approx(prior ** 2)
    # from the fifth second difference on, the samples' own (0.35 m, within the
    # estimate's scatter over 5-60 samples), no longer the prior
    later = np.sqrt(white[10:55])
    assert np.all(later != prior)
    assert 0.2 < float(np.median(later)) < 0.5


@pytest.mark.parametrize("seed", range(1, 9))
def test_a_noisy_baro_at_rest_does_not_set_the_speed(seed):
    """A PX4-like baro (0.35 m of white noise at 5 Hz) on a vehicle at rest:
    the speed stays within its own uncertainty (before: up to 2.4 m/s and a
    mean normalised error of 11.6 on seed 3, the speed 10 sigma off)."""
    cfg = load_config(None)
    v, pvv, _ = _ground_start(seed, cfg)
    nees = v * v / pvv
    assert float(np.max(np.abs(v))) < 0.8
    assert float(np.mean(nees)) < 1.0
    assert float(np.max(nees)) < 9.0


def test_paper_mode_passes_no_white_noise():
    cfg = load_config(None)
    cfg = cfg.model_copy(update={"monitor": cfg.monitor.model_copy(update={"mode": "paper"})})
    _, _, white = _ground_start(1, cfg)
    assert not np.any(white)


def test_the_prior_is_held_within_the_configured_bounds():
    cfg = load_config(None)
    baro = cfg.sensors.baro.model_copy(update={"white_prior_m": 2.0, "white_max_m": 0.5})
    cfg = cfg.model_copy(update={"sensors": cfg.sensors.model_copy(update={"baro": baro})})
    assert EpochBuilder(cfg).baro_white_var_m2 == pytest.approx(0.25)
    assert math.isfinite(EpochBuilder(load_config(None)).baro_white_var_m2)
