"""The GNSS altitude against the receiver's own Doppler vertical velocity.

A receiver measures its vertical velocity from carrier Doppler, independently
of the pseudorange position solution whose slow errors (multipath, satellite
geometry, convergence after a cold start, bad ephemeris) move the altitude by
metres while the velocity stays right. Over a window of ``window_s`` the
altitude's change less the integral of the Doppler velocity,

    e = [h(t) - h(t - W)] - integral_{t-W}^{t} v_up dt,

is near zero for a healthy receiver and grows with a position-only fault at
the fault's rate (a step shows whole for W seconds). On the real flights here
(``bench/doppler_stats.py``, docs/integrity.md) modern receivers keep ``|e|``
within 0.3-1.4 m over 5 s; receivers whose altitude drifts 15 m in a minute
while the baro and their own Doppler agree show 3-4 m.

The test is one-sided in what it proves: a failure implicates the GNSS alone
(neither the baro nor the INS enters ``e``); a pass rules nothing out, since a
fault that moves position and velocity together (spoofing) passes it.

Pure: samples in, ``e`` out; the caller owns thresholds and verdicts.
"""

from __future__ import annotations

import math
from collections import deque
from typing import Callable, Optional

# The shortest span a window check reads from by default, as a fraction of its
# window: a window restarted by a gap reads again once it holds this much.
MIN_SPAN_FRAC = 0.8


def _or(x: Optional[float], default: float) -> float:
    return default if x is None else x


def restart_on_gap(h: deque, t_us: int, max_gap_us: int) -> None:
    """A sample not after the last one, or after a gap, starts the history again."""
    if h and (t_us <= h[-1][0] or t_us - h[-1][0] > max_gap_us):
        h.clear()


def window_first(h: deque, t_us: int, window_us: int, min_span_us: float):
    """Trim the history to the window ending at ``t_us``; its first entry, or
    None while it spans less than ``min_span_us``."""
    start = t_us - window_us
    while len(h) > 2 and h[1][0] <= start:
        h.popleft()
    return h[0] if t_us - h[0][0] >= min_span_us else None


class DopplerCheck:
    """``e`` over ``window_s`` at each GNSS sample that carries a Doppler
    velocity. Samples further apart than ``max_gap_s``, or without a
    velocity, restart the integral (no interpolation across a gap).

    With ``min_span_s`` the check reads from that span on (a window restarted
    by a gap is not blind for most of its length). The reading's own error is
    ``hypot(sigma_m, scale_frac * distance moved)``. With a ``recent_span_s``
    shorter than the window, it also reads over the latest ``recent_span_s``
    and keeps the reading larger against its own error, so a window that
    still holds a climb or a landing does not hide a ramp that began after
    it."""

    __slots__ = ("window_us", "max_gap_us", "min_span_us", "recent_span_us", "sigma_m", "scale_frac", "hist",
                 "last_e_m", "last_disp_m", "last_span_s", "last_us")

    def __init__(self, window_s: float, max_gap_s: float, min_span_s: Optional[float] = None,
                 sigma_m: float = 1.0, scale_frac: float = 0.0, recent_span_s: Optional[float] = None):
        self.window_us = int(window_s * 1e6)
        self.max_gap_us = int(max_gap_s * 1e6)
        # the shortest span that gives a reading (default 80 % of the window)
        self.min_span_us = (MIN_SPAN_FRAC * self.window_us if min_span_s is None
                            else min(min_span_s * 1e6, self.window_us))
        # the latest span read beside the whole window (None: none)
        self.recent_span_us = (None if not recent_span_s or recent_span_s * 1e6 >= MIN_SPAN_FRAC * self.window_us
                               else recent_span_s * 1e6)
        self.sigma_m = sigma_m
        self.scale_frac = scale_frac
        self.hist: deque = deque()  # (t_us, height_m, vel_up_mps, integral_m)
        self.last_e_m = math.nan
        self.last_disp_m = math.nan  # the Doppler's integral over the same window: how far the vehicle moved
        self.last_span_s = math.nan  # the span the last reading covers
        self.last_us: Optional[int] = None

    def clear(self) -> None:
        self.hist.clear()
        self.last_e_m = math.nan

    def push(self, t_us: int, height_m: float, vel_up_mps: float,
             start_m: Optional[Callable[[int], Optional[float]]] = None) -> Optional[float]:
        """``e`` at this sample (m), or None while less than 80 % of a window of
        continuous data is held. ``start_m``: the height at an earlier
        sample's time, read again now (a level that needed later samples, as
        :mod:`.barolevel`'s), used at the window's start where it gives one."""
        if not (math.isfinite(height_m) and math.isfinite(vel_up_mps)):
            self.clear()
            return None
        h = self.hist
        restart_on_gap(h, t_us, self.max_gap_us)
        integral = 0.0
        if h:
            t0, _, v0, i0 = h[-1]
            integral = i0 + 0.5 * (v0 + vel_up_mps) * (t_us - t0) * 1e-6
        h.append((t_us, height_m, vel_up_mps, integral))
        first = window_first(h, t_us, self.window_us, self.min_span_us)
        if first is None:
            return None
        t_j, h_j, _, i_j = first
        if start_m is not None:
            h_j = _or(start_m(t_j), h_j)
        e = (height_m - h_j) - (integral - i_j)
        disp = integral - i_j
        recent = self.recent_span_us
        if recent is not None and t_us - t_j > recent:
            # the latest short span too: the first entry at least recent_span back
            k = len(h) - 1
            while k > 0 and t_us - h[k][0] < recent:
                k -= 1
            t_k, h_k, _, i_k = h[k]
            if start_m is not None:
                h_k = _or(start_m(t_k), h_k)
            e_k, d_k = (height_m - h_k) - (integral - i_k), integral - i_k
            if abs(e_k) * self.error_m(disp) > abs(e) * self.error_m(d_k):
                t_j, e, disp = t_k, e_k, d_k
        self.last_e_m = e
        self.last_disp_m = disp
        self.last_span_s = (t_us - t_j) * 1e-6
        self.last_us = t_us
        return e

    def error_m(self, disp_m: float) -> float:
        """The reading's own error over a span in which the vehicle moved ``disp_m``."""
        return math.hypot(self.sigma_m, self.scale_frac * disp_m)


