"""One pipeline for live and replay: a failing sink is reported once, dropped,
and changes nothing in the monitor's result; the fold is deterministic."""

from __future__ import annotations

import pytest

from mavnav.config import load_config
from mavnav.ingest import TlogSource
from mavnav.pipeline import run
from mavnav.sinks.base import Sink

from tests.support.paths import SITL_LOGS as LOGS


class Recorder(Sink):
    name = "recorder"

    def __init__(self):
        self.rows = []

    def epoch(self, r):
        self.rows.append((r.t_us, r.height_fused_m, r.overall))


class Exploding(Sink):
    name = "exploding"

    def __init__(self, after):
        self.after, self.n, self.closed = after, 0, 0

    def epoch(self, r):
        self.n += 1
        if self.n > self.after:
            raise ConnectionResetError("viewer went away")

    def close(self, summary):
        self.closed += 1


def _run(path, sinks):
    cfg = load_config(None)
    return run(TlogSource(path, cfg.ingest), cfg, sinks)


@pytest.mark.slow
def test_failing_sink_is_dropped_and_changes_nothing():
    path = LOGS / "px4_hover_gnss_step.tlog"
    a, b = Recorder(), Recorder()
    boom = Exploding(after=100)
    s1 = _run(path, [a])
    s2 = _run(path, [boom, b])
    assert a.rows == b.rows and len(a.rows) > 1000
    assert [(e.t_us, e.source, e.state) for e in s1.alarms] == [(e.t_us, e.source, e.state) for e in s2.alarms]
    assert "exploding" in s2.sink_failures and "viewer went away" in s2.sink_failures["exploding"]
    assert boom.n == 101 and boom.closed == 1  # called until it failed, then closed once, never again


def test_reboot_restarts_the_pipeline_cleanly():
    s = _run(LOGS / "ardupilot_input_faults.tlog", [])
    assert s.reboots == 1
    assert s.epochs > 500
