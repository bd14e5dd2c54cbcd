"""Rerun viewer sink: every height, residual, threshold and alarm on one
vehicle-time axis, live during a flight or scrubbing through a log.

The sink writes to one explicit :class:`rerun.RecordingStream` that the
CLI edge (:mod:`mavnav.cli.viewer_options`) has connected to its targets (a
spawned viewer, a web viewer, a running viewer, an ``.rrd`` file); it never
touches Rerun's global recording. What goes where is listed in
:mod:`mavnav.sinks.rerun_blueprint`.

Time. One timeline, ``vehicle_time`` (a duration, nanosecond exact), from
the reports' and samples' vehicle time. Vehicle time restarts at a reboot;
so that one axis stays monotonic, boot ``k > 0`` is shifted to continue from
the last vehicle time of boot ``k - 1`` (``vehicle_time = t_s + offset_k``,
``offset_0 = 0``); each reboot is a line in ``input/events`` giving the
offset. Events without a vehicle time (link loss, rejected frames) are placed
at the latest vehicle time seen.

Sending. Replays buffer columns and send them with ``send_columns`` in
large batches and at close. Live runs send what came in every
``live_batch_s`` of vehicle time (0.25 s by default), and at once after an
epoch with an alarm, so the viewer follows the flight a quarter second
behind; ``live_batch_s=0`` logs every row as it comes (``log`` with
``set_time``), at about ten times the cost (2.5 ms against 0.2-0.5 ms per
epoch here). The recording holds the same values every way.

Raw heights wait for the epoch that judged them (the first epoch at or
after their vehicle time, in stream order): a sample the monitor used goes to
``heights/raw/<sensor>``, one it refused (its source excluded, in alarm, or
the gate keeping it out of its channel: the channel's row for that sensor is
NaN at that epoch) to ``heights/rejected/<sensor>``, which the pilot's plot
does not show (:func:`raw_used`). The pilot's readout (``pilot/readout``) is
written every ``readout_interval_s`` of vehicle time and at every change of
a source's or the overall state (:func:`readout_markdown`).

Outputs. The stream writes to every target at once with Rerun's own
multi-sink (``set_sinks``): the chunks are made once for the file and the
viewers. A viewer that goes away stays one of the stream's sinks (Rerun
drops what it can no longer send there; replacing the sinks would reopen,
and so empty, the ``.rrd``).

Failures. Logging never stops the monitor. Rerun itself does not raise on a
viewer that goes away, so the sink checks its viewers (at most once a
second of wall clock) and reports a lost one once, as a warning; it keeps
writing to an ``.rrd`` if there is one, and stops logging when nothing is
left to write to. A programming error in the sink raises, and
:class:`~mavnav.sinks.base.SinkSet` drops the sink; the monitor's results
never depend on this sink.
"""

from __future__ import annotations

import logging
import math
import re
import time
from collections import deque
from dataclasses import dataclass, field
from typing import Callable, Optional, Sequence

import numpy as np
import rerun as rr

from ..home_frame import home_moved_text
from ..report import CHANNEL_NAMES, SOURCES, AlarmEvent, EpochReport, RunSummary
from ..sensors import BARO, BARO_INS, GNSS, RANGEFINDER
from ..samples import (
    AutopilotHeight,
    BaroHeight,
    Gap,
    GnssHeight,
    LinkLost,
    LinkRecovered,
    Notice,
    RangeHeight,
    Reboot,
    ReferenceMoved,
    ReferenceSet,
    Rejected,
)
from . import rerun_blueprint as bp
from .base import Sink

log = logging.getLogger("mavnav.sinks.rerun")

NS_PER_US = 1000
NS_PER_S = 1_000_000_000
READOUT_INTERVAL_S = 0.2  # the pilot's readout, at most this long behind the epochs (vehicle time)


# --------------------------------------------------------------------------
# Vehicle time across reboots


