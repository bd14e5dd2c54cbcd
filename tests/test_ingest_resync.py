"""Garbage on the link never costs a valid frame: the stream reader (live links)
and the tlog reader resynchronise at the next candidate start byte, whatever the
garbage looks like (noise, start bytes with unknown message ids and large
lengths, bad checksums, fake timestamps), for MAVLink 1 and 2 frames encoded by
pymavlink; and over a real UDP socket on 127.0.0.1 every sample of a flight
arrives through garbage datagrams."""

from __future__ import annotations

import random
import socket
import struct
import threading
import time

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from mavnav.config import IngestConfig
from mavnav.ingest import LiveSource, TlogSource, wire
from mavnav.ingest.stream_reader import StreamReader
from mavnav.ingest.tlog_reader import TlogReader
from tests.support.live import no_recv, tlog_records
from tests.support.flightlog import FlightLog

ALL = frozenset(wire.MSG_NAME)
UNKNOWN_MSGID = 0x2B7A00  # in no dialect
T0_US = 1_700_000_000_000_000


def _frames(n, seed):
    """``n`` real frames (MAVLink 2, every fifth MAVLink 1) of the messages mavnav reads."""
    rng = random.Random(seed)
    mav2 = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    mav1 = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    mav1.WIRE_PROTOCOL_VERSION = "1.0"
    out = []
    for i in range(n):
        k = i % 5
        if k == 0:
            msg = mavlink.MAVLink_scaled_pressure_message(i, 1000 + rng.random(), 0.0, 2000)
        elif k == 1:
            msg = mavlink.MAVLink_attitude_message(i, rng.random(), 0.1, 0.2, 0, 0, 0)
        elif k == 2:
            msg = mavlink.MAVLink_heartbeat_message(2, 3, 0, 0, 4, 3)
        elif k == 3:
            msg = mavlink.MAVLink_gps_raw_int_message(i * 1000, 3, 473977000, 85455000, rng.randrange(10**6), 80, 120, 0, 0, 12)
        else:
            msg = mavlink.MAVLink_highres_imu_message(i, 0, 0, -9.8, 0, 0, 0, 0, 0, 0, 1000.0, 0, 0, 20.0, 7)
        out.append(bytes(msg.pack(mav1 if i % 5 == 4 else mav2)))
    return out


def _garbage(rng):
    """Noise that tempts the parser: random bytes, start bytes, frame headers with
    unknown message ids or a known id and a bad checksum, large lengths."""
    kind = rng.randrange(4)
    body = bytearray(rng.randrange(256) for _ in range(rng.randrange(0, 30)))
    if kind == 0:  # noise with start bytes in it
        for _ in range(rng.randrange(1, 4)):
            body.insert(rng.randrange(len(body) + 1), rng.choice((wire.STX_V1, wire.STX_V2)))
        return bytes(body) or b"\xfd"
    plen = rng.choice((rng.randrange(256), 255, 200))
    if kind == 1:  # MAVLink 2 header, unknown id, length running over the frames behind it
        mid = UNKNOWN_MSGID + rng.randrange(256)
        head = bytes([wire.STX_V2, plen, 0, 0, rng.randrange(256), rng.randrange(1, 255), 1,
                      mid & 0xFF, (mid >> 8) & 0xFF, mid >> 16])
    elif kind == 2:  # MAVLink 2 header of a known id, bad checksum
        head = bytes([wire.STX_V2, plen, 0, 0, 0, 1, 1, 29, 0, 0])
    else:  # MAVLink 1 header of a known id
        head = bytes([wire.STX_V1, plen, 0, 1, 1, 30])
    return head + bytes(body)


def _key(frame):
    """(msgid, sysid, compid, payload) of an encoded frame, as the readers yield it."""
    if frame[0] == wire.STX_V2:
        return (frame[7] | frame[8] << 8 | frame[9] << 16, frame[5], frame[6], frame[10:10 + frame[1]])
    return (frame[5], frame[3], frame[4], frame[6:6 + frame[1]])


def _dirty(frames, rng, every=0.3):
    """(frame or garbage, is_frame) in stream order; garbage after about ``every`` of the frames."""
    out = []
    for f in frames:
        out.append((f, True))
        if rng.random() < every:
            out.append((_garbage(rng), False))
    out.append((_garbage(rng), False))
    return out


@pytest.mark.parametrize("seed", [1, 2, 3, 4])
def test_stream_reader_recovers_every_frame_through_garbage(seed):
    rng = random.Random(seed)
    frames = _frames(1500, seed)
    stream = b"".join(b for b, _ in _dirty(frames, rng))
    reader = StreamReader(ALL)
    got, pos = [], 0
    while pos < len(stream):  # arbitrary chunking, as a serial port delivers
        k = rng.randrange(1, 400)
        got += [it[1:] for it in reader.feed(stream[pos:pos + k], 0.0) if type(it) is tuple]
        pos += k
    assert got == [_key(f) for f in frames]
    assert reader.frames - reader.unknown_frames == len(frames) and reader.garbage_bytes > 0
    assert reader.unknown_frames <= 2  # garbage taken for an unknown message: rare, and harmless


def test_noise_start_byte_does_not_hold_up_the_frames_behind_it():
    frames = _frames(3, 7)
    reader = StreamReader(ALL)
    # a start byte promising 255 bytes, then three good frames: all out at once
    out = reader.feed(bytes([wire.STX_V2, 255, 0, 0, 0, 1, 1, 0x00, 0x7A, 0x2B]) + b"".join(frames), 0.0)
    assert [it[1:] for it in out if type(it) is tuple] == [_key(f) for f in frames]


