"""The per-epoch shortcuts of the monitor's decision step give what the
readable forms they replace give, float for float."""

from __future__ import annotations

import math

import numpy as np

from mavnav.bank import ChannelBank
from mavnav.channel import Model
from mavnav.config import config_from_dict
from mavnav.monitor.decision import diff_sigmas, pair_reports, pair_reports_scaled
from mavnav.monitor.tracker import SourceTracker
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


def test_window_status_is_status_with_the_window_fields():
    tr = SourceTracker(GNSS, 1_000_000, 0, clear_us=500_000)
    for t, state, reason in ((2_000_000, "caution", "x"), (3_000_000, "caution", "y"), (4_000_000, "alarm", "z")):
        tr.set(state, t, reason)
        for stat, hi, rej in ((1.5, 3.0, 0), (math.nan, math.nan, 2)):
            ref = tr.status(window_stat=stat, window_low=math.nan, window_high=hi, rejected=rej)
            assert _same(tr.window_status(stat, hi, rej), ref)


def test_live_hypotheses_kept_answers_are_the_rule():
    for excluded in (set(), {GNSS}, {BARO_INS}, {GNSS, RANGEFINDER}, {BARO_INS, INPUT}, {GNSS, RANGEFINDER, BARO_INS}):
        want = frozenset(h for h in HYPOTHESES if h is INS or REPORT_SOURCE[h] not in excluded)
        assert live_hypotheses(excluded) == want
        assert live_hypotheses(set(excluded)) == want  # asked again: the kept answer
    excluded = {GNSS}
    live_hypotheses(excluded)
    excluded.add(BARO_INS)  # the set changed: a new answer, not the kept one
    assert live_hypotheses(excluded) == frozenset((RANGEFINDER, INS))
