"""The transmit side of a MAVLink link: guarded writes and MAVLink 2 signing keys.

:class:`LinkWriter` writes whole frames to any pymavlink connection
(``conn.write(bytes)``). A send that fails never raises: the first failure
of an outage is logged once, later ones are only counted, and a send that
works again is logged as a recovery. pymavlink itself swallows socket errors
on UDP and TCP, so a closed socket or a dropped TCP peer is detected by
looking at the connection's port as well.

Signing keys (:func:`load_signing_key`): a key file holds either

* exactly 32 raw bytes (the secret key itself), when they are not all
  printable text; or
* a passphrase (UTF-8 text; surrounding whitespace and the trailing newline
  are stripped), hashed with SHA-256 to the 32-byte key, as MAVProxy's
  ``signing setup PASSPHRASE`` does, so a vehicle set up from MAVProxy with
  that passphrase accepts mavnav's frames.

A 64-character hex string is a passphrase under this rule, not a key.

TCP: the CLI opens TCP links with pymavlink's reconnection and a single
connect attempt per try; while the peer is gone the writer tries again at
most every ``retry_s`` seconds (wall clock) and drops frames in between.
pymavlink's connect is blocking, so a peer that vanished without refusing
connections can still stall one attempt: prefer UDP for ``--emit``.
"""

from __future__ import annotations

import hashlib
import logging
import socket
import time
from pathlib import Path
from typing import Callable, Optional, Union

from ..errors import ConfigError

log = logging.getLogger("mavnav.sinks.mavlink_out")

KEY_BYTES = 32
_TEXT_BYTES = frozenset(range(0x20, 0x7F)) | {0x09, 0x0A, 0x0D}


def passphrase_to_key(passphrase: str) -> bytes:
    """MAVProxy's rule: SHA-256 of the passphrase."""
    return hashlib.sha256(passphrase.encode("utf-8")).digest()


def load_signing_key(path: Union[str, Path]) -> bytes:
    """The 32-byte secret key from a key file (raw key or passphrase; see the module docstring)."""
    p = Path(path)
    try:
        data = p.read_bytes()
    except OSError as exc:
        raise ConfigError(f"{p}: cannot read the signing key ({exc.strerror or exc})") from None
    if len(data) == KEY_BYTES and not set(data) <= _TEXT_BYTES:
        return data
    try:
        text = data.decode("utf-8").strip()
    except UnicodeDecodeError:
        raise ConfigError(
            f"{p}: a signing key file holds 32 raw bytes or a text passphrase; this is {len(data)} bytes of binary"
        ) from None
    if not text:
        raise ConfigError(f"{p}: the signing key file is empty")
    return passphrase_to_key(text)


def _port_problem(conn) -> Optional[str]:
    """Why a connection cannot send, when pymavlink would hide it (None if it looks usable)."""
    port = getattr(conn, "port", "absent")
    if port is None:
        return "not connected"
    if isinstance(port, socket.socket) and port.fileno() < 0:
        return "socket closed"
    return None


class LinkWriter:
    """Writes frames to a pymavlink connection; failures are reported once per outage, never raised."""

    def __init__(self, conn, description: str, *, retry_s: float = 1.0,
                 clock: Callable[[], float] = time.monotonic):
        self.conn = conn
        self.description = description
        self.retry_s = retry_s
        self.clock = clock
        self._last_attempt = -float("inf")
        self.frames_sent = 0
        self.bytes_sent = 0
        self.failures = 0
        self.outages = 0
        self.last_error: Optional[str] = None
        self._failing = False

    def write(self, buf: bytes) -> bool:
        problem = _port_problem(self.conn)
        if problem == "not connected":  # pymavlink reconnects inside write(): not too often
            now = self.clock()
            if now - self._last_attempt >= self.retry_s:
                self._last_attempt = now
                problem = None
        if problem is None:
            try:
                r = self.conn.write(buf)
            except Exception as exc:  # any transport: serial, socket, file
                problem = f"{type(exc).__name__}: {exc}"
            else:
                if r == -1:  # pymavlink's serial write reports a dead device this way
                    problem = "device write failed"
                else:
                    problem = _port_problem(self.conn)  # a TCP peer gone during this write
        if problem is not None:
            self.failures += 1
            self.last_error = problem
            if not self._failing:
                self._failing = True
                self.outages += 1
                log.warning("MAVLink output %s: send failed (%s); the monitor goes on, "
                            "further failures are counted", self.description, problem)
            return False
        if self._failing:
            self._failing = False
            log.warning("MAVLink output %s: sending again (%d sends failed so far)", self.description, self.failures)
        self.frames_sent += 1
        self.bytes_sent += len(buf)
        return True
