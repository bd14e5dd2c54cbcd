"""Baro against the INS: the baro's second difference over two windows against
the INS's (its acceleration integrated twice), with no velocity estimate in it.
The formula below the first paragraph describes the one-window form it replaced
only in spirit: see :meth:`InsBaroCheck.residual`.

``e = (b_t - b_s) - [(P_t - P_s) - v_s D + V_s D - da_s D^2 / 2]``, where ``P``
and ``v`` are the INS increments chained from the start of the run (so any
window is a difference of two entries), ``V_s`` and ``da_s`` the channel's
velocity and accelerometer bias at the window's start and ``D`` its length.
Its variance: the baro's white noise twice, the channel's velocity and bias
covariance carried over ``D``, the accelerometer noise integrated twice
(``psd D^3 / 3``), the baro bias walk and the Gauss-Markov baro error over
``D``.

A baro step or ramp moves ``b`` and not the INS; an accelerometer fault moves
the INS and not ``b``; a GNSS or rangefinder fault moves neither, so a clear
pass rules out the baro and the INS.
"""

from __future__ import annotations

import bisect
import math
from collections import deque
from typing import Optional


class InsBaroCheck:
    def __init__(self, window_s: float):
        self.window_us = int(window_s * 1e6)
        self._pos = 0.0  # chained INS position increments (m)
        self._vel = 0.0  # chained INS velocity increments (m/s)
        # (t_us, pos, vel, baro_m, V, P_VV, da, P_dd, P_Vd)
        self._q: deque = deque()

    @property
    def pos_m(self) -> float:
        """The chained INS position increments up to the last epoch (m)."""
        return self._pos

    @property
    def vel_mps(self) -> float:
        return self._vel

    def clear(self) -> None:
        self._q.clear()

    def push(self, t_us: int, dt_s: float, dp_m: float, dv_mps: float, baro_m: Optional[float],
             x, P) -> None:
        """One epoch: the INS increments, the baro sample (or None) and the
        baro+INS channel's state ``x`` and covariance ``P`` after the step."""
        self._pos += self._vel * dt_s + dp_m
        self._vel += dv_mps
        if baro_m is None:
            return
        if self._q and t_us - self._q[-1][0] > self.window_us:
            self._q.clear()  # a gap in the baro: the windows would straddle it
        self._q.append((t_us, self._pos, self._vel, baro_m, float(x[3]), float(P[3, 3])))
        limit = t_us - 2 * self.window_us
        q = self._q
        while len(q) > 1 and q[1][0] <= limit:
            q.popleft()

    def residual(self, white_var_m2: float, psd_m2ps3: float, bias_rw_var_m2ps: float,
                 gm_var_m2: float, gm_rate_per_s: float) -> Optional[tuple[float, float, float]]:
        """``(e, sigma, D)``: the baro's second difference over two windows of
        about ``D`` against the INS's, or None before they fill. No velocity
        enters: a filter's velocity error cannot pass for a baro fault."""
        q = self._q
        if len(q) < 3:
            return None
        u, t = q[0], q[-1]
        if (t[0] - u[0]) * 1e-6 < self.window_us * 1e-6:
            return None
        mid = 0.5 * (u[0] + t[0])
        # the sample nearest the middle (the earlier on a tie); q is in time order:
        # the first entry at or after mid (a 1-tuple sorts before every entry of its time)
        i = bisect.bisect_left(q, (mid,))
        s = q[i - 1] if i == len(q) or (i > 0 and mid - q[i - 1][0] <= q[i][0] - mid) else q[i]
        D0, D1 = (s[0] - u[0]) * 1e-6, (t[0] - s[0]) * 1e-6
        if D0 <= 0 or D1 <= 0:
            return None
        r = D1 / D0
        # h_t - h_s - r (h_s - h_u) = A1 - r A0 + (v_s - v_u) D1, A = displacement from zero velocity
        a1 = t[1] - s[1] - s[2] * D1
        a0 = s[1] - u[1] - u[2] * D0
        ins = a1 - r * a0 + (s[2] - u[2]) * D1
        # a constant accelerometer bias da moves A1 - r A0 + (v_s - v_u) D1 by
        # da (D1^2 / 2 - r D0^2 / 2 + D0 D1) = da D1 (D0 + D1) / 2 (da D^2 for equal windows)
        da, pdd = s[4], s[5]
        k = 0.5 * (D1 * D1 - r * D0 * D0) + D0 * D1
        ins -= da * k
        e = (t[3] - s[3]) - r * (s[3] - u[3]) - ins
        var = ((1.0 + (1.0 + r) ** 2 + r * r) * white_var_m2 + k * k * pdd
               + psd_m2ps3 * (D1 ** 3 + r * r * D0 ** 3) / 3.0 + psd_m2ps3 * D0 * D1 * D1
               + bias_rw_var_m2ps * (D1 + r * r * D0)
               + 2.0 * (1.0 + r + r * r) * gm_var_m2 * (1.0 - math.exp(-gm_rate_per_s * max(D0, D1))))
        return e, math.sqrt(max(var, 1e-12)), D0 + D1
