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
    """
    summary = RunSummary()
    out = SinkSet(sinks, summary)
    monitor = Monitor(cfg)
    frame = HomeFrame()
    out.start({"mode": cfg.monitor.mode, "config": cfg, **(info or {})})
    push = monitor.push
    on_sample = frame.sample
    sample_out = out.sample
    epoch_out = out.epoch
    on_report = frame.report
    spans = summary.spans
    try:
        for s in source:
            sample_out(on_sample(s))
            if isinstance(s, Reboot):
                summary.reboots += 1
            for report, events in push(s):
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
            if should_stop is not None and should_stop():
                break
    finally:
        summary.monitor_counters = dict(monitor.counters)  # type: ignore[attr-defined]
        out.close()
    return summary
