"""The sink protocol and the guard that keeps a failing sink from stopping the monitor."""

from __future__ import annotations

import logging
from typing import Iterable

from ..report import AlarmEvent, EpochReport, RunSummary

log = logging.getLogger("mavnav.sinks")


class Sink:
    """Base sink: every hook is a no-op. Hooks are called in vehicle-time order.

    * ``start(info)``: once, before any data; ``info`` is a plain dict
      (``source`` description, ``mode``, ``config`` object, ``live`` flag).
    * ``sample(s)``: every sample and event from the source
      (:mod:`mavnav.samples` types), before the epochs it completes.
    * ``imu_run(run, i, j)``, optional: the IMU samples ``i .. j - 1`` of an
      :class:`~mavnav.ingest.onboard.imurun.ImuRun` (an onboard log's
      columns), in place of ``sample`` for each (``run.samples(i, j)``
      builds them). When a sink defines ``sample`` without ``imu_run``, the
      pipeline reads the source sample by sample.
    * ``epoch(report)``: every filter epoch.
    * ``alarm(event)``: every change of a source's state.
    * ``close(summary)``: once, at the end (also after an interruption).
    """

    name = "sink"

    def start(self, info: dict) -> None:
        pass

    def sample(self, s) -> None:
        pass

    def epoch(self, report: EpochReport) -> None:
        pass

    def alarm(self, event: AlarmEvent) -> None:
        pass

    def close(self, summary: RunSummary) -> None:
        pass


_HOOKS = ("start", "sample", "epoch", "alarm", "close")


def _noop(sink, hook: str) -> bool:
    """Whether ``sink``'s ``hook`` is :class:`Sink`'s own no-op (calling it does nothing, and cannot fail)."""
    return getattr(type(sink), hook, None) is getattr(Sink, hook) and hook not in getattr(sink, "__dict__", ())


class SinkSet:
    """Calls every sink; a sink that raises is reported once and dropped.

    A hook a sink leaves as :class:`Sink`'s no-op is not called (``sample``
    runs for every sample of the log); the method is looked up at each call,
    as a sink may replace its own."""

    def __init__(self, sinks: Iterable[Sink], summary: RunSummary):
        self._sinks = list(sinks)
        self._summary = summary
        self._update()

    def _update(self) -> None:
        """The sinks each hook calls, in order (after a change of ``_sinks``)."""
        self._by_hook = {h: tuple(s for s in self._sinks if not _noop(s, h)) for h in _HOOKS}
        self._on_sample = self._by_hook["sample"]
        self._on_epoch = self._by_hook["epoch"]

    def takes_runs(self) -> bool:
        """Whether every sink that watches samples takes IMU runs (``imu_run``)."""
        return all(callable(getattr(s, "imu_run", None)) for s in self._on_sample)

    @property
    def active(self) -> list[Sink]:
        return list(self._sinks)

    def _call(self, hook: str, *args) -> None:
        for sink in self._by_hook[hook]:
            try:
                getattr(sink, hook)(*args)
            except Exception as exc:  # a sink must never stop the monitor
                self._drop(sink, hook, exc)

    def _drop(self, sink: Sink, hook: str, exc: BaseException) -> None:
        text = f"{type(exc).__name__}: {exc}"
        self._summary.sink_failures[sink.name] = f"{hook}: {text}"
        log.warning("sink %s failed in %s (%s); it is dropped, the monitor goes on", sink.name, hook, text)
        if sink in self._sinks:
            self._sinks.remove(sink)
            self._update()
        if hook != "close":
            try:
                sink.close(self._summary)
            except Exception:
                pass

    def start(self, info: dict) -> None:
        self._call("start", info)

    def sample(self, s) -> None:
        for sink in self._on_sample:  # _call, inline: once per sample
            try:
                sink.sample(s)
            except Exception as exc:
                self._drop(sink, "sample", exc)

    def imu_run(self, run, i: int, j: int) -> None:
        """The IMU samples ``i .. j - 1`` of ``run``, to every sink that
        watches samples (all take runs: :meth:`takes_runs`)."""
        for sink in self._on_sample:
            try:
                sink.imu_run(run, i, j)
            except Exception as exc:
                self._drop(sink, "sample", exc)

    def epoch(self, report: EpochReport) -> None:
        for sink in self._on_epoch:
            try:
                sink.epoch(report)
            except Exception as exc:
                self._drop(sink, "epoch", exc)

    def alarm(self, event: AlarmEvent) -> None:
        self._call("alarm", event)

    def close(self) -> None:
        self._call("close", self._summary)
