"""The tlog record walk: which bytes of a .tlog are MAVLink frames, and where they are.

A tlog record is an 8-byte big-endian Unix time in microseconds (receive
time) followed by one MAVLink v1 or v2 frame. The walk reads the file in
chunks (never whole) and accepts a record when its start byte is a MAVLink
start byte, its timestamp is plausible (:func:`plausible`: within a day of
the previous accepted record, or between 2000 and 2100 for the first), and
its CRC is correct (for every message id the dialect knows; unknown ids are
accepted only while the walk is in step, never to resynchronise on).
Anything else is skipped byte by byte until the next plausible record:
garbage, CRC failures and a truncated tail are counted and reported as
:class:`~mavnav.samples.Rejected` items, never raised.

Its two consumers: the tlog reader (:mod:`.tlog_reader`), which skips what
is not a frame, and the fault injector (:mod:`mavnav.sim.inject`), which
keeps every byte and asks for each frame's offsets (``offsets=True``): the
bytes between two accepted frames are its junk. Both therefore see the same
frames at the same offsets.
"""

from __future__ import annotations

import io
from pathlib import Path
from typing import Iterator, Optional, Union

from ..samples import Rejected
from . import wire

TS_MIN_US = 946_684_800_000_000  # 2000-01-01
TS_MAX_US = 4_102_444_800_000_000  # 2100-01-01
TS_JUMP_US = 86_400_000_000  # one day
CHUNK_BYTES = 1 << 20
MIN_RECORD_BYTES = 8 + wire.HEADER_LEN_V1 + 2
ALL_KNOWN = frozenset(wire.CRC_EXTRA)  # every message id of the dialect: ``wanted`` for every frame

_MARGIN = 8 + wire.MAX_FRAME_LEN  # the longest record: a refill is due when less is left
_NO_FRAME = (wire.NEED_MORE, 0, 0, 0, 0, 0)  # parse status of a record whose frame starts past the buffer

Item = Union[tuple, Rejected]


def plausible(ts: int, last_ts: Optional[int]) -> bool:
    """A record's timestamp (us) is plausible within a day of the last accepted
    one, or (the first) between 2000 and 2100."""
    return abs(ts - last_ts) <= TS_JUMP_US if last_ts is not None else TS_MIN_US <= ts <= TS_MAX_US


def starts_like_a_tlog(head: bytes) -> bool:
    """Whether ``head`` (the first bytes of a file) holds a record with a
    plausible timestamp and a good CRC."""
    n = len(head)
    pos = 0
    while pos + MIN_RECORD_BYTES <= n:
        q = wire.next_start(head, pos + 8, n)
        if q < 0:
            break
        if plausible(int.from_bytes(head[q - 8 : q], "big"), None) and wire.parse_frame(head, q, n)[0] == wire.OK:
            return True
        pos = q - 7
    return False


def _seconds(last_ts: Optional[int]) -> float:
    """The time of a problem: the last accepted timestamp (s), 0 before any."""
    return last_ts / 1e6 if last_ts else 0.0


def _good_record_after(buf, pos: int, n: int, last_ts, stop: int = -1) -> bool:
    """Whether a complete, plausible record with a good CRC starts after ``buf[pos]``
    (its frame's start byte before ``stop``, default: anywhere in the buffer).
    Then a record at ``pos`` that would overlap it was garbage (a noise start
    byte with a large length, a record cut short), not one to skip whole: a
    record without a checkable CRC (unknown id) is skipped whole only if no
    good record begins before its end, timestamp included."""
    q = wire.next_start(buf, pos + 9, n if stop < 0 else min(stop, n))
    while q >= 0:
        if wire.parse_frame(buf, q, n)[0] == wire.OK:
            if plausible(int.from_bytes(buf[q - 8 : q], "big"), last_ts):
                return True
        q = wire.next_start(buf, q + 1, n if stop < 0 else min(stop, n))
    return False


