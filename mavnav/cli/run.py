"""``mavnav run`` (live daemon) and ``mavnav replay`` (a recorded tlog).

Both run :func:`mavnav.pipeline.run`, the same fold; only the source and
the pacing differ. The wall clock is read here and nowhere in the core.
"""

from __future__ import annotations

import signal
import sys
import time
from typing import TYPE_CHECKING, Iterable, Iterator, Optional

import click

from ..errors import MavnavError
from ..home_frame import home_moved_text
from ..report import AlarmEvent, RunSummary
from ..samples import LinkLost, LinkRecovered, Notice, Reboot, ReferenceMoved, ReferenceSet
from ..sensors import BARO
from ..sinks.base import Sink
from ..sinks.csv_sink import CsvSink
from . import main
from .emit_options import emit_options, emit_sinks
from .honest import check_outputs, has_vehicle_data, no_vehicle_error
from .viewer_options import viewer_options, viewer_settings, viewer_sinks

# The monitor, its sources and sinks (numba, scipy, pymavlink, rerun) are
# imported where a command runs, not when the CLI parses its arguments.
if TYPE_CHECKING:
    from ..config import Config, ViewerSection


def common_options(f):
    """``--config``, ``--sysid``, ``--csv``, ``--inject``: shared by run, replay and audit."""
    f = click.option("--inject", "inject", multiple=True, metavar="FAULT",
                     help="Inject a fault into the input's samples, as 'mavnav inject' does to a tlog "
                          "(repeatable; e.g. gnss_step:onset=60,duration=20,magnitude=10). "
                          "Onsets are vehicle time of the log.")(f)
    f = click.option("--csv", "csv_path", type=click.Path(dir_okay=False, writable=True), default=None,
                     help="Write the estimates of every epoch to this CSV file.")(f)
    f = click.option("--sysid", type=click.IntRange(1, 255), default=None,
                     help="Vehicle system id (default: the first autopilot heartbeat); with --allow-commands "
                          "the rate requests go to its autopilot.")(f)
    f = click.option("--config", "config_path", type=click.Path(dir_okay=False), default=None,
                     help="Configuration YAML (default: built-in small-drone defaults).")(f)
    return f


REFERENCE_ORIGIN_WORDS = {
    "config": "configured",
    "home": "from HOME_POSITION",
    "autopilot_home": "from the autopilot's home in GLOBAL_POSITION_INT",
    "ekf_origin": "from the EKF origin (GPS_GLOBAL_ORIGIN, LOCAL_POSITION_NED)",
    "startup": ("start-up mean: nothing from the autopilot in time, the vehicle is taken to have been "
                "at the reference point when the data started"),
}


def _recv(recv_s: float) -> str:
    return f"[recv {time.strftime('%H:%M:%S', time.localtime(recv_s))}]"


class AlarmPrinter(Sink):
    """Alarm transitions on stderr as they happen (the daemon's console), and what
    the input says a person should know: link loss, what it waits for, the
    references it fixed."""

    name = "console"

    def alarm(self, ev: AlarmEvent) -> None:
        click.echo(f"[t={ev.t_s:9.3f} s boot {ev.boot}] {ev.source:<11} {ev.previous} -> {ev.state}: {ev.reason}",
                   err=True)

    def sample(self, s) -> None:
        # a live link's loss and recovery, as they happen (receive clock, not vehicle time)
        ts = type(s)
        if ts is LinkLost:
            click.echo(f"{_recv(s.recv_s)} input       LINK LOST: no data from the vehicle for {s.silent_s:.1f} s",
                       err=True)
        elif ts is LinkRecovered:
            click.echo(f"{_recv(s.recv_s)} input       link recovered after {s.outage_s:.1f} s", err=True)
        elif ts is Notice:
            click.echo(f"{_recv(s.recv_s)} input       {s.text}", err=True)
        elif ts is Reboot:
            click.echo(f"[t={s.t_us * 1e-6:9.3f} s boot {s.boot}] input       VEHICLE REBOOTED: its time restarted at "
                       f"{s.t_us * 1e-6:.3f} s after {s.last_t_us * 1e-6:.3f} s of boot {s.boot - 1}; "
                       f"the monitor starts again", err=True)
        elif ts is ReferenceMoved:
            click.echo(f"[t={s.t_us * 1e-6:9.3f} s boot {s.boot}] input       {home_moved_text(s)}", err=True)
        elif ts is ReferenceSet:
            value = f"{s.value:.1f} Pa" if s.kind == BARO else f"{s.value:.2f} m"
            at = f", reference point {s.alt_ref_msl_m:.2f} m MSL" if s.alt_ref_msl_m is not None else ""
            click.echo(f"[t={s.t_us * 1e-6:9.3f} s boot {s.boot}] input       height reference ({s.kind}): "
                       f"{value}{at}, {REFERENCE_ORIGIN_WORDS.get(s.origin, s.origin)}", err=True)


