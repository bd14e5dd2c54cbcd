"""The fault-hypothesis monitor: the decision table on its own, the CUSUM
threshold from the false-alert budget, and the rangefinder rules on a real
ArduPilot log whose rangefinder reads 0 m the whole flight."""

from __future__ import annotations

import numpy as np
import pytest

from mavnav.audit import audit_file
from mavnav.config import load_config
from mavnav.monitor.cusum import Cusum, siegmund_arl, threshold_for
from mavnav.monitor.table import TABLE, judge
from mavnav.monitor.verdict import Verdict
from tests.support.monitor import fly
from tests.support.paths import SHARED

G, R, B, I = "gnss", "rangefinder", "baro", "ins"


def fail(*hyps, size=5.0):
    return Verdict("t", "fail", frozenset(hyps), text="x", scale_m=size)


def clear(*hyps, scale=1.0):
    return Verdict("t", "pass", frozenset(hyps), frozenset(hyps), scale_m=scale)


@pytest.mark.parametrize("verdicts, situation, sources", [
    ([fail(G, B), clear(B, I)], "isolated", {"gnss"}),
    ([fail(R, B), clear(B, I)], "isolated", {"rangefinder"}),
    ([fail(B, I)], "isolated", {"baro_ins"}),  # baro and INS are one report source
    ([fail(G, B)], "ambiguous", {"gnss", "baro_ins"}),
    ([fail(G, B), clear(B, I, scale=9.0)], "ambiguous", {"gnss", "baro_ins"}),  # the pass lacks the power
    ([fail(G, B), fail(R)], "inconsistent", {"gnss", "baro_ins", "rangefinder"}),
    ([Verdict("t", "suspect", frozenset((G,)))], "suspect", {"gnss"}),
    ([clear(G), clear(B, I)], "clear", set()),
])
def test_the_table_isolates_only_what_the_evidence_isolates(verdicts, situation, sources):
    j = judge(verdicts)
    assert j.situation == situation
    assert set(j.sources) == sources
    assert j.state == TABLE[situation][0]


def test_an_excluded_source_cannot_explain_a_new_failure():
    j = judge([fail(G, B)], live=frozenset((G, R, I)))
    assert j.situation == "isolated" and set(j.sources) == {"gnss"}


def test_ambiguity_keeps_the_suspects_out_of_the_output():
    assert judge([fail(G, B)]).enters_output is False
    assert judge([Verdict("t", "suspect", frozenset((G,)))]).enters_output is True


def test_cusum_threshold_spends_the_budget_at_the_streams_rate():
    h10, h2 = threshold_for(0.5, 0.01, 10.0), threshold_for(0.5, 0.01, 2.0)
    assert h2 < h10  # a slower stream reaches the same budget with a lower threshold
    arl = siegmund_arl(0.5, h10)
    assert arl == pytest.approx(2 * 3600 * 10.0 / 0.01, rel=1e-3)


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_cusum_on_white_noise_rarely_trips_and_finds_a_small_shift(seed):
    rng = np.random.default_rng(seed)
    h = threshold_for(0.5, 1.0, 10.0)  # 1 per hour at 10 Hz
    c = Cusum(0.5, 5.0)
    trips = 0
    for z in rng.standard_normal(6000):  # 10 minutes
        c.push(float(z))
        if c.stat > h:
            trips += 1
            c.clear()
    assert trips <= 2
    c.clear()
    n = 0
    for z in rng.standard_normal(600) + 1.5:  # a 1.5 sigma shift
        c.push(float(z))
        n += 1
        if c.stat > h:
            break
    assert n < 30 and c.sign > 0


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_the_fast_arms_find_a_3_sigma_step_in_three_samples_and_keep_their_budget(seed):
    """At 5 Hz and 0.01 false alerts per hour a 3 sigma step takes the k = 0.5
    arms five or six samples and the k = 1.5 arms (tuned to 3 sigma) about
    three: within the 1 s time-to-alarm. On white noise each pair keeps to its
    own budget (1 per hour for the count)."""
    rng = np.random.default_rng(seed)
    h, h_fast = threshold_for(0.5, 1.0, 5.0), threshold_for(1.5, 1.0, 5.0)
    c = Cusum(0.5, 5.0, k_fast=1.5)
    trips = trips_fast = 0
    for z in rng.standard_normal(36000):  # 2 hours at 5 Hz
        c.push(float(z))
        if c.stat > h or c.fast_stat > h_fast:
            trips += c.stat > h
            trips_fast += c.fast_stat > h_fast
            c.clear()
    assert trips <= 6 and trips_fast <= 6  # 2 expected each
    h, h_fast = threshold_for(0.5, 0.01, 5.0), threshold_for(1.5, 0.01, 5.0)  # the monitor's budget
    slow_n, fast_n = [], []
    for _ in range(200):
        c.clear()
        n = n_fast = 0
        for z in rng.standard_normal(20) + 3.0:
            c.push(float(z))
            n += c.stat <= h
            n_fast += c.fast_stat <= h_fast
        slow_n.append(n + 1)
        fast_n.append(n_fast + 1)
    assert np.median(fast_n) <= 3 < np.median(slow_n) and np.median(slow_n) >= 5
    # within 1 s at 5 Hz (the 90 % of 3 sigma steps), where the slow arms alone are not
    assert np.mean(np.array(fast_n) <= 5) >= 0.9 > np.mean(np.array(slow_n) <= 5)


