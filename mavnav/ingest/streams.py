"""Per-kind stream discipline: one source per kind, strictly increasing time, gaps.

* :class:`SourceSelector` picks one message type for a kind (IMU,
  rangefinder, autopilot height) and never mixes two. A fixed choice passes
  its type only. ``"auto"`` notes the types that arrive during ``select_s``
  of vehicle time after the first one (holding their items), then picks the
  best type seen (a type ranked first is taken at once), releases its held
  items and drops the others.
* :class:`KindGuard` keeps, per (kind, boot), the last vehicle time: an item
  at the same time is a duplicate, an earlier one is out of order; both are
  dropped and counted. An interval longer than
  ``max(gap_min_s, gap_factor * usual interval)`` is a gap (the usual
  interval is an exponential average of the intervals that were not gaps).
"""

from __future__ import annotations

from typing import Dict, List, Optional, Sequence, Tuple


class SourceSelector:
    def __init__(self, ranking: Sequence[str], fixed: Optional[str], select_s: float):
        self.ranking = list(ranking)
        self.chosen: Optional[str] = None if fixed in (None, "auto") else fixed
        self.window_us = int(select_s * 1e6)
        self._first_t: Optional[int] = None
        self._seen: set = set()
        self._held: List[Tuple[str, object]] = []
        self.dropped = 0

    def note(self, source: str, now_us: Optional[int]) -> list:
        """A message of ``source`` arrived (vehicle clock ``now_us``): may decide.

        Returns the held items released by a decision."""
        if self.chosen is not None:
            return []
        self._seen.add(source)
        if now_us is not None and self._first_t is None:
            self._first_t = now_us
        if source == self.ranking[0] or (now_us is not None and now_us - self._first_t >= self.window_us):
            return self.decide()
        return []

    def offer(self, source: str, item) -> list:
        """Items ready for the next stage (in arrival order)."""
        if self.chosen is not None:
            if source == self.chosen:
                return [item]
            self.dropped += 1
            return []
        self._seen.add(source)
        self._held.append((source, item))
        return []

    def decide(self) -> list:
        """Choose now among what was seen (window over, end of stream, reboot)."""
        if self.chosen is None:
            if not self._seen:
                return []
            rank = self.ranking
            self.chosen = min(self._seen, key=lambda s: rank.index(s) if s in rank else len(rank))
        out = [item for s, item in self._held if s == self.chosen]
        self.dropped += len(self._held) - len(out)
        self._held = []
        return out


class KindGuard:
    def __init__(self, gap_min_s: float, gap_factor: float):
        self.gap_min_us = gap_min_s * 1e6
        self.gap_factor = gap_factor
        self._last: Dict[Tuple[str, int], int] = {}
        self._avg_dt: Dict[Tuple[str, int], float] = {}

    def check(self, kind: str, boot: int, t_us: int) -> Tuple[str, float]:
        """``("ok", gap_s)`` with ``gap_s`` > 0 when a gap precedes the item,
        or ``("duplicate" | "out_of_order", 0)``."""
        key = (kind, boot)
        last = self._last.get(key)
        if last is None:
            self._last[key] = t_us
            return ("ok", 0.0)
        if t_us <= last:
            return ("duplicate" if t_us == last else "out_of_order", 0.0)
        dt = t_us - last
        self._last[key] = t_us
        avg = self._avg_dt.get(key)
        if avg is not None and dt > max(self.gap_min_us, self.gap_factor * avg):
            return ("ok", dt / 1e6)
        self._avg_dt[key] = dt if avg is None else avg + 0.1 * (dt - avg)
        return ("ok", 0.0)
