"""Bad input is counted and reported, never raised: garbage, CRC errors,
truncation, unknown messages, NaN and impossible values; and a file that is
not a tlog is refused with one line naming it."""

from __future__ import annotations

import math
import random
import struct

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mavnav.config import IngestConfig
from mavnav.errors import InputError
from mavnav.ingest import TlogSource, expand_tlog_paths
from mavnav.samples import BaroHeight, Rejected, SpecificForceUp
from tests.support.flightlog import P_GROUND_PA, UNIX0, FlightLog, collect, of, rejected

CFG = {"baro_reference": {"source": "config", "value": P_GROUND_PA}}


@pytest.fixture(scope="module")
def ingest_clean_log(tmp_path_factory):
    path = tmp_path_factory.mktemp("clean") / "clean.tlog"
    f = FlightLog(path)
    f.fly(0, 4, height_fn=lambda t: t)
    return f.close()


def _records(path):
    """Split a tlog we wrote into (timestamp, frame) records."""
    data = path.read_bytes()
    out, pos = [], 0
    while pos < len(data):
        stx, plen = data[pos + 8], data[pos + 9]
        flen = (6 + plen + 2) if stx == 0xFE else (10 + plen + 2)
        out.append(data[pos:pos + 8 + flen])
        pos += 8 + flen
    return out


def _measurements(items):
    return [s for s in items if not isinstance(s, Rejected)]


@pytest.mark.parametrize("content", [b"", b"hello, this is plainly text\n" * 100, bytes(range(256)) * 10])
def test_not_a_tlog_is_one_line_input_error_naming_the_file(tmp_path, content):
    p = tmp_path / "notes.tlog"
    p.write_bytes(content)
    with pytest.raises(InputError) as ei:
        TlogSource(p, IngestConfig())
    msg = str(ei.value)
    assert str(p) in msg and "\n" not in msg


def test_missing_file_and_directory_are_input_errors(tmp_path):
    with pytest.raises(InputError, match="no such file"):
        TlogSource(tmp_path / "absent.tlog", IngestConfig())
    with pytest.raises(InputError, match="directory"):
        TlogSource(tmp_path, IngestConfig())


def test_expand_tlog_paths(tmp_path, ingest_clean_log):
    (tmp_path / "b").mkdir()
    (tmp_path / "b" / "z.tlog").write_bytes(ingest_clean_log.read_bytes())
    (tmp_path / "b" / "a.TLOG").write_bytes(b"x")
    (tmp_path / "b" / "readme.txt").write_text("x")
    got = expand_tlog_paths([tmp_path / "b", ingest_clean_log, tmp_path / "b" / "z.tlog"])
    # argument order; a directory's logs sorted in its place; no file twice
    assert got == [tmp_path / "b" / "a.TLOG", tmp_path / "b" / "z.tlog", ingest_clean_log]
    assert expand_tlog_paths([ingest_clean_log, tmp_path / "b"])[0] == ingest_clean_log
    with pytest.raises(InputError, match="nope: no such file or directory"):
        expand_tlog_paths([tmp_path / "nope"])


def test_garbage_between_frames_loses_no_good_frame(tmp_path, ingest_clean_log):
    recs = _records(ingest_clean_log)
    rng = random.Random(1)
    out = bytearray()
    for i, r in enumerate(recs):
        out += r
        if i % 50 == 7:
            junk = bytes(rng.randrange(256) for _ in range(rng.randrange(1, 40)))
            out += junk + b"\xfe\xfd"  # with start bytes to tempt the parser
    p = tmp_path / "garbage.tlog"
    p.write_bytes(bytes(out))
    clean, _ = collect(ingest_clean_log, **CFG)
    dirty, st = collect(p, **CFG)
    assert _measurements(dirty) == _measurements(clean)
    assert st.rejected["garbage"] == len([i for i in range(len(recs)) if i % 50 == 7])
    assert st.garbage_bytes > 0


def test_crc_error_drops_only_that_frame(tmp_path, ingest_clean_log):
    recs = _records(ingest_clean_log)
    # corrupt one barometer frame's payload
    idx = next(i for i, r in enumerate(recs[100:], 100) if r[8] == 0xFD and r[15] == 29)
    bad = bytearray(recs[idx])
    bad[8 + 10 + 5] ^= 0x40
    p = tmp_path / "crc.tlog"
    p.write_bytes(b"".join(recs[:idx]) + bytes(bad) + b"".join(recs[idx + 1:]))
    clean, _ = collect(ingest_clean_log, **CFG)
    dirty, st = collect(p, **CFG)
    assert st.rejected["crc"] == 1
    assert len(of(dirty, BaroHeight)) == len(of(clean, BaroHeight)) - 1
    assert len(of(dirty, SpecificForceUp)) == len(of(clean, SpecificForceUp))


