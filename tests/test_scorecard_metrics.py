"""Scorecard metrics on hand-checked cases, and the autopilot baseline end to end."""

from __future__ import annotations

import math
import tempfile
from pathlib import Path

import numpy as np
import pytest

from bench import scoremetrics as sm
from bench.autopilot_baseline import BaselineConfig, run_baseline
from mavnav.config import config_from_dict
from mavnav.ingest import TlogSource
from mavnav.report import AlarmEvent
from mavnav.sim import scenario_from_dict, simulate


def ev(t_s, source, state, previous):
    return AlarmEvent(t_us=int(round(t_s * 1e6)), boot=0, source=source, state=state, previous=previous, reason="")


# A fault on the GNSS from 10 s to 20 s. The events, in order:
#   2.0  gnss nominal->caution        not an alarm
#   5.0  rangefinder nominal->alarm   alarm before the onset: a false alarm
#   6.0  rangefinder alarm->nominal
#  10.4  gnss caution->alarm          first alarm in [10, 20]: TTA 0.4 s, source gnss: isolated
#  10.9  gnss alarm->alarm            not a transition into alarm (previous is alarm): ignored
#  12.0  baro_ins nominal->alarm      a later alarm inside the window (not the first)
#  25.0  gnss alarm->nominal
#  30.0  baro_ins nominal->alarm      after the window: a false alarm (margin 0), not one with margin 10 s
ALARMS = [
    ev(2.0, "gnss", "caution", "nominal"),
    ev(5.0, "rangefinder", "alarm", "nominal"),
    ev(6.0, "rangefinder", "nominal", "alarm"),
    ev(10.4, "gnss", "alarm", "caution"),
    ev(10.9, "gnss", "alarm", "alarm"),
    ev(12.0, "baro_ins", "alarm", "nominal"),
    ev(25.0, "gnss", "nominal", "alarm"),
    ev(30.0, "baro_ins", "alarm", "nominal"),
]


def test_alarm_onsets_are_transitions_into_alarm_only():
    got = [(round(e.t_s, 3), e.source) for e in sm.alarm_onsets(ALARMS)]
    assert got == [(5.0, "rangefinder"), (10.4, "gnss"), (12.0, "baro_ins"), (30.0, "baro_ins")]


def test_detection_tta_and_isolation_hand_checked():
    d = sm.detect(ALARMS, onset_s=10.0, end_s=20.0, source="gnss")
    assert d.detected and d.isolated
    assert d.tta_s == pytest.approx(0.4, abs=1e-9)  # 10.4 - 10.0
    assert d.first_sources == ("gnss",)
    # the same alarms judged for a rangefinder fault: detected at 10.4, wrong source
    d2 = sm.detect(ALARMS, 10.0, 20.0, "rangefinder")
    assert d2.detected and not d2.isolated
    # a fault from 13 to 20 s: no alarm transition inside (12.0 is before, 30.0 after)
    assert not sm.detect(ALARMS, 13.0, 20.0, "gnss").detected
    # ... unless the grace period reaches 30.0 (20 + 10): TTA 30 - 13 = 17 s
    d3 = sm.detect(ALARMS, 13.0, 20.0, "baro_ins", grace_s=10.0)
    assert d3.detected and d3.tta_s == pytest.approx(17.0) and d3.isolated


def test_two_sources_at_the_same_instant_is_not_an_isolation():
    alarms = [ev(3.0, "gnss", "alarm", "nominal"), ev(3.0, "baro_ins", "alarm", "nominal")]
    d = sm.detect(alarms, 2.0, 8.0, "gnss")
    assert d.detected and d.tta_s == pytest.approx(1.0)
    assert d.first_sources == ("baro_ins", "gnss") and not d.isolated


def test_tta_stats_and_isolation_rate():
    # TTAs 0.2, 0.4, 1.0, 3.0 and a miss (NaN, ignored). Sorted n = 4:
    # median = (0.4 + 1.0) / 2 = 0.7; p95 at position 0.95 * 3 = 2.85:
    # x[2] + 0.85 (x[3] - x[2]) = 1.0 + 0.85 * 2.0 = 2.7
    med, p95 = sm.tta_stats([1.0, 0.2, math.nan, 3.0, 0.4])
    assert med == pytest.approx(0.7)
    assert p95 == pytest.approx(2.7)
    assert all(math.isnan(v) for v in sm.tta_stats([math.nan]))
    dets = [sm.Detection(True, 0.2, True, ("gnss",)), sm.Detection(True, 0.4, False, ("baro_ins",)),
            sm.Detection(False, math.nan, False, ()), sm.Detection(True, 1.0, True, ("gnss",))]
    assert sm.isolation_rate(dets) == (2, 3)  # 2 correct of 3 detected (the miss does not count)


