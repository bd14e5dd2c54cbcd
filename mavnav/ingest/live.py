"""A live MAVLink link: :class:`LiveSource` over any pymavlink connection string.

pymavlink opens the port (``udpin:``, ``udpout:``, ``tcp:``, ``tcpin:``, a
serial device with ``baud`` or written ``/dev/ttyUSB0,57600``); the bytes it
receives go through :class:`~.stream_reader.StreamReader` and the same
:class:`~.normaliser.Normaliser` as a tlog. The wall clock (``clock``,
injectable) is read only here: it stamps each received chunk and drives the
link-loss timer. The source never transmits.

**No input lost to a busy consumer.** A receive thread drains the port as
data arrives, stamps each chunk with its receive time and queues it; the
iterator parses and normalises from the queue. When the monitor or a sink
stalls (the filter bank compiled at the first epoch, a viewer starting, a
burst of held samples released), the datagrams wait in the queue instead of
overflowing the socket's receive buffer, which is enlarged as well
(``SO_RCVBUF``, up to :data:`RCVBUF_BYTES`) for the moments the thread
itself is not scheduled. The queue is bounded (``max_backlog_bytes``): a
consumer that stays slower than the link drops what does not fit, counted
in ``stats.dropped_chunks``. The link-loss timer runs only when the queue is
empty, so a backlog is never taken for silence.

**Reordered datagrams** are put back in MAVLink sequence order by the
reader (:mod:`.stream_reader`): a gap waits up to :data:`REORDER_S` for its
late frames, so nothing is refused as out of order downstream.

**Replies for a sink** (:meth:`LiveSource.tap`): a sink that writes back on
this link (``--emit input``) and sends commands needs the vehicle's answers,
which only this source reads. A tap receives the monitored vehicle's
HEARTBEAT and COMMAND_ACK messages as pymavlink message objects, in the
thread that iterates the source (the pipeline's), as they are parsed.
"""

from __future__ import annotations

import queue
import socket
import threading
import time
from typing import Callable, Iterator, List, Optional

from pymavlink import mavutil

from pymavlink.dialects.v20 import ardupilotmega as _dialect

from ..config import IngestConfig
from ..errors import InputError
from . import wire
from .normaliser import WANTED, Normaliser
from ..samples import Rejected
from .stats import IngestStats
from .stream_reader import StreamReader
from .tlog import fill_message_stats

_RECV_BYTES = 65536
RCVBUF_BYTES = 8 << 20  # 8 MiB: ~10 s of a busy 4x link in the kernel
MAX_BACKLOG_BYTES = 256 << 20
REORDER_S = 0.1  # a sequence gap waits this long for its late frames (receive time)
REORDER_FRAMES = 100  # or this many frames behind it (stream_reader.MAX_DISPLACEMENT)
TAPPED = frozenset((wire.MSG_ID["HEARTBEAT"], wire.MSG_ID["COMMAND_ACK"]))  # handed to taps
TAP_ONLY = TAPPED - WANTED  # read for the taps alone, never normalised


