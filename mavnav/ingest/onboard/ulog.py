"""PX4 ULog (``.ulg``) -> :class:`~.record.OnboardRecord`.

pyulog parses the file, keeping only the topics below
(``message_name_filter_list``); the columns come straight from its numpy
arrays (``Data.data``), never a Python object per row.

Topics and fields, PX4 1.9 to 1.17 (fields are looked up, not assumed):

* time: ``timestamp`` (us since boot); ``timestamp_sample`` instead where the
  topic has it and it is nonzero (the sensor's sample time; 0 in the GPS
  topics), for ``sensor_combined`` ``timestamp + accelerometer_timestamp_relative``
  (unless that is ``INT32_MAX``, "invalid").
* IMU: ``sensor_combined`` ``accelerometer_m_s2[0..2]`` (body FRD).
* attitude: ``vehicle_attitude`` ``q[0..3]`` (w, x, y, z, body to NED).
* baro: ``vehicle_air_data`` ``baro_pressure_pa`` (the estimator's baro, Pa;
  its instance is the ``sensor_baro`` instance whose ``device_id`` equals
  ``baro_device_id``, else 0); without it ``sensor_baro`` instance 0 (or the
  lowest) ``pressure``: Pa since PX4 1.12, hPa before (told apart by
  magnitude: a median below 2000 is hPa).
* GNSS: ``vehicle_gps_position`` (the GPS the estimator uses; PX4 >= 1.14
  logs it with ``sensor_gps``'s fields), else the ``sensor_gps`` instance with
  the most rows. Altitude ``altitude_msl_m`` (m, PX4 >= 1.15) or ``alt``
  (integer mm; metres if a log stores it as a float). ``epv`` (m) is sigma
  when finite and > 0. Every fix type is kept (MAVLink numbering).
* rangefinder: ``distance_sensor`` rows with ``orientation`` 25 (downward),
  from the instance with the most such rows; ``valid`` is
  ``signal_quality != 0`` (-1 "unknown" is valid; no field: all valid).
* autopilot: ``vehicle_local_position`` ``-z`` above the EKF origin, rows
  with ``z_valid`` (when logged); the origin altitude is ``ref_alt`` of the
  latest row whose reference is valid (``z_global``, else ``xy_global``, else
  ``ref_timestamp > 0``).
* home: ``home_position`` ``alt`` (MSL) of the first row with ``valid_alt``
  and a timestamp in the log: where the vehicle armed, as the DataFlash
  reader takes ORGN's first AHRS home. PX4 sets home again at each arming
  and, on some logs, after landing over an EKF height that has drifted: the
  latest home of flug_log_13 lies 1.9 m below the point it took off from
  (its ``-z`` on the ground -8.48 m, the first home's ``z`` 8.47 m, the
  last's 6.59 m), so the vehicle read 1.9 m off the datum on the ground.
* firmware from ``ver_sw_release`` (``sys_name``, default "PX4"), else the
  ``ver_sw`` git hash; vehicle from ``vehicle_status`` (``is_vtol``,
  ``vehicle_type`` or old ``is_rotary_wing``), else the ``MAV_TYPE`` parameter.

Every series is sorted by time; rows with no time, non-finite values (or a
quaternion far from unit norm) and repeated times are dropped, one line in
``damage`` per series saying how many. Damage to the file itself (cut short,
corrupt bytes pyulog skipped, logger dropouts, pyulog giving up mid-file)
is reported there too; only a file that is not a ULog at all, or from which
nothing usable can be read, raises :class:`~mavnav.errors.InputError`.

pyulog reports corruption with ``print``: those lines are captured (per
thread) into ``damage`` instead of reaching stdout. It reads through a file
object that watches its seeks, so that a corrupt file cannot make it loop.

Speed: pyulog reads the data section one message at a time in Python (two
reads, a dispatch and a buffer append per message, kept topic or not). The
same result is built in bulk (:func:`_load_bulk`): pyulog reads the header
and definitions; a compiled walk (:func:`_walk`) finds every message's
offset, following pyulog's recovery from corrupt bytes (its resync on the
sync sequence) step for step; the rows of the kept topics are gathered with
numpy into the buffers pyulog would have filled; every other message
(subscriptions, info, parameters, log strings, dropouts) goes through
pyulog's own message classes in file order. Where pyulog's loop would do
something the walk does not follow (a message cut by the end of the file,
a resync that finds no sync sequence, a message its classes refuse, a
subscription given twice), pyulog's own loop takes over from that message,
in the state it would be in there, so damage is found and reported exactly
as before; with appended data or damaged definitions it reads the whole
file. ``read_ulog(path,
bulk=False)`` is pyulog's loop throughout; the tests check both give the
same pyulog state and record on every committed log and on cut, spliced and
bit-flipped copies.
"""

from __future__ import annotations

import builtins
import io
import os
import sys
import threading
from collections import Counter
from typing import Callable, Dict, List, NamedTuple, Optional, Tuple

import numpy as np

from ...errors import InputError
from ...jit import njit
from .head import read_head
from .record import (
    AttitudeSeries,
    AutopilotSeries,
    BaroSeries,
    GnssSeries,
    ImuSeries,
    OnboardRecord,
    RangeSeries,
)

ULOG_MAGIC = b"ULog\x01\x12\x35"
HEADER_LEN = 16
TOPICS = [
    "sensor_combined",
    "vehicle_attitude",
    "vehicle_air_data",
    "sensor_baro",
    "vehicle_gps_position",
    "sensor_gps",
    "distance_sensor",
    "vehicle_local_position",
    "home_position",
    "vehicle_status",
]
ROTATION_DOWNWARD_FACING = 25  # distance_sensor.orientation, MAV_SENSOR_ROTATION_PITCH_270
RELATIVE_TIMESTAMP_INVALID = 0x7FFFFFFF  # sensor_combined.accelerometer_timestamp_relative
HPA_BELOW = 2000.0  # sensor_baro.pressure medians below this are hPa (PX4 <= 1.11)
QUAT_NORM_TOL = 0.1  # |q| outside 1 +- this is not an attitude (garbage rows)
_BACK_SEEK_REGRESSIONS = 64  # seeks back behind an earlier seek back: a looping parser beyond this
_VEHICLE_TYPE = {1: "copter", 2: "plane", 3: "rover"}  # vehicle_status.vehicle_type
_MAV_TYPE = {1: "plane", 2: "copter", 3: "copter", 4: "copter", 10: "rover", 11: "boat", 12: "sub",
             13: "copter", 14: "copter", 15: "copter", 19: "vtol", 20: "vtol", 21: "vtol", 22: "vtol",
             23: "vtol", 24: "vtol", 25: "vtol", 29: "copter", 35: "copter"}

Data = Dict[str, np.ndarray]


# --------------------------------------------------------------------- pyulog's prints

_capture = threading.local()


def _pyulog_print(*args, **kwargs) -> None:
    """Stands in for ``print`` inside ``pyulog.core``: kept for ``damage`` while
    this thread decodes a ULog, a normal print otherwise."""
    lines = getattr(_capture, "lines", None)
    if lines is None or kwargs.get("file") not in (None, sys.stdout):
        builtins.print(*args, **kwargs)
        return
    lines.append(kwargs.get("sep", " ").join(str(a) for a in args).strip())