def print_summary(summary: RunSummary, title: str) -> None:
    span = ""
    spans = summary.spans
    if len(spans) == 1:
        _, t0, t1 = spans[0]
        span = f", vehicle time {t0 * 1e-6:.1f}-{t1 * 1e-6:.1f} s"
    elif spans:  # vehicle time restarts at each reboot: one span per boot, and their sum
        total = sum(t1 - t0 for _, t0, t1 in spans) * 1e-6
        span = ", vehicle time " + ", ".join(f"{t0 * 1e-6:.1f}-{t1 * 1e-6:.1f} s (boot {b})" for b, t0, t1 in spans)
        span += f" ({total:.1f} s in all)"
    alarms = [a for a in summary.alarms if a.state == "alarm"]
    click.echo(f"{title}: {summary.epochs} epochs{span}, {len(alarms)} alarms, {summary.reboots} reboots", err=True)
    for name, why in summary.sink_failures.items():
        click.echo(f"  sink {name} failed and was dropped: {why}", err=True)


def paced(source: Iterable, speed: Optional[float]) -> Iterator:
    """Release samples at ``speed`` times their vehicle-time pace (None: as fast as possible)."""
    if speed is None:
        yield from source
        return
    t0_vehicle: Optional[int] = None
    t0_wall = 0.0
    boot = None
    for s in source:
        t_us = getattr(s, "t_us", None)
        b = getattr(s, "boot", None)
        if t_us is not None and b is not None:
            if t0_vehicle is None or b != boot:
                t0_vehicle, t0_wall, boot = t_us, time.monotonic(), b
            due = t0_wall + (t_us - t0_vehicle) * 1e-6 / speed
            delay = due - time.monotonic()
            if delay > 0:
                time.sleep(delay)
        yield s


def parse_speed(text: str) -> Optional[float]:
    if text == "max":
        return None
    if text == "realtime":
        return 1.0
    try:
        v = float(text)
    except ValueError:
        raise click.BadParameter("realtime, max, or a positive factor (e.g. 4)") from None
    if not v > 0:
        raise click.BadParameter("the factor must be positive")
    return v


def build_sinks(cfg: Config, csv_path: Optional[str], live: bool, viewer: ViewerSection,
                emit_flags: dict, sysid: Optional[int] = None) -> list[Sink]:
    sinks: list[Sink] = [AlarmPrinter()]
    if csv_path:
        sinks.append(CsvSink(csv_path))
    sinks += viewer_sinks(viewer, live=live)
    sinks += emit_sinks(cfg, emit_flags, live_input=live, say=lambda text: click.echo(text, err=True),
                        vehicle_sysid=sysid)
    return sinks


