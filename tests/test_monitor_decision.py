"""The per-epoch shortcuts of the monitor's decision step give what the
readable forms they replace give, float for float."""

from __future__ import annotations

import math

import numpy as np

from mavnav.bank import PAIRS, ChannelBank
from mavnav.channel import Model
from mavnav.config import config_from_dict
from mavnav.monitor.decision import diff_sigmas, pair_reports, pair_reports_scaled
from mavnav.monitor.tracker import SourceTracker
from mavnav.report import PAIR_NAMES, PairReport
from mavnav.monitor.verdict import HYPOTHESES, INS, REPORT_SOURCE, live_hypotheses
from mavnav.sensors import BARO_INS, GNSS, INPUT, RANGEFINDER


def _same(a, b) -> bool:
    """Equal, field for field, with NaN equal to NaN (repr: the bytes a report prints)."""
    return repr(a) == repr(b)


def test_pair_reports_scaled_is_pair_reports_of_the_scaled_diff_sigmas():
    rng = np.random.default_rng(7)
    bank = ChannelBank(Model.from_config(config_from_dict({})))
    k = 3.29
    for trial in range(400):
        bank.x[:] = rng.normal(0.0, 5.0, bank.x.shape)
        bank.P[:, 0, 0] = rng.choice([0.0, 1e-14, 0.3, 2.0, math.nan, math.inf], 3) * rng.uniform(0.5, 2.0, 3)
        bank.Pc[:, 0, 0] = rng.normal(0.0, 0.5, 3)
        if trial % 7 == 0:
            bank.Pc[trial % 3, 0, 0] = math.nan
        floor = list(rng.choice([0.0, 0.25, 1.0, math.nan], 3))
        avail = tuple(bool(v) for v in rng.integers(0, 2, 3))
        ref = pair_reports(bank, avail, k * diff_sigmas(bank, floor))
        assert _same(pair_reports_scaled(bank, avail, floor, k), ref)


def _diff_sigmas_plain(bank, floor) -> list:
    """The formula as first written: max() per pair and channel, numpy scalars."""
    out = []
    for p, (a, b) in enumerate(PAIRS):
        v = (max(float(bank.P[a, 0, 0]), floor[a]) + max(float(bank.P[b, 0, 0]), floor[b])
             - 2.0 * float(bank.Pc[p, 0, 0]))
        out.append(math.sqrt(max(v, 1e-12)))
    return out


def _pair_reports_plain(bank, available, thresholds) -> tuple:
    """pair_reports as first written (keyword arguments)."""
    return tuple(PairReport(name=PAIR_NAMES[p], diff_m=float(bank.x[a, 0]) - float(bank.x[b, 0]),
                            threshold_m=float(thresholds[p]),
                            exceeded=bool(available[a] and available[b])
                            and abs(float(bank.x[a, 0]) - float(bank.x[b, 0])) > float(thresholds[p]),
                            valid=bool(available[a] and available[b]))
                 for p, (a, b) in enumerate(PAIRS))


def test_diff_sigmas_and_pair_reports_are_the_plain_formulas():
    """With NaN and infinite variances, floors above and below them: the same floats."""
    rng = np.random.default_rng(11)
    bank = ChannelBank(Model.from_config(config_from_dict({})))
    for trial in range(600):
        bank.x[:] = rng.normal(0.0, 5.0, bank.x.shape)
        bank.P[:, 0, 0] = rng.choice([0.0, -1e-13, 1e-14, 0.3, 2.0, math.nan, math.inf], 3) * rng.uniform(0.5, 2.0, 3)
        bank.Pc[:, 0, 0] = rng.normal(0.0, 0.5, 3)
        if trial % 5 == 0:
            bank.Pc[trial % 3, 0, 0] = rng.choice([math.nan, math.inf, 1.0])
        floor = [float(v) for v in rng.choice([0.0, 0.25, 1.0, math.nan, math.inf], 3)]
        want = _diff_sigmas_plain(bank, floor)
        assert repr(diff_sigmas(bank, floor).tolist()) == repr(want)
        avail = tuple(bool(v) for v in rng.integers(0, 2, 3))
        assert _same(pair_reports(bank, avail, want), _pair_reports_plain(bank, avail, want))


def test_the_plain_formula_can_fail():
    bank = ChannelBank(Model.from_config(config_from_dict({})))
    bank.P[:, 0, 0] = [1.0, 2.0, 3.0]
    assert diff_sigmas(bank, [0.0, 0.0, 0.0]).tolist() != _diff_sigmas_plain(bank, [0.0, 5.0, 0.0])


def test_window_status_is_status_with_the_window_fields():
    tr = SourceTracker(GNSS, 1_000_000, 0, clear_us=500_000)
    for t, state, reason in ((2_000_000, "caution", "x"), (3_000_000, "caution", "y"), (4_000_000, "alarm", "z")):
        tr.set(state, t, reason)
        for stat, hi, rej in ((1.5, 3.0, 0), (math.nan, math.nan, 2)):
            ref = tr.status(window_stat=stat, window_low=math.nan, window_high=hi, rejected=rej)
            assert _same(tr.window_status(stat, hi, rej), ref)


def test_window_status_without_a_test_is_kept_until_it_changes():
    tr = SourceTracker(GNSS, 1_000_000, 0)
    a = tr.window_status(math.nan, math.nan, 0)
    assert tr.window_status(math.nan, math.nan, 0) is a  # nothing changed: the same object
    b = tr.window_status(math.nan, math.nan, 1)  # a rejection more
    assert b is not a and b.rejected == 1
    tr.set("caution", 2_000_000, "x")
    c = tr.window_status(math.nan, math.nan, 1)
    assert _same(c, tr.status(window_stat=math.nan, window_low=math.nan, window_high=math.nan, rejected=1))
    tr.set("caution", 3_000_000, "y")  # the same state, another reason
    assert tr.window_status(math.nan, math.nan, 1).reason == "y"
    assert _same(tr.window_status(1.0, 2.0, 1), tr.status(window_stat=1.0, window_low=math.nan, window_high=2.0,
                                                          rejected=1))


def test_live_hypotheses_kept_answers_are_the_rule():
    for excluded in (set(), {GNSS}, {BARO_INS}, {GNSS, RANGEFINDER}, {BARO_INS, INPUT}, {GNSS, RANGEFINDER, BARO_INS}):
        want = frozenset(h for h in HYPOTHESES if h is INS or REPORT_SOURCE[h] not in excluded)
        assert live_hypotheses(excluded) == want
        assert live_hypotheses(set(excluded)) == want  # asked again: the kept answer
    excluded = {GNSS}
    live_hypotheses(excluded)
    excluded.add(BARO_INS)  # the set changed: a new answer, not the kept one
    assert live_hypotheses(excluded) == frozenset((RANGEFINDER, INS))
