"""The ULog bulk reader's fast paths against their references: the compiled row gather
(:func:`~mavnav.ingest.onboard.ulog._gather_rows`) copies the same bytes as its readable
form, and the subscriptions of topics not kept, read without pyulog's class when their
format is shown safe (:class:`~mavnav.ingest.onboard.ulog._FormatCheck`), leave the same
state as pyulog's class; a decode through either is the same, also of damaged copies."""

from __future__ import annotations

import os

import numpy as np
import pytest

from mavnav.ingest.onboard import ulog as ulog_mod
from mavnav.ingest.onboard.ulog import _FormatCheck, _gather_rows, _gather_rows_reference, read_ulog
from tests.support.paths import SHARED_FLIGHTLOGS

pyulog = pytest.importorskip("pyulog")
ULog = pyulog.core.ULog


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


def _reference_others(monkeypatch):
    light = ulog_mod._other_messages
    monkeypatch.setattr(ulog_mod, "_other_messages", lambda *a: light(*a, light=False))


@pytest.mark.realdata
@pytest.mark.parametrize("name", ["frs_motor_failure_hexa.ulg", "aut_quadrotor_local.ulg", "aut_plane_plexus.ulg"])
def test_unkept_subscriptions_read_light_leave_the_same_state(name, monkeypatch):
    p = SHARED_FLIGHTLOGS / name
    if not p.is_file():
        pytest.skip(f"committed flight log {p} not present")
    seen = []
    orig = ulog_mod._other_messages

    def spy(light):
        def other_messages(*a):
            out = orig(*a, light=light)
            seen.append([(x.offset, x.type, getattr(x.msg, "msg_id", None), getattr(x.msg, "message_name", None),
                          type(x.msg).__name__) for x in out[0]] + [out[1], out[2]])
            return out
        return other_messages

    monkeypatch.setattr(ulog_mod, "_other_messages", spy(True))
    fast = _digest(read_ulog(p))
    monkeypatch.setattr(ulog_mod, "_other_messages", spy(False))
    ref = _digest(read_ulog(p))
    assert fast == ref
    (a, b) = seen
    assert sum(t[4] == "_Unkept" for t in a[:-2]) > 20 and not any(t[4] == "_Unkept" for t in b[:-2])
    assert [t[:4] for t in a[:-2]] == [t[:4] for t in b[:-2]] and a[-2:] == b[-2:]


@pytest.mark.realdata
@pytest.mark.slow
def test_damaged_copies_decode_alike_with_light_subscriptions(tmp_path, monkeypatch):
    """Bytes flipped in the definitions and in the subscriptions: the same record (or the same error)."""
    p = SHARED_FLIGHTLOGS / "frs_motor_failure_hexa.ulg"
    if not p.is_file():
        pytest.skip(f"committed flight log {p} not present")
    raw = bytearray(p.read_bytes())
    subs = [m.start() for m in __import__("re").finditer(rb"A\x00", bytes(raw[:400_000]))][:400]
    rng = np.random.default_rng(11)
    spots = rng.integers(16, 60_000, 25).tolist() + [int(rng.choice(subs)) + int(rng.integers(-2, 12))
                                                     for _ in range(25)]
    differ = 0
    for k, at in enumerate(spots):
        bad = bytearray(raw)
        bad[at] ^= 0xFF if k % 2 else 0x01
        f = tmp_path / f"flip{k}.ulg"
        f.write_bytes(bytes(bad))

        def run():
            try:
                return _digest(read_ulog(f))
            except Exception as exc:  # the same refusal on both sides
                return repr(exc)

        with monkeypatch.context() as m:
            fast = run()
            _reference_others(m)
            ref = run()
        assert fast == ref, at
        differ += fast != _digest(read_ulog(p))
        os.remove(f)
    assert differ > 5  # the flips did damage


class _Fmt:
    def __init__(self, *fields):
        self.fields = list(fields)


def _pyulog_parses(formats, name) -> bool:
    data = bytes([0, 7, 0]) + name.encode()
    try:
        ULog._MessageAddLogged(data, ULog._MessageHeader(), formats)
        return True
    except Exception:
        return False


FORMATS = {
    "ok": _Fmt(("uint64_t", 0, "timestamp"), ("float", 3, "xyz"), ("inner", 2, "pair"), ("uint8_t", 0, "_padding0")),
    "inner": _Fmt(("int16_t", 0, "a"), ("double", 0, "b")),
    "missing_nested": _Fmt(("uint64_t", 0, "timestamp"), ("nowhere", 0, "x")),
    "cycle": _Fmt(("uint64_t", 0, "timestamp"), ("cycle", 0, "again")),
    "duplicate": _Fmt(("uint64_t", 0, "timestamp"), ("float", 0, "x"), ("float", 0, "x")),
    "dotted": _Fmt(("uint64_t", 0, "timestamp"), ("float", 0, "a.b")),
    "huge": _Fmt(("uint64_t", 0, "timestamp"), ("wide", 0xFFFF, "w")),
    "wide": _Fmt(("float", 0xFFFF, "v")),
}


@pytest.mark.parametrize("name", list(FORMATS) + ["not_a_format"])
def test_format_check_says_safe_only_where_pyulog_parses(name):
    safe = _FormatCheck(FORMATS, ULog._UNPACK_TYPES).ok(name)
    assert safe == (name in ("ok", "inner", "wide"))
    if safe:
        assert _pyulog_parses(FORMATS, name)
    elif name not in ("dotted", "huge"):  # refused by the check, and pyulog raises too (those two it parses, slowly)
        assert not _pyulog_parses(FORMATS, name)
