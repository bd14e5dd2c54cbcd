"""The only command mavnav may send: MAV_CMD_SET_MESSAGE_INTERVAL (511), when allowed.

A monitor's time-to-alarm needs its inputs at rates the default telemetry
streams often do not give (docs MAVLINK.md); with ``--allow-commands`` mavnav
asks the autopilot for them, one message at a time (COMMAND_ACK does not say
which message an answer is for), and checks each COMMAND_ACK:

* ACCEPTED: done; IN_PROGRESS: keep waiting;
* TEMPORARILY_REJECTED or no answer within ``timeout_s``: ask again, up to
  ``attempts`` times in all (``confirmation`` counts the retries);
* DENIED, UNSUPPORTED, FAILED, CANCELLED: refused, reported, not retried.

The target is the autopilot of the system the monitor watches (``--sysid``),
or without it the first autopilot heard (the normaliser's vehicle rule,
:func:`mavnav.ingest.systems.is_vehicle_heartbeat`: autopilot not
MAV_AUTOPILOT_INVALID, type not a GCS; and not an onboard controller either);
nothing is sent before one is heard. Timing is on the wall clock (the
vehicle answers in real time), passed in by the caller.

What is asked for (:func:`needed_rates`), unless the user names the rates:
the streams the monitor reads on that autopilot (the IMU it uses: RAW_IMU on
ArduPilot, which fills it in milli-g, HIGHRES_IMU elsewhere, or the
configured ``ingest.imu_source``; ATTITUDE; the configured barometer's
SCALED_PRESSURE; GPS_RAW_INT; DISTANCE_SENSOR or the configured
``ingest.range_source``), each at the larger of its ``emit.request`` rate and
``emit.request.tta_margin`` times the rate the time-to-alarm needs
(:func:`mavnav.audit.required_rates_hz`).
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from typing import Callable, Dict, List, Optional, Sequence, Tuple, Union

from pymavlink.dialects.v20 import ardupilotmega as dialect
from pymavlink.dialects.v20 import common as mavlink2

from ..config import Config
from ..errors import ConfigError
from ..ingest.systems import is_vehicle_heartbeat
from ..sensors import BARO, GNSS, IMU, RANGEFINDER

log = logging.getLogger("mavnav.sinks.mavlink_out")

MAV_CMD_SET_MESSAGE_INTERVAL = mavlink2.MAV_CMD_SET_MESSAGE_INTERVAL  # 511

_IDS: Dict[str, int] = {cls.msgname: mid for mid, cls in dialect.mavlink_map.items()}

_RESULT = {k: v.name.replace("MAV_RESULT_", "") for k, v in mavlink2.enums["MAV_RESULT"].items()}


@dataclass(frozen=True)
class RateRequest:
    name: str
    msg_id: int
    rate_hz: float

    @property
    def interval_us(self) -> int:
        return int(round(1e6 / self.rate_hz))


def parse_rate(spec: str) -> RateRequest:
    """``NAME:HZ`` (e.g. ``HIGHRES_IMU:50``) -> a :class:`RateRequest`; bad names refused by name."""
    name, sep, hz = spec.partition(":")
    name = name.strip().upper()
    if not sep:
        raise ConfigError(f"message rate {spec!r}: write NAME:HZ, e.g. HIGHRES_IMU:50")
    if name not in _IDS:
        raise ConfigError(f"message rate {spec!r}: no MAVLink message named {name}")
    try:
        rate = float(hz)
    except ValueError:
        raise ConfigError(f"message rate {spec!r}: {hz!r} is not a number of Hz") from None
    if not (math.isfinite(rate) and 0 < rate <= 1000):
        raise ConfigError(f"message rate {spec!r}: the rate must be in (0, 1000] Hz")
    return RateRequest(name, _IDS[name], rate)


_BARO_MESSAGES = {1: "SCALED_PRESSURE", 2: "SCALED_PRESSURE2", 3: "SCALED_PRESSURE3"}


def needed_rates(cfg: Config, autopilot: Optional[int]) -> Tuple[RateRequest, ...]:
    """The streams the monitor reads from this autopilot (MAV_AUTOPILOT), at the rates
    ``cfg`` needs (see the module docstring)."""
    from ..audit import required_rates_hz  # the monitor's rule, kept in one place

    need = required_rates_hz(cfg)
    req = cfg.emit.request
    ing = cfg.ingest
    if ing.imu_source != "auto":
        imu = ing.imu_source
    else:
        imu = "RAW_IMU" if autopilot == mavlink2.MAV_AUTOPILOT_ARDUPILOTMEGA else "HIGHRES_IMU"
    rng = ing.range_source if ing.range_source != "auto" else "DISTANCE_SENSOR"

    def rate(floor_hz: float, kind: Optional[str]) -> float:
        return max(floor_hz, req.tta_margin * need[kind]) if kind else floor_hz

    return (
        RateRequest(imu, _IDS[imu], rate(req.imu_rate_hz, IMU)),
        RateRequest("ATTITUDE", _IDS["ATTITUDE"], rate(req.attitude_rate_hz, IMU)),
        RateRequest(_BARO_MESSAGES[ing.baro_instance], _IDS[_BARO_MESSAGES[ing.baro_instance]],
                    rate(req.baro_rate_hz, BARO)),
        RateRequest("GPS_RAW_INT", _IDS["GPS_RAW_INT"], rate(req.gnss_rate_hz, GNSS)),
        RateRequest(rng, _IDS[rng], rate(req.range_rate_hz, RANGEFINDER)),
    )


#: What to ask for: a fixed list, or a plan made from the target's HEARTBEAT.
Requests = Union[Sequence[RateRequest], Callable[[object], Sequence[RateRequest]]]


def is_autopilot_heartbeat(msg) -> bool:
    """A HEARTBEAT of a vehicle's autopilot (the normaliser's rule) that is not a
    companion computer naming one: commands go to the autopilot itself."""
    return msg.get_type() == "HEARTBEAT" and is_vehicle_heartbeat(
        {"autopilot": msg.autopilot, "type": msg.type}, onboard_controller=False)


class IntervalRequester:
    """Sends SET_MESSAGE_INTERVAL requests one at a time and checks their COMMAND_ACKs.

    :meth:`poll` returns the COMMAND_LONG to send now (or None);
    :meth:`on_message` takes what the link receives. ``results`` maps each
    message name to ``accepted``, ``refused: <RESULT>`` or ``no answer``.
    ``requests`` is a list, or a function of the target's HEARTBEAT that
    makes it once the target is heard (:func:`needed_rates` depends on the
    autopilot). ``on_result(request, result)`` is called at each verdict
    (the sink tells a person; this class logs at DEBUG only).
    ``vehicle_sysid``: the system the monitor watches (``--sysid``); the
    commands go to its autopilot only (None: the first autopilot heard).
    """

    def __init__(
        self,
        requests: Requests,
        own: Tuple[int, int],
        *,
        timeout_s: float = 1.0,
        attempts: int = 3,
        on_result: Optional[Callable[[RateRequest, str], None]] = None,
        vehicle_sysid: Optional[int] = None,
    ):
        if attempts < 1:
            raise ValueError("attempts must be >= 1")
        self._plan = requests if callable(requests) else None
        self.requests: List[RateRequest] = [] if self._plan is not None else list(requests)
        self._queue: List[RateRequest] = list(self.requests)
        self.on_result = on_result
        self.own = own
        self.timeout_s = timeout_s
        self.attempts = attempts
        self.target: Optional[Tuple[int, int]] = None
        #: the system the monitor watches (``--sysid``): only its autopilot is a target
        self.vehicle_sysid = vehicle_sysid
        self.results: Dict[str, str] = {}
        self.sent = 0
        self._current: Optional[RateRequest] = None
        self._attempt = 0
        self._sent_at = -math.inf

    @property
    def done(self) -> bool:
        planned = self._plan is None or self.target is not None
        return planned and self._current is None and not self._queue

    def on_message(self, msg, now: float) -> None:
        mtype = msg.get_type()
        if mtype == "HEARTBEAT":
            if (self.target is None and is_autopilot_heartbeat(msg)
                    and self.vehicle_sysid in (None, msg.get_srcSystem())):
                self.target = (msg.get_srcSystem(), msg.get_srcComponent())
                if self._plan is not None:
                    self.requests = list(self._plan(msg))
                    self._queue = list(self.requests)
                log.debug("MAVLink output: commands go to the autopilot %d/%d", *self.target)
        elif mtype == "COMMAND_ACK":
            self._on_ack(msg, now)

    def _on_ack(self, msg, now: float) -> None:
        req = self._current
        if req is None or msg.command != MAV_CMD_SET_MESSAGE_INTERVAL or self.target is None:
            return
        if msg.get_srcSystem() != self.target[0]:
            return
        # MAVLink 2 extension fields: 0 when the sender leaves them out
        ts, tc = getattr(msg, "target_system", 0), getattr(msg, "target_component", 0)
        if (ts and ts != self.own[0]) or (tc and tc != self.own[1]):
            return  # an answer to someone else's command
        result = _RESULT.get(msg.result, str(msg.result))
        if msg.result == mavlink2.MAV_RESULT_ACCEPTED:
            self._finish(req, "accepted")
            log.debug("MAVLink output: %s at %g Hz accepted", req.name, req.rate_hz)
        elif msg.result == mavlink2.MAV_RESULT_IN_PROGRESS:
            self._sent_at = now
        elif msg.result == mavlink2.MAV_RESULT_TEMPORARILY_REJECTED and self._attempt < self.attempts:
            self._sent_at = -math.inf  # ask again at the next poll
        else:
            self._finish(req, f"refused: {result}")
            log.debug("MAVLink output: the vehicle refused %s at %g Hz (%s)", req.name, req.rate_hz, result)

    def _finish(self, req: RateRequest, result: str) -> None:
        self.results[req.name] = result
        if self.on_result is not None:
            self.on_result(req, result)
        self._current = None
        self._attempt = 0
        self._sent_at = -math.inf

    def poll(self, now: float):
        """The COMMAND_LONG to send now, or None."""
        if self.target is None:
            return None
        if self._current is None:
            if not self._queue:
                return None
            self._current = self._queue.pop(0)
            self._attempt = 0
            self._sent_at = -math.inf
        if now - self._sent_at < self.timeout_s:
            return None
        req = self._current
        if self._attempt >= self.attempts:
            self._finish(req, "no answer")
            log.debug("MAVLink output: no COMMAND_ACK for %s at %g Hz after %d attempts",
                        req.name, req.rate_hz, self.attempts)
            return self.poll(now)
        self._attempt += 1
        self._sent_at = now
        self.sent += 1
        return mavlink2.MAVLink_command_long_message(
            self.target[0], self.target[1], MAV_CMD_SET_MESSAGE_INTERVAL, self._attempt - 1,
            float(req.msg_id), float(req.interval_us), 0.0, 0.0, 0.0, 0.0, 0.0,
        )
