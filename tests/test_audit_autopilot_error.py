"""The audit's fused-against-autopilot figures: the RMS and its split into the
constant part (the two heights' datums) and what varies, checked against the
same epochs' differences summed independently."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mavnav.audit import audit_file
from mavnav.config import load_config
from mavnav.sinks.base import Sink
from tests.support.paths import SITL_LOGS


class _Diffs(Sink):
    name = "diffs"

    def __init__(self):
        self.d = []

    def epoch(self, r):
        self.d.append(r.height_fused_m - r.autopilot_height_ref_m)


@pytest.mark.simulation
@pytest.mark.parametrize("log", [pytest.param("px4_landing_nominal.tlog", marks=pytest.mark.slow),
                                 "ardupilot_rng_dropout.tlog"])
def test_fused_against_autopilot_splits_into_datum_offset_and_spread(log):
    diffs = _Diffs()
    r = audit_file(SITL_LOGS / log, load_config(None), extra_sinks=[diffs])
    d = np.asarray(diffs.d, float)
    d = d[np.isfinite(d)]
    assert d.size > 100
    assert r["fused_vs_autopilot_rms_m"] == pytest.approx(math.sqrt(np.mean(d * d)), abs=1e-4)
    assert r["fused_vs_autopilot_mean_m"] == pytest.approx(float(np.mean(d)), abs=1e-4)
    assert r["fused_vs_autopilot_sd_m"] == pytest.approx(float(np.std(d)), abs=1e-4)
    assert r["fused_vs_autopilot_max_m"] == pytest.approx(float(np.max(np.abs(d))), abs=1e-4)
