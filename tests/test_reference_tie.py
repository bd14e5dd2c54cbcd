"""A baro reference taken at the datum ties the baro to it: the flag on real
logs, and what it does to the channels' prior and the protection level."""

from __future__ import annotations

import math

import pytest

from mavnav.config import config_from_dict
from mavnav.ingest import open_log
from mavnav.pipeline import run
from mavnav.samples import ReferenceSet
from mavnav.sinks.base import Sink
from tests.support.paths import SHARED_FLIGHTLOGS

DKLA = SHARED_FLIGHTLOGS / "dkla_log171.bin"  # starts on the ground: the autopilot's height 0.0 m
PLEXUS = SHARED_FLIGHTLOGS / "aut_plane_plexus.ulg"  # starts with the autopilot 6.9 m below its datum
MOTOR = SHARED_FLIGHTLOGS / "frs_motor_failure_hexa.ulg"  # starts with the autopilot 2.1 m above it

pytestmark = [pytest.mark.realdata, pytest.mark.skipif(not DKLA.exists(), reason="no shared flight logs")]


def _baro_ref(path) -> ReferenceSet:
    cfg = config_from_dict({})
    for s in open_log(path, cfg.ingest):
        if type(s) is ReferenceSet and s.kind == "baro":
            return s
    raise AssertionError("no baro reference")


def test_an_onboard_log_that_starts_at_home_ties_its_baro_reference():
    assert _baro_ref(DKLA).at_datum is True
    assert _baro_ref(PLEXUS).at_datum is False
    assert _baro_ref(MOTOR).at_datum is False


class _Sigmas(Sink):
    def __init__(self):
        self.first = None
        self.vpl = []
        self.alarmed = False

    def epoch(self, r):
        if self.first is None:
            self.first = {c.name: c.sigma_height_m for c in r.channels}
        if not self.alarmed:  # up to the flight's first sensor alarm (after one, the datum is lost honestly)
            self.vpl.append(r.vpl_m)

    def alarm(self, e):
        self.alarmed = self.alarmed or (e.state == "alarm" and e.source != "input")


def _run(path, filter_=None, **monitor):
    cfg = config_from_dict({"monitor": monitor, "filter": filter_ or {}})
    sink = _Sigmas()
    run(open_log(path, cfg.ingest), cfg, [sink])
    return sink, cfg


@pytest.mark.slow
def test_the_tie_sets_the_start_prior_in_adaptive_mode_only():
    tied, cfg = _run(DKLA)
    # the baro channel's height at start: the tie's sigma and the baro's own noise, not the 2 m prior
    tie = math.sqrt(cfg.filter.p0.baro_bias_at_datum_m2)
    assert tie < tied.first["baro"] < math.sqrt(cfg.filter.p0.baro_bias_m2)
    paper, _ = _run(DKLA, mode="paper")
    assert paper.first["baro"] > 2 * tied.first["baro"]  # paper mode keeps the paper's P0
    # tied at the datum, the fault-free protection level (k sigma: what the tie sets) is within the alert
    # limit until the flight's first alarm; with the in-flight prior it is not. (The separation terms are
    # set aside: dkla's first 34 s have the baro alone, which no subset can check.)
    def within(s):
        return sum(v <= cfg.monitor.alert_limit_m for v in s.vpl) / len(s.vpl)

    fault_free = {"features": {"separation_protection": False}}
    tied_ff, _ = _run(DKLA, **fault_free)
    untied, _ = _run(DKLA, filter_={"p0": {"baro_bias_at_datum_m2": cfg.filter.p0.baro_bias_m2}}, **fault_free)
    assert within(tied_ff) > 0.9 and within(untied) < 0.1
