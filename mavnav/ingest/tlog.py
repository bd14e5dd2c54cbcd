"""Recorded telemetry: :class:`TlogSource` over one .tlog, and path expansion for audits."""

from __future__ import annotations

from pathlib import Path
from typing import Iterable, Iterator, List, Optional, Union

from ..config import IngestConfig
from ..errors import InputError
from .normaliser import WANTED, Normaliser
from .stats import IngestStats
from .tlog_reader import TlogReader
from . import wire

PathLike = Union[str, Path]


class TlogSource:
    """Samples and events from one tlog, streamed (memory flat however long the log).

    Raises :class:`~mavnav.errors.InputError` at construction for a file
    that is not a tlog at all; damage inside a tlog is reported in the
    stream (``Rejected``) and in :attr:`stats`, never raised. Each iteration
    re-reads the file from the start with fresh statistics.
    """

    def __init__(self, path: PathLike, config: Optional[IngestConfig] = None, sysid: Optional[int] = None):
        self.path = Path(path)
        self.config = config if config is not None else IngestConfig()
        self.sysid = sysid
        TlogReader(self.path, WANTED).probe()
        self.stats = IngestStats(source=str(self.path))

    def __iter__(self) -> Iterator[object]:
        reader = TlogReader(self.path, WANTED)
        stats = self.stats = IngestStats(source=str(self.path))
        norm = Normaliser(self.config, self.sysid, stats)
        feed = norm.feed
        problem = norm.problem
        for item in reader:
            out = feed(*item) if type(item) is tuple else problem(item)
            if out:
                yield from out
        out = norm.finish()
        fill_message_stats(stats, reader, norm.sysid)
        yield from out


def fill_message_stats(stats: IngestStats, reader, sysid: Optional[int]) -> None:
    """Per-message-type counts and rates (over vehicle time) from a frame reader's counters."""
    msgs = {}
    ignored = {}
    for (sid, mid), n in reader.counts.items():
        if sid == sysid:
            name = wire.msg_name(mid)
            msgs[name] = msgs.get(name, 0) + n
        else:
            ignored[sid] = ignored.get(sid, 0) + n
    stats.messages = dict(sorted(msgs.items()))
    stats.ignored_by_sysid = dict(sorted(ignored.items()))
    dur = stats.duration_s
    stats.rates_hz = {k: (v / dur if dur > 0 else 0.0) for k, v in stats.messages.items()}
    stats.frames = reader.frames
    stats.bytes_read = reader.bytes_read
    stats.garbage_bytes = reader.garbage_bytes
    stats.seq_missing = getattr(reader, "seq_missing", 0)


def expand_tlog_paths(paths: Union[PathLike, Iterable[PathLike]]) -> List[Path]:
    """:func:`~.logs.expand_log_paths` restricted to ``*.tlog`` in directories."""
    from .logs import expand_paths

    return expand_paths(paths, (".tlog",))
