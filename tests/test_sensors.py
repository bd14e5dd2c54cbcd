"""The sensor vocabulary (mavnav.sensors): one enum whose members are their words."""

from __future__ import annotations

import csv
import io
import json

import pytest

from mavnav import sensors
from mavnav.report import CHANNEL_NAMES, PAIR_NAMES, SOURCES
from mavnav.sensors import BARO, BARO_INS, GNSS, INPUT, INS, RANGEFINDER, Sensor


def test_a_member_is_its_word_everywhere():
    for s in Sensor:
        assert s == s.value and hash(s) == hash(s.value)
        assert str(s) == s.value and f"{s}" == s.value and "%s" % s == s.value
        assert f"{s:>12}" == f"{s.value:>12}"
        assert repr(s) == repr(s.value)
        assert {s.value: 1}[s] == 1 and {s: 1}[s.value] == 1
    assert json.dumps({GNSS: [BARO_INS, INPUT]}) == '{"gnss": ["baro_ins", "input"]}'
    out = io.StringIO()
    csv.writer(out).writerow([RANGEFINDER, 1])
    assert out.getvalue() == "rangefinder,1\r\n"


def test_the_groups_reports_use():
    assert CHANNEL_NAMES == ("gnss", "rangefinder", "baro")
    assert SOURCES == ("gnss", "rangefinder", "baro_ins", "input")
    assert sensors.HYPOTHESES == ("gnss", "rangefinder", "baro", "ins")
    assert sensors.SENSOR_SOURCES == SOURCES[:3]
    assert {h: sensors.REPORT_SOURCE[h] for h in sensors.HYPOTHESES} == {
        "gnss": "gnss", "rangefinder": "rangefinder", "baro": "baro_ins", "ins": "baro_ins"}
    assert sensors.INPUTS == ("imu", "baro", "gnss", "rangefinder")
    assert PAIR_NAMES == ("gnss-rng", "gnss-baro", "rng-baro")


def test_the_other_spellings_are_declared_once():
    assert [c.short for c in CHANNEL_NAMES] == ["gnss", "rng", "baro"]
    assert BARO_INS.short == "baro"
    assert RANGEFINDER.stream == "range" and sensors.RANGE_STREAM == "range"
    streams = (sensors.IMU_STREAM, sensors.BARO_STREAM, sensors.GNSS_STREAM, sensors.RANGE_STREAM,
               sensors.AUTOPILOT_STREAM)
    assert streams == ("imu", "baro", "gnss", "range", "autopilot")
    assert all(type(s) is str for s in streams)  # the normaliser's per-sample path keys plain strings
    assert [s.word for s in SOURCES] == ["GNSS", "rangefinder", "baro+INS", "telemetry"]
    assert INS.word == "ins" and BARO.word == "baro"


def test_old_spellings_parse():
    assert Sensor("rng") is RANGEFINDER and Sensor("range") is RANGEFINDER
    assert Sensor("baro+INS") is BARO_INS and Sensor("gnss") is GNSS
    with pytest.raises(ValueError, match="not a valid Sensor"):
        Sensor("sonar")
