"""A rangefinder's maximum is a slant range: tilted, the vehicle reaches it
below that height.

The envelope test calls a reading refused at the maximum a failure while the
baro+INS channel puts the vehicle well inside the range. It compared the
vertical height with the maximum: on a simulated descent from above the
rangefinder's 40 m (truth model, seed 8 of 12) the readings at 40.01 m came
with the vehicle 36.6 m up by baro+INS and tilted, and the healthy
rangefinder was excluded. The refusal now carries the tilt's cosine."""

from __future__ import annotations

import math

import pytest

from bench import integrity as I
from mavnav.ingest import TlogSource
from mavnav.monitor import hypotheses
from mavnav.samples import Rejected
from tests.support.tlog_writer import TlogWriter


def test_a_refused_reading_at_the_maximum_carries_its_tilt(tmp_path):
    path = tmp_path / "tilt.tlog"
    roll = math.radians(25.0)
    with TlogWriter(path) as w:
        recv = 1.7e9
        for k in range(30):
            t_ms = 1000 + 100 * k
            if k % 10 == 0:
                w.write(w.mav.heartbeat_encode(2, 3, 0, 0, 4, 3), recv)
            w.write(w.mav.attitude_encode(t_ms, roll, 0.0, 0.0, 0.0, 0.0, 0.0), recv)
            # 40.01 m against a 40 m maximum, and a reading in range
            cm = 4001 if k % 2 else 3000
            w.write(w.mav.distance_sensor_encode(t_ms + 5, 20, 4000, cm, 10, 0, 25, 0), recv + 0.005)
            recv += 0.1
    events = list(TlogSource(str(path)))
    refused = [e for e in events if isinstance(e, Rejected) and e.kind == "out_of_range"]
    assert len(refused) >= 10
    assert all(e.cos_tilt == pytest.approx(math.cos(roll), abs=1e-6) for e in refused)


@pytest.mark.slow
def test_a_tilted_descent_into_range_excludes_nothing(monkeypatch):
    spec = {"family": "descent_above_max", "seed": 8, "contenders": ["adaptive"], "baseline_fail_s": 5.0,
            "sensor_model": "truth"}
    s = I.job(dict(spec)).scores["adaptive"]
    assert not s["wrong_exclusions"] and s["false_alarms"] == 0
    untilted = hypotheses.HypothesisLogic.on_range_refused

    def vertical(self, s):  # the refusal without its tilt: the maximum compared with the vertical height
        untilted(self, Rejected(s.recv_s, s.kind, s.detail, s.t_us, s.boot, s.sensor, s.value_m, s.min_m, s.max_m))

    monkeypatch.setattr(hypotheses.HypothesisLogic, "on_range_refused", vertical)
    s = I.job(dict(spec)).scores["adaptive"]
    assert "rangefinder" in s["wrong_exclusions"]