def _enlarge_rcvbuf(conn, nbytes: int = RCVBUF_BYTES) -> Optional[int]:
    """Ask for a large receive buffer on a socket link (the kernel may cap it); its size, or None."""
    sock = getattr(conn, "port", None)
    if not isinstance(sock, socket.socket):
        return None
    force = getattr(socket, "SO_RCVBUFFORCE", None)  # beyond rmem_max when privileged
    for opt in ((force,) if force is not None else ()) + (socket.SO_RCVBUF,):
        try:
            sock.setsockopt(socket.SOL_SOCKET, opt, nbytes)
            break
        except OSError:
            continue
    try:
        return sock.getsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF)
    except OSError:
        return None


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
    close is noticed and a link loss is reported. ``max_backlog_bytes``
    bounds what waits between the receive thread and the consumer.
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
        max_backlog_bytes: int = MAX_BACKLOG_BYTES,
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
        self._reader = StreamReader(WANTED | TAPPED, reorder_s=REORDER_S, reorder_frames=REORDER_FRAMES)
        self._taps: list = []
        self._tap_decoders = {mid: wire.make_decoder(mid) for mid in TAPPED}
        self._norm = Normaliser(self.config, sysid, self.stats, link_name=self._link_name(connection))
        self.stats.format = "live"
        self.rcvbuf_bytes = _enlarge_rcvbuf(self._conn)
        self.max_backlog_bytes = max_backlog_bytes
        # queue.Queue, not SimpleQueue: a SimpleQueue.get(timeout) interrupted by the SIGTERM
        # handler (which closes this source) was seen never to return (CPython 3.11.7)
        self._queue: "queue.Queue[tuple]" = queue.Queue()
        self._backlog = 0  # bytes queued and not yet parsed
        self._backlog_lock = threading.Lock()
        self._receiver: Optional[threading.Thread] = None

    @property
    def mav(self):
        """The underlying pymavlink connection (for sending back on the same link)."""
        return self._conn

    def _link_name(self, connection: str) -> str:
        """The connection string, with the port actually bound when it asked for any (``:0``)."""
        addr = self.local_address
        scheme, _, rest = connection.partition(":")
        if addr and scheme in ("udpin", "udp", "tcpin") and rest.rpartition(":")[2] == "0":
            return f"{scheme}:{rest.rpartition(':')[0]}:{addr[1]}"
        return connection

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
            th = self._receiver
            if th is not None and th is not threading.current_thread():
                th.join(max(1.0, 4 * self.poll_s))  # out of select() before the port closes
            try:
                self._conn.close()
            except Exception:
                pass

    @property
    def backlog_bytes(self) -> int:
        """Received and not yet parsed (the receive thread is ahead of the consumer by this much)."""
        return self._backlog

    def _receive(self) -> None:
        """The receive thread: drain the port into the queue until closed."""
        conn, q, closed, clock = self._conn, self._queue, self._closed, self.clock
        while not closed.is_set():
            try:
                if not conn.select(self.poll_s):
                    continue
                while not closed.is_set():  # everything the port holds now
                    data = conn.recv(_RECV_BYTES)
                    if not data:
                        break
                    if not isinstance(data, (bytes, bytearray)):
                        data = bytes(data, "latin-1")
                    now = clock()
                    with self._backlog_lock:
                        if self._backlog + len(data) > self.max_backlog_bytes:
                            self.stats.dropped_chunks += 1
                            continue
                        self._backlog += len(data)
                    q.put((now, data))
            except Exception:
                if closed.is_set():
                    break
                time.sleep(self.poll_s)  # a transient socket or serial error: keep listening

    def tap(self, callback: Callable[[object], None]) -> None:
        """Hand the monitored vehicle's HEARTBEAT and COMMAND_ACK messages to ``callback``
        (pymavlink message objects), in the iterating thread."""
        self._taps.append(callback)

    def _to_taps(self, msgid: int, sysid: int, compid: int, payload: bytes) -> List[object]:
        """Returns what the normaliser says of a malformed payload (else nothing)."""
        if sysid != self._norm.sysid:
            return []  # another system's heartbeat or answer: not the vehicle the commands go to
        try:
            fields = self._tap_decoders[msgid](payload)
            cls = _dialect.mavlink_map[msgid]
            msg = cls(*[fields[n] for n in cls.fieldnames])
            msg._header = _dialect.MAVLink_header(msgid, srcSystem=sysid, srcComponent=compid)
        except Exception as exc:  # a CRC-valid but malformed payload
            return self._norm.problem(Rejected(self.clock(), "malformed", f"{wire.msg_name(msgid)}: {exc}"))
        for cb in self._taps:
            cb(msg)
        return []

    def _handle(self, items) -> List[object]:
        """The reader's frames and problems through the normaliser (and the taps): what they release."""
        norm = self._norm
        out: List[object] = []
        for item in items:
            if type(item) is tuple:
                msgid = item[1]
                if msgid not in TAP_ONLY:
                    out += norm.feed(*item)
                if msgid in TAPPED and self._taps:
                    out += self._to_taps(*item[1:])
            else:
                out += norm.problem(item)
        return out

    def _start_receiver(self) -> None:
        if self._receiver is None and not self._closed.is_set():
            self._receiver = threading.Thread(target=self._receive, name="mavnav-receive", daemon=True)
            self._receiver.start()

    def __enter__(self) -> "LiveSource":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def __iter__(self) -> Iterator[object]:
        norm, reader = self._norm, self._reader
        q = self._queue
        closed = self._closed
        self._start_receiver()
        while not closed.is_set():
            try:
                recv_s, data = q.get(timeout=self.poll_s)
            except queue.Empty:
                data = None
            out: List[object] = []
            if data:
                with self._backlog_lock:
                    self._backlog -= len(data)
                out += self._handle(reader.feed(data, recv_s))
            if q.empty():  # caught up: a silence now is a silence on the link, not a backlog
                now = self.clock()
                out += self._handle(reader.expire(now))
                out += norm.tick(now)
            if out:
                yield from out
        out = self._handle(reader.flush())
        out += norm.finish()
        fill_message_stats(self.stats, reader, norm.sysid)
        yield from out
