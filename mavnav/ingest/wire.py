"""MAVLink wire format: frame headers, CRC, payload decoding. No field semantics.

Frames are checked with the MAVLink checksum (CRC-16/MCRF4XX over the frame
after the start byte, plus the message's ``crc_extra``). That CRC is the
bit-reflected form of CRC-16/CCITT, so it is computed with the standard
library's C ``binascii.crc_hqx`` on bit-reversed bytes (``bytes.translate``)
and compared with the bit-reversed checksum: C speed, no dependency.

Decoding uses pymavlink's generated message classes (ardupilotmega dialect,
a superset of common) only for their ``struct`` layouts; payloads are
unpacked straight into a ``dict`` of wire fields, truncated MAVLink 2
payloads and MAVLink 1 frames without extensions zero-padded, as pymavlink
does.
"""

from __future__ import annotations

import binascii
from collections import Counter
from typing import Callable, Dict, Optional, Sequence, Tuple

from pymavlink.dialects.v20 import ardupilotmega as _dialect

STX_V1 = 0xFE
STX_V2 = 0xFD
HEADER_LEN_V1 = 6
HEADER_LEN_V2 = 10
SIGNATURE_LEN = 13
IFLAG_SIGNED = 0x01
MAX_FRAME_LEN = HEADER_LEN_V2 + 255 + 2 + SIGNATURE_LEN

REV = bytes(int(f"{i:08b}"[::-1], 2) for i in range(256))
"""Bit-reversal of every byte value."""

CRC_EXTRA: Dict[int, int] = {mid: cls.crc_extra for mid, cls in _dialect.mavlink_map.items()}
CRC_EXTRA_BYTE: Dict[int, bytes] = {mid: bytes([x]) for mid, x in CRC_EXTRA.items()}
MSG_NAME: Dict[int, str] = {mid: cls.msgname for mid, cls in _dialect.mavlink_map.items()}
MSG_ID: Dict[str, int] = {name: mid for mid, name in MSG_NAME.items()}
ENUMS = _dialect.enums  # enum name -> value -> entry (``.name``), for words on the console


def msg_name(msgid: int) -> str:
    return MSG_NAME.get(msgid, f"UNKNOWN_{msgid}")


# Frame parse results
OK = 0
NEED_MORE = 1
BAD_START = 2
BAD_CRC = 3
UNKNOWN_ID = 4

FrameHead = Tuple[int, int, int, int, int, int]  # status, frame_len, msgid, sysid, compid, payload_start


def parse_frame(buf, p: int, n: int) -> FrameHead:
    """Parse the MAVLink frame starting at ``buf[p]`` (``n`` = usable length of buf).

    Returns ``(status, frame_len, msgid, sysid, compid, payload_start)``;
    ``payload_start + payload_len + 2 (+13 if signed) == p + frame_len``.
    The CRC is checked for every message id the dialect knows.
    """
    if p + 2 > n:
        return (NEED_MORE, 0, 0, 0, 0, 0)
    stx = buf[p]
    plen = buf[p + 1]
    if stx == STX_V2:
        if p + HEADER_LEN_V2 > n:
            return (NEED_MORE, 0, 0, 0, 0, 0)
        flen = HEADER_LEN_V2 + plen + 2 + (SIGNATURE_LEN if buf[p + 2] & IFLAG_SIGNED else 0)
        if p + flen > n:
            return (NEED_MORE, flen, 0, 0, 0, 0)
        msgid = buf[p + 7] | (buf[p + 8] << 8) | (buf[p + 9] << 16)
        sysid = buf[p + 5]
        compid = buf[p + 6]
        hl = HEADER_LEN_V2
    elif stx == STX_V1:
        if p + HEADER_LEN_V1 > n:
            return (NEED_MORE, 0, 0, 0, 0, 0)
        flen = HEADER_LEN_V1 + plen + 2
        if p + flen > n:
            return (NEED_MORE, flen, 0, 0, 0, 0)
        msgid = buf[p + 5]
        sysid = buf[p + 3]
        compid = buf[p + 4]
        hl = HEADER_LEN_V1
    else:
        return (BAD_START, 0, 0, 0, 0, 0)
    extra = CRC_EXTRA_BYTE.get(msgid)
    if extra is None:
        return (UNKNOWN_ID, flen, msgid, sysid, compid, p + hl)
    end = p + hl + plen
    c = binascii.crc_hqx((buf[p + 1 : end] + extra).translate(REV), 0xFFFF)
    # wire checksum is little-endian of the reflected CRC: compare in the unreflected form
    if c != ((REV[buf[end]] << 8) | REV[buf[end + 1]]):
        return (BAD_CRC, flen, msgid, sysid, compid, p + hl)
    return (OK, flen, msgid, sysid, compid, p + hl)