@pytest.mark.parametrize("cut", [1, 5, 9, 20, 33])
def test_truncated_file_is_reported_not_raised(tmp_path, ingest_clean_log, cut):
    data = ingest_clean_log.read_bytes()
    p = tmp_path / "cut.tlog"
    p.write_bytes(data[:-cut])
    items, st = collect(p, **CFG)
    assert st.rejected["truncated"] + st.rejected["garbage"] >= 1
    assert len(_measurements(items)) >= len(_measurements(collect(ingest_clean_log, **CFG)[0])) - 2


def test_unknown_message_is_counted(tmp_path):
    f = FlightLog(tmp_path / "unknown.tlog")
    f.heartbeat(0)
    f.pressure(0.0, P_GROUND_PA)
    # a well-formed MAVLink 2 frame with a message id no dialect knows
    f.w.write_raw(bytes([0xFD, 3, 0, 0, 7, 1, 1, 0x7A, 0x2B, 0x00, 1, 2, 3, 0x11, 0x22]), UNIX0 + 0.05)
    f.pressure(0.1, P_GROUND_PA)
    items, st = collect(f.close(), **CFG)
    assert st.rejected["unknown_message"] == 1
    assert len(of(items, BaroHeight)) == 2


def test_nan_and_impossible_values_are_refused(tmp_path):
    f = FlightLog(tmp_path / "nan.tlog")
    f.heartbeat(0)
    f.attitude(0.0)
    f.highres(0.01, (0.0, math.nan, -9.8))
    f.highres(0.02, (math.inf, 0.0, -9.8))
    f.highres(0.03, (0.0, 0.0, -9.8))
    f.attitude(0.04, math.nan, 0.0)
    f.attitude(0.05)
    f.pressure(0.06, math.nan)
    f.pressure(0.07, 0.0)  # zero pressure
    f.pressure(0.08, -5.0)
    f.pressure(0.09, P_GROUND_PA)
    f.lpn(0.1, math.nan)
    items, st = collect(f.close(), **CFG)
    assert len(of(items, SpecificForceUp)) == 1 and len(of(items, BaroHeight)) == 1
    assert st.rejected["nan"] == 5 and st.rejected["impossible"] == 2
    for r in rejected(items):
        assert r.detail


def test_mixed_mavlink1_and_mavlink2_in_one_file(tmp_path):
    a, b = FlightLog(tmp_path / "a.tlog", mavlink1=True), FlightLog(tmp_path / "b.tlog")
    a.fly(0, 2, imu="scaled_imu")
    b.fly(0, 2, imu="scaled_imu")
    ra, rb = _records(a.close()), _records(b.close())
    mixed = [ra[i] if i % 2 else rb[i] for i in range(len(ra))]
    p = tmp_path / "mixed.tlog"
    p.write_bytes(b"".join(mixed))
    items, st = collect(p)
    assert {r[8] for r in mixed} == {0xFE, 0xFD}
    assert st.samples["imu"] == 200 and st.samples["baro"] == 40 and not st.rejected


# ------------------------------------------------------------------ fuzzing

_FUZZ = settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])


def _drain(path):
    try:
        src = TlogSource(path, IngestConfig())
    except InputError:
        return None  # refused up front, as a non-tlog must be
    items = list(src)
    src.stats.to_dict()
    assert src.stats.rejected["internal_error"] == 0, [r.detail for r in items if getattr(r, "kind", "") == "internal_error"]
    return items


@_FUZZ
@given(data=st.binary(min_size=0, max_size=3000))
def test_fuzz_random_bytes_never_raise(tmp_path, data):
    p = tmp_path / "rand.tlog"
    p.write_bytes(data)
    _drain(p)


@pytest.mark.slow
@_FUZZ
@given(cut=st.integers(min_value=0, max_value=30000), flips=st.lists(st.integers(0, 10**9), max_size=40))
def test_fuzz_truncated_and_bit_flipped_tlogs_never_raise(tmp_path, ingest_clean_log, cut, flips):
    data = bytearray(ingest_clean_log.read_bytes()[:30000])
    data = data[: max(0, len(data) - cut)]
    for f in flips:
        if data:
            data[(f // 8) % len(data)] ^= 1 << (f % 8)
    p = tmp_path / "flip.tlog"
    p.write_bytes(bytes(data))
    items = _drain(p)
    if items is not None:
        for s in items:
            if isinstance(s, SpecificForceUp):
                assert math.isfinite(s.f_up_mps2)


@pytest.mark.slow
@_FUZZ
@given(seed=st.integers(0, 2**32 - 1))
def test_fuzz_spliced_records_never_raise(tmp_path, ingest_clean_log, seed):
    rng = random.Random(seed)
    recs = _records(ingest_clean_log)[:600]
    out = bytearray()
    for r in recs:
        op = rng.random()
        if op < 0.05:
            continue  # dropped
        if op < 0.10:
            r = r[: rng.randrange(len(r))]  # cut short
        elif op < 0.15:
            r = struct.pack(">Q", rng.randrange(2**64)) + r[8:]  # wild timestamp
        elif op < 0.20:
            r = r + bytes(rng.randrange(256) for _ in range(rng.randrange(20)))
        out += r
    p = tmp_path / "splice.tlog"
    p.write_bytes(bytes(out))
    _drain(p)
