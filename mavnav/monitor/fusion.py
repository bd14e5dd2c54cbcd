"""Fusion of the passing channels' heights (at most three: closed form on floats)."""

from __future__ import annotations

import math
from typing import Sequence


def _solve_ones(cov: Sequence[Sequence[float]]) -> list[float]:
    """``Sigma^-1 1`` for a 1x1, 2x2 or 3x3 symmetric ``Sigma`` (Cramer)."""
    n = len(cov)
    if n == 1:
        return [1.0 / cov[0][0]]
    if n == 2:
        a, b, d = cov[0][0], cov[0][1], cov[1][1]
        det = a * d - b * b
        return [(d - b) / det, (a - b) / det]
    (a, b, c), (_, e, f), (_, _, i) = cov
    A = e * i - f * f
    B = c * f - b * i
    C = b * f - c * e
    E = a * i - c * c
    F = b * c - a * f
    I = a * e - b * b
    det = a * A + b * B + c * C
    return [(A + B + C) / det, (B + E + F) / det, (C + F + I) / det]


def fuse_heights(heights: Sequence[float], cov: Sequence[Sequence[float]],
                 inverse_variance: bool) -> tuple[float, float, list[float]]:
    """Combine channel heights with error covariance ``cov`` (the channels'
    ``P_HH`` and cross terms). Returns ``(height, sigma, weights)``.

    ``inverse_variance``: the best linear unbiased combination, weights
    ``Sigma^-1 1 / (1^T Sigma^-1 1)``, which accounts for the errors the
    channels share. Otherwise the paper's arithmetic mean (its variance still
    computed from ``cov``, so the reported sigma stays honest).
    """
    n = len(heights)
    if n == 0:
        return math.nan, math.nan, []
    w = None
    if inverse_variance and n > 1:
        try:
            u = _solve_ones(cov)
            tot = sum(u)
            if tot > 0 and all(math.isfinite(v) for v in u):
                w = [v / tot for v in u]
        except ZeroDivisionError:
            w = None
        if w is None:
            inv = [1.0 / cov[k][k] for k in range(n)]
            tot = sum(inv)
            w = [v / tot for v in inv]
    if w is None:
        w = [1.0 / n] * n
    var = sum(w[a] * w[b] * cov[a][b] for a in range(n) for b in range(n))
    h = sum(wi * hi for wi, hi in zip(w, heights))
    return h, math.sqrt(max(var, 0.0)), w
