"""Pure Kalman-filter math for measurements correlated with the process noise.

This module knows no navigation. It implements one step of the filter of
MODEL.md section 4 (the paper's eq. 16-17), in which every measurement row is
written against the *previous* state ``x(k)``:

    x(k+1) = Phi x(k) + psi_w + w(k),          cov(w) = Bxx
    y      = Phi_y x(k) + v(k),                cov(v) = Byy,  cov(w, v) = Bxy

The estimate of ``x(k+1)`` given ``y`` is

    K      = (Phi P Phi_y^T + Bxy) (Byy + Phi_y P Phi_y^T)^-1          (16)
    x(k+1) = Phi x + psi_w + K (y - Phi_y x)
    P(k+1) = (Phi P Phi^T + Bxx) - K (Bxy + Phi P Phi_y^T)^T            (17)

The covariance is computed in the Joseph-like form that holds for any gain,

    A = Phi - K Phi_y
    P(k+1) = A P A^T + Bxx - K Bxy^T - Bxy K^T + K Byy K^T

which equals (17) at the optimal gain but stays symmetric positive
semi-definite under rounding whenever the joint noise covariance
``[[Bxx, Bxy], [Bxy^T, Byy]]`` is. (:func:`posterior_cov_short` gives the
printed short form (17), kept for tests.)

Every array may carry leading batch dimensions, so that several independent
filters (mavnav's three channels) advance in one call; ``Phi``, ``psi_w`` and
``Bxx`` may be shared (no batch dimension). A row can be made *neutral*
(contributing nothing) by zero ``Phi_y`` row, zero ``Bxy`` column, zero ``y``,
unit ``Byy`` diagonal and zero ``Byy`` off-diagonals: this lets a batch carry
filters that use different numbers of rows.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np


class StepResult(NamedTuple):
    x: np.ndarray  # (..., n) estimate of x(k+1)
    P: np.ndarray  # (..., n, n) its covariance
    innovation: np.ndarray  # (..., m) r = y - Phi_y x(k)
    S: np.ndarray  # (..., m, m) covariance of r
    K: np.ndarray  # (..., n, m) gain


def _t(a: np.ndarray) -> np.ndarray:
    return np.swapaxes(a, -1, -2)


def correlated_step(
    x: np.ndarray,
    P: np.ndarray,
    Phi: np.ndarray,
    psi_w: np.ndarray,
    Bxx: np.ndarray,
    Phi_y: np.ndarray,
    Bxy: np.ndarray,
    Byy: np.ndarray,
    y: np.ndarray,
) -> StepResult:
    """One predict-and-correct step with correlated noise (eq. 16-17, Joseph form).

    Shapes: ``x (..., n)``, ``P (..., n, n)``, ``Phi (..., n, n)``,
    ``psi_w (..., n)``, ``Bxx (..., n, n)``, ``Phi_y (..., m, n)``,
    ``Bxy (..., n, m)``, ``Byy (..., m, m)``, ``y (..., m)``. ``m`` may be 0.
    """
    x_pred = np.einsum("...ij,...j->...i", Phi, x) + psi_w
    m = y.shape[-1]
    if m == 0:
        P_new = Phi @ P @ _t(Phi) + Bxx
        P_new = 0.5 * (P_new + _t(P_new))
        empty = np.zeros(y.shape[:-1] + (0, 0))
        return StepResult(x_pred, P_new, y.copy(), empty, np.zeros(x.shape + (0,)))
    P_PhiyT = P @ _t(Phi_y)  # (..., n, m)
    C = Phi @ P_PhiyT + Bxy  # cov(x(k+1), y)
    S = Byy + Phi_y @ P_PhiyT  # cov(y)
    S = 0.5 * (S + _t(S))
    K = _t(np.linalg.solve(S, _t(C)))  # C S^-1, S symmetric
    r = y - np.einsum("...ij,...j->...i", Phi_y, x)
    x_new = x_pred + np.einsum("...ij,...j->...i", K, r)
    A = Phi - K @ Phi_y
    KBxyT = K @ _t(Bxy)
    P_new = A @ P @ _t(A) + Bxx - KBxyT - _t(KBxyT) + K @ Byy @ _t(K)
    P_new = 0.5 * (P_new + _t(P_new))
    return StepResult(x_new, P_new, r, S, K)


def posterior_cov_short(P, Phi, Bxx, Phi_y, Bxy, Byy) -> np.ndarray:
    """The printed form (17) of the covariance update, for comparison in tests."""
    PhiPPhiyT = Phi @ P @ _t(Phi_y)
    C = PhiPPhiyT + Bxy
    S = Byy + Phi_y @ P @ _t(Phi_y)
    K = _t(np.linalg.solve(S, _t(C)))
    return (Phi @ P @ _t(Phi) + Bxx) - K @ _t(Bxy + PhiPPhiyT)


def normalised_innovation(r: np.ndarray, S: np.ndarray) -> tuple[float, np.ndarray]:
    """``(r^T S^-1 r, L^-1 r)`` with ``S = L L^T``: the chi-square statistic and
    the Cholesky-whitened innovation (each element ~ N(0, 1) under the model)."""
    if r.shape[-1] == 0:
        return 0.0, r.copy()
    L = np.linalg.cholesky(S)
    white = np.linalg.solve(L, r)
    return float(white @ white), white
