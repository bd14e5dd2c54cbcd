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

**Sequence order** (``reorder_s`` > 0, live links). Each system and
component numbers its frames (``seq``, modulo 256). A frame ahead of the
next expected number opens a gap: the frames behind it are held until the
missing ones arrive (a reordered link: they are put back in order, nothing
refused as out of order downstream) or until the gap is given up, after
``reorder_s`` of receive time or ``reorder_frames`` held frames (a lost
frame: the held ones go on). In order, nothing waits. Only displacements up
to :data:`MAX_DISPLACEMENT` frames are reordering: a frame further ahead
marks a loss, one further behind re-synchronises the sequence (a stray
frame, a stale one re-sent, a restarted sender). A frame a little behind
the expected number is passed on at once (late or duplicated: the
normaliser judges its time). A link whose gaps are mostly never filled (a sender that
does not number its frames one by one) is passed on as it comes.

``seq_missing`` counts the frames the sequence numbers say never arrived
(gaps given up, less the late frames that filled them afterwards; forward
gaps below 128): what the link or the receive buffer lost.
"""

from __future__ import annotations

from collections import deque
from typing import Dict, List, Optional, Union

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


MAX_DISPLACEMENT = 100  # frames (a datagram may carry many): further ahead or behind is a loss or a stray


class _Link:
    """Sequence state of one (sysid, compid)."""

    __slots__ = ("next", "held", "given_up", "filled", "abandoned", "ordered", "jump")

    def __init__(self, seq: int):
        self.next = (seq + 1) & 0xFF
        self.held: Dict[int, tuple] = {}  # seq -> (entry or None, recv_s)
        self.given_up: deque = deque(maxlen=256)  # seqs skipped when a gap was given up
        self.filled = 0  # gaps closed by their late frames
        self.abandoned = 0  # gaps given up
        self.ordered = True  # False: this link does not number its frames one by one
        self.jump: Optional[tuple] = None  # (next before, frames counted missing) of the last skip ahead


class StreamReader(wire.FrameCounts):
    def __init__(self, wanted, reorder_s: float = 0.0, reorder_frames: int = 64):
        super().__init__(wanted)
        self._buf = b""
        self._garbage_run = 0
        self._in_step = False  # the buffer starts where the last good frame ended
        self.seq_missing = 0
        self.late_frames = 0  # frames that arrived after their gap was given up
        self.reordered = 0  # frames put back in sequence order
        self.reorder_s = reorder_s
        self.reorder_frames = reorder_frames
        self._links: Dict[tuple, _Link] = {}

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
            entry = None
            if st == wire.UNKNOWN_ID:
                self.unknown_frames += 1
                out.append(Rejected(recv_s, "unknown_message", f"msgid {msgid}"))
            else:
                in_step = True
                if msgid in wanted:
                    entry = (recv_s, msgid, sysid, compid, buf[ps : ps + buf[pos + 1]])
            self._in_order((sysid, compid), buf[pos + 4] if b == wire.STX_V2 else buf[pos + 2], entry, recv_s, out)
            pos += flen
        self._buf = buf[pos:]
        self._in_step = in_step
        if self.reorder_s > 0:
            self._expire(recv_s, out)
        return out

    # ------------------------------------------------------------------ sequence order

    def expire(self, now_s: float) -> List[Item]:
        """Give up the gaps held longer than ``reorder_s`` (receive clock ``now_s``)."""
        out: List[Item] = []
        if self.reorder_s > 0:
            self._expire(now_s, out)
        return out

    def flush(self) -> List[Item]:
        """Everything still held, in sequence order (end of stream)."""
        out: List[Item] = []
        for link in self._links.values():
            while link.held:
                self._give_up(link, out)
        return out

    def _in_order(self, key, seq: int, entry, recv_s: float, out: list) -> None:
        link = self._links.get(key)
        if link is None:
            self._links[key] = _Link(seq)
            if entry is not None:
                out.append(entry)
            return
        d = (seq - link.next) & 0xFF
        if d == 0:
            if entry is not None:
                out.append(entry)
            link.next = (seq + 1) & 0xFF
            link.jump = None
            if link.held:
                link.filled += 1
                self._drain(link, out)
            return
        if seq in link.held:  # the same frame twice: the normaliser judges it
            if entry is not None:
                out.append(entry)
            return
        if d <= MAX_DISPLACEMENT and self.reorder_s > 0 and link.ordered:
            link.held[seq] = (entry, recv_s)  # ahead: wait for the frames before it
            if len(link.held) > self.reorder_frames:
                self._give_up(link, out)
            return
        if d < 128:  # far ahead (or not reordering): the frames before it are missing
            self.seq_missing += d
            link.jump = (link.next, d)
            link.next = (seq + 1) & 0xFF
            if entry is not None:
                out.append(entry)
            return
        behind = 256 - d
        if behind > MAX_DISPLACEMENT:
            # not a late frame: the sequence goes on from where it was before a stray
            # frame (stale, or from another sender) moved it ahead, or it restarted
            if link.jump is not None and (seq - link.jump[0]) & 0xFF <= MAX_DISPLACEMENT:
                self.seq_missing -= link.jump[1]
            link.jump = None
            link.next = (seq + 1) & 0xFF
        elif seq in link.given_up:  # the late frame of a gap given up
            link.given_up.remove(seq)
            self.seq_missing -= 1
            self.late_frames += 1
        if entry is not None:
            out.append(entry)

    def _drain(self, link: _Link, out: list) -> None:
        held = link.held
        while link.next in held:
            entry, _ = held.pop(link.next)
            self.reordered += 1
            if entry is not None:
                out.append(entry)
            link.next = (link.next + 1) & 0xFF

    def _give_up(self, link: _Link, out: list) -> None:
        """The oldest gap will not be filled: skip it and pass on what is held behind it."""
        nxt = link.next
        first = min(link.held, key=lambda q: (q - nxt) & 0xFF)
        gap = (first - nxt) & 0xFF
        for k in range(gap):
            link.given_up.append((nxt + k) & 0xFF)
        self.seq_missing += gap
        link.abandoned += 1
        link.next = first
        self._drain(link, out)
        self.reordered -= 1  # the first one after the gap was not out of order
        if link.abandoned > 20 and link.abandoned > 2 * link.filled:
            link.ordered = False  # gaps that never fill: not numbered one by one, stop waiting
            while link.held:
                self._give_up(link, out)

    def _expire(self, now_s: float, out: list) -> None:
        for link in self._links.values():
            while link.held and now_s - min(r for _, r in link.held.values()) >= self.reorder_s:
                self._give_up(link, out)
