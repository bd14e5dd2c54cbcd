"""The rangefinder's checks on their own (mavnav.ingest.rangecheck)."""

from __future__ import annotations

import math

from mavnav.atmosphere import P0_PA, pressure_at_height_pa
from mavnav.config import IngestConfig
from mavnav.ingest.rangecheck import CrossCheck, RangeChecks, RangeReading, Refusal, StuckCheck, decode_reading


def _ds(cm, quality=100, lo=20, hi=4000):
    return {"current_distance": cm, "min_distance": lo, "max_distance": hi, "signal_quality": quality}


def test_decode_reading():
    assert decode_reading("DISTANCE_SENSOR", _ds(1234), 0.1, 30.0) == RangeReading("DISTANCE_SENSOR", 1234, 12.34, 0.2, 40.0)
    assert decode_reading("DISTANCE_SENSOR", _ds(1234, hi=0), 0.1, 30.0).hi_m == 30.0  # 0: unknown, the configured one
    assert decode_reading("DISTANCE_SENSOR", _ds(1234, quality=1), 0.1, 30.0).kind == "invalid_quality"
    r = decode_reading("DISTANCE_SENSOR", _ds(5000), 0.1, 30.0)
    assert (r.kind, r.value_m, r.min_m, r.max_m) == ("out_of_range", 50.0, 0.2, 40.0)
    assert decode_reading("RANGEFINDER", {"distance": 3.5}, 0.1, 30.0) == RangeReading("RANGEFINDER", 3.5, 3.5, 0.1, 30.0)
    assert decode_reading("RANGEFINDER", {"distance": math.nan}, 0.1, 30.0).kind == "nan"
    r = decode_reading("RANGEFINDER", {"distance": -1.0}, 0.1, 30.0)
    assert r.kind == "impossible" and math.isnan(r.value_m)


def test_cross_check_compares_with_the_other_message_when_recent():
    c = CrossCheck(max_age_s=0.3, tol_m=0.1, tol_frac=0.05)
    r = RangeReading("DISTANCE_SENSOR", 1000, 10.0, 0.2, 40.0)
    assert c.check(r, 100.0) is None  # nothing to compare with
    c.note("RANGEFINDER", {"distance": 10.4}, 100.0)
    assert c.check(r, 100.1) is None  # within 5 % of 10.4
    c.note("RANGEFINDER", {"distance": 11.0}, 100.0)
    got = c.check(r, 100.1)
    assert isinstance(got, Refusal) and got.kind == "disagrees" and got.value_m == 10.0
    assert c.check(r, 100.5) is None  # the other's reading is too old
    c.note("RANGEFINDER", {"distance": math.nan}, 100.5)  # not a reading: the latest stays
    assert c.latest["RANGEFINDER"].range_m == 11.0


def test_stuck_needs_the_time_and_the_baro_moving():
    s = StuckCheck(stuck_s=2.0, min_move_m=1.0)
    p0 = pressure_at_height_pa(0.0, P0_PA)
    s.pressure(p0)
    assert not s.stuck(500, 0, 0)
    s.pressure(pressure_at_height_pa(3.0, P0_PA))
    assert not s.stuck(500, 1_000_000, 0)  # not long enough yet
    assert s.stuck(500, 2_000_000, 0)
    assert not s.stuck(501, 2_100_000, 0)  # a new value: a new run
    s.reset()
    assert s.run is None
    s2 = StuckCheck(stuck_s=2.0, min_move_m=1.0)
    s2.pressure(p0)
    assert not s2.stuck(500, 0, 0)
    s2.pressure(p0)
    assert not s2.stuck(500, 5_000_000, 0)  # a steady hover: the baro did not move


def test_the_checks_in_order():
    checks = RangeChecks(IngestConfig())
    assert checks.check("DISTANCE_SENSOR", _ds(1000), 1.0, 0, 0).range_m == 10.0
    assert checks.check("DISTANCE_SENSOR", _ds(1000, quality=1), 1.1, 100_000, 0).kind == "invalid_quality"
