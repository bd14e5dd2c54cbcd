"""The baro channel's feedback takes only aux channels clearly consistent with
it now (``HypothesisLogic._feedback``).

A rangefinder frozen in a descent leads its channel away from the others for
the 2.5 s its test needs. Fed back into the baro channel while its tracker was
still nominal (0.7 m, 3 sigma off the baro channel), it carried the fused
height and the subset without it along, and the error outran the protection
level (the simulated frozen descent, seed 3: 0.2 s with the shipped model,
1.2 s with a 1 % rangefinder)."""

from __future__ import annotations

import numpy as np
import pytest

from bench import integrity as I
from bench import scoremetrics as sm
from mavnav.config import SensorsConfig, config_from_dict
from mavnav.monitor import hypotheses
from mavnav.pipeline import run
from mavnav.sim import scenario_from_dict, simulate

pytestmark = pytest.mark.slow

FAMILY = {f.name: f for f in I.families()}["rng_frozen_descent"]


def _audit(seed: int, rng_scale_frac: float):
    b = FAMILY.build(seed, {})
    res = simulate(scenario_from_dict(b["scenario"]), seed=seed)
    samples = I.ingest(res.tlog)
    sensors = SensorsConfig().model_dump()
    sensors["rangefinder"]["scale_sigma_frac"] = rng_scale_frac
    sink = I._Collect()
    # the descent joins in the air over ground at the reference: given as known, so the
    # rangefinder's absolute height is in the output and its frozen readings can mislead
    run(samples, config_from_dict({"sensors": sensors, "monitor": {"ground_at_reference": True}}), [sink])
    return sm.misleading(sink.t, sink.h, sink.pl, sink.overall, np.asarray(res.truth["t_s"], dtype=float),
                         np.asarray(res.truth["true_height_ref_m"], dtype=float))


@pytest.mark.parametrize("seed", [1, 2, 3, 4])
@pytest.mark.parametrize("rng_scale_frac", [0.03, 0.01])
def test_the_protection_level_bounds_a_frozen_rangefinder(seed, rng_scale_frac):
    misleading_s, usable_s = _audit(seed, rng_scale_frac)
    assert usable_s > 5.0  # the descent is short and the fault takes a third of it
    assert misleading_s == 0.0


def test_without_the_consistency_rule_the_fault_is_fed_back(monkeypatch):
    # every aux channel agreeing with the baro channel, however far apart: the rule taken out
    monkeypatch.setattr(hypotheses, "diff_sigmas", lambda bank, *floor: np.full(3, np.inf))
    misleading_s, _ = _audit(3, 0.01)
    assert misleading_s > 0.5