class RecordWalk(wire.FrameCounts):
    """The records of one tlog. Iterating over :meth:`walk` yields, for each
    accepted frame whose message id is in ``wanted``, ``(recv_s, msgid,
    sysid, compid, payload)``, followed by the record's file offsets
    ``start, end`` (timestamp included) when ``offsets``; and a
    :class:`~mavnav.samples.Rejected` for each problem: ``garbage``,
    ``crc``, ``unknown_message`` (a record accepted whole, in step, whose id
    the dialect does not know), ``truncated``. ``counts[(sysid, msgid)]``
    (every accepted frame) and the byte counters are filled while walking."""

    def __init__(self, wanted, chunk_size: int = CHUNK_BYTES, offsets: bool = False):
        super().__init__(wanted)
        self.chunk_size = max(int(chunk_size), 2 * _MARGIN)
        self.offsets = offsets
        self.truncated_bytes = 0
        self.truncated_at: Optional[int] = None  # byte offset of a record the end of the file cuts short

    def walk(self, source: Union[str, Path, bytes]) -> Iterator[Item]:
        """The items of a tlog: the file at path ``source``, or a whole tlog's bytes."""
        w = _Walk()
        with io.BytesIO(source) if isinstance(source, bytes) else open(source, "rb") as f:
            while True:
                self._refill(f, w)
                if w.pos >= len(w.buf):
                    break
                yield from self._records(w)
                if w.eof and w.pos >= len(w.buf):
                    break
        if w.bad_from >= 0:
            self.garbage_bytes += w.base + len(w.buf) - w.bad_from
            yield Rejected(_seconds(w.last_ts), "garbage", "bytes skipped at end of file")

    def _refill(self, f, w: _Walk) -> None:
        """Read the next chunk behind what is left of the buffer, once less than a record is left."""
        if not w.eof and len(w.buf) - w.pos < _MARGIN:
            data = f.read(self.chunk_size)
            self.bytes_read += len(data)
            w.base += w.pos
            w.buf = w.buf[w.pos:] + data
            w.pos = 0
            if not data:
                w.eof = True

    def _records(self, w: _Walk) -> Iterator[Item]:
        """The records of the buffer from ``w.pos``, until a refill is due or the buffer ends.
        The hot loop: its state in locals, stored in ``w`` around the rare paths."""
        parse = wire.parse_frame
        OK, UNKNOWN_ID = wire.OK, wire.UNKNOWN_ID
        wanted = self.wanted
        counts = self.counts
        offsets = self.offsets
        buf, base = w.buf, w.base
        n = len(buf)
        limit = n if w.eof else n - _MARGIN
        pos, last_ts, in_step, bad_from = w.pos, w.last_ts, w.in_step, w.bad_from
        while pos <= limit and pos < n:
            p = pos + 8
            st, flen, msgid, sysid, compid, ps = parse(buf, p, n) if p < n else _NO_FRAME
            if st == OK or (
                st == UNKNOWN_ID and in_step and not _good_record_after(buf, pos, n, last_ts, p + flen + 8)
            ):
                ts = int.from_bytes(buf[pos:p], "big")
                # plausible(ts, last_ts), inline: the hot path
                if abs(ts - last_ts) <= TS_JUMP_US if last_ts is not None else TS_MIN_US <= ts <= TS_MAX_US:
                    if bad_from >= 0:
                        yield self._garbage_ends(ts, base + pos - bad_from)
                        bad_from = -1
                    last_ts = ts
                    in_step = True
                    self.frames += 1
                    counts[(sysid, msgid)] += 1
                    pos = p + flen
                    if st != OK:
                        self.unknown_frames += 1
                        yield Rejected(ts / 1e6, "unknown_message", f"msgid {msgid}")
                    elif msgid in wanted:
                        if offsets:
                            yield (ts / 1e6, msgid, sysid, compid, buf[ps : ps + buf[p + 1]], base + p - 8, base + pos)
                        else:
                            yield (ts / 1e6, msgid, sysid, compid, buf[ps : ps + buf[p + 1]])
                    continue
            w.pos, w.last_ts, w.in_step, w.bad_from = pos, last_ts, in_step, bad_from
            stop = yield from self._not_accepted(w, st, msgid, sysid)
            pos, in_step, bad_from = w.pos, w.in_step, w.bad_from
            if stop:
                break
        w.pos, w.last_ts, w.in_step, w.bad_from = pos, last_ts, in_step, bad_from

    def _garbage_ends(self, ts: int, skipped: int) -> Rejected:
        """A good record after ``skipped`` bytes of garbage."""
        self.garbage_bytes += skipped
        return Rejected(ts / 1e6, "garbage", f"{skipped} bytes skipped")

    def _not_accepted(self, w: _Walk, st: int, msgid: int, sysid: int):
        """No record to accept at ``w.pos`` (parse status ``st``): more bytes
        needed, a record cut short by the end of the file, a CRC error, or
        garbage; then on to the next record start. Returns whether the walk
        of this buffer stops (a refill, or the end of the file)."""
        if st == wire.NEED_MORE:
            if w.eof and not _good_record_after(w.buf, w.pos, len(w.buf), w.last_ts):
                yield self._truncated(w)
                return True
            if not w.eof:
                return True  # refill
        if st == wire.BAD_CRC and w.in_step:
            self.crc_errors += 1
            yield Rejected(_seconds(w.last_ts), "crc", f"{wire.msg_name(msgid)} from {sysid}")
        return (yield from self._resync(w))

    def _truncated(self, w: _Walk) -> Rejected:
        """A record cut short by the end of the file (no good record follows it): the walk ends."""
        n, pos = len(w.buf), w.pos
        if w.bad_from < 0:
            w.bad_from = w.base + pos
        self.truncated_at = w.base + pos
        self.truncated_bytes += w.base + n - w.bad_from
        w.bad_from = -1
        w.pos = n
        return Rejected(_seconds(w.last_ts), "truncated", f"{n - pos} bytes at end of file")

    def _resync(self, w: _Walk):
        """Out of step: on to the next plausible record start. Returns whether
        the walk of this buffer stops (none in it: a refill, or garbage to the
        end of the file)."""
        buf, n = w.buf, len(w.buf)
        if w.bad_from < 0:
            w.bad_from = w.base + w.pos
        w.in_step = False
        q = wire.next_start(buf, w.pos + 9, n)
        if q >= 0:
            w.pos = q - 8
            return False
        if not w.eof:
            w.pos = max(w.pos + 1, n - 8)
            return True
        w.pos = n
        skipped = w.base + n - w.bad_from
        self.garbage_bytes += skipped
        w.bad_from = -1
        yield Rejected(_seconds(w.last_ts), "garbage", f"{skipped} bytes skipped at end of file")
        return True


class _Walk:
    """Where a :class:`RecordWalk` is: the buffer (its first byte at file
    offset ``base``), the position in it, whether the file is read to its
    end, the last accepted timestamp (us), whether the walk is in step, and
    where the current run of garbage started (file offset; -1: none)."""

    __slots__ = ("buf", "base", "pos", "eof", "last_ts", "in_step", "bad_from")

    def __init__(self) -> None:
        self.buf = b""
        self.base = 0
        self.pos = 0
        self.eof = False
        self.last_ts: Optional[int] = None
        self.in_step = True
        self.bad_from = -1
