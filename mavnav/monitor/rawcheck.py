"""Baro-independent evidence: raw GNSS height against raw rangefinder height.

All three channels use the barometer, each trusting it to a different degree,
so a baro fault makes the channels disagree with each other in ways that look
like an aux-sensor fault. The raw heights of the two aux sensors share nothing
with the baro or the INS: if they agree, an aux sensor is not the culprit.

Rangefinder heights are above the ground, GNSS heights above the reference;
the paper's flat-ground assumption is made here too, as in the rangefinder
channel itself: the ground is where the vehicle stood. A start on the ground
at the datum puts it at the reference, as does the operator's word
(``monitor.ground_at_reference``: ``learn_ground`` False). A start anywhere else (a log or a link
joined in flight) says nothing of where the ground lies against the
reference, so the check learns it: the mean difference of its first full
window, where it departs from zero by more than the test's own threshold,
is the ground's height against the reference (``ground_m``; within it the
flat ground stands). The monitor then adds it to every rangefinder reading,
for its channel and for this check, whose later windows are tested against
zero with the ground's own sigma (one window's) counted. A rangefinder
already faulty at such a start is learnt as ground; nothing in the data can
tell the two apart.

Why a threshold, measured (``bench/integrity.py``, families inflight_start,
inflight_terrain and the descents, 12 seeds, shipped model). Learnt always,
the rangefinder channel carries the GNSS's error of that moment, which its
filter does not know (the ground is no state of the channel): in-flight
starts and descents from above the rangefinder's range had their output
0.4-1.2 m off beyond the protection level for up to 4.4 s (46.5 s over 316
runs, against none), and a GNSS fault under way when the ground was learnt
stayed in the rangefinder channel after it (a frozen rangefinder in a
descent 1.5 -> 2.7 m, a GNSS ramp in a descent 1.1 -> 2.2 m): the output
following a faulty GNSS. Kept: within the threshold the flat ground
stands (``ground_m`` 0).

Either way the ground is known only as well as one window of the GNSS can
say, and that variance (``ground_var_m2``) is counted in the rangefinder
channel's height where the channels are fused (HypothesisLogic._fuse): the
channel's filter does not know it (the ground is no state of the channel).
Uncounted where the ground was learnt, it put the truth model's output
0.6-1.0 m off beyond the protection level for whole flights
(inflight_terrain, 5 of 12 seeds); uncounted where the flat ground stood, a
ground 3.4-5.6 m off carried the output that far off at nominal for up to
55 s (inflight_terrain, 3 of 12 seeds, both models). Counted, those flights
are unavailable wherever the GNSS and the baro cannot meet the alert limit
without the rangefinder's absolute height: a flight joined in the air over
ground no sensor has placed has no height above the reference that the
evidence can bound to the alert limit. The simulated flights joined in the
air over flat ground at the reference lost their availability with it
(inflight_start 80 -> 0 %, descent_above_max 41 -> 0 %): the same evidence,
the ground right only by the scenario's construction. Until the ground is
placed (``ground_m`` None: the first window not yet full, or no GNSS at all)
the rangefinder's height stays out of the fused height.
"""

from __future__ import annotations

import math
from collections import deque
from typing import Optional


class RawAuxCheck:
    def __init__(self, window_s: float, k: float, max_skew_s: float = 0.25, learn_ground: bool = False):
        self.window_us = int(window_s * 1e6)
        self.k = k
        self.max_skew_us = int(max_skew_s * 1e6)
        # the ground's height against the reference and its variance: known (0, 0)
        # for a start at the datum, learnt from the first full window otherwise
        self.ground_m: Optional[float] = None if learn_ground else 0.0
        self.ground_var_m2 = 0.0
        self._g: Optional[tuple[int, float, float]] = None  # (t_us, z, sigma)
        self._r: Optional[tuple[int, float, float]] = None
        self._q: deque[tuple[int, float, float]] = deque()  # (t_us, diff, var)

    def push(self, t_us: int, gnss: Optional[tuple[float, float]], rng: Optional[tuple[float, float]]) -> None:
        """Latest raw (height, sigma) of each aux sensor seen at this epoch. A
        pair is formed at each GNSS sample (the slower, noisier stream) with the
        latest rangefinder reading, so no GNSS sample counts twice."""
        if rng is not None:
            self._r = (t_us, rng[0], rng[1])
        if gnss is not None:
            self._g = (t_us, gnss[0], gnss[1])
            if self._r and abs(self._g[0] - self._r[0]) <= self.max_skew_us:
                self._q.append((t_us, self._g[1] - self._r[1], self._g[2] ** 2 + self._r[2] ** 2))
        while self._q and self._q[0][0] <= t_us - self.window_us:
            self._q.popleft()

    def verdict(self) -> Optional[tuple[bool, float, float]]:
        """``(agree, mean difference, its sigma)`` over the window, or None
        when there are too few paired samples to say. The sigma is one
        sample's: GNSS errors are correlated in time, so averaging the window
        does not shrink them."""
        n = len(self._q)
        if n < 3:
            return None
        mean = sum(d for _, d, _ in self._q) / n
        var = sum(v for _, _, v in self._q) / n
        if self.ground_m is None:
            if self._q[-1][0] - self._q[0][0] < self.window_us * (n - 1) / n:
                return None  # the first window is not full yet
            if abs(mean) > self.k * math.sqrt(var):
                # the readings still to come carry the ground (the caller adds it)
                self.ground_m, self.ground_var_m2 = mean, var
                self._q.clear()
                return None
            self.ground_m = 0.0
            # flat, as far as one window can tell: the ground is known no better
            # than when it is learnt, and the rangefinder channel carries that
            self.ground_var_m2 = var
        sigma = math.sqrt(var + self.ground_var_m2)
        return abs(mean) <= self.k * max(sigma, 1e-6), mean, sigma

    def clear(self) -> None:
        self._q.clear()
