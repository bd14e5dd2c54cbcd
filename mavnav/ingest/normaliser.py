"""MAVLink messages -> mavnav samples: with its decoders, the only place that knows MAVLink field names.

One :class:`Normaliser` per link (a live connection or one tlog) is fed
decoded-on-demand frames ``(recv_s, msgid, sysid, compid, payload)`` by a
frame reader (:mod:`.tlog_reader` or :mod:`.stream_reader`), so live and
replay share every rule below. Each of :meth:`~Normaliser.feed`,
:meth:`~Normaliser.problem`, :meth:`~Normaliser.tick` and
:meth:`~Normaliser.finish` returns what it releases: samples and events in
arrival order, except that samples held for a reference or a bracketing
attitude are released when it arrives; within each kind and boot ``t_us``
strictly increases.

Decisions the issue left open (see also the module docs of :mod:`.clock`,
:mod:`.attitude`, :mod:`.references`, :mod:`.streams`). Stages of their own:
the per-message decoders, a reading or why not (:mod:`.decoders`), the time
base (:mod:`.timebase`), the height references (:mod:`.heightref`), the
rangefinder's checks (:mod:`.rangecheck`), and the other systems on the link
and what is said about them (:mod:`.systems`):

* **Vehicle.** The first HEARTBEAT with ``autopilot != MAV_AUTOPILOT_INVALID``
  and ``type != MAV_TYPE_GCS`` selects the system (or the ``sysid`` given).
  All components of that system are used (a sonar is often its own
  component), but only the autopilot component's times drive the vehicle
  clock and reboot detection. Frames that arrive before the heartbeat are
  held (up to ``preselect_max_frames``) and replayed once it does.
* **IMU.** ``auto`` ranks HIGHRES_IMU > RAW_IMU > SCALED_IMU > SCALED_IMU2 >
  SCALED_IMU3; RAW_IMU is only milli-g on ArduPilot, so it is a candidate
  only when the heartbeat says ArduPilot (for other autopilots it is raw
  sensor counts). HIGHRES_IMU with ``fields_updated`` set but no
  accelerometer bit is not a new accelerometer sample and is skipped.
* **Rangefinder.** ``auto`` prefers DISTANCE_SENSOR (downward, timed) over
  RANGEFINDER (untimed); ArduPilot often sends both for one sensor, and
  one sensor must not be counted twice. Tilt correction uses the latest
  attitude (within ``attitude_max_age_s``); beyond ``rangefinder_max_tilt_deg``
  the reading is refused (``tilt``). DISTANCE_SENSOR limits come from the
  message (``max_distance`` 0 means unknown), RANGEFINDER limits from the
  configuration. Where both come, each reading of the chosen one is
  compared with the other's latest (received within
  ``range_cross_max_age_s``); one that disagrees beyond
  ``range_cross_tol_m`` / ``range_cross_tol_frac`` is refused
  (``disagrees``). *Stuck*: the same raw reading for ``rangefinder_stuck_s``
  while the barometer moved at least ``rangefinder_stuck_min_move_m``; the
  run's later readings are refused (``stuck``) until the value changes (the
  first ``rangefinder_stuck_s`` of a run cannot be told from a steady hover).
* **References "home": the autopilot's own, within a second of connecting.**
  The first of these fixes the point both references are taken at (its
  altitude MSL is ``alt_ref_msl_m``), on the ground or in flight:
  HOME_POSITION (origin ``home``); GLOBAL_POSITION_INT, whose ``alt -
  relative_alt`` is the home altitude (``autopilot_home``; only with a
  position, ``lat``/``lon`` not both zero, and with home set: ArduPilot
  reports ``relative_alt == alt`` before it is); GPS_GLOBAL_ORIGIN with
  LOCAL_POSITION_NED (``ekf_origin``, heights ``-z`` above it). The GNSS
  reference is that altitude (for the ellipsoid datum shifted by the geoid
  separation seen in GPS_RAW_INT, ``alt_ellipsoid - alt``). The baro
  reference pressure is the one that makes the baro height equal the
  autopilot's height above that point (``relative_alt``, or ``-z``) at the
  same moment (ISA), averaged over the first second (at most
  ``startup_window_s``) of baro samples with such a height within 1 s
  (moved along by the autopilot's vertical speed). A HOME_POSITION with no
  such height (no position stream) takes the pressure over
  ``startup_window_s`` up to it as the pressure at home. Held samples wait
  at most ``home_wait_s``; after 1 s a :class:`~mavnav.samples.Notice`
  says what they wait for, and with nothing in time the reference is the
  start-up mean. While the baro reference is pending every sample and
  timed event waits with the baro samples and goes out with them, the
  reference first, then in time order: the epoch builder starts at the
  first baro sample and would drop what reached it before.
* **A home that moves** (``follow_home``): a new home set at arming, or at
  another altitude, moves the reference point and a
  :class:`~mavnav.samples.ReferenceMoved` says so; the references stay
  where they were fixed (the filters must see no step) and the pipeline
  reports heights above the new point. What moves it: a HOME_POSITION whose
  altitude changed by more than ``home_move_min_m`` from the previous one;
  on a link without HOME_POSITION, GLOBAL_POSITION_INT's ``alt -
  relative_alt`` changed by as much in :data:`HOME_CONFIRM_N` messages in a
  row. The autopilot's heights above its home (``relative_alt``) are taken
  above the point the references were fixed at (``alt`` minus its
  altitude), so they do not jump with it.
* **Autopilot height.** GLOBAL_POSITION_INT ``alt`` (MSL) minus the GNSS
  reference in MSL, i.e. above the same point as :class:`GnssHeight`;
  LOCAL_POSITION_NED ``-z`` plus the EKF origin altitude (GPS_GLOBAL_ORIGIN)
  minus the same. Held until the GNSS reference is known; with none
  within the GNSS ``home_wait_s`` (e.g. no fix indoors) the autopilot's own
  datum is used for the rest of the stream: ``relative_alt`` (above its
  home) or ``-z`` (above its EKF origin); ``stats.autopilot_reference``
  says which.
* **First IMU first.** At the start of a boot, baro, GNSS and rangefinder
  samples wait (at most 5 s of their vehicle time) until the first IMU
  sample of the boot has gone out: the IMU is held a little longer (its
  source choice, its attitude), and the epochs start on IMU data, so a
  reference known quickly must not make the first baro samples arrive
  before anything they can be integrated with.
* **Link.** The link is lost when nothing from the vehicle arrived for
  ``link_timeout_s`` of receive time: a live source calls :meth:`tick`,
  a tlog shows it as a receive-time hole (both events then come together).
"""

