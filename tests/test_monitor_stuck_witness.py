"""A rangefinder refused as stuck is evidence only while the baro, the
ingest's witness that the vehicle moved, is in use.

The ingest calls a reading stuck when it holds while the baro moves. On the
ArduPilot SITL rangefinder flight (a hover whose rangefinder repeats its
centimetres) with a 5-sigma baro step injected for 10 s, the step's return
while the baro was out for it read as the vehicle moving under a frozen
rangefinder: the healthy rangefinder was excluded 14 s after the step's
onset (bench/integrity.py, real_baro_step5 seed 3 of 12)."""

from __future__ import annotations

import pytest

from bench import integrity as I
from mavnav.monitor import hypotheses

pytestmark = [pytest.mark.realdata, pytest.mark.slow]

SPEC = {"family": "real_baro_step5", "seed": 3, "contenders": ["adaptive"], "baseline_fail_s": 5.0,
        "sensor_model": "shipped"}


@pytest.fixture(autouse=True)
def _needs_the_sitl_log():
    if not I.REAL_LOG.exists():
        pytest.skip("no shared SITL telemetry")


def test_the_baro_step_is_alarmed_and_nothing_else_excluded():
    s = I.job(dict(SPEC)).scores["adaptive"]
    assert s["detected"] and s["isolated"]
    assert not s["wrong_exclusions"]


def test_counting_stuck_readings_while_the_baro_is_out_excludes_the_rangefinder(monkeypatch):
    def old(self, s):
        if s.kind in hypotheses.REFUSAL_KINDS:
            self.refused.append((s.t_us, s.kind, s.value_m, s.min_m, s.max_m, s.cos_tilt))

    monkeypatch.setattr(hypotheses.HypothesisLogic, "on_range_refused", old)
    s = I.job(dict(SPEC)).scores["adaptive"]
    assert "rangefinder" in s["wrong_exclusions"]
