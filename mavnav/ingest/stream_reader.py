"""Frame reader for a raw MAVLink byte stream (a live link): no record timestamps.

Bytes are fed as they arrive, each chunk stamped with its receive time.
Frames are found by start byte and accepted on a correct CRC. Garbage and
CRC failures are counted and reported as :class:`~mavnav.samples.Rejected`,
the same way :mod:`.tlog_reader` does for files, and the output tuples are
the same.

Resynchronisation never costs a valid frame: a start byte that fails is
skipped alone (one byte), never a whole "frame length", and the search goes
on from the next candidate start byte. A frame with a message id the
dialect does not know has no checksum that can be verified, so it is
accepted (counted, skipped whole) only when the reader is in step (it starts
exactly where the previous good frame ended), no good frame begins inside it
and its end is consistent with framing (see :func:`_unknown_verdict`);
otherwise its start byte is garbage. A start byte whose frame
would need more bytes than have arrived waits for them, unless a complete
frame with a good CRC already follows it in the buffer, which shows it was
garbage (so a noise byte never holds up the frames behind it).

``seq_missing`` counts the frames the MAVLink sequence numbers say never
arrived (per system and component, forward gaps below 128; a frame behind
its predecessor is late, not a gap): what the link or the receive buffer
lost.
"""

from __future__ import annotations

from collections import Counter
from typing import List, Union

from ..samples import Rejected
from . import wire

Item = Union[tuple, Rejected]


def _good_frame_from(buf, start: int, n: int) -> bool:
    """Whether a candidate start byte in ``buf[start:n]`` begins a frame with a good CRC."""
    parse = wire.parse_frame
    q = wire.next_start(buf, start, n)
    while q >= 0:
        if parse(buf, q, n)[0] == wire.OK:
            return True
        q = wire.next_start(buf, q + 1, n)
    return False


_ACCEPT, _NOISE, _WAIT = 0, 1, 2


def _unknown_verdict(buf, pos: int, end: int, n: int) -> int:
    """Whether an unknown-id frame ``buf[pos:end]`` met in step is a real frame.

    Noise if a good frame begins inside it; a real frame if a good frame
    begins right behind it, or if nothing inside it could begin one and it
    ends where the buffer does or at a start byte; noise if it ends in the
    middle of other bytes; otherwise (something inside it might still begin
    a frame) wait for more bytes."""
    parse = wire.parse_frame
    pending = False
    q = wire.next_start(buf, pos + 1, end)
    while q >= 0:
        st = parse(buf, q, n)[0]
        if st == wire.OK:
            return _NOISE
        if st == wire.NEED_MORE:
            pending = True
        q = wire.next_start(buf, q + 1, end)
    if end < n and parse(buf, end, n)[0] == wire.OK:
        return _ACCEPT
    if pending:
        return _WAIT
    if end == n or buf[end] == wire.STX_V1 or buf[end] == wire.STX_V2:
        return _ACCEPT
    return _NOISE


class StreamReader:
    def __init__(self, wanted):
        self.wanted = frozenset(wanted)
        self.counts: Counter = Counter()
        self.frames = 0
        self.bytes_read = 0
        self.garbage_bytes = 0
        self.crc_errors = 0
        self.unknown_frames = 0
        self._buf = b""
        self._garbage_run = 0
        self._in_step = False  # the buffer starts where the last good frame ended
        self.seq_missing = 0
        self._seq = {}  # (sysid, compid) -> last sequence number

    def feed(self, data: bytes, recv_s: float) -> List[Item]:
        """Parse what ``data`` completes; keep an unfinished frame for the next call."""
        out: List[Item] = []
        self.bytes_read += len(data)
        buf = self._buf + bytes(data)
        n = len(buf)
        pos = 0
        parse = wire.parse_frame
        wanted = self.wanted
        in_step = self._in_step
        while pos < n:
            b = buf[pos]
            if b != wire.STX_V1 and b != wire.STX_V2:
                q = wire.next_start(buf, pos + 1, n)
                skip = (q if q >= 0 else n) - pos
                self._garbage_run += skip
                pos += skip
                in_step = False
                continue
            st, flen, msgid, sysid, compid, ps = parse(buf, pos, n)
            if st == wire.NEED_MORE:
                if not _good_frame_from(buf, pos + 1, n):
                    break  # wait for the rest of this frame
                st = wire.BAD_START  # a good frame follows inside it: this start byte is noise
            elif st == wire.UNKNOWN_ID:
                verdict = _unknown_verdict(buf, pos, pos + flen, n) if in_step else _NOISE
                if verdict == _WAIT:
                    break
                if verdict == _NOISE:
                    st = wire.BAD_START
            if st == wire.BAD_CRC or st == wire.BAD_START:
                if st == wire.BAD_CRC:
                    self.crc_errors += 1
                    out.append(Rejected(recv_s, "crc", f"{wire.msg_name(msgid)} from {sysid}"))
                self._garbage_run += 1
                pos += 1
                in_step = False
                continue
            if self._garbage_run:
                self.garbage_bytes += self._garbage_run
                out.append(Rejected(recv_s, "garbage", f"{self._garbage_run} bytes skipped"))
                self._garbage_run = 0
            self.frames += 1
            self.counts[(sysid, msgid)] += 1
            seq = buf[pos + 4] if b == wire.STX_V2 else buf[pos + 2]
            last = self._seq.get((sysid, compid))
            gap = 0 if last is None else (seq - last - 1) & 0xFF
            if gap < 128:
                self.seq_missing += gap
                self._seq[(sysid, compid)] = seq
            if st == wire.UNKNOWN_ID:
                self.unknown_frames += 1
                out.append(Rejected(recv_s, "unknown_message", f"msgid {msgid}"))
            else:
                in_step = True
                if msgid in wanted:
                    out.append((recv_s, msgid, sysid, compid, buf[ps : ps + buf[pos + 1]]))
            pos += flen
        self._buf = buf[pos:]
        self._in_step = in_step
        return out
