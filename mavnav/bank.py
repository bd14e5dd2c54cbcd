"""The three channels stepped together: mavnav's production filter.

Same filter as :func:`mavnav.channel.step` (MODEL.md eq. 16-17; that module
is the readable reference), specialised to the structure of the model and
compiled with numba (state ``[H, Vz, dH, da, b_g]``):

* ``Phi`` is sparse (``1, T, -T^2/2, -T``, and ``phi_g`` on the GNSS error
  ``b_g``) and applied in closed form;
* ``Bxx = g g^T + diag(0, 0, q_dH, q_da, q_g)``, ``g = -q_a [T^2/2, T, 0, 0, 0]``,
  so ``Bxy`` and ``Byy`` reduce to scalar products;
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

import dataclasses
import math
from dataclasses import dataclass
from typing import Optional

import numpy as np

from .channel import (AUX_GB, CHANNELS, DH, GB, N_STATES, VZ, EpochInputs, Model, _check_finite,
                      gnss_gauss_markov, initial_state)
from .fastinit import fast_frozen_init
from .jit import njit

N_CH = len(CHANNELS)
GNSS, RNG, BARO = 0, 1, 2
# the aux row's entry at b_g per channel (the GNSS row observes the GNSS error)
AUX_GB_ROW = tuple(float(AUX_GB[k]) for k in CHANNELS)
assert N_STATES == 5 and GB == 4  # the kernels below spell out Phi and Bxx for this layout


@njit(cache=True, fastmath=False)
def bank_kernel(x, P, baro_prev, T, dp, dv, g0, g1, q_dh, q_da, phi_g, q_g,
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

    ``Phi`` acts in closed form (rows 0, 1 mix H, Vz, da; ``b_g`` decays by
    ``phi_g``); ``Bxx = g g^T + diag(0, 0, q_dh, q_da, q_g)`` with
    ``g = (g0, g1, 0, 0, 0)``, so ``Bxx h^T = g (g . h) + qd * h``.
    """
    n = x.shape[1]
    hT2 = 0.5 * T * T
    qd = np.zeros(n)
    qd[2] = q_dh; qd[3] = q_da; qd[4] = q_g
    A = np.empty((n, n))  # Phi P
    Pp = np.empty((n, n))  # Phi P Phi^T + Bxx (upper triangle)
    xp = np.empty(n)
    U = np.empty((2, n))  # P f^T per row
    C = np.empty((2, n))  # Phi P f^T + Bxx h^T per row
    Kc = np.empty((2, n))  # gain per row
    R = np.empty(2)
    Y = np.empty(2)
    GH = np.empty(2)
    for c in range(x.shape[0]):
        # prediction: Phi x + psi_w, Pp = Phi P Phi^T + Bxx
        for i in range(n):
            xp[i] = x[c, i]
        xp[0] = x[c, 0] + T * x[c, 1] - hT2 * x[c, 3] + dp
        xp[1] = x[c, 1] - T * x[c, 3] + dv
        xp[4] = phi_g * x[c, 4]
        for j in range(n):
            A[0, j] = P[c, 0, j] + T * P[c, 1, j] - hT2 * P[c, 3, j]
            A[1, j] = P[c, 1, j] - T * P[c, 3, j]
            A[2, j] = P[c, 2, j]
            A[3, j] = P[c, 3, j]
            A[4, j] = phi_g * P[c, 4, j]
        for i in range(n):
            Pp[i, 0] = A[i, 0] + T * A[i, 1] - hT2 * A[i, 3]
            Pp[i, 1] = A[i, 1] - T * A[i, 3]
            Pp[i, 2] = A[i, 2]
            Pp[i, 3] = A[i, 3]
            Pp[i, 4] = phi_g * A[i, 4]
        Pp[0, 0] += g0 * g0; Pp[0, 1] += g0 * g1; Pp[1, 1] += g1 * g1
        for i in range(2, n):
            Pp[i, i] += qd[i]
        # rows: observation row h (of x(k+1)), Phi_y row f, y, noise R
        use_b = has_baro and baro_on[c] and not math.isnan(baro_prev[c])
        use_a = aux_on[c]
        inn[c, 0] = math.nan; inn[c, 1] = math.nan
        sdiag[c, 0] = math.nan; sdiag[c, 1] = math.nan
        s12_out[c] = 0.0
        for j in range(2):
            rb[c, j] = False
            for i in range(n):
                K[c, i, j] = 0.0
                Hr[c, j, i] = 0.0
                Fy[c, j, i] = 0.0
        nr = 0
        if use_b:
            am = 1.0 - phi_u
            Hr[c, 0, 0] = 1.0; Hr[c, 0, 2] = 1.0
            Fy[c, 0, 0] = am; Fy[c, 0, 1] = T; Fy[c, 0, 2] = am; Fy[c, 0, 3] = -hT2
            Y[0] = xi_new - phi_u * baro_prev[c] - dp
            R[0] = gamma_u2
            rb[c, 0] = True
            nr = 1
        if use_a:
            age = aux_age[c]
            gb = AUX_GB_ROW[c]
            Hr[c, nr, 0] = 1.0; Hr[c, nr, 1] = -age; Hr[c, nr, 4] = gb
            Fy[c, nr, 0] = 1.0; Fy[c, nr, 1] = T - age; Fy[c, nr, 3] = -hT2 + age * T
            Fy[c, nr, 4] = gb * phi_g
            Y[nr] = aux_z[c] - (dp - age * dv)
            R[nr] = aux_var[c]
            nr += 1
        dof_out[c] = nr
        if has_baro and baro_on[c]:
            baro_prev[c] = xi_new
        else:
            baro_prev[c] = math.nan
        # per row: U = P f^T, C = Phi U + Bxx h^T, innovation
        for r in range(nr):
            for i in range(n):
                acc = 0.0
                for j in range(n):
                    acc += P[c, i, j] * Fy[c, r, j]
                U[r, i] = acc
            gh = g0 * Hr[c, r, 0] + g1 * Hr[c, r, 1]
            GH[r] = gh
            C[r, 0] = U[r, 0] + T * U[r, 1] - hT2 * U[r, 3] + g0 * gh
            C[r, 1] = U[r, 1] - T * U[r, 3] + g1 * gh
            C[r, 2] = U[r, 2] + qd[2] * Hr[c, r, 2]
            C[r, 3] = U[r, 3] + qd[3] * Hr[c, r, 3]
            C[r, 4] = phi_g * U[r, 4] + qd[4] * Hr[c, r, 4]
            acc = 0.0
            for i in range(n):
                acc += Fy[c, r, i] * x[c, i]
            Y[r] -= acc  # now the innovation
        # S = f P f^T + h Bxx h^T + R and the gain K = C^T S^-1 (the sums in
        # this order make the filter with b_g off bitwise the 4-state one)
        if nr == 1:
            fu = 0.0
            qhh = 0.0
            for i in range(n):
                fu += Fy[c, 0, i] * U[0, i]
                qhh += qd[i] * Hr[c, 0, i] * Hr[c, 0, i]
            s11 = fu + GH[0] * GH[0] + R[0] + qhh
            for i in range(n):
                Kc[0, i] = C[0, i] / s11
            nis_out[c] = Y[0] * Y[0] / s11
            slot = 0 if rb[c, 0] else 1
            inn[c, slot] = Y[0]
            sdiag[c, slot] = s11
        elif nr == 2:
            fu11 = fu22 = fu12 = 0.0
            q11 = q22 = q12 = 0.0
            for i in range(n):
                fu11 += Fy[c, 0, i] * U[0, i]
                fu22 += Fy[c, 1, i] * U[1, i]
                fu12 += Fy[c, 0, i] * U[1, i]
                q11 += qd[i] * Hr[c, 0, i] * Hr[c, 0, i]
                q22 += qd[i] * Hr[c, 1, i] * Hr[c, 1, i]
                q12 += qd[i] * Hr[c, 0, i] * Hr[c, 1, i]
            s11 = fu11 + GH[0] * GH[0] + R[0] + q11
            s22 = fu22 + GH[1] * GH[1] + R[1] + q22
            s12 = fu12 + GH[0] * GH[1] + q12
            det = s11 * s22 - s12 * s12
            w11 = s22 / det; w12 = -s12 / det; w22 = s11 / det
            for i in range(n):
                Kc[0, i] = C[0, i] * w11 + C[1, i] * w12
                Kc[1, i] = C[0, i] * w12 + C[1, i] * w22
            i1 = Y[0]; i2 = Y[1]
            nis_out[c] = i1 * (w11 * i1 + w12 * i2) + i2 * (w12 * i1 + w22 * i2)
            inn[c, 0] = i1; sdiag[c, 0] = s11
            inn[c, 1] = i2; sdiag[c, 1] = s22
            s12_out[c] = s12
        else:
            nis_out[c] = 0.0
        # x+ = xp + K r, P+ = Pp - K C^T (upper triangle, mirrored)
        for i in range(n):
            acc = xp[i]
            for r in range(nr):
                acc += Kc[r, i] * Y[r]
                K[c, i, r] = Kc[r, i]
            x[c, i] = acc
        for i in range(n):
            for j in range(i, n):
                acc = Pp[i, j]
                for r in range(nr):
                    acc -= Kc[r, i] * C[r, j]
                P[c, i, j] = acc
                P[c, j, i] = acc