class BootClock:
    """Maps (boot, vehicle time) to one monotonic ``vehicle_time`` in ns.

    Boot 0 is unshifted. A later boot continues from the last time seen in
    the boot before it (or the ``last_t_us`` a :class:`Reboot` reports).
    """

    def __init__(self) -> None:
        self.offset_ns: dict[int, int] = {}
        self._last_raw_ns: dict[int, int] = {}
        self.now_ns = 0  # latest vehicle_time seen

    def reboot(self, boot: int, first_t_us: int, last_t_us: int) -> int:
        prev = boot - 1
        if prev in self.offset_ns:
            self._last_raw_ns[prev] = max(self._last_raw_ns.get(prev, 0), last_t_us * NS_PER_US)
        return self._offset(boot, first_t_us * NS_PER_US)

    def _offset(self, boot: int, raw_ns: int) -> int:
        off = self.offset_ns.get(boot)
        if off is None:
            earlier = [b for b in self.offset_ns if b < boot]
            if not earlier:
                off = 0
            else:
                prev = max(earlier)
                end_prev = self.offset_ns[prev] + self._last_raw_ns.get(prev, 0)
                off = max(0, end_prev - raw_ns)
            self.offset_ns[boot] = off
        return off

    def ns(self, boot: Optional[int], t_us: Optional[int]) -> int:
        if t_us is None or boot is None:
            return self.now_ns
        raw = int(t_us) * NS_PER_US
        ns = self._offset(int(boot), raw) + raw
        if raw > self._last_raw_ns.get(boot, -1):
            self._last_raw_ns[boot] = raw
        if ns > self.now_ns:
            self.now_ns = ns
        return ns


# --------------------------------------------------------------------------
# Writers: rows (live) or buffered columns (replay)


class _RowWriter:
    """Logs every row at once (live)."""

    def __init__(self, rec: rr.RecordingStream):
        self.rec = rec

    def _at(self, ns: int) -> None:
        self.rec.set_time(bp.TIMELINE, duration=np.timedelta64(int(ns), "ns"))

    def scalars(self, entity: str, ns: int, values: Sequence[float]) -> None:
        self._at(ns)
        self.rec.log(entity, rr.Scalars(np.asarray(values, dtype=np.float64)))

    def text(self, entity: str, ns: int, text: str, level: str, colour) -> None:
        self._at(ns)
        self.rec.log(entity, rr.TextLog(text, level=level, color=colour))

    def state(self, entity: str, ns: int, state: str) -> None:
        self._at(ns)
        self.rec.log(entity, rr.StateChange(state=[state]))

    def document(self, entity: str, ns: int, markdown: str) -> None:
        self._at(ns)
        self.rec.log(entity, rr.TextDocument(markdown, media_type=rr.MediaType.MARKDOWN))

    def pending(self) -> int:
        return 0

    def send_one(self) -> None:
        pass

    def flush(self) -> None:
        pass


@dataclass
class _Column:
    times: list = field(default_factory=list)
    values: list = field(default_factory=list)
    extra: list = field(default_factory=list)  # text: (level, colour)


