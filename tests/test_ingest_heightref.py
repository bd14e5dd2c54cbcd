"""The reference stage on its own (mavnav/ingest/heightref.py): what each entry point releases."""

from __future__ import annotations

import pytest

from mavnav.atmosphere import pressure_at_height_pa
from mavnav.config import IngestConfig
from mavnav.ingest.clock import VehicleClock
from mavnav.ingest.heightref import GNSS_FIXED, BaroItem, GnssItem, HeightReferences
from mavnav.samples import BaroHeight, GnssHeight, Notice, ReferenceMoved, ReferenceSet

P0 = 100_000.0


def refs(**ingest) -> HeightReferences:
    clock = VehicleClock(2.0)
    clock.accept(1_000_000, 10.0)
    return HeightReferences(IngestConfig(**ingest), clock, lambda: 10.0)


def test_a_configured_reference_releases_at_once():
    r = refs(baro_reference={"source": "config", "value": P0})
    out = r.pressure(BaroItem(1_000_000, 10.0, 0, pressure_at_height_pa(3.0, P0)))
    assert [type(x) for x in out] == [ReferenceSet, BaroHeight]
    assert out[0].kind == "baro" and out[0].origin == "config" and out[0].value == P0
    assert out[1].height_ref_m == pytest.approx(3.0, abs=1e-6)
    assert [type(x) for x in r.pressure(BaroItem(1_100_000, 10.1, 0, P0))] == [BaroHeight]  # no second event


def test_gnss_waits_for_the_home_then_goes_out_above_it():
    r = refs()
    held = [GnssItem(1_000_000 + k * 200_000, 10.0 + k * 0.2, 0, 105.0 + k, 0.5, 3, 12) for k in range(3)]
    for it in held:
        assert r.gnss_altitude(it) == []
    out = r.home_position(100.0)
    assert [type(x) for x in out[:-1]] == [ReferenceSet, GnssHeight, GnssHeight, GnssHeight]
    assert out[-1] is GNSS_FIXED  # after its samples: the autopilot's heights held for it may go
    assert out[0].origin == "home" and out[0].value == 100.0 and out[0].alt_ref_msl_m == 100.0
    assert [g.height_ref_m for g in out[1:-1]] == [5.0, 6.0, 7.0]
    assert r.gnss_ref_msl_m() == 100.0


def test_a_home_that_moves_is_said_once():
    r = refs()
    r.home_position(100.0)
    [moved] = r.home_position(103.0)
    assert type(moved) is ReferenceMoved and moved.shift_m == pytest.approx(3.0) and moved.offset_m == pytest.approx(3.0)
    assert r.home_position(103.0) == []  # the same home again
    assert r.home_position(103.01) == []  # within home_move_min_m


def test_waiting_for_the_home_is_said_after_a_second():
    r = refs()
    said = []
    for k in range(12):
        said += r.pressure(BaroItem(1_000_000 + k * 100_000, 10.0 + k * 0.1, 0, P0))
    assert [type(x) for x in said] == [Notice] and "baro height reference" in said[0].text


def test_the_baro_reference_from_the_autopilots_height_above_home():
    # the vehicle 10 m above home: the pressure at home is the measured one moved down 10 m
    r = refs()
    p_home = 101_000.0
    p_at_10 = pressure_at_height_pa(10.0, p_home)
    for k in range(15):
        t = 1_000_000 + k * 100_000
        rel, out = r.autopilot_home(t, 110.0, 100.0, 10.0, 0.0)
        assert rel == 10.0 and all(type(x) is not BaroHeight for x in out)
        out = r.pressure(BaroItem(t, 10.0 + k * 0.1, 0, p_at_10))
        if out:
            break
    sets = [x for x in out if type(x) is ReferenceSet]
    assert sets and sets[0].origin == "autopilot_home" and sets[0].value == pytest.approx(p_home, rel=1e-9)
    assert all(b.height_ref_m == pytest.approx(10.0, abs=1e-6) for b in out if type(b) is BaroHeight)


def _baro_reference_above_home(rel_m: float, **ingest) -> ReferenceSet:
    r = refs(**ingest)
    p_home = 101_000.0
    p_meas = pressure_at_height_pa(rel_m, p_home)
    for k in range(15):
        t = 1_000_000 + k * 100_000
        r.autopilot_home(t, 100.0 + rel_m, 100.0, rel_m, 0.0)
        sets = [x for x in r.pressure(BaroItem(t, 10.0 + k * 0.1, 0, p_meas)) if type(x) is ReferenceSet]
        if sets:
            return sets[0]
    raise AssertionError("no baro reference released")


def test_a_baro_reference_taken_on_the_ground_at_home_is_at_the_datum():
    assert _baro_reference_above_home(0.3).at_datum is True
    # in flight the tie is only as good as the autopilot's height then
    assert _baro_reference_above_home(10.0).at_datum is False
    # the threshold is the configured one
    assert _baro_reference_above_home(0.3, baro_reference={"at_datum_max_m": 0.1}).at_datum is False


def test_a_startup_or_configured_baro_reference_is_not_at_the_datum():
    r = refs(baro_reference={"source": "config", "value": P0})
    [ref] = [x for x in r.pressure(BaroItem(1_000_000, 10.0, 0, P0)) if type(x) is ReferenceSet]
    assert ref.at_datum is False
    r = refs(baro_reference={"source": "startup"})
    out = []
    for k in range(40):
        out += r.pressure(BaroItem(1_000_000 + k * 100_000, 10.0 + k * 0.1, 0, P0))
    [ref] = [x for x in out if type(x) is ReferenceSet]
    assert ref.origin == "startup" and ref.at_datum is False  # a tlog may start in flight
