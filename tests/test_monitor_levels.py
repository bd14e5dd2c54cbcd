"""``monitor.levels`` against scipy.stats, float for float.

The thresholds come from :mod:`scipy.special` so that starting the monitor
does not import :mod:`scipy.stats`; they must be the very floats
``stats.norm.isf`` and ``stats.chi2.isf``/``ppf`` give (the decisions
compare against them), on the configured probabilities and around them.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from mavnav.config import Config
from mavnav.monitor import levels

PROBS = sorted({*np.geomspace(1e-12, 0.999, 60).tolist(), 1e-7, 1e-5, 1e-3, 0.01, 0.05, 0.1, 0.5, 0.9, 1.0, 0.0})


def _same(a: float, b: float) -> bool:
    return (math.isnan(a) and math.isnan(b)) or (a == b and math.copysign(1, a) == math.copysign(1, b))


@pytest.mark.parametrize("p", PROBS)
def test_normal_k_is_scipy_stats(p):
    assert _same(levels.normal_k(p), float(stats.norm.isf(p / 2.0)))


@pytest.mark.parametrize("dof", [1, 2, 3, 5])
@pytest.mark.parametrize("p", PROBS)
def test_chi2_gate_is_scipy_stats(p, dof):
    assert _same(levels.chi2_gate(p, dof), float(stats.chi2.isf(p, dof)))


@pytest.mark.parametrize("n", [1, 2, 5, 10, 25, 61, 200])
@pytest.mark.parametrize("p", [1e-9, 1e-5, 1e-3, 0.01, 0.05, 0.3])
def test_chi2_window_is_scipy_stats(n, p):
    lo, hi = levels.chi2_window(n, p)
    assert _same(lo, float(stats.chi2.ppf(p / 2.0, n)))
    assert _same(hi, float(stats.chi2.isf(p / 2.0, n)))


def test_configured_thresholds_are_scipy_stats():
    m = Config().monitor
    for p in (m.integrity_risk, m.false_alarm_prob):
        assert _same(levels.normal_k(p), float(stats.norm.isf(p / 2.0)))
    for p in (m.gate_prob, m.baro_jump_prob):
        assert _same(levels.chi2_gate(p), float(stats.chi2.isf(p, 1)))