PAIRS = ((GNSS, RNG), (GNSS, BARO), (RNG, BARO))
# the index in PAIRS of the pair of channels a != b, either way round
_PAIR_OF = tuple(tuple(next((p for p, ij in enumerate(PAIRS) if ij in ((a, b), (b, a))), -1) for b in range(N_CH))
                 for a in range(N_CH))


@njit(cache=True)
def cross_kernel(Pc, pairs, T, g0, g1, q_dh, q_da, phi_g, q_g, gamma_u2, dof, K, Fy, Hr, rb):  # pragma: no cover
    """Propagate the cross-covariances ``Pc[p] = cov(e_a, e_b)`` of channel pairs.

    The channels share the INS (process noise ``w``) and the baro (its
    differenced noise ``gamma_u n``), so with ``e(k+1) = A e(k) + w - K v``,
    ``A = Phi - K Phi_y``, ``v = H w + n``:

        Pc+ = A_a Pc A_b^T + Bxx - K_a H_a Bxx - Bxx H_b^T K_b^T
              + K_a (H_a Bxx H_b^T + R_ab) K_b^T,

    ``R_ab = gamma_u^2`` between two baro rows, else 0. (The GNSS error
    ``b_g`` is one truth shared by every channel, so its process noise is in
    the common ``Bxx`` too.) :func:`cross_reference` is the same in matrix form.
    """
    n = Pc.shape[1]
    hT2 = 0.5 * T * T
    Phi = np.eye(n)
    Phi[0, 1] = T; Phi[0, 3] = -hT2; Phi[1, 3] = -T; Phi[4, 4] = phi_g
    Bxx = np.zeros((n, n))
    g = np.zeros(n)
    g[0] = g0; g[1] = g1
    for i in range(n):
        for j in range(n):
            Bxx[i, j] = g[i] * g[j]
    Bxx[2, 2] += q_dh
    Bxx[3, 3] += q_da
    Bxx[4, 4] += q_g
    A = np.empty((2, n, n))
    HB = np.empty((2, 2, n))  # H Bxx per side
    tmp = np.empty((n, n))
    out = np.empty((n, n))
    for p in range(pairs.shape[0]):
        ca = pairs[p, 0]
        cb = pairs[p, 1]
        for side in range(2):
            c = ca if side == 0 else cb
            for i in range(n):
                for j in range(n):
                    acc = Phi[i, j]
                    for r in range(dof[c]):
                        acc -= K[c, i, r] * Fy[c, r, j]
                    A[side, i, j] = acc
            for r in range(2):
                for j in range(n):
                    acc = 0.0
                    for m in range(n):
                        acc += Hr[c, r, m] * Bxx[m, j]
                    HB[side, r, j] = acc
        # A_a Pc A_b^T
        for i in range(n):
            for j in range(n):
                acc = 0.0
                for m in range(n):
                    acc += A[0, i, m] * Pc[p, m, j]
                tmp[i, j] = acc
        for i in range(n):
            for j in range(n):
                acc = 0.0
                for m in range(n):
                    acc += tmp[i, m] * A[1, j, m]
                out[i, j] = acc + Bxx[i, j]
        na = dof[ca]
        nb = dof[cb]
        # - K_a H_a Bxx - Bxx H_b^T K_b^T
        for i in range(n):
            for j in range(n):
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
                for m in range(n):
                    m_rs += HB[0, r, m] * Hr[cb, s, m]
                if rb[ca, r] and rb[cb, s]:
                    m_rs += gamma_u2
                for i in range(n):
                    for j in range(n):
                        out[i, j] += K[ca, i, r] * m_rs * K[cb, j, s]
        for i in range(n):
            for j in range(n):
                Pc[p, i, j] = out[i, j]


