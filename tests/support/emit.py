"""MAVLink output helpers: a pymavlink peer on 127.0.0.1 (:class:`Peer`), an
autopilot that answers commands (:class:`Autopilot`), hand-made epoch reports and
alarm events, STATUSTEXT reassembly, a MAVLink output sink aimed at a peer.
"""

from __future__ import annotations

import socket
import threading
import time
from typing import Callable, List, Optional

import numpy as np
from pymavlink.dialects.v20 import common as mavlink2

from mavnav.cli.emit_options import open_link
from mavnav.report import (
    CHANNEL_NAMES, PAIR_NAMES, SOURCES, AlarmEvent, ChannelReport, EpochReport, PairReport, SourceStatus,
)
from mavnav.sinks.base import Sink
from mavnav.config import Config, config_from_dict
from mavnav.sinks.mavlink_out import MavlinkOutSink


F32 = np.float32


class Peer:
    """A pymavlink endpoint on a UDP port of 127.0.0.1: decodes all it receives, in a thread.

    ``key``: check MAVLink 2 signatures with this key (unsigned frames are
    then refused too, unless ``allow_unsigned``).
    """

    def __init__(self, key: Optional[bytes] = None, allow_unsigned: bool = False, sysid: int = 1, compid: int = 1):
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        # a max-speed replay sends minutes of telemetry in a fraction of a
        # second: a receive buffer for the whole burst, or loopback drops it
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4 << 20)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.settimeout(0.02)
        self.port = self.sock.getsockname()[1]
        self.mav = mavlink2.MAVLink(None, srcSystem=sysid, srcComponent=compid)
        self.mav.robust_parsing = True
        if key is not None:
            self.mav.signing.secret_key = key
            self.mav.signing.timestamp = int(max(time.time() - 1420070400, 0) * 100_000)
            self.mav.signing.allow_unsigned_callback = (lambda mav, msgid: True) if allow_unsigned else (
                lambda mav, msgid: False)
        self.msgs: list = []
        self.bad: list = []
        self.last_from = None
        self.handler: Optional[Callable] = None  # called in the receive thread: handler(peer, msg)
        self._cond = threading.Condition()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    @property
    def url(self) -> str:
        return f"udpout:127.0.0.1:{self.port}"

    def _run(self) -> None:
        while not self._stop.is_set():
            try:
                data, addr = self.sock.recvfrom(65536)
            except (socket.timeout, OSError):
                continue
            out = self.mav.parse_buffer(data) or []
            with self._cond:
                self.last_from = addr
                for m in out:
                    (self.bad if m.get_type() == "BAD_DATA" else self.msgs).append(m)
                self._cond.notify_all()
            if self.handler is not None:
                for m in out:
                    self.handler(self, m)

    def of(self, mtype: str, compid: Optional[int] = None) -> list:
        with self._cond:
            return [m for m in self.msgs if m.get_type() == mtype
                    and (compid is None or m.get_srcComponent() == compid)]

    def wait_for(self, cond: Callable[[], bool], timeout: float = 5.0) -> bool:
        deadline = time.monotonic() + timeout
        with self._cond:
            while not cond():
                left = deadline - time.monotonic()
                if left <= 0:
                    return False
                self._cond.wait(min(left, 0.05))
        return True

    def clear(self) -> None:
        with self._cond:
            self.msgs.clear()
            self.bad.clear()

    def send(self, msg, addr=None) -> None:
        self.sock.sendto(msg.pack(self.mav), addr or self.last_from)
        self.mav.seq = (self.mav.seq + 1) % 256

    def close(self) -> None:
        self._stop.set()
        self._thread.join(2)
        self.sock.close()


def status(state="nominal"):
    return SourceStatus(state=state, since_t_s=0.0, reason="", window_stat=1.5)


def report(t_us: int, h: float = 12.5, sigma: float = 0.4, *, boot: int = 0, overall: str = "nominal",
           rng: str = "nominal", rng_agl: float = 7.25, rng_h: float = 7.5, baro_h: float = 13.0) -> EpochReport:
    chans = tuple(
        ChannelReport(n, rng_h if n == "rangefinder" else h + 0.1 * i, 0.3, 0.2, 0.0, 0.0, True, True,
                      1.0 + i, 2, 0.1, -0.2)
        for i, n in enumerate(CHANNEL_NAMES)
    )
    pairs = tuple(PairReport(n, 0.5 * (i + 1), 3.0, False, True) for i, n in enumerate(PAIR_NAMES))
    sources = {s: status(rng if s == "rangefinder" else "nominal") for s in SOURCES}
    return EpochReport(t_us=t_us, boot=boot, height_fused_m=h, sigma_fused_m=sigma, channels=chans, pairs=pairs,
                       sources=sources, overall=overall, vpl_m=2.5, alert_limit_m=10.0,
                       baro_height_ref_m=baro_h, range_height_agl_m=rng_agl)