def test_false_alarms_per_hour():
    # Fault-free: 4 alarm transitions (5.0, 10.4, 12.0, 30.0) in 30 min = 8 per hour.
    n = sm.false_alarms(ALARMS)
    assert n == 4
    assert sm.per_hour(n, 1800.0) == pytest.approx(8.0)
    # With the fault window [10, 20]: 5.0 and 30.0 remain; with a 10 s margin only 5.0.
    assert sm.false_alarms(ALARMS, [(10.0, 20.0)]) == 2
    assert sm.false_alarms(ALARMS, [(10.0, 20.0)], margin_s=10.0) == 1
    # No event in one hour: the exact 95 % upper bound is -ln(0.05) = 3.0 per hour.
    assert sm.poisson_upper_95(0, 3600.0) == pytest.approx(-math.log(0.05), rel=1e-6)


def test_hold_and_windowed_rms_hand_checked():
    # Estimates at 0.0, 1.0, 2.0 s: 10, 11, 13. Truth at 0.5, 1.5, 2.5, 3.5 s: 10, 10, 12, 12.
    # Held estimate at the truth times: 10, 11, 13, 13 -> errors 0, 1, 1, 1.
    t_est, h_est = [0.0, 1.0, 2.0], [10.0, 11.0, 13.0]
    t_tr, h_tr = [0.5, 1.5, 2.5, 3.5], [10.0, 10.0, 12.0, 12.0]
    assert list(sm.hold_at(t_est, h_est, [-1.0, 0.0, 0.99, 2.5])[1:]) == [10.0, 10.0, 13.0]
    assert math.isnan(sm.hold_at(t_est, h_est, [-1.0])[0])
    e, nan = sm.height_errors(t_est, h_est, t_tr, h_tr)
    assert list(e) == [0.0, 1.0, 1.0, 1.0] and nan == 0
    assert sm.rms(e) == pytest.approx(math.sqrt(3.0 / 4.0))  # sqrt((0 + 1 + 1 + 1) / 4)
    # inside [1, 3]: truth times 1.5, 2.5 -> errors 1, 1 -> RMS 1; outside: 0.5, 3.5 -> 0, 1
    e_in, _ = sm.height_errors(t_est, h_est, t_tr, h_tr, windows=[(1.0, 3.0)])
    e_out, _ = sm.height_errors(t_est, h_est, t_tr, h_tr, windows=[(1.0, 3.0)], inside=False)
    assert list(e_in) == [1.0, 1.0] and list(e_out) == [0.0, 1.0]
    # a NaN estimate (monitor unavailable) is counted apart, not as an error
    e2, nan2 = sm.height_errors(t_est, [10.0, float("nan"), 13.0], t_tr, h_tr)
    assert list(e2) == [0.0, 1.0, 1.0] and nan2 == 1
    # pooled: run A errors (0, 1, 1, 1) -> ss 3, n 4; run B (2, 2) -> ss 8, n 2: sqrt(11 / 6)
    assert sm.pooled_rms([(3.0, 4), (8.0, 2)]) == pytest.approx(math.sqrt(11.0 / 6.0))
    assert sm.icao_band(0.25) == "CAT III" and sm.icao_band(0.8) == "CAT II"
    assert sm.icao_band(1.9) == "CAT I" and sm.icao_band(2.5) == "none"


# ---------------------------------------------------------------- the baseline end to end

HOVER = {
    "name": "baseline_test",
    "duration_s": 40.0,
    "seed": 5,
    "profile": "px4",
    "trajectory": {"kind": "hover", "height_m": 12.0, "takeoff": False, "wander_m": 0.5},
    "sensors": {"baro": {"sigma_bb_m": 0.5, "gamma_bb_per_s": 1.0, "bias_m": 1.5},
                "gnss": {"sigma_z_m": 0.8, "correlated_sigma_m": 1.0}},
}


def _run(scn_dict, cfg=BaselineConfig()):
    scn = scenario_from_dict(scn_dict)
    res = simulate(scn)
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / "x.tlog"
        p.write_bytes(res.tlog)
        samples = list(TlogSource(p, config_from_dict({}).ingest))
    out = run_baseline(samples, scn.filter_sensors(), cfg)
    return res, out


