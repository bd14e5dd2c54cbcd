"""Sliding window (in vehicle time) of squared normalised innovations."""

from __future__ import annotations

from collections import deque


class InnovationWindow:
    """Sum of ``nu^2`` and count of gate rejections over the last ``length_us``.

    Rejected samples enter the sum capped at ``cap`` (one wild sample must not
    mask the window for its whole length, but many must show).
    """

    def __init__(self, length_s: float, cap: float = 100.0):
        self.length_us = int(length_s * 1e6)
        self.cap = cap
        self._q: deque[tuple[int, float, bool]] = deque()
        self.total = 0.0
        self.rejected = 0

    def clear(self) -> None:
        self._q.clear()
        self.total = 0.0
        self.rejected = 0

    def push(self, t_us: int, nu2: float, rejected: bool) -> None:
        v = min(nu2, self.cap)
        self._q.append((t_us, v, rejected))
        self.total += v
        self.rejected += rejected
        self.expire(t_us)

    def expire(self, t_us: int) -> None:
        limit = t_us - self.length_us
        q = self._q
        while q and q[0][0] <= limit:
            _, v, r = q.popleft()
            self.total -= v
            self.rejected -= r
        if not q:
            self.total = 0.0

    @property
    def n(self) -> int:
        return len(self._q)
