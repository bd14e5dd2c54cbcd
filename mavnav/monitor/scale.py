"""The measured scale of a normalised residual stream: what the filters'
covariance predicts against what the flight shows.

A test statistic built from normalised residuals ``z = r / sqrt(S)`` assumes
``z`` is white with unit variance. On real flights neither holds: GNSS
altitude wanders with minutes of correlation, telemetry-rate IMU samples make
the INS worse than its model, and receivers report conservative accuracies
(``z`` far below 1). A CUSUM fed such residuals either alarms on the wander or
sleeps through a ramp.

:class:`ResidualScale` estimates, from the residuals themselves, their
variance ratio ``E[z^2]`` and lag-one correlation ``phi`` with exponential
forgetting (time constant ``tau_s``), and returns the long-run standard
deviation factor ``sqrt(E[z^2] (1 + phi) / (1 - phi))``: the scale a sum of
residuals actually grows with. Dividing ``z`` by it gives residuals whose sums
behave as the test assumes. It starts at 1 (the model), with the model's
weight worth ``tau_s`` of data, and is clipped to ``[lo, hi]``: the data may
sharpen a test at most ``1/lo`` times and dull it at most ``hi`` times. The
caller freezes it (does not push) while its test is past caution, so a fault
cannot teach the test to ignore it.
"""

from __future__ import annotations

import math
import statistics
from collections import deque
from typing import Optional

_INF = math.inf
_exp = math.exp
_sqrt = math.sqrt


class ResidualScale:
    __slots__ = ("tau_s", "lo", "hi", "max_phi", "m2", "c1", "prev", "last_us")

    def __init__(self, tau_s: float, lo: float, hi: float, max_phi: float = 0.95, prior_m2: float = 1.0):
        self.tau_s = tau_s
        self.lo = lo
        self.hi = hi
        self.max_phi = max_phi
        self.m2 = prior_m2  # E[z^2]; 1: the model's own scale
        self.c1 = 0.0  # E[z_t z_{t-1}]
        self.prev = math.nan
        self.last_us = None

    def push(self, t_us: int, z: float) -> None:
        if z != z or z == _INF or z == -_INF:  # abs(z) == inf
            return
        last = self.last_us
        if last is None:
            dt = 0.1
        else:
            dt = (t_us - last) * 1e-6
            if 0.0 > dt:  # max(dt, 0.0)
                dt = 0.0
        self.last_us = t_us
        w = 1.0 - _exp(-dt / self.tau_s)
        m2 = self.m2
        self.m2 = m2 + w * (z * z - m2)
        prev = self.prev
        if prev == prev:
            self.c1 += w * (z * prev - self.c1)
        self.prev = z

    def gap(self) -> None:
        """The stream paused: the next residual is not a neighbour of the last."""
        self.prev = math.nan

    # The clips below are max(lo, min(hi, v)) spelled as conditionals (several
    # calls an epoch): min(a, b) is a unless b < a, max(a, b) is a unless b > a,
    # so NaN and signed zeros come out as max and min give them
    # (tests/test_monitor_scale.py).

    @property
    def phi(self) -> float:
        m2 = self.m2
        if m2 <= 0:
            return 0.0
        r = self.c1 / m2
        mp = self.max_phi
        r = r if r < mp else mp  # min(max_phi, r)
        return r if r > 0.0 else 0.0  # max(0.0, r)

    @property
    def sd(self) -> float:
        """The residuals' own standard deviation (for per-sample gates, where
        correlation does not matter), clipped like :attr:`factor`."""
        m2 = self.m2
        v = _sqrt(0.0 if 0.0 > m2 else m2)  # max(m2, 0.0)
        hi, lo = self.hi, self.lo
        v = v if v < hi else hi
        return v if v > lo else lo

    @property
    def factor(self) -> float:
        phi = self.phi
        lrv = self.m2 * (1.0 + phi) / (1.0 - phi)
        v = _sqrt(0.0 if 0.0 > lrv else lrv)  # max(lrv, 0.0)
        hi, lo = self.hi, self.lo
        v = v if v < hi else hi
        return v if v > lo else lo


