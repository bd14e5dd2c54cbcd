"""MAVLink output: mavnav's result back on a vehicle link, as its own component.

Off unless asked (the CLI's ``--emit``). mavnav transmits as system
``sysid`` (default 1, the usual vehicle id, so ground stations group it with
the vehicle), component ``compid`` (default 191, MAV_COMP_ID_ONBOARD_COMPUTER;
1, the autopilot's, is refused). Every frame is MAVLink 2, optionally signed.

What is sent (all clocks are *vehicle* time, from the reports; a replay
sends the same frames as the live run did):

* HEARTBEAT every 1 s of vehicle time (and one at start): type
  MAV_TYPE_ONBOARD_CONTROLLER, autopilot MAV_AUTOPILOT_INVALID, base and
  custom mode 0, system_status STANDBY before the first epoch, ACTIVE while
  the overall state is nominal or caution, CRITICAL when it is unavailable
  or alarm. It pauses when the vehicle's telemetry stops (nothing current to
  report); the ``input`` source's STATUSTEXT says why.
* ALTITUDE at ``altitude_rate_hz`` (epochs decimated on a vehicle-time grid):
  ``time_usec`` the epoch's vehicle time; ``altitude_local`` and
  ``altitude_relative`` the fused height above the reference (normally home);
  ``altitude_amsl`` that plus the reference's altitude MSL (NaN if unknown;
  after a :class:`~mavnav.samples.ReferenceMoved`, the new home's);
  ``altitude_monotonic`` the raw barometric height above the reference (the
  field's recommended "uncorrected barometric altitude"); ``altitude_terrain``
  the rangefinder channel's height and ``bottom_clearance`` the latest
  tilt-corrected rangefinder height, both only while the rangefinder is usable
  (``report.ok("rangefinder")``), NaN otherwise (as PX4 fills unknown fields;
  the message's own sentinels are < -1000 and < 0).
* STATUSTEXT at every alarm transition (:mod:`.mavlink_statustext`): never
  cut, MAVLink 2 chunks (``id``, ``chunk_seq``) for a text over 50
  characters; a source still starting up is INFO, not ERROR. A live link's
  loss and recovery are said as they happen (receive clock): ``mavnav input
  LINK LOST: ...`` (ERROR) and ``... LINK RECOVERED after N s`` (NOTICE).
  Every vehicle reboot the input detects is said at once, ``mavnav input
  VEHICLE REBOOTED: ...`` (NOTICE, after the old boot's pending texts), a
  moved home (``mavnav input HOME MOVED ...``, NOTICE), and so
  are the input's notices (a clock step at NOTICE; the vehicle chosen, the
  systems ignored and what the source waits for at INFO).
* With ``debug_values``: NAMED_VALUE_FLOAT at the ALTITUDE rate
  (:data:`DEBUG_NAMES`).
* With ``fusable``: ODOMETRY (331) at the ALTITUDE rate, for an autopilot
  to fuse. PX4 takes ODOMETRY with estimator_type UNKNOWN as external vision
  (height only with EKF2_EV_CTRL's vertical-position bit); ArduPilot's
  external-navigation path expects a full pose, so a height-only ODOMETRY is
  not known to be used there (not verified against either autopilot here).
  GLOBAL_POSITION_SENSOR (296) exists in the installed dialects but needs
  latitude and longitude, which mavnav does not estimate. Frame MAV_FRAME_LOCAL_NED, child MAV_FRAME_BODY_FRD;
  ``z = -height`` (down); x, y, velocities, rates and q[0] NaN (not
  provided); ``pose_covariance`` is diagonal with var(z) = sigma_fused^2 and
  the unprovided variances +inf (NaN in the first element would mean "whole
  matrix unknown"). ``quality`` 100 nominal, 50 caution/unavailable, and -1
  ("odometry has failed") with var(z) = +inf while the overall state is
  alarm or the height is not finite. ``reset_counter`` counts reboots and
  reference changes (the origin jumps).
* With ``allow_commands``: MAV_CMD_SET_MESSAGE_INTERVAL only
  (:mod:`.mavlink_commands`), for the streams and rates the configuration's
  time-to-alarm needs (or the ``message_rates`` given); each COMMAND_ACK
  verdict (accepted, refused with its result, no answer) and a last word
  on what was not granted go to ``say`` (the CLI's console) and the log.

The link: a pymavlink connection the CLI opened (``--emit CONNECTION``), or
``link=None, use_input_link=True`` (``--emit input``): then ``start(info)``
takes ``info["link"]``, the live source's pymavlink connection, and writes
to it without reading (the live source owns the receive side). Replies
needed for commands come from ``info["link_tap"]`` when the source offers
it: a callable that registers a callback for decoded HEARTBEAT and
COMMAND_ACK messages. Without it, commands are not sent on the input link.

A failing send never stops the monitor (:class:`.mavlink_link.LinkWriter`).
"""