from __future__ import annotations

import math
from collections import deque
from typing import Deque, List, NamedTuple, Optional, Sequence

from ..config import IngestConfig
from ..frames import cos_tilt, down_row_from_quat, f_up_from_body
from ..samples import (
    AutopilotHeight,
    BaroHeight,
    Gap,
    GnssHeight,
    LinkLost,
    LinkRecovered,
    RangeHeight,
    Notice,
    Reboot,
    ReferenceMoved,
    ReferenceSet,
    Rejected,
    SpecificForceUp,
)
from ..sensors import AUTOPILOT_STREAM, BARO_STREAM, GNSS_STREAM, IMU_STREAM, RANGE_STREAM
from . import wire
from .attitude import AttitudeInterpolator
from .heightref import GNSS_FIXED, BaroItem, GnssItem, HeightReferences
from .clock import HOLD
from .decoders import (HIGHRES_IMU_ACCEL_BITS, MAX_SPECIFIC_FORCE_MPS2, GlobalPositionReading, GnssReading,
                       LocalPositionReading, Refusal, Skipped, decode_attitude, decode_attitude_quaternion,
                       decode_global_position_int, decode_gps_global_origin, decode_gps_raw_int, decode_highres_imu,
                       decode_home_position, decode_local_position_ned, decode_pressure, decode_raw_imu,
                       decode_scaled_imu)
from .rangecheck import RangeChecks
from .timebase import BEHIND_US, SETTLED, ClockStepped, NewBoot, Placed, TimeBase
from .stats import GapRecord, IngestStats, ReferenceRecord, VehicleInfo
from .streams import KindGuard, SourceSelector
from .systems import OtherSystems, describe_system, is_vehicle_heartbeat
from .vehicle_class import is_height_input, not_applicable_reason, notice_text

MAV_COMP_ID_AUTOPILOT1 = 1
MAV_SENSOR_ROTATION_PITCH_270 = 25  # downward
PRE_IMU_HOLD_US = 5_000_000  # at most this long do measurements wait for the first IMU sample of a boot
GATED = frozenset((BARO_STREAM, GNSS_STREAM, RANGE_STREAM))

IMU_RANKING = ("HIGHRES_IMU", "RAW_IMU", "SCALED_IMU", "SCALED_IMU2", "SCALED_IMU3")
RANGE_RANKING = ("DISTANCE_SENSOR", "RANGEFINDER")
AUTOPILOT_RANKING = ("GLOBAL_POSITION_INT", "LOCAL_POSITION_NED")

_ID = wire.MSG_ID
HEARTBEAT = _ID["HEARTBEAT"]
PRESSURE_IDS = {1: _ID["SCALED_PRESSURE"], 2: _ID["SCALED_PRESSURE2"], 3: _ID["SCALED_PRESSURE3"]}
IMU_IDS = {_ID[n]: n for n in IMU_RANKING}
WANTED = frozenset(
    [HEARTBEAT, _ID["SYSTEM_TIME"], _ID["ATTITUDE"], _ID["ATTITUDE_QUATERNION"], _ID["GPS_RAW_INT"]]
    + list(IMU_IDS)
    + list(PRESSURE_IDS.values())
    + [_ID["DISTANCE_SENSOR"], _ID["RANGEFINDER"], _ID["HOME_POSITION"]]
    + [_ID["GLOBAL_POSITION_INT"], _ID["LOCAL_POSITION_NED"], _ID["GPS_GLOBAL_ORIGIN"]]
)


class ImuItem(NamedTuple):
    """An IMU sample on the vehicle clock, before its attitude is known."""

    t_us: int
    recv_s: float
    boot: int
    fb: tuple  # specific force, body FRD, m/s^2
    name: str  # the message it came in


class RangeItem(NamedTuple):
    """A rangefinder message on the vehicle clock, before its checks."""

    t_us: int
    recv_s: float
    boot: int
    name: str  # DISTANCE_SENSOR or RANGEFINDER
    f: dict  # its fields


class AutopilotItem(NamedTuple):
    """The autopilot's own height on the vehicle clock, before its datum is decided."""

    t_us: int
    recv_s: float
    boot: int
    alt_msl: Optional[float]  # GLOBAL_POSITION_INT alt (None without a position; LOCAL_POSITION_NED: None)
    local_up: float  # above its home (relative_alt) or its EKF origin (-z)
    vel_up: float


_NOTHING: tuple = ()  # what a call that releases nothing returns


