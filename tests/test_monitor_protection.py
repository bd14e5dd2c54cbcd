"""The protection level by solution separation (mavnav/monitor/protection.py),
against the closed forms it must reduce to."""

from __future__ import annotations

import math

import pytest

from mavnav.monitor.fusion import fuse_heights
from mavnav.monitor.protection import protection_level, separation_levels

K_FF, K_FA, K_MD = 4.42, 4.42, 3.29


def _fused(cov):
    h, sigma, w = fuse_heights([0.0] * len(cov), cov, True)
    return sigma, w


@pytest.mark.parametrize("s1,s2", [(0.5, 1.0), (1.0, 1.0), (0.3, 2.5)])
def test_two_independent_channels_match_the_closed_form(s1, s2):
    cov = [[s1 * s1, 0.0], [0.0, s2 * s2]]
    s0, w = _fused(cov)
    assert s0 == pytest.approx(1.0 / math.sqrt(1 / s1 ** 2 + 1 / s2 ** 2))
    pl = separation_levels(cov, w, K_FA, K_MD)
    # without channel 0 the subset is channel 1: Delta = h0 - h1, var = s2^2 - s0^2 (nested BLUE)
    assert pl[0] == pytest.approx(K_FA * math.sqrt(s2 * s2 - s0 * s0) + K_MD * s2)
    assert pl[1] == pytest.approx(K_FA * math.sqrt(s1 * s1 - s0 * s0) + K_MD * s1)
    vpl, limit = protection_level(s0, cov, w, K_FF, K_FA, K_MD)
    assert vpl == pytest.approx(max(K_FF * s0, *pl))
    assert limit == (0 if pl[0] >= pl[1] else 1)  # the worse-monitored source sets it


def test_one_channel_has_no_subset_to_check_it():
    vpl, limit = protection_level(0.2, [[0.04]], [1.0], K_FF, K_FA, K_MD)
    assert vpl == math.inf and limit == 0


def test_nothing_in_the_output_is_unbounded():
    assert protection_level(math.nan, [], [], K_FF, K_FA, K_MD) == (math.inf, -1)


def test_a_channel_copied_from_another_cannot_vouch_for_it():
    """An aux channel restarted as a copy of the baro channel, its height opened
    by an independent 5 m: the fused height is still the baro's to 0.2 m (the
    fault-free bound is small), but a baro fault the comparison cannot see is
    as large as the copy's opening."""
    p, e = 0.2 ** 2, 5.0 ** 2
    cov = [[p + e, p], [p, p]]  # channel 0: the copy; channel 1: the baro+INS channel
    s0, w = _fused(cov)
    assert K_FF * s0 < 1.0
    vpl, limit = protection_level(s0, cov, w, K_FF, K_FA, K_MD)
    assert limit == 1 and vpl > K_MD * 5.0
    # the same two channels with the copy's opening gone are checked as well as two independent ones
    vpl_tight, _ = protection_level(*_fused([[p, 0.0], [0.0, p]])[:1], [[p, 0.0], [0.0, p]], [0.5, 0.5],
                                    K_FF, K_FA, K_MD)
    assert vpl_tight < 4.0 < vpl


def test_a_third_channel_lowers_the_level_of_the_other_two():
    a = [[0.25, 0.0], [0.0, 1.0]]
    b = [[0.25, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 0.25]]
    s_a, w_a = _fused(a)
    s_b, w_b = _fused(b)
    assert protection_level(s_b, b, w_b, K_FF, K_FA, K_MD)[0] < protection_level(s_a, a, w_a, K_FF, K_FA, K_MD)[0]


def test_non_blue_weights_are_read_as_given():
    """With the paper's arithmetic mean the separation is that of the mean."""
    cov = [[0.25, 0.0], [0.0, 4.0]]
    pl = separation_levels(cov, [0.5, 0.5], K_FA, K_MD)
    # without channel 0: Delta = 0.5 h0 - 0.5 h1, var = 0.25 (0.25 + 4)
    assert pl[0] == pytest.approx(K_FA * math.sqrt(0.25 * 4.25) + K_MD * 2.0)


def test_subset_weights_are_the_subsets_blue():
    import random

    from mavnav.monitor.protection import _subset_weights

    rnd = random.Random(7)
    for _ in range(50):
        a = [[rnd.gauss(0, 1) for _ in range(3)] for _ in range(3)]
        cov = [[sum(a[i][k] * a[j][k] for k in range(3)) + (0.1 if i == j else 0.0) for j in range(3)]
               for i in range(3)]
        for drop in range(3):
            keep = [k for k in range(3) if k != drop]
            _, _, w = fuse_heights([0.0, 0.0], [[cov[i][j] for j in keep] for i in keep], True)
            got = _subset_weights(cov, drop)
            assert got[drop] == 0.0
            assert [got[k] for k in keep] == pytest.approx(w, rel=1e-9, abs=1e-12)


def test_a_subset_without_the_baro_is_no_better_than_its_own_sensor():
    """An aux channel that takes the baro's changes, pinned to 0.5 m by them,
    with a sensor of 10 m: the baro's fault moves it too, so the subset without
    the baro is held to the sensor's own 10 m (k_md * 10 m at least); without
    the lean the same channels give a level of a few metres."""
    cov = [[0.25, 0.2], [0.2, 0.25]]  # channel 0: the aux channel; channel 1: the baro+INS channel
    s0, w = _fused(cov)
    plain = separation_levels(cov, w, K_FA, K_MD)
    leaned = separation_levels(cov, w, K_FA, K_MD, lean=1, own_var=[100.0, 0.0])
    assert plain[1] < 4.0
    assert leaned[1] >= K_MD * 10.0
    assert leaned[0] == plain[0]  # the aux channel's own fault: the baro+INS subset does not lean on it
    # the closed form: the subset is channel 0 alone, its variance plus its sensor's
    sd_delta = math.sqrt(_quad_delta(cov, w, [1.0, 0.0]))
    assert leaned[1] == pytest.approx(K_FA * sd_delta + K_MD * math.sqrt(0.25 + 100.0))
    vpl, limit = protection_level(s0, cov, w, K_FF, K_FA, K_MD, lean=1, own_var=[100.0, 0.0])
    assert limit == 1 and vpl == pytest.approx(leaned[1])


def _quad_delta(cov, w, wi):
    d = [a - b for a, b in zip(w, wi)]
    return sum(d[i] * d[j] * cov[i][j] for i in range(len(d)) for j in range(len(d)))
