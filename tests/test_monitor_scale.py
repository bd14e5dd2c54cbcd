"""ResidualScale's clipped properties (conditionals) against the max/min formulas they spell out."""

from __future__ import annotations

import math

import numpy as np

from mavnav.monitor.scale import ResidualScale


def _phi(s: ResidualScale) -> float:
    if s.m2 <= 0:
        return 0.0
    return max(0.0, min(s.max_phi, s.c1 / s.m2))


def _sd(s: ResidualScale) -> float:
    return max(s.lo, min(s.hi, math.sqrt(max(s.m2, 0.0))))


def _factor(s: ResidualScale) -> float:
    phi = _phi(s)
    lrv = s.m2 * (1.0 + phi) / (1.0 - phi)
    return max(s.lo, min(s.hi, math.sqrt(max(lrv, 0.0))))


SPECIAL = [0.0, -0.0, 1e-300, -1e-300, 0.3, 1.0, 2.5, 40.0, -0.5, -3.0, math.nan, math.inf, -math.inf]


def test_clipped_properties_are_the_max_min_formulas():
    rng = np.random.default_rng(5)
    for _ in range(20000):
        lo = float(rng.choice([0.0, 0.5, 1.0, 0.2]))
        hi = float(rng.choice([1.0, 3.0, 10.0, math.inf]))
        s = ResidualScale(30.0, lo, hi, max_phi=float(rng.choice([0.0, 0.5, 0.95])))
        s.m2 = float(rng.choice(SPECIAL)) if rng.random() < 0.5 else float(rng.lognormal(0.0, 2.0))
        s.c1 = float(rng.choice(SPECIAL)) if rng.random() < 0.5 else float(rng.normal(0.0, 2.0))
        for got, want in ((s.phi, _phi(s)), (s.sd, _sd(s)), (s.factor, _factor(s))):
            assert repr(got) == repr(want), (s.m2, s.c1, lo, hi, s.max_phi)


def test_the_comparison_can_fail():
    s = ResidualScale(30.0, 1.0, 3.0)
    s.m2 = 9.5
    assert repr(s.sd) != repr(math.sqrt(s.m2))  # clipped at hi