@pytest.mark.unit
def test_the_fast_arms_size_the_step_they_sum():
    """``k + S / n`` over the samples since the leading fast arm left zero: the
    step's own size at once (the innovations' 1 s mean has only a third of it
    after two samples at 5 Hz), either sign, and nothing after a clear."""
    c = Cusum(0.5, 5.0, k_fast=1.5)
    for z in (0.2, -0.4, 0.1):
        c.push(z)
    assert c.fast_shift == 0.0
    for _ in range(3):
        c.push(3.0)
    assert c.fast_shift == pytest.approx(3.0)
    c.clear()
    assert c.fast_shift == 0.0
    for _ in range(2):
        c.push(-4.0)
    assert c.fast_shift == pytest.approx(4.0) and c.sign < 0
    rng = np.random.default_rng(7)
    sizes = []
    for _ in range(200):
        c.clear()
        for z in rng.standard_normal(3) + 3.0:
            c.push(float(z))
        sizes.append(c.fast_shift)
    assert np.median(sizes) == pytest.approx(3.0, abs=0.4)


LOG = SHARED / "flightlogs" / "SITL_wlichon_baseline_00000001.BIN"


@pytest.mark.realdata
@pytest.mark.slow
@pytest.mark.skipif(not LOG.exists(), reason="needs ../shared/flightlogs")
def test_a_rangefinder_reading_zero_in_flight_is_a_rangefinder_alarm_and_nothing_else():
    """RFND.Dist 0 (status out-of-range-low) for the whole flight while the
    copter hovers at 3 m: the dead rangefinder is found, and blamed alone."""
    r = audit_file(LOG, load_config(None))
    alarms = [a for a in r["alarms"] if a["state"] == "alarm"]
    assert alarms and {a["source"] for a in alarms} == {"rangefinder"}, alarms
    assert "reads 0.00 m" in alarms[0]["reason"]


def test_with_the_baro_excluded_the_ins_still_shares_the_blame():
    """Excluding baro_ins takes the baro out, not the INS: a drift of one aux
    channel running on the INS alone cannot be pinned on that aux sensor
    until the other channel clears the INS."""
    from mavnav.monitor.verdict import live_hypotheses

    live = live_hypotheses({"baro_ins"})
    assert live == frozenset((G, R, I))
    assert judge([fail(G, I)], live=live).situation == "ambiguous"
    assert judge([fail(G, I), clear(R, I)], live=live).situation == "isolated"


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_residual_scale_measures_variance_and_correlation(seed):
    from mavnav.monitor.scale import ResidualScale

    rng = np.random.default_rng(seed)
    white, ar = ResidualScale(60.0, 0.1, 10.0), ResidualScale(60.0, 0.1, 10.0)
    z_prev = 0.0
    for k in range(20000):  # 2000 s at 10 Hz
        t = k * 100_000
        white.push(t, float(rng.standard_normal()) * 0.5)
        z_prev = 0.8 * z_prev + 0.6 * float(rng.standard_normal())  # unit-variance AR(1), phi 0.8
        ar.push(t, z_prev)
    assert white.factor == pytest.approx(0.5, rel=0.25)  # a pessimistic model: the test sharpens
    assert ar.phi == pytest.approx(0.8, abs=0.1)
    assert ar.factor == pytest.approx(3.0, rel=0.3)  # sqrt((1 + phi) / (1 - phi))
    clipped = ResidualScale(60.0, 1.0, 2.0)
    for k in range(3000):
        clipped.push(k * 100_000, 10.0)
    assert clipped.factor == 2.0


