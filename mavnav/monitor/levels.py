"""Test thresholds from probabilities (computed once, at start-up).

The quantiles come from :mod:`scipy.special` (``ndtri``, ``chdtri``,
``gammaincinv``), imported on first use: these are the functions
``scipy.stats.norm`` and ``scipy.stats.chi2`` evaluate, without the 0.5 s
import of :mod:`scipy.stats` (``tests/test_monitor_levels.py`` checks they
give the same floats). ``+ 0.0`` is the ``* scale + loc`` of a frozen
scipy.stats distribution (it turns a ``-0.0`` into ``0.0``).
"""

from __future__ import annotations

from functools import lru_cache


def normal_k(p_two_sided: float) -> float:
    """``k`` such that ``P(|N(0,1)| > k) = p``."""
    from scipy.special import ndtri

    return float(-ndtri(p_two_sided / 2.0)) + 0.0


def chi2_gate(p: float, dof: int = 1) -> float:
    """Upper ``1 - p`` quantile of chi-square with ``dof`` degrees of freedom."""
    from scipy.special import chdtri

    return float(chdtri(dof, p)) + 0.0


@lru_cache(maxsize=4096)
def chi2_window(n: int, p_two_sided: float) -> tuple[float, float]:
    """Two-sided bounds of a sum of ``n`` squared standard normals."""
    from scipy.special import chdtri, gammaincinv

    q = p_two_sided / 2.0
    return float(2.0 * gammaincinv(n / 2.0, q)) + 0.0, float(chdtri(n, q)) + 0.0
