"""One record walk (:mod:`mavnav.ingest.records`) for the tlog reader and the
fault injector: on a log with garbage between frames, a record with a good
CRC but a timestamp two days off, an unknown message in step and a truncated
tail, the injector's frames are the reader's, at the same offsets, and its
junk is exactly the bytes the reader skipped."""

from __future__ import annotations

import random
import struct

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from mavnav.ingest import wire
from mavnav.ingest.records import ALL_KNOWN, TS_JUMP_US
from mavnav.ingest.tlog_reader import TlogReader
from mavnav.sim.inject import split_tlog

T0_US = 1_700_000_000_000_000
STEP_US = 10_000
UNKNOWN_MSGID = 0x2B7A00  # in no dialect


def _frame(i: int, link) -> bytes:
    k = i % 3
    if k == 0:
        msg = mavlink.MAVLink_scaled_pressure_message(i, 1000.0 + i / 100, 0.0, 2000)
    elif k == 1:
        msg = mavlink.MAVLink_attitude_message(i, 0.01 * i, 0.1, 0.2, 0, 0, 0)
    else:
        msg = mavlink.MAVLink_heartbeat_message(2, 3, 0, 0, 4, 3)
    return bytes(msg.pack(link))


def _garbage(rng: random.Random) -> bytes:
    """Noise with start bytes in it, or a known id's header with a bad checksum,
    half the time behind a plausible timestamp."""
    body = bytearray(rng.randrange(256) for _ in range(rng.randrange(1, 30)))
    if rng.random() < 0.5:
        body.insert(rng.randrange(len(body) + 1), rng.choice((wire.STX_V1, wire.STX_V2)))
    else:
        body[:0] = bytes([wire.STX_V2, 20, 0, 0, 0, 1, 1, 29, 0, 0])
    ts = struct.pack(">Q", T0_US) if rng.random() < 0.5 else b""
    return ts + bytes(body)


def _log(seed: int):
    """The log's bytes, the number of good frames in it, and the bytes of its
    one unknown-message record."""
    rng = random.Random(seed)
    v2 = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    v1 = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    v1.WIRE_PROTOCOL_VERSION = "1.0"
    data, t_us, n = bytearray(), T0_US, 400
    unknown = struct.pack(">Q", T0_US) + bytes([wire.STX_V2, 3, 0, 0, 7, 1, 1, 0x00, 0x7A, 0x2B, 1, 2, 3, 0x11, 0x22])
    for i in range(n):
        t_us += STEP_US
        data += struct.pack(">Q", t_us) + _frame(i, v1 if i % 4 == 3 else v2)
        if rng.random() < 0.3:
            data += _garbage(rng)
        if i == n // 3:  # a good frame two days off: not plausible
            data += struct.pack(">Q", t_us - 2 * TS_JUMP_US) + _frame(i, v2)
        if i == n // 2:  # an unknown message, in step
            data += unknown
    last = struct.pack(">Q", t_us + STEP_US) + _frame(n, v2)
    return bytes(data) + last[:-5], n, len(unknown)


def _payload(data: bytes, start: int) -> bytes:
    f = start + 8
    head = wire.HEADER_LEN_V1 if data[f] == wire.STX_V1 else wire.HEADER_LEN_V2
    return data[f + head : f + head + data[f + 1]]


@pytest.mark.parametrize("seed", [1, 2, 3])
@pytest.mark.parametrize("chunk", [1, 1 << 20])  # the smallest chunk the reader takes, and its default
def test_reader_and_injector_see_the_same_frames(tmp_path, seed, chunk):
    data, n, unknown_bytes = _log(seed)
    path = tmp_path / "dirty.tlog"
    path.write_bytes(data)
    reader = TlogReader(path, ALL_KNOWN, chunk_size=chunk)
    seen = [it for it in reader if type(it) is tuple]
    records = split_tlog(data)
    frames = [r for r in records if r.is_frame]
    # the same frames: count, then offsets (the timestamp and payload at each)
    assert len(seen) == len(frames) == n == reader.frames - reader.unknown_frames
    assert reader.unknown_frames == 1 and reader.garbage_bytes > 0 and reader.truncated_bytes > 0
    at = [(int.from_bytes(data[r.start : r.start + 8], "big") / 1e6, r.msgid, r.sysid, r.compid,
           _payload(data, r.start)) for r in frames]
    assert at == seen
    # every byte in one record, in order; the junk is what the reader skipped
    assert records[0].start == 0 and records[-1].end == len(data)
    assert all(a.end == b.start for a, b in zip(records, records[1:]))
    junk = sum(r.end - r.start for r in records if not r.is_frame)
    assert junk == reader.garbage_bytes + reader.truncated_bytes + unknown_bytes
    assert not records[-1].is_frame and records[-1].start <= reader.truncated_at < records[-1].end
