"""Live-link helpers: tlog records sent over real UDP on 127.0.0.1 (paced, or all at once
under flow control), a receive clock the test moves, waiting on a condition, a
``mavnav run`` process on a free port.
"""

from __future__ import annotations

import signal
import socket
import subprocess
import sys
import threading
import time
from dataclasses import replace
from pathlib import Path

from pymavlink import mavutil

from mavnav.samples import (
    AutopilotHeight, BaroHeight, GnssHeight, RangeHeight, SpecificForceUp,
)
from tests.support.emit import Peer

MEASUREMENTS = (SpecificForceUp, BaroHeight, GnssHeight, RangeHeight, AutopilotHeight)


def tlog_records(path):
    """(recv_s, frame) of a clean tlog."""
    data = Path(path).read_bytes()
    out, pos = [], 0
    while pos + 10 <= len(data):
        stx, plen = data[pos + 8], data[pos + 9]
        flen = (6 + plen + 2) if stx == 0xFE else (10 + plen + 2 + (13 if data[pos + 10] & 1 else 0))
        out.append((int.from_bytes(data[pos:pos + 8], "big") / 1e6, data[pos + 8:pos + 8 + flen]))
        pos += 8 + flen
    return out


class Sender(threading.Thread):
    """Streams tlog frames over UDP at ``speed`` times their recorded pace, frames
    received within ``batch_s`` of each other in one datagram; pauses on request."""

    def __init__(self, records, addr, speed=1.0, batch_s=0.02, pause_at=None, pause_s=0.0):
        super().__init__(daemon=True)
        self.records, self.addr, self.speed, self.batch_s = records, addr, speed, batch_s
        self.pause_at, self.pause_s = pause_at, pause_s

    def run(self):
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        t_log0, t_wall0 = self.records[0][0], time.monotonic()
        paused = 0.0
        i = 0
        n = len(self.records)
        while i < n:
            t0 = self.records[i][0]
            chunk = bytearray()
            while i < n and self.records[i][0] - t0 <= self.batch_s and len(chunk) < 8000:
                chunk += self.records[i][1]
                i += 1
            if self.pause_at is not None and not paused and t0 - t_log0 >= self.pause_at:
                time.sleep(self.pause_s)
                paused = self.pause_s
            due = t_wall0 + paused + (t0 - t_log0) / self.speed
            delay = due - time.monotonic()
            if delay > 0:
                time.sleep(delay)
            sock.sendto(bytes(chunk), self.addr)
        sock.close()


def no_recv(items):
    return [replace(s, recv_s=0.0) for s in items if isinstance(s, MEASUREMENTS)]


class ReceiveClock:
    """Unix seconds the test controls: steady while data flows, moved on to make a silence."""

    def __init__(self):
        self.now = 1_700_000_000.0
        self._lock = threading.Lock()

    def __call__(self) -> float:
        with self._lock:
            self.now += 1e-4
            return self.now

    def skip(self, s: float) -> None:
        with self._lock:
            self.now += s


def wait_until(cond, timeout=10.0):
    deadline = time.monotonic() + timeout
    while not cond():
        if time.monotonic() > deadline:
            return False
        time.sleep(0.005)
    return True


def send_all(sock, src, records) -> None:
    """Send tlog records to a LiveSource and wait until its reader has them all
    (flow control every 25 frames, not pacing)."""
    start = src._reader.frames
    for i, (_, frame) in enumerate(records):
        sock.sendto(frame, src.local_address)
        if i % 25 == 24:
            assert wait_until(lambda: src._reader.frames >= start + i + 1 - 50)
    assert wait_until(lambda: src._reader.frames == start + len(records))


MAVNAV = Path(sys.executable).parent / "mavnav"


SPEED = 8.0


def free_udp_port() -> int:
    return free_udp_ports(1)[0]


def free_udp_ports(n: int) -> list:
    """``n`` distinct free UDP ports of 127.0.0.1 (all held until all are
    chosen: ports asked for one by one may come back the same)."""
    socks = [socket.socket(socket.AF_INET, socket.SOCK_DGRAM) for _ in range(n)]
    try:
        for s in socks:
            s.bind(("127.0.0.1", 0))
        return [s.getsockname()[1] for s in socks]
    finally:
        for s in socks:
            s.close()


def tlog_frames(path: Path, seconds: float):
    """``(offset s, frame bytes)`` of a tlog's first ``seconds`` (record time)."""
    log = mavutil.mavlink_connection(str(path))
    out, t0 = [], None
    while True:
        m = log.recv_msg()
        if m is None:
            break
        t0 = m._timestamp if t0 is None else t0
        if m._timestamp - t0 > seconds:
            break
        out.append((m._timestamp - t0, bytes(m.get_msgbuf())))
    log.close()
    return out


def send_paced(peer: Peer, port: int, frames, speed: float = SPEED) -> None:
    start = time.monotonic()
    for t, buf in frames:
        wait = start + t / speed - time.monotonic()
        if wait > 0:
            time.sleep(wait)  # the simulated vehicle's clock, not a wait for a result
        peer.sock.sendto(buf, ("127.0.0.1", port))


class LiveRun:
    """``mavnav run udpin:127.0.0.1:PORT ARGS`` as a process, stopped with SIGTERM."""

    def __init__(self, tmp_path: Path, args, port: int = 0):
        self.port = port or free_udp_port()
        self.err_path = tmp_path / f"run-{self.port}.err"
        self._err = self.err_path.open("w")
        self.proc = subprocess.Popen([str(MAVNAV), "run", f"udpin:127.0.0.1:{self.port}", *args],
                                     stdout=subprocess.DEVNULL, stderr=self._err, stdin=subprocess.DEVNULL)

    def stderr(self) -> str:
        return self.err_path.read_text()

    def wait_for_text(self, text: str, timeout: float = 30.0) -> bool:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if text in self.stderr():
                return True
            if self.proc.poll() is not None:
                return text in self.stderr()
            time.sleep(0.05)  # polling a file for a condition, bounded
        return False

    def stop(self) -> str:
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
        try:
            self.proc.wait(20)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait(5)
        self._err.close()
        return self.stderr()
