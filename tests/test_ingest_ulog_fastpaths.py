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
from mavnav.ingest.onboard.ulog import (_FormatCheck, _fill_buffers, _fill_buffers_reference, _gather_rows,
                                        _gather_rows_reference, read_ulog)
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


class _Sub:
    """What :func:`_fill_buffers` reads of a pyulog subscription."""

    def __init__(self, item: int, extra: int, t_off: int):
        self.dtype = np.dtype((np.void, item))
        self.max_data_size = item + extra
        self.timestamp_offset = t_off
        self.buffer = bytearray()


class _U:
    _file_corrupt = False


def _fill(fn, buf, spec, known, d_ids, d_offs, d_sizes):
    subs = {i: _Sub(*a) for i, a in spec.items()}
    u = _U()
    off, ts = fn(u, buf, subs, known, d_ids, d_offs, d_sizes)
    return off.tolist(), off.dtype, ts.tolist(), ts.dtype, {i: bytes(s.buffer) for i, s in subs.items()}, u._file_corrupt


@pytest.mark.parametrize("seed", (1, 2, 3))
def test_one_pass_fill_matches_the_per_subscription_reference(seed):
    """Rows of several subscriptions interleaved, ids without one, rows before their
    subscription (not known), rows too short or too long: the same bytes per buffer,
    offsets, timestamps and corruption flag."""
    rng = np.random.default_rng(seed)
    spec = {3: (20, 0, 0), 7: (9, 3, 1), 40: (33, 8, 25)}  # msg_id -> (item, padding allowed, timestamp offset)
    ids = np.array([3, 7, 40, 5, 41], dtype=np.int64)
    n = 400
    d_ids = ids[rng.integers(0, ids.size, n)]
    d_sizes = np.array([spec.get(int(i), (12, 0, 0))[0] + 2 for i in d_ids], dtype=np.int64)
    d_sizes += rng.choice([0, 0, 0, 0, 2, -1, 9], n)  # some padded, some of the wrong size
    d_offs = np.cumsum(np.concatenate([[16], d_sizes[:-1] + 3])).astype(np.int64)
    buf = rng.integers(0, 256, int(d_offs[-1] + d_sizes[-1] + 3), dtype=np.uint8)
    known = rng.random(n) > 0.1
    got = _fill(_fill_buffers, buf, spec, known, d_ids, d_offs, d_sizes)
    want = _fill(_fill_buffers_reference, buf, spec, known, d_ids, d_offs, d_sizes)
    assert got == want
    assert want[5] and all(want[4].values())  # the case has corrupt rows and rows for every subscription
    clean = d_sizes == np.array([spec.get(int(i), (12, 0, 0))[0] + 2 for i in d_ids])
    assert _fill(_fill_buffers, buf, spec, known & clean, d_ids, d_offs, d_sizes)[5] is False
    # rows of one subscription swapped: the buffers differ (the comparison can fail)
    swapped = d_offs.copy()
    a, b = np.flatnonzero(known & (d_ids == 3) & clean)[:2]
    swapped[[a, b]] = swapped[[b, a]]
    assert _fill(_fill_buffers, buf, spec, known, d_ids, swapped, d_sizes)[4] != got[4]
    empty = np.zeros(0, dtype=np.int64)
    assert _fill(_fill_buffers, buf, spec, known[:0], empty, empty, empty) == \
        _fill(_fill_buffers_reference, buf, spec, known[:0], empty, empty, empty)


def _digest(rec) -> list:
    out = [rec.format, rec.firmware, rec.vehicle, rec.home_alt_msl_m, rec.origin_alt_msl_m, rec.messages,
           rec.damage, rec.bytes_read]
    for key in ("imu", "attitude", "baro", "gnss", "rangefinder", "autopilot"):
        s = getattr(rec, key)
        out.append(None if s is None else {k: (v.tobytes() if isinstance(v, np.ndarray) else v)
                                           for k, v in vars(s).items()})
    return out


@pytest.mark.realdata
@pytest.mark.parametrize("name,attr,reference", [
    (name, "_gather_rows", _gather_rows_reference)
    for name in ("frs_motor_failure_hexa.ulg", "aut_quadrotor_local.ulg")] + [
    (name, "_fill_buffers", _fill_buffers_reference)
    for name in ("frs_motor_failure_hexa.ulg", "aut_quadrotor_local.ulg", "aut_plane_plexus.ulg")])
def test_decode_with_the_reference_form_is_the_same(name, attr, reference, monkeypatch):
    """The compiled row gather and the one-pass buffer fill each give the decode
    their readable reference gives."""
    p = SHARED_FLIGHTLOGS / name
    if not p.is_file():
        pytest.skip(f"committed flight log {p} not present")
    fast = _digest(read_ulog(p))
    monkeypatch.setattr(ulog_mod, attr, reference)
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


def _last_timestamps_reference(start_ts, ro, rt):
    """The running maximum of the row timestamps in file order, built at once (as before)."""
    order = np.argsort(ro, kind="stable")
    ro, run_max = ro[order], np.maximum.accumulate(rt[order])

    def last_ts(o):
        j = int(np.searchsorted(ro, o))
        return max(start_ts, int(run_max[j - 1])) if j else start_ts

    return last_ts


def test_last_timestamps_built_lazily_give_the_same_times():
    rng = np.random.default_rng(5)
    for _ in range(200):
        n = int(rng.integers(0, 40))
        ro = rng.choice(5000, n, replace=False).astype(np.int64)
        rt = rng.integers(0, 2 ** 40, n).astype(np.uint64)
        start = int(rng.integers(0, 2 ** 40))
        got, want = ulog_mod._last_timestamps(start, ro, rt), _last_timestamps_reference(start, ro, rt)
        asks = [int(q) for q in rng.integers(0, 5100, 10)] + [int(o) for o in ro] + [10 ** 9, 0]
        rng.shuffle(asks)
        assert [got(q) for q in asks] == [want(q) for q in asks]
