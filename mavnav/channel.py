"""One height channel of the paper: a Kalman filter with the INS as control.

State ``X = [H, Vz, dH, da, b_g]`` (named indices below): height above the
reference (m, up), vertical speed (m/s, up), barometer bias (m), accelerometer
bias (m/s^2), and the slow GNSS vertical error (m). The first four are the
paper's (MODEL.md section 3). ``b_g`` is not in the paper: GNSS altitude
wanders by metres over minutes relative to the baro (multipath, satellite
geometry), which white noise alone cannot describe, so the GNSS error is
white noise plus a first-order Gauss-Markov process,
``b(k+1) = phi_g b(k) + w_b``, ``phi_g = exp(-T / tau_g)``,
``var(w_b) = sigma_g^2 (1 - phi_g^2)`` (exact discretisation), started at
``b = 0`` with variance ``sigma_g^2`` (``sensors.gnss.gm_sigma_m``,
``gm_tau_s``). Every channel carries ``b_g`` (a uniform shape keeps the
cross-covariances of :mod:`mavnav.bank` simple); only the GNSS row observes
it. With ``sigma_g = 0`` (paper mode) ``b_g`` stays exactly 0 with zero
variance and the first four states are the paper's 4-state filter.
The vertical specific force enters as a control input, already
integrated over the epoch by :mod:`mavnav.epochs` (``dp_m``, ``dv_mps``:
the position and velocity increments of ``f_up - g`` from zero initial
velocity; with one IMU sample per epoch they equal the paper's ``Psi W``).

Measurement rows, each written against ``X(k)`` (MODEL.md section 4):

* baro, by differencing out the Gauss-Markov noise ``u``:
  ``y1 = xi1(k+1) - phi_u xi1(k) - H1 psi_w``, ``Phi_y1 = H1 Phi - phi_u H1``,
  ``H1 = [1, 0, 1, 0, 0]``, noise ``H1 w + gamma_u n`` with
  ``gamma_u^2 = sigma_bb^2 (1 - phi_u^2)`` (erratum: the paper prints ``-phi_u^2``);
* GNSS / rangefinder height measured ``age`` seconds before the epoch:
  ``h = [1, -age, 0, 0, 1]`` (GNSS) or ``[1, -age, 0, 0, 0]`` (rangefinder),
  first order in the age (``b_g`` is slow: its value at the epoch is used),
  ``y = z - h psi_w``, ``Phi_y = h Phi``, noise ``h w + sigma n``.

``Bxx = Gamma Gamma^T`` (+ optional random walks on dH and da, + the
Gauss-Markov noise ``var(w_b)`` at ``[b_g, b_g]``; ``w_b`` is independent of
the INS noise),
``Gamma = -[T^2/2, T, 0, 0, 0] q_a``, ``q_a = sigma_a sqrt(2 / (alpha_a T))`` by
default (the dimensionally consistent form; the printed ``sigma_a sqrt(2T /
alpha_a)`` is selectable to reproduce the paper). ``Bxy = Bxx h^T`` per row
(the GNSS row's noise ``h w`` carries ``w_b``, so its column has
``var(w_b)`` at ``b_g``), ``Byy = [h_i Bxx h_j^T] + diag(noise)``.

Channels are configurations of the same filter: ``gnss`` (channel 1: GNSS +
baro + INS), ``rangefinder`` (channel 2: radio/rangefinder + baro + INS),
``baro`` (channel 3: baro + INS, which alone observes only ``H + dH``).

Everything here is pure: ``step(kind, state, inputs, model) -> (state, output)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal, Optional

import numpy as np

from .config import Config
from .errors import NonFiniteInputError
from .fastinit import fast_frozen_init
from .kalman import correlated_step, normalised_innovation
from .sensors import CHANNELS, Sensor  # noqa: F401 (CHANNELS: re-exported)

# Named state indices.
H, VZ, DH, DA, GB = 0, 1, 2, 3, 4
N_STATES = 5
N_PAPER = 4  # the paper's states [H, Vz, dH, da]

ChannelKind = Sensor  # one of CHANNELS: gnss, rangefinder, baro
_AUX_ROW = {Sensor.GNSS: Sensor.GNSS.short, Sensor.RANGEFINDER: Sensor.RANGEFINDER.short, Sensor.BARO: None}  # gnss, rng
# the entry of the aux row at b_g: the GNSS row observes the GNSS error, the rangefinder row does not
AUX_GB = {Sensor.GNSS: 1.0, Sensor.RANGEFINDER: 0.0, Sensor.BARO: 0.0}

H_BARO = np.array([1.0, 0.0, 1.0, 0.0, 0.0])


@dataclass(frozen=True, slots=True)
class Model:
    """Error-model parameters of the channel filters, in SI units."""

    sigma_a_mps2: float
    alpha_a_per_s: float
    accel_noise_form: Literal["consistent", "printed"]
    sigma_bb_m: float
    gamma_bb_per_s: float
    baro_bias_rw_m_per_sqrt_s: float
    acc_bias_rw_mps2_per_sqrt_s: float
    gravity_mps2: float
    p0_diag: tuple[float, float, float, float]  # [H, Vz, dH, da]; b_g starts at gnss_gm_sigma_m^2
    init_from_first_baro: bool
    height_prior: Literal["diffuse", "p0"] = "p0"
    gnss_gm_sigma_m: float = 0.0  # stationary RMS of the GNSS Gauss-Markov error (0: off)
    gnss_gm_tau_s: float = 300.0  # its correlation time

    @classmethod
    def from_config(cls, cfg: Config) -> "Model":
        s, f = cfg.sensors, cfg.filter
        # paper mode is exactly the paper: GNSS noise white only
        gm_sigma = 0.0 if cfg.monitor.mode == "paper" else s.gnss.gm_sigma_m
        return cls(
            sigma_a_mps2=s.ins.sigma_a_mps2,
            alpha_a_per_s=s.ins.alpha_a_per_s,
            accel_noise_form=f.accel_noise_form,
            sigma_bb_m=s.baro.sigma_bb_m,
            gamma_bb_per_s=s.baro.gamma_bb_per_s,
            baro_bias_rw_m_per_sqrt_s=s.baro.bias_rw_m_per_sqrt_s,
            acc_bias_rw_mps2_per_sqrt_s=s.ins.bias_rw_mps2_per_sqrt_s,
            gravity_mps2=f.gravity_mps2,
            p0_diag=(f.p0.height_m2, f.p0.vel_m2ps2, f.p0.baro_bias_m2, f.p0.acc_bias_m2ps4),
            init_from_first_baro=f.init_from_first_baro,
            height_prior=f.height_prior,
            gnss_gm_sigma_m=gm_sigma,
            gnss_gm_tau_s=s.gnss.gm_tau_s,
        )


# ------------------------------------------------------------------ model matrices


def transition(T: float) -> np.ndarray:
    """``Phi`` of MODEL.md section 3 for a step of ``T`` seconds: the paper's
    4x4 block of ``[H, Vz, dH, da]`` (:func:`state_transition` is the whole)."""
    return np.array(
        [
            [1.0, T, 0.0, -0.5 * T * T],
            [0.0, 1.0, 0.0, -T],
            [0.0, 0.0, 1.0, 0.0],
            [0.0, 0.0, 0.0, 1.0],
        ]
    )


def accel_noise_q(T: float, model: Model) -> float:
    """Per-step RMS ``q_a`` of the acceleration noise (see the erratum)."""
    if model.accel_noise_form == "printed":
        return model.sigma_a_mps2 * math.sqrt(2.0 * T / model.alpha_a_per_s)
    return model.sigma_a_mps2 * math.sqrt(2.0 / (model.alpha_a_per_s * T))


def process_noise(T: float, model: Model, dv_var_m2ps2: float = 0.0) -> np.ndarray:
    """``Bxx = Gamma Gamma^T`` plus the optional bias random walks: the 4x4
    block of ``[H, Vz, dH, da]`` (:func:`state_process_noise` is the whole).
    ``dv_var`` (the measured error of the integrated IMU, :mod:`mavnav.epochs`)
    adds to the acceleration noise in the same shape: ``q^2 += dv_var / T^2``."""
    q = math.sqrt(accel_noise_q(T, model) ** 2 + dv_var_m2ps2 / (T * T))
    g = np.array([-0.5 * T * T * q, -T * q, 0.0, 0.0])
    B = np.outer(g, g)
    B[DH, DH] += model.baro_bias_rw_m_per_sqrt_s**2 * T
    B[DA, DA] += model.acc_bias_rw_mps2_per_sqrt_s**2 * T
    return B


def baro_gauss_markov(T: float, model: Model) -> tuple[float, float]:
    """``(phi_u, gamma_u)`` of the baro noise over ``T`` seconds (exact discretisation)."""
    phi = math.exp(-model.gamma_bb_per_s * T)
    return phi, model.sigma_bb_m * math.sqrt(1.0 - phi * phi)


def gnss_gauss_markov(T: float, model: Model) -> tuple[float, float]:
    """``(phi_g, var(w_b))`` of the GNSS error ``b_g`` over ``T`` seconds (exact discretisation)."""
    phi = math.exp(-T / model.gnss_gm_tau_s)
    return phi, model.gnss_gm_sigma_m**2 * (1.0 - phi * phi)


def state_transition(T: float, model: Model) -> np.ndarray:
    """``Phi`` of the whole state: :func:`transition` and ``phi_g`` on ``b_g``."""
    Phi = np.zeros((N_STATES, N_STATES))
    Phi[:N_PAPER, :N_PAPER] = transition(T)
    Phi[GB, GB] = gnss_gauss_markov(T, model)[0]
    return Phi


def state_process_noise(T: float, model: Model, dv_var_m2ps2: float = 0.0) -> np.ndarray:
    """``Bxx`` of the whole state: :func:`process_noise` and ``var(w_b)`` on ``b_g``
    (``w_b`` is independent of the INS noise)."""
    B = np.zeros((N_STATES, N_STATES))
    B[:N_PAPER, :N_PAPER] = process_noise(T, model, dv_var_m2ps2)
    B[GB, GB] = gnss_gauss_markov(T, model)[1]
    return B


def prior_covariance(model: Model) -> np.ndarray:
    """``P0``: ``diag(p0_diag)`` and the stationary ``sigma_g^2`` on ``b_g``."""
    return np.diag(np.asarray(tuple(model.p0_diag) + (model.gnss_gm_sigma_m**2,), dtype=float))


# ------------------------------------------------------------------ inputs, state, output


@dataclass(frozen=True, slots=True)
class AuxMeasurement:
    """A GNSS or rangefinder height used at an epoch."""

    height_m: float  # height above the reference (rangefinder: flat ground at the reference)
    sigma_m: float  # 1-sigma noise
    age_s: float  # epoch time minus measurement time, >= 0
    vel_up_mps: float = float("nan")  # GNSS Doppler vertical velocity (NaN: none); not a filter row


@dataclass(frozen=True, slots=True)
class EpochInputs:
    """Everything one filter step consumes (built by :mod:`mavnav.epochs`)."""

    t_us: int  # vehicle time at the end of the step
    dt_s: float  # T
    dp_m: float  # position increment of f_up - g over T, from zero velocity
    dv_mps: float  # velocity increment of f_up - g over T
    baro_m: Optional[float]  # baro height at t_us, or None (no baro sample this epoch)
    gnss: Optional[AuxMeasurement] = None
    rng: Optional[AuxMeasurement] = None
    baro_restart: bool = False  # baro differencing restarts at this sample (after a gap)
    # Measured input noise beyond the model (mavnav.epochs): the variance of
    # dv_mps from IMU snapshots that miss the acceleration between them, and
    # the baro's white noise.
    dv_var_m2ps2: float = 0.0
    baro_white_var_m2: float = 0.0


# built per epoch: the cheaper __init__ of mavnav.fastinit (same fields, same defaults)
fast_frozen_init(AuxMeasurement, EpochInputs)


@dataclass(frozen=True, slots=True)
class ChannelState:
    x: np.ndarray  # (N_STATES,)
    P: np.ndarray  # (N_STATES, N_STATES)
    t_us: int
    baro_prev_m: Optional[float]  # xi1(k) for the differencing, None when it must restart


@dataclass(frozen=True, slots=True)
class ChannelOutput:
    t_us: int
    rows: tuple[str, ...]  # measurement rows used this step: "baro", "gnss", "rng"
    innovation: np.ndarray  # (m,)
    S: np.ndarray  # (m, m)
    nis: float  # r^T S^-1 r
    whitened: np.ndarray  # (m,) Cholesky-whitened innovation

    @property
    def dof(self) -> int:
        return len(self.rows)


def _check_finite(inputs: EpochInputs) -> None:
    for name in ("dt_s", "dp_m", "dv_mps"):
        v = getattr(inputs, name)
        if not math.isfinite(v):
            raise NonFiniteInputError(f"epoch input {name} is not finite ({v})")
    if inputs.dt_s <= 0.0:
        raise NonFiniteInputError(f"epoch input dt_s must be positive ({inputs.dt_s})")
    if inputs.baro_m is not None and not math.isfinite(inputs.baro_m):
        raise NonFiniteInputError(f"epoch input baro_m is not finite ({inputs.baro_m})")
    for name in ("gnss", "rng"):
        a = getattr(inputs, name)
        if a is None:
            continue
        for field in ("height_m", "sigma_m", "age_s"):
            v = getattr(a, field)
            if not math.isfinite(v):
                raise NonFiniteInputError(f"epoch input {name}.{field} is not finite ({v})")
        if a.sigma_m <= 0.0:
            raise NonFiniteInputError(f"epoch input {name}.sigma_m must be positive ({a.sigma_m})")


def initial_state(model: Model, t_us: int, baro_m: Optional[float]) -> ChannelState:
    """The state at the first baro sample.

    ``height_prior == "p0"``: prior ``0``, ``P0``, conditioned on
    the first baro sample (this makes the differencing filter exactly equal
    to the state-augmented one, see ``tests/test_channel_reference.py``).
    ``"diffuse"``: the same conditioning under an uninformative height prior:
    ``H`` = the baro reading, its variance ``P0_dH + sigma_bb^2``, fully
    anti-correlated with ``dH``; nothing assumes the vehicle starts near the
    reference point."""
    x = np.zeros(N_STATES)
    P = prior_covariance(model)
    if baro_m is not None and not math.isfinite(baro_m):
        raise NonFiniteInputError(f"first baro sample is not finite ({baro_m})")
    if baro_m is not None and model.init_from_first_baro and model.height_prior == "diffuse":
        # H = xi1(0) - dH - u(0): the posterior under an uninformative height prior
        x[H] = baro_m
        P[H, H] = model.p0_diag[DH] + model.sigma_bb_m**2
        P[H, DH] = P[DH, H] = -model.p0_diag[DH]
    elif baro_m is not None and model.init_from_first_baro:
        s = float(H_BARO @ P @ H_BARO) + model.sigma_bb_m**2
        k = P @ H_BARO / s
        x = x + k * (baro_m - float(H_BARO @ x))
        P = P - np.outer(k, H_BARO @ P)
        P = 0.5 * (P + P.T)
    return ChannelState(x=x, P=P, t_us=t_us, baro_prev_m=baro_m)


def measurement_rows(
    kind: ChannelKind,
    state: ChannelState,
    inputs: EpochInputs,
    model: Model,
    Phi: np.ndarray,
    Bxx: np.ndarray,
    psi_w: np.ndarray,
) -> tuple[tuple[str, ...], np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The stacked rows ``(names, Phi_y, Bxy, Byy, y)`` this channel uses at this epoch."""
    names: list[str] = []
    hs: list[np.ndarray] = []
    phis: list[np.ndarray] = []
    ys: list[float] = []
    noise: list[float] = []
    if inputs.baro_m is not None and state.baro_prev_m is not None and not inputs.baro_restart:
        phi_u, gamma_u = baro_gauss_markov(inputs.dt_s, model)
        names.append("baro")
        hs.append(H_BARO)
        phis.append(H_BARO @ Phi - phi_u * H_BARO)
        ys.append(inputs.baro_m - phi_u * state.baro_prev_m - float(H_BARO @ psi_w))
        noise.append(gamma_u * gamma_u + (1.0 + phi_u * phi_u) * inputs.baro_white_var_m2)
    aux_name = _AUX_ROW[kind]
    aux = getattr(inputs, aux_name) if aux_name else None
    if aux is not None:
        h = np.array([1.0, -aux.age_s, 0.0, 0.0, AUX_GB[kind]])
        names.append(aux_name)
        hs.append(h)
        phis.append(h @ Phi)
        ys.append(aux.height_m - float(h @ psi_w))
        noise.append(aux.sigma_m * aux.sigma_m)
    m = len(names)
    if m == 0:
        return (), np.zeros((0, N_STATES)), np.zeros((N_STATES, 0)), np.zeros((0, 0)), np.zeros(0)
    Hm = np.array(hs)
    Bxy = Bxx @ Hm.T
    Byy = Hm @ Bxx @ Hm.T + np.diag(noise)
    return tuple(names), np.array(phis), Bxy, Byy, np.array(ys)


def step(
    kind: ChannelKind, state: ChannelState, inputs: EpochInputs, model: Model
) -> tuple[ChannelState, ChannelOutput]:
    """Advance one channel by one epoch. Refuses non-finite inputs."""
    _check_finite(inputs)
    T = inputs.dt_s
    Phi = state_transition(T, model)
    Bxx = state_process_noise(T, model, inputs.dv_var_m2ps2)
    psi_w = np.array([inputs.dp_m, inputs.dv_mps, 0.0, 0.0, 0.0])
    names, Phi_y, Bxy, Byy, y = measurement_rows(kind, state, inputs, model, Phi, Bxx, psi_w)
    res = correlated_step(state.x, state.P, Phi, psi_w, Bxx, Phi_y, Bxy, Byy, y)
    nis, white = normalised_innovation(res.innovation, res.S)
    new_state = ChannelState(x=res.x, P=res.P, t_us=inputs.t_us, baro_prev_m=inputs.baro_m)
    out = ChannelOutput(
        t_us=inputs.t_us, rows=names, innovation=res.innovation, S=res.S, nis=nis, whitened=white
    )
    return new_state, out