class _ColumnWriter:
    """Buffers rows per entity and sends them with ``send_columns``: in large
    batches (replay), or every ``every_ns`` of vehicle time (live).

    Live, a batch that falls due is queued per entity and sent one entity per
    call of :meth:`send_one` (the sink calls it once per message), so no
    message waits for the whole batch (about 30 entities at 75 us each); the
    queue is emptied before the next batch is queued, and :meth:`flush`
    (an alarm, close) sends everything at once."""

    def __init__(self, rec: rr.RecordingStream, batch_rows: int, every_ns: Optional[int] = None):
        self.rec = rec
        self.batch_rows = batch_rows
        self.every_ns = every_ns
        self._scalars: dict[str, _Column] = {}
        self._texts: dict[str, _Column] = {}
        self._states: dict[str, _Column] = {}
        self._docs: dict[str, _Column] = {}
        self._n = 0
        self._since_ns: Optional[int] = None  # vehicle time of the oldest buffered row
        self._queue: deque = deque()  # (kind, entity, column) of a batch due, in sending order

    def _add(self, table: dict, entity: str, ns: int, value, extra=None) -> None:
        col = table.get(entity)
        if col is None:
            col = table[entity] = _Column()
        col.times.append(ns)
        col.values.append(value)
        if extra is not None:
            col.extra.append(extra)
        self._n += 1
        if self._since_ns is None:
            self._since_ns = ns
        if self._n >= self.batch_rows:
            self.flush()
        elif self.every_ns is not None and ns - self._since_ns >= self.every_ns:
            self._queue_batch()

    def scalars(self, entity: str, ns: int, values: Sequence[float]) -> None:
        self._add(self._scalars, entity, ns, tuple(values))

    def text(self, entity: str, ns: int, text: str, level: str, colour) -> None:
        self._add(self._texts, entity, ns, text, (level, colour))

    def state(self, entity: str, ns: int, state: str) -> None:
        self._add(self._states, entity, ns, state)

    def document(self, entity: str, ns: int, markdown: str) -> None:
        self._add(self._docs, entity, ns, markdown)

    def pending(self) -> int:
        return self._n + sum(len(col.times) for _, _, col in self._queue)

    @staticmethod
    def _index(col: _Column) -> list:
        return [rr.TimeColumn(bp.TIMELINE, duration=np.asarray(col.times, dtype=np.int64).astype("timedelta64[ns]"))]

    def _take(self) -> list:
        """The buffered columns as ``(kind, entity, column)`` in sending order; the buffers start empty."""
        items = [("scalars", e, c) for e, c in self._scalars.items()]
        items += [("text", e, c) for e, c in self._texts.items()]
        items += [("state", e, c) for e, c in self._states.items()]
        items += [("doc", e, c) for e, c in self._docs.items()]
        self._scalars, self._texts, self._states, self._docs, self._n, self._since_ns = {}, {}, {}, {}, 0, None
        return items

    def _queue_batch(self) -> None:
        while self._queue:  # the previous batch goes first, whole
            self._send(*self._queue.popleft())
        self._queue.extend(self._take())

    def send_one(self) -> None:
        """Send one queued entity's columns, if any."""
        if self._queue:
            self._send(*self._queue.popleft())

    def flush(self) -> None:
        while self._queue:
            self._send(*self._queue.popleft())
        for item in self._take():
            self._send(*item)

    def _send(self, kind: str, entity: str, col: _Column) -> None:
        if kind == "scalars":
            values = np.asarray(col.values, dtype=np.float64)
            self.rec.send_columns(entity, indexes=self._index(col), columns=rr.Scalars.columns(scalars=values))
        elif kind == "text":
            levels = [lv for lv, _ in col.extra]
            colours = np.asarray([c for _, c in col.extra], dtype=np.uint8)
            self.rec.send_columns(
                entity,
                indexes=self._index(col),
                columns=rr.TextLog.columns(text=col.values, level=levels, color=colours),
            )
        elif kind == "state":
            self.rec.send_columns(entity, indexes=self._index(col), columns=rr.StateChange.columns(state=col.values))
        else:
            self.rec.send_columns(entity, indexes=self._index(col), columns=rr.TextDocument.columns(
                text=col.values, media_type=[str(rr.MediaType.MARKDOWN)] * len(col.values)))


# --------------------------------------------------------------------------
# Input health: rates per second of vehicle time, rejected counts


class _Rates:
    """Counts samples per kind in whole seconds of vehicle time.

    A second is closed when any sample reaches a later one; every kind seen
    so far then gets a rate, 0 when it was silent. The last, partial second
    is not reported.
    """

    MAX_EMPTY_BINS = 600  # a longer jump reports one zero and resumes

    def __init__(self) -> None:
        self.bin: Optional[int] = None
        self.counts: dict[str, int] = {}

    def observe(self, kind: str, ns: int, emit: Callable[[str, int, float], None]) -> None:
        b = ns // NS_PER_S
        if self.bin is None:
            self.bin = b
        if b > self.bin:
            jump = b - self.bin
            self._close(emit)
            if jump > 1:
                # silent seconds: every kind at 0
                for k in range(1, min(jump, self.MAX_EMPTY_BINS)):
                    for kind_seen in self.counts:
                        emit(kind_seen, (self.bin + k + 1) * NS_PER_S, 0.0)
            self.bin = b
        self.counts[kind] = self.counts.get(kind, 0) + 1

    def _close(self, emit) -> None:
        end_ns = (self.bin + 1) * NS_PER_S
        for kind, n in self.counts.items():
            emit(kind, end_ns, float(n))
            self.counts[kind] = 0


_SAFE = re.compile(r"[^A-Za-z0-9_\-]")


