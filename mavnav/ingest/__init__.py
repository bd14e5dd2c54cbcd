"""MAVLink ingestion: live links and recorded tlogs -> mavnav samples.

Data flow: a frame reader (:mod:`.tlog_reader` for files, over the record
walk of :mod:`.records` that the fault injector shares; :mod:`.stream_reader`
for live bytes) finds and CRC-checks MAVLink frames; one
:class:`~.normaliser.Normaliser` per link turns the frames it wants into
:mod:`mavnav.samples` in SI units on the vehicle clock. :class:`TlogSource`
and :class:`LiveSource` are thin loops around the two; they share every
rule, so a replayed log and the same log streamed live give the same samples.

Only :mod:`.normaliser` and its decoders (:mod:`.decoders`, :mod:`.rangecheck`)
know MAVLink field names. Onboard logs (ArduPilot
DataFlash, PX4 ULog) are decoded into columns by :mod:`.onboard` and turned
into the same samples by :class:`~.onboard.source.OnboardSource`;
:func:`~.logs.open_log` picks the source for a file by its content.
"""

from .live import LiveSource
from .stats import IngestStats
from .logs import expand_log_paths, open_log
from .onboard.source import OnboardSource
from .tlog import TlogSource, expand_tlog_paths

__all__ = ["TlogSource", "OnboardSource", "LiveSource", "IngestStats", "expand_tlog_paths",
           "expand_log_paths", "open_log"]
