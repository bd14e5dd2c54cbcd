"""The baro's slow error as the flight shows it (``features.baro_u_measured``).

The sensor model's baro error ``u`` (a first-order Gauss-Markov process,
``sigma_bb_m`` at ``gamma_bb_per_s``) is sized from the real flights, but a
baro can be noisier than any of them: the simulator's ``u`` (0.5 m at 1 s)
read as a caution most of a flight, and a take-off excursion of 3 of its
sigmas was 9 of the model's, a false alarm. This meter measures ``u`` at run
time, so the monitor need not be told its baro's noise.

It reads a baro/INS second difference over short windows
(:class:`~.inscheck.InsBaroCheck` at ``baro_u_window_s``): at a 1 s lag a
noisier ``u`` shows at once (ten times the model's variance for the
simulator's baro), and a second difference does not move for a ramp or a
step (only at their onset, readings the outlier cut and the median drop).
The median of ``|e| / sigma`` over the last ``baro_u_memory_s``
(:class:`~.scale.MedianScale`) gives a variance ratio ``m2`` against the
model. Read from N independent spans it scatters by ``2.33 / sqrt(N)``
(60 % over 30 s of a 2 s statistic): only past ``baro_u_significance_sigma``
of that scatter above 1 (a baro that is noisier, not a noisy reading of a
baro that is not; a 1.2 floor had widened a simulated flight told its true
noise, and a baro ramp was alarmed 1.7 s later) is the excess put on ``u``::

    u_var = sigma_bb^2 + (m2 - 1) sigma^2 / (6 (1 - exp(-gamma D / 2)))

the inverse of the statistic's own term for ``u`` over two windows of ``D / 2``
(the excess could be white noise or IMU scatter: put on the correlated term
it widens the level tests most, the safe side). It only widens: below
significance ``u`` is the model's, and it widens at most ``max_factor`` times (the
measured scales' limit, ``residual_scale_max``: a log whose clock is skewed
against its IMU read a ``u`` of 19 m). Pure: time comes from the samples.
"""

from __future__ import annotations

import math
from typing import Optional

from .inscheck import InsBaroCheck
from .scale import MEDIAN_ABS_NORMAL, MedianScale


# the relative standard deviation of a variance ratio read from the median of
# |z| over N independent normal values, times sqrt(N): twice the median's,
# 1 / (2 f(m) m) with m = 0.6745 and f(m) = 2 phi(m) the density of |z| there
_M2_REL_SD = 2.0 / (2.0 * 0.6355531 * MEDIAN_ABS_NORMAL)  # 2.33


class BaroNoiseMeter:
    def __init__(self, sigma_bb_m: float, gamma_bb_per_s: float, window_s: float, memory_s: float,
                 min_samples: int, outlier_sigma: float, significance_sigma: float, update_s: float,
                 max_factor: float = 5.0):
        self.model_var_m2 = sigma_bb_m * sigma_bb_m
        self.max_var_m2 = self.model_var_m2 * max_factor * max_factor
        self.gamma = gamma_bb_per_s
        self.check = InsBaroCheck(window_s)
        self.z = MedianScale(memory_s, min_samples, update_s)
        self.outlier_sigma = outlier_sigma
        self.significance = significance_sigma
        self.u_var_m2 = self.model_var_m2
        self.ratio = 1.0  # the last measured variance ratio against the model

    def push(self, t_us: int, dt_s: float, dp_m: float, dv_mps: float, baro_m: Optional[float], x, P) -> None:
        """The epoch's INS increments and baro sample (or None), as
        :meth:`InsBaroCheck.push` takes them."""
        self.check.push(t_us, dt_s, dp_m, dv_mps, baro_m, x, P)

    def observe(self, t_us: int, white_var_m2: float, psd_m2ps3: float, bias_rw_var_m2ps: float) -> None:
        """After a baro sample: read the short second difference with the
        model's ``u`` and update the measured one."""
        res = self.check.residual(white_var_m2, psd_m2ps3, bias_rw_var_m2ps, self.model_var_m2, self.gamma)
        if res is None:
            return
        e, sigma, D = res
        z = abs(e) / sigma
        ms = self.z
        if z > self.outlier_sigma * max(1.0, ms.sd or 1.0):
            return  # a step's onset, a spike: not the baro's noise (at its measured scale)
        if not ms.push(t_us, z):
            return
        m2 = ms.sd * ms.sd
        self.ratio = m2
        # the readings overlap: about one independent value per span D
        n_eff = max((ms.t[-1] - ms.t[0]) * 1e-6 / D, 1.0)
        if m2 <= 1.0 + self.significance * _M2_REL_SD * n_eff ** -0.5:
            self.u_var_m2 = self.model_var_m2
            return
        # the statistic's u term at equal windows: 6 u^2 (1 - exp(-gamma D / 2))
        gm = 6.0 * (1.0 - math.exp(-self.gamma * 0.5 * D))
        self.u_var_m2 = min(self.model_var_m2 + (m2 - 1.0) * sigma * sigma / gm, self.max_var_m2)
