"""``frames.slerp`` (written out for speed) gives the very floats of its readable reference."""

from __future__ import annotations

import math
import random

import pytest

from mavnav.frames import slerp, slerp_reference


def _unit(rng: random.Random):
    q = [rng.gauss(0.0, 1.0) for _ in range(4)]
    n = math.sqrt(sum(c * c for c in q))
    return tuple(c / n for c in q)


@pytest.mark.parametrize("seed", range(5))
def test_slerp_equals_reference_bit_for_bit(seed):
    rng = random.Random(seed)
    for _ in range(2000):
        q0 = _unit(rng)
        # far apart, close (the linear branch), opposite hemispheres (the sign flip)
        kind = rng.randrange(3)
        if kind == 0:
            q1 = _unit(rng)
        else:
            q1 = tuple(c + rng.gauss(0.0, 1e-3) for c in q0)
            if kind == 2:
                q1 = tuple(-c for c in q1)
        frac = rng.choice([0.0, 1.0, rng.random()])
        assert slerp(q0, q1, frac) == slerp_reference(q0, q1, frac)


def test_slerp_endpoints():
    q0, q1 = (1.0, 0.0, 0.0, 0.0), (math.cos(0.5), math.sin(0.5), 0.0, 0.0)
    assert slerp(q0, q1, 0.0) == pytest.approx(q0)
    assert slerp(q0, q1, 1.0) == pytest.approx(q1)
