"""The scorecards' measure of an output away from every raw height (bench/scoremetrics.py ``departure``,
read by bench/output_departure.py and bench/realflights.py)."""

from __future__ import annotations

import math

import pytest

from bench.scoremetrics import departure

NAN = math.nan


def test_time_away_from_every_height_is_counted_by_state_and_nothing_else():
    t = [0.0, 1.0, 2.0, 3.0, 4.0, 5.0]
    fused = [0.0, 5.0, 5.0, 5.0, NAN, 5.0]
    baro = [0.1, 0.2, 4.5, 0.0, 0.0, NAN]   # epoch 2: the baro is within the margin
    gnss = [NAN, 0.0, 0.0, 0.0, 0.0, NAN]
    ap = [0.0, 0.1, 0.0, 0.0, 0.0, NAN]     # epoch 5: no other height at all
    states = ["nominal", "caution", "nominal", "alarm", "nominal", "nominal"]
    secs, worst, at = departure(t, fused, [baro, gnss, ap], states, 2.0)
    # epoch 1 (caution, 4.8 m from the nearest) and epoch 3 (alarm, 5 m), one second each
    assert secs == {"nominal": 0.0, "caution": 1.0, "unavailable": 0.0, "alarm": 1.0}
    assert worst == pytest.approx(5.0) and at == 3.0


def test_an_output_between_two_sensors_within_the_margin_is_not_away():
    t = [0.0, 1.0, 2.0]
    secs, worst, _ = departure(t, [1.5, 1.5, 1.5], [[0.0] * 3, [3.0] * 3], ["nominal"] * 3, 2.0)
    assert sum(secs.values()) == 0.0 and worst == pytest.approx(1.5)