@pytest.mark.simulation
@pytest.mark.slow
def test_a_baro_spike_is_gated_and_a_baro_step_alarms_within_a_second():
    """A 6 m baro transient of 0.15 s (prop wash, a pressure glitch) returns:
    no alarm. The same jump that stays is a baro step: alarmed on baro_ins
    within 1 s."""
    spike = fly(("baro", "step", 40.0, 0.15, 6.0))
    assert not [a for a in spike.alarms if a.state == "alarm"], spike.alarms
    step = fly(("baro", "step", 40.0, 20.0, 6.0))
    first = step.first_alarm_after(40.0)
    assert list(first) == ["baro_ins"] and first["baro_ins"] - 40.0 <= 1.0


@pytest.mark.unit
def test_a_baro_jump_being_watched_is_no_evidence_and_one_that_stayed_is_a_failure():
    """A baro sample past the jump gate is out of every filter; while the
    monitor watches whether the jump stays, the baro/INS verdict is a pass that
    rules nothing out (no caution for a gated sample: on real flights the
    watches alone put the baro in caution 1.7 % of the flight time). The jump
    that stayed fails and isolates baro_ins."""
    from mavnav.bank import ChannelBank
    from mavnav.channel import Model
    from mavnav.config import config_from_dict
    from mavnav.monitor.hypotheses import HypothesisLogic

    cfg = config_from_dict({})
    logic = HypothesisLogic(cfg, ChannelBank(Model.from_config(cfg)))
    logic.start(0, 0)
    implicates = frozenset((B, I))
    assert logic._jump_verdict(10_000_000, implicates) is None  # no jump: the window test decides
    logic.jump = [10_000_000, 2.0, 0.2, 2.0, 1, ()]  # opened at 10 s: 2 m, 10 sigma
    watched = logic._jump_verdict(10_200_000, implicates)
    assert watched.level == "pass" and not watched.exonerates
    assert judge([watched]).situation == "clear"
    assert judge([watched, fail(B, G)]).situation == "ambiguous"  # it clears nothing
    logic.jump, logic.jump_confirmed = None, (10_600_000, 1.9, 10.0)
    stayed = logic._jump_verdict(10_700_000, implicates)
    assert stayed.level == "fail" and judge([stayed]).situation == "isolated"
    assert judge([stayed]).sources == frozenset(("baro_ins",))


@pytest.mark.unit
def test_a_failure_can_be_sized_per_hypothesis():
    """One INS-against-Doppler failure: 5 m of position if it is the GNSS's
    velocity, 1 m of the baro/INS check's second difference if it is the INS.
    A coarse INS pass (3 m) cannot rule the INS out; a GNSS pass as coarse can
    rule the GNSS out."""
    f = Verdict("INS/Doppler", "fail", frozenset((G, I)), text="x", scale_m=5.0, sizes={I: 1.0})
    assert f.size_for(I) == 1.0 and f.size_for(G) == 5.0
    j = judge([f, clear(I, scale=3.0), clear(G, scale=3.0)])
    assert j.situation == "isolated" and set(j.sources) == {"baro_ins"} and j.candidates == {I}
    # sized alike (no per-hypothesis sizes) both passes would clear, and nothing would be left
    g = Verdict("INS/Doppler", "fail", frozenset((G, I)), text="x", scale_m=5.0)
    assert judge([g, clear(I, scale=3.0), clear(G, scale=3.0)]).situation == "inconsistent"


