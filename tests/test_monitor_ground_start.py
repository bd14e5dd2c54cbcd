"""A start on the ground at the datum takes the vertical speed's prior of a
vehicle at rest (``filter.p0.vel_at_datum_m2ps2``).

With the general prior (4.5 m/s) the first differenced baro row, the baro's
sample-to-sample noise over 0.04 s, set the speed to 4-6 m/s on simulated
ground starts; the rows after it could not take it back for three seconds and
the fused height sat 2.5-3.3 m below the ground at 'nominal' while the baro
and the GNSS read it within 0.4 m (the grid flights of bench/integrity.py,
seeds 8 and 10, shipped model). Part of that was the IMU dropped before the
first epoch while the baro waited for its reference (fixed in session 21)."""

from __future__ import annotations

import numpy as np
import pytest

from bench import integrity as I
from bench import scoremetrics as sm
from mavnav.config import SensorsConfig, config_from_dict
from mavnav.pipeline import run
from mavnav.sim import scenario_from_dict, simulate

pytestmark = pytest.mark.slow


def _fly(seed: int, p0: dict, white_prior_m=None):
    b = I.grid_flight(seed)
    res = simulate(scenario_from_dict(b), seed=seed)
    sink = I._Collect()
    sensors = SensorsConfig().model_dump()
    if white_prior_m is not None:
        sensors["baro"]["white_prior_m"] = white_prior_m
    run(I.ingest(res.tlog), config_from_dict({"sensors": sensors, "filter": {"p0": p0}}), [sink])
    t_truth = np.asarray(res.truth["t_s"], dtype=float)
    h_truth = np.asarray(res.truth["true_height_ref_m"], dtype=float)
    usable = np.isin(np.asarray(sink.overall), ["nominal", "caution"])
    err = np.abs(np.asarray(sink.h) - np.interp(sink.t, t_truth, h_truth))
    first = np.asarray(sink.t) < 5.0
    return float(np.max(err[usable & first], initial=0.0)), sm.misleading(
        sink.t, sink.h, sink.pl, sink.overall, t_truth, h_truth)[0]


@pytest.mark.parametrize("seed", [8, 10])
def test_a_ground_start_does_not_take_its_speed_from_baro_noise(seed):
    """No hazardous output (3 m while usable) in the first 5 s, and none
    beyond the protection level in the flight. (Seed 8's own baro wanders
    2.4 m on the ground in its first 3 s, and the output with it, to 2.3 m.)"""
    err_m, misleading_s = _fly(seed, {})
    assert err_m < 3.0
    assert misleading_s == 0.0


def test_with_the_general_prior_the_start_is_worse_where_the_first_rows_are_trusted():
    """Since the IMU waits with the baro for its reference instead of being
    dropped before the first epoch (session 21), the general prior is no
    longer hazardous on these seeds (seed 10: over 3 m -> 0.9 m). Where the
    first baro rows are trusted (no white noise passed before the baro is
    measured, as until session 25) it still lets them move the speed: seed 8
    sits 2.45 m off in its first 5 s against 1.79 m with the prior of a
    vehicle at rest. With the baro's white-noise prior (session 25,
    tests/test_baro_white_prior.py) the first rows no longer set the speed
    and either start stays within 1.6 m (1.03 m general, 1.53 m at rest:
    this seed's baro itself wanders 2.4 m on the ground)."""
    err_general_m, _ = _fly(8, {"vel_at_datum_m2ps2": 20.0}, white_prior_m=0.0)
    err_m, _ = _fly(8, {}, white_prior_m=0.0)
    assert err_general_m > err_m + 0.4
    for p0 in ({"vel_at_datum_m2ps2": 20.0}, {}):
        err_m, misleading_s = _fly(8, p0)
        assert err_m < 1.6 and misleading_s == 0.0
