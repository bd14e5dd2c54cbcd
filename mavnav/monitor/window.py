"""Sliding window (in vehicle time) of a stream's gate rejections."""

from __future__ import annotations

from collections import deque


class RejectionWindow:
    """How many of a stream's samples the gate rejected over the last
    ``length_s`` (the innovation tests' ``caution_rejections`` and
    ``alarm_rejections``)."""

    def __init__(self, length_s: float):
        self.length_us = int(length_s * 1e6)
        self._q: deque[int] = deque()  # times of the rejected samples
        self.rejected = 0

    def clear(self) -> None:
        self._q.clear()
        self.rejected = 0

    def push(self, t_us: int, rejected: bool) -> None:
        q = self._q
        if rejected:
            q.append(t_us)
        limit = t_us - self.length_us  # expire(t_us), inline
        while q and q[0] <= limit:
            q.popleft()
        self.rejected = len(q)

    def expire(self, t_us: int) -> None:
        """Forget the rejections older than the window at ``t_us``."""
        limit = t_us - self.length_us
        q = self._q
        while q and q[0] <= limit:
            q.popleft()
        self.rejected = len(q)