def test_a_real_unknown_message_in_step_is_skipped_whole():
    frames = _frames(2, 3)
    unknown = bytes([wire.STX_V2, 3, 0, 0, 7, 1, 1, 0x00, 0x7A, 0x2B, 0xFD, 0xFE, 0xFD, 0x11, 0x22])
    reader = StreamReader(ALL)
    out = reader.feed(frames[0] + unknown + frames[1], 0.0)
    assert [it[1:] for it in out if type(it) is tuple] == [_key(f) for f in frames]
    assert reader.unknown_frames == 1 and reader.garbage_bytes == 0


def _tlog(tmp_path, seed, *, fake_timestamps):
    rng = random.Random(seed)
    frames = _frames(1500, seed)
    data = bytearray()
    t_us = T0_US
    for chunk, is_frame in _dirty(frames, rng):
        if is_frame:
            t_us += 10_000
            data += struct.pack(">Q", t_us) + chunk
        else:  # garbage, in half the cases behind a plausible timestamp
            data += (struct.pack(">Q", t_us) if fake_timestamps and rng.random() < 0.5 else b"") + chunk
    path = tmp_path / f"garbage{seed}.tlog"
    path.write_bytes(bytes(data))
    return path, frames


@pytest.mark.parametrize("seed,fake_timestamps,chunk", [(1, False, 1 << 20), (2, True, 1 << 20), (3, True, 700), (4, False, 700)])
def test_tlog_reader_recovers_every_frame_through_garbage(tmp_path, seed, fake_timestamps, chunk):
    path, frames = _tlog(tmp_path, seed, fake_timestamps=fake_timestamps)
    reader = TlogReader(path, ALL, chunk_size=chunk)
    got = [it[1:] for it in reader if type(it) is tuple]
    assert got == [_key(f) for f in frames]
    assert reader.frames - reader.unknown_frames == len(frames) and reader.unknown_frames <= 2


def test_live_udp_through_garbage_datagrams_loses_no_sample(tmp_path):
    """A flight sent over real UDP with a garbage datagram (or garbage inside a
    datagram) after every few frames yields exactly the file's samples."""
    f = FlightLog(tmp_path / "noisy.tlog")
    f.fly(0, 4, height_fn=lambda t: t)
    path = f.close()
    cfg = IngestConfig(link_timeout_s=30.0)
    want = list(TlogSource(path, cfg))
    recs = tlog_records(path)
    rng = random.Random(5)
    src = LiveSource("udpin:127.0.0.1:0", cfg)
    addr = src.local_address
    got = []

    def send():
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        sent = missing = 0
        for i, (_, frame) in enumerate(recs):
            roll = rng.random()
            if roll < 0.15:
                sock.sendto(_garbage(rng), addr)  # a datagram of garbage
                sock.sendto(frame, addr)
            elif roll < 0.30:
                sock.sendto(_garbage(rng) + frame, addr)  # garbage in front, same datagram
            elif roll < 0.45:
                sock.sendto(frame + _garbage(rng), addr)  # garbage behind, same datagram
            else:
                sock.sendto(frame, addr)
            sent += 1
            if sent % 25 == 0:
                missing += _drain_to(sent - 50 - missing)  # flow control, not pacing: stay within the socket buffer
        _drain_to(sent - missing)
        sock.close()
        src.close()

    def _drain_to(k):
        """Wait until the reader has accepted ``k`` frames; if it stops short (frames
        lost), give up after 0.2 s without progress and return the shortfall."""
        last, since = -1, time.monotonic()
        while src._reader.frames < k:
            now_frames = src._reader.frames
            if now_frames != last:
                last, since = now_frames, time.monotonic()
            elif time.monotonic() - since > 0.2:
                return k - now_frames
            time.sleep(0.001)
        return 0

    sender = threading.Thread(target=send, daemon=True)
    sender.start()
    for s in src:
        got.append(s)
    sender.join(10)
    assert len(no_recv(want)) > 500
    assert no_recv(got) == no_recv(want)
    assert src.stats.garbage_bytes > 0


def test_tlog_noise_near_the_end_is_not_taken_for_truncation(tmp_path):
    """A start byte promising 250 bytes just before the last records of a file is
    noise, not a record cut short: the records behind it are read."""
    frames = _frames(10, 9)
    recs = [struct.pack(">Q", T0_US + 10_000 * i) + f for i, f in enumerate(frames)]
    noise = struct.pack(">Q", T0_US + 65_000) + bytes([wire.STX_V2, 250, 0, 0, 0, 1, 1, 29, 0, 0])
    path = tmp_path / "noisy_end.tlog"
    path.write_bytes(b"".join(recs[:7]) + noise + b"".join(recs[7:]))
    reader = TlogReader(path, ALL)
    got = [it[1:] for it in reader if type(it) is tuple]
    assert got == [_key(f) for f in frames] and reader.truncated_bytes == 0
    # and a file that really ends mid-record still says so
    path.write_bytes(b"".join(recs) + recs[0][:20])
    reader = TlogReader(path, ALL)
    assert len([it for it in reader if type(it) is tuple]) == 10 and reader.truncated_bytes == 20
