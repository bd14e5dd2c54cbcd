"""Recorded logs of any kind: detection by content and path expansion.

:func:`open_log` returns the source for one file: a
:class:`~.onboard.source.OnboardSource` for an ArduPilot DataFlash log or a
PX4 ULog (recognised by their first bytes, whatever the file is called),
else a :class:`~.tlog.TlogSource` (which refuses a file that holds no
MAVLink). Every source iterates :mod:`mavnav.samples` and keeps an
:class:`~.stats.IngestStats` in ``.stats``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Iterable, List, Optional, Union

from ..config import IngestConfig
from ..errors import InputError
from .onboard.head import read_head
from .onboard.source import OnboardSource, detect_onboard
from .tlog import TlogSource

PathLike = Union[str, Path]
LOG_SUFFIXES = (".tlog", ".bin", ".ulg")


def log_format(path: PathLike) -> str:
    """'dataflash', 'ulog' or 'tlog' (the last is checked when the source opens)."""
    return detect_onboard(read_head(path, 16)) or "tlog"


def open_log(path: PathLike, config: Optional[IngestConfig] = None, sysid: Optional[int] = None):
    """The source for one recorded log, detected by content."""
    if log_format(path) == "tlog":
        return TlogSource(path, config, sysid=sysid)
    return OnboardSource(path, config, sysid=sysid)


def expand_log_paths(paths: Union[PathLike, Iterable[PathLike]]) -> List[Path]:
    """Files as given plus every ``*.tlog``, ``*.bin`` and ``*.ulg`` (any case)
    under each directory: see :func:`expand_paths`."""
    return expand_paths(paths, LOG_SUFFIXES)


def expand_paths(paths: Union[PathLike, Iterable[PathLike]], suffixes) -> List[Path]:
    """Files as given plus every file with one of ``suffixes`` (any case) under
    each directory (recursively, sorted within the directory), in the order of
    the arguments; a file named twice is kept at its first place.

    Raises :class:`~mavnav.errors.InputError` for a path that does not exist.
    """
    if isinstance(paths, (str, Path)):
        paths = [paths]
    out: List[Path] = []
    seen = set()
    for p in paths:
        p = Path(p)
        if p.is_dir():
            group = sorted(q for q in p.rglob("*") if q.is_file() and q.suffix.lower() in suffixes)
        elif p.is_file():
            group = [p]
        else:
            raise InputError(f"{p}: no such file or directory")
        for q in group:
            key = q.resolve()
            if key not in seen:
                seen.add(key)
                out.append(q)
    return out


__all__ = ["open_log", "expand_log_paths", "log_format", "LOG_SUFFIXES"]