def cross_reference(Pc: np.ndarray, pairs, Phi: np.ndarray, Bxx: np.ndarray, gamma_u2: float,
                    dof, K: np.ndarray, Fy: np.ndarray, Hr: np.ndarray, rb: np.ndarray) -> np.ndarray:
    """The readable reference of :func:`cross_kernel`: the propagated
    cross-covariances, in matrix form (``Pc`` is left as it is).

    ``Phi`` and ``Bxx`` are the whole state's (:func:`mavnav.channel.state_transition`,
    :func:`mavnav.channel.state_process_noise`); ``dof``, ``K``, ``Fy``, ``Hr``
    and ``rb`` are what :func:`bank_kernel` left for the step (per channel
    ``c``, its first ``dof[c]`` rows: gain columns, ``Phi_y`` rows, observation
    rows, whether the row is the baro's). Per pair ``(a, b)``:

        Pc+ = A_a Pc A_b^T + Bxx - K_a H_a Bxx - Bxx H_b^T K_b^T
              + K_a (H_a Bxx H_b^T + R_ab) K_b^T,   A = Phi - K Phi_y,

    ``R_ab[r, s] = gamma_u^2`` where rows ``r`` of ``a`` and ``s`` of ``b`` are
    both baro rows (the one differenced baro noise they share), else 0.
    ``tests/test_bank.py`` holds the kernel to it.
    """
    out = np.empty_like(Pc)
    for p, (a, b) in enumerate(pairs):
        na, nb = int(dof[a]), int(dof[b])
        Ka, Kb = K[a][:, :na], K[b][:, :nb]
        Ha, Hb = Hr[a][:na], Hr[b][:nb]
        Aa = Phi - Ka @ Fy[a][:na]
        Ab = Phi - Kb @ Fy[b][:nb]
        R_ab = gamma_u2 * np.outer(rb[a][:na], rb[b][:nb]).astype(float)
        out[p] = (Aa @ Pc[p] @ Ab.T + Bxx - Ka @ Ha @ Bxx - Bxx @ Hb.T @ Kb.T
                  + Ka @ (Ha @ Bxx @ Hb.T + R_ab) @ Kb.T)
    return out


