"""The ``--emit`` options of ``run`` and ``replay``, and the factory of MAVLink output sinks.

Use::

    @main.command("run")
    @emit_options
    def run_cmd(..., emit_flags):
        sinks += emit_sinks(cfg, emit_flags, live_input=True)

The command receives the flags given on the command line as one dict,
``emit_flags``. Each flag but ``--emit`` and ``--allow-commands`` is also a
key of the configuration's ``emit:`` section; a flag given wins over the
key. Nothing is transmitted without ``--emit``; no command without
``--allow-commands``: those two are flags only. The sink itself is
:mod:`mavnav.sinks.mavlink_out`.
"""

from __future__ import annotations

import time
from typing import TYPE_CHECKING, Callable, List, Optional, Sequence, Tuple

import click

from ..errors import ConfigError, InputError
from .flags import flag_group

# pymavlink and the output sink are imported when a link is opened or a sink
# built, not when the CLI parses its arguments.
if TYPE_CHECKING:
    from ..config import Config, EmitSection
    from ..sinks.base import Sink

INPUT = "input"

#: The flags that turn the output on: on the command line only.
COMMAND_LINE_ONLY: Tuple[str, ...] = ("emit", "allow_commands")
#: The other flags (click parameter) -> key of the configuration's ``emit:`` section.
EMIT_FLAGS = {
    "emit_sysid": "sysid",
    "emit_compid": "compid",
    "altitude_rate": "altitude_rate_hz",
    "statustext_interval": "statustext_interval_s",
    "emit_debug": "debug_values",
    "emit_fusable": "fusable",
    "request_rate": "message_rates",
    "signing_key": "signing_key",
    "signing_link_id": "signing_link_id",
}
#: The keyword arguments :func:`emit_options` adds (click's parameter names).
EMIT_OPTION_KEYS: Tuple[str, ...] = COMMAND_LINE_ONLY + tuple(EMIT_FLAGS)

_OPTIONS = [
    click.option("--emit", "emit", metavar="CONNECTION", default=None,
                 help="Send mavnav's result on this MAVLink link (any pymavlink connection string, e.g. "
                      "udpout:127.0.0.1:14560, tcp:HOST:PORT, /dev/ttyUSB0,57600), or 'input' for back out of "
                      "the link `run` listens on. Off by default: without it nothing is transmitted."),
    click.option("--emit-sysid", "emit_sysid", type=click.IntRange(1, 255), default=1, show_default=True,
                 help="MAVLink system id mavnav sends as (usually the vehicle's)."),
    click.option("--emit-compid", "emit_compid", type=click.IntRange(2, 255), default=191, show_default=True,
                 help="MAVLink component id mavnav sends as (191 = onboard computer; 1, the autopilot's, is refused)."),
    click.option("--altitude-rate", "altitude_rate", type=click.FloatRange(0, 100, min_open=True), default=5.0,
                 show_default=True, metavar="HZ", help="ALTITUDE rate, on vehicle time."),
    click.option("--statustext-interval", "statustext_interval", type=click.FloatRange(0), default=1.0,
                 show_default=True, metavar="S",
                 help="Least vehicle time between two alarm STATUSTEXTs of one source; changes within it are "
                      "coalesced (the latest state is always sent)."),
    click.option("--emit-debug", "emit_debug", is_flag=True,
                 help="Also send residuals and test statistics as NAMED_VALUE_FLOAT."),
    click.option("--emit-fusable", "emit_fusable", is_flag=True,
                 help="Also send ODOMETRY with the fused height and its variance, for an autopilot to fuse "
                      "(quality -1 while in alarm)."),
    click.option("--allow-commands", "allow_commands", is_flag=True,
                 help="Allow mavnav to send MAV_CMD_SET_MESSAGE_INTERVAL (and nothing else) to ask the "
                      "autopilot for the input rates the time-to-alarm needs; the answers (COMMAND_ACK) are "
                      "said on the console."),
    click.option("--request-rate", "request_rate", multiple=True, metavar="NAME:HZ",
                 help="A message rate to request with --allow-commands (repeatable). Default: the streams the "
                      "monitor reads from that autopilot (its IMU, ATTITUDE, SCALED_PRESSURE, GPS_RAW_INT, "
                      "DISTANCE_SENSOR), at the rates the configuration's time-to-alarm needs (emit.request)."),
    click.option("--signing-key", "signing_key", type=click.Path(dir_okay=False), default=None, metavar="FILE",
                 help="Sign what mavnav sends (MAVLink 2). FILE holds 32 raw bytes, or a passphrase hashed "
                      "with SHA-256 as MAVProxy's `signing setup` does."),
    click.option("--signing-link-id", "signing_link_id", type=click.IntRange(0, 255), default=0,
                 show_default=True, help="MAVLink 2 signing link id of mavnav's frames."),
]


def emit_options(f: Callable) -> Callable:
    """Decorator: add the ``--emit`` family of options to a click command, which
    receives those given on the command line as one dict, ``emit_flags``."""
    return flag_group(_OPTIONS, EMIT_OPTION_KEYS, "emit_flags")(f)


def emit_settings(cfg: Config, flags: dict) -> EmitSection:
    """The configuration's ``emit:`` section with the flags given over it."""
    from ..config import with_overrides

    return with_overrides(cfg.emit, {EMIT_FLAGS[k]: v for k, v in flags.items() if k in EMIT_FLAGS}, "emit options")