class InsDopplerCheck:
    """The INS's vertical velocity change against the receiver's Doppler
    velocity change over ``window_s``:

        e_v = [v_dop(t) - v_dop(t - W)] - [V_ins(t) - V_ins(t - W)],

    ``V_ins`` the chained increments of ``f_up - g`` less the channel's
    accelerometer-bias estimate. An accelerometer fault moves ``V_ins`` and
    not the Doppler; a fault in the GNSS velocity (spoofing moves position and
    velocity together) moves the Doppler and not the INS; a baro fault or a
    GNSS position-only fault moves neither. The variance the INS adds is the
    measured scatter of held IMU snapshots over the window (the epoch
    builder's ``dv_var``), chained like the velocity, so a telemetry-rate IMU
    widens the test instead of failing it."""

    __slots__ = ("window_us", "max_gap_us", "_vel", "_var", "hist", "last_e_mps", "last_var_mps2", "last_us")

    def __init__(self, window_s: float, max_gap_s: float):
        self.window_us = int(window_s * 1e6)
        self.max_gap_us = int(max_gap_s * 1e6)
        self._vel = 0.0
        self._var = 0.0
        self.hist: deque = deque()  # (t_us, v_dop, V_ins, var_ins)
        self.last_e_mps = math.nan
        self.last_var_mps2 = 0.0
        self.last_us: Optional[int] = None

    def clear(self) -> None:
        self.hist.clear()
        self.last_e_mps = math.nan

    def push_ins(self, dt_s: float, dv_mps: float, dv_var_m2ps2: float, acc_bias_mps2: float) -> None:
        self._vel += dv_mps - acc_bias_mps2 * dt_s
        self._var += max(dv_var_m2ps2, 0.0)

    def push_gnss(self, t_us: int, vel_up_mps: float) -> Optional[float]:
        if not math.isfinite(vel_up_mps):
            self.clear()
            return None
        h = self.hist
        restart_on_gap(h, t_us, self.max_gap_us)
        h.append((t_us, vel_up_mps, self._vel, self._var))
        first = window_first(h, t_us, self.window_us, 0.8 * self.window_us)
        if first is None:
            return None
        _, v_j, V_j, var_j = first
        e = (vel_up_mps - v_j) - (self._vel - V_j)
        self.last_e_mps = e
        self.last_var_mps2 = self._var - var_j
        self.last_us = t_us
        return e


class Exceedance:
    """Consecutive samples of a statistic past its threshold, and since when:
    a test fails on two in a row held ``persist_us`` (one outlier is the
    gate's business); and consecutive samples past its suspect level (or its
    threshold): a test is suspect on two in a row, not on one."""

    __slots__ = ("count", "since_us", "near")

    def __init__(self) -> None:
        self.count = 0
        self.since_us: Optional[int] = None
        self.near = 0

    def update(self, t_us: int, over: bool, near: bool = False) -> None:
        self.near = self.near + 1 if over or near else 0
        if over:
            self.count += 1
            if self.since_us is None:
                self.since_us = t_us
        else:
            self.count, self.since_us = 0, None

    def reset(self) -> None:
        self.count, self.since_us, self.near = 0, None, 0

    def persistent(self, t_us: int, persist_us: int) -> bool:
        return self.count >= 2 and self.since_us is not None and t_us - self.since_us >= persist_us
