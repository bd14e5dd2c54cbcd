"""Test thresholds from probabilities (computed once, at start-up)."""

from __future__ import annotations

from functools import lru_cache

from scipy import stats


def normal_k(p_two_sided: float) -> float:
    """``k`` such that ``P(|N(0,1)| > k) = p``."""
    return float(stats.norm.isf(p_two_sided / 2.0))


def chi2_gate(p: float, dof: int = 1) -> float:
    """Upper ``1 - p`` quantile of chi-square with ``dof`` degrees of freedom."""
    return float(stats.chi2.isf(p, dof))


@lru_cache(maxsize=4096)
def chi2_window(n: int, p_two_sided: float) -> tuple[float, float]:
    """Two-sided bounds of a sum of ``n`` squared standard normals."""
    return float(stats.chi2.ppf(p_two_sided / 2.0, n)), float(stats.chi2.isf(p_two_sided / 2.0, n))
