"""The ULog bulk reader's compiled row gather (:func:`~mavnav.ingest.onboard.ulog._gather_rows`)
copies the same bytes as its readable reference, and a decode through either is the same."""

from __future__ import annotations

import numpy as np
import pytest

from mavnav.ingest.onboard import ulog as ulog_mod
from mavnav.ingest.onboard.ulog import _gather_rows, _gather_rows_reference, read_ulog
from tests.support.paths import SHARED_FLIGHTLOGS

pytest.importorskip("pyulog")


def test_gather_matches_reference_on_random_rows():
    rng = np.random.default_rng(7)
    buf = rng.integers(0, 256, 5000, dtype=np.uint8)
    for item in (1, 8, 37, 120):
        starts = rng.integers(0, buf.size - item + 1, 300).astype(np.int64)
        fast = _gather_rows(buf, starts, item)
        ref = _gather_rows_reference(buf, starts, item)
        assert fast.dtype == ref.dtype == np.uint8 and fast.shape == ref.shape == (300, item)
        assert np.array_equal(fast, ref)
    starts = np.array([0, buf.size - 10], dtype=np.int64)
    assert not np.array_equal(_gather_rows(buf, starts, 10), _gather_rows(buf, starts[::-1].copy(), 10))
    assert _gather_rows(buf, np.zeros(0, np.int64), 8).shape == (0, 8)


def test_gather_refuses_rows_beyond_the_buffer():
    buf = np.arange(100, dtype=np.uint8)
    with pytest.raises(IndexError):
        _gather_rows(buf, np.array([95], dtype=np.int64), 8)


def _digest(rec) -> list:
    out = [rec.format, rec.firmware, rec.vehicle, rec.home_alt_msl_m, rec.origin_alt_msl_m, rec.messages,
           rec.damage, rec.bytes_read]
    for key in ("imu", "attitude", "baro", "gnss", "rangefinder", "autopilot"):
        s = getattr(rec, key)
        out.append(None if s is None else {k: (v.tobytes() if isinstance(v, np.ndarray) else v)
                                           for k, v in vars(s).items()})
    return out


@pytest.mark.realdata
@pytest.mark.parametrize("name", ["frs_motor_failure_hexa.ulg", "aut_quadrotor_local.ulg"])
def test_decode_with_the_reference_gather_is_the_same(name, monkeypatch):
    p = SHARED_FLIGHTLOGS / name
    if not p.is_file():
        pytest.skip(f"committed flight log {p} not present")
    fast = _digest(read_ulog(p))
    monkeypatch.setattr(ulog_mod, "_gather_rows", _gather_rows_reference)
    ref = _digest(read_ulog(p))
    assert fast[3] is not None or fast[5] is not None
    assert fast == ref