def emit_sinks(cfg: Config, flags: dict, *, live_input: Optional[bool] = None,
               say: Optional[Callable[[str], None]] = None, vehicle_sysid: Optional[int] = None) -> List[Sink]:
    """The MAVLink output sinks of a command: none without ``--emit`` (and the
    flags that need it refused); else as the ``emit:`` section says, with the
    flags given over it. The section's ``message_rates`` apply only with
    ``--allow-commands``; its commands go to the autopilot of ``vehicle_sysid``
    (``--sysid``; None: the first autopilot heard)."""
    if flags.get("emit") is None:
        return make_emit_sinks(**flags, live_input=live_input, config=cfg, say=say)
    settings = emit_settings(cfg, flags)
    allow = bool(flags.get("allow_commands", False))
    if flags.get("request_rate") and not allow:
        raise ConfigError("--request-rate needs --allow-commands")
    config = cfg.model_copy(update={"emit": settings})
    return _sinks(flags["emit"], config, allow, live_input=live_input, say=say, vehicle_sysid=vehicle_sysid)


def _split_baud(connection: str):
    if "," in connection:
        dev, _, b = connection.rpartition(",")
        if b.strip().isdigit():
            return dev, int(b)
    return connection, None


def open_link(connection: str, sysid: int, compid: int):
    """Open a pymavlink connection for sending (UDP, TCP with reconnection, serial)."""
    device, baud = _split_baud(connection)
    kwargs = {"source_system": sysid, "source_component": compid}
    if baud is not None:
        kwargs["baud"] = baud
    if device.startswith("tcp:"):
        # reconnect inside write(), one connect attempt each time, no sleeping retries
        kwargs.update(autoreconnect=True, retries=0)
    from pymavlink import mavutil

    try:
        return mavutil.mavlink_connection(device, **kwargs)
    except Exception as exc:  # socket, serial and parsing errors alike
        raise InputError(f"--emit {connection}: cannot open ({exc})") from None


def make_emit_sinks(
    *,
    emit: Optional[str] = None,
    emit_sysid: int = 1,
    emit_compid: int = 191,
    altitude_rate: float = 5.0,
    statustext_interval: float = 1.0,
    emit_debug: bool = False,
    emit_fusable: bool = False,
    allow_commands: bool = False,
    request_rate: Sequence[str] = (),
    signing_key: Optional[str] = None,
    signing_link_id: int = 0,
    live_input: Optional[bool] = None,
    vehicle_sysid: Optional[int] = None,
    config: Optional[Config] = None,
    say: Optional[Callable[[str], None]] = None,
    clock: Callable[[], float] = time.monotonic,
    wall_clock: Callable[[], float] = time.time,
) -> List[Sink]:
    """The MAVLink output sinks the options ask for: none without ``--emit``.

    ``live_input``: whether the run has a live input link (``run``: True,
    ``replay``: False); ``--emit input`` is refused when it is False.
    ``config``: the run's configuration (the rates its time-to-alarm needs,
    the command timeout); ``say``: where command results are told (the
    console). Misspelt keywords raise ``TypeError`` (no ``**kwargs`` swallowing).
    """
    from ..config import Config, with_overrides

    config = config if config is not None else Config()
    if emit is None:
        stray = [name for name, on in (("--allow-commands", allow_commands), ("--emit-debug", emit_debug),
                                       ("--emit-fusable", emit_fusable), ("--signing-key", signing_key),
                                       ("--request-rate", request_rate)) if on]
        if stray:
            raise ConfigError(f"{', '.join(stray)} without --emit: nothing is transmitted without --emit")
        return []
    if request_rate and not allow_commands:
        raise ConfigError("--request-rate needs --allow-commands")
    settings = with_overrides(config.emit, {
        "sysid": emit_sysid, "compid": emit_compid, "altitude_rate_hz": altitude_rate,
        "statustext_interval_s": statustext_interval, "debug_values": emit_debug, "fusable": emit_fusable,
        "message_rates": tuple(request_rate), "signing_key": str(signing_key) if signing_key else None,
        "signing_link_id": signing_link_id,
    }, "emit")
    return _sinks(emit, config.model_copy(update={"emit": settings}), allow_commands, live_input=live_input,
                  say=say, clock=clock, wall_clock=wall_clock, vehicle_sysid=vehicle_sysid)


def _sinks(emit: str, config: Config, allow_commands: bool, *, live_input: Optional[bool],
           say: Optional[Callable[[str], None]], clock: Callable[[], float] = time.monotonic,
           wall_clock: Callable[[], float] = time.time, vehicle_sysid: Optional[int] = None) -> List[Sink]:
    """The sink sending to connection ``emit`` as ``config.emit`` says (the flags
    already over it): the rates and the key checked before the link is opened."""
    from ..sinks.mavlink_link import load_signing_key
    from ..sinks.mavlink_out import MavlinkOutSink, requested_rates

    settings = config.emit
    emit = emit.strip()
    if allow_commands:
        requested_rates(settings)  # a bad NAME:HZ is refused before anything is opened
    secret = load_signing_key(settings.signing_key) if settings.signing_key else None
    sink_args = dict(allow_commands=allow_commands, signing_secret=secret, clock=clock, wall_clock=wall_clock, say=say,
                     vehicle_sysid=vehicle_sysid)
    if emit == INPUT:
        if live_input is False:
            raise ConfigError("--emit input needs a live input link (`run`); use a connection string here")
        return [MavlinkOutSink(None, config, use_input_link=True, **sink_args)]
    link = open_link(emit, settings.sysid, settings.compid)
    return [MavlinkOutSink(link, config, description=emit, **sink_args)]
