"""The GNSS altitude's drift against the baro, where the receiver gives no
Doppler velocity.

The GNSS's slow error (multipath, satellite geometry) is modelled as a
Gauss-Markov state in every channel (``sensors.gnss.gm_sigma_m``): without it a
channel averages a wandering receiver's fixes as if independent and claims
centimetres. The state follows a slow GNSS ramp as it follows the wander, so
the innovation CUSUM cannot see a 0.5 m/s ramp. What tells the two apart is
the rate: real receivers wander by metres per minute, a ramp fault moves
their altitude by metres in seconds. Where the receiver reports its Doppler
velocity, :mod:`.doppler` measures that rate against the receiver's own
velocity. Without one, this check measures it against the baro: the slope,
fitted by least squares over ``window_s``, of

    d(t) = h_gnss(t) - h_baro(t)

(the vehicle's motion cancels). Its error is the samples' white noise through
the fit, ``sigma_w / sqrt(sum (t - mean t)^2)``, with ``sigma_w`` measured
from the window's own second differences (a ramp has none), and the healthy
receivers' drift rate, which the caller adds.

A failure implicates the GNSS and the baro: either can ramp. A pass rules
nothing out (a ramp slower than the threshold passes while its error grows).

Pure: samples in, the slope out; the caller owns thresholds and verdicts.
"""

from __future__ import annotations

import functools
import math
from collections import deque
from typing import Optional

from .doppler import MIN_SPAN_FRAC, restart_on_gap, window_first


def gm_slope_var_factor(gamma_per_s: float, window_s: float) -> float:
    """The variance of the least-squares slope over ``window_s`` of a
    stationary first-order Gauss-Markov process, per unit of its variance
    (m^2/s^2 per m^2):

        (12 / W^3)^2 * 2 * integral_0^W g(tau) exp(-gamma tau) dtau,
        g(tau) = W^3 / 12 - W^2 tau / 4 + tau^3 / 6

    (``g`` sums ``c(t) c(t + tau)`` over the window, ``c(t) = t - W / 2``: the
    slope of a continuous record; a sampled one is no steadier). The baro's
    slow error ``u`` is such a process; sampled at 5-10 Hz with a correlation
    time of a second or two its second differences hardly show it, so the
    fit's white-noise term misses it: the simulator's ``u`` (0.5 m at 1 s)
    moves the slope over 10 s by 0.065 m/s (1 sigma), more than the check's
    whole allowance for a real receiver. The integral in closed form (a cubic
    times an exponential); below ``gamma W`` 0.5, where its terms cancel, by
    midpoint sums. Limits: ``12 gamma / (5 W)`` for a slow process (a random
    walk), ``24 / (gamma W^3)`` for a fast one (white noise)."""
    return _gm_slope_var_factor(float(gamma_per_s), float(window_s))


@functools.lru_cache(maxsize=16)
def _gm_slope_var_factor(gamma: float, W: float) -> float:
    if gamma * W >= 0.5:
        e = math.exp(-gamma * W)
        j = (W ** 3 / (12.0 * gamma) - W * W * (1.0 + e) / (4.0 * gamma ** 2) - W * e / gamma ** 3
             + (1.0 - e) / gamma ** 4)
    else:
        n = 400
        h = W / n
        j = 0.0
        for i in range(n):
            tau = (i + 0.5) * h
            j += (W ** 3 / 12.0 - W * W * tau / 4.0 + tau ** 3 / 6.0) * math.exp(-gamma * tau)
        j *= h
    return 2.0 * j * 144.0 / W ** 6


# A fit needs this many samples (and the window spanned to MIN_SPAN_FRAC).
MIN_SAMPLES = 5
# Median absolute deviation to sigma, for a normal variable.
MAD_TO_SIGMA = 1.0 / 0.6745
# A second difference of white noise has sqrt(6) times its sigma.
SECOND_DIFF_GAIN = math.sqrt(6.0)


class DriftCheck:
    """The slope of ``d`` over ``window_s`` at each sample; samples further
    apart than ``max_gap_s`` restart the window."""

    __slots__ = ("window_us", "max_gap_us", "min_span_us", "hist", "last_slope_mps", "last_white_sd_mps",
                 "last_span_s", "last_us")

    def __init__(self, window_s: float, max_gap_s: float):
        self.window_us = int(window_s * 1e6)
        self.max_gap_us = int(max_gap_s * 1e6)
        self.min_span_us = MIN_SPAN_FRAC * self.window_us
        self.hist: deque = deque()  # (t_us, d_m)
        self.last_slope_mps = math.nan
        self.last_white_sd_mps = math.nan  # the slope's error from the window's white noise
        self.last_span_s = math.nan
        self.last_us: Optional[int] = None

    def clear(self) -> None:
        self.hist.clear()
        self.last_slope_mps = math.nan

    def push(self, t_us: int, d_m: float) -> Optional[float]:
        """The slope (m/s) at this sample, or None while the window holds less
        than ``MIN_SPAN_FRAC`` of its length or ``MIN_SAMPLES`` samples."""
        if not math.isfinite(d_m):
            self.clear()
            return None
        h = self.hist
        restart_on_gap(h, t_us, self.max_gap_us)
        h.append((t_us, d_m))
        first = window_first(h, t_us, self.window_us, self.min_span_us)
        if first is None or len(h) < MIN_SAMPLES:
            return None
        ts = [(s[0] - t_us) * 1e-6 for s in h]
        ds = [s[1] for s in h]
        n = len(ts)
        t_mean = sum(ts) / n
        d_mean = sum(ds) / n
        # the sums over lists (not generators): the same terms added in the same order
        sxx = sum([(x - t_mean) ** 2 for x in ts])
        sxy = sum([(x - t_mean) * (y - d_mean) for x, y in zip(ts, ds)])
        # |ds[i + 1] - 2 ds[i] + ds[i - 1]| for i in 1 .. n - 2, and their median (statistics.median's)
        second = sorted([abs(c - 2.0 * b + a) for a, b, c in zip(ds, ds[1:], ds[2:])])
        m = len(second)
        median = second[m // 2] if m % 2 == 1 else (second[m // 2 - 1] + second[m // 2]) / 2
        white_m = median * MAD_TO_SIGMA / SECOND_DIFF_GAIN
        self.last_slope_mps = sxy / sxx
        self.last_white_sd_mps = white_m / math.sqrt(sxx)
        self.last_span_s = -ts[0]
        self.last_us = t_us
        return self.last_slope_mps
