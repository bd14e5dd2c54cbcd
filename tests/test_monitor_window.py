"""The innovation tests' rejection count over a sliding window of vehicle time."""

from __future__ import annotations

import pytest

from mavnav.monitor.window import RejectionWindow


@pytest.mark.unit
def test_rejections_are_counted_over_the_window_and_forgotten_after_it():
    w = RejectionWindow(5.0)
    for t_s, rejected in [(0.0, True), (1.0, False), (2.0, True), (3.0, True)]:
        w.push(int(t_s * 1e6), rejected)
    assert w.rejected == 3
    w.expire(int(5.0 * 1e6))  # the rejection at 0 s is exactly one window old: gone
    assert w.rejected == 2
    w.push(int(7.5 * 1e6), False)  # 2 s is gone; 3 s is not
    assert w.rejected == 1
    w.clear()
    assert w.rejected == 0
    w.push(int(8.0 * 1e6), True)
    assert w.rejected == 1
