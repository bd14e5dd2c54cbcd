"""A live MAVLink link: :class:`LiveSource` over any pymavlink connection string.

pymavlink opens the port (``udpin:``, ``udpout:``, ``tcp:``, ``tcpin:``, a
serial device with ``baud`` or written ``/dev/ttyUSB0,57600``); the bytes it
receives go through :class:`~.stream_reader.StreamReader` and the same
:class:`~.normaliser.Normaliser` as a tlog. The wall clock (``clock``,
injectable) is read only here: it stamps each received chunk and drives the
link-loss timer. The source never transmits.
"""

from __future__ import annotations

import threading
import time
from typing import Callable, Iterator, Optional

from pymavlink import mavutil

from ..config import IngestConfig
from ..errors import InputError
from .normaliser import WANTED, Normaliser
from .stats import IngestStats
from .stream_reader import StreamReader
from .tlog import fill_message_stats

_RECV_BYTES = 65536


def _split_baud(connection: str, baud: Optional[int]):
    """``/dev/ttyUSB0,57600`` -> (``/dev/ttyUSB0``, 57600); other strings unchanged."""
    if "," in connection:
        dev, _, b = connection.rpartition(",")
        if b.strip().isdigit():
            return dev, int(b)
    return connection, baud


class LiveSource:
    """Iterate samples and events from a live link until :meth:`close` (from any thread).

    ``poll_s`` bounds how long one wait for data lasts, hence how promptly a
    close is noticed and a link loss is reported.
    """

    def __init__(
        self,
        connection: str,
        config: Optional[IngestConfig] = None,
        sysid: Optional[int] = None,
        *,
        clock: Callable[[], float] = time.time,
        baud: Optional[int] = None,
        poll_s: float = 0.05,
    ):
        self.connection = connection
        self.config = config if config is not None else IngestConfig()
        self.sysid = sysid
        self.clock = clock
        self.poll_s = poll_s
        self.stats = IngestStats(source=connection)
        self._closed = threading.Event()
        device, baud = _split_baud(connection, baud)
        kwargs = {"baud": baud} if baud is not None else {}
        if device.startswith("tcp:"):
            kwargs["autoreconnect"] = True
        try:
            self._conn = mavutil.mavlink_connection(device, **kwargs)
        except Exception as exc:  # socket, serial and parsing errors alike
            raise InputError(f"{connection}: cannot open ({exc})") from None
        self._reader = StreamReader(WANTED)
        self._norm = Normaliser(self.config, sysid, self.stats)

    @property
    def mav(self):
        """The underlying pymavlink connection (for sending back on the same link)."""
        return self._conn

    @property
    def local_address(self):
        """``(host, port)`` the link is bound to (sockets only; ``udpin:HOST:0`` picks a free port)."""
        port = getattr(self._conn, "port", None)
        try:
            return port.getsockname()
        except Exception:
            return None

    def close(self) -> None:
        """Stop iterating (promptly, from any thread) and release the port."""
        if not self._closed.is_set():
            self._closed.set()
            try:
                self._conn.close()
            except Exception:
                pass

    def __enter__(self) -> "LiveSource":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def __iter__(self) -> Iterator[object]:
        norm, reader = self._norm, self._reader
        out = norm.out
        conn = self._conn
        closed = self._closed
        while not closed.is_set():
            try:
                ready = conn.select(self.poll_s)
                data = conn.recv(_RECV_BYTES) if ready else b""
            except Exception:
                if closed.is_set():
                    break
                data = b""  # a transient socket or serial error: keep listening
                time.sleep(self.poll_s)
            now = self.clock()
            if data:
                for item in reader.feed(data if isinstance(data, (bytes, bytearray)) else bytes(data, "latin-1"), now):
                    if type(item) is tuple:
                        norm.feed(*item)
                    else:
                        norm.problem(item)
            norm.tick(now)
            if out:
                yield from out
                out.clear()
        norm.finish()
        fill_message_stats(self.stats, reader, norm.sysid)
        yield from out
        out.clear()
