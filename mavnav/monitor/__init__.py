"""Integrity control of the three channels (MODEL.md section 5).

:class:`Monitor` is the pure fold ``push(sample) -> [(EpochReport, [AlarmEvent])]``;
``mode: paper`` (:mod:`.paper`) reproduces the paper, ``mode: adaptive``
(:mod:`.adaptive`, the default) makes it safe.
"""

from .core import Monitor

__all__ = ["Monitor"]