def _part(text: str) -> str:
    return _SAFE.sub("_", str(text)) or "_"


# --------------------------------------------------------------------------
# The sink


HealthCheck = Callable[[], Optional[str]]  # None while fine, else why it is gone


@dataclass
class ViewerTarget:
    """A place the recording goes that can go away (a viewer, a gRPC server)."""

    description: str
    check: HealthCheck
    lost: Optional[str] = None


class RerunSink(Sink):
    """Logs epochs, alarms and input events to a Rerun recording.

    ``rec`` has its sinks already set (an ``.rrd`` file, gRPC servers);
    ``targets`` are the viewers among them to watch, ``has_file`` says an
    ``.rrd`` is one of them. After every viewer is gone and there is no
    file, logging stops. ``on_close`` callbacks run after the recording is
    flushed (e.g. keep a web viewer serving).
    """

    name = "rerun"

    def __init__(
        self,
        rec: rr.RecordingStream,
        *,
        live: bool,
        targets: Sequence["ViewerTarget"] = (),
        has_file: bool = False,
        window_s: float = 30.0,
        batch_rows: int = 200_000,
        live_batch_s: float = 0.25,
        check_interval_s: float = 1.0,
        flush_timeout_s: float = 10.0,
        readout_interval_s: float = READOUT_INTERVAL_S,
        on_close: Sequence[Callable[[], None]] = (),
    ):
        """``live_batch_s``: live runs send every this many seconds of vehicle
        time (0: every row at once); ``batch_rows``: most rows buffered;
        ``readout_interval_s``: the pilot's readout between state changes."""
        self.rec = rec
        self.targets = list(targets)
        self.has_file = has_file
        self.live = live
        self.window_s = window_s
        self.check_interval_s = check_interval_s
        self.flush_timeout_s = flush_timeout_s
        self.on_close = list(on_close)
        self.clock = BootClock()
        if not live:
            self.writer = _ColumnWriter(rec, batch_rows)
        elif live_batch_s > 0:
            self.writer = _ColumnWriter(rec, batch_rows, every_ns=int(live_batch_s * NS_PER_S))
        else:
            self.writer = _RowWriter(rec)
        self._urgent = False
        self.enabled = bool(self.targets) or has_file
        self._styled: set[str] = set()
        self._states: dict[str, str] = {}
        self._rates = _Rates()
        self._rejected: dict[str, int] = {}
        self._next_check = 0.0
        self._closed = False
        self.readout_every_ns = int(readout_interval_s * NS_PER_S)
        self._readout_ns: Optional[int] = None  # vehicle time of the last readout
        self._readout_states: Optional[tuple] = None  # the states it showed
        self._raw_pending: list[tuple[int, int, int, str, float]] = []  # (boot, t_us, ns, sensor, height)

    # -- setup -------------------------------------------------------------

    def start(self, info: dict) -> None:
        rec = self.rec
        rec.set_log_tick_enabled(False)
        rec.set_log_time_enabled(False)
        source = info.get("source")
        if source:
            rec.send_recording_name(f"mavnav: {source}")
        rec.send_blueprint(bp.blueprint(self.live, self.window_s), make_active=True, make_default=True)
        for entity, archetype in bp.series_styles():
            self._style(entity, archetype)
        self._check_targets(force=True)

    def _style(self, entity: str, archetype) -> None:
        if entity not in self._styled:
            self._styled.add(entity)
            self.rec.log(entity, archetype, static=True)

    # -- viewer health -----------------------------------------------------

    def _check_targets(self, force: bool = False) -> None:
        now = time.monotonic()
        if not force and now < self._next_check:
            return
        self._next_check = now + self.check_interval_s
        for target in self.targets:
            if target.lost is not None:
                continue
            try:
                why = target.check()
            except Exception as exc:  # a broken probe counts as a lost viewer
                why = f"{type(exc).__name__}: {exc}"
            if why is not None:
                self._lose(target, why)

    def _lose(self, target: "ViewerTarget", why: str) -> None:
        """Report a viewer gone (once); stop logging when nothing is left to write to."""
        target.lost = why
        log.warning(
            "rerun: %s is gone (%s) at vehicle time %.3f s; the monitor goes on without it%s",
            target.description,
            why,
            self.clock.now_ns / NS_PER_S,
            " (the .rrd file is still written)" if self.has_file else "",
        )
        if not self.has_file and all(t.lost is not None for t in self.targets):
            self.enabled = False

    @property
    def lost(self) -> list[str]:
        """Descriptions of the viewers that went away."""
        return [t.description for t in self.targets if t.lost is not None]

    # -- hooks -------------------------------------------------------------

    def sample(self, s) -> None:
        if not self.enabled:
            return
        w = self.writer
        w.send_one()  # a live batch due goes out one entity per message
        if isinstance(s, Reboot):
            self._judge_raw(None)  # the old boot's epochs are over: what they did not judge is shown as is
            offset = self.clock.reboot(s.boot, s.t_us, s.last_t_us)
            ns = self.clock.ns(s.boot, s.t_us)
            w.text(
                "input/events",
                ns,
                f"reboot: boot {s.boot} begins at vehicle time {s.t_us * 1e-6:.3f} s "
                f"(previous boot ended at {s.last_t_us * 1e-6:.3f} s); plotted shifted by {offset / NS_PER_S:+.3f} s",
                "WARN",
                bp.STATE_COLOURS["caution"],
            )
            return
        if isinstance(s, (LinkLost, LinkRecovered)):
            ns = self.clock.now_ns
            if isinstance(s, LinkLost):
                w.text("input/events", ns, f"link lost: silent for {s.silent_s:.1f} s", "ERROR", bp.STATE_COLOURS["alarm"])
            else:
                w.text("input/events", ns, f"link recovered after {s.outage_s:.1f} s", "INFO", bp.STATE_COLOURS["nominal"])
            return
        if isinstance(s, Notice):  # what the input waits for, the vehicle chosen, systems ignored, clock steps
            w.text("input/events", self.clock.now_ns, s.text, "INFO", bp.STATE_COLOURS["nominal"])
            return
        if isinstance(s, Rejected):
            ns = self.clock.ns(s.boot, s.t_us)
            kind = _part(s.kind)
            n = self._rejected[kind] = self._rejected.get(kind, 0) + 1
            self._style(*bp.input_styles("rejected", kind))
            w.scalars(f"input/rejected/{kind}", ns, (float(n),))
            return
        t_us = getattr(s, "t_us", None)
        boot = getattr(s, "boot", None)
        ns = self.clock.ns(boot, t_us)
        if isinstance(s, Gap):
            kind = _part(s.kind)
            self._style(*bp.input_styles("gaps", kind))
            w.scalars(f"input/gaps/{kind}", ns, (float(s.length_s),))
            w.text("input/events", ns, f"gap: no {s.kind} for {s.length_s:.2f} s", "WARN", bp.STATE_COLOURS["caution"])
            return
        if isinstance(s, ReferenceMoved):
            w.text("input/events", ns, home_moved_text(s), "WARN", bp.STATE_COLOURS["caution"])
            return
        if isinstance(s, ReferenceSet):
            w.text(
                "input/events",
                ns,
                f"reference set: {s.kind} = {s.value:.3f} ({s.origin})",
                "INFO",
                bp.STATE_COLOURS["nominal"],
            )
            return
        kind = bp.RATE_KINDS.get(type(s).__name__)
        if kind is not None:
            self._rates.observe(kind, ns, self._emit_rate)
        if isinstance(s, BaroHeight):
            sensor = BARO if s.instance in (0, 1) else f"{BARO}{int(s.instance)}"
            self._raw_pending.append((s.boot, s.t_us, ns, sensor, s.height_ref_m))
        elif isinstance(s, GnssHeight):
            self._raw_pending.append((s.boot, s.t_us, ns, GNSS, s.height_ref_m))
        elif isinstance(s, RangeHeight):
            self._raw_pending.append((s.boot, s.t_us, ns, RANGEFINDER, s.height_agl_m))
        elif isinstance(s, AutopilotHeight):
            w.scalars("heights/autopilot", ns, (s.height_ref_m,))
        self._check_targets()

    def _judge_raw(self, report: Optional[EpochReport]) -> None:
        """Write the raw heights ``report`` judged (all pending with None: shown as used)."""
        keep = []
        for item in self._raw_pending:
            boot, t_us, ns, sensor, h = item
            if report is not None and boot == report.boot and t_us > report.t_us:
                keep.append(item)  # a later epoch takes it
                continue
            used = True if report is None or boot != report.boot else raw_used(sensor, report)
            entity = bp.raw_entity(sensor, used)
            if sensor not in bp.CHANNEL_NAMES:  # another baro instance
                word = f"{sensor} (raw)" if used else f"{sensor} (raw, not used)"
                self._style(entity, rr.SeriesPoints(colors=[bp.CHANNEL_COLOURS[BARO]], names=[word]))
            self.writer.scalars(entity, ns, (h,))
        self._raw_pending = keep

    def _readout(self, report: EpochReport, ns: int) -> None:
        states = (report.overall, *(st.state for st in report.sources.values()))
        last = self._readout_ns
        if last is not None and states == self._readout_states and 0 <= ns - last < self.readout_every_ns:
            return
        self._readout_ns, self._readout_states = ns, states
        self.writer.document(bp.READOUT, ns, readout_markdown(report))

    def _emit_rate(self, kind: str, ns: int, rate: float) -> None:
        self._style(*bp.input_styles("rate", kind))
        self.writer.scalars(f"input/rate/{kind}", ns, (rate,))

    def epoch(self, report: EpochReport) -> None:
        if not self.enabled:
            return
        ns = self.clock.ns(report.boot, report.t_us)
        if self._raw_pending:
            self._judge_raw(report)
        for entity, values in epoch_rows(report):
            self.writer.scalars(entity, ns, values)
        for entity, state in epoch_states(report):
            if self._states.get(entity) != state:
                self._states[entity] = state
                self.writer.state(entity, ns, state)
        self._readout(report, ns)
        if self._urgent:  # an alarm in this epoch: show it now, with its state change
            self._urgent = False
            self.writer.flush()
        self._check_targets()

    def alarm(self, event: AlarmEvent) -> None:
        if not self.enabled:
            return
        ns = self.clock.ns(event.boot, event.t_us)
        self.writer.text(
            "alarms",
            ns,
            alarm_text(event),
            bp.STATE_LEVELS.get(event.state, "WARN"),
            bp.STATE_COLOURS.get(event.state, (199, 199, 199)),
        )
        self._urgent = self.live

    def close(self, summary: RunSummary) -> None:
        if self._closed:
            return
        self._closed = True
        try:
            if self.enabled:
                self._judge_raw(None)
                self.writer.flush()
            self._check_targets(force=True)
            try:
                self.rec.flush(timeout_sec=self.flush_timeout_s)
            except Exception as exc:  # a sink that does not take the data: a viewer gone, said once
                if not self.targets or any(t.lost is None for t in self.targets):
                    log.warning("rerun: could not flush the recording (%s: %s)", type(exc).__name__, exc)
            self.rec.disconnect()
        finally:
            for callback in self.on_close:
                try:
                    callback()
                except Exception as exc:
                    log.warning("rerun: after close: %s: %s", type(exc).__name__, exc)


