"""bench/realflights.py: the rangefinder faults of the real-flight scorecard.

Issue 11, part 2: "rangefinder stuck" and "rangefinder reading zero" go
into every flight whose IMU, baro and usable rangefinder readings come at
5 Hz or more, and the report says so when no flight has one. Checked on a
simulated PX4 flight with a 20 Hz (and a 3 Hz) rangefinder, and on the
committed ArduCopter SITL log whose rangefinder logs 20 Hz of readings, all
flagged invalid.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from bench import realflights as rf
from mavnav.sim import scenario_from_dict, simulate
from mavnav.sim.faults import parse_fault
from tests.support.paths import SHARED_FLIGHTLOGS

pytestmark = [pytest.mark.realdata, pytest.mark.slow]

SITL_BIN = SHARED_FLIGHTLOGS / "SITL_wlichon_baseline_00000001.BIN"
RNG_FAULTS = tuple(f for f in rf.FAULTS if f[2] == "rangefinder")


def test_every_fault_parses_with_its_window():
    for name, spec, _source in rf.FAULTS:
        f = parse_fault(rf._fault_text(spec, 12.5, 20.0))
        assert (f.kind, f.onset_s, f.duration_s) == (spec.split(":")[0], 12.5, 20.0), name
    assert parse_fault(rf._fault_text(dict((n, s) for n, s, _ in rf.FAULTS)["rng_zero"], 1, 2)).magnitude == 0.0
    assert parse_fault(rf._fault_text(dict((n, s) for n, s, _ in rf.FAULTS)["rng_stuck"], 1, 2)).magnitude is None


def _hover_log(tmp_path: Path, rng_hz: float) -> Path:
    scn = scenario_from_dict({
        "name": f"hover_rng_{rng_hz:g}", "duration_s": 45.0, "seed": 11, "profile": "px4",
        "rates_hz": {"HIGHRES_IMU": 100, "ATTITUDE": 50, "SCALED_PRESSURE": 25, "GPS_RAW_INT": 10,
                     "DISTANCE_SENSOR": rng_hz},
        "trajectory": {"kind": "hover", "height_m": 8.0, "takeoff": False, "wander_m": 0.3},
        "sensors": {"rangefinder": {"sigma_m": 0.05, "min_m": 0.2, "max_m": 40}},
    })
    p = tmp_path / f"hover_rng_{rng_hz:g}.tlog"
    p.write_bytes(simulate(scn).tlog)
    return p


def _rates(path: Path) -> dict:
    return rf.audit_file(path, rf._cfg("adaptive"))["inputs"]["rates_hz"]


def test_rangefinder_faults_run_where_the_rangefinder_is_fast(tmp_path):
    p = _hover_log(tmp_path, 20)
    rates = _rates(p)
    assert rates["rangefinder"] >= rf.MIN_RATE_HZ
    rows, skipped = rf._part2(str(p), rates, faults=RNG_FAULTS, contenders=("adaptive",))
    assert skipped == []
    assert sorted((r["fault"], r["onset_s"]) for r in rows) == sorted(
        (name, on) for name, _, _ in RNG_FAULTS for on in (11.25, 22.5, 33.75))
    for r in rows:
        assert r["samples_changed"] > 0, r  # the fault reached the rangefinder's samples
        assert {"detected", "tta_s", "wrong", "hazard_s"} <= set(r["adaptive"])


def test_no_rangefinder_faults_below_5_hz(tmp_path):
    p = _hover_log(tmp_path, 3)
    rates = _rates(p)
    assert 0 < rates["rangefinder"] < rf.MIN_RATE_HZ
    rows, skipped = rf._part2(str(p), rates, faults=RNG_FAULTS, contenders=("adaptive",))
    assert rows == [] and skipped == []


def test_report_says_no_flight_has_a_fast_rangefinder():
    if not SITL_BIN.is_file():
        pytest.skip(f"committed flight log {SITL_BIN} not present")
    r = rf.flight_job({"path": str(SITL_BIN), "sitl": True, "faults": True})
    rng = r["audit"]["rangefinder"]
    assert rng["readings_hz"] > 15 and rng["used"] == 0 and rng["refused"] == {"invalid_status": rng["readings"]}
    assert r["fast"] and not r["rng_faults"]
    assert {x["fault"] for x in r["faults"]} == {n for n, _, s in rf.FAULTS if s != "rangefinder"}

    class Args:
        no_faults = False

    text = rf.report({"shared/flightlogs": [SITL_BIN]}, [r], 1.0, Args())
    for name, _, _ in RNG_FAULTS:
        assert f"| {name} | 0 | no flight with a rangefinder at ≥5 Hz | - | - |" in text
    assert ("* SITL_wlichon_baseline_00000001.BIN: 20.0 Hz of readings, 0.0 Hz usable (invalid_status "
            f"{rng['readings']} refused)") in text
    assert "not faulted: usable readings below 5 Hz" in text


def _trace(t, h, overall):
    import numpy as np
    return {"t": np.asarray(t, float), "h": np.asarray(h, float), "overall": np.asarray(overall)}


@pytest.mark.parametrize("left,state,hazard", [(4.0, "nominal", True), (4.0, "unavailable", False),
                                               (0.2, "nominal", False)])
def test_what_a_fault_leaves_after_it_ended(left, state, hazard):
    """A fault from 10 to 30 s: the output is 6 m off inside it, then `left`
    metres off to the end of the flight, in `state`. Hazard inside the window
    is the fault's; hazard after it is what it left while offered as usable;
    the offset left is measured in any state (a user still sees that height)."""
    import numpy as np
    t = np.arange(0.0, 100.0, 0.1)
    clean = _trace(t, np.sin(t), ["nominal"] * t.size)
    h = np.sin(t) + np.where((t >= 10) & (t <= 30), 6.0, np.where(t > 30, left, 0.0))
    st = np.where((t >= 10) & (t <= 32), "alarm", state)
    r = _trace(t, h, st)
    assert rf._hazard_s(r, clean, 10.0, 32.0) == 0.0  # in alarm through the window
    assert (rf._hazard_s(r, clean, 32.0, 100.0) > 60.0) == hazard
    assert rf._left_m(r, clean, 30.0) == pytest.approx(left, abs=1e-6)
    assert "| baro_step |" in rf.after_lines([{"fault": "baro_step", **{m: {"hazard_after_s": 1.0, "left_m": left}
                                                                          for m in rf.CONTENDERS}}])
