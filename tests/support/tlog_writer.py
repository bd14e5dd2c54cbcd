"""Write .tlog files with pymavlink's own encoder (the tests' hand-made flights, bench/ingest.py).

Each record is the 8-byte big-endian receive time in microseconds followed
by the frame pymavlink packs, MAVLink 2 by default or MAVLink 1 on request.
"""

from __future__ import annotations

import struct
from pathlib import Path
from typing import BinaryIO, Union

from pymavlink.dialects.v10 import ardupilotmega as _v1
from pymavlink.dialects.v20 import ardupilotmega as _v2

_TS = struct.Struct(">Q")


class TlogWriter:
    """``writer.write(msg, recv_s)`` where ``msg`` is a pymavlink message object
    built with :attr:`mav` (e.g. ``writer.mav.attitude_encode(...)``)."""

    def __init__(self, path: Union[str, Path, BinaryIO], sysid: int = 1, compid: int = 1, mavlink1: bool = False):
        self._own = not hasattr(path, "write")
        self._f = open(path, "wb") if self._own else path
        dialect = _v1 if mavlink1 else _v2
        self.mav = dialect.MAVLink(None, srcSystem=sysid, srcComponent=compid)
        self.mav.robust_parsing = True

    def frame(self, msg, sysid: int = None, compid: int = None) -> bytes:
        """The packed MAVLink frame of ``msg`` (optionally as another system/component)."""
        mav = self.mav
        if sysid is not None or compid is not None:
            s0, c0 = mav.srcSystem, mav.srcComponent
            mav.srcSystem = s0 if sysid is None else sysid
            mav.srcComponent = c0 if compid is None else compid
            try:
                return bytes(msg.pack(mav))
            finally:
                mav.srcSystem, mav.srcComponent = s0, c0
        return bytes(msg.pack(mav))

    def write(self, msg, recv_s: float, sysid: int = None, compid: int = None) -> bytes:
        buf = self.frame(msg, sysid, compid)
        self.write_raw(buf, recv_s)
        return buf

    def write_raw(self, frame: bytes, recv_s: float) -> None:
        self._f.write(_TS.pack(int(round(recv_s * 1e6))) + frame)

    def close(self) -> None:
        if self._own:
            self._f.close()

    def __enter__(self) -> "TlogWriter":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
