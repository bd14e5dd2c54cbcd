"""With the baro the only height sensor beside the INS, monitoring is degraded
(a slow baro error passes every test against the INS), and says so."""

from __future__ import annotations

import pytest

from mavnav.config import config_from_dict
from mavnav.ingest import open_log
from mavnav.pipeline import run
from mavnav.sinks.base import Sink
from tests.support.paths import SHARED_FLIGHTLOGS

QUAD = SHARED_FLIGHTLOGS / "aut_quadrotor_local.ulg"  # PX4 1.16, baro and IMU at 5 / 219 Hz, no GNSS fix
DKLA = SHARED_FLIGHTLOGS / "dkla_log171.bin"  # ArduCopter 3.3, baro and GNSS

pytestmark = [pytest.mark.realdata, pytest.mark.skipif(not QUAD.exists(), reason="no shared flight logs")]


class _Overall(Sink):
    def __init__(self):
        self.states = []
        self.reasons = set()
        self.alone_with_gnss = 0  # epochs said to have the baro alone while the GNSS is in use

    def epoch(self, r):
        self.states.append(r.overall)
        self.reasons.add(r.sources["input"].reason)
        if "baro and the INS alone" in r.sources["input"].reason and r.sources["gnss"].state in ("nominal", "caution"):
            self.alone_with_gnss += 1


def _fly(path, **monitor):
    cfg = config_from_dict({"monitor": monitor})
    sink = _Overall()
    run(open_log(str(path), cfg.ingest), cfg, [sink])
    return sink


def _share(states, state):
    return sum(s == state for s in states) / len(states)


def test_the_baro_alone_makes_monitoring_degraded_and_says_why():
    alone = _fly(QUAD)
    assert _share(alone.states, "nominal") == 0.0
    assert any("baro and the INS alone" in r for r in alone.reasons)
    # the rule and nothing else: at one sensor, and without the protection
    # level that bounds a fault nothing else can see, the same flight is nominal
    alone_allowed = _fly(QUAD, min_height_sensors=1, features={"separation_protection": False})
    assert _share(alone_allowed.states, "nominal") > 0.9
    # and that protection level says the same by itself: one height sensor has no subset to check it
    assert _share(_fly(QUAD, min_height_sensors=1).states, "nominal") == 0.0
    # paper mode stays the paper's
    assert not any("INS alone" in r for r in _fly(QUAD, mode="paper").reasons)


@pytest.mark.slow
def test_with_the_gnss_beside_the_baro_monitoring_is_not_degraded_by_it():
    """dkla has no GNSS fix for its first 34 s: the rule applies there and
    nowhere else (the input is judged once a second, so an epoch or two may
    lag the GNSS's arrival)."""
    both = _fly(DKLA)
    assert any("baro and the INS alone" in r for r in both.reasons)  # before the first fix
    assert both.alone_with_gnss <= 0.01 * len(both.states)
    assert _share(both.states, "nominal") > 0.1
