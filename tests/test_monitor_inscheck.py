"""The baro/INS second-difference check (mavnav/monitor/inscheck.py) on exact
trajectories: what it reads with and without an accelerometer bias, and the
bias correction from the channel's estimate."""

from __future__ import annotations

import numpy as np
import pytest

from mavnav.monitor.inscheck import InsBaroCheck

pytestmark = [pytest.mark.unit]


def _fly(bias_mps2: float, da_est_mps2: float, dt_s: float = 0.1, window_s: float = 2.0, n: int = 60):
    """Climb with a constant true acceleration; the INS increments carry
    ``bias_mps2`` and the channel's estimate of it is ``da_est_mps2``."""
    a_true, v0, h0 = 0.3, 1.0, 10.0
    chk = InsBaroCheck(window_s)
    x = np.zeros(5)
    x[3] = da_est_mps2
    P = np.eye(5) * 1e-6
    out = []
    for k in range(1, n + 1):
        t = k * dt_s
        a = a_true + bias_mps2
        dp, dv = 0.5 * a * dt_s ** 2, a * dt_s  # from zero initial velocity, as the epoch builder gives them
        if k == 1:  # the chained INS starts at the true velocity
            dp += v0 * dt_s
            dv += v0
        baro = h0 + v0 * t + 0.5 * a_true * t * t
        chk.push(int(round(t * 1e6)), dt_s, dp, dv, baro, x, P)
        res = chk.residual(0.0, 0.0, 0.0, 0.0, 1.0)
        if res is not None:
            out.append(res[0])
    return out


def test_an_ins_that_follows_the_baro_reads_zero():
    e = _fly(0.0, 0.0)
    assert e and max(abs(v) for v in e) < 1e-9


def test_an_accelerometer_bias_reads_its_second_difference_and_a_known_bias_nothing():
    # equal windows of 2 s: the bias shows as c D^2 (the INS climbs faster than the baro: e < 0)
    e = _fly(0.5, 0.0)
    assert e[-1] == pytest.approx(-0.5 * 2.0 ** 2, rel=0.05)
    # the channel's estimate of the same bias takes it out (before the fix it took out twice as much)
    e = _fly(0.5, 0.5)
    assert max(abs(v) for v in e) < 1e-6
