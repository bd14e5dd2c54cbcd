"""A subset without the baro is no better than its own sensor: an aux channel
that takes the baro's changes cannot vouch for the baro beyond what its sensor
reports (monitor/protection.py, ``features.own_sensor_floor``). On a real
flight (ArduCopter 3.3, baro and GNSS) whose receiver is made to report 10 m
instead of its own accuracy, the output is never nominal: two channels that
agree, one of them pinned by the baro's own rows, hold nothing at a 4 m alert
limit. With the receiver's own accuracy the flag changes nothing."""

from __future__ import annotations

import dataclasses

import pytest

from mavnav.config import config_from_dict
from mavnav.ingest import open_log
from mavnav.pipeline import run
from mavnav.samples import GnssHeight
from mavnav.sinks.base import Sink
from tests.support.paths import SHARED_FLIGHTLOGS

DKLA = SHARED_FLIGHTLOGS / "dkla_log171.bin"

pytestmark = [pytest.mark.realdata, pytest.mark.skipif(not DKLA.exists(), reason="no shared flight logs")]


class _States(Sink):
    def __init__(self):
        self.rows = []

    def epoch(self, r):
        self.rows.append((r.overall, r.vpl_m))


def _fly(samples, floor: bool):
    cfg = config_from_dict({"monitor": {"features": {"own_sensor_floor": floor}}})
    sink = _States()
    run(samples, cfg, [sink])
    return sink.rows


@pytest.fixture(scope="module")
def flight():
    return list(open_log(str(DKLA), config_from_dict({}).ingest))


def _nominal(rows):
    return sum(o == "nominal" for o, _ in rows) / len(rows)


def test_a_receiver_reporting_worse_than_the_alert_limit_vouches_for_nothing(flight):
    vague = [dataclasses.replace(s, sigma_m=10.0) if isinstance(s, GnssHeight) else s for s in flight]
    assert _nominal(_fly(vague, floor=False)) > 0.2  # without the floor its copy of the baro passes as a check
    rows = _fly(vague, floor=True)
    assert _nominal(rows) == 0.0
    limit = config_from_dict({}).monitor.alert_limit_m
    assert all(not v <= limit for o, v in rows if o != "alarm")


def test_a_receiver_within_the_alert_limit_is_unchanged(flight):
    assert _fly(flight, floor=True) == _fly(flight, floor=False)
