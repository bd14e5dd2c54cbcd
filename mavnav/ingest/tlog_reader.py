"""Frame reader for .tlog files: chunked, resynchronising, never loads the file whole.

The record walk (:mod:`.records`: which bytes are frames, the plausibility
and resynchronisation rules, what is counted) is shared with the fault
injector; the reader skips what is not a frame. It yields ``(recv_s, msgid,
sysid, compid, payload)`` for the message ids in ``wanted`` and counts every
frame per ``(sysid, msgid)``; problems (garbage, CRC failures, unknown
messages, a truncated tail) are yielded as :class:`~mavnav.samples.Rejected`
objects, never raised.
"""

from __future__ import annotations

from pathlib import Path
from typing import Iterator, Union

from ..errors import InputError
from .records import CHUNK_BYTES, Item, RecordWalk, starts_like_a_tlog

_PROBE = 1 << 20


class TlogReader(RecordWalk):
    """Iterate over the frames of one tlog. ``counts[(sysid, msgid)]`` and the
    byte counters are filled while iterating."""

    def __init__(self, path: Union[str, Path], wanted, chunk_size: int = CHUNK_BYTES):
        super().__init__(wanted, chunk_size)
        self.path = Path(path)

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
        if not starts_like_a_tlog(head):
            raise InputError(f"{self.path}: not a tlog (no MAVLink record with a valid checksum found)")

    def __iter__(self) -> Iterator[Item]:
        return self.walk(self.path)
