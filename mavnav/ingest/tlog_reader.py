"""Frame reader for .tlog files: chunked, resynchronising, never loads the file whole.

A tlog record is an 8-byte big-endian Unix time in microseconds (receive
time) followed by one MAVLink v1 or v2 frame. The reader walks records; a
record is accepted when its start byte is a MAVLink start byte, its
timestamp is plausible (within a day of the previous accepted record, or
between 2000 and 2100 for the first), and its CRC is correct (for every
message id the dialect knows; unknown ids are accepted only while the reader
is in step, never to resynchronise on). Anything else is skipped byte by
byte until the next plausible record: garbage, CRC failures and a truncated
tail are counted and reported, never raised.

It yields ``(recv_s, msgid, sysid, compid, payload)`` for the message ids
in ``wanted`` and counts every frame per ``(sysid, msgid)``; problems are
yielded as :class:`~mavnav.samples.Rejected` objects.
"""

from __future__ import annotations

from collections import Counter
from pathlib import Path
from typing import Iterator, Optional, Union

from ..errors import InputError
from ..samples import Rejected
from . import wire

_TS_MIN_US = 946_684_800_000_000  # 2000-01-01
_TS_MAX_US = 4_102_444_800_000_000  # 2100-01-01
_TS_JUMP_US = 86_400_000_000  # one day
_CHUNK = 1 << 20
_PROBE = 1 << 20
_MIN_RECORD = 8 + wire.HEADER_LEN_V1 + 2

Item = Union[tuple, Rejected]


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
            ts = int.from_bytes(buf[q - 8 : q], "big")
            if abs(ts - last_ts) <= _TS_JUMP_US if last_ts is not None else _TS_MIN_US <= ts <= _TS_MAX_US:
                return True
        q = wire.next_start(buf, q + 1, n if stop < 0 else min(stop, n))
    return False


class TlogReader:
    """Iterate over the frames of one tlog. ``counts[(sysid, msgid)]`` and the
    byte counters are filled while iterating."""

    def __init__(self, path: Union[str, Path], wanted, chunk_size: int = _CHUNK):
        self.path = Path(path)
        self.wanted = frozenset(wanted)
        self.chunk_size = max(int(chunk_size), 2 * (8 + wire.MAX_FRAME_LEN))
        self.counts: Counter = Counter()
        self.frames = 0
        self.bytes_read = 0
        self.garbage_bytes = 0
        self.crc_errors = 0
        self.unknown_frames = 0
        self.truncated_bytes = 0
        self.truncated_at: Optional[int] = None  # byte offset of a record the end of the file cuts short

    def probe(self) -> None:
        """Raise :class:`InputError` unless the file starts like a tlog."""
        try:
            with open(self.path, "rb") as f:
                head = f.read(_PROBE)
        except IsADirectoryError:
            raise InputError(f"{self.path}: is a directory, not a tlog") from None
        except FileNotFoundError:
            raise InputError(f"{self.path}: no such file") from None
        except OSError as exc:
            raise InputError(f"{self.path}: cannot read ({exc.strerror})") from None
        if not head:
            raise InputError(f"{self.path}: empty file, not a tlog")
        n = len(head)
        pos = 0
        while pos + _MIN_RECORD <= n:
            q = wire.next_start(head, pos + 8, n)
            if q < 0:
                break
            ts = int.from_bytes(head[q - 8 : q], "big")
            if _TS_MIN_US <= ts <= _TS_MAX_US:
                st = wire.parse_frame(head, q, n)[0]
                if st == wire.OK:
                    return
            pos = q - 7
        raise InputError(f"{self.path}: not a tlog (no MAVLink record with a valid checksum found)")

    def __iter__(self) -> Iterator[Item]:
        parse = wire.parse_frame
        OK, NEED_MORE, UNKNOWN_ID = wire.OK, wire.NEED_MORE, wire.UNKNOWN_ID
        wanted = self.wanted
        counts = self.counts
        last_ts = None
        in_step = True
        bad_from = -1  # absolute offset where the current garbage run started
        base = 0  # absolute offset of buf[0]
        buf = b""
        pos = 0
        eof = False
        margin = 8 + wire.MAX_FRAME_LEN
        with open(self.path, "rb") as f:
            while True:
                if not eof and len(buf) - pos < margin:
                    data = f.read(self.chunk_size)
                    self.bytes_read += len(data)
                    base += pos
                    buf = buf[pos:] + data
                    pos = 0
                    if not data:
                        eof = True
                n = len(buf)
                limit = n if eof else n - margin
                if pos >= n:
                    break
                while pos <= limit and pos < n:
                    p = pos + 8
                    if p >= n:
                        st = NEED_MORE
                    else:
                        st, flen, msgid, sysid, compid, ps = parse(buf, p, n)
                    if st == OK or (
                        st == UNKNOWN_ID and in_step and not _good_record_after(buf, pos, n, last_ts, p + flen + 8)
                    ):
                        ts = int.from_bytes(buf[pos:p], "big")
                        plausible = (
                            abs(ts - last_ts) <= _TS_JUMP_US
                            if last_ts is not None
                            else _TS_MIN_US <= ts <= _TS_MAX_US
                        )
                        if plausible:
                            if bad_from >= 0:
                                skipped = base + pos - bad_from
                                self.garbage_bytes += skipped
                                bad_from = -1
                                yield Rejected(ts / 1e6, "garbage", f"{skipped} bytes skipped")
                            last_ts = ts
                            in_step = True
                            self.frames += 1
                            counts[(sysid, msgid)] += 1
                            pos = p + flen
                            if st == OK:
                                if msgid in wanted:
                                    yield (ts / 1e6, msgid, sysid, compid, buf[ps : ps + buf[p + 1]])
                            else:
                                self.unknown_frames += 1
                                yield Rejected(ts / 1e6, "unknown_message", f"msgid {msgid}")
                            continue
                    if st == NEED_MORE and eof and not _good_record_after(buf, pos, n, last_ts):
                        # a record cut short by the end of the file (no good record follows it)
                        if bad_from < 0:
                            bad_from = base + pos
                        self.truncated_at = base + pos
                        self.truncated_bytes += base + n - bad_from
                        bad_from = -1
                        yield Rejected(last_ts / 1e6 if last_ts else 0.0, "truncated", f"{n - pos} bytes at end of file")
                        pos = n
                        break
                    if st == NEED_MORE and not eof:
                        break  # refill
                    if st == wire.BAD_CRC and in_step:
                        self.crc_errors += 1
                        yield Rejected(last_ts / 1e6 if last_ts else 0.0, "crc", f"{wire.msg_name(msgid)} from {sysid}")
                    # out of step: look for the next plausible record start
                    if bad_from < 0:
                        bad_from = base + pos
                    in_step = False
                    q = wire.next_start(buf, pos + 9, n)
                    if q < 0:
                        pos = max(pos + 1, n - 8) if not eof else n
                        if eof:
                            self.garbage_bytes += base + n - bad_from
                            yield Rejected(last_ts / 1e6 if last_ts else 0.0, "garbage", f"{base + n - bad_from} bytes skipped at end of file")
                            bad_from = -1
                        break
                    pos = q - 8
                if eof and pos >= len(buf):
                    break
        if bad_from >= 0:
            self.garbage_bytes += base + len(buf) - bad_from
            yield Rejected(last_ts / 1e6 if last_ts else 0.0, "garbage", "bytes skipped at end of file")

