"""Which sensor bent away: the onset of a ramp against the INS.

A GNSS (or rangefinder) drift against the baro implicates both: the baro/INS
second difference is blind to a ramp, and the level tests see only the gap
between the two. What tells them apart is the INS: a ramp that starts at
``tau`` adds ``a (t - tau)+`` to the faulty sensor's height, so the faulty
sensor's height minus the INS's position bends ("kinks") at ``tau`` and the
healthy sensor's does not. The INS's own unknowns over a short window, an
offset, a velocity and a constant accelerometer bias, are fitted out
(``c + v s + b s^2``); what remains of the kink is the GLR estimate of a ramp
onset (Willsky & Jones): for a regressor ``g = (s - tau)+`` made orthogonal
to the nuisance columns,

    a_hat = g'e / g'g,   z = g'e / (sigma sqrt(g'g)),

with ``e`` the residual of the nuisance fit. ``sigma`` is not the white noise
of the samples (GNSS wanders, the INS drifts, the baro has transients): it is
measured on the flight itself, as the scatter of ``z`` at a fixed onset while
nothing is suspect (:class:`MeanSquare`), so each flight's own noise sets how
sure the test can be.

:func:`isolate` weighs the two explanations of a drift of ``aux - baro``
that starts at ``tau`` (the onset where its kink is largest): an aux ramp
(``baro - INS`` does not kink) or a baro ramp (``aux - INS`` does not kink).
The kink of ``aux - baro`` is the difference of the other two, so the
evidence is those two alone: ``z_aux^2 - z_baro^2``, each kink over its
measured scatter, is the log-likelihood ratio of "the aux sensor bent"
against "the baro bent" (each with its slope free). Only a ratio beyond
``margin`` rules one out: blaming the baro wrongly needs the healthy baro's
kink past ``sqrt(margin)`` sigma by itself. On a flight whose INS is too
noisy the ratio stays small, nothing is ruled out and the monitor stays
unable to isolate, which is the truth.
"""

from __future__ import annotations

import math
from collections import deque
from typing import Optional

import numpy as np

try:  # np.linalg.qr's own gufuncs (numpy >= 1.22): its LAPACK calls without the wrapper's overhead
    from numpy.linalg import _umath_linalg

    _qr_raw, _qr_reduced = _umath_linalg.qr_r_raw, _umath_linalg.qr_reduced
except (ImportError, AttributeError):  # pragma: no cover
    _qr_raw = _qr_reduced = None


class KinkSeries:
    """``(t_s, y)`` over the last ``window_s``."""

    __slots__ = ("window_s", "t", "y")

    def __init__(self, window_s: float):
        self.window_s = window_s
        self.t: deque = deque()
        self.y: deque = deque()

    def push(self, t_s: float, y: float) -> None:
        if y != y or abs(y) == math.inf:
            return
        if self.t and t_s <= self.t[-1]:
            return
        self.t.append(t_s)
        self.y.append(y)
        while self.t and self.t[0] <= t_s - self.window_s:
            self.t.popleft()
            self.y.popleft()

    def clear(self) -> None:
        self.t.clear()
        self.y.clear()

    def arrays(self, t_now_s: float) -> tuple[np.ndarray, np.ndarray]:
        """Times relative to ``t_now_s`` (<= 0) and values."""
        return np.fromiter(self.t, float, len(self.t)) - t_now_s, np.fromiter(self.y, float, len(self.y))


def kink_fit(s: np.ndarray, y: np.ndarray, taus: np.ndarray, quadratic: bool) -> tuple[np.ndarray, np.ndarray]:
    """``(g'e, g'g)`` at each onset in ``taus`` (``s`` and ``taus`` relative
    times), the nuisance being an offset and a slope, and a curvature if
    ``quadratic`` (an accelerometer bias). :func:`kink_fit_reference`'s
    arithmetic, the orthonormal basis from the two LAPACK calls
    ``np.linalg.qr`` makes (``dgeqrf``, ``dorgqr``) without its wrapper
    (checks, R, error state: the series are finite, :meth:`KinkSeries.push`);
    ``tests/test_monitor_kink.py`` checks the two agree bit for bit."""
    if _qr_raw is None:  # pragma: no cover - numpy without its gufuncs
        return kink_fit_reference(s, y, taus, quadratic)
    X = np.empty((s.size, 3 if quadratic else 2))  # the nuisance columns, as the reference stacks them
    X[:, 0] = 1.0
    X[:, 1] = s
    if quadratic:
        np.multiply(s, s, out=X[:, 2])
    q = _qr_reduced(X, _qr_raw(X, signature="d->d"), signature="dd->d")  # dgeqrf in place, then dorgqr
    qt = q.T
    e = y - q @ (qt @ y)
    G = np.maximum(s[:, None] - taus[None, :], 0.0)
    MG = G - q @ (qt @ G)
    return G.T @ e, np.einsum("ij,ij->j", G, MG)