@pytest.mark.unit
def test_an_ins_test_on_a_sparse_imu_is_no_evidence():
    """With the IMU below min_imu_rate_hz (the core's rate check sets
    slow_imu_hz) an INS test says nothing: snapshots that sparse cannot tell a
    baro fault from the motion between them, so neither its failures (no
    caution, no alarm) nor its passes (no clearing) count. On a fast IMU the
    verdict is as the test gave it."""
    from mavnav.bank import ChannelBank
    from mavnav.channel import Model
    from mavnav.config import config_from_dict
    from mavnav.monitor.hypotheses import HypothesisLogic

    cfg = config_from_dict({})
    logic = HypothesisLogic(cfg, ChannelBank(Model.from_config(cfg)))
    logic.start(0, 0)
    failed = Verdict("baro/INS", "fail", frozenset((B, I)), stat=5.0, threshold=3.0, text="baro moved", scale_m=5.0)
    passed = clear(I)
    assert logic._slow_ins(failed) is failed and logic._slow_ins(passed) is passed  # the IMU's rate not short
    logic.slow_imu_hz = 4.2
    assert logic._slow_ins(failed) is None and logic._slow_ins(passed) is None
    assert logic._slow_ins(None) is None


def test_a_baro_isolated_while_its_stream_is_sparse_is_held_not_alarmed():
    """With the baro's own rate below min_baro_rate_hz an isolation on the
    baro is held as ambiguous (caution, out of the output, no alarm); at its
    nominal rate, and for an isolation that is not the baro's, the judgement
    stands."""
    from mavnav.bank import ChannelBank
    from mavnav.channel import Model
    from mavnav.config import config_from_dict
    from mavnav.monitor.hypotheses import HypothesisLogic

    cfg = config_from_dict({})
    logic = HypothesisLogic(cfg, ChannelBank(Model.from_config(cfg)))
    logic.start(0, 0)
    failed = Verdict("baro level against rangefinder", "fail", frozenset((B, R)), stat=1.5, threshold=1.37,
                     text="baro +1.50 m from the rangefinder channel", scale_m=1.5)
    isolated = judge([failed, clear(R)])
    assert isolated.situation == "isolated" and isolated.state == "alarm"
    for k in range(12):  # 10 Hz
        logic.rates["baro_ins"].push(k * 100_000)
    assert logic._slow_blame(isolated) is isolated
    for k in range(1, 9):  # then 2 Hz: the rate follows within a few samples
        logic.rates["baro_ins"].push(1_100_000 + k * 500_000)
    held = logic._slow_blame(isolated)
    assert held.situation == "ambiguous" and held.state == "caution" and not held.enters_output
    assert held.sources == isolated.sources and "too sparse" in held.reason
    gnss_fault = judge([Verdict("GNSS/Doppler", "fail", frozenset((G,)), stat=3.0, threshold=1.0, scale_m=3.0)])
    assert logic._slow_blame(gnss_fault) is gnss_fault


def test_an_ins_isolated_while_the_baro_is_already_out_freezes_the_aux_tests():
    """The baro+INS source out for its baro, then the INS isolated too (an
    accelerometer bias): from then on the aux channels' sequential tests sum
    the INS's doing, so they restart and stay frozen (an accelerometer bias on
    a real flight whose baro was already out had been pinned on the GNSS when
    it ended). An isolation not on the INS leaves them running."""
    from mavnav.bank import ChannelBank
    from mavnav.channel import Model
    from mavnav.config import config_from_dict
    from mavnav.monitor.hypotheses import HypothesisLogic
    from mavnav.monitor.table import Judgement

    cfg = config_from_dict({})
    logic = HypothesisLogic(cfg, ChannelBank(Model.from_config(cfg)))
    logic.start(0, 0)
    logic.excluded.add("baro_ins")  # out for its baro
    assert not logic.ins_excluded
    for z in (3.0,) * 6:
        logic.cusum["gnss"].push(z)
    summed = logic.cusum["gnss"].stat
    assert summed > 0.0
    t = 10_000_000
    logic.isolated_since = t - 1_000_000
    baro_again = Judgement("isolated", frozenset((B,)), frozenset(("baro_ins",)), "baro")
    logic._source_state("baro_ins", t, baro_again)
    assert not logic.ins_excluded and logic.cusum["gnss"].stat == summed
    ins = Judgement("isolated", frozenset((I,)), frozenset(("baro_ins",)), "INS velocity changed")
    logic._source_state("baro_ins", t, ins)
    assert logic.ins_excluded and logic.cusum["gnss"].stat == 0.0
    logic._sequential("gnss", t, 3.0, False)  # frozen while the INS is out
    assert logic.cusum["gnss"].stat == 0.0