@main.command("run")
@click.argument("connection")
@common_options
@viewer_options
@emit_options
def run_cmd(connection: str, config_path, sysid, csv_path, inject, viewer_flags, emit_flags) -> None:
    """Attach to a live autopilot link and monitor it until interrupted.

    CONNECTION is any pymavlink connection string: udpin:0.0.0.0:14550,
    udpout:HOST:PORT, tcp:HOST:PORT, tcpin:0.0.0.0:5760, or a serial device
    with its baud rate (/dev/ttyACM0,115200). SIGINT or SIGTERM stop it
    cleanly with a summary.
    """
    from ..config import load_config
    from ..ingest import LiveSource
    from ..pipeline import run as run_pipeline
    from ..sim.effects import FaultedSource
    from ..sim.faults import parse_faults

    cfg = load_config(config_path)
    viewer = viewer_settings(cfg, viewer_flags)
    faults = parse_faults(inject)
    check_outputs({"--csv": csv_path, "--rrd": viewer.rrd})
    live = source = LiveSource(connection, cfg.ingest, sysid=sysid)
    if faults:
        source = FaultedSource(live, faults)
    stop = {"flag": False}

    def on_signal(signum, frame):
        stop["flag"] = True
        source.close()

    old = {sig: signal.signal(sig, on_signal) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        sinks = build_sinks(cfg, csv_path, True, viewer, emit_flags, sysid)
        click.echo(f"mavnav: monitoring {connection} ({cfg.monitor.mode} mode); Ctrl-C to stop", err=True)
        # the sinks write back on the input link, and take the replies to their commands from it
        summary = run_pipeline(source, cfg, sinks, info={"source": connection, "live": True,
                                                          "link": live.mav, "link_tap": live.tap},
                               should_stop=lambda: stop["flag"])
    finally:
        source.close()
        for sig, handler in old.items():
            signal.signal(sig, handler)
    print_summary(summary, "mavnav run")


@main.command("replay")
@click.argument("tlog", type=click.Path(exists=True, dir_okay=False))
@click.option("--speed", default="max", show_default=True,
              help="realtime, max, or a factor of real time (e.g. 4).")
@common_options
@viewer_options
@emit_options
def replay_cmd(tlog: str, speed: str, config_path, sysid, csv_path, inject, viewer_flags, emit_flags) -> None:
    """Replay a recorded log (tlog, ArduPilot DataFlash .bin or PX4 .ulg, detected by
    content) through the monitor: the same pipeline as ``run``."""
    from ..config import load_config
    from ..ingest import open_log
    from ..pipeline import run as run_pipeline
    from ..sim.effects import FaultedSource
    from ..sim.faults import parse_faults

    pace = parse_speed(speed)
    cfg = load_config(config_path)
    viewer = viewer_settings(cfg, viewer_flags)
    faults = parse_faults(inject)
    check_outputs({"--csv": csv_path, "--rrd": viewer.rrd})
    source = open_log(tlog, cfg.ingest, sysid=sysid)
    if faults:
        source = FaultedSource(source, faults)
    # a paced replay is watched as it goes: the viewer logs as for a live run
    sinks = build_sinks(cfg, csv_path, pace is not None, viewer, emit_flags, sysid)
    # SIGINT and SIGTERM alike: stop between samples, close the sinks (the CSV
    # complete), print the summary, exit 130 as for Ctrl-C
    stop: dict = {}

    def on_signal(signum, frame):
        stop["signal"] = signal.Signals(signum).name

    old = {}
    try:
        for sig in (signal.SIGINT, signal.SIGTERM):
            old[sig] = signal.signal(sig, on_signal)
    except ValueError:  # not the main thread: Ctrl-C stays a KeyboardInterrupt
        pass
    try:
        summary = run_pipeline(paced(source, pace), cfg, sinks, info={"source": tlog, "live": False},
                               should_stop=lambda: bool(stop))
    except KeyboardInterrupt:
        click.echo("mavnav replay: interrupted", err=True)
        sys.exit(130)
    finally:
        for sig, handler in old.items():
            signal.signal(sig, handler)
    if stop:
        print_summary(summary, "mavnav replay")
        click.echo(f"mavnav replay: interrupted by {stop['signal']}", err=True)
        sys.exit(130)
    if sysid is not None and not has_vehicle_data(source.stats.to_dict()):
        raise MavnavError(f"{tlog}: " + no_vehicle_error(tlog, sysid, source.stats.format))
    print_summary(summary, "mavnav replay")


__all__ = ["run_cmd", "replay_cmd", "common_options", "MavnavError"]