def _install_print_capture(core) -> None:
    if getattr(core, "print", None) is not _pyulog_print:
        core.print = _pyulog_print  # a module global shadows the builtin, for pyulog.core only


# --------------------------------------------------------------------- guarded file

class _Guard:
    """Watches pyulog's reads and seeks: the first short read (a cut file),
    where it stopped, and seeks back behind an earlier seek back. pyulog's
    corruption recovery steps back over a header it could not use; near the
    end of the file, in the definitions section, that step can land before
    the header and the same bytes are scanned forever. The second identical
    jump (or too many such jumps) ends it: pyulog is given end-of-file.
    ``limit`` hides the bytes from that offset on."""

    def _guard_init(self, size: int, limit: Optional[int]) -> None:
        self.size = size
        self.limit = limit
        self.cut: Optional[Tuple[int, int, int]] = None  # (offset, wanted, got) of the first short read
        self.stopped_at: Optional[int] = None
        self.gave_up_at: Optional[int] = None
        self._last_back = -1
        self._regressions = 0
        self._loops: set = set()

    def read(self, n=-1):  # pyulog always asks for a size
        if self.gave_up_at is not None:
            return b""
        if self.limit is not None:
            pos = self.tell()
            if n is None or n < 0 or pos + n > self.limit:
                n = max(0, self.limit - pos)
        b = _buffered_read(self, n)  # super().read(n) of _GuardedFile, without super()'s lookup (once per pyulog read)
        if n is not None and len(b) < n and self.cut is None and not (n == 3 and not b) and n != 512:
            # 3: a header at the very end is a clean end; 512: pyulog's sync search chunk
            self.cut = (self.tell() - len(b), n, len(b))
        return b

    def seek(self, offset, whence=0):
        here = self.tell()
        if self.gave_up_at is not None:
            return here
        dest = offset if whence == 0 else here + offset if whence == 1 else self.size + offset
        if dest < 0:
            raise ValueError("seek before the start of the file")  # pyulog treats it as corruption
        if dest < here:
            if dest <= self._last_back:  # back behind an earlier step back: a loop, or a one-off
                self._regressions += 1
                if (here, dest) in self._loops or self._regressions > _BACK_SEEK_REGRESSIONS:
                    self.gave_up_at = here  # the same jump twice: pyulog would repeat it forever
                    return here
                self._loops.add((here, dest))
            self._last_back = dest
        return super().seek(dest, 0)

    def close(self):
        if not self.closed and self.stopped_at is None:
            self.stopped_at = self.tell()
        super().close()


_buffered_read = io.BufferedReader.read


class _GuardedFile(_Guard, io.BufferedReader):
    def __init__(self, path: str, size: int, limit: Optional[int] = None):
        io.BufferedReader.__init__(self, io.FileIO(path, "rb"), 1 << 16)
        self._guard_init(size, limit)


class _DefsFile(_GuardedFile):
    """:class:`_GuardedFile` for pyulog's header and definitions (thousands of
    small reads) with the file's own ``read``: the same bytes, without the
    guard's watch on each read. Its seeks are the guard's, counted. A read can
    come up short only at the end of the file, so the guard's record (no cut,
    no loop) is known afterwards where pyulog made one seek, from before the
    end: the step back over the first data message, where the definitions end
    (:meth:`whole`). Otherwise the guarded file reads the definitions again."""

    read = _buffered_read

    def _guard_init(self, size: int, limit: Optional[int]) -> None:
        super()._guard_init(size, limit)
        self.seeks = 0
        self.first_seek_from = -1

    def seek(self, offset, whence=0):
        if not self.seeks:
            self.first_seek_from = self.tell()
        self.seeks += 1
        return super().seek(offset, whence)

    def whole(self) -> bool:
        """Every read was whole and no seek was a loop: the guard would have
        recorded nothing but the one step back."""
        return self.seeks == 1 and 0 <= self.first_seek_from < self.size and self.limit is None


# --------------------------------------------------------------------- parsing

def _probe(path: str) -> int:
    """The file's size; :class:`InputError` unless it starts like a ULog."""
    if os.path.isdir(path):
        raise InputError(f"{path}: is a directory, not a ULog")
    head = read_head(path, HEADER_LEN)
    size = os.path.getsize(path)
    if not head:
        raise InputError(f"{path}: empty file, not a ULog")
    if not head.startswith(ULOG_MAGIC):
        raise InputError(f"{path}: not a PX4 ULog (no 'ULog' header)")
    if len(head) < HEADER_LEN:
        raise InputError(f"{path}: ULog cut inside its {HEADER_LEN}-byte header")
    return size


class _Parsed:
    def __init__(self, ulog, fh: _Guard, printed: List[str], bulk_to: Optional[int] = None):
        self.ulog = ulog
        self.fh = fh
        self.printed = printed
        self.bulk_to = bulk_to  # the data section was read in bulk up to this offset (None: not at all)


def _parse(fh: _GuardedFile) -> _Parsed:
    """pyulog over ``fh``; on an exception ``fh.stopped_at`` says where it was."""
    import pyulog.core as core

    _install_print_capture(core)
    printed: List[str] = []
    _capture.lines = printed
    try:
        ulog = core.ULog(fh, message_name_filter_list=list(TOPICS), disable_str_exceptions=True)
    finally:
        _capture.lines = None
        if not fh.closed:
            fh.stopped_at = fh.tell()
            fh.close()
    return _Parsed(ulog, fh, printed)


def _open(path: str, size: int, limit: Optional[int] = None) -> _GuardedFile:
    try:
        return _GuardedFile(path, size, limit)
    except OSError as exc:
        raise InputError(f"{path}: cannot read ({exc.strerror or exc})") from None


def _load(path: str, size: int, bulk: bool = True) -> Tuple[_Parsed, List[str]]:
    """pyulog's view of ``path``, and a damage line if pyulog raised mid-file
    (then the file is read again up to just before where it failed).
    ``bulk``: try :func:`_load_bulk` first (the same result, faster)."""
    from pyulog.exceptions import ULogIncompatibleFlagException

    if bulk:
        parsed = _load_bulk(path, size)
        if parsed is not None:
            return parsed, []
    fh = _open(path, size)
    try:
        return _parse(fh), []
    except ULogIncompatibleFlagException:
        raise InputError(f"{path}: ULog with unknown incompatible flags (a newer format, or a corrupt header)") from None
    except Exception as exc:  # pyulog gave up mid-file: read up to there
        at = fh.stopped_at
        why = f"{type(exc).__name__}: {exc}"[:200]
    if not at or at <= HEADER_LEN + 1:
        raise InputError(f"{path}: unreadable ULog ({why})")
    try:
        parsed = _parse(_open(path, size, limit=at - 1))
    except Exception as exc:
        raise InputError(f"{path}: unreadable ULog ({type(exc).__name__}: {exc})"[:300]) from None
    return parsed, [f"pyulog failed at byte {at} of {size} ({why}); read up to there, the rest is lost"]