# --------------------------------------------------------------------------
# What one epoch shows (pure functions)


def _f(x) -> float:
    """A plottable float: None and +-inf become NaN (a gap in the line)."""
    if x is None:
        return math.nan
    x = float(x)
    return x if math.isfinite(x) else math.nan


def epoch_rows(r: EpochReport) -> list[tuple[str, tuple[float, ...]]]:
    """Scalar rows of one epoch: (entity, values).

    Non-finite values (an unbounded VPL, no fused height) are NaN, a gap; a
    pair's difference and threshold are NaN while the pair is not valid.
    """
    rows: list[tuple[str, tuple[float, ...]]] = []
    for ch in r.channels:
        rows.append((bp.channel_entity(ch.name), (_f(ch.height_ref_m),)))
        rows.append((f"integrity/nis/{ch.name}", (_f(ch.nis) if ch.dof > 0 else math.nan,)))
        rows.append((f"integrity/norm_innov/{ch.name}", (_f(ch.norm_innov_baro), _f(ch.norm_innov_aux))))
    h, s = _f(r.height_fused_m), _f(r.sigma_fused_m)
    rows.append(("heights/fused", (h,)))
    rows.append(("heights/fused_sigma", (h - s, h + s)))
    for p in r.pairs:  # shown while both channels are available (the test is meaningless otherwise)
        diff, thr = (_f(p.diff_m), _f(p.threshold_m)) if p.valid else (math.nan, math.nan)
        rows.append((bp.pair_entity(p.name, "diff"), (diff,)))
        rows.append((bp.pair_entity(p.name, "threshold"), (thr, -thr)))
    for src in SOURCES:
        st = r.sources.get(src)
        if st is None:
            continue
        w = (_f(st.window_stat), _f(st.window_low), _f(st.window_high))
        if not all(math.isnan(v) for v in w):
            rows.append((f"integrity/window/{src}", w))
    rows.append(("integrity/vpl", (_f(r.vpl_m),)))
    rows.append(("integrity/alert_limit", (_f(r.alert_limit_m),)))
    return rows


