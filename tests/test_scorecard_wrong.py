"""bench/realflights.py: a wrong exclusion the unfaulted flight raises too is
the flight's own alarm, not the fault's."""

from __future__ import annotations

from types import SimpleNamespace as Ev

import pytest

from bench import realflights as rf

pytestmark = [pytest.mark.unit]


def test_only_the_alarms_the_unfaulted_flight_does_not_raise_are_the_faults():
    onsets = [Ev(source="baro_ins", t_s=101.0), Ev(source="gnss", t_s=105.0), Ev(source="baro_ins", t_s=140.0)]
    clean = [("baro_ins", 100.0)]  # the flight raises this one by itself, 1 s earlier
    assert rf.wrong_by_fault(onsets, clean, ["baro_ins", "gnss"], 100.0, 120.0) == ["gnss"]
    # the same source again later in the window, away from the flight's own: the fault's
    onsets.append(Ev(source="baro_ins", t_s=110.0))
    assert rf.wrong_by_fault(onsets, clean, ["baro_ins", "gnss"], 100.0, 120.0) == ["baro_ins", "gnss"]
    # outside the window (end + 2 s) counts for neither; a source not wrongly blamed is not listed
    assert rf.wrong_by_fault(onsets, [], ["baro_ins"], 100.0, 107.0) == ["baro_ins"]
    assert rf.wrong_by_fault(onsets, [], [], 100.0, 120.0) == []
    assert rf.wrong_by_fault([Ev(source="gnss", t_s=100.0 + rf.SAME_ALARM_S + 0.1)], [("gnss", 100.0)],
                             ["gnss"], 99.0, 120.0) == ["gnss"]