class Text:
    """One STATUSTEXT as a ground station shows it: MAVLink 2 chunks joined."""

    def __init__(self, first):
        self.first, self.severity, self.id = first, first.severity, first.id
        self.parts = [(first.chunk_seq, first.text)]

    @property
    def text(self) -> str:
        """The chunks joined, the spaces that pad a chunk to the field collapsed."""
        return " ".join("".join(t for _, t in sorted(self.parts)).split())


def texts_of(msgs, strict: bool = True) -> List[Text]:
    """STATUSTEXT messages reassembled: ``id`` 0 is a whole text; chunks of one nonzero
    ``id`` are joined in ``chunk_seq`` order (the last is shorter than 50 characters).
    Not ``strict`` (while messages are still arriving): only the complete texts."""
    out: List[Text] = []
    open_: dict = {}
    for m in msgs:
        if m.get_type() != "STATUSTEXT":
            continue
        if m.id == 0:
            out.append(Text(m))
            continue
        t = open_.get(m.id)
        if t is None:
            t = open_[m.id] = Text(m)
            out.append(t)
        else:
            assert m.severity == t.severity
            t.parts.append((m.chunk_seq, m.text))
        if len(m.text) < 50:
            del open_[m.id]
    if not strict:
        return [t for t in out if t not in open_.values()]
    assert not open_, "a chunked STATUSTEXT without its last chunk"
    return out


def event(t_s: float, source="gnss", state="alarm", previous="nominal", reason="innovation 6.1 sigma", boot=0):
    return AlarmEvent(t_us=int(round(t_s * 1e6)), boot=boot, source=source, state=state, previous=previous,
                      reason=reason)


def feed(sink: Sink, reports) -> List[EpochReport]:
    out = []
    for r in reports:
        sink.epoch(r)
        out.append(r)
    return out


def reports_every(dt_s: float, duration_s: float, t0_s: float = 0.0, **kw) -> List[EpochReport]:
    n = int(round(duration_s / dt_s))
    return [report(int(round((t0_s + k * dt_s) * 1e6)), h=10.0 + 0.01 * k, **kw) for k in range(n)]


def emit_config(**emit) -> Config:
    """The default configuration with these keys in its ``emit:`` section (refused as a file's would be)."""
    return config_from_dict({"emit": emit})


def udp_sink(peer: Peer, *, allow_commands: bool = False, signing_secret: Optional[bytes] = None,
             **emit) -> MavlinkOutSink:
    """A sink aimed at ``peer``, sending as the ``emit:`` keys given say."""
    config = emit_config(**emit)
    return MavlinkOutSink(open_link(peer.url, config.emit.sysid, config.emit.compid), config,
                          allow_commands=allow_commands, signing_secret=signing_secret, description=peer.url)


R = mavlink2


def autopilot_heartbeat():
    return R.MAVLink_heartbeat_message(R.MAV_TYPE_QUADROTOR, R.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 0,
                                       R.MAV_STATE_STANDBY, 3)


class Autopilot:
    """Answers SET_MESSAGE_INTERVAL per message id: a list of answers, one per request (the last one
    repeats); an answer is a result, a tuple of results sent in a row, or None (silent)."""

    def __init__(self, peer: Peer, policy: dict):
        self.peer = peer
        self.policy = {k: list(v) for k, v in policy.items()}
        self.commands = []
        self.heartbeats_sent = 0
        peer.handler = self.handle

    def handle(self, peer, m):
        if m.get_type() == "HEARTBEAT" and m.get_srcComponent() == 191 and len(peer.of("HEARTBEAT", 191)) == 1:
            peer.send(autopilot_heartbeat())  # the vehicle announces itself once it knows the address
            self.heartbeats_sent += 1
        if m.get_type() != "COMMAND_LONG":
            return
        self.commands.append(m)
        answers = self.policy.get(int(m.param1), [R.MAV_RESULT_ACCEPTED])
        result = answers.pop(0) if len(answers) > 1 else answers[0]
        for res in (result if isinstance(result, tuple) else () if result is None else (result,)):
            peer.send(R.MAVLink_command_ack_message(m.command, res, 0, 0, m.get_srcSystem(), m.get_srcComponent()))


def run_until(sink, cond, timeout=10.0):
    t = 0
    deadline = time.monotonic() + timeout
    while not cond() and time.monotonic() < deadline:
        sink.epoch(report(t))
        t += 20_000
        time.sleep(0.002)  # live pacing: the vehicle answers in real time
    return cond()
