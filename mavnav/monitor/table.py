"""The decision table: verdicts in, one situation and the state of every sensor
source out.

Candidates are the hypotheses that explain every failed test (the
intersection of what the failures implicate) less those a clear pass rules
out; a pass rules out only faults as large as the largest discrepancy the
failures show (the fault that would have made it fail, its threshold less
its statistic in metres, is at most that size). Precedence, highest first, is the order of :data:`TABLE`:

1. ``isolated``: the candidates are one report source. It goes to alarm and
   is excluded; the others stay as their own evidence says.
2. ``ambiguous``: two or more sources could explain the failures. Each is in
   caution and none of them enters the output; with nothing cleared left the
   output is unavailable (never a height the evidence does not clear).
3. ``inconsistent``: failures that no single fault explains (two faults, or a
   model that does not fit this flight). Every implicated source is in
   caution, out of the output.
4. ``suspect``: no failure yet, a test past its caution level. The sources it
   implicates are in caution and stay in the output (a caution is a watch,
   not an exclusion).
5. ``clear``: every source nominal.

Sources without data are ``unavailable`` whatever the table says, and an
excluded source stays in alarm until its readmission test (in the logic)
clears it: those two overrides come before the table.
"""

from __future__ import annotations

from dataclasses import dataclass

from ..fastinit import fast_frozen_init
from .verdict import HYPOTHESES, Verdict, report_sources

# situation -> (state of the candidate sources, whether they enter the output, action)
TABLE = {
    "isolated": ("alarm", False, "exclude"),
    "ambiguous": ("caution", False, "hold"),
    "inconsistent": ("caution", False, "hold"),
    "suspect": ("caution", True, "watch"),
    "clear": ("nominal", True, "none"),
}


@dataclass(frozen=True, slots=True)
class Judgement:
    situation: str
    candidates: frozenset  # hypotheses
    sources: frozenset  # report sources the situation applies to
    reason: str

    @property
    def state(self) -> str:
        return TABLE[self.situation][0]

    @property
    def enters_output(self) -> bool:
        return TABLE[self.situation][1]

    @property
    def action(self) -> str:
        return TABLE[self.situation][2]


fast_frozen_init(Judgement)  # one (at least) per epoch

# the situation of most epochs, one object (a Judgement is frozen)
_CLEAR = Judgement("clear", frozenset(), frozenset(), "consistent")


def _why(vs) -> str:
    return "; ".join(v.text for v in vs if v.text)


def _cleared(passes: list[Verdict], failed: list[Verdict]) -> frozenset:
    """The hypotheses the passes rule out: each only against the largest
    discrepancy the failures show as that hypothesis would make it."""
    if not failed:
        return frozenset().union(*(v.exonerates for v in passes))
    size_m = {h: max(f.size_for(h) for f in failed) for v in passes for h in v.exonerates}
    return frozenset(h for v in passes for h in v.exonerates if v.scale_m <= size_m[h])


def judge(verdicts: list[Verdict], live: frozenset = frozenset(HYPOTHESES)) -> Judgement:
    """The situation the verdicts describe. ``live``: hypotheses still in play
    (an excluded source cannot be the cause of a new failure)."""
    failed, passes, suspects = [], [], []
    for v in verdicts:  # one pass, in order
        level = v.level
        if level == "pass":
            passes.append(v)
        elif level == "fail":
            failed.append(v)
        elif level == "suspect":
            suspects.append(v)
    if not failed and not suspects:
        return _CLEAR  # (what the passes rule out matters only beside a failure or a suspicion)
    # a pass rules a hypothesis out only if it would have seen a fault as large
    # as the largest discrepancy the failures show, as that hypothesis would make it
    cleared = _cleared(passes, failed)
    if failed:
        cand = frozenset(live)
        for v in failed:
            cand &= v.implicates
        cand -= cleared
        src = report_sources(cand)
        if len(src) == 1:
            return Judgement("isolated", cand, src, _why(failed))
        if src:
            return Judgement("ambiguous", cand, src, "cannot isolate: " + _why(failed))
        implicated = frozenset().union(*(v.implicates for v in failed)) & live
        return Judgement("inconsistent", frozenset(), report_sources(implicated),
                         "no single source explains it: " + _why(failed))
    if suspects:
        implicated = frozenset().union(*(v.implicates for v in suspects)) & live
        cand = implicated - cleared
        return Judgement("suspect", cand, report_sources(cand), _why(suspects))
    return _CLEAR
