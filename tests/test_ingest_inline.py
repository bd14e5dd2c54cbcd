"""The normaliser's inline hot paths (``_boot_ms``, ``_imu_usec``) give the
same stream of samples and events as their references, which go through
:class:`~mavnav.ingest.timebase.TimeBase`'s steps."""

from __future__ import annotations

from pathlib import Path

import pytest

from mavnav.config import IngestConfig
from mavnav.ingest import TlogSource
from mavnav.ingest.normaliser import Normaliser

REPO = Path(__file__).resolve().parents[1]
SHARED = REPO.parent / "shared" / "tlogs"
LOGS = sorted((REPO / "sitl_logs").glob("*.tlog"))[:3] + [
    p for p in (SHARED / "other" / "copter_sitl_speedup_clock_skew.tlog",
                SHARED / "other" / "copter_sitl_mixed_v1_v2.tlog",
                SHARED / "real" / "dronekit_copter_2015.tlog") if p.exists()]


def _stream(path: Path) -> tuple[list[str], dict]:
    src = TlogSource(path, IngestConfig())
    out = [repr(s) for s in src]
    return out, src.stats.to_dict()


@pytest.mark.parametrize("path", [pytest.param(p, marks=pytest.mark.slow) if p.name == "dronekit_copter_2015.tlog"
                                  else p for p in LOGS], ids=lambda p: p.name)  # the long real flight is slow
def test_inline_time_paths_match_their_references(path, monkeypatch):
    fast = _stream(path)
    monkeypatch.setattr(Normaliser, "_boot_ms", Normaliser._boot_ms_reference)
    monkeypatch.setattr(Normaliser, "_imu_usec", Normaliser._imu_usec_reference)
    ref = _stream(path)
    assert len(fast[0]) == len(ref[0]) > 0
    assert fast[0] == ref[0]
    assert fast[1] == ref[1]