def test_baseline_falls_back_when_the_rangefinder_goes_stale():
    d = dict(HOVER, faults=[{"kind": "rng_dropout", "onset_s": 15.0, "duration_s": 10.0, "mode": "silent"}])
    res, out = _run(d)
    t_tr, h_tr = res.truth["t_s"], res.truth["true_height_ref_m"]
    # fuses sensibly: fault-free part (after 5 s, outside the dropout) within 0.5 m RMS of truth
    e, _ = sm.height_errors(out.t_s, out.height_m, t_tr, h_tr, windows=[(5.0, 15.0), (25.0, 40.0)])
    assert e.size > 250 and sm.rms(e) < 0.5
    # the rangefinder goes unavailable once stale: 0.5 s after its last sample (at most one
    # 20 Hz interval before the onset), checked at the next sample of any sensor (25 Hz baro)
    rng = [a for a in out.alarms if a.source == "rangefinder" and 14.0 < a.t_s]
    assert rng[0].state == "unavailable" and 15.0 - 0.06 + 0.5 <= rng[0].t_s <= 15.5 + 0.05
    # ... is back with its first sample after the dropout, and none of this is an alarm
    assert rng[1].state == "nominal" and 25.0 <= rng[1].t_s <= 25.2
    assert not sm.alarm_onsets(out.alarms)
    # the height carries on from baro and GNSS: within 1 m RMS during the dropout
    e_drop, _ = sm.height_errors(out.t_s, out.height_m, t_tr, h_tr, windows=[(15.5, 25.0)])
    assert sm.rms(e_drop) < 1.0
    states = [s for t, s in out.states if 16.0 <= t <= 24.5]
    assert states and all(s["rangefinder"] == "unavailable" and s["gnss"] == "nominal" for s in states)


def test_baseline_alarms_on_a_gross_gnss_step_after_its_timeout():
    d = dict(HOVER, faults=[{"kind": "gnss_step", "onset_s": 15.0, "duration_s": 15.0, "magnitude": 15.0}])
    res, out = _run(d, BaselineConfig(fail_s=5.0))
    det = sm.detect(out.alarms, 15.0, 30.0, "gnss")
    # 15 m is far outside the 5-sigma gate: every sample rejected, a failure after 5 s
    assert det.detected and det.isolated and 5.0 <= det.tta_s <= 5.3
    # the rejected GNSS never pulled the height: still close to truth during the fault
    e, _ = sm.height_errors(out.t_s, out.height_m, res.truth["t_s"], res.truth["true_height_ref_m"],
                            windows=[(15.0, 30.0)])
    assert sm.rms(e) < 0.5


# ---------------------------------------------------------------- score_run (bench/integrity.py families)

# 10 Hz output for 40 s, truth flat at 10 m; the fault window is [10, 20].
T_EST = np.round(np.arange(0.0, 40.0, 0.1), 3)
TRUTH_T, TRUTH_H = np.array([0.0, 40.0]), np.array([10.0, 10.0])


def _out(err_m=0.0, overall="nominal", at=(12.0, 14.0)):
    """Heights with ``err_m`` of error inside ``at``, and one overall state everywhere else ``nominal``."""
    h = np.full(T_EST.shape, 10.0)
    inside = (T_EST >= at[0]) & (T_EST < at[1])
    h[inside] += err_m
    ov = np.where(inside, overall, "nominal").tolist()
    return h, ov


def test_score_run_fault_detected_isolated_with_source_aliases():
    alarms = [ev(3.0, "gnss", "alarm", "nominal"), ev(3.5, "gnss", "nominal", "alarm"),  # before onset: false alarm
              ev(10.4, "baro_ins", "alarm", "nominal"),  # a baro fault, named by the current monitor
              ev(15.0, "gnss", "alarm", "nominal")]  # a healthy source excluded after the onset
    h, ov = _out()
    s = sm.score_run(alarms, T_EST, h, ov, TRUTH_T, TRUTH_H, window=(10.0, 20.0), expected=sm.SOURCE_GROUPS["baro"])
    assert s.fault and s.detected and s.isolated
    assert s.tta_s == pytest.approx(0.4) and s.blamed == ("baro_ins",)
    assert s.false_alarms == 1 and s.wrong_exclusions == ("gnss",)
    assert not s.hazardous and s.available_frac == pytest.approx(1.0)
    assert not s.right  # the wrong exclusion and the false alarm
    clean = sm.score_run(alarms[2:3], T_EST, h, ov, TRUTH_T, TRUTH_H, window=(10.0, 20.0),
                         expected=sm.SOURCE_GROUPS["baro"])
    assert clean.right
    wrong = sm.score_run([ev(10.4, "rangefinder", "alarm", "nominal")], T_EST, h, ov, TRUTH_T, TRUTH_H,
                         window=(10.0, 20.0), expected=sm.SOURCE_GROUPS["gnss"])
    assert wrong.detected and not wrong.isolated and wrong.wrong_exclusions == ("rangefinder",) and not wrong.right
    late = sm.score_run([ev(20.5, "gnss", "alarm", "nominal")], T_EST, h, ov, TRUTH_T, TRUTH_H,
                        window=(10.0, 20.0), expected=("gnss",))
    assert not late.detected and math.isnan(late.tta_s) and not late.right