class LagSeries:
    """A series' second difference over a lag, ``x(t) - 2 x(t - L) + x(t - 2 L)``
    in the form a straight line does not move whatever the sample times: the
    latest sample's departure from the line through two lagged samples ``x1``
    (the latest at or before ``t - L``) and ``x2`` (at or before ``t - 2 L``),
    ``x - x1 - a (x1 - x2)`` with ``a = (t - t1) / (t1 - t2)``, scaled by
    ``sqrt(6 / (1 + (1 + a)^2 + a^2))`` so that white noise reads as the even
    second difference does (variance ``6 sigma^2``). Each lagged sample must be
    within a quarter of the lag of its time (else none: a gap). Amortised O(1)
    per sample; :meth:`clear` starts it again (a fault, a restart)."""

    __slots__ = ("lag_us", "tol_us", "t", "x", "i1", "i2")

    def __init__(self, lag_s: float):
        self.lag_us = int(lag_s * 1e6)
        self.tol_us = self.lag_us // 4
        self.t: list[int] = []
        self.x: list[float] = []
        self.i1 = self.i2 = 0

    def clear(self) -> None:
        if self.t:  # (asked every epoch a channel is out: nothing to drop then)
            self.t, self.x = [], []
            self.i1 = self.i2 = 0

    def push(self, t_us: int, x: float) -> Optional[float]:
        ts, xs = self.t, self.x
        ts.append(t_us)
        xs.append(x)
        lag = self.lag_us
        i1, i2, last = self.i1, self.i2, len(ts) - 1
        while i1 < last and ts[i1 + 1] <= t_us - lag:
            i1 += 1
        while i2 < i1 and ts[i2 + 1] <= t_us - 2 * lag:
            i2 += 1
        if i2 > 512:  # drop what no lag reaches any more
            del ts[:i2], xs[:i2]
            i1, i2 = i1 - i2, 0
        self.i1, self.i2 = i1, i2
        tol = self.tol_us
        t1, t2 = ts[i1], ts[i2]
        if not (0 <= t_us - lag - t1 <= tol and 0 <= t_us - 2 * lag - t2 <= tol) or t1 <= t2:
            return None
        a = (t_us - t1) / (t1 - t2)
        x1 = xs[i1]
        return (x - x1 - a * (x1 - xs[i2])) * math.sqrt(6.0 / (1.0 + (1.0 + a) ** 2 + a * a))


# |x| of a standard normal: its median
MEDIAN_ABS_NORMAL = 0.6744897501960817


class MedianScale:
    """The sigma of a zero-mean series from the median of its absolute values
    over the last ``memory_s`` (``median |x| / 0.6745``): robust to the few
    readings a fault's onset adds, so the caller need not freeze it. None
    until ``min_samples`` are held; recomputed at most every ``update_s``
    (time from the samples)."""

    def __init__(self, memory_s: float, min_samples: int, update_s: float):
        self.memory_us = int(memory_s * 1e6)
        self.min_samples = min_samples
        self.update_us = int(update_s * 1e6)
        self.t: deque = deque()
        self.x: deque = deque()
        self.next_us = -(1 << 62)
        self.sd: Optional[float] = None

    def push(self, t_us: int, x_abs: float) -> bool:
        """One reading; True when the scale was recomputed."""
        ts, xs = self.t, self.x
        ts.append(t_us)
        xs.append(x_abs)
        limit = t_us - self.memory_us
        while ts[0] < limit:
            ts.popleft()
            xs.popleft()
        if t_us < self.next_us or len(xs) < self.min_samples:
            return False
        self.next_us = t_us + self.update_us
        self.sd = statistics.median(xs) / MEDIAN_ABS_NORMAL
        return True