class Normaliser:
    def __init__(self, config: IngestConfig, sysid: Optional[int] = None, stats: Optional[IngestStats] = None,
                 link_name: str = "the link"):
        cfg = self.cfg = config
        self.stats = stats if stats is not None else IngestStats()
        self._out: List[object] = []  # what the current call releases (see _drain)
        self.sysid = sysid
        self.link_name = link_name
        self._asked = sysid is not None
        self._not_applicable: Optional[str] = None  # why height integrity does not apply (vehicle_class)
        self.autopilot: Optional[int] = None
        self._preselect: Deque[tuple] = deque()
        if sysid is not None:
            self.stats.vehicle = VehicleInfo(sysid=sysid)
        self.time = TimeBase(cfg.reboot_jump_s)
        self.clock = self.time.clock  # read here (boot, last time); moved by the time stage only
        self.att = AttitudeInterpolator(cfg.attitude_wait_s, cfg.attitude_max_age_s)
        self.guard = KindGuard(cfg.gap_min_s, cfg.gap_factor)
        self.imu_sel = SourceSelector(IMU_RANKING, cfg.imu_source, cfg.source_select_s)
        self.range_sel = SourceSelector(RANGE_RANKING, cfg.range_source, cfg.source_select_s)
        self.ap_sel = SourceSelector(AUTOPILOT_RANKING, cfg.autopilot_source, cfg.source_select_s)
        self.refs = HeightReferences(cfg, self.clock, lambda: self._last_recv)
        self._imu_out = False  # an IMU sample of this boot went out
        self._pre_imu: List[object] = []  # measurements waiting for it
        # every sample while the baro reference is pending (its baro samples held in
        # refs): released with the baro samples in time order once it is known
        self._ref_hold: Optional[List[tuple]] = None
        self._last_recv: Optional[float] = None
        self._link_lost = False
        self._ap_held: Deque[AutopilotItem] = deque()
        self._ap_mode: Optional[str] = None
        self._gnss_wait_us = int(cfg.gnss_reference.home_wait_s * 1e6)
        self._cos_max_tilt = math.cos(math.radians(cfg.rangefinder_max_tilt_deg))
        self.range_checks = RangeChecks(cfg)  # reading, cross-check, stuck (see .rangecheck)
        self._pressure_id = PRESSURE_IDS[cfg.baro_instance]
        self._decoders = {mid: wire.make_decoder(mid) for mid in WANTED}
        self.others = OtherSystems(link_name, self._decoders[HEARTBEAT])  # the systems that are not the vehicle
        self._handlers = {
            HEARTBEAT: self._heartbeat,
            _ID["SYSTEM_TIME"]: self._system_time,
            _ID["ATTITUDE"]: self._attitude,
            _ID["ATTITUDE_QUATERNION"]: self._attitude_quaternion,
            _ID["HIGHRES_IMU"]: self._highres_imu,
            _ID["RAW_IMU"]: self._raw_imu,
            _ID["SCALED_IMU"]: self._scaled_imu_handler("SCALED_IMU"),
            _ID["SCALED_IMU2"]: self._scaled_imu_handler("SCALED_IMU2"),
            _ID["SCALED_IMU3"]: self._scaled_imu_handler("SCALED_IMU3"),
            _ID["GPS_RAW_INT"]: self._gps_raw_int,
            _ID["DISTANCE_SENSOR"]: self._distance_sensor,
            _ID["RANGEFINDER"]: self._rangefinder,
            _ID["HOME_POSITION"]: self._home_position,
            _ID["GLOBAL_POSITION_INT"]: self._global_position_int,
            _ID["LOCAL_POSITION_NED"]: self._local_position_ned,
            _ID["GPS_GLOBAL_ORIGIN"]: self._gps_global_origin,
        }
        for mid in PRESSURE_IDS.values():
            self._handlers[mid] = self._scaled_pressure
        # what the time stage places (timebase.Placed.what) -> its handler, (f, t_us, recv_s)
        self._placed = {
            "system_time": self._system_time_at,
            "attitude": self._attitude_at,
            "imu": self._imu_at,
            "pressure": self._pressure_at,
            "gnss": self._gnss_at,
            "distance_sensor": self._distance_sensor_at,
            "rangefinder": self._rangefinder_at,
            "global_position_int": self._global_position_int_at,
            "local_position_ned": self._local_position_ned_at,
        }

    # ------------------------------------------------------------------ input

    def feed(self, recv_s: float, msgid: int, sysid: int, compid: int, payload: bytes) -> Sequence[object]:
        """One frame of the link; returns the samples and events it releases."""
        self._frame(recv_s, msgid, sysid, compid, payload)
        out = self._out  # _drain(), inline: once per frame
        if not out:
            return _NOTHING  # most frames release nothing: no new list for them
        self._out = []
        return out

    def _drain(self) -> Sequence[object]:
        out = self._out
        if not out:
            return _NOTHING
        self._out = []
        return out

    def _frame(self, recv_s: float, msgid: int, sysid: int, compid: int, payload: bytes) -> None:
        if sysid != self.sysid:
            self._not_the_vehicle(recv_s, msgid, sysid, compid, payload)
            return
        last = self._last_recv
        if last is not None and (self._link_lost or recv_s - last > self.cfg.link_timeout_s):
            if not self._link_lost:
                self._emit(LinkLost(recv_s=last + self.cfg.link_timeout_s, silent_s=self.cfg.link_timeout_s))
                self.stats.link_losses += 1
            self._link_lost = False
            self._emit(LinkRecovered(recv_s=recv_s, outage_s=recv_s - last))
        self._last_recv = recv_s if last is None or recv_s > last else last
        # skip early what is decided away (cheap path for unused streams)
        if msgid in IMU_IDS:
            chosen = self.imu_sel.chosen
            if chosen is not None and IMU_IDS[msgid] != chosen:
                self.imu_sel.dropped += 1
                return
        elif msgid in PRESSURE_IDS.values() and msgid != self._pressure_id:
            self.stats.filtered["baro_other_instance"] += 1
            return
        try:
            fields = self._decoders[msgid](payload)
        except Exception as exc:  # struct errors on a CRC-valid but malformed payload
            self._reject(recv_s, "malformed", f"{wire.msg_name(msgid)}: {exc}")
            return
        try:
            self._handlers[msgid](fields, recv_s, compid)
        except Exception as exc:  # a bug must not stop a live monitor: counted, and tests require zero
            self._reject(recv_s, "internal_error", f"{wire.msg_name(msgid)}: {type(exc).__name__}: {exc}")
        if self._pre_imu and self._imu_out:
            self._merge_gate()

    def problem(self, rejected: Rejected) -> Sequence[object]:
        """A frame-level problem reported by the reader (garbage, CRC, unknown id...): returns it."""
        self.stats.rejected[rejected.kind] += 1
        self.stats.events["Rejected"] += 1
        self._out.append(rejected)
        return self._drain()

    def tick(self, now_s: float) -> Sequence[object]:
        """Live links: declare the link lost after ``link_timeout_s`` of silence, and say
        what is awaited while no heartbeat of the vehicle came. Returns those events."""
        if self.autopilot is None:
            said = self.others.waiting(now_s, self.sysid, self._asked, self._last_recv is not None)
            if said is not None:
                self._emit(said)
        last = self._last_recv
        if last is not None and not self._link_lost and now_s - last > self.cfg.link_timeout_s:
            self._link_lost = True
            self.stats.link_losses += 1
            self._emit(LinkLost(recv_s=now_s, silent_s=now_s - last))
        return self._drain()

    def finish(self) -> Sequence[object]:
        """End of stream: decide what is pending and release everything held (returned)."""
        if self.sysid is None and self._preselect:
            self.stats.filtered["no_vehicle_heartbeat"] += len(self._preselect)
            self._preselect.clear()
        self._on_time(self.time.finish())
        self._settle_boot()
        self._finalise_stats()
        return self._drain()

    # ------------------------------------------------------------------ vehicle

    def _not_the_vehicle(self, recv_s, msgid, sysid, compid, payload) -> None:
        """A frame of another system, or of any while none is chosen: said (see
        :class:`.systems.OtherSystems`), held until a heartbeat chooses the vehicle, or counted."""
        said = self.others.frame(recv_s, msgid, sysid, payload, self.sysid if self.autopilot is not None else None)
        if said is not None:
            self._emit(said)
        if self.sysid is None:
            self._preselect_frame(recv_s, msgid, sysid, compid, payload)
        else:
            self.stats.ignored_by_sysid[sysid] = self.stats.ignored_by_sysid.get(sysid, 0) + 1

    def _preselect_frame(self, recv_s, msgid, sysid, compid, payload) -> None:
        if msgid == HEARTBEAT:
            f = self._decoders[HEARTBEAT](payload)
            if is_vehicle_heartbeat(f):
                self.sysid = sysid
                self._heartbeat(f, recv_s, compid)
                held = list(self._preselect)
                self._preselect.clear()
                for fr in held:
                    self._frame(*fr)
                self._frame(recv_s, msgid, sysid, compid, payload)
                return
        if len(self._preselect) >= self.cfg.preselect_max_frames:
            self._preselect.popleft()
            self.stats.filtered["before_vehicle_heartbeat"] += 1
        self._preselect.append((recv_s, msgid, sysid, compid, payload))

    def _heartbeat(self, f, recv_s, compid) -> None:
        if self.autopilot is None and is_vehicle_heartbeat(f):
            self.autopilot = f["autopilot"]
            self.time.ap_compid = compid
            self.stats.vehicle = VehicleInfo(self.sysid, compid, f["type"], f["autopilot"])
            why = "as asked (--sysid)" if self._asked else "the first autopilot heartbeat"
            self._emit(Notice(recv_s, "vehicle", f"monitoring system {self.sysid} "
                                                 f"({describe_system(f['type'], f['autopilot'])}, component {compid}) "
                                                 f"on {self.link_name}: {why}"))
            self._not_applicable = not_applicable_reason(mav_type=f["type"])
            if self._not_applicable:
                self.stats.not_applicable = self._not_applicable
                self._emit(Notice(recv_s, "not_applicable", notice_text(self._not_applicable)))
            for said in self.others.vehicle_chosen(recv_s, self.sysid):
                self._emit(said)

    # ------------------------------------------------------------------ time

    def _on_time(self, steps) -> None:
        """Act on the time stage's steps (see :mod:`.timebase`), each before taking the next."""
        placed = self._placed
        for step in steps:
            kind = type(step)
            if kind is Placed:
                placed[step.what](step.f, step.t_us, step.recv_s)
            elif step is SETTLED:
                if self.att.pending:
                    self._resolve_attitude()
            elif kind is NewBoot:
                self._reboot(step.t_us, step.recv_s)
            elif kind is ClockStepped:
                self.stats.clock_steps += 1
                self._emit(Notice(step.recv_s, "clock_step", step.text))
            else:  # Refused
                self._reject(step.recv_s, step.kind, step.detail, step.t_us)

    def _boot_ms(self, t_us: int, recv_s: float, compid: int, what: str, f) -> None:
        """``self._on_time(self.time.boot_ms(t_us, recv_s, compid, what, f))``, with the hot path of
        :meth:`TimeBase.boot_ms` inline (the autopilot's clock, no candidate time
        base open, the time accepted): its Placed, then SETTLED, acted on without
        the steps. ``tests/test_ingest_inline.py`` checks it against
        :meth:`_boot_ms_reference`."""
        tb = self.time
        if compid == tb.ap_compid and not tb._cands:
            clock = tb.clock
            t = t_us + clock.step_us
            if clock.classify(t, recv_s, BEHIND_US) != HOLD:
                clock.accept(t, recv_s)
                self._placed[what](f, t, recv_s)
                if self.att.pending:
                    self._resolve_attitude()
                return
        self._on_time(tb.boot_ms(t_us, recv_s, compid, what, f))

    def _boot_ms_reference(self, t_us: int, recv_s: float, compid: int, what: str, f) -> None:
        self._on_time(self.time.boot_ms(t_us, recv_s, compid, what, f))

    def _flush_streams(self) -> None:
        self._on_time(self.time.flush())

    def _settle_boot(self) -> None:
        """Release everything held for the current boot: stream ordering,
        source choices, attitude waits, and samples held for a reference not
        yet known (resolved from what is held, as at the end of a stream).
        Called at the end of the stream and before a Reboot event, so no
        sample of a boot follows the event that ends it."""
        self._flush_streams()
        for sel, fn in ((self.imu_sel, self._imu_selected), (self.range_sel, self._range_selected), (self.ap_sel, self._ap_selected)):
            for item in sel.decide():
                fn(item)
        self._resolve_attitude(flush=True)
        self._on_refs(self.refs.settle())
        self._ap_release(final=True)
        self._imu_out = True
        self._merge_gate()

    def _reboot(self, t_us: int, recv_s: float) -> None:
        self._settle_boot()  # what belongs to the old boot goes out before the Reboot event
        last, boot = self.time.new_boot(t_us, recv_s)
        self.att.reset()
        self.range_checks.stuck.reset()
        self.refs.new_boot()
        self._imu_out = False
        self.stats.reboots += 1
        self._emit(Reboot(t_us=t_us, recv_s=recv_s, boot=boot, last_t_us=last if last is not None else 0))

    def _system_time(self, f, recv_s, compid) -> None:
        self._boot_ms(f["time_boot_ms"] * 1000, recv_s, compid, "system_time", f)

    def _system_time_at(self, f, t_us, recv_s) -> None:
        self.clock.set_unix_offset(f["time_unix_usec"], t_us)

    # ------------------------------------------------------------------ attitude and IMU

    def _attitude(self, f, recv_s, compid) -> None:
        r = decode_attitude(f)
        if type(r) is Refusal:
            self._reject(recv_s, r.kind, r.detail)
            return
        self._boot_ms(r.t_boot_us, recv_s, compid, "attitude", r.q)

    def _attitude_quaternion(self, f, recv_s, compid) -> None:
        r = decode_attitude_quaternion(f)
        if type(r) is Refusal:
            self._reject(recv_s, r.kind, r.detail)
            return
        self._boot_ms(r.t_boot_us, recv_s, compid, "attitude", r.q)

    def _attitude_at(self, q, t_us, recv_s) -> None:
        self.att.add(t_us, q)

    def _highres_imu(self, f, recv_s, compid) -> None:
        """:meth:`_highres_imu_reference` with a valid reading's decoding inline
        (:func:`.decoders.decode_highres_imu`: a new accelerometer sample, each
        axis finite and within 50 g), the IMU's hot path on PX4; skips and
        refusals go through the decoder. ``tests/test_ingest_decoders.py``
        checks the two give the same stream."""
        upd = f["fields_updated"]
        x, y, z = f["xacc"], f["yacc"], f["zacc"]  # m/s^2, body FRD
        m = MAX_SPECIFIC_FORCE_MPS2
        if (not upd or upd & HIGHRES_IMU_ACCEL_BITS) and -m <= x <= m and -m <= y <= m and -m <= z <= m:
            if self.imu_sel.chosen is None:  # _imu's note
                for it in self.imu_sel.note("HIGHRES_IMU", self.clock.last_t_us):
                    self._imu_selected(it)
            self._imu_usec((x, y, z), "HIGHRES_IMU", f["time_usec"], recv_s, compid)
            return
        self._imu("HIGHRES_IMU", decode_highres_imu(f), recv_s, compid)

    def _highres_imu_reference(self, f, recv_s, compid) -> None:
        self._imu("HIGHRES_IMU", decode_highres_imu(f), recv_s, compid)

    def _raw_imu(self, f, recv_s, compid) -> None:
        self._imu("RAW_IMU", decode_raw_imu(f, self.autopilot), recv_s, compid)

    def _scaled_imu_handler(self, name: str):
        def handler(f, recv_s, compid) -> None:
            self._imu(name, decode_scaled_imu(name, f), recv_s, compid)

        return handler

    def _imu(self, name: str, r, recv_s, compid) -> None:
        """One IMU message's decoding (:mod:`.decoders`): skipped, or noted for the
        source choice, then refused or placed on the vehicle clock."""
        kind = type(r)
        if kind is Skipped:
            self.stats.filtered[r.counter] += 1
            return
        if self.imu_sel.chosen is None:  # _noted, inline: once chosen, nothing to note
            for it in self.imu_sel.note(name, self.clock.last_t_us):
                self._imu_selected(it)
        if kind is Refusal:
            self._reject(recv_s, r.kind, r.detail)
            return
        if r.usec:
            self._imu_usec(r.fb, name, r.t_raw, recv_s, compid)
        else:
            self._boot_ms(r.t_raw, recv_s, compid, "imu", (r.fb, name))

    def _imu_usec(self, fb, name, t_raw, recv_s, compid) -> None:
        """:meth:`_imu_usec_reference` with the hot path inline (no candidate time
        base open, the stream's clock known): TimeBase.usec and .stream, then
        _on_time's Placed and SETTLED, without the steps; and for the chosen
        source, no second attitude resolution after the one its admission ran
        (nothing changes in between). ``tests/test_ingest_inline.py`` checks the
        two give the same stream."""
        key = (name, compid)
        tb = self.time
        if not tb._cands:
            off = tb.streams.offsets.get(key)
            if off is not None:
                t = tb.clock.boot_from_usec(t_raw, recv_s)
                if t is not None:
                    if name == self.imu_sel.chosen:  # _imu_at, inline: the source is chosen
                        if self._imu_selected(ImuItem(t - off, recv_s, self.clock.boot, fb, name)):
                            return  # the attitude waits were resolved just now: SETTLED finds nothing new
                    else:
                        self._imu_at((fb, name), t - off, recv_s)
                    if self.att.pending:
                        self._resolve_attitude()
                    return
        self._on_time(tb.usec(key, t_raw, recv_s, name, "imu", (fb, name)))

    def _imu_usec_reference(self, fb, name, t_raw, recv_s, compid) -> None:
        self._on_time(self.time.usec((name, compid), t_raw, recv_s, name, "imu", (fb, name)))

    def _imu_at(self, payload, t_us, recv_s) -> None:
        fb, name = payload
        item = ImuItem(t_us, recv_s, self.clock.boot, fb, name)
        sel = self.imu_sel
        if sel.chosen is not None:  # SourceSelector.offer, inline: the source is chosen
            if name == sel.chosen:
                self._imu_selected(item)
            else:
                sel.dropped += 1
            return
        for it in sel.offer(name, item):
            self._imu_selected(it)

    def _imu_selected(self, item: ImuItem) -> bool:
        """Admitted, the sample waits for its attitude and the waits are resolved (True)."""
        self.stats.imu_source = self.imu_sel.chosen
        if not self._admit(IMU_STREAM, item.t_us, item.recv_s, item.boot):
            return False
        self.att.pending.append(item)
        self._resolve_attitude()
        return True

    def _resolve_attitude(self, flush: bool = False) -> None:
        att = self.att
        pend = att.pending
        if not pend:
            return  # nothing waits (att.resolve would release nothing)
        now_us = self.clock.last_t_us
        if not flush and now_us is not None:
            ts = att._t  # att.resolve's own fast path, without the call: the head still waits
            if ts:
                t = pend[0].t_us
                if t > ts[-1] and now_us < t + att.wait_us:
                    return
        for item, q, _nearest in att.resolve(now_us, flush):  # item: the ImuItem that waited
            if q is None:
                self._reject(item.recv_s, "no_attitude",
                             f"{item.name}: no attitude within {self.cfg.attitude_max_age_s} s", item.t_us, item.boot)
                continue
            f_up = f_up_from_body(item.fb, down_row_from_quat(q))
            self._yield(IMU_STREAM, SpecificForceUp(item.t_us, item.recv_s, item.boot, f_up, item.name))

    # ------------------------------------------------------------------ barometer

    def _scaled_pressure(self, f, recv_s, compid) -> None:
        r = decode_pressure(f)
        if type(r) is Refusal:
            self._reject(recv_s, r.kind, r.detail)
            return
        self._boot_ms(r.t_boot_us, recv_s, compid, "pressure", r.p_pa)

    def _pressure_at(self, p_pa, t_us, recv_s) -> None:
        self.range_checks.stuck.pressure(p_pa)
        self._on_refs(self.refs.pressure(BaroItem(t_us, recv_s, self.clock.boot, p_pa)))
        if self._ref_hold is None and self.refs.baro.value is None and self.refs.baro.held:
            # the baro waits for its reference: so does everything after it, or the
            # epoch builder would meet the IMU and the rangefinder before the baro
            # that starts it and drop them
            self._ref_hold = []

    # ------------------------------------------------------------------ GNSS

    def _gps_raw_int(self, f, recv_s, compid) -> None:
        r = decode_gps_raw_int(f, self.cfg.min_fix_type, self.cfg.gnss_altitude)
        if type(r) is Skipped:
            self.stats.filtered[r.counter] += 1
            return
        if r.geoid_sep_m is not None:
            self.refs.geoid_sep_m = r.geoid_sep_m
        if r.time_usec == 0:  # not filled: placed on the vehicle clock by receive time
            self._on_time(self.time.untimed(recv_s, "gnss", r, "GPS_RAW_INT without time"))
            return
        self._on_time(self.time.usec(("GPS_RAW_INT", compid), r.time_usec, recv_s, "GPS_RAW_INT", "gnss", r))

    def _gnss_at(self, r: GnssReading, t_us, recv_s) -> None:
        self._on_refs(self.refs.gnss_altitude(GnssItem(t_us, recv_s, self.clock.boot, r.alt_m, r.sigma_m, r.fix, r.sats)))

    def gnss_ref_msl_m(self) -> Optional[float]:
        """The GNSS reference as an altitude MSL (None: not known yet)."""
        return self.refs.gnss_ref_msl_m()

    def _home_position(self, f, recv_s, compid) -> None:
        self._on_refs(self.refs.home_position(decode_home_position(f).alt_msl_m))

    # ------------------------------------------------------------------ rangefinder

    def _distance_sensor(self, f, recv_s, compid) -> None:
        if f["orientation"] != MAV_SENSOR_ROTATION_PITCH_270:
            self.stats.filtered["range_not_downward"] += 1
            return
        for it in self._noted(self.range_sel, "DISTANCE_SENSOR"):
            self._range_selected(it)
        self.range_checks.cross.note("DISTANCE_SENSOR", f, recv_s)
        self._boot_ms(f["time_boot_ms"] * 1000, recv_s, compid, "distance_sensor", f)

    def _distance_sensor_at(self, f, t_us, recv_s) -> None:
        item = RangeItem(t_us, recv_s, self.clock.boot, "DISTANCE_SENSOR", f)
        for it in self.range_sel.offer("DISTANCE_SENSOR", item):
            self._range_selected(it)

    def _rangefinder(self, f, recv_s, compid) -> None:
        self.range_checks.cross.note("RANGEFINDER", f, recv_s)
        self._on_time(self.time.untimed(recv_s, "rangefinder", f, "RANGEFINDER"))  # no time field: see clock.py

    def _rangefinder_at(self, f, t_us, recv_s) -> None:
        for it in self._noted(self.range_sel, "RANGEFINDER"):
            self._range_selected(it)
        item = RangeItem(t_us, recv_s, self.clock.boot, "RANGEFINDER", f)
        for it in self.range_sel.offer("RANGEFINDER", item):
            self._range_selected(it)

    def _range_selected(self, item) -> None:
        t_us, recv_s, boot, name, f = item
        self.stats.range_source = self.range_sel.chosen
        r = self.range_checks.check(name, f, recv_s, t_us, boot)
        if type(r) is Refusal:
            q = self.att.latest(t_us) if r.kind == "out_of_range" else None
            self._reject(recv_s, r.kind, r.detail, t_us, boot, sensor=RANGE_STREAM, value_m=r.value_m, min_m=r.min_m,
                         max_m=r.max_m, cos_tilt=cos_tilt(down_row_from_quat(q)) if q is not None else math.nan)
            return
        if not self._admit(RANGE_STREAM, t_us, recv_s, boot):
            return
        q = self.att.latest(t_us)
        if q is None:
            self._reject(recv_s, "no_attitude", f"{name}: no attitude for tilt correction", t_us, boot, sensor=RANGE_STREAM)
            return
        c = cos_tilt(down_row_from_quat(q))
        if c < self._cos_max_tilt:
            self._reject(recv_s, "tilt", f"{name}: tilted {math.degrees(math.acos(max(-1.0, min(1.0, c)))):.0f} deg", t_us, boot, sensor=RANGE_STREAM)
            return
        self._yield(RANGE_STREAM, RangeHeight(t_us, recv_s, boot, r.range_m * c, r.range_m, name, r.lo_m, r.hi_m))

    # ------------------------------------------------------------------ autopilot's own height

    def _global_position_int(self, f, recv_s, compid) -> None:
        r = decode_global_position_int(f)
        for it in self._noted(self.ap_sel, "GLOBAL_POSITION_INT"):
            self._ap_selected(it)
        self._boot_ms(r.t_boot_us, recv_s, compid, "global_position_int", r)

    def _global_position_int_at(self, r: GlobalPositionReading, t_us, recv_s) -> None:
        rel_m = r.rel_m  # above the autopilot's home
        if r.home_msl_m is not None:  # a position and home set: the autopilot's home is known
            rel_m, out = self.refs.autopilot_home(t_us, r.alt_msl_m, r.home_msl_m, rel_m, r.vel_up)
            self._on_refs(out)
        item = AutopilotItem(t_us, recv_s, self.clock.boot, r.alt_msl_m, rel_m, r.vel_up)
        for it in self.ap_sel.offer("GLOBAL_POSITION_INT", item):
            self._ap_selected(it)

    def _local_position_ned(self, f, recv_s, compid) -> None:
        r = decode_local_position_ned(f)
        if type(r) is Refusal:
            self._reject(recv_s, r.kind, r.detail)
            return
        for it in self._noted(self.ap_sel, "LOCAL_POSITION_NED"):
            self._ap_selected(it)
        self._boot_ms(r.t_boot_us, recv_s, compid, "local_position_ned", r)

    def _local_position_ned_at(self, r: LocalPositionReading, t_us, recv_s) -> None:
        self._on_refs(self.refs.local_position(t_us, r.up_m, r.vel_up))
        item = AutopilotItem(t_us, recv_s, self.clock.boot, None, r.up_m, r.vel_up)
        for it in self.ap_sel.offer("LOCAL_POSITION_NED", item):
            self._ap_selected(it)

    def _gps_global_origin(self, f, recv_s, compid) -> None:
        self._on_refs(self.refs.ekf_origin(decode_gps_global_origin(f).alt_msl_m))

    def _noted(self, sel: SourceSelector, name: str) -> list:
        """A message of source ``name`` arrived: the items held for the source
        choice it settles, if it does (else none)."""
        return sel.note(name, self.clock.last_t_us) if sel.chosen is None else []

    def _ap_selected(self, item) -> None:
        self.stats.autopilot_source = self.ap_sel.chosen
        self._ap_held.append(item)
        self._ap_release(final=False)

    def _ap_release(self, final: bool) -> None:
        held = self._ap_held
        if not held or (self._ap_mode is None and not self._ap_choose_datum(final)):
            return
        src = self.ap_sel.chosen
        ref_msl = self.gnss_ref_msl_m()
        while held:
            item = held.popleft()
            h = self._ap_height(item, src, ref_msl)
            if h is None:
                self.stats.filtered["autopilot_no_position"] += 1
                continue
            t_us, recv_s, boot = item.t_us, item.recv_s, item.boot
            self._guarded(AUTOPILOT_STREAM, t_us, recv_s, boot, AutopilotHeight(t_us, recv_s, boot, h, src, item.vel_up))

    def _ap_choose_datum(self, final: bool) -> bool:
        """The datum of the autopilot's heights (``stats.autopilot_reference``): the
        GNSS reference once it is known, else, when waiting longer is no use, its
        own (home or EKF origin). False: keep waiting."""
        held = self._ap_held
        src = self.ap_sel.chosen
        ref_msl = self.gnss_ref_msl_m()
        if ref_msl is not None and (src == "GLOBAL_POSITION_INT" or self.refs.ekf_origin_msl_m is not None):
            self._ap_mode = "gnss_reference"
        elif final or held[-1].boot != held[0].boot or held[-1].t_us - held[0].t_us >= self._gnss_wait_us:
            self._ap_mode = "autopilot_home" if src == "GLOBAL_POSITION_INT" else "ekf_origin"
        else:
            return False
        self.stats.autopilot_reference = self._ap_mode
        return True

    def _ap_height(self, item: AutopilotItem, src: str, ref_msl: Optional[float]) -> Optional[float]:
        """One held autopilot height in the chosen datum (None: GLOBAL_POSITION_INT without a position)."""
        if self._ap_mode != "gnss_reference":
            return item.local_up
        if src == "GLOBAL_POSITION_INT":
            return None if item.alt_msl is None else item.alt_msl - ref_msl
        return item.local_up + self.refs.ekf_origin_msl_m - ref_msl

    # ------------------------------------------------------------------ output

    def _admit(self, kind: str, t_us: int, recv_s: float, boot: int) -> bool:
        """Strictly increasing time per (kind, boot); reports a gap before the item."""
        verdict, gap_s = self.guard.check(kind, boot, t_us)
        if verdict != "ok":
            self._reject(recv_s, verdict, f"{kind} at {t_us} us", t_us, boot)
            return False
        if gap_s > 0.0:
            self.stats.gaps.append(GapRecord(kind, t_us, boot, gap_s))
            self._emit(Gap(t_us=t_us, recv_s=recv_s, boot=boot, kind=kind, length_s=gap_s))
        return True

    def _yield(self, kind: str, sample) -> None:
        if self._not_applicable and is_height_input(sample):
            self.stats.filtered["vehicle_class"] += 1
            return
        self.stats.samples[kind] += 1
        hold = self._ref_hold
        if hold is not None:
            hold.append((kind, sample))
            return
        self._pass(kind, sample)

    def _pass(self, kind: str, sample) -> None:
        if kind not in GATED or (self._imu_out and not self._pre_imu):
            self._out.append(sample)
            if kind == IMU_STREAM:
                self._imu_out = True  # what waited joins the output at the end of this frame (_merge_gate)
            return
        held = self._pre_imu
        held.append(sample)
        if sample.boot != held[0].boot or sample.t_us - held[0].t_us > PRE_IMU_HOLD_US:
            self._imu_out = True  # no IMU coming: the epoch builder will say what it could not use
            self._merge_gate()

    def _merge_gate(self) -> None:
        """Measurements that waited for the first IMU sample join the output in time order
        with the IMU samples released meanwhile (often a burst, once its source is chosen)."""
        held = self._pre_imu
        if not held or not self._imu_out:
            return
        self._pre_imu = []
        held.sort(key=_sample_t)
        out = self._out
        merged: List[object] = []
        i, n = 0, len(held)
        boot = held[0].boot
        for item in out:
            if i < n and type(item) is SpecificForceUp and item.boot == boot:
                t = item.t_us
                while i < n and held[i].t_us <= t:
                    merged.append(held[i])
                    i += 1
            merged.append(item)
        merged.extend(held[i:])
        self._out = merged

    def _on_refs(self, out: list) -> None:
        """Pass on what the reference stage releases (see :mod:`.heightref`);
        once the baro reference is known, the samples held while it was pending
        go out with the baro samples, in time order."""
        self._pass_refs(out)
        hold = self._ref_hold
        if hold is not None and self.refs.baro.value is not None:
            self._ref_hold = None
            # the references first (they fix the frame of what follows), then the rest
            # in time order (stable: one stream's samples keep their order, and a
            # gap or a refusal stays before the sample it came with)
            self._out += [x for k, x in hold if k is None and type(x) is ReferenceSet]
            hold.sort(key=_held_order)
            for kind, sample in hold:
                if kind is None:
                    if type(sample) is not ReferenceSet:
                        self._out.append(sample)
                else:
                    self._pass(kind, sample)

    def _pass_refs(self, out: list) -> None:
        for x in out:
            kind = type(x)
            if kind is BaroHeight:
                self._guarded(BARO_STREAM, x.t_us, x.recv_s, x.boot, x)
            elif kind is GnssHeight:
                self._guarded(GNSS_STREAM, x.t_us, x.recv_s, x.boot, x)
            elif x is GNSS_FIXED:
                self._ap_release(final=False)
            else:
                if kind is ReferenceSet:
                    self.stats.references[x.kind] = ReferenceRecord(x.value, x.origin, x.alt_ref_msl_m)
                elif kind is ReferenceMoved:
                    self.stats.reference_moves += 1
                self._emit(x)

    def _guarded(self, kind: str, t_us: int, recv_s: float, boot: int, sample) -> None:
        if self._admit(kind, t_us, recv_s, boot):
            self._yield(kind, sample)

    def _emit(self, event) -> None:
        if self._not_applicable and is_height_input(event):
            self.stats.filtered["vehicle_class"] += 1
            return
        self.stats.events[type(event).__name__] += 1
        hold = self._ref_hold
        if hold is not None and getattr(event, "t_us", None) is not None:
            hold.append((None, event))  # a timed event (a gap, a refusal) keeps its place among the samples
            return
        self._out.append(event)

    def _reject(self, recv_s: float, kind: str, detail: str, t_us: Optional[int] = None, boot: Optional[int] = None,
                sensor: Optional[str] = None, value_m: float = math.nan, min_m: float = math.nan,
                max_m: float = math.nan, cos_tilt: float = math.nan) -> None:
        self.stats.rejected[kind] += 1
        self._emit(Rejected(recv_s=recv_s, kind=kind, detail=detail, t_us=t_us,
                            boot=boot if boot is not None or t_us is None else self.clock.boot, sensor=sensor,
                            value_m=value_m, min_m=min_m, max_m=max_m, cos_tilt=cos_tilt))

    def _finalise_stats(self) -> None:
        st = self.stats
        st.attitude_nearest = self.att.nearest
        st.imu_source = self.imu_sel.chosen
        st.range_source = self.range_sel.chosen
        st.autopilot_source = self.ap_sel.chosen
        st.duration_s = self.clock.total_duration_us / 1e6


def _sample_t(s) -> int:
    return s.t_us


def _held_order(item: tuple) -> tuple:
    sample = item[1]
    return sample.boot, sample.t_us
