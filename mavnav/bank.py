"""The three channels stepped together: mavnav's production filter.

Same filter as :func:`mavnav.channel.step` (MODEL.md eq. 16-17; that module
is the readable reference), unrolled for the structure of the model and
compiled with numba:

* ``Phi`` is sparse (``1, T, -T^2/2, -T``) and applied in closed form;
* ``Bxx = g g^T + diag(0, 0, q_dH, q_da)``, ``g = -q_a [T^2/2, T, 0, 0]``, so
  ``Bxy`` and ``Byy`` reduce to scalar products;
* at most two rows per channel (baro and its own aux sensor), so ``S`` is
  inverted in closed form.

The covariance uses the symmetric short form ``P+ = Pp - C S^-1 C^T`` (upper
triangle computed and mirrored), equal to the Joseph form of
:mod:`mavnav.kalman` at the optimal gain; ``tests/test_bank.py`` pins the two
together and checks positive definiteness over long irregular runs.

Channel order is :data:`mavnav.channel.CHANNELS`: 0 = gnss, 1 = rangefinder,
2 = baro. Pure: no clock, no I/O; all state is in the arrays.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional

import numpy as np

from .channel import CHANNELS, N_STATES, ChannelState, EpochInputs, Model, _check_finite, fix_height, initial_state

try:  # numba is a dependency; the kernel also runs (slowly) as plain Python.
    from numba import njit
except ImportError:  # pragma: no cover
    def njit(*args, **kwargs):
        if args and callable(args[0]):
            return args[0]
        return lambda f: f

N_CH = len(CHANNELS)
GNSS, RNG, BARO = 0, 1, 2
ROW_BARO, ROW_AUX = 0, 1


@njit(cache=True, fastmath=False)
def bank_kernel(x, P, baro_prev, T, dp, dv, g0, g1, q_dh, q_da,
                has_baro, baro_on, xi_new, phi_u, gamma_u2,
                aux_on, aux_z, aux_var, aux_age,
                inn, sdiag, s12_out, nis_out, dof_out, K, Fy, Hr, rb):  # pragma: no cover - compiled
    """Advance every channel by one epoch, in place.

    Per channel ``c``: rows are the baro row (when ``has_baro``,
    ``baro_on[c]`` and ``baro_prev[c]`` is finite) and the aux row (when
    ``aux_on[c]``). A channel with ``baro_on[c]`` false runs without the baro
    and restarts its differencing when it is switched back on.
    Outputs: ``inn[c] = (baro, aux)`` innovations, ``sdiag[c]`` their
    variances (NaN when unused), ``s12_out[c]`` their covariance,
    ``nis_out[c]`` = r^T S^-1 r and ``dof_out[c]`` the number of rows.
    For the cross-covariances it also leaves, per channel and used row slot
    ``j < dof``: the gain column ``K[c, :, j]``, ``Phi_y`` row ``Fy[c, j]``,
    observation row ``Hr[c, j]`` (of ``x(k+1)``) and whether it is the baro
    row ``rb[c, j]``.
    """
    hT2 = 0.5 * T * T
    for c in range(x.shape[0]):
        p00 = P[c, 0, 0]; p01 = P[c, 0, 1]; p02 = P[c, 0, 2]; p03 = P[c, 0, 3]
        p11 = P[c, 1, 1]; p12 = P[c, 1, 2]; p13 = P[c, 1, 3]
        p22 = P[c, 2, 2]; p23 = P[c, 2, 3]
        p33 = P[c, 3, 3]
        x0 = x[c, 0]; x1 = x[c, 1]; x2 = x[c, 2]; x3 = x[c, 3]
        # prediction: Phi x + psi_w, Pp = Phi P Phi^T + Bxx
        xp0 = x0 + T * x1 - hT2 * x3 + dp
        xp1 = x1 - T * x3 + dv
        a00 = p00 + T * p01 - hT2 * p03
        a01 = p01 + T * p11 - hT2 * p13
        a02 = p02 + T * p12 - hT2 * p23
        a03 = p03 + T * p13 - hT2 * p33
        a11 = p11 - T * p13
        a12 = p12 - T * p23
        a13 = p13 - T * p33
        q00 = a00 + T * a01 - hT2 * a03 + g0 * g0
        q01 = a01 - T * a03 + g0 * g1
        q02 = a02
        q03 = a03
        q11 = a11 - T * a13 + g1 * g1
        q12 = a12
        q13 = a13
        q22 = p22 + q_dh
        q23 = p23
        q33 = p33 + q_da
        # rows
        use_b = has_baro and baro_on[c] and not math.isnan(baro_prev[c])
        use_a = aux_on[c]
        inn[c, 0] = math.nan; inn[c, 1] = math.nan
        sdiag[c, 0] = math.nan; sdiag[c, 1] = math.nan
        s12_out[c] = 0.0
        nr = 0
        # slot 1 / slot 2 row descriptors
        f10 = f11 = f12 = f13 = gh1 = y1 = n1 = 0.0
        f20 = f21 = f22 = f23 = gh2 = y2 = n2 = 0.0
        b1 = False
        if use_b:
            am = 1.0 - phi_u
            f10 = am; f11 = T; f12 = am; f13 = -hT2
            gh1 = g0; b1 = True
            y1 = xi_new - phi_u * baro_prev[c] - dp
            n1 = gamma_u2
            nr = 1
        if use_a:
            age = aux_age[c]
            fa0 = 1.0; fa1 = T - age; fa2 = 0.0; fa3 = -hT2 + age * T
            gha = g0 - age * g1
            ya = aux_z[c] - (dp - age * dv)
            na = aux_var[c]
            if nr == 0:
                f10 = fa0; f11 = fa1; f12 = fa2; f13 = fa3; gh1 = gha; y1 = ya; n1 = na
                nr = 1
            else:
                f20 = fa0; f21 = fa1; f22 = fa2; f23 = fa3; gh2 = gha; y2 = ya; n2 = na
                nr = 2
        dof_out[c] = nr
        rb[c, 0] = b1
        rb[c, 1] = False
        Fy[c, 0, 0] = f10; Fy[c, 0, 1] = f11; Fy[c, 0, 2] = f12; Fy[c, 0, 3] = f13
        Fy[c, 1, 0] = f20; Fy[c, 1, 1] = f21; Fy[c, 1, 2] = f22; Fy[c, 1, 3] = f23
        for j in range(2):
            for i in range(4):
                K[c, i, j] = 0.0
                Hr[c, j, i] = 0.0
        if nr >= 1:
            if b1:
                Hr[c, 0, 0] = 1.0; Hr[c, 0, 2] = 1.0
            else:
                Hr[c, 0, 0] = 1.0; Hr[c, 0, 1] = -aux_age[c]
        if nr == 2:
            Hr[c, 1, 0] = 1.0; Hr[c, 1, 1] = -aux_age[c]
        if has_baro and baro_on[c]:
            baro_prev[c] = xi_new
        else:
            baro_prev[c] = math.nan
        if nr == 0:
            n00 = q00; n01 = q01; n02 = q02; n03 = q03; n11 = q11; n12 = q12; n13 = q13
            n22 = q22; n23 = q23; n33 = q33
            x[c, 0] = xp0; x[c, 1] = xp1
            nis_out[c] = 0.0
        else:
            # row 1: u = P f^T, C = Phi u + Bxy, innovation, S11
            u0 = p00 * f10 + p01 * f11 + p02 * f12 + p03 * f13
            u1 = p01 * f10 + p11 * f11 + p12 * f12 + p13 * f13
            u2 = p02 * f10 + p12 * f11 + p22 * f12 + p23 * f13
            u3 = p03 * f10 + p13 * f11 + p23 * f12 + p33 * f13
            c10 = u0 + T * u1 - hT2 * u3 + g0 * gh1
            c11 = u1 - T * u3 + g1 * gh1
            c12 = u2 + (q_dh if b1 else 0.0)
            c13 = u3
            i1 = y1 - (f10 * x0 + f11 * x1 + f12 * x2 + f13 * x3)
            s11 = f10 * u0 + f11 * u1 + f12 * u2 + f13 * u3 + gh1 * gh1 + n1 + (q_dh if b1 else 0.0)
            if nr == 1:
                k0 = c10 / s11; k1 = c11 / s11; k2 = c12 / s11; k3 = c13 / s11
                x[c, 0] = xp0 + k0 * i1; x[c, 1] = xp1 + k1 * i1
                x[c, 2] = x2 + k2 * i1; x[c, 3] = x3 + k3 * i1
                n00 = q00 - k0 * c10; n01 = q01 - k0 * c11; n02 = q02 - k0 * c12; n03 = q03 - k0 * c13
                n11 = q11 - k1 * c11; n12 = q12 - k1 * c12; n13 = q13 - k1 * c13
                n22 = q22 - k2 * c12; n23 = q23 - k2 * c13
                n33 = q33 - k3 * c13
                nis_out[c] = i1 * i1 / s11
                K[c, 0, 0] = k0; K[c, 1, 0] = k1; K[c, 2, 0] = k2; K[c, 3, 0] = k3
                slot = 0 if b1 else 1
                inn[c, slot] = i1
                sdiag[c, slot] = s11
            else:
                v0 = p00 * f20 + p01 * f21 + p02 * f22 + p03 * f23
                v1 = p01 * f20 + p11 * f21 + p12 * f22 + p13 * f23
                v2 = p02 * f20 + p12 * f21 + p22 * f22 + p23 * f23
                v3 = p03 * f20 + p13 * f21 + p23 * f22 + p33 * f23
                c20 = v0 + T * v1 - hT2 * v3 + g0 * gh2
                c21 = v1 - T * v3 + g1 * gh2
                c22 = v2
                c23 = v3
                i2 = y2 - (f20 * x0 + f21 * x1 + f22 * x2 + f23 * x3)
                s22 = f20 * v0 + f21 * v1 + f22 * v2 + f23 * v3 + gh2 * gh2 + n2
                s12 = f10 * v0 + f11 * v1 + f12 * v2 + f13 * v3 + gh1 * gh2
                det = s11 * s22 - s12 * s12
                w11 = s22 / det; w12 = -s12 / det; w22 = s11 / det
                ka0 = c10 * w11 + c20 * w12; kb0 = c10 * w12 + c20 * w22
                ka1 = c11 * w11 + c21 * w12; kb1 = c11 * w12 + c21 * w22
                ka2 = c12 * w11 + c22 * w12; kb2 = c12 * w12 + c22 * w22
                ka3 = c13 * w11 + c23 * w12; kb3 = c13 * w12 + c23 * w22
                x[c, 0] = xp0 + ka0 * i1 + kb0 * i2
                x[c, 1] = xp1 + ka1 * i1 + kb1 * i2
                x[c, 2] = x2 + ka2 * i1 + kb2 * i2
                x[c, 3] = x3 + ka3 * i1 + kb3 * i2
                n00 = q00 - ka0 * c10 - kb0 * c20
                n01 = q01 - ka0 * c11 - kb0 * c21
                n02 = q02 - ka0 * c12 - kb0 * c22
                n03 = q03 - ka0 * c13 - kb0 * c23
                n11 = q11 - ka1 * c11 - kb1 * c21
                n12 = q12 - ka1 * c12 - kb1 * c22
                n13 = q13 - ka1 * c13 - kb1 * c23
                n22 = q22 - ka2 * c12 - kb2 * c22
                n23 = q23 - ka2 * c13 - kb2 * c23
                n33 = q33 - ka3 * c13 - kb3 * c23
                nis_out[c] = i1 * (w11 * i1 + w12 * i2) + i2 * (w12 * i1 + w22 * i2)
                K[c, 0, 0] = ka0; K[c, 1, 0] = ka1; K[c, 2, 0] = ka2; K[c, 3, 0] = ka3
                K[c, 0, 1] = kb0; K[c, 1, 1] = kb1; K[c, 2, 1] = kb2; K[c, 3, 1] = kb3
                inn[c, 0] = i1; sdiag[c, 0] = s11
                inn[c, 1] = i2; sdiag[c, 1] = s22
                s12_out[c] = s12
        if nr == 0:
            x[c, 2] = x2; x[c, 3] = x3
        P[c, 0, 0] = n00; P[c, 0, 1] = n01; P[c, 0, 2] = n02; P[c, 0, 3] = n03
        P[c, 1, 0] = n01; P[c, 1, 1] = n11; P[c, 1, 2] = n12; P[c, 1, 3] = n13
        P[c, 2, 0] = n02; P[c, 2, 1] = n12; P[c, 2, 2] = n22; P[c, 2, 3] = n23
        P[c, 3, 0] = n03; P[c, 3, 1] = n13; P[c, 3, 2] = n23; P[c, 3, 3] = n33


PAIRS = ((GNSS, RNG), (GNSS, BARO), (RNG, BARO))


@njit(cache=True)
def cross_kernel(Pc, pairs, T, g0, g1, q_dh, q_da, gamma_u2, dof, K, Fy, Hr, rb):  # pragma: no cover
    """Propagate the cross-covariances ``Pc[p] = cov(e_a, e_b)`` of channel pairs.

    The channels share the INS (process noise ``w``) and the baro (its
    differenced noise ``gamma_u n``), so with ``e(k+1) = A e(k) + w - K v``,
    ``A = Phi - K Phi_y``, ``v = H w + n``:

        Pc+ = A_a Pc A_b^T + Bxx - K_a H_a Bxx - Bxx H_b^T K_b^T
              + K_a (H_a Bxx H_b^T + R_ab) K_b^T,

    ``R_ab = gamma_u^2`` between two baro rows, else 0.
    """
    hT2 = 0.5 * T * T
    Phi = np.eye(4)
    Phi[0, 1] = T; Phi[0, 3] = -hT2; Phi[1, 3] = -T
    Bxx = np.zeros((4, 4))
    g = np.array([g0, g1, 0.0, 0.0])
    for i in range(4):
        for j in range(4):
            Bxx[i, j] = g[i] * g[j]
    Bxx[2, 2] += q_dh
    Bxx[3, 3] += q_da
    A = np.empty((2, 4, 4))
    HB = np.empty((2, 2, 4))  # H Bxx per side
    for p in range(pairs.shape[0]):
        ca = pairs[p, 0]
        cb = pairs[p, 1]
        for side in range(2):
            c = ca if side == 0 else cb
            for i in range(4):
                for j in range(4):
                    acc = Phi[i, j]
                    for r in range(dof[c]):
                        acc -= K[c, i, r] * Fy[c, r, j]
                    A[side, i, j] = acc
            for r in range(2):
                for j in range(4):
                    acc = 0.0
                    for m in range(4):
                        acc += Hr[c, r, m] * Bxx[m, j]
                    HB[side, r, j] = acc
        # A_a Pc A_b^T
        tmp = np.zeros((4, 4))
        for i in range(4):
            for j in range(4):
                acc = 0.0
                for m in range(4):
                    acc += A[0, i, m] * Pc[p, m, j]
                tmp[i, j] = acc
        out = np.zeros((4, 4))
        for i in range(4):
            for j in range(4):
                acc = 0.0
                for m in range(4):
                    acc += tmp[i, m] * A[1, j, m]
                out[i, j] = acc + Bxx[i, j]
        na = dof[ca]
        nb = dof[cb]
        # - K_a H_a Bxx - Bxx H_b^T K_b^T
        for i in range(4):
            for j in range(4):
                acc = 0.0
                for r in range(na):
                    acc += K[ca, i, r] * HB[0, r, j]
                for r in range(nb):
                    acc += HB[1, r, i] * K[cb, j, r]
                out[i, j] -= acc
        # + K_a (H_a Bxx H_b^T + R_ab) K_b^T
        for r in range(na):
            for s in range(nb):
                m_rs = 0.0
                for m in range(4):
                    m_rs += HB[0, r, m] * Hr[cb, s, m]
                if rb[ca, r] and rb[cb, s]:
                    m_rs += gamma_u2
                for i in range(4):
                    for j in range(4):
                        out[i, j] += K[ca, i, r] * m_rs * K[cb, j, s]
        for i in range(4):
            for j in range(4):
                Pc[p, i, j] = out[i, j]


@dataclass(frozen=True, slots=True)
class BankStep:
    """What one epoch produced, per channel (index = CHANNELS order)."""

    t_us: int
    innovation: np.ndarray  # (3, 2): baro row, aux row; NaN where unused
    innovation_var: np.ndarray  # (3, 2)
    innovation_cov: np.ndarray  # (3,): cov(baro, aux) rows
    nis: np.ndarray  # (3,)
    dof: np.ndarray  # (3,) int


class ChannelBank:
    """The three channel filters and their shared epoch bookkeeping."""

    def __init__(self, model: Model, track_cross: bool = True):
        self.model = model
        self.track_cross = track_cross
        self._printed = model.accel_noise_form == "printed"
        self.x = np.zeros((N_CH, N_STATES))
        self.P = np.zeros((N_CH, N_STATES, N_STATES))
        self.baro_prev = np.full(N_CH, math.nan)
        self.t_us: Optional[int] = None
        self._inn = np.zeros((N_CH, 2))
        self._sdiag = np.zeros((N_CH, 2))
        self._s12 = np.zeros(N_CH)
        self._nis = np.zeros(N_CH)
        self._dof = np.zeros(N_CH, dtype=np.int64)
        self._aux_on = np.zeros(N_CH, dtype=np.bool_)
        self._aux_z = np.zeros(N_CH)
        self._aux_var = np.ones(N_CH)
        self._aux_age = np.zeros(N_CH)
        self._K = np.zeros((N_CH, N_STATES, 2))
        self._Fy = np.zeros((N_CH, 2, N_STATES))
        self._Hr = np.zeros((N_CH, 2, N_STATES))
        self._rb = np.zeros((N_CH, 2), dtype=np.bool_)
        self._pairs = np.array(PAIRS, dtype=np.int64)
        # which channels use the baro (all, unless the monitor excludes it)
        self.baro_on = np.ones(N_CH, dtype=np.bool_)
        # cross-covariances cov(e_a, e_b) for the pairs in PAIRS
        self.Pc = np.zeros((len(PAIRS), N_STATES, N_STATES))

    @property
    def started(self) -> bool:
        return self.t_us is not None

    def start(self, t_us: int, baro_m: float) -> None:
        """Initialise every channel from the same prior: their errors start identical."""
        for c in range(N_CH):
            self.reinit(c, t_us, baro_m)
        self.Pc[:] = self.P[0]
        self.t_us = t_us

    def cross(self, a: int, b: int) -> np.ndarray:
        """``cov(e_a, e_b)``, the error cross-covariance of channels ``a`` and ``b``."""
        if a == b:
            return self.P[a]
        for p, (i, j) in enumerate(PAIRS):
            if (i, j) == (a, b):
                return self.Pc[p]
            if (i, j) == (b, a):
                return self.Pc[p].T
        raise ValueError((a, b))

    def reinit(self, c: int, t_us: int, baro_m: Optional[float]) -> None:
        """(Re)initialise channel ``c`` from the prior, conditioned on a baro sample."""
        st = initial_state(self.model, t_us, baro_m)
        self.x[c] = st.x
        self.P[c] = st.P
        self.baro_prev[c] = math.nan if baro_m is None else baro_m
        for p, (i, j) in enumerate(PAIRS):
            if c in (i, j):
                self.Pc[p] = 0.0  # a fresh prior: independent of the others' errors

    def reinit_from(self, c: int, src: int, extra_height_var: float = 0.0) -> None:
        """Re-initialise channel ``c`` as a copy of channel ``src`` (state,
        covariance and cross-covariances), its height made less certain by an
        independent ``extra_height_var`` (so it can settle onto its own
        sensor; the covariances stay exact for that model). Used to readmit a
        channel mid-flight, where the prior of the start would be far off."""
        self.x[c] = self.x[src]
        self.P[c] = self.P[src]
        self.P[c, 0, 0] += extra_height_var
        self.baro_prev[c] = self.baro_prev[src]
        for j in range(N_CH):
            if j != c:
                self._set_cross(c, j, self.P[src].copy() if j == src else self.cross(src, j).copy())

    def predicted_baro(self, c: int, ep: EpochInputs) -> tuple[float, float]:
        """Innovation and variance the differenced baro row would have in channel
        ``c`` at ``ep`` (NaN if the channel has no previous baro sample)."""
        prev = self.baro_prev[c]
        if ep.baro_m is None or math.isnan(prev) or ep.baro_restart:
            return math.nan, math.nan
        m = self.model
        T = ep.dt_s
        g0, _ = self._g(T)
        phi_u = math.exp(-m.gamma_bb_per_s * T)
        a = 1.0 - phi_u
        f = np.array([a, T, a, -0.5 * T * T])
        y = ep.baro_m - phi_u * prev - ep.dp_m
        r = y - float(f @ self.x[c])
        q_dh = m.baro_bias_rw_m_per_sqrt_s**2 * T
        S = float(f @ self.P[c] @ f) + g0 * g0 + m.sigma_bb_m**2 * (1.0 - phi_u * phi_u) + q_dh
        return r, S

    def channel_state(self, c: int) -> ChannelState:
        prev = self.baro_prev[c]
        return ChannelState(x=self.x[c].copy(), P=self.P[c].copy(), t_us=self.t_us or 0,
                            baro_prev_m=None if math.isnan(prev) else float(prev))

    def set_channel(self, c: int, x: np.ndarray, P: np.ndarray) -> None:
        self.x[c] = x
        self.P[c] = 0.5 * (P + P.T)

    def _g(self, T: float) -> tuple[float, float]:
        m = self.model
        if self._printed:
            q = m.sigma_a_mps2 * math.sqrt(2.0 * T / m.alpha_a_per_s)
        else:
            q = m.sigma_a_mps2 * math.sqrt(2.0 / (m.alpha_a_per_s * T))
        return -0.5 * T * T * q, -T * q

    def predicted_aux(self, c: int, ep: EpochInputs, aux) -> tuple[float, float]:
        """Innovation and its variance that ``aux`` would have in channel ``c``
        at epoch ``ep``, before it enters (for the chi-square gate)."""
        T = ep.dt_s
        g0, g1 = self._g(T)
        age = aux.age_s
        x = self.x[c]
        P = self.P[c]
        f0, f1, f3 = 1.0, T - age, -0.5 * T * T + age * T
        y = aux.height_m - (ep.dp_m - age * ep.dv_mps)
        r = y - (f0 * x[0] + f1 * x[1] + f3 * x[3])
        u0 = P[0, 0] * f0 + P[0, 1] * f1 + P[0, 3] * f3
        u1 = P[1, 0] * f0 + P[1, 1] * f1 + P[1, 3] * f3
        u3 = P[3, 0] * f0 + P[3, 1] * f1 + P[3, 3] * f3
        gh = g0 - age * g1
        S = f0 * u0 + f1 * u1 + f3 * u3 + gh * gh + aux.sigma_m * aux.sigma_m
        return float(r), float(S)

    def step(self, ep: EpochInputs) -> BankStep:
        _check_finite(ep)
        m = self.model
        T = ep.dt_s
        g0, g1 = self._g(T)
        q_dh = m.baro_bias_rw_m_per_sqrt_s**2 * T
        q_da = m.acc_bias_rw_mps2_per_sqrt_s**2 * T
        has_baro = ep.baro_m is not None
        phi_u = math.exp(-m.gamma_bb_per_s * T)
        gamma_u2 = m.sigma_bb_m**2 * (1.0 - phi_u * phi_u)
        if has_baro and ep.baro_restart:
            self.baro_prev[:] = math.nan
        aux_on = self._aux_on
        for c, a in ((GNSS, ep.gnss), (RNG, ep.rng)):
            if a is None:
                aux_on[c] = False
            else:
                aux_on[c] = True
                self._aux_z[c] = a.height_m
                self._aux_var[c] = a.sigma_m * a.sigma_m
                self._aux_age[c] = a.age_s
        bank_kernel(self.x, self.P, self.baro_prev, T, ep.dp_m, ep.dv_mps, g0, g1, q_dh, q_da,
                    has_baro, self.baro_on, ep.baro_m if has_baro else 0.0, phi_u, gamma_u2,
                    aux_on, self._aux_z, self._aux_var, self._aux_age,
                    self._inn, self._sdiag, self._s12, self._nis, self._dof,
                    self._K, self._Fy, self._Hr, self._rb)
        if self.track_cross:
            cross_kernel(self.Pc, self._pairs, T, g0, g1, q_dh, q_da, gamma_u2, self._dof,
                         self._K, self._Fy, self._Hr, self._rb)
        self.t_us = ep.t_us
        return BankStep(ep.t_us, self._inn.copy(), self._sdiag.copy(), self._s12.copy(),
                        self._nis.copy(), self._dof.copy())

    def height_cov(self, idx) -> list[list[float]]:
        """Error covariance of the heights of channels ``idx`` (with cross terms)."""
        P, Pc = self.P, self.Pc
        hh = {(a, a): P[a, 0, 0] for a in idx}
        for p, (i, j) in enumerate(PAIRS):
            hh[(i, j)] = hh[(j, i)] = Pc[p, 0, 0]
        return [[float(hh[(a, b)]) for b in idx] for a in idx]

    def _set_cross(self, a: int, b: int, M: np.ndarray) -> None:
        for p, (i, j) in enumerate(PAIRS):
            if (i, j) == (a, b):
                self.Pc[p] = M
                return
            if (i, j) == (b, a):
                self.Pc[p] = M.T
                return
        raise ValueError((a, b))

    def fused_from(self, sources: list[int], weights: np.ndarray) -> tuple[float, float]:
        """Height and error variance of ``sum w_i H_i`` over ``sources``."""
        h = float(sum(w * self.x[i, 0] for i, w in zip(sources, weights)))
        var = 0.0
        for i, wi in zip(sources, weights):
            for j, wj in zip(sources, weights):
                var += wi * wj * self.cross(i, j)[0, 0]
        return h, var

    def feedback(self, target: int, sources: list[int], weights: np.ndarray, shift_m: float = 0.0,
                 inflation: float = 1.0) -> float:
        """Correct channel ``target`` towards the combination ``sum w_i H_i`` of
        other channels (plus ``shift_m``), keeping every covariance exact.

        The gain uses the combination's variance times ``inflation`` (a weak,
        deliberately sub-optimal correction); the covariance update is the
        Joseph form for that gain with the true variance and the target's
        correlation with the sources, and the cross-covariances with every
        other channel follow. Returns the height correction applied.
        """
        h_f, var_f = self.fused_from(sources, weights)
        h_f += shift_m
        P = self.P[target]
        # cov(e_target, e_f) and cov(e_f, e_j) for every channel j
        c_tf = sum(w * self.cross(target, i)[:, 0] for i, w in zip(sources, weights))
        s = P[0, 0] + inflation * var_f
        k = P[:, 0] / s
        A = np.eye(N_STATES)
        A[:, 0] -= k
        dx = k * (h_f - self.x[target, 0])
        Pn = A @ P @ A.T + var_f * np.outer(k, k) + A @ np.outer(c_tf, k) + np.outer(k, c_tf) @ A.T
        new_cross = {}
        for j in range(N_CH):
            if j == target:
                continue
            c_fj = sum(w * self.cross(i, j)[0, :] for i, w in zip(sources, weights))
            new_cross[j] = A @ self.cross(target, j) + np.outer(k, c_fj)
        self.x[target] += dx
        self.P[target] = 0.5 * (Pn + Pn.T)
        for j, M in new_cross.items():
            self._set_cross(target, j, M)
        return float(dx[0])

    def height_fix(self, c: int, height_m: float, var_m2: float) -> None:
        """Correct channel ``c`` with an independent measurement of H (feedback)."""
        self.x[c], self.P[c] = fix_height(self.x[c], self.P[c], height_m, var_m2)