from __future__ import annotations

import logging
import math
import time
from collections import Counter
from typing import Callable, Optional, Tuple

from pymavlink.dialects.v20 import common as mavlink2

from ..config import Config, EmitSection
from ..errors import ConfigError, InputError
from ..home_frame import home_moved_text
from ..report import CHANNEL_NAMES, PAIR_NAMES, AlarmEvent, EpochReport, RunSummary
from ..sensors import BARO, GNSS, RANGEFINDER, SENSOR_SOURCES
from ..samples import LinkLost, LinkRecovered, Notice, Reboot, ReferenceMoved, ReferenceSet
from .base import Sink
from .mavlink_commands import IntervalRequester, RateRequest, needed_rates, parse_rate
from .mavlink_link import KEY_BYTES, LinkWriter
from .mavlink_statustext import (
    StartupWatch, StatusTextLimiter, format_text, input_text, severity, split_text,
)

log = logging.getLogger("mavnav.sinks.mavlink_out")

HEARTBEAT_PERIOD_US = 1_000_000
_COMMAND_POLL_S = 0.02
_MAX_READS_PER_POLL = 200
INF = math.inf
NAN = math.nan

_CHANNEL_SHORT = {c: c.short for c in CHANNEL_NAMES}  # gnss, rng, baro
_SOURCE_SHORT = {s: s.short for s in SENSOR_SOURCES}  # gnss, rng, baro
_PAIR_SHORT = {"gnss-rng": "dH_gns_rng", "gnss-baro": "dH_gns_bar", "rng-baro": "dH_rng_bar"}

#: NAMED_VALUE_FLOAT names (10 characters at most) with ``--emit-debug``.
DEBUG_NAMES: Tuple[str, ...] = (
    tuple(f"nis_{_CHANNEL_SHORT[c]}" for c in CHANNEL_NAMES)
    + tuple(_PAIR_SHORT[p] for p in PAIR_NAMES)
    + tuple(f"win_{s}" for s in _SOURCE_SHORT.values())
    + ("sig_fused", "vpl")
)

_SYSTEM_STATUS = {
    "nominal": mavlink2.MAV_STATE_ACTIVE,
    "caution": mavlink2.MAV_STATE_ACTIVE,
    "unavailable": mavlink2.MAV_STATE_CRITICAL,
    "alarm": mavlink2.MAV_STATE_CRITICAL,
}
_QUALITY = {"nominal": 100, "caution": 50, "unavailable": 50, "alarm": -1}


def requested_rates(emit: EmitSection) -> Optional[Tuple[RateRequest, ...]]:
    """The message rates ``emit.message_rates`` asks for, parsed (bad ones refused
    by name); None when it names none: the rates the configuration needs then."""
    return tuple(parse_rate(s) for s in emit.message_rates) if emit.message_rates else None


class _Ticker:
    """Fires on a vehicle-time grid of ``period_us``; restarts on a reboot or a jump back."""

    def __init__(self, period_us: int):
        self.period_us = period_us
        self._boot: Optional[int] = None
        self._next = 0

    def __call__(self, boot: int, t_us: int) -> bool:
        if self._boot != boot or t_us < self._next - self.period_us:
            self._boot = boot
            self._next = t_us + self.period_us
            return True
        if t_us >= self._next:
            self._next += self.period_us
            if self._next <= t_us:  # after a gap: back on a grid from now
                self._next = t_us + self.period_us
            return True
        return False


