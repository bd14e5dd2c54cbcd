"""The baro's level at a GNSS sample's time, robust to its white noise and
outliers, for the baro/Doppler window check (:mod:`.doppler`).

That check compares the baro's change over a window with the integral of the
receiver's Doppler velocity. Read from one baro sample at each end, a small
drone's baro (white noise 0.3-0.6 m under its propellers, single readings
2-3 m off) makes the reading as noisy as a fault's first seconds: on the PX4
flights here with 5 Hz baros the 99th percentile of the 10 s reading is
1.3-2.2 m, and 0.7-1.5 m with each end the mean of the baro over a second
(BENCHMARKS.md, session 22). A mean spreads one outlier over every reading
that holds it, so two readings in a row (the check's suspicion) would see one
bad sample: the median does not.

The two ends are not alike. The window's start lies ``window_s`` in the
past, so its level is the median of the samples on both sides of it,
``span_s`` wide: no lag. Its end is now, where a median over a span would lag
a ramp or a step by half of it (0.5 s later alerts on every injected baro
ramp of the real-flight scorecard with a 1 s trailing span); it is the median
of the last ``end_count`` samples, one sample interval of lag.

Each baro sample is kept as its offset from the Doppler integral at its own
time, ``r = b - J(t_b)`` (``J`` carried from the last GNSS sample by its
velocity, over at most one GNSS interval), so samples taken while the
vehicle moves are compared at one time: a level at a GNSS sample's time
``t`` is ``median(r) + J(t)``. Pure: time comes from the samples.
"""

from __future__ import annotations

import math
import statistics
from collections import deque
from typing import Optional


class BaroLevel:
    __slots__ = ("span_us", "keep_us", "max_gap_us", "end_count", "r", "j_hist", "t_gnss_us", "j_m", "v_mps")

    def __init__(self, span_s: float, keep_s: float, max_gap_s: float, end_count: int = 3):
        self.span_us = int(span_s * 1e6)
        self.keep_us = int(keep_s * 1e6) + self.span_us  # the window and half a span each side
        self.max_gap_us = int(max_gap_s * 1e6)
        self.end_count = end_count
        self.r: deque = deque()  # (t_us, baro height less the Doppler integral, m)
        self.j_hist: deque = deque()  # (t_us, the Doppler integral there) per GNSS sample
        self.t_gnss_us: Optional[int] = None
        self.j_m = 0.0  # the Doppler integral at t_gnss_us
        self.v_mps = math.nan

    def clear(self) -> None:
        self.r.clear()
        self.j_hist.clear()
        self.t_gnss_us = None
        self.j_m = 0.0
        self.v_mps = math.nan

    def _j_at(self, t_us: int) -> float:
        return self.j_m + self.v_mps * (t_us - self.t_gnss_us) * 1e-6

    def push_baro(self, t_us: int, height_m: float) -> None:
        """A baro sample (ignored before a GNSS velocity, or one not finite)."""
        if self.t_gnss_us is None or not math.isfinite(height_m):
            return
        if t_us - self.t_gnss_us > self.max_gap_us:
            self.clear()  # no Doppler to carry it: a stale velocity is no reference
            return
        self.r.append((t_us, height_m - self._j_at(t_us)))

    def push_gnss(self, t_us: int, vel_up_mps: float) -> None:
        """A GNSS sample's Doppler velocity: the integral moves on to it."""
        if not math.isfinite(vel_up_mps):
            self.clear()
            return
        t0 = self.t_gnss_us
        if t0 is None or t_us <= t0 or t_us - t0 > self.max_gap_us:
            self.clear()
        else:
            self.j_m += 0.5 * (self.v_mps + vel_up_mps) * (t_us - t0) * 1e-6
        self.t_gnss_us, self.v_mps = t_us, vel_up_mps
        self.j_hist.append((t_us, self.j_m))
        start = t_us - self.keep_us
        while self.j_hist[0][0] < start:
            self.j_hist.popleft()
        r = self.r
        while r and r[0][0] < start:
            r.popleft()

    def end_m(self, t_us: int) -> Optional[float]:
        """The level at ``t_us`` (the last GNSS sample's time): the median of
        the last ``end_count`` samples not after it and within a span of it,
        carried to it; None without one."""
        vals = []
        for t_b, x in reversed(self.r):
            if t_b > t_us:
                continue
            if t_b <= t_us - self.span_us or len(vals) == self.end_count:
                break
            vals.append(x)
        return statistics.median(vals) + self._j_at(t_us) if vals else None

    def centred_m(self, t_us: int) -> Optional[float]:
        """The level at an earlier GNSS sample's time ``t_us``: the median of
        the samples within half a span either side, carried to it; None
        without one, or without that sample's integral."""
        j = next((jm for tj, jm in self.j_hist if tj == t_us), None)
        if j is None:
            return None
        half = self.span_us // 2
        vals = [x for t_b, x in self.r if t_us - half < t_b <= t_us + half]
        return statistics.median(vals) + j if vals else None