def kink_fit_reference(s: np.ndarray, y: np.ndarray, taus: np.ndarray,
                       quadratic: bool) -> tuple[np.ndarray, np.ndarray]:
    """The readable form of :func:`kink_fit`."""
    cols = [np.ones_like(s), s] + ([s * s] if quadratic else [])
    # the projection off the nuisance columns through their orthonormal basis
    # (X = QR; the same projection as X pinv(X), without the SVD)
    q, _ = np.linalg.qr(np.stack(cols, 1))
    e = y - q @ (q.T @ y)
    G = np.maximum(s[:, None] - taus[None, :], 0.0)
    MG = G - q @ (q.T @ G)
    return G.T @ e, np.einsum("ij,ij->j", G, MG)


def onsets(s: np.ndarray, min_pre_s: float, min_post_s: float) -> np.ndarray:
    """Candidate onsets: sample times with ``min_pre_s`` of data before and ``min_post_s`` after."""
    if s.size == 0:
        return s
    return s[(s >= s[0] + min_pre_s) & (s <= -min_post_s)]


def _fast_path_agrees() -> bool:
    """The gufunc path is numpy's private API: used only if, on this numpy, it
    gives the reference's floats on a fixed series (else the reference serves)."""
    if _qr_raw is None:
        return False
    s = np.linspace(0.0, 3.0, 17)
    y = np.sin(s) + 0.1 * s * s
    taus = np.array([0.5, 1.5, 2.5])
    try:
        for quadratic in (False, True):
            a, b = kink_fit(s, y, taus, quadratic), kink_fit_reference(s, y, taus, quadratic)
            if not all(np.array_equal(x, z) for x, z in zip(a, b)):
                return False
    except Exception:  # pragma: no cover - a numpy whose gufuncs changed
        return False
    return True


if not _fast_path_agrees():  # pragma: no cover
    _qr_raw = _qr_reduced = None


class MeanSquare:
    """``E[z^2]``: a plain mean until ``tau_s`` worth of pushes, then forgetting
    with time constant ``tau_s`` (no prior: it knows nothing until it has data)."""

    __slots__ = ("tau_s", "m2", "n", "last_s")

    def __init__(self, tau_s: float):
        self.tau_s = tau_s
        self.m2 = 0.0
        self.n = 0
        self.last_s: Optional[float] = None

    def push(self, t_s: float, z: float) -> None:
        if z != z or abs(z) == math.inf:
            return
        dt = 0.0 if self.last_s is None else max(t_s - self.last_s, 0.0)
        self.last_s = t_s
        self.n += 1
        w = max(1.0 / self.n, 1.0 - math.exp(-dt / self.tau_s))
        self.m2 += w * (z * z - self.m2)

    @property
    def sd(self) -> float:
        return math.sqrt(self.m2) if self.n else math.nan


def isolate(a: float, k_aux: float, sd_aux: float, k_baro: float, sd_baro: float) -> float:
    """``z_aux^2 - z_baro^2`` for the kinks ``k_aux`` of ``aux - INS`` and
    ``k_baro`` of ``baro - INS`` (standard deviations beside each) at the onset
    of a kink ``a`` of ``aux - baro``; a kink that does not go the way of ``a``
    (``aux`` up is ``a`` up, ``baro`` up is ``a`` down) explains nothing and
    counts zero. Large and positive: the aux sensor bent; large and negative:
    the baro."""
    z_aux = k_aux / sd_aux if k_aux * a > 0 else 0.0
    z_baro = k_baro / sd_baro if k_baro * a < 0 else 0.0
    return z_aux * z_aux - z_baro * z_baro
