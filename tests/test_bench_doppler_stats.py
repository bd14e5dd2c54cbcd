"""bench/doppler_stats.py: the baro's scale against the Doppler (the number
behind monitor.baro_doppler_scale_frac, BENCHMARKS.md session 23)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bench import doppler_stats as ds


def _climbs(scale: float, t_end_s: float = 60.0):
    """Climbs and descents at 1 m/s between hovers, GNSS at 5 Hz; the baro
    moves ``scale`` times the Doppler's distance."""
    t = np.arange(0.0, t_end_s, 0.2)
    v = np.where((t % 20.0) < 5.0, 1.0, np.where((t % 20.0) >= 10.0, np.where((t % 20.0) < 15.0, -1.0, 0.0), 0.0))
    h = np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * np.diff(t))])
    return ds._window_diffs(t, h, v, scale * h, 10.0)


@pytest.mark.parametrize("scale", [0.85, 1.0, 1.1])
def test_the_baro_scale_is_the_slope_of_the_reading_on_the_distance_moved(scale):
    r = _climbs(scale)
    assert np.abs(r["disp"]).max() >= ds.MIN_MOVED_M
    assert ds.baro_scale(r) == pytest.approx(scale - 1.0, abs=1e-9)


def test_a_flight_that_never_moves_far_has_no_scale():
    t = np.arange(0.0, 60.0, 0.2)
    v = 0.1 * np.sin(t)  # 0.1 m up and down
    h = np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * np.diff(t))])
    r = ds._window_diffs(t, h, v, 0.5 * h, 10.0)
    assert r["disp"].size > 0 and math.isnan(ds.baro_scale(r))