def test_a_window_test_is_suspect_on_two_readings_in_a_row_not_one():
    """Consecutive windows share all but their end samples: one reading past
    the suspect level (or even past the threshold) is one noisy sample and
    raises nothing; two in a row are a suspect; a failure needs two past the
    threshold held persist_s. (The Doppler, INS/Doppler, baro/Doppler, GNSS
    drift and baro/INS tests all grade through ``_graded``.)"""
    from mavnav.bank import ChannelBank
    from mavnav.channel import Model
    from mavnav.config import config_from_dict
    from mavnav.monitor.doppler import Exceedance
    from mavnav.monitor.hypotheses import HypothesisLogic

    cfg = config_from_dict({})
    logic = HypothesisLogic(cfg, ChannelBank(Model.from_config(cfg)))
    logic.start(0, 0)
    thr, near, over, low = 2.0, 0.9 * 2.0, 2.5, 0.5
    assert cfg.monitor.suspect_frac * thr < near < thr
    ex = Exceedance()

    def reading(t_us, stat):
        ex.update(t_us, stat > thr, stat > cfg.monitor.suspect_frac * thr)
        return logic._graded("baro/Doppler", stat, thr, ex, t_us, frozenset((B, G)), lambda: "baro moved").level

    assert reading(0, over) == "pass"  # one sample past the threshold
    assert reading(200_000, low) == "pass"
    assert reading(400_000, near) == "pass"  # one past the suspect level
    assert reading(600_000, near) == "suspect"  # two in a row
    assert reading(800_000, over) == "suspect"  # past the threshold, not yet held
    assert reading(1_000_000, over) == "fail"  # two past it, held persist_s (0.2 s)
    assert reading(1_200_000, low) == "pass"


SKEW = SHARED / "tlogs" / "other" / "copter_sitl_speedup_clock_skew.tlog"


@pytest.mark.slow
@pytest.mark.skipif(not SKEW.exists(), reason="needs ../shared/tlogs")
def test_a_4_hz_imu_makes_monitoring_degraded_and_no_sensor_faulty():
    """ArduCopter SITL telemetry at 4 Hz (SCALED_IMU too): the INS integrated
    from such snapshots runs metres away from the healthy baro in the climb.
    The input is reported too slow, and no sensor goes to alarm or caution on
    the INS's word (five baro/INS alarms before session 10's rule, then the
    baro in caution for 23 % of the flight)."""
    r = audit_file(SKEW, load_config(None))
    assert r["inputs"]["rates_hz"]["imu"] < 5.0
    assert not [a for a in r["alarms"] if a["state"] == "alarm"], r["alarms"]
    assert r["availability"]["input"]["unavailable"] > 0.9  # monitoring degraded, said as such
    assert not [a for a in r["alarms"] if "INS" in a["reason"]], r["alarms"]


def test_the_isolation_and_the_sudden_jump_hold_for_their_own_times():
    # the sudden-jump rule's persistence once overwrote the isolation's (equal by default)
    from mavnav.config import config_from_dict
    from mavnav.monitor.core import Monitor

    cfg = config_from_dict({"monitor": {"persist_s": 0.7, "sudden_jump_persist_s": 0.3}})
    logic = Monitor(cfg).logic
    assert logic.persist_us == 700_000
    assert logic.sudden_persist_us == 300_000
