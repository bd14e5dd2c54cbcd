"""Fault injection into recorded tlogs: real sensor data with a known fault onset.

The log is split into records (8-byte big-endian receive time + one MAVLink
frame) by the tlog reader's own record walk
(:class:`mavnav.ingest.records.RecordWalk`: plausible timestamps, CRC with
the message's CRC_EXTRA, resynchronisation), so the injector's *frames* are
exactly the frames the monitor reads, at the same offsets. Unlike the reader,
which skips the rest, the injector keeps every byte: what lies between two
frames (radio garbage, damaged or unknown frames, a truncated tail) is an
opaque *junk* record, copied byte for byte. The vehicle is the system the
monitor would follow: the first heartbeat
:func:`mavnav.ingest.systems.is_vehicle_heartbeat` takes (of ``sysid`` if
given), as the normaliser chooses it.

Every record the faults do not touch is copied byte for byte. A faulted
message is decoded with pymavlink, changed, and re-framed with its original
MAVLink version, incompat/compat flags, sequence number, system and component
id, and a correct CRC (a signed frame loses its signature: it cannot be
re-signed without the key; counted in the report).

Vehicle time: the clock is the autopilot component's ``time_boot_ms`` (its
``time_usec`` only while no ``time_boot_ms`` has been seen). A record takes
its own ``time_boot_ms``, or its own ``time_usec`` when that is within 1 s of
the clock (zero and Unix times are ignored, the normaliser's threshold
:data:`mavnav.ingest.clock.UNIX_THRESHOLD_US`: GNSS and old ArduPilot IMU
stamps are not always on the boot clock), else the latest
clock value before it. The clock running backwards by more than
``ingest.reboot_jump_s`` (2 s) is a reboot (``boot`` counts from 0): the
normaliser's rule, :func:`mavnav.ingest.clock.is_reboot` (one message decides
here; the normaliser waits for several to confirm). Smaller steps back are
jitter between message types or a step of the vehicle clock. A fault
applies in the boot where its onset is first reached (or the ``boot`` it
names), to the vehicle's system only, except ``link_loss`` and ``reboot``,
which remove every record in the window (all systems, junk included).
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, field
from typing import Callable, Dict, List, Optional, Sequence, Tuple

import numpy as np
from pymavlink.dialects.v20 import ardupilotmega as mav2

from ..atmosphere import P0_PA, height_from_pressure_m, pressure_at_height_pa
from ..config import REBOOT_JUMP_S
from ..constants import G0_MPS2
from ..errors import InputError
from ..frames import down_row_from_euler
from ..ingest import wire
from ..ingest.clock import UNIX_THRESHOLD_US, is_reboot
from ..ingest.records import ALL_KNOWN, RecordWalk
from ..ingest.systems import is_vehicle_heartbeat
from .effects import height_error_m, keeps, out_of_range_reading_m, spikes
from .faults import describe_fault
from .scenario import Fault


ID = wire.MSG_ID
ID_HEARTBEAT = ID["HEARTBEAT"]
_decode_heartbeat = wire.make_decoder(ID_HEARTBEAT)  # as the normaliser decodes it
ID_GPS_RAW_INT, ID_GPS2_RAW = ID["GPS_RAW_INT"], ID["GPS2_RAW"]
ID_ATTITUDE = ID["ATTITUDE"]
ID_HIGHRES_IMU = ID["HIGHRES_IMU"]
INT_IMU_IDS = tuple(ID[n] for n in ("RAW_IMU", "SCALED_IMU", "SCALED_IMU2", "SCALED_IMU3"))  # milli-g
PRESSURE_IDS = tuple(ID[n] for n in ("SCALED_PRESSURE", "SCALED_PRESSURE2", "SCALED_PRESSURE3"))  # hPa
ID_DISTANCE_SENSOR, ID_RANGEFINDER = ID["DISTANCE_SENSOR"], ID["RANGEFINDER"]
GNSS_IDS = (ID_GPS_RAW_INT, ID_GPS2_RAW)
RNG_IDS = (ID_DISTANCE_SENSOR, ID_RANGEFINDER)
BARO_IDS = PRESSURE_IDS + (ID_HIGHRES_IMU,)
IMU_IDS = (ID_HIGHRES_IMU,) + INT_IMU_IDS
MAV_SENSOR_ROTATION_PITCH_270 = mav2.MAV_SENSOR_ROTATION_PITCH_270  # a DISTANCE_SENSOR looking down

_KIND_IDS = {
    "gnss": GNSS_IDS,
    "rng": RNG_IDS,
    "baro": BARO_IDS,
    "accel": IMU_IDS,
}


@dataclass(frozen=True)
class Record:
    start: int  # byte offset of the 8-byte timestamp
    end: int  # one past the last byte of the record
    recv_us: int  # receive time (junk: the leading 8 bytes, may be garbage)
    is_frame: bool
    version: int = 0  # 1 or 2
    msgid: int = -1
    sysid: int = -1
    compid: int = -1


# ---------------------------------------------------------------- splitting


def split_tlog(data: bytes) -> List[Record]:
    """Split tlog bytes into frame and junk records covering every byte, in order:
    the frames the tlog reader yields (:class:`mavnav.ingest.records.RecordWalk`),
    and the bytes between them (garbage, damaged or unknown frames, a cut tail)
    as junk records."""
    out: List[Record] = []
    walk = RecordWalk(ALL_KNOWN, offsets=True)
    pos = 0
    for item in walk.walk(data):
        if type(item) is not tuple:
            continue  # a problem: its bytes become junk
        _, msgid, sysid, compid, _, start, end = item
        if start > pos:
            out.append(_junk(data, pos, start))
        out.append(Record(start, end, int.from_bytes(data[start : start + 8], "big"), True,
                          1 if data[start + 8] == wire.STX_V1 else 2, msgid, sysid, compid))
        pos = end
    if pos < len(data):
        out.append(_junk(data, pos, len(data)))
    return out


def _junk(data: bytes, start: int, end: int) -> Record:
    """The bytes between two frames, kept as they are."""
    return Record(start, end, int.from_bytes(data[start : start + 8], "big") if start + 8 <= len(data) else 0, False)


# ---------------------------------------------------------------- frames


_TIME_FIELDS = ("time_boot_ms", "time_usec")
_TIME_READERS: Dict[int, Optional[Tuple[Callable[[bytes], object], float]]] = {}


def _time_reader(msgid: int) -> Optional[Tuple[Callable[[bytes], object], float]]:
    """(reader of a message's boot-time field, seconds per unit), None if it has none."""
    if msgid not in _TIME_READERS:
        found = wire.make_field_reader(msgid, _TIME_FIELDS)
        _TIME_READERS[msgid] = None if found is None else (found[1], 1e-3 if found[0] == "time_boot_ms" else 1e-6)
    return _TIME_READERS[msgid]


def _payload(data: bytes, rec: Record) -> bytes:
    f = rec.start + 8
    hdr = wire.HEADER_LEN_V1 if rec.version == 1 else wire.HEADER_LEN_V2
    return data[f + hdr : f + hdr + data[f + 1]]


def _vehicle_time_s(data: bytes, rec: Record) -> Optional[Tuple[float, bool]]:
    """(boot time in s, True if from time_boot_ms) of a frame, None if it has none.

    Zero (unknown) and Unix-looking ``time_usec`` values are ignored.
    """
    tr = _time_reader(rec.msgid)
    if tr is None:
        return None
    read, scale = tr
    v = read(_payload(data, rec))  # MAVLink 2 trailing-zero truncation padded
    if v == 0 or (scale == 1e-6 and v >= UNIX_THRESHOLD_US):
        return None
    return v * scale, scale == 1e-3


def reframe(original: bytes, msg) -> bytes:
    """Re-frame a modified message with the original frame's header fields and a fresh CRC."""
    v1 = original[0] == 0xFE
    scratch = mav2.MAVLink(None)
    msg.pack(scratch)  # as MAVLink 2 (an id above 255 has no MAVLink 1 header): trailing zeros stripped
    cls = mav2.mavlink_map[msg.get_msgId()]
    payload = bytes(msg.get_payload()).ljust(cls.unpacker.size, b"\0")  # the full payload, extensions included
    if v1:
        payload = payload[: original[1]]
        header = bytes((0xFE, len(payload), original[2], original[3], original[4], original[5]))
    else:
        plen = len(payload)
        while plen > 1 and payload[plen - 1] == 0:
            plen -= 1
        payload = payload[:plen]
        header = bytes((0xFD, plen, original[2] & ~0x01, original[3], original[4], original[5], original[6],
                        original[7], original[8], original[9]))
    crc = mav2.x25crc(header[1:] + payload)
    crc.accumulate(bytes((cls.crc_extra,)))
    return header + payload + struct.pack("<H", crc.crc)


# ---------------------------------------------------------------- injection


@dataclass
class _FaultState:
    fault: Fault
    index: int
    boot: Optional[int]
    rng: np.random.Generator
    held: Dict[Tuple[int, str], float]
    counters: Dict[int, int]
    modified: int = 0
    dropped: int = 0
    first_recv_us: Optional[int] = None
    last_recv_us: Optional[int] = None
    first_vehicle_s: Optional[float] = None

    def touch(self, rec: Record, vt: Optional[float]) -> None:
        if self.first_recv_us is None:
            self.first_recv_us = rec.recv_us
            self.first_vehicle_s = vt
        self.last_recv_us = rec.recv_us


def _detect_vehicle(data: bytes, records: Sequence[Record], sysid: Optional[int]) -> Tuple[Optional[int], Optional[int]]:
    """(system id, autopilot component id): those of the first HEARTBEAT the
    normaliser takes for the vehicle's (:func:`mavnav.ingest.systems.is_vehicle_heartbeat`,
    of system ``sysid`` if given), so that the faults go where the monitor
    looks; else (no such heartbeat: the monitor has no vehicle to agree with)
    the busiest (sysid, compid)."""
    counts: Dict[Tuple[int, int], int] = {}
    for r in records:
        if not r.is_frame or (sysid is not None and r.sysid != sysid):
            continue
        if r.msgid == ID_HEARTBEAT and is_vehicle_heartbeat(_decode_heartbeat(_payload(data, r))):
            return r.sysid, r.compid
        counts[(r.sysid, r.compid)] = counts.get((r.sysid, r.compid), 0) + 1
    if not counts:
        return sysid, None
    return max(counts, key=counts.get)


def _applies_to(fault: Fault, msgid: int) -> bool:
    k = fault.kind
    if fault.messages is not None:
        cls = mav2.mavlink_map.get(msgid)
        if cls is None or cls.msgname not in fault.messages:
            return False
    if k.startswith("gnss_"):
        return msgid in GNSS_IDS
    if k.startswith("rng_"):
        return msgid in RNG_IDS
    if k.startswith("baro_"):
        return msgid in BARO_IDS
    if k == "accel_bias_step":
        return msgid in IMU_IDS
    if k == "rate_drop":
        return msgid != ID_HEARTBEAT
    return False


class _Timeline:
    """The vehicle clock as the injector follows it (see the module docstring)."""

    def __init__(self, autopilot_compid: Optional[int], reboot_jump_s: float = REBOOT_JUMP_S):
        self.compid = autopilot_compid
        self.reboot_jump_s = reboot_jump_s
        self.boot = 0
        self.last_vt: Optional[float] = None
        self.have_ms_clock = False

    def time_of(self, data: bytes, rec: Record) -> Optional[float]:
        """Vehicle time of one of the vehicle's frames (the clock advanced by it)."""
        vt = self.last_vt
        own = _vehicle_time_s(data, rec)
        if own is None:
            return vt
        own_vt, is_ms = own
        clock_msg = rec.compid == self.compid and rec.msgid not in GNSS_IDS
        if clock_msg and (is_ms or not self.have_ms_clock):
            # the autopilot's time_boot_ms: drives vehicle time and reboot detection
            if self.last_vt is not None and is_reboot(self.last_vt, own_vt, self.reboot_jump_s):
                self.boot += 1
            self.last_vt = vt = own_vt
            self.have_ms_clock = self.have_ms_clock or is_ms
        elif self.last_vt is not None and abs(own_vt - self.last_vt) < 1.0:
            vt = own_vt  # a sample time (time_usec) on the same clock
        return vt


@dataclass
class _Seen:
    """What the vehicle's frames have said so far, for the faults that need it."""

    attitude: Tuple[float, float] = (0.0, 0.0)  # roll, pitch (rad)
    rng_max_m: Optional[float] = None  # the downward DISTANCE_SENSOR's max_distance
    originals: Dict[Tuple[int, str], float] = field(default_factory=dict)  # latest (msgid, field) value

    def note(self, msg, msgid: int) -> Dict[str, float]:
        """Remember attitude and range limit; returns the held fields' values before any fault."""
        if msgid == ID_ATTITUDE:
            self.attitude = (msg.roll, msg.pitch)
        if msgid == ID_DISTANCE_SENSOR and msg.orientation == MAV_SENSOR_ROTATION_PITCH_270:
            self.rng_max_m = msg.max_distance / 100.0
        return {k: getattr(msg, k) for k in _HELD_FIELDS if hasattr(msg, k)}


def _watched_ids(faults: Sequence[Fault]) -> set:
    """Messages decoded even outside a window: attitude for accel faults, the
    rangefinder's max_distance, and the values a hold (freeze/stuck/no-fix) needs."""
    watch = set()
    for f in faults:
        if f.kind == "accel_bias_step":
            watch.add(ID_ATTITUDE)
        if f.kind.startswith("rng_"):
            watch.add(ID_DISTANCE_SENSOR)
        if f.kind in ("baro_freeze", "rng_stuck", "gnss_dropout"):
            watch.update(mid for mid in GNSS_IDS + RNG_IDS + BARO_IDS if _applies_to(f, mid))
    return watch


def _in_window(states: Sequence[_FaultState], vt: Optional[float], boot: int) -> List[_FaultState]:
    """The faults in their window at vehicle time ``vt`` (a fault's boot is the
    first in which its onset is reached, unless it names one)."""
    active: List[_FaultState] = []
    if vt is None:
        return active
    for st in states:
        f = st.fault
        if st.boot is None and vt >= f.onset_s:
            st.boot = boot
        if st.boot == boot and f.onset_s <= vt < f.end_s:
            active.append(st)
    return active


def _shift_boot_times(msg, shift_s: float) -> bool:
    """Move a message's boot-time fields back by ``shift_s`` (after an injected
    reboot the clock restarts); True if it has one."""
    moved = False
    if hasattr(msg, "time_boot_ms"):
        msg.time_boot_ms = int(max(0, msg.time_boot_ms - round(shift_s * 1000)))
        moved = True
    if hasattr(msg, "time_usec") and msg.time_usec < UNIX_THRESHOLD_US:
        msg.time_usec = int(max(0, msg.time_usec - round(shift_s * 1e6)))
        moved = True
    return moved


def _fault_message(msg, rec: Record, vt, relevant, shifting, seen: _Seen) -> Tuple[bool, bool]:
    """Apply the faults in window and the reboots' clock shifts to one decoded
    message of the vehicle. Returns (dropped, changed)."""
    before = seen.note(msg, rec.msgid)
    dropped = changed = False
    for st in relevant:
        st.touch(rec, vt)
        res = _apply(st.fault, st, msg, rec.msgid, vt, seen.originals, seen.attitude, seen.rng_max_m)
        if res == "drop":
            dropped = True
            st.dropped += 1
            break
        if res:
            changed = True
            st.modified += 1
    for key, value in before.items():
        seen.originals[(rec.msgid, key)] = value
    if dropped:
        return True, False
    for st in shifting:
        if _shift_boot_times(msg, st.fault.onset_s):
            changed = True
            st.modified += 1
    return False, changed


def _report(target, target_comp, records, n_frames, junk, boots, signed_stripped, states) -> dict:
    report = {
        "generator": "mavnav inject",
        "sysid": target,
        "autopilot_compid": target_comp,
        "records": len(records),
        "frames": n_frames,
        "junk_records": junk,
        "boots_seen": boots,
        "signatures_stripped": signed_stripped,
        "clock": "onset_s/end_s: the input log's vehicle clock (time_boot_ms / time_usec) in boot 'boot'",
        "faults": [],
    }
    for st in states:
        d = describe_fault(st.fault)
        d.update(
            boot=st.boot,
            seed=st.fault.seed,
            records_modified=st.modified,
            records_dropped=st.dropped,
            first_vehicle_s=st.first_vehicle_s,
            first_recv_unix_s=None if st.first_recv_us is None else st.first_recv_us / 1e6,
            last_recv_unix_s=None if st.last_recv_us is None else st.last_recv_us / 1e6,
        )
        report["faults"].append(d)
    return report


class _Injector:
    """The faults applied record by record to one log's vehicle (``sysid``, its
    autopilot component ``compid``)."""

    def __init__(self, faults: Sequence[Fault], sysid: Optional[int], compid: Optional[int]):
        self.sysid = sysid
        self.states = [
            _FaultState(f, i, f.boot, np.random.default_rng([f.seed, i]), {}, {}) for i, f in enumerate(faults)
        ]
        self.reboots = [s for s in self.states if s.fault.kind == "reboot"]
        self.watch = _watched_ids(faults)
        self.clock = _Timeline(compid)
        self.seen = _Seen()
        self.decoder = mav2.MAVLink(None)
        self.decoder.robust_parsing = True
        self.junk = 0
        self.signed_stripped = 0

    def record(self, data: bytes, rec: Record) -> Optional[bytes]:
        """The record as it goes out (itself, or re-framed), None if a fault removes it."""
        raw = data[rec.start : rec.end]
        ours = rec.is_frame and rec.sysid == self.sysid
        vt = self.clock.time_of(data, rec) if ours else self.clock.last_vt
        if not rec.is_frame:
            self.junk += 1
        active = _in_window(self.states, vt, self.clock.boot)
        # link loss / reboot: nothing arrives
        drop = [st for st in active if st.fault.kind in ("link_loss", "reboot")]
        for st in drop:
            st.touch(rec, vt)
            st.dropped += 1
        if drop:
            return None
        return self._vehicle_frame(raw, rec, vt, active) if ours else raw

    def _vehicle_frame(self, raw: bytes, rec: Record, vt: Optional[float], active) -> Optional[bytes]:
        boot = self.clock.boot
        relevant = [st for st in active if _applies_to(st.fault, rec.msgid)]
        shifting = [st for st in self.reboots if st.boot == boot and vt is not None and vt >= st.fault.end_s]
        if not relevant and not shifting and rec.msgid not in self.watch:
            return raw
        frame = raw[8:]
        try:
            msg = self.decoder.decode(bytearray(frame))
        except Exception:  # a frame pymavlink refuses: keep it as it is
            return raw
        dropped, changed = _fault_message(msg, rec, vt, relevant, shifting, self.seen)
        if dropped:
            return None
        if not changed:
            return raw
        if rec.version == 2 and frame[2] & wire.IFLAG_SIGNED:
            self.signed_stripped += 1
        return raw[:8] + reframe(frame, msg)


def inject_bytes(
    data: bytes, faults: Sequence[Fault], sysid: Optional[int] = None
) -> Tuple[bytes, dict]:
    """Apply ``faults`` to tlog bytes. Returns (new bytes, report for the sidecar)."""
    records = split_tlog(data)
    n_frames = sum(1 for r in records if r.is_frame)
    if n_frames == 0:
        raise InputError("no MAVLink frames found: not a tlog")
    target, target_comp = _detect_vehicle(data, records, sysid)
    inj = _Injector(faults, target, target_comp)
    out = [b for b in (inj.record(data, rec) for rec in records) if b is not None]
    report = _report(target, target_comp, records, n_frames, inj.junk, inj.clock.boot + 1, inj.signed_stripped,
                     inj.states)
    return b"".join(out), report


_HELD_FIELDS = ("alt", "alt_ellipsoid", "lat", "lon", "current_distance", "signal_quality", "distance",
                "press_abs", "abs_pressure", "pressure_alt")


def _hold(st: _FaultState, originals, msgid: int, field: str, current):
    key = (msgid, field)
    if key not in st.held:
        st.held[key] = originals.get(key, current)
    return st.held[key]


def _shift_pressure_hpa(p_hpa: float, dh_m: float) -> float:
    if not p_hpa > 0:
        return p_hpa
    alt = height_from_pressure_m(p_hpa * 100.0, P0_PA)
    return pressure_at_height_pa(alt + dh_m, P0_PA) / 100.0


def _apply(f: Fault, st: _FaultState, msg, msgid: int, vt: float, originals, att, rng_max_m) -> object:
    """Change ``msg`` in place for fault ``f``. Returns True if changed, "drop", or False."""
    k = f.kind
    if k == "rate_drop":
        c = st.counters.get(msgid, 0)
        st.counters[msgid] = c + 1
        return False if keeps(f, c) else "drop"
    if k.startswith("gnss_"):
        return _apply_gnss(f, st, msg, msgid, vt, originals)
    if k.startswith("rng_"):
        if msgid == ID_DISTANCE_SENSOR:
            return _apply_distance_sensor(f, st, msg, msgid, originals)
        return _apply_rangefinder(f, st, msg, msgid, originals, rng_max_m)
    if k.startswith("baro_"):
        return _apply_baro(f, st, msg, msgid, vt, originals)
    if k == "accel_bias_step":
        return _apply_accel(f, msg, msgid, vt, att)
    return False


def _apply_gnss(f: Fault, st: _FaultState, msg, msgid: int, vt: float, originals) -> object:
    k = f.kind
    if k in ("gnss_step", "gnss_ramp", "gnss_noise"):
        dh = height_error_m(f, vt, st.rng)
        d_mm = int(round(dh * 1000))
        msg.alt = int(msg.alt + d_mm)
        if getattr(msg, "alt_ellipsoid", 0):
            msg.alt_ellipsoid = int(msg.alt_ellipsoid + d_mm)
        return True
    if k == "gnss_dropout":
        if f.effective_mode == "silent":
            return "drop"
        for fld in ("alt", "lat", "lon", "alt_ellipsoid"):
            if hasattr(msg, fld):
                setattr(msg, fld, int(_hold(st, originals, msgid, fld, getattr(msg, fld))))
        msg.fix_type = 1
        msg.satellites_visible = min(3, msg.satellites_visible)
        msg.eph, msg.epv = 9999, 9999
        if hasattr(msg, "v_acc"):
            msg.v_acc, msg.h_acc = 99999, 99999
        return True
    return False


def _apply_distance_sensor(f: Fault, st: _FaultState, msg, msgid: int, originals) -> object:
    """DISTANCE_SENSOR (centimetres), the downward one only."""
    k = f.kind
    if msg.orientation != MAV_SENSOR_ROTATION_PITCH_270:
        return False
    if k == "rng_dropout":
        if f.effective_mode == "silent":
            return "drop"
        msg.current_distance = min(65535, msg.max_distance + 1)
        msg.signal_quality = 1
    elif k == "rng_stuck":
        if f.magnitude is None:
            msg.current_distance = int(_hold(st, originals, msgid, "current_distance", msg.current_distance))
            msg.signal_quality = int(_hold(st, originals, msgid, "signal_quality", msg.signal_quality))
        else:
            msg.current_distance = int(min(65535, max(0, round(f.magnitude * 100))))
    elif k == "rng_spikes":
        if not spikes(f, st.rng):
            return False
        msg.current_distance = int(min(65535, max(0, msg.current_distance + round(f.magnitude * 100))))
    elif k == "rng_out_of_range":
        msg.current_distance = int(min(65535, round(out_of_range_reading_m(f, msg.max_distance / 100.0) * 100)))
    return True


def _apply_rangefinder(f: Fault, st: _FaultState, msg, msgid: int, originals, rng_max_m) -> object:
    """RANGEFINDER (ArduPilot), metres."""
    k = f.kind
    if k == "rng_dropout":
        if f.effective_mode == "silent":
            return "drop"
        msg.distance = (rng_max_m + 0.01) if rng_max_m is not None else 0.0
    elif k == "rng_stuck":
        msg.distance = _hold(st, originals, msgid, "distance", msg.distance) if f.magnitude is None else f.magnitude
    elif k == "rng_spikes":
        if not spikes(f, st.rng):
            return False
        msg.distance = msg.distance + f.magnitude
    elif k == "rng_out_of_range":
        msg.distance = out_of_range_reading_m(f, rng_max_m if rng_max_m is not None else msg.distance)
    return True


def _apply_baro(f: Fault, st: _FaultState, msg, msgid: int, vt: float, originals) -> object:
    if f.kind == "baro_freeze":
        if msgid == ID_HIGHRES_IMU:
            msg.abs_pressure = _hold(st, originals, msgid, "abs_pressure", msg.abs_pressure)
            msg.pressure_alt = _hold(st, originals, msgid, "pressure_alt", msg.pressure_alt)
        else:
            msg.press_abs = _hold(st, originals, msgid, "press_abs", msg.press_abs)
        return True
    dh = height_error_m(f, vt)
    if msgid == ID_HIGHRES_IMU:
        if not msg.abs_pressure > 0:
            return False
        msg.abs_pressure = _shift_pressure_hpa(msg.abs_pressure, dh)
        msg.pressure_alt = msg.pressure_alt + dh
    else:
        msg.press_abs = _shift_pressure_hpa(msg.press_abs, dh)
    return True


def _apply_accel(f: Fault, msg, msgid: int, vt: float, att) -> object:
    d = down_row_from_euler(att[0], att[1])
    # f_up = -(down_row . f_b): adding -m * down_row to f_b adds m to f_up
    dx, dy, dz = (-height_error_m(f, vt) * c for c in d)
    if msgid == ID_HIGHRES_IMU:
        msg.xacc, msg.yacc, msg.zacc = msg.xacc + dx, msg.yacc + dy, msg.zacc + dz
    else:
        to_mg = 1000.0 / G0_MPS2

        def clip(v):
            return int(max(-32768, min(32767, round(v))))

        msg.xacc = clip(msg.xacc + dx * to_mg)
        msg.yacc = clip(msg.yacc + dy * to_mg)
        msg.zacc = clip(msg.zacc + dz * to_mg)
    return True


def inject_file(in_path, out_path, faults: Sequence[Fault], sysid: Optional[int] = None) -> dict:
    """Read a tlog, inject, write the result; returns the report (sidecar content)."""
    try:
        with open(in_path, "rb") as fh:
            data = fh.read()
    except FileNotFoundError:
        raise InputError(f"{in_path}: no such file") from None
    except OSError as exc:
        raise InputError(f"{in_path}: cannot read ({exc.strerror})") from None
    out, report = inject_bytes(data, faults, sysid)
    with open(out_path, "wb") as fh:
        fh.write(out)
    report["input"] = str(in_path)
    report["output"] = str(out_path)
    return report


__all__ = ["Record", "split_tlog", "reframe", "inject_bytes", "inject_file"]
