"""Height references: where zero height is, and holding samples until it is known.

A :class:`ReferenceResolver` serves one reference (the baro reference
pressure, or the GNSS reference altitude). Items that need it are held, in
order, until it is known, then released together with one
:class:`~mavnav.samples.ReferenceSet` event naming the origin:

* ``config``: the configured value, known from the first item.
* ``startup``: the mean over the first ``startup_window_s`` of vehicle
  time of the items themselves (the vehicle is assumed still at the
  reference point when the stream starts).
* source ``home``: the place the autopilot itself calls home, from what
  it streams anyway, so that the reference is known within about a second
  of connecting, on the ground or in flight (the normaliser's ``anchored``
  callback decides; origins ``home``, ``autopilot_home``, ``ekf_origin``).
  If nothing of the kind arrives within ``home_wait_s`` of the first held
  item (or before the end of the stream, or a reboot), the start-up
  estimate is used instead and the event says ``startup``. This bounds
  what is held.

The reference is fixed once per source and kept across reboots (it is a
place, not a state of the vehicle). A home the autopilot moves later (a new
home set at arming) does not re-fix it: the filters would see every height
step at once; the normaliser says the move (``ReferenceMoved``) and the
pipeline reports heights above the new home (:mod:`mavnav.home_frame`).
"""

from __future__ import annotations

from collections import deque
from typing import Callable, Deque, List, NamedTuple, Optional, Sequence, Tuple

from ..config import ReferenceConfig


class AnchoredValue(NamedTuple):
    """The reference taken from the autopilot's reference point, and its origin
    (``home``, ``autopilot_home``, ``ekf_origin``)."""

    value: float
    origin: str


# anchored(held items, final) -> the value and its origin once the autopilot's reference is known, else None
Anchored = Callable[[Sequence[object], bool], Optional[AnchoredValue]]


class ReferenceResolver:
    """``item_t(item) -> (t_us, boot)``; ``startup_value(items) -> float``;
    ``anchored(held, final) -> AnchoredValue | None``."""

    def __init__(
        self,
        kind: str,
        cfg: ReferenceConfig,
        item_t: Callable[[object], Tuple[int, int]],
        startup_value: Callable[[Sequence[object]], float],
        anchored: Anchored,
    ):
        self.kind = kind
        self.cfg = cfg
        self.window_us = int(cfg.startup_window_s * 1e6)
        self.wait_us = int(cfg.home_wait_s * 1e6)
        self._item_t = item_t
        self._startup_value = startup_value
        self._anchored = anchored
        self.value: Optional[float] = None
        self.origin: Optional[str] = None
        self.held: Deque[object] = deque()

    def push(self, item) -> Tuple[Optional[str], List[object]]:
        """Returns ``(origin if the reference was just fixed else None, items released)``."""
        if self.value is not None:
            return None, [item]
        self.held.append(item)
        return self._try(final=False)

    def retry(self) -> Tuple[Optional[str], List[object]]:
        """Something the reference may be taken from arrived (e.g. the autopilot's
        home): fix it now if it can be, even with nothing held yet."""
        if self.value is not None or self.cfg.source != "home":
            return None, []
        return self._try(final=False)

    def finish(self) -> Tuple[Optional[str], List[object]]:
        if self.value is not None or not self.held:
            return None, []
        return self._try(final=True)

    def held_span_us(self) -> int:
        """Vehicle time the held items span (0 when nothing is held)."""
        if not self.held:
            return 0
        t0, b0 = self._item_t(self.held[0])
        t1, b1 = self._item_t(self.held[-1])
        return t1 - t0 if b1 == b0 else self.wait_us

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
            got = self._anchored(list(self.held), final)
            if got is not None:
                return self._release(got.value, got.origin)
            if not self.held:
                return None, []
            if not final and self.held_span_us() < self.wait_us:
                return None, []
        if not self.held:
            return None, []
        window = self._startup_window(final)
        if window is None:
            return None, []
        return self._release(self._startup_value(window), "startup")