Decoder = Callable[[bytes], Dict[str, object]]


def make_decoder(msgid: int) -> Optional[Decoder]:
    """A function turning a payload into ``{field: value}`` (arrays as tuples)."""
    cls = _dialect.mavlink_map.get(msgid)
    if cls is None or "s" in cls.unpacker.format:
        return None  # unknown, or carries char arrays (never needed by mavnav)
    unpacker = cls.unpacker
    size = unpacker.size
    unpack = unpacker.unpack
    names = tuple(cls.ordered_fieldnames)
    lens = tuple(cls.array_lengths)
    zeros = bytes(size)

    if not any(lens):

        def decode(payload: bytes) -> Dict[str, object]:
            k = len(payload)
            if k < size:
                payload = payload + zeros[k:]
            elif k > size:
                payload = payload[:size]
            return dict(zip(names, unpack(payload)))

        return decode

    spans = []
    i = 0
    for name, ln in zip(names, lens):
        spans.append((name, i, ln))
        i += ln if ln else 1

    def decode_arrays(payload: bytes) -> Dict[str, object]:
        k = len(payload)
        if k < size:
            payload = payload + zeros[k:]
        elif k > size:
            payload = payload[:size]
        vals = unpack(payload)
        out: Dict[str, object] = {}
        for name, start, ln in spans:
            out[name] = tuple(vals[start : start + ln]) if ln else vals[start]
        return out

    return decode_arrays


def make_field_reader(msgid: int, names: Sequence[str]) -> Optional[Tuple[str, Callable[[bytes], object]]]:
    """``(name, read)`` for the first of ``names`` a message has, in wire order:
    ``read(payload)`` gives that field's value (a truncated MAVLink 2 payload
    zero-padded, as :func:`make_decoder` does). None if the message has none
    of them. Works for every message, char arrays included."""
    cls = _dialect.mavlink_map.get(msgid)
    if cls is None:
        return None
    types = dict(zip(cls.fieldnames, cls.fieldtypes))
    index = 0  # position of the field's value in the unpacked tuple
    for name, ln in zip(cls.ordered_fieldnames, cls.array_lengths):
        if name in names:
            break
        index += ln if ln and types[name] != "char" else 1  # a char array unpacks to one bytes value
    else:
        return None
    unpack, size = cls.unpacker.unpack, cls.unpacker.size
    zeros = bytes(size)

    def read(payload: bytes) -> object:
        k = len(payload)
        if k < size:
            payload = payload + zeros[k:]
        elif k > size:
            payload = payload[:size]
        return unpack(payload)[index]

    return name, read


def next_start(buf, start: int, n: int) -> int:
    """Index of the next MAVLink start byte in ``buf[start:n]``, or -1."""
    a = buf.find(b"\xfe", start, n)
    b = buf.find(b"\xfd", start, n)
    if a < 0:
        return b
    if b < 0:
        return a
    return a if a < b else b


class FrameCounts:
    """What a frame reader counts while it reads, whatever the frames come
    from (a tlog's records, a live link's bytes): every accepted frame per
    ``(sysid, msgid)``, the bytes read, the garbage skipped, CRC failures and
    frames of ids the dialect does not know; ``wanted``: the message ids it
    yields."""

    def __init__(self, wanted) -> None:
        self.wanted = frozenset(wanted)
        self.counts: Counter = Counter()
        self.frames = 0
        self.bytes_read = 0
        self.garbage_bytes = 0
        self.crc_errors = 0
        self.unknown_frames = 0
