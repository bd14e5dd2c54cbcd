"""Fault hypotheses and the verdicts of the tests that weigh them.

Each source is a hypothesis: ``gnss``, ``rangefinder``, ``baro``, ``ins``
(a single fault at a time). A test is a pure function of the filters' state
and its own statistics that returns a :class:`Verdict`: pass, suspect or
fail, the hypotheses a failure implicates (the sources the tested quantity
depends on), the hypotheses a clear pass rules out (the sources it would have
seen, with power to spare), and its evidence in numbers and words.

The report has three sensor sources: ``baro`` and ``ins`` are both
``baro_ins`` there (the reference channel); the reason says which.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal, Optional

from ..fastinit import fast_frozen_init
from ..sensors import HYPOTHESES, INS, REPORT_SOURCE, SENSOR_SOURCES  # noqa: F401 (re-exported)

Level = Literal["pass", "suspect", "fail"]

NONE: frozenset = frozenset()


@dataclass(frozen=True, slots=True)
class Verdict:
    test: str
    level: Level
    implicates: frozenset  # hypotheses a failure points at
    exonerates: frozenset = NONE  # hypotheses this (clear) pass rules out
    stat: float = 0.0
    threshold: float = 0.0
    text: str = ""
    # metres: a failure's discrepancy, or the smallest fault that would have made
    # a pass fail (its threshold less its statistic); a pass rules out only
    # faults it could have seen
    scale_m: float = 0.0
    # a failure's discrepancy as each hypothesis would make it, where that
    # differs from scale_m (one velocity error is metres of position for the
    # GNSS and fewer metres of a second difference for the INS's own test)
    sizes: Optional[dict] = None

    @property
    def failed(self) -> bool:
        return self.level == "fail"

    def size_for(self, hyp: str) -> float:
        """The discrepancy this failure shows, as ``hyp`` would make it (m)."""
        if self.sizes is not None and hyp in self.sizes:
            return self.sizes[hyp]
        return self.scale_m


fast_frozen_init(Verdict)  # built per test per epoch: the cheaper __init__ of mavnav.fastinit


def live_hypotheses(excluded) -> frozenset:
    """The hypotheses still in play with these report sources excluded.
    Excluding ``baro_ins`` takes the baro out; the INS still drives every
    channel, so it stays a hypothesis. (Asked every epoch, of a handful of
    distinct sets: each answer is kept.)"""
    key = frozenset(excluded)
    live = _LIVE.get(key)
    if live is None:
        if len(_LIVE) >= _LIVE_MAX:
            _LIVE.clear()
        live = _LIVE[key] = frozenset(h for h in HYPOTHESES if h is INS or REPORT_SOURCE[h] not in key)
    return live


_LIVE: dict = {}  # frozenset(excluded) -> live_hypotheses(excluded)
_LIVE_MAX = 64  # bounded: the report sources' subsets are 16


def report_sources(hyps) -> frozenset:
    return frozenset(REPORT_SOURCE[h] for h in hyps)