@dataclass(frozen=True, slots=True)
class BankStep:
    """What one epoch produced, per channel (index = CHANNELS order)."""

    t_us: int
    innovation: np.ndarray  # (3, 2): baro row, aux row; NaN where unused
    innovation_var: np.ndarray  # (3, 2)
    innovation_cov: np.ndarray  # (3,): cov(baro, aux) rows
    nis: np.ndarray  # (3,)
    dof: np.ndarray  # (3,) int


fast_frozen_init(BankStep)  # one per epoch: the cheaper __init__ of mavnav.fastinit


@njit(cache=True, fastmath=False)
def step_kernel(x, P, baro_prev, T, dp, dv, g0, g1, q_dh, q_da, phi_g, q_g,
                has_baro, baro_on, xi_new, phi_u, gamma_u2,
                aux_on, aux_z, aux_var, aux_age,
                inn, sdiag, s12_out, nis_out, dof_out, K, Fy, Hr, rb,
                track_cross, Pc, pairs):  # pragma: no cover - compiled
    """:func:`bank_kernel`, then with ``track_cross`` :func:`cross_kernel`,
    in one compiled call: the same two kernels, one dispatch of their
    arguments per epoch instead of two (``tests/test_bank.py``)."""
    bank_kernel(x, P, baro_prev, T, dp, dv, g0, g1, q_dh, q_da, phi_g, q_g,
                has_baro, baro_on, xi_new, phi_u, gamma_u2,
                aux_on, aux_z, aux_var, aux_age,
                inn, sdiag, s12_out, nis_out, dof_out, K, Fy, Hr, rb)
    if track_cross:
        cross_kernel(Pc, pairs, T, g0, g1, q_dh, q_da, phi_g, q_g, gamma_u2, dof_out, K, Fy, Hr, rb)


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
        self.start_baro_bias_m2: Optional[float] = None
        self.start_vel_m2ps2: Optional[float] = None
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
        # _g's last inputs and answer (NaN: none yet; a NaN input never matches)
        self._g_T = self._g_dv = math.nan
        self._g_last = (math.nan, math.nan)
        self._decay_T = math.nan
        self._decay_last = (math.nan, math.nan, math.nan)
        # which channels use the baro (all, unless the monitor excludes it)
        self.baro_on = np.ones(N_CH, dtype=np.bool_)
        # cross-covariances cov(e_a, e_b) for the pairs in PAIRS
        self.Pc = np.zeros((len(PAIRS), N_STATES, N_STATES))

    @property
    def started(self) -> bool:
        return self.t_us is not None

    def start(self, t_us: int, baro_m: float, baro_bias_m2: Optional[float] = None,
              vel_m2ps2: Optional[float] = None) -> None:
        """Initialise every channel from the same prior: their errors start identical.
        ``baro_bias_m2`` and ``vel_m2ps2`` replace the prior variances of the baro
        bias ``dH`` and the vertical speed for this start only (a start on the
        ground at the datum: the reference ties the baro closer, and the vehicle
        is at rest); a channel re-initialised later in the flight takes the
        model's prior."""
        model = self.model
        # a start again within the warm-up takes the same priors
        self.start_baro_bias_m2, self.start_vel_m2ps2 = baro_bias_m2, vel_m2ps2
        if baro_bias_m2 is not None or vel_m2ps2 is not None:
            p0 = list(model.p0_diag)
            if baro_bias_m2 is not None:
                p0[DH] = baro_bias_m2
            if vel_m2ps2 is not None:
                p0[VZ] = vel_m2ps2
            model = dataclasses.replace(model, p0_diag=tuple(p0))
        for c in range(N_CH):
            self.reinit(c, t_us, baro_m, model)
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

    def reinit(self, c: int, t_us: int, baro_m: Optional[float], model: Optional[Model] = None) -> None:
        """(Re)initialise channel ``c`` from the prior (``model``'s, else the
        bank's), conditioned on a baro sample."""
        st = initial_state(model or self.model, t_us, baro_m)
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

    def open_speed(self, c: int, var_mps2: float) -> None:
        """Channel ``c``'s vertical speed made less certain by an independent
        ``var_mps2`` (its cross-covariances unchanged: an added independent
        error), so its own sensor can set it again."""
        self.P[c, VZ, VZ] += var_mps2

    def rebase_baro_bias(self, c: int, baro_m: float, noise_var_m2: float) -> None:
        """Channel ``c`` takes its baro bias from one baro sample and its own
        height: ``dH = baro - H``, the error of which is ``-(e_H + n)``
        (variance ``P_HH + noise_var_m2``; covariances, also with the other
        channels, those of ``-e_H``). For a channel that ran without the baro
        while the baro was at fault: the baro returns with whatever offset its
        fault left, as a bias, and the channel keeps its height."""
        P = self.P[c]
        self.x[c, DH] = baro_m - self.x[c, 0]
        row = -P[0, :].copy()
        row[DH] = P[0, 0] + noise_var_m2
        P[DH, :] = row
        P[:, DH] = row
        for p, (i, j) in enumerate(PAIRS):
            if i == c:
                self.Pc[p][DH, :] = -self.Pc[p][0, :]
            elif j == c:
                self.Pc[p][:, DH] = -self.Pc[p][:, 0]

    def shift_baro_level(self, c: int, step_m: float, step_var_m2: float) -> None:
        """Channel ``c``'s baro reading moved by ``step_m`` (measured with variance
        ``step_var_m2``) that is the sensor's, not the vehicle's: the bias takes
        it and the height gives it back (``H + dH`` unchanged); the uncertainty
        of the measured step goes with it, along ``dH - H``."""
        d = np.zeros(N_STATES)
        d[0], d[DH] = -1.0, 1.0
        self.x[c] += step_m * d
        self.P[c] += step_var_m2 * np.outer(d, d)

    def predicted_baro(self, c: int, ep: EpochInputs) -> tuple[float, float]:
        """Innovation and variance the differenced baro row would have in channel
        ``c`` at ``ep`` (NaN if the channel has no previous baro sample)."""
        prev = self.baro_prev[c]
        if ep.baro_m is None or math.isnan(prev) or ep.baro_restart:
            return math.nan, math.nan
        m = self.model
        T = ep.dt_s
        g0, _ = self._g(T, ep.dv_var_m2ps2)
        phi_u = self._decay(T)[0]
        a = 1.0 - phi_u
        f = np.array([a, T, a, -0.5 * T * T, 0.0])
        y = ep.baro_m - phi_u * prev - ep.dp_m
        r = y - float(f @ self.x[c])
        q_dh = m.baro_bias_rw_m_per_sqrt_s**2 * T
        S = (float(f @ self.P[c] @ f) + g0 * g0 + m.sigma_bb_m**2 * (1.0 - phi_u * phi_u) + q_dh
             + (1.0 + phi_u * phi_u) * ep.baro_white_var_m2)
        return r, S

    def _g(self, T: float, dv_var_m2ps2: float = 0.0) -> tuple[float, float]:
        """``Gamma``'s two non-zero entries; ``dv_var`` (the measured error of
        the integrated IMU) adds to the acceleration noise: ``q^2 += dv_var / T^2``.
        The last answer is kept: an epoch asks it two or three times (the baro
        and aux predictions, then the step) with the same inputs."""
        if T == self._g_T and dv_var_m2ps2 == self._g_dv:
            return self._g_last
        self._g_last = out = self._g_fresh(T, dv_var_m2ps2)
        self._g_T, self._g_dv = T, dv_var_m2ps2
        return out

    def _decay(self, T: float) -> tuple[float, float, float]:
        """``(phi_u, phi_g, var(w_b))`` over ``T``: the baro's Gauss-Markov decay
        ``exp(-gamma_bb T)`` and :func:`gnss_gauss_markov`; the last answer kept,
        as :meth:`_g`'s."""
        if T == self._decay_T:
            return self._decay_last
        phi_g, q_g = gnss_gauss_markov(T, self.model)
        self._decay_last = out = (math.exp(-self.model.gamma_bb_per_s * T), phi_g, q_g)
        self._decay_T = T
        return out

    def _g_fresh(self, T: float, dv_var_m2ps2: float = 0.0) -> tuple[float, float]:
        """:meth:`_g` computed."""
        m = self.model
        if self._printed:
            q = m.sigma_a_mps2 * math.sqrt(2.0 * T / m.alpha_a_per_s)
        else:
            q = m.sigma_a_mps2 * math.sqrt(2.0 / (m.alpha_a_per_s * T))
        if dv_var_m2ps2 > 0.0:
            q = math.sqrt(q * q + dv_var_m2ps2 / (T * T))
        return -0.5 * T * T * q, -T * q

    def predicted_aux(self, c: int, ep: EpochInputs, aux) -> tuple[float, float]:
        """Innovation and its variance that ``aux`` would have in channel ``c``
        at epoch ``ep``, before it enters (for the chi-square gate)."""
        T = ep.dt_s
        g0, g1 = self._g(T, ep.dv_var_m2ps2)
        _, phi_g, q_g = self._decay(T)
        age = aux.age_s
        gb = AUX_GB_ROW[c]
        f = np.array([1.0, T - age, 0.0, -0.5 * T * T + age * T, gb * phi_g])
        y = aux.height_m - (ep.dp_m - age * ep.dv_mps)
        r = y - float(f @ self.x[c])
        gh = g0 - age * g1
        S = float(f @ self.P[c] @ f) + gh * gh + gb * gb * q_g + aux.sigma_m * aux.sigma_m
        return float(r), float(S)

    def step(self, ep: EpochInputs) -> BankStep:
        _check_finite(ep)
        m = self.model
        T = ep.dt_s
        g0, g1 = self._g(T, ep.dv_var_m2ps2)
        q_dh = m.baro_bias_rw_m_per_sqrt_s**2 * T
        q_da = m.acc_bias_rw_mps2_per_sqrt_s**2 * T
        has_baro = ep.baro_m is not None
        phi_u, phi_g, q_g = self._decay(T)
        gamma_u2 = m.sigma_bb_m**2 * (1.0 - phi_u * phi_u) + (1.0 + phi_u * phi_u) * ep.baro_white_var_m2
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
        step_kernel(self.x, self.P, self.baro_prev, T, ep.dp_m, ep.dv_mps, g0, g1, q_dh, q_da, phi_g, q_g,
                    has_baro, self.baro_on, ep.baro_m if has_baro else 0.0, phi_u, gamma_u2,
                    aux_on, self._aux_z, self._aux_var, self._aux_age,
                    self._inn, self._sdiag, self._s12, self._nis, self._dof,
                    self._K, self._Fy, self._Hr, self._rb, bool(self.track_cross), self.Pc, self._pairs)
        self.t_us = ep.t_us
        return BankStep(ep.t_us, self._inn.copy(), self._sdiag.copy(), self._s12.copy(),
                        self._nis.copy(), self._dof.copy())

    def height_cov(self, idx) -> list[list[float]]:
        """Error covariance of the heights of channels ``idx`` (with cross terms)."""
        ph = self.P[:, 0, 0].tolist()  # Python floats, as float() of each element
        pc = self.Pc[:, 0, 0].tolist()
        return [[ph[a] if a == b else pc[_PAIR_OF[a][b]] for b in idx] for a in idx]

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
