"""Sinks: where the monitor's results go (CSV, Rerun, MAVLink out, audit).

Every sink derives from :class:`~mavnav.sinks.base.Sink` and overrides the
hooks it needs. The pipeline calls them through
:class:`~mavnav.sinks.base.SinkSet`, which reports a failing sink once,
drops it, and keeps the monitor running.
"""

from .base import Sink, SinkSet

__all__ = ["Sink", "SinkSet"]