class MavlinkOutSink(Sink):
    name = "mavlink-out"

    def __init__(
        self,
        link=None,
        config: Optional[Config] = None,
        *,
        allow_commands: bool = False,
        signing_secret: Optional[bytes] = None,
        use_input_link: bool = False,
        description: Optional[str] = None,
        close_link: bool = True,
        clock: Callable[[], float] = time.monotonic,
        wall_clock: Callable[[], float] = time.time,
        say: Optional[Callable[[str], None]] = None,
        vehicle_sysid: Optional[int] = None,
    ):
        """What is sent, and as whom: ``config.emit`` (the CLI gives the run's
        configuration with the flags over its ``emit:`` section); the rest of
        ``config`` gives the rates its time-to-alarm needs. Only with
        ``allow_commands`` are commands sent (``config.emit.message_rates``, or
        those rates). ``signing_secret``: the 32-byte MAVLink 2 signing key (the
        CLI reads it from ``emit.signing_key``'s file); None: unsigned.
        ``say``: where the command results are told to a person (the console).
        ``vehicle_sysid``: the system the monitor watches (``--sysid``), whose
        autopilot alone the commands go to (None: the first autopilot heard)."""
        if (link is None) != use_input_link:
            raise ValueError("give a link, or use_input_link=True (not both)")
        if signing_secret is not None and len(signing_secret) != KEY_BYTES:
            raise ConfigError(f"a MAVLink 2 signing key has {KEY_BYTES} bytes")
        self.config = config if config is not None else Config()
        self.settings = cfg = self.config.emit
        self.allow_commands = allow_commands
        #: with allow_commands: the rates asked for, or None for those the configuration needs
        self.message_rates = requested_rates(cfg) if allow_commands else None
        self.use_input_link = use_input_link
        self.description = description or ("input link" if use_input_link else str(link))
        self._link = link
        self._close_link = close_link and not use_input_link
        self.clock = clock
        self._mav = mavlink2.MAVLink(None, srcSystem=cfg.sysid, srcComponent=cfg.compid)
        if signing_secret is not None:
            sg = self._mav.signing
            sg.secret_key = bytes(signing_secret)
            sg.sign_outgoing = True
            sg.link_id = cfg.signing_link_id
            # 10 us units since 2015-01-01 (MAVLink 2 signing), then +1 per frame
            sg.timestamp = int(max(wall_clock() - 1420070400, 0) * 100_000)
        self.writer: Optional[LinkWriter] = None
        self.limiter = StatusTextLimiter(int(round(cfg.statustext_interval_s * 1e6)))
        self.startup = StartupWatch()
        self._text_id = 0  # id of the last chunked STATUSTEXT (1..65535; 0 = a single message)
        self._hb = _Ticker(HEARTBEAT_PERIOD_US)
        self._alt = _Ticker(int(round(1e6 / cfg.altitude_rate_hz)))
        self.say = say
        self.requester: Optional[IntervalRequester] = None
        if allow_commands:
            plan = self.message_rates if self.message_rates is not None else self._plan_rates
            self.requester = IntervalRequester(
                plan, (cfg.sysid, cfg.compid),
                timeout_s=cfg.command_timeout_s, attempts=cfg.command_attempts, on_result=self._on_result,
                vehicle_sysid=vehicle_sysid,
            )
        self._read_link = False  # whether this sink reads replies from its own link
        self._next_poll = -INF
        self._alt_ref_msl: dict = {}  # ReferenceSet.kind -> alt_ref_msl_m (None if unknown)
        self._point_msl: Optional[float] = None  # the home the heights are above, once it moved
        self._boot: Optional[int] = None
        self._reset_counter = 0
        self._commands_reported = False
        self.counts: Counter = Counter()  # message name -> frames handed to the link

    # ------------------------------------------------------------------ hooks

    def start(self, info: dict) -> None:
        link = self._link
        if self.use_input_link:
            link = info.get("link")
            if link is None:
                raise InputError("--emit input needs a live input link; this run has none (a replay?)")
            self._link = link
            if self.requester is not None:
                tap = info.get("link_tap")
                if callable(tap):
                    tap(self.handle_message)
                else:
                    log.warning("MAVLink output: --allow-commands on the input link needs the live source "
                                "to pass replies (info['link_tap']); no command is sent")
                    self.requester = None
        else:
            self._read_link = self.requester is not None
        self.writer = LinkWriter(link, self.description, clock=self.clock)
        self._send(self._heartbeat(mavlink2.MAV_STATE_STANDBY))

    def sample(self, s) -> None:
        ts = type(s)
        if ts is ReferenceSet:
            prev = self._alt_ref_msl.get(s.kind, "unset")
            self._alt_ref_msl[s.kind] = s.alt_ref_msl_m
            if prev != "unset":
                self._reset_counter += 1
        elif ts is ReferenceMoved:
            self._point_msl = s.alt_ref_msl_m  # the heights reported are above it from now on
            self._reset_counter += 1
            self._send_statustext(mavlink2.MAV_SEVERITY_NOTICE, f"mavnav input {home_moved_text(s)}")
        elif ts is Reboot:
            self._alt_ref_msl.clear()
            self._point_msl = None
            self._send_texts(self.limiter.flush())  # the old boot's pending changes first
            self._send_statustext(*input_text(s))
        elif ts is Notice:
            self._send_statustext(*input_text(s))
        elif ts is LinkLost:
            # said at once, from the receive clock: the monitor's own input
            # transition waits for the next epoch, i.e. for the link to return
            self._send_texts(self.limiter.flush())
            self._send_statustext(mavlink2.MAV_SEVERITY_ERROR,
                                  f"mavnav input LINK LOST: no data for {s.silent_s:.1f} s")
        elif ts is LinkRecovered:
            self._send_statustext(mavlink2.MAV_SEVERITY_NOTICE, f"mavnav input LINK RECOVERED after {s.outage_s:.1f} s")
        if self.requester is not None:
            self._service_commands()

    def alarm(self, event: AlarmEvent) -> None:
        self._send_texts(self.limiter.offer(event))

    def epoch(self, report: EpochReport) -> None:
        boot, t_us = report.boot, report.t_us
        self.startup.epoch(report)
        if boot != self._boot:
            if self._boot is not None:
                self._reset_counter += 1
            self._boot = boot
        if self.limiter.pending:
            self._send_texts(self.limiter.due(boot, t_us))
        if self._hb(boot, t_us):
            self._send(self._heartbeat(_SYSTEM_STATUS.get(report.overall, mavlink2.MAV_STATE_ACTIVE)))
        if self._alt(boot, t_us):
            self._send(self._altitude(report))
            if self.settings.debug_values:
                for name, value in self._debug_values(report):
                    self._send(mavlink2.MAVLink_named_value_float_message(
                        (t_us // 1000) & 0xFFFFFFFF, name.encode("ascii"), value))
            if self.settings.fusable:
                self._send(self._odometry(report))
        if self.requester is not None:
            self._service_commands()

    def close(self, summary: RunSummary) -> None:
        try:
            if self.writer is not None:
                self._send_texts(self.limiter.flush())
                if self.requester is not None and not self._commands_reported:
                    self._report_commands()
                log.info("MAVLink output %s: %s; %d sends failed", self.description,
                         ", ".join(f"{k} {v}" for k, v in sorted(self.counts.items())) or "nothing sent",
                         self.writer.failures)
        finally:
            if self._close_link and self._link is not None:
                try:
                    self._link.close()
                except Exception:
                    pass

    # ------------------------------------------------------------------ replies

    def handle_message(self, msg) -> None:
        """A decoded message from the link (HEARTBEAT, COMMAND_ACK matter)."""
        if self.requester is not None:
            self.requester.on_message(msg, self.clock())

    def _read_replies(self) -> None:
        conn = self._link
        for _ in range(_MAX_READS_PER_POLL):
            try:
                msg = conn.recv_msg()
            except Exception:
                return
            if msg is None:
                return
            self.handle_message(msg)

    def _service_commands(self) -> None:
        req = self.requester
        if req.done:
            if not self._commands_reported:
                self._report_commands()
            return
        now = self.clock()
        if now < self._next_poll:
            return
        self._next_poll = now + _COMMAND_POLL_S
        if self._read_link:
            self._read_replies()
        msg = req.poll(now)
        if msg is not None:
            self._send(msg)

    def _tell(self, level: int, text: str) -> None:
        """To the console when there is one (``say``), else to the log at ``level``."""
        if self.say is not None:
            self.say(f"mavnav: {text}")
            level = logging.DEBUG
        log.log(level, "MAVLink output: %s", text)

    def _plan_rates(self, heartbeat) -> Tuple[RateRequest, ...]:
        rates = needed_rates(self.config, heartbeat.autopilot)
        self._tell(logging.INFO, f"asking the autopilot {heartbeat.get_srcSystem()}/{heartbeat.get_srcComponent()} "
                                 "for the input rates the time-to-alarm needs: "
                                 + ", ".join(f"{r.name} {r.rate_hz:g} Hz" for r in rates))
        return rates

    def _on_result(self, req: RateRequest, result: str) -> None:
        self._tell(logging.INFO if result == "accepted" else logging.WARNING,
                   f"SET_MESSAGE_INTERVAL {req.name} {req.rate_hz:g} Hz: {result}")

    def _report_commands(self) -> None:
        self._commands_reported = True
        req = self.requester
        results = dict(req.results)
        if req.target is None:
            self._tell(logging.WARNING, "no autopilot heard: no message rate was requested (not sent)")
            return
        for r in req.requests:
            results.setdefault(r.name, "no answer yet")
        bad = {k: v for k, v in results.items() if v != "accepted"}
        if bad:
            self._tell(logging.WARNING, "message rates not granted: " + "; ".join(f"{k} {v}" for k, v in bad.items())
                       + " (the input may be too slow for the time-to-alarm: see the input source's state)")
        else:
            self._tell(logging.INFO, "every requested message rate was accepted")

    # ------------------------------------------------------------------ frames

    def _send(self, msg) -> bool:
        mav = self._mav
        buf = msg.pack(mav)
        mav.seq = (mav.seq + 1) % 256
        ok = self.writer.write(buf)
        if ok:
            self.counts[msg.get_type()] += 1
        return ok

    def _send_texts(self, items) -> None:
        for event, swallowed in items:
            starting = self.startup.starting(event)
            self._send_statustext(severity(event, starting), format_text(event, swallowed, starting))

    def _send_statustext(self, sev: int, text: str) -> None:
        chunks = split_text(text)
        if len(chunks) == 1:
            self._send(mavlink2.MAVLink_statustext_message(sev, chunks[0].encode("ascii"), 0, 0))
            return
        self._text_id = self._text_id % 0xFFFF + 1
        for seq, chunk in enumerate(chunks):
            self._send(mavlink2.MAVLink_statustext_message(sev, chunk.encode("ascii"), self._text_id, seq))

    def _heartbeat(self, status: int):
        return mavlink2.MAVLink_heartbeat_message(
            mavlink2.MAV_TYPE_ONBOARD_CONTROLLER, mavlink2.MAV_AUTOPILOT_INVALID, 0, 0, status, 3)

    def _alt_ref(self) -> float:
        if self._point_msl is not None:
            return self._point_msl
        for kind in (GNSS, BARO):
            v = self._alt_ref_msl.get(kind)
            if v is not None:
                return float(v)
        return NAN

    def _altitude(self, r: EpochReport):
        h = r.height_fused_m
        if r.ok(RANGEFINDER):
            rng = r.channels[CHANNEL_NAMES.index(RANGEFINDER)]
            terrain = rng.height_ref_m if rng.available else NAN
            clearance = r.range_height_agl_m
        else:
            terrain = clearance = NAN
        return mavlink2.MAVLink_altitude_message(
            r.t_us, r.baro_height_ref_m, self._alt_ref() + h, h, h, terrain, clearance)

    def _debug_values(self, r: EpochReport):
        out = [(f"nis_{_CHANNEL_SHORT[c.name]}", c.nis) for c in r.channels]
        out += [(_PAIR_SHORT[p.name], p.diff_m) for p in r.pairs]
        for src, short in _SOURCE_SHORT.items():
            st = r.sources.get(src)
            out.append((f"win_{short}", st.window_stat if st is not None else NAN))
        out += [("sig_fused", r.sigma_fused_m), ("vpl", r.vpl_m)]
        return out

    def _odometry(self, r: EpochReport):
        h, sigma = r.height_fused_m, r.sigma_fused_m
        healthy = r.overall != "alarm" and math.isfinite(h) and math.isfinite(sigma)
        pose = [0.0] * 21
        for i in (0, 6, 15, 18, 20):  # var x, y, roll, pitch, yaw: not provided
            pose[i] = INF
        pose[11] = sigma * sigma if healthy else INF  # var z
        vel = [NAN] + [0.0] * 20
        return mavlink2.MAVLink_odometry_message(
            r.t_us, mavlink2.MAV_FRAME_LOCAL_NED, mavlink2.MAV_FRAME_BODY_FRD,
            NAN, NAN, -h, [NAN, 0.0, 0.0, 0.0], NAN, NAN, NAN, NAN, NAN, NAN,
            pose, vel, self._reset_counter & 0xFF, mavlink2.MAV_ESTIMATOR_TYPE_UNKNOWN,
            _QUALITY.get(r.overall, 0) if healthy else -1,
        )
