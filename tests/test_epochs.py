"""The epoch builder: INS pre-integration, aux alignment, gaps."""

from __future__ import annotations

import math

import pytest

from mavnav.config import load_config
from mavnav.epochs import EpochBuilder, EpochStart
from mavnav.samples import BaroHeight, GnssHeight, RangeHeight, Reboot, SpecificForceUp

G = 9.80665


def imu(t_s, f=G):
    return SpecificForceUp(int(round(t_s * 1e6)), 0.0, 0, f, "test")


def baro(t_s, h=0.0, p_pa=None):
    # a distinct pressure per sample unless given: exact repeats are a resent measurement
    return BaroHeight(int(round(t_s * 1e6)), 0.0, 0, h, 1e5 - 12.0 * h - t_s if p_pa is None else p_pa, 1)


def rng(t_s, h=1.0):
    return RangeHeight(int(round(t_s * 1e6)), 0.0, 0, h, h, "test")


def gnss(t_s, h=1.0):
    return GnssHeight(int(round(t_s * 1e6)), 0.0, 0, h, h, None, 3, 10)


def feed(b, items):
    out = []
    for s in items:
        out += b.push(s)
    return out


def test_zero_order_hold_integration_is_exact_for_piecewise_constant_acceleration():
    b = EpochBuilder(load_config(None))
    # 1 m/s^2 up from 0.0 to 0.05 s, then 3 m/s^2 from 0.05 to 0.1 s; epoch at 0.1 s
    eps = feed(b, [imu(0.0, G + 1.0), baro(0.0), imu(0.05, G + 3.0), imu(0.1, G), baro(0.1)])
    assert isinstance(eps[0], EpochStart)
    ep = eps[1]
    assert ep.dt_s == pytest.approx(0.1)
    assert ep.dv_mps == pytest.approx(1.0 * 0.05 + 3.0 * 0.05)
    # p = 0.5*1*0.05^2 + (0.05*0.05 + 0.5*3*0.05^2)
    assert ep.dp_m == pytest.approx(0.5 * 0.0025 + 0.05 * 0.05 + 0.5 * 3 * 0.0025)


def test_aux_stream_leading_the_baro_clock_at_the_same_rate_is_not_lost():
    """Rangefinder 30 ms ahead of the baro, both at 10 Hz: every sample must be
    used at the next epoch (keeping only the newest lost them all)."""
    b = EpochBuilder(load_config(None))
    items = [imu(0.0), baro(0.0)]
    for k in range(1, 50):
        t = 0.1 * k
        items += [rng(t - 0.07), imu(t), baro(t)]
    eps = [e for e in feed(b, items) if not isinstance(e, EpochStart)]
    used = [e for e in eps if e.rng is not None]
    assert len(used) == len(eps) and all(abs(e.rng.age_s - 0.07) < 1e-9 for e in used)
    assert b.counters["rng_superseded"] == 0


def test_every_pending_aux_sample_is_used_averaged_and_future_ones_wait():
    b = EpochBuilder(load_config(None))
    eps = feed(b, [imu(0.0), baro(0.0), gnss(0.02, 1.0), gnss(0.05, 2.0), gnss(0.15, 3.0), imu(0.1), baro(0.1),
                   imu(0.2), baro(0.2)])
    e1, e2 = [e for e in eps if not isinstance(e, EpochStart)]
    sigma = load_config(None).sensors.gnss.sigma_z_m
    assert e1.gnss.height_m == pytest.approx(1.5) and e1.gnss.age_s == pytest.approx(0.065)
    assert e1.gnss.sigma_m == pytest.approx(sigma / math.sqrt(2))
    assert e2.gnss.height_m == 3.0 and e2.gnss.age_s == pytest.approx(0.05)
    assert b.counters["gnss_used"] == 3 and b.counters["gnss_superseded"] == 0


def test_baro_gap_forces_epochs_and_restarts_the_differencing():
    cfg = load_config(None)
    b = EpochBuilder(cfg)
    items = [imu(0.0), baro(0.0)]
    items += [imu(0.01 * k) for k in range(1, 101)]  # 1 s of IMU, no baro
    items += [baro(1.0)] + [imu(1.0 + 0.01 * k) for k in range(1, 5)] + [baro(1.04)]
    eps = [e for e in feed(b, items) if not isinstance(e, EpochStart)]
    forced = [e for e in eps if e.baro_m is None]
    assert len(forced) >= int(0.9 / cfg.filter.max_epoch_gap_s)
    assert all(e.dt_s <= cfg.filter.max_epoch_gap_s + 0.011 for e in forced)
    after = [e for e in eps if e.baro_m is not None]
    assert after[0].baro_restart and not after[-1].baro_restart


def test_late_aux_is_dropped_and_counted_and_a_reboot_resets():
    b = EpochBuilder(load_config(None))
    feed(b, [imu(1.0), baro(1.0), imu(1.1), baro(1.1)])
    feed(b, [gnss(0.5)])  # 0.6 s older than the last epoch
    assert b.counters["gnss_late"] == 1
    b.push(Reboot(t_us=10_000, recv_s=0.0, boot=1, last_t_us=1_100_000))
    assert not b.started
    eps = feed(b, [imu(0.01), baro(0.02)])
    assert isinstance(eps[0], EpochStart) and eps[0].t_us == 20_000
    assert math.isfinite(eps[0].baro_m)
