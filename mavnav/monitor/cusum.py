"""Two-sided CUSUM of normalised residuals: the sequential test for ramps and
small steps that a per-sample gate cannot see.

``g+ = max(0, g+ + z - k)``, ``g- = max(0, g- - z - k)``; the test fails when
either passes ``h``. ``k`` (in sigma) is half the smallest shift worth
detecting quickly; ``h`` follows from the false-alert budget through
Siegmund's approximation of the in-control average run length of a one-sided
CUSUM of unit-variance normal residuals,

    ARL0(h) = (exp(2 k b) - 2 k b - 1) / (2 k^2),  b = h + 1.166,

solved for the run length that spends the budget at the stream's own rate
(a 2 Hz stream gets a lower ``h`` than a 20 Hz one for the same alarms per
hour). Residuals enter clipped at ``clip`` sigma: one wild sample is the
gate's business, many are this test's.
"""

from __future__ import annotations

import math


def siegmund_arl(k: float, h: float) -> float:
    """In-control average run length (samples) of a one-sided CUSUM."""
    b = h + 1.166
    x = 2.0 * k * b
    return (math.exp(x) - x - 1.0) / (2.0 * k * k)


def threshold_for(k: float, false_alerts_per_h: float, rate_hz: float) -> float:
    """``h`` whose two-sided false-alert rate is ``false_alerts_per_h`` at ``rate_hz``."""
    arl = 2.0 * 3600.0 * max(rate_hz, 1e-3) / false_alerts_per_h  # two sides share the budget
    lo, hi = 0.0, 200.0
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if siegmund_arl(k, mid) < arl:
            lo = mid
        else:
            hi = mid
    return hi


class Cusum:
    """The two-sided CUSUM; with ``k_fast`` a second pair of arms beside it,
    tuned to steps of ``2 k_fast`` sigma (a CUSUM is quickest for shifts near
    ``2 k``: ``k = 0.5`` waits five or six samples for a 3 sigma step, ``k =
    1.5`` about three). The caller sets each pair's threshold from its own
    false-alert budget (:func:`threshold_for`)."""

    __slots__ = ("k", "clip", "up", "down", "k_fast", "up_fast", "down_fast", "n_up_fast", "n_down_fast")

    def __init__(self, k: float, clip: float, k_fast: float = 0.0):
        self.k = k
        self.clip = clip
        self.up = 0.0
        self.down = 0.0
        self.k_fast = k_fast  # 0: no fast arms
        self.up_fast = 0.0
        self.down_fast = 0.0
        self.n_up_fast = 0  # samples since each fast arm last stood at zero
        self.n_down_fast = 0

    def push(self, z: float) -> None:
        if z != z:
            return
        z = max(-self.clip, min(self.clip, z))
        self.up = max(0.0, self.up + z - self.k)
        self.down = max(0.0, self.down - z - self.k)
        if self.k_fast:
            self.up_fast = max(0.0, self.up_fast + z - self.k_fast)
            self.down_fast = max(0.0, self.down_fast - z - self.k_fast)
            self.n_up_fast = self.n_up_fast + 1 if self.up_fast > 0.0 else 0
            self.n_down_fast = self.n_down_fast + 1 if self.down_fast > 0.0 else 0

    @property
    def stat(self) -> float:
        return max(self.up, self.down)

    @property
    def fast_stat(self) -> float:
        return max(self.up_fast, self.down_fast)

    @property
    def fast_shift(self) -> float:
        """The shift the leading fast arm has summed, in sigma: ``k + S / n``
        over the ``n`` samples since it left zero (the CUSUM's own estimate of
        a step's size; 0 while both arms stand at zero)."""
        if self.up_fast >= self.down_fast:
            return self.k_fast + self.up_fast / self.n_up_fast if self.n_up_fast else 0.0
        return self.k_fast + self.down_fast / self.n_down_fast if self.n_down_fast else 0.0

    @property
    def sign(self) -> int:
        # the slow arms always hold at least what the fast ones do (a smaller k
        # on the same residuals), so their sign is the fast arms' too
        return 1 if self.up >= self.down else -1

    def clear(self) -> None:
        self.up = self.down = 0.0
        self.up_fast = self.down_fast = 0.0
        self.n_up_fast = self.n_down_fast = 0