def test_score_run_nominal_allowed_sources_and_input():
    h, ov = _out()
    roof = [ev(12.0, "rangefinder", "alarm", "nominal")]
    s = sm.score_run(roof, T_EST, h, ov, TRUTH_T, TRUTH_H, window=(10.0, 20.0), allowed=("rangefinder",))
    assert not s.fault and s.false_alarms == 0 and s.wrong_exclusions == () and s.right
    assert s.alarmed == ("rangefinder",)
    s = sm.score_run(roof + [ev(13.0, "baro_ins", "alarm", "nominal"), ev(30.0, "input", "alarm", "nominal")],
                     T_EST, h, ov, TRUTH_T, TRUTH_H, allowed=("rangefinder",))
    assert s.false_alarms == 2 and s.wrong_exclusions == ("baro_ins",) and not s.right
    s = sm.score_run([ev(30.0, "input", "alarm", "nominal")], T_EST, h, ov, TRUTH_T, TRUTH_H)
    assert s.false_alarms == 1 and s.wrong_exclusions == () and not s.right  # slow inputs are no alarm either


@pytest.mark.parametrize("err_m,overall,haz_s,avail,caution", [
    (3.5, "nominal", 2.0, 1.0, 0.0),  # 2 s offered as usable 3.5 m off: hazardous
    (3.5, "caution", 2.0, 1.0, 0.05),  # 2 s of 40 in caution
    (3.5, "unavailable", 0.0, 0.95, 0.0),  # flagged: not hazardous, not available
    (3.5, "alarm", 0.0, 0.95, 0.0),
    (2.9, "nominal", 0.0, 1.0, 0.0),  # within 3 m
    (-3.5, "nominal", 2.0, 1.0, 0.0),
    (math.nan, "nominal", 0.0, 0.95, 0.0),  # no output: nothing offered
])
def test_score_run_hazardous_output(err_m, overall, haz_s, avail, caution):
    h, ov = _out(err_m, overall)
    s = sm.score_run([], T_EST, h, ov, TRUTH_T, TRUTH_H)
    assert s.hazardous_s == pytest.approx(haz_s, abs=1e-6)
    assert s.hazardous == (haz_s > 0) and s.right == (haz_s == 0)
    assert s.available_frac == pytest.approx(avail, abs=2e-3)
    assert s.caution_frac == pytest.approx(caution, abs=2e-3)


def test_score_run_without_states_counts_every_output_as_offered():
    h, ov = _out(5.0, "unavailable")
    s = sm.score_run([], T_EST, h, None, TRUTH_T, TRUTH_H)
    assert s.hazardous_s == pytest.approx(2.0) and s.max_usable_error_m == pytest.approx(5.0)
    assert math.isnan(s.caution_frac)  # a contender without states shows no caution


def test_score_run_holds_an_epoch_at_most_max_hold_s():
    t = np.array([0.0, 1.0, 10.0])  # a 9 s gap after a bad output
    s = sm.score_run([], t, np.array([10.0, 20.0, 10.0]), ["nominal"] * 3, TRUTH_T, TRUTH_H, max_hold_s=0.5)
    assert s.hazardous_s == pytest.approx(0.5)


