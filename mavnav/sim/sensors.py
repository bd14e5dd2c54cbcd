"""Vectorised sensor models (MODEL.md sections 2-3), pure numpy, seeded by the caller.

* :func:`gauss_markov` - first-order Gauss-Markov noise exactly discretised at
  arbitrary sample times: ``phi_k = exp(-gamma dt_k)``,
  ``u_k = phi_k u_{k-1} + sigma sqrt(1 - phi_k^2) n_k``, stationary start.
* :func:`mat_nb` - body->NED rotations for arrays of Z-Y-X Euler angles.
* :func:`specific_force_body` - ``f_b = R_bn (a_n - g_n + e_n) + b_b``: the
  true specific force plus the INS errors ``e_n`` (vertical bias ``da`` and
  white noise) and an optional body-frame bias ``b_b``.
* :func:`pressure_from_height` - ISA static pressure for a barometric height
  above the reference point (inverse of what a monitor computes).
"""

from __future__ import annotations

import math

import numpy as np

from ..atmosphere import L_KPM, P0_PA, T0_K, _EXP, pressure_at_height_pa


def gauss_markov(t_s: np.ndarray, sigma: float, gamma_per_s: float, rng: np.random.Generator) -> np.ndarray:
    """First-order Gauss-Markov samples at times ``t_s`` (stationary, std ``sigma``)."""
    t_s = np.asarray(t_s, dtype=float)
    n = t_s.size
    out = np.empty(n)
    if n == 0:
        return out
    if sigma == 0:
        out[:] = 0.0
        return out
    white = rng.standard_normal(n)
    phi = np.exp(-gamma_per_s * np.diff(t_s))
    gain = sigma * np.sqrt(1.0 - phi * phi)
    drive = gain * white[1:]
    x = sigma * white[0]
    out[0] = x
    phi_l = phi.tolist()
    drive_l = drive.tolist()
    for k in range(n - 1):
        x = phi_l[k] * x + drive_l[k]
        out[k + 1] = x
    return out


def mat_nb(roll: np.ndarray, pitch: np.ndarray, yaw: np.ndarray) -> np.ndarray:
    """Body->NED rotation matrices, shape (n, 3, 3), Z-Y-X Euler angles."""
    sr, cr = np.sin(roll), np.cos(roll)
    sp, cp = np.sin(pitch), np.cos(pitch)
    sy, cy = np.sin(yaw), np.cos(yaw)
    m = np.empty((np.size(roll), 3, 3))
    m[:, 0, 0] = cp * cy
    m[:, 0, 1] = sr * sp * cy - cr * sy
    m[:, 0, 2] = cr * sp * cy + sr * sy
    m[:, 1, 0] = cp * sy
    m[:, 1, 1] = sr * sp * sy + cr * cy
    m[:, 1, 2] = cr * sp * sy - sr * cy
    m[:, 2, 0] = -sp
    m[:, 2, 1] = sr * cp
    m[:, 2, 2] = cr * cp
    return m


def body_rates(roll, pitch, roll_rate, pitch_rate, yaw_rate):
    """Body angular rates (p, q, r) from Euler angle rates (arrays)."""
    sr, cr = np.sin(roll), np.cos(roll)
    sp, cp = np.sin(pitch), np.cos(pitch)
    return (
        roll_rate - yaw_rate * sp,
        pitch_rate * cr + yaw_rate * sr * cp,
        -pitch_rate * sr + yaw_rate * cr * cp,
    )


def accel_noise_std(sigma_a_mps2: float, alpha_a_per_s: float, interval_s: float) -> float:
    """Per-sample std of the INS noise: ``sigma_a sqrt(2 / (alpha_a T))`` (MODEL.md erratum)."""
    return sigma_a_mps2 * math.sqrt(2.0 / (alpha_a_per_s * interval_s))


def specific_force_body(
    m_nb: np.ndarray,
    acc_n: np.ndarray,
    gravity_mps2: float,
    bias_up_mps2: np.ndarray,
    noise_std_mps2: float,
    body_bias_mps2,
    rng: np.random.Generator,
) -> np.ndarray:
    """Measured body specific force (n, 3), FRD: ``R_bn (a_n - g_n + e_n) + b_b``.

    ``acc_n`` (n, 3) is the true NED acceleration; the vertical bias enters as
    ``e_down = -bias_up`` so that ``f_up = a_up + g + da + w``.
    """
    f_n = np.array(acc_n, dtype=float, copy=True)
    f_n[:, 2] -= gravity_mps2
    f_n[:, 2] -= bias_up_mps2
    if noise_std_mps2 > 0:
        f_n += noise_std_mps2 * rng.standard_normal(f_n.shape)
    f_b = np.einsum("kji,kj->ki", m_nb, f_n)  # R_bn = R_nb^T
    return f_b + np.asarray(body_bias_mps2, dtype=float)


def pressure_from_height(height_ref_m: np.ndarray, ref_alt_msl_m: float) -> np.ndarray:
    """Static pressure (Pa) for a barometric height above the reference point.

    The reference pressure is the standard-day pressure at the reference
    elevation; ``height_from_pressure_m(p, p_ref)`` recovers the height.
    """
    p_ref = pressure_at_height_pa(ref_alt_msl_m, P0_PA)
    return pressure_at_height_pa(np.asarray(height_ref_m, dtype=float), p_ref)


def isa_altitude_m(pressure_pa: np.ndarray) -> np.ndarray:
    """Standard-atmosphere pressure altitude (what PX4 puts in ``pressure_alt``)."""
    return (T0_K / L_KPM) * (1.0 - (np.asarray(pressure_pa, dtype=float) / P0_PA) ** _EXP)


def hold_latest(t_src: np.ndarray, t_dst: np.ndarray):
    """For each ``t_dst``, the index of the latest ``t_src <= t_dst`` (-1 if none)."""
    return np.searchsorted(t_src, t_dst, side="right") - 1