def epoch_states(r: EpochReport) -> list[tuple[str, str]]:
    """State lanes of one epoch: (entity, state); the sink logs changes only."""
    out = [(f"state/source/{src}", r.sources[src].state) for src in SOURCES if src in r.sources]
    out.append(("state/overall", r.overall))
    for ch in r.channels:
        out.append((f"state/channel/{ch.name}", "used" if ch.used else ("available" if ch.available else "unavailable")))
    return out


def raw_used(sensor: str, r: EpochReport) -> bool:
    """Whether the monitor used a raw height of ``sensor`` judged at epoch ``r``.

    Not when its source is in alarm (excluded), nor, for GNSS and the
    rangefinder, when the source is usable (nominal, caution) but its channel
    took no row of that sensor at that epoch (``norm_innov_aux`` NaN: the gate
    refused it, or it came too late). Otherwise (the baro of a usable
    baro+INS, a source still unavailable) it is shown as used.
    """
    source = BARO_INS if sensor.startswith(BARO) else sensor
    st = r.sources.get(source)
    if st is None:
        return True
    if st.state == "alarm":
        return False
    if source in CHANNEL_NAMES and st.state in ("nominal", "caution"):
        aux = r.channels[CHANNEL_NAMES.index(source)].norm_innov_aux
        return aux == aux
    return True


