"""One pure fold over time-ordered samples: source -> monitor -> sinks.

Live and replay run this same function; only the source differs (a
:class:`~mavnav.ingest.TlogSource` or a :class:`~mavnav.ingest.LiveSource`)
and the CLI chooses the sinks. The monitor takes time from the data only.
Sinks see heights above the autopilot's current home (:mod:`.home_frame`);
the monitor sees them in the frame its references were fixed in.
"""

from __future__ import annotations

from typing import Callable, Iterable, Optional

from .config import Config
from .home_frame import HomeFrame
from .ingest.onboard.imurun import ImuRun
from .monitor import Monitor
from .report import RunSummary
from .samples import Reboot
from .sinks.base import Sink, SinkSet


def run(
    source: Iterable,
    cfg: Config,
    sinks: Iterable[Sink] = (),
    *,
    info: Optional[dict] = None,
    should_stop: Optional[Callable[[], bool]] = None,
) -> RunSummary:
    """Feed every sample of ``source`` through the monitor into ``sinks``.

    Returns the run summary (epochs, alarm events, failed sinks). Stops early
    when ``should_stop()`` turns true (checked between samples). Sinks are
    always closed, also on an exception or KeyboardInterrupt.

    A source whose class has a ``runs()`` stream (an onboard log: its IMU
    samples as :class:`~.ingest.onboard.imurun.ImuRun` columns; not a wrapper
    that passes attributes through) is read through it when
    there is no ``should_stop`` and every sink that watches samples takes
    runs (an ``imu_run`` hook): each run goes through the monitor and the
    sinks a slice at a time, up to the sample that completes an epoch, the
    same fold as one sample at a time.
    """
    summary = RunSummary()
    out = SinkSet(sinks, summary)
    monitor = Monitor(cfg)
    frame = HomeFrame()
    out.start({"mode": cfg.monitor.mode, "config": cfg, **(info or {})})
    push = monitor.push
    push_run = monitor.push_run
    on_sample = frame.sample
    sample_out = out.sample
    run_out = out.imu_run
    epoch_out = out.epoch
    on_report = frame.report
    spans = summary.spans

    def epochs(done) -> None:
        for report, events in done:
            summary.epochs += 1
            t_us = report.t_us
            if summary.first_t_us is None:
                summary.first_t_us = t_us
            summary.last_t_us = t_us
            if spans and spans[-1][0] == report.boot:
                spans[-1][2] = t_us
            else:
                spans.append([report.boot, t_us, t_us])
            for ev in events:
                summary.alarms.append(ev)
                out.alarm(ev)
            epoch_out(on_report(report))

    # a source's own class must say it has runs: a wrapper that passes its
    # attributes through (FaultedSource, whose faults act on each sample) does not
    if callable(getattr(type(source), "runs", None)) and should_stop is None and out.takes_runs():
        source = source.runs()
    try:
        for s in source:
            if type(s) is ImuRun:  # no home-frame change (not a height), not a reboot
                ts, fs, i, j, ta, fa = s.t_us, s.f_up, s.lo, s.hi, s.t_arr, s.f_arr
                while i < j:
                    k, done = push_run(ts, fs, i, j, ta, fa)
                    run_out(s, i, k)
                    i = k
                    if done:
                        epochs(done)
                continue
            sample_out(on_sample(s))
            if isinstance(s, Reboot):
                summary.reboots += 1
            done = push(s)
            if done:
                epochs(done)
            if should_stop is not None and should_stop():
                break
    finally:
        summary.monitor_counters = monitor.counts()  # type: ignore[attr-defined]
        out.close()
    return summary
