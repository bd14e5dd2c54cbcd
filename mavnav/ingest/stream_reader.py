"""Frame reader for a raw MAVLink byte stream (a live link): no record timestamps.

Bytes are fed as they arrive, each chunk stamped with its receive time.
Frames are found by start byte and accepted on a correct CRC (unknown
message ids are skipped whole); garbage and CRC failures are counted and
reported as :class:`~mavnav.samples.Rejected`, the same way
:mod:`.tlog_reader` does for files, and the output tuples are the same.
"""

from __future__ import annotations

from collections import Counter
from typing import List, Union

from ..samples import Rejected
from . import wire

Item = Union[tuple, Rejected]


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

    def feed(self, data: bytes, recv_s: float) -> List[Item]:
        """Parse what ``data`` completes; keep an unfinished frame for the next call."""
        out: List[Item] = []
        self.bytes_read += len(data)
        buf = self._buf + bytes(data)
        n = len(buf)
        pos = 0
        parse = wire.parse_frame
        wanted = self.wanted
        while pos < n:
            b = buf[pos]
            if b != wire.STX_V1 and b != wire.STX_V2:
                q = wire.next_start(buf, pos + 1, n)
                skip = (q if q >= 0 else n) - pos
                self._garbage_run += skip
                pos += skip
                continue
            st, flen, msgid, sysid, compid, ps = parse(buf, pos, n)
            if st == wire.NEED_MORE:
                break
            if st == wire.BAD_CRC or st == wire.BAD_START:
                if st == wire.BAD_CRC:
                    self.crc_errors += 1
                    out.append(Rejected(recv_s, "crc", f"{wire.msg_name(msgid)} from {sysid}"))
                self._garbage_run += 1
                pos += 1
                continue
            if self._garbage_run:
                self.garbage_bytes += self._garbage_run
                out.append(Rejected(recv_s, "garbage", f"{self._garbage_run} bytes skipped"))
                self._garbage_run = 0
            self.frames += 1
            self.counts[(sysid, msgid)] += 1
            if st == wire.UNKNOWN_ID:
                self.unknown_frames += 1
                out.append(Rejected(recv_s, "unknown_message", f"msgid {msgid}"))
            elif msgid in wanted:
                out.append((recv_s, msgid, sysid, compid, buf[ps : ps + buf[pos + 1]]))
            pos += flen
        self._buf = buf[pos:]
        return out

