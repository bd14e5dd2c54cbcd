"""Attitude at IMU time: buffer IMU samples briefly until a bracketing attitude arrives.

An IMU sample at ``t`` is resolved with the two consecutive attitudes
around it (quaternion slerp) when they are at most ``2 * max_age`` apart.
If none brackets it once the vehicle clock has passed ``t + wait`` (or when
every attitude is later than ``t``), it takes the nearest attitude within
``max_age`` (counted as ``nearest``); with none that close by ``t + max_age``
it is refused (``no_attitude``). Samples leave in arrival order.
"""

from __future__ import annotations

from bisect import bisect_left
from collections import deque
from typing import Deque, List, Optional, Tuple

from ..frames import Quat, slerp

_KEEP = 512  # attitudes kept (10 s at 50 Hz)
_WAIT = object()  # an item that waits for a later attitude


class AttitudeInterpolator:
    def __init__(self, wait_s: float, max_age_s: float):
        self.wait_us = int(wait_s * 1e6)
        self.max_age_us = int(max_age_s * 1e6)
        self._t: List[int] = []
        self._q: List[Quat] = []
        self.pending: Deque = deque()  # items waiting for their attitude, in arrival order; each has .t_us (ImuItem)
        self.nearest = 0

    def reset(self) -> None:
        self._t.clear()
        self._q.clear()

    def add(self, t_us: int, q: Quat) -> None:
        if self._t and t_us <= self._t[-1]:
            return  # keep the attitude series strictly increasing
        self._t.append(t_us)
        self._q.append(q)
        if len(self._t) > 2 * _KEEP:
            del self._t[:_KEEP]
            del self._q[:_KEEP]

    def latest(self, t_us: int) -> Optional[Quat]:
        """Most recent attitude, if within ``max_age`` of ``t_us`` (for the rangefinder)."""
        if self._t and abs(self._t[-1] - t_us) <= self.max_age_us:
            return self._q[-1]
        return None

    def resolve(self, now_us: Optional[int], flush: bool = False) -> List[Tuple[object, Optional[Quat], bool]]:
        """Pop resolvable pending items: ``(item, quat or None, used_nearest)``, in arrival order."""
        pend = self.pending
        ts = self._t
        if pend and not flush and ts and now_us is not None:  # inline, the hot path
            t = pend[0].t_us
            if t > ts[-1] and now_us < t + self.wait_us:
                return []  # fast path: still waiting for the next attitude
        out = []
        while pend:
            item = pend[0]
            t = item.t_us
            q = self._bracketed(t)
            if q is not None:
                pend.popleft()
                out.append((item, q, False))
                continue
            near = self._unbracketed(t, now_us, flush)
            if near is _WAIT:
                break
            pend.popleft()
            if near is None:
                out.append((item, None, False))
            else:
                self.nearest += 1
                out.append((item, near, True))
        return out

    def _bracketed(self, t: int) -> Optional[Quat]:
        """The attitude at ``t`` from the two attitudes around it (one at ``t``
        itself, or a slerp between two no more than twice ``max_age`` apart)."""
        ts = self._t
        if not ts or not ts[0] <= t <= ts[-1]:
            return None
        i = bisect_left(ts, t)
        if ts[i] == t:
            return self._q[i]
        t0, t1 = ts[i - 1], ts[i]
        if t1 - t0 <= 2 * self.max_age_us:
            return slerp(self._q[i - 1], self._q[i], (t - t0) / (t1 - t0))
        return None

    def _unbracketed(self, t: int, now_us: Optional[int], flush: bool):
        """The attitude of an item no pair brackets: the first attitude when
        every one is later (None when too far), else the nearest one once its
        wait is over (None when none is close); ``_WAIT`` while a better one
        may still come."""
        ts = self._t
        if ts and t < ts[0]:
            return self._q[0] if ts[0] - t <= self.max_age_us else None  # every attitude is later
        if not flush and (now_us is None or now_us < t + self.wait_us):
            return _WAIT  # a bracketing attitude may still come
        near = self._nearest(t)
        if near is None and not flush and now_us < t + self.max_age_us:
            return _WAIT  # nothing close yet; a later attitude may still be
        return near

    def _nearest(self, t: int) -> Optional[Quat]:
        ts = self._t
        if not ts:
            return None
        i = bisect_left(ts, t)
        best = None
        for j in (i - 1, i):
            if 0 <= j < len(ts) and abs(ts[j] - t) <= self.max_age_us:
                if best is None or abs(ts[j] - t) < abs(ts[best] - t):
                    best = j
        return self._q[best] if best is not None else None