def test_integrity_families_build_valid_runs():
    """Every family's run is a valid scenario (or a SITL injection) whose fault lies in its window."""
    from bench import integrity

    assert {"descent_above_max", "takeoff_landing", "terrain_roof", "rng_frozen_descent", "accel_bias",
            "gnss_wander", "slow_telemetry", "inflight_start", "gnss_step3", "baro_ramp", "rng_stuck"} <= set(
        integrity.FAMILIES)
    for fam in integrity.FAMILIES.values():
        for seed in (1, 2):
            b = fam.build(seed, {"long_minutes": 1.0})
            fault = b.get("fault") if b.get("real") else (b["scenario"]["faults"] or [None])[0]
            if not b.get("real"):
                scenario_from_dict(b["scenario"])
            if fam.expect is None:
                assert fault is None, fam.name
            else:
                on, end = b["window"]
                assert fault["onset_s"] == pytest.approx(on, abs=1e-3) and end > on, fam.name
    roof = integrity.FAMILIES["terrain_roof"].build(3, {})
    assert roof["scenario"]["terrain"][0]["from_s"] == pytest.approx(roof["window"][0], abs=1e-3)
    assert [f.name for f in integrity.select("gnss_step*,terrain_roof")] == [
        "gnss_step3", "gnss_step5", "gnss_step8", "terrain_roof"]
    with pytest.raises(SystemExit):
        integrity.select("no_such_family")


def test_integrity_job_scores_every_contender():
    from bench import integrity

    r = integrity.job({"family": "slow_telemetry", "seed": 3, "contenders": ["adaptive", "baseline"],
                       "baseline_fail_s": 5.0})
    assert set(r.scores) == {"adaptive", "baseline"} and r.note == "2 Hz" and r.span_s > 50.0
    for s in r.scores.values():
        assert not s["fault"] and 0.0 <= s["available_frac"] <= 1.0


@pytest.mark.parametrize("model", ["truth", "shipped"])
def test_integrity_job_runs_the_monitor_on_the_sensor_model_asked(model, monkeypatch):
    from bench import integrity
    from mavnav.config import SensorsConfig

    seen = []
    real = integrity.run_contenders
    monkeypatch.setattr(integrity, "run_contenders", lambda samples, sensors, *a: seen.append(sensors)
                        or real(samples, sensors, *a))
    r = integrity.job({"family": "slow_telemetry", "seed": 3, "contenders": ["adaptive"], "baseline_fail_s": 5.0,
                       "sensor_model": model})
    shipped = SensorsConfig()
    assert len(seen) == 1 and 0.0 <= r.scores["adaptive"]["caution_frac"] <= 1.0
    # the scenario's baro (u 0.5 m) told to the monitor, or mavnav's shipped 0.2 m
    assert (seen[0].baro.sigma_bb_m == shipped.baro.sigma_bb_m) == (model == "shipped")


def test_misleading_counts_error_beyond_the_protection_level_hand_checked():
    t = [0.0, 0.1, 0.2, 0.3, 0.4]
    truth_t, truth_h = [0.0, 1.0], [10.0, 10.0]
    h = [10.0, 12.0, 13.0, 10.5, math.nan]
    pl = [1.0, 1.0, 4.0, 1.0, 1.0]
    overall = ["nominal", "caution", "nominal", "unavailable", "nominal"]
    # epoch 1: error 2 > 1, usable: 0.1 s; epoch 2: 3 < 4; epoch 3 not offered; epoch 4 no height
    bad, usable = sm.misleading(t, h, pl, overall, truth_t, truth_h)
    assert bad == pytest.approx(0.1) and usable == pytest.approx(0.3)
    # an infinite protection level bounds everything; nothing offered, nothing misleading
    assert sm.misleading(t, h, [math.inf] * 5, overall, truth_t, truth_h)[0] == 0.0
    assert sm.misleading(t, h, pl, ["unavailable"] * 5, truth_t, truth_h) == (0.0, 0.0)


def test_isolation_counts_only_runs_whose_fault_changed_a_sample():
    """A GNSS fault injected into a flight without GNSS changes nothing; the
    flight's own baro alarm in its window is not an isolation failure of it."""
    from bench import realflights as R

    def run(changed, detected, isolated):
        one = {"detected": detected, "isolated": isolated}
        return {"samples_changed": changed, **{m: dict(one) for m in R.CONTENDERS}}

    rows = [run(90, True, True), run(90, True, True), run(90, True, False), run(0, True, False), run(80, False, False)]
    applicable = [r for r in rows if r["samples_changed"] > 0]
    line = R.isolation_line(applicable)
    assert "adaptive 2/3 (66.7 %)" in line
    assert "adaptive 2/4 (50.0 %)" in R.isolation_line(rows)  # what counting every run would say