# --------------------------------------------------------------------- bulk data section

_MSG_D, _MSG_A = ord("D"), ord("A")
# the data-section message types pyulog's loop reads; any other goes to its corruption recovery
_KNOWN_TYPES = np.zeros(256, dtype=np.bool_)
_KNOWN_TYPES[[ord(c) for c in "DAIMPQLCOS"]] = True
_SYNC = np.frombuffer(b"\x2F\x73\x13\x20\x25\x0C\xBB\x12", dtype=np.uint8)  # ULog.SYNC_BYTES
_SYNC_CHUNK = 512  # pyulog's _find_sync reads this much at a time, stepping back len(SYNC) - 1


@njit(cache=True)
def _find_sync(buf, lo, hi, sync):  # pragma: no cover - compiled
    """First offset ``j`` with ``buf[j:j+8] == sync`` inside ``[lo, hi)``, else -1."""
    m = sync.size
    for j in range(lo, hi - m + 1):
        if buf[j] == sync[0]:
            ok = True
            for q in range(1, m):
                if buf[j + q] != sync[q]:
                    ok = False
                    break
            if ok:
                return j
    return -1


@njit(cache=True)
def _walk(buf, start, limit, known, sync, last_back):  # pragma: no cover - compiled
    """pyulog's ``_read_file_data`` walk over the messages from ``start``
    (3-byte header: uint16 size, uint8 type) up to ``limit``, without
    decoding them. Returns the offsets of the messages of a type its loop
    reads, where the walk stopped (``buf.size``: a clean end; else the
    offset from which pyulog's own loop must go on: a message cut by the
    end of the file, or a recovery this walk does not follow), whether a
    recovery declared the file corrupt, and the guard's ``_last_back``
    (the last destination of a seek back) at that point.

    A message of another type is pyulog's recovery: a header that cannot be
    one (type 0, size 0 or above 10000) means corruption, one byte on and
    then the next sync sequence anywhere after it; any other unknown
    message is skipped, unless a sync sequence lies inside it (then
    corruption, and on after the sync). Its seeks back are tracked as
    :class:`_Guard` sees them; a search that finds no sync up to the end of
    the file, or a seek back not beyond the previous one, is left to pyulog."""
    n = buf.size
    m = sync.size
    offs = np.empty((n - start) // 3 + 1, dtype=np.int64)
    k = 0
    pos = start
    corrupt = False
    while pos + 3 <= n and pos < limit:
        size = np.int64(buf[pos]) | (np.int64(buf[pos + 1]) << 8)
        typ = buf[pos + 2]
        end = pos + 3 + size
        if end > n:
            break  # cut inside this message
        if known[typ]:
            offs[k] = pos
            k += 1
            pos = end
            continue
        if typ == 0 or size == 0 or size > 10000:  # corrupt header: one byte on, then the next sync
            dest = pos + 1
            if dest <= last_back:
                break
            j = _find_sync(buf, dest, n, sync)
            if j < 0:
                break  # no sync to the end: pyulog goes on byte by byte without it
            last_back = dest
            cs = dest  # pyulog reads 512-byte chunks, stepping back m - 1 bytes after each
            while j + m > cs + _SYNC_CHUNK:
                cs += _SYNC_CHUNK - (m - 1)
            if cs > dest:
                last_back = cs
            if j + m < min(cs + _SYNC_CHUNK, n):  # back from the chunk's end to just after the sync
                last_back = j + m
            corrupt = True
            pos = j + m
        else:  # an unknown message: skipped, unless a sync sequence lies inside it
            dest = pos + 3
            if dest <= last_back:
                break
            last_back = dest
            j = _find_sync(buf, dest, end, sync) if size >= m else -1
            if j < 0:
                pos = end
            else:
                if j + m < end:
                    last_back = j + m
                corrupt = True
                pos = j + m
    stop = n if pos == n else pos
    return offs[:k], stop, corrupt, last_back


def _u16(buf: np.ndarray, at: np.ndarray) -> np.ndarray:
    return buf[at].astype(np.int64) | (buf[at + 1].astype(np.int64) << 8)


def _load_bulk(path: str, size: int) -> Optional[_Parsed]:
    """pyulog's result with the regular part of the data section read in bulk;
    None if pyulog raises (then :func:`_load` reads the file its own way)."""
    import pyulog.core as core

    _install_print_capture(core)
    printed: List[str] = []
    try:
        fh: _GuardedFile = _DefsFile(path, size)
    except OSError as exc:
        raise InputError(f"{path}: cannot read ({exc.strerror or exc})") from None
    _capture.lines = printed
    try:
        u = core.ULog(fh, message_name_filter_list=list(TOPICS), disable_str_exceptions=True,
                      parse_header_only=True)
        if not fh.whole():  # a read may have come up short, or pyulog recovered: the guarded read
            del printed[:]
            if not fh.closed:
                fh.close()
            fh = _open(path, size)
            u = core.ULog(fh, message_name_filter_list=list(TOPICS), disable_str_exceptions=True,
                          parse_header_only=True)
        if (fh.cut is not None or fh.gave_up_at is not None or u.has_data_appended
                or not hasattr(u, "_subscriptions")):
            return None  # the header or definitions are damaged, or appended data: pyulog's own loop
        start = fh.stopped_at  # pyulog closed the file where its definitions end
        with open(path, "rb") as f:
            buf = np.frombuffer(f.read(), dtype=np.uint8)
        if buf.size != size:
            return None
        stop, last_back = _data_section(u, core.ULog, buf, start, fh._last_back, printed)
        if stop < size:  # irregular from there on: pyulog's own loop reads the rest
            rest = _open(path, size)
            rest.seek(stop)
            rest._last_back, rest._regressions, rest._loops = last_back, fh._regressions, fh._loops
            fh = rest
            u._file_handle = fh
            try:
                u._read_file_data(list(TOPICS))
            finally:
                if not fh.closed:
                    fh.stopped_at = fh.tell()
                    fh.close()
                del u._file_handle
        else:  # where pyulog's loop ends, as the guard saw it
            fh.stopped_at, fh._last_back = size, last_back
    except Exception:
        return None
    finally:
        _capture.lines = None
        if not fh.closed:
            fh.close()
    return _Parsed(u, fh, printed, bulk_to=stop)


def _data_section(u, ULog, buf: np.ndarray, start: int, last_back: int, printed: List[str]) -> Tuple[int, int]:
    """Read the data section of ``buf`` from ``start`` into ``u`` (a pyulog
    ULog that has read its definitions) as pyulog's ``_read_file_data``
    would, up to where its loop does something :func:`_walk` and this
    function do not follow. Returns that offset (``buf.size``: the end, and
    ``u`` is complete; else ``u`` is in the state pyulog's loop is in when
    it gets there) and the guard's ``_last_back`` there (``last_back``: at
    ``start``)."""
    offs, stop, corrupt, walked_back = _walk(buf, start, buf.size, _KNOWN_TYPES, _SYNC, last_back)
    walked_to = stop
    types = buf[offs + 2]
    sizes = _u16(buf, offs)
    short = (types == _MSG_D) & (sizes < 2)
    if short.any():  # a data message too short for its id: pyulog stops there
        stop = int(offs[np.argmax(short)])
    others, since, stop = _other_messages(u, ULog, buf, offs, sizes, types, stop)
    filt = list(TOPICS)
    subs = _kept_subscriptions(others, filt)

    # data messages before ``stop``: subscribed before them, kept topic, valid size
    is_d = (types == _MSG_D) & (offs < stop)
    d_offs, d_sizes = offs[is_d], sizes[is_d]
    d_ids = _u16(buf, d_offs + 3)
    stop = _short_timestamp_stop(subs, since, d_ids, d_offs, stop)
    # the walk again, to ``stop``: its recoveries before there only (the same
    # walk when ``stop`` is where the first one stopped: it ends there too)
    if stop == walked_to:
        last_back = walked_back
    else:
        _, _, corrupt, last_back = _walk(buf, start, stop, _KNOWN_TYPES, _SYNC, last_back)
    if corrupt:
        u._file_corrupt = True
    if stop < buf.size:
        others = [x for x in others if x.offset < stop]
        subs = _kept_subscriptions(others, filt)
        since = {i: o for i, o in since.items() if o < stop}
        keep = d_offs < stop
        d_offs, d_sizes, d_ids = d_offs[keep], d_sizes[keep], d_ids[keep]
    known, missing = _subscribed_rows(d_ids, d_offs, since, buf.size)
    if missing:
        u._file_corrupt = True
    last_ts = _last_timestamps(u._last_timestamp, *_fill_buffers(u, buf, subs, known, d_ids, d_offs, d_sizes))
    _apply_other_messages(u, ULog, others, filt, last_ts)
    for msg_id in missing:  # pyulog's warning, once per unknown id, in file order
        printed.append(f"Warning: no subscription found for message id {msg_id}. Continuing, "
                       "but file is most likely corrupt")
    u._missing_message_ids.update(missing)
    u._last_timestamp = last_ts(buf.size)
    if stop == buf.size:
        _final_conversion(u, ULog)
    return stop, last_back


class _Other(NamedTuple):
    """A data-section message other than data, parsed by pyulog's own class."""

    offset: int
    type: int
    msg: object  # None for a sync message


def _parse_other(u, ULog, typ: int, data: bytes, header):
    """One message that is not data through pyulog's class for its type (None: sync)."""
    if typ == _MSG_A:
        return ULog._MessageAddLogged(data, header, u._message_formats)
    if typ in (ULog.MSG_TYPE_INFO, ULog.MSG_TYPE_PARAMETER):
        return ULog._MessageInfo(data, header)
    if typ == ULog.MSG_TYPE_INFO_MULTIPLE:
        return ULog._MessageInfo(data, header, is_info_multiple=True)
    if typ == ULog.MSG_TYPE_PARAMETER_DEFAULT:
        return ULog._MessageParameterDefault(data, header)
    if typ == ULog.MSG_TYPE_LOGGING:
        return ULog.MessageLogging(data, header)
    if typ == ULog.MSG_TYPE_LOGGING_TAGGED:
        return ULog.MessageLoggingTagged(data, header)
    if typ == ULog.MSG_TYPE_DROPOUT:
        return ULog.MessageDropout(data, header, 0)  # its time is set later
    return None


class _Unkept(NamedTuple):
    """The subscription of a topic mavnav does not keep: what is read of it
    (pyulog's class would also flatten its format and build a numpy dtype)."""

    multi_id: int
    msg_id: int
    message_name: str


_MAX_FLAT_DEPTH = 32  # nested formats deeper than this get pyulog's own parse
_MAX_FLAT_FIELDS = 100_000  # and formats that flatten to more fields


class _FormatCheck:
    """Whether pyulog's ``_MessageAddLogged`` parses a subscription of a
    topic without raising, from the log's formats alone (memoised per type):
    every nested type is defined, none refers back to itself, the field
    names of each format are distinct, not empty and free of ``.``, ``[``
    and ``]`` (so the flattened names are distinct: numpy's dtype accepts
    them), and the whole flattens to a bounded number of fields. False
    means "not shown safe", not "raises": such a subscription gets
    pyulog's own parse."""

    def __init__(self, formats: dict, base_types) -> None:
        self.formats = formats
        self.base = base_types
        self.fields: Dict[str, int] = {}  # type -> flattened fields; -1: not shown safe

    def ok(self, name: str) -> bool:
        return self._count(name, 0) >= 0

    def _count(self, name: str, depth: int) -> int:
        n = self.fields.get(name)
        if n is not None:
            return n
        fmt = self.formats.get(name)
        if fmt is None or depth > _MAX_FLAT_DEPTH:
            return -1
        self.fields[name] = -1  # while it is being looked at: a type that refers back to itself fails
        total = 0
        seen = set()
        for type_name, size, field in fmt.fields:
            if not field or field in seen or "." in field or "[" in field or "]" in field:
                return -1
            seen.add(field)
            k = 1 if type_name in self.base else self._count(type_name, depth + 1)
            if k < 0:
                return -1
            total += k * (size if size > 0 else 1)
            if total > _MAX_FLAT_FIELDS:
                return -1
        self.fields[name] = total
        return total


def _other_messages(u, ULog, buf: np.ndarray, offs: np.ndarray, sizes: np.ndarray, types: np.ndarray,
                    stop: int, light: bool = True) -> Tuple[List[_Other], Dict[int, int], int]:
    """Every message but data before ``stop``, in file order, through pyulog's
    own classes: ``(messages, msg_id -> offset of its subscription, stop)``,
    ``stop`` moved back to a message pyulog's loop reports (or stops at).
    With ``light``, the subscription of a topic not kept whose format
    :class:`_FormatCheck` shows safe is read as an :class:`_Unkept` (its
    ids and name: all that is used of it); ``light=False`` is the reference
    (pyulog's class for every one), which ``tests/test_ingest_ulog_gather.py``
    holds it to."""
    header = ULog._MessageHeader()
    others: List[_Other] = []
    since: Dict[int, int] = {}
    rest = (types != _MSG_D) & (offs < stop)
    check = _FormatCheck(u._message_formats, ULog._UNPACK_TYPES) if light else None
    kept = set(TOPICS)
    for o, n, typ in zip(offs[rest].tolist(), sizes[rest].tolist(), types[rest].tolist()):
        header.msg_size, header.msg_type = n, typ
        data = buf[o + 3:o + 3 + n].tobytes()
        try:
            msg = None
            if check is not None and typ == _MSG_A and n >= 3:
                name = ULog.parse_string(data[3:])
                if name not in kept and check.ok(name):
                    msg = _Unkept(data[0], data[1] | (data[2] << 8), name)
            if msg is None:
                msg = _parse_other(u, ULog, typ, data, header)
            if typ == _MSG_A:
                if msg.msg_id in since:  # subscribed again: pyulog's loop replaces the first
                    raise ValueError("msg_id subscribed twice")
                since[msg.msg_id] = o
        except Exception:  # pyulog's loop reports (or stops at) this message
            stop = o
            break
        others.append(_Other(o, typ, msg))
    return others, since, stop


def _kept_subscriptions(others: List[_Other], filt: List[str]) -> dict:
    """msg_id -> subscription, of the topics kept."""
    return {x.msg.msg_id: x.msg for x in others if x.type == _MSG_A and x.msg.message_name in filt}


def _short_timestamp_stop(subs: dict, since: Dict[int, int], d_ids: np.ndarray, d_offs: np.ndarray,
                          stop: int) -> int:
    """pyulog reads 8 timestamp bytes: past a row too short for them, it stops."""
    for msg_id, sub in subs.items():
        if sub.timestamp_offset + 8 > sub.dtype.itemsize:
            later = (d_ids == msg_id) & (d_offs > since[msg_id])
            if later.any():
                stop = min(stop, int(d_offs[np.argmax(later)]))
    return stop


def _subscribed_rows(d_ids: np.ndarray, d_offs: np.ndarray, since: Dict[int, int],
                     size: int) -> Tuple[np.ndarray, List[int]]:
    """Which data rows come after their id's subscription, and the ids of the
    others (each once, in file order)."""
    table = np.full(int(d_ids.max()) + 1 if d_ids.size else 1, size, dtype=np.int64)
    for i, o in since.items():
        if i < table.size:
            table[i] = o
    known = d_offs > table[d_ids] if d_ids.size else np.zeros(0, dtype=bool)
    missing: List[int] = []
    if not known.all():
        ids, first = np.unique(d_ids[~known], return_index=True)
        missing = ids[np.argsort(first, kind="stable")].tolist()
    return known, missing


def _fill_buffers(u, buf: np.ndarray, subs: dict, known: np.ndarray, d_ids: np.ndarray, d_offs: np.ndarray,
                  d_sizes: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    """Append each kept subscription's rows to its buffer, as pyulog does
    (rows of the wrong size skipped as corrupt); returns the offsets and
    timestamps of the rows appended. Every kept row is found and copied in
    one pass over the data rows and the file (:func:`_gather_by_sub`), not
    one pass per subscription; the same buffers and results as
    :func:`_fill_buffers_reference` (``tests/test_ingest_ulog_fastpaths.py``)."""
    ts_off, ts_val = [np.zeros(0, dtype=np.int64)], [np.zeros(0, dtype=np.uint64)]
    if not subs or not d_ids.size:
        return ts_off[0], ts_val[0]
    ids = np.fromiter(subs, np.int64, len(subs))
    items = np.array([sub.dtype.itemsize for sub in subs.values()], dtype=np.int64)
    maxs = np.array([sub.max_data_size for sub in subs.values()], dtype=np.int64)
    table = np.full(max(int(ids.max()), int(d_ids.max())) + 1, -1, dtype=np.int64)
    table[ids] = np.arange(ids.size)
    flat, rows, offs, corrupt = _gather_by_sub(buf, d_offs, d_sizes, d_ids, known, table, items, maxs)
    if corrupt:  # pyulog skips a row of the wrong size as corrupt
        u._file_corrupt = True
    at = 0
    for k, sub in enumerate(subs.values()):
        lo, hi, item = int(rows[k]), int(rows[k + 1]), int(items[k])
        if lo == hi:
            continue
        rows_b = flat[at:at + (hi - lo) * item].reshape(hi - lo, item)
        at += (hi - lo) * item
        sub.buffer += rows_b.data  # the bytes, without a copy of them first
        t = sub.timestamp_offset
        ts_off.append(offs[lo:hi])
        ts_val.append(np.ascontiguousarray(rows_b[:, t:t + 8]).view("<u8").reshape(-1))
    return np.concatenate(ts_off), np.concatenate(ts_val)


@njit(cache=True)
def _gather_by_sub(buf, d_offs, d_sizes, d_ids, known, table, items, maxs):  # pragma: no cover - compiled
    """The kept data rows (``known``, id of a subscription: ``table[id] = k``,
    ``-1`` none) of the right size (``items[k] <= size - 2 <= maxs[k]``;
    another size sets ``corrupt``), ``items[k]`` bytes from 5 bytes into
    each message, packed per subscription in file order: ``(bytes, rows,
    offsets, corrupt)``, subscription ``k``'s rows ``rows[k] .. rows[k + 1]``
    of ``offsets`` (their messages' offsets) and the bytes of those rows one
    after the other. What :func:`_gather_rows` gives per subscription."""
    nsub = items.shape[0]
    n = d_offs.shape[0]
    take = np.full(n, -1, np.int64)
    counts = np.zeros(nsub, np.int64)
    corrupt = False
    for r in range(n):
        if not known[r]:
            continue
        k = table[d_ids[r]]
        if k < 0:
            continue
        size = d_sizes[r] - 2
        if size < items[k] or size > maxs[k]:
            corrupt = True
            continue
        take[r] = k
        counts[k] += 1
    rows = np.zeros(nsub + 1, np.int64)
    byte_at = np.zeros(nsub + 1, np.int64)
    for k in range(nsub):
        rows[k + 1] = rows[k] + counts[k]
        byte_at[k + 1] = byte_at[k] + counts[k] * items[k]
    out = np.empty(byte_at[nsub], np.uint8)
    offs = np.empty(rows[nsub], np.int64)
    row_at = rows[:nsub].copy()
    b_at = byte_at[:nsub].copy()
    for r in range(n):
        k = take[r]
        if k < 0:
            continue
        item = items[k]
        s = d_offs[r] + 5
        if s < 0 or s + item > buf.size:
            raise IndexError("a row beyond the buffer")
        d = b_at[k]
        out[d:d + item] = buf[s:s + item]
        b_at[k] = d + item
        offs[row_at[k]] = d_offs[r]
        row_at[k] += 1
    return out, rows, offs, corrupt


def _fill_buffers_reference(u, buf: np.ndarray, subs: dict, known: np.ndarray, d_ids: np.ndarray, d_offs: np.ndarray,
                  d_sizes: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    """The readable form of :func:`_fill_buffers`: one subscription at a time
    (each a pass over the data rows and the file)."""
    ts_off, ts_val = [np.zeros(0, dtype=np.int64)], [np.zeros(0, dtype=np.uint64)]
    for msg_id, sub in subs.items():
        rows = known & (d_ids == msg_id)
        if not rows.any():
            continue
        o, n = d_offs[rows], d_sizes[rows] - 2
        item = sub.dtype.itemsize
        fits = (n >= item) & (n <= sub.max_data_size)
        if not fits.all():  # pyulog skips a row of the wrong size as corrupt
            u._file_corrupt = True
            o = o[fits]
        if not o.size:
            continue
        rows_b = _gather_rows(buf, o + 5, item)
        sub.buffer += rows_b.tobytes()
        t = sub.timestamp_offset
        ts_off.append(o)
        ts_val.append(np.ascontiguousarray(rows_b[:, t:t + 8]).view("<u8").reshape(-1))
    return np.concatenate(ts_off), np.concatenate(ts_val)


@njit(cache=True)
def _gather_rows(buf, starts, item):  # pragma: no cover - compiled
    """``item`` bytes of ``buf`` from each of ``starts``, as rows: what
    :func:`_gather_rows_reference` indexes, copied row by row
    (``tests/test_ingest_ulog.py`` checks the two agree)."""
    out = np.empty((starts.shape[0], item), np.uint8)
    for r in range(starts.shape[0]):
        s = starts[r]
        if s < 0 or s + item > buf.size:
            raise IndexError("a row beyond the buffer")
        out[r, :] = buf[s:s + item]
    return out


def _gather_rows_reference(buf: np.ndarray, starts: np.ndarray, item: int) -> np.ndarray:
    """The readable form of :func:`_gather_rows`: one fancy index over every byte."""
    return buf[starts[:, None] + np.arange(item, dtype=np.int64)]


def _last_timestamps(start_ts: int, ro: np.ndarray, rt: np.ndarray) -> Callable[[int], int]:
    """pyulog's ``_last_timestamp`` before the message at an offset: the
    largest data timestamp so far (``start_ts`` before any). Past every row
    (the end of the file, where it is always asked) that is the largest of
    all; the running maximum in file order is built only when a message
    among the rows asks (a parameter change, a dropout)."""
    end = int(ro.max()) if ro.size else -1
    top = max(start_ts, int(rt.max())) if rt.size else start_ts
    running: list = []

    def last_ts(o: int) -> int:
        if o > end:
            return top
        if not running:
            order = np.argsort(ro, kind="stable")
            running.extend((ro[order], np.maximum.accumulate(rt[order])))
        ro_s, run_max = running
        j = int(np.searchsorted(ro_s, o))
        return max(start_ts, int(run_max[j - 1])) if j else start_ts

    return last_ts


def _apply_other_messages(u, ULog, others: List[_Other], filt: List[str], last_ts: Callable[[int], int]) -> None:
    """Into ``u``, each message but data as pyulog's loop keeps it."""
    for o, typ, msg in others:
        if typ == _MSG_A:
            if msg.message_name in filt:
                u._subscriptions[msg.msg_id] = msg
            else:
                u._filtered_message_ids.add(msg.msg_id)
        elif typ == ULog.MSG_TYPE_INFO:
            u._msg_info_dict[msg.key] = msg.value
            u._msg_info_dict_types[msg.key] = msg.type
        elif typ == ULog.MSG_TYPE_INFO_MULTIPLE:
            u._add_message_info_multiple(msg)
        elif typ == ULog.MSG_TYPE_PARAMETER:
            u._changed_parameters.append((last_ts(o), msg.key, msg.value))
        elif typ == ULog.MSG_TYPE_PARAMETER_DEFAULT:
            u._add_parameter_default(msg)
        elif typ == ULog.MSG_TYPE_LOGGING:
            u._logged_messages.append(msg)
        elif typ == ULog.MSG_TYPE_LOGGING_TAGGED:
            u._logged_messages_tagged.setdefault(msg.tag, []).append(msg)
        elif typ == ULog.MSG_TYPE_DROPOUT:
            msg.timestamp = last_ts(o)
            u._dropouts.append(msg)
        else:
            u._sync_seq_cnt += 1


def _final_conversion(u, ULog) -> None:
    """pyulog's conversion at the end of the file (subscriptions popped last first)."""
    while u._subscriptions:
        _, sub = u._subscriptions.popitem()
        if len(sub.buffer) > 0:
            u._data_list.append(ULog.Data(sub))
    u._data_list.sort(key=lambda ds: (ds.name, ds.multi_id))


def _file_damage(p: _Parsed, size: int) -> List[str]:
    """The damage lines of a ULog: where pyulog's reading ended early, what
    it printed, appended data past the end, logger dropouts."""
    u = p.ulog
    out = _reading_damage(u, p.fh, size)
    out += _printed_damage(u, p.printed)
    out += _appended_damage(u, size)
    out += _dropout_damage(u)
    return out


def _reading_damage(u, fh, size: int) -> List[str]:
    """A file cut short, pyulog going round in circles or stopping early, no message formats."""
    out: List[str] = []
    end = size if fh.limit is None else min(size, fh.limit)
    if fh.cut is not None and end == size:
        off, want, got = fh.cut
        out.append(f"file cut short: it ends inside a message at byte {size} "
                   f"({got} of {want} bytes from byte {off}); the last message is lost")
    if fh.gave_up_at is not None:
        out.append(f"pyulog went round in circles on corrupt bytes near byte {fh.gave_up_at} of {size}; "
                   "stopped there, the rest is lost")
    elif fh.cut is None and fh.stopped_at is not None and fh.stopped_at < end:
        out.append(f"pyulog stopped at byte {fh.stopped_at} of {size} (a malformed message); "
                   "the rest is lost")
    if not getattr(u, "message_formats", None):
        out.append("no message formats: the file ends inside its header or definitions")
    return out


def _printed_lines(printed: List[str]) -> Tuple[List[str], List[str]]:
    """pyulog's printed lines without their prefixes, each once: ``(about
    corruption or subscriptions, the others)``."""
    corrupt: List[str] = []
    other: List[str] = []
    for line in printed:
        for pre in ("Warning: ", "Error: "):
            if line.startswith(pre):
                line = line[len(pre):]
        line = line.replace(". Continuing, but file is most likely corrupt", "").rstrip(".! ")
        which = corrupt if ("corrupt" in line.lower() or "subscription" in line) else other
        if line and line not in which:
            which.append(line)
    return corrupt, other


def _printed_damage(u, printed: List[str]) -> List[str]:
    """Corrupt data pyulog skipped (up to three of its reasons), and up to three other lines it printed."""
    out: List[str] = []
    corrupt, other = _printed_lines(printed)
    if getattr(u, "file_corruption", False) or corrupt:
        said = [c for c in corrupt if not c.lower().startswith("file corruption detected")]
        text = "; ".join(said[:3]) + (f"; {len(said) - 3} more" if len(said) > 3 else "")
        out.append("corrupt data skipped by pyulog" + (f" ({text})" if text else ""))
    out.extend(f"pyulog: {line}"[:300] for line in other[:3])
    return out


def _appended_damage(u, size: int) -> List[str]:
    if not getattr(u, "has_data_appended", False):
        return []
    offs = [o for o in getattr(u, "_appended_offsets", []) or [] if o > size]
    return [f"appended-data offset {offs[0]} lies past the end of the file ({size} bytes)"] if offs else []


def _dropout_damage(u) -> List[str]:
    drops = list(getattr(u, "dropouts", []) or [])
    if not drops:
        return []
    ms = [int(d.duration) for d in drops]
    return [f"logger dropouts: {len(ms)}, {sum(ms)} ms of data not logged (longest {max(ms)} ms)"]


# --------------------------------------------------------------------- columns

def _key(name: str, multi_id: int) -> str:
    return name if multi_id == 0 else f"{name}[{multi_id}]"


def _rows(d: Data) -> int:
    return len(next(iter(d.values()))) if d else 0


def _times(d: Data) -> np.ndarray:
    """Sample time per row (int64 us): ``timestamp_sample`` where nonzero, else ``timestamp``."""
    t = d["timestamp"].astype(np.int64)
    ts = d.get("timestamp_sample")
    if ts is not None:
        ts = ts.astype(np.int64)
        t = np.where(ts > 0, ts, t)
    return t


def _f(d: Data, key: str) -> np.ndarray:
    return d[key].astype(np.float64) if key in d else np.full(_rows(d), np.nan)


def _clean(what: str, t: np.ndarray, cols: List[np.ndarray], damage: List[str],
           good: Optional[np.ndarray] = None) -> Tuple[np.ndarray, List[np.ndarray]]:
    """Sort by time, keep the first of equal times, drop rows without a time or
    with non-finite values (``good`` False: invalid too); one damage line."""
    no_time = t <= 0
    ok = ~no_time
    bad = np.zeros(t.size, dtype=bool) if good is None else ~good
    for c in cols:
        if c.dtype.kind == "f":
            fin = np.isfinite(c) if c.ndim == 1 else np.isfinite(c).all(axis=1)
            bad |= ~fin
    bad &= ok
    ok &= ~bad
    tk = t[ok]
    backwards = int(np.count_nonzero(np.diff(tk) < 0)) if tk.size > 1 else 0
    order = np.argsort(tk, kind="stable")
    ts = tk[order]
    keep = np.ones(ts.size, dtype=bool)
    keep[1:] = ts[1:] != ts[:-1]
    dups = int(ts.size - np.count_nonzero(keep))
    parts = []
    if backwards:
        parts.append(f"time went backwards {backwards} time(s), records re-ordered")
    n_nt, n_bad = int(no_time.sum()), int(bad.sum())
    dropped = n_nt + n_bad + dups
    if dropped:
        why = [f"{n} {w}" for n, w in ((n_bad, "non-finite or invalid"), (dups, "repeating a time"),
                                       (n_nt, "without a time")) if n]
        parts.append(f"{dropped} record(s) dropped ({', '.join(why)})")
    if parts:
        damage.append(f"{what}: " + "; ".join(parts))
    return ts[keep], [c[ok][order][keep] for c in cols]


class _Topics:
    """pyulog's datasets by topic name and multi_id."""

    def __init__(self, ulog):
        self.by: Dict[str, Dict[int, Data]] = {}
        for ds in getattr(ulog, "data_list", []):
            self.by.setdefault(ds.name, {})[int(ds.multi_id)] = ds.data

    def get(self, name: str, multi_id: int = 0) -> Optional[Data]:
        d = self.by.get(name, {}).get(multi_id)
        return d if d and _rows(d) else None

    def all(self, name: str) -> Dict[int, Data]:
        return {i: d for i, d in sorted(self.by.get(name, {}).items()) if _rows(d)}

    def messages(self) -> Dict[str, int]:
        return {_key(n, i): _rows(d) for n, inst in sorted(self.by.items()) for i, d in sorted(inst.items())}


def _imu(tp: _Topics, damage: List[str]) -> Optional[ImuSeries]:
    d = tp.get("sensor_combined")
    if d is None or "accelerometer_m_s2[0]" not in d:
        return None
    t = d["timestamp"].astype(np.int64)
    rel = d.get("accelerometer_timestamp_relative")
    if rel is not None:
        rel = rel.astype(np.int64)
        t = np.where(rel != RELATIVE_TIMESTAMP_INVALID, t + rel, t)
    t, (fx, fy, fz) = _clean("sensor_combined", t, [_f(d, f"accelerometer_m_s2[{i}]") for i in range(3)], damage)
    return ImuSeries("sensor_combined", t, fx, fy, fz)


def _attitude(tp: _Topics, damage: List[str]) -> Optional[AttitudeSeries]:
    d = tp.get("vehicle_attitude")
    if d is None or "q[0]" not in d:
        return None
    q = np.column_stack([_f(d, f"q[{i}]") for i in range(4)])
    norm = np.sqrt((q * q).sum(axis=1))
    good = np.abs(norm - 1.0) <= QUAT_NORM_TOL
    t, (q, norm) = _clean("vehicle_attitude", _times(d), [q, norm], damage, good)
    return AttitudeSeries("vehicle_attitude", t, q / norm[:, None])


def _baro(tp: _Topics, damage: List[str]) -> Optional[BaroSeries]:
    baros = {i: d for i, d in tp.all("sensor_baro").items() if "pressure" in d}
    instances = max(1, len(tp.all("sensor_baro")))
    air = tp.get("vehicle_air_data")
    if air is not None and "baro_pressure_pa" in air:
        instance = 0
        ids = air.get("baro_device_id")
        if ids is not None and ids.size:
            ids = ids[ids != 0]
            if ids.size:
                dev = Counter(ids.tolist()).most_common(1)[0][0]
                for i, d in baros.items():
                    if "device_id" in d and np.any(d["device_id"] == dev):
                        instance = i
                        break
        t, (p,) = _clean("vehicle_air_data", _times(air), [_f(air, "baro_pressure_pa")], damage)
        return BaroSeries("vehicle_air_data", t, p, instance=instance, instances=instances)
    if not baros:
        return None
    i = min(baros)
    d = baros[i]
    name = _key("sensor_baro", i)
    p = _f(d, "pressure")
    fin = p[np.isfinite(p)]
    if fin.size and np.median(fin) < HPA_BELOW:
        p = p * 100.0  # hPa (millibar) in PX4 <= 1.11
    t, (p,) = _clean(name, _times(d), [p], damage)
    return BaroSeries(name, t, p, instance=i, instances=instances)


def _gps_alt(d: Data) -> Optional[np.ndarray]:
    if "altitude_msl_m" in d:
        return d["altitude_msl_m"].astype(np.float64)
    if "alt" in d:
        a = d["alt"]
        return a.astype(np.float64) * (1e-3 if a.dtype.kind in "iu" else 1.0)
    return None


def _gnss(tp: _Topics, damage: List[str]) -> Optional[GnssSeries]:
    d = tp.get("vehicle_gps_position")
    if d is not None and _gps_alt(d) is not None:
        name = "vehicle_gps_position"
    else:
        inst = [(i, g) for i, g in tp.all("sensor_gps").items() if _gps_alt(g) is not None]
        if not inst:
            return None
        i, d = max(inst, key=lambda x: (_rows(x[1]), -x[0]))
        name = _key("sensor_gps", i)
    n = _rows(d)
    epv = _f(d, "epv")
    sigma = np.where(np.isfinite(epv) & (epv > 0), epv, np.nan)
    fix = d["fix_type"].astype(np.int64) if "fix_type" in d else np.zeros(n, dtype=np.int64)
    sats = d["satellites_used"].astype(np.int64) if "satellites_used" in d else np.zeros(n, dtype=np.int64)
    # sigma is NaN by design when not reported: only the altitude decides whether a row is finite
    vel_up = -_f(d, "vel_d_m_s")
    if "vel_ned_valid" in d:
        vel_up = np.where(d["vel_ned_valid"].astype(bool), vel_up, np.nan)
    t, (alt, idx) = _clean(name, _times(d), [_gps_alt(d), np.arange(n)], damage)
    return GnssSeries(name, t, alt, sigma[idx], fix[idx], sats[idx], vel_up[idx])


def _range(tp: _Topics, damage: List[str]) -> Optional[RangeSeries]:
    best = None
    for i, d in tp.all("distance_sensor").items():
        if "orientation" not in d or "current_distance" not in d:
            continue
        down = d["orientation"] == ROTATION_DOWNWARD_FACING
        n = int(down.sum())
        if n and (best is None or n > best[0]):
            best = (n, i, d, down)
    if best is None:
        return None
    _, i, d, down = best
    name = _key("distance_sensor", i)
    valid = d["signal_quality"] != 0 if "signal_quality" in d else np.ones(_rows(d), dtype=bool)
    lo, hi, valid = _f(d, "min_distance")[down], _f(d, "max_distance")[down], valid[down]
    t, (rng, idx) = _clean(name, _times(d)[down], [_f(d, "current_distance")[down], np.arange(lo.size)], damage)
    return RangeSeries(name, t, rng, lo[idx], hi[idx], valid[idx])


def _latest(t: np.ndarray, v: np.ndarray, ok: np.ndarray, pick=np.argmax) -> Optional[float]:
    """The value of the valid row stamped in the log's time that ``pick``
    chooses by time: the latest (``np.argmax``) or the first (``np.argmin``)."""
    ok = ok & np.isfinite(v) & (t > 0)
    if not ok.any():
        return None
    j = np.flatnonzero(ok)
    return float(v[j[pick(t[j])]])


def _autopilot(tp: _Topics, damage: List[str]) -> Tuple[Optional[AutopilotSeries], Optional[float]]:
    d = tp.get("vehicle_local_position")
    if d is None:
        return None, None
    origin = None
    if "ref_alt" in d:
        if "z_global" in d:
            ref_ok = d["z_global"] != 0
        elif "xy_global" in d:
            ref_ok = d["xy_global"] != 0
        elif "ref_timestamp" in d:
            ref_ok = d["ref_timestamp"] > 0
        else:
            ref_ok = np.ones(_rows(d), dtype=bool)
        origin = _latest(d["timestamp"].astype(np.int64), _f(d, "ref_alt"), ref_ok)
    if "z" not in d:
        return None, origin
    sel = d["z_valid"] != 0 if "z_valid" in d else np.ones(_rows(d), dtype=bool)
    vz = -_f(d, "vz")[sel] if "vz" in d else np.full(int(sel.sum()), np.nan)
    if "v_z_valid" in d:
        vz = np.where(d["v_z_valid"][sel] != 0, vz, np.nan)
    # a missing velocity must not drop the height row: _clean drops non-finite rows
    t, (up, vz) = _clean("vehicle_local_position", _times(d)[sel], [-_f(d, "z")[sel], np.nan_to_num(vz, nan=1e300)], damage)
    vz = np.where(vz == 1e300, np.nan, vz)
    return AutopilotSeries("vehicle_local_position", t, up, "ekf_origin", vz), origin


def _home(tp: _Topics) -> Optional[float]:
    d = tp.get("home_position")
    if d is None or "alt" not in d:
        return None
    ok = d["valid_alt"] != 0 if "valid_alt" in d else np.ones(_rows(d), dtype=bool)
    return _latest(d["timestamp"].astype(np.int64), _f(d, "alt"), ok, pick=np.argmin)  # the first


def _firmware(u) -> str:
    info = getattr(u, "msg_info_dict", {}) or {}
    sysname = info.get("sys_name") if isinstance(info.get("sys_name"), str) and info.get("sys_name") else "PX4"
    rel = info.get("ver_sw_release")
    if isinstance(rel, int) and rel > 0:
        major, minor, patch, kind = (rel >> 24) & 0xFF, (rel >> 16) & 0xFF, (rel >> 8) & 0xFF, rel & 0xFF
        suffix = ("" if kind == 255 else " (RC)" if kind >= 192 else " (beta)" if kind >= 128
                  else " (alpha)" if kind >= 64 else " (dev)")
        return f"{sysname} v{major}.{minor}.{patch}{suffix}"
    sw = info.get("ver_sw")
    if isinstance(sw, str) and sw.strip():
        return f"{sysname} {sw.strip()[:12]}"
    return ""


def _vehicle(tp: _Topics, u) -> str:
    d = tp.get("vehicle_status")
    kind = ""
    mav_type = (getattr(u, "initial_parameters", {}) or {}).get("MAV_TYPE")
    from_param = _MAV_TYPE.get(int(mav_type), "") if isinstance(mav_type, (int, np.integer)) else ""
    if d is not None:
        if "is_vtol" in d and np.any(d["is_vtol"] != 0):
            return "vtol"
        if "vehicle_type" in d:
            kind = _VEHICLE_TYPE.get(Counter(d["vehicle_type"].tolist()).most_common(1)[0][0], "")
        elif "is_rotary_wing" in d and np.any(d["is_rotary_wing"] != 0):
            kind = "copter"
    if kind == "rover" and from_param == "boat":
        return "boat"
    return kind or from_param


# --------------------------------------------------------------------- entry point

def read_ulog(path, *, bulk: bool = True) -> OnboardRecord:
    """Decode one PX4 ULog. :class:`InputError` if it is not one at all (or
    nothing can be read from it); damage to the file is listed in ``damage``.
    ``bulk=False`` reads the data section with pyulog's own loop throughout:
    the reference the bulk reader is tested against (same record, slower)."""
    path = os.fspath(path)
    size = _probe(path)
    parsed, damage = _load(path, size, bulk=bulk)
    failed = bool(damage)
    u = parsed.ulog
    damage += _file_damage(parsed, size)
    tp = _Topics(u)
    rec = OnboardRecord(path=path, format="ulog", bytes_read=size, messages=tp.messages())
    series: List[str] = []

    def build(what: str, fn: Callable[[], object]):
        try:
            with np.errstate(all="ignore"):
                return fn()
        except Exception as exc:  # a corrupt format (missing or odd fields) must not sink the file
            series.append(f"{what}: could not be decoded ({type(exc).__name__}: {exc})"[:300])
            return None

    rec.firmware = build("firmware", lambda: _firmware(u)) or ""
    rec.vehicle = build("vehicle_status", lambda: _vehicle(tp, u)) or ""
    rec.imu = build("sensor_combined", lambda: _imu(tp, series))
    rec.attitude = build("vehicle_attitude", lambda: _attitude(tp, series))
    rec.baro = build("baro", lambda: _baro(tp, series))
    rec.gnss = build("gnss", lambda: _gnss(tp, series))
    rec.rangefinder = build("distance_sensor", lambda: _range(tp, series))
    ap = build("vehicle_local_position", lambda: _autopilot(tp, series))
    if ap is not None:
        rec.autopilot, rec.origin_alt_msl_m = ap
    rec.home_alt_msl_m = build("home_position", lambda: _home(tp))
    rec.damage = damage + series
    if failed and len(rec.missing()) == 6:  # pyulog gave up and left nothing usable
        raise InputError(f"{path}: unreadable ULog: {damage[0]}")
    return rec


__all__ = ["read_ulog", "TOPICS"]
