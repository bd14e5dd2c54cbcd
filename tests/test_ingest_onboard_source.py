"""The onboard source's per-kind stream rule against the tlog's KindGuard.

:func:`mavnav.ingest.onboard.source._guard_series` applies
:meth:`mavnav.ingest.streams.KindGuard.check` to one kind's whole series at
once (compiled); both must give the same verdict and the same gap, to the
bit, on any series: duplicates, times going back, gaps long and short.
"""

from __future__ import annotations

import random

import numpy as np
import pytest

from mavnav.ingest.onboard.source import _VERDICT, _guard_series
from mavnav.ingest.streams import KindGuard


def _series(rng: random.Random, n: int) -> list[int]:
    t, out = rng.randrange(0, 10**9), []
    base = rng.choice([2_500, 5_000, 100_000, 500_000, 1_000_000])  # 400 Hz .. 1 Hz
    for _ in range(n):
        r = rng.random()
        if r < 0.03:
            pass  # the same time again
        elif r < 0.06:
            t -= rng.randrange(1, 3 * base)  # back in time
        elif r < 0.09:
            t += rng.randrange(base, max(40 * base, 5_000_000))  # a gap, or nearly one
        else:
            t += max(1, int(base * rng.uniform(0.5, 1.5)))
        out.append(t)
    return out


@pytest.mark.parametrize("seed", range(12))
def test_guard_series_equals_kind_guard(seed):
    rng = random.Random(seed)
    gap_min_s, gap_factor = rng.choice([0.5, 0.05, 2.0]), rng.choice([5.0, 1.5, 3.3])
    t = _series(rng, rng.choice([1, 2, 50, 3000]))
    guard = KindGuard(gap_min_s, gap_factor)
    expected = [guard.check("imu", 0, x) for x in t]
    verdict, gap_s = _guard_series(np.array(t, dtype=np.int64), float(gap_min_s * 1e6), float(gap_factor))
    got = [(_VERDICT.get(v, "ok"), g) for v, g in zip(verdict.tolist(), gap_s.tolist())]
    assert got == expected
    if len(t) > 100:  # the series exercise every branch
        kinds = {v for v, _ in expected}
        assert {"ok", "duplicate", "out_of_order"} <= kinds and any(g > 0 for _, g in expected)
