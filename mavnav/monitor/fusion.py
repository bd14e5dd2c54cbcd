"""Fusion of the passing channels' heights."""

from __future__ import annotations

import math

import numpy as np


def fuse_heights(heights: np.ndarray, cov: np.ndarray, inverse_variance: bool) -> tuple[float, float, np.ndarray]:
    """Combine channel heights with error covariance ``cov`` (n x n, the channels'
    ``P_HH`` and cross terms). Returns ``(height, sigma, weights)``.

    ``inverse_variance``: the best linear unbiased combination, weights
    ``Sigma^-1 1 / (1^T Sigma^-1 1)``, which accounts for the errors the
    channels share. Otherwise the paper's arithmetic mean (its variance still
    computed from ``cov``, so the reported sigma stays honest).
    """
    n = heights.size
    if n == 0:
        return math.nan, math.nan, np.zeros(0)
    ones = np.ones(n)
    if inverse_variance and n > 1:
        try:
            w = np.linalg.solve(cov, ones)
            w = w / w.sum()
        except np.linalg.LinAlgError:
            w = 1.0 / np.diag(cov)
            w = w / w.sum()
    else:
        w = ones / n
    var = float(w @ cov @ w)
    return float(w @ heights), math.sqrt(max(var, 0.0)), w