_WHAT_TO_DO = {
    "nominal": "",
    "caution": "Carry on; watch the named source, be ready.",
    "unavailable": "Do not rely on this height near the ground: keep a margin.",
    "alarm": "Stop height-critical work; hold or climb to a safe height; cross-check.",
}


def readout_markdown(r: EpochReport) -> str:
    """The pilot's readout of one epoch: the fused height and the overall state in large
    type, then what is not nominal and why, and what to do (README's table, in short)."""
    h, s = _f(r.height_fused_m), _f(r.sigma_fused_m)
    height = f"{h:.1f} m" if h == h else "no height"
    sigma = f"±{s:.1f} m (1σ) above home" if s == s else "above home"
    vpl = _f(r.vpl_m)
    protection = (f"protection level {vpl:.1f} m, alert limit {r.alert_limit_m:.1f} m" if vpl == vpl
                  else f"no protection level (alert limit {r.alert_limit_m:.1f} m)")
    lines = [f"# {height}", f"{sigma}; {protection}", "", f"# {r.overall.upper()}"]
    todo = _WHAT_TO_DO.get(r.overall, "")
    if todo:
        lines += ["", f"*{todo}*"]
    lines.append("")
    fine = []
    for src in SOURCES:
        st = r.sources.get(src)
        if st is None:
            continue
        word = bp.SOURCE_WORDS.get(src, src)
        if st.state == "nominal":
            fine.append(word)
        else:
            lines.append(f"- **{word} {st.state}**: {st.reason}" if st.reason else f"- **{word} {st.state}**")
    if fine:
        lines.append(f"- nominal: {', '.join(fine)}")
    lines += ["", f"vehicle time {r.t_s:.1f} s, boot {r.boot}"]
    return "\n".join(lines)


def alarm_text(e: AlarmEvent) -> str:
    text = f"{e.source}: {e.previous} -> {e.state}"
    return f"{text}: {e.reason}" if e.reason else text


__all__ = ["RerunSink", "ViewerTarget", "BootClock", "epoch_rows", "epoch_states", "alarm_text", "raw_used",
           "readout_markdown"]
