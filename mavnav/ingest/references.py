"""Height references: where zero height is, and holding samples until it is known.

A :class:`ReferenceResolver` serves one reference (the baro reference
pressure, or the GNSS reference altitude). Items that need it are held, in
order, until it is known, then released together with one
:class:`~mavnav.samples.ReferenceSet` event naming the origin:

* ``config``: the configured value, known from the first item.
* ``startup``: the mean over the first ``startup_window_s`` of vehicle
  time of the items themselves (the vehicle is assumed still at the
  reference point when the stream starts).
* ``home``: from HOME_POSITION (``home_value``). If no HOME_POSITION arrives
  within ``home_wait_s`` of the first held item (or before the end of the
  stream), the start-up estimate is used instead and the event says
  ``startup``. This bounds what is held.

The reference is fixed once per source and kept across reboots (it is a
place, not a state of the vehicle).
"""

from __future__ import annotations

from collections import deque
from typing import Callable, Deque, List, Optional, Sequence, Tuple

from ..config import ReferenceConfig


class ReferenceResolver:
    """``item_t(item) -> (t_us, boot)``; ``startup_value(items) -> float``;
    ``home_value(home, items_before, items_after) -> float | None``."""

    def __init__(
        self,
        kind: str,
        cfg: ReferenceConfig,
        item_t: Callable[[object], Tuple[int, int]],
        startup_value: Callable[[Sequence[object]], float],
        home_value: Callable[[tuple, Sequence[object], Sequence[object]], Optional[float]],
    ):
        self.kind = kind
        self.cfg = cfg
        self.window_us = int(cfg.startup_window_s * 1e6)
        self.wait_us = int(cfg.home_wait_s * 1e6)
        self._item_t = item_t
        self._startup_value = startup_value
        self._home_value = home_value
        self.value: Optional[float] = None
        self.origin: Optional[str] = None
        self.home: Optional[tuple] = None  # (t_us, boot, alt_msl_m)
        self.held: Deque[object] = deque()

    def set_home(self, t_us: int, boot: int, alt_msl_m: float) -> None:
        if self.home is None:
            self.home = (t_us, boot, alt_msl_m)

    def push(self, item) -> Tuple[Optional[str], List[object]]:
        """Returns ``(origin if the reference was just fixed else None, items released)``."""
        if self.value is not None:
            return None, [item]
        self.held.append(item)
        return self._try(final=False)

    def finish(self) -> Tuple[Optional[str], List[object]]:
        if self.value is not None or not self.held:
            return None, []
        return self._try(final=True)

    def _release(self, value: float, origin: str) -> Tuple[Optional[str], List[object]]:
        self.value = value
        self.origin = origin
        out = list(self.held)
        self.held.clear()
        return origin, out

    def _startup_window(self, final: bool) -> Optional[List[object]]:
        t0, b0 = self._item_t(self.held[0])
        window = []
        complete = final
        for it in self.held:
            t, b = self._item_t(it)
            if b != b0 or t - t0 >= self.window_us:
                complete = True
                if t - t0 > self.window_us or b != b0:
                    break
            window.append(it)
        return window if complete else None

    def _try(self, final: bool) -> Tuple[Optional[str], List[object]]:
        src = self.cfg.source
        if src == "config":
            return self._release(float(self.cfg.value), "config")
        if src == "home":
            if self.home is not None:
                th, bh, _ = self.home
                before, after = [], []
                for it in self.held:
                    t, b = self._item_t(it)
                    if b == bh and th - self.window_us <= t <= th:
                        before.append(it)
                    elif (b == bh and t > th) or b > bh:
                        after.append(it)
                v = self._home_value(self.home, before, after)
                if v is None and final:
                    v = self._home_value(self.home, before, after or list(self.held))
                if v is not None:
                    return self._release(v, "home")
                if not final:
                    return None, []
            else:
                t0, b0 = self._item_t(self.held[0])
                t1, b1 = self._item_t(self.held[-1])
                if not final and b1 == b0 and t1 - t0 < self.wait_us:
                    return None, []
        window = self._startup_window(final)
        if window is None:
            return None, []
        return self._release(self._startup_value(window), "startup")
