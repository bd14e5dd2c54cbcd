"""The systems on a link: which heartbeat is a vehicle's, what they are in
words, and what the operator is told about the systems not monitored.

The normaliser chooses the vehicle (the first heartbeat for which
:func:`is_vehicle_heartbeat` holds, or the ``sysid`` asked for: see its
docstring, "Vehicle"); :class:`OtherSystems` remembers every other system
heard and returns the :class:`~mavnav.samples.Notice` to give about them,
once each: an ignored system (when its heartbeat came, or after
:data:`OTHER_FRAMES_BEFORE_SAYING` frames without one, or, for those heard
before, when the vehicle is chosen), and, on a live link, what is awaited
while no heartbeat of the vehicle came.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, List, NamedTuple, Optional

from ..samples import Notice
from . import wire

MAV_AUTOPILOT_ARDUPILOTMEGA = 3
MAV_AUTOPILOT_PX4 = 12
MAV_AUTOPILOT_INVALID = 8
MAV_TYPE_GCS = 6
MAV_TYPE_ONBOARD_CONTROLLER = 18  # a companion computer (mavnav's own heartbeat says it is one)
HEARTBEAT = wire.MSG_ID["HEARTBEAT"]
WAIT_HEARTBEAT_S = 2.0  # live: no vehicle heartbeat this long after starting: say what is awaited
WAIT_HEARTBEAT_REPEAT_S = 10.0  # and again this often
OTHER_FRAMES_BEFORE_SAYING = 20  # another system without a heartbeat is said after this many frames


def is_vehicle_heartbeat(f: dict, *, onboard_controller: bool = True) -> bool:
    """A HEARTBEAT (its fields) from an autopilot that is not a ground station.

    ``onboard_controller=False``: nor a companion computer that names an
    autopilot (the target of mavnav's commands must be the autopilot itself;
    the normaliser's choice of the vehicle keeps the default).
    """
    return (f["autopilot"] != MAV_AUTOPILOT_INVALID and f["type"] != MAV_TYPE_GCS
            and (onboard_controller or f["type"] != MAV_TYPE_ONBOARD_CONTROLLER))


def describe_system(mav_type: int, autopilot: int) -> str:
    """``quadrotor, ArduPilot``: a HEARTBEAT's type and autopilot in words."""
    def word(enum: str, value: int, prefix: str) -> str:
        e = wire.ENUMS.get(enum, {}).get(value)
        return e.name[len(prefix):].lower().replace("_", " ") if e is not None else f"{enum.lower()} {value}"

    ap = {MAV_AUTOPILOT_ARDUPILOTMEGA: "ArduPilot", MAV_AUTOPILOT_PX4: "PX4", MAV_AUTOPILOT_INVALID: "no autopilot"}.get(
        autopilot) or word("MAV_AUTOPILOT", autopilot, "MAV_AUTOPILOT_")
    if mav_type == MAV_TYPE_GCS:
        return "ground station"
    return f"{word('MAV_TYPE', mav_type, 'MAV_TYPE_')}, {ap}"


class Heartbeat(NamedTuple):
    type: int  # MAV_TYPE
    autopilot: int  # MAV_AUTOPILOT


@dataclass
class OtherSystem:
    """Another system heard on the link: its frames, its heartbeat if one came, said yet."""

    frames: int = 0
    heartbeat: Optional[Heartbeat] = None
    said: bool = False


class OtherSystems:
    """The systems heard that are not (or not yet) the vehicle, and what is said about them."""

    def __init__(self, link_name: str, decode_heartbeat: Callable[[bytes], dict]):
        self.link_name = link_name
        self._decode_heartbeat = decode_heartbeat
        self.heard: dict[int, OtherSystem] = {}  # by sysid
        self._wait_t0: Optional[float] = None  # receive time of the first tick (live)
        self._wait_next: Optional[float] = None

    def frame(self, recv_s: float, msgid: int, sysid: int, payload: bytes,
              vehicle: Optional[int]) -> Optional[Notice]:
        """A frame of system ``sysid``; ``vehicle``: the monitored system once its
        heartbeat came (None before). Returns the notice it is time to give."""
        o = self.heard.get(sysid)
        if o is None:
            o = self.heard[sysid] = OtherSystem()
        o.frames += 1
        if msgid == HEARTBEAT and o.heartbeat is None:
            try:
                hb = self._decode_heartbeat(payload)
                o.heartbeat = Heartbeat(hb["type"], hb["autopilot"])
            except Exception:
                pass
        if vehicle is not None and not o.said and (
                o.heartbeat is not None or o.frames >= OTHER_FRAMES_BEFORE_SAYING):
            return self._ignored(recv_s, sysid, vehicle)
        return None

    def vehicle_chosen(self, recv_s: float, vehicle: int) -> List[Notice]:
        """The vehicle's heartbeat came: every other system heard before is said."""
        self.heard.pop(vehicle, None)  # heard before it was chosen
        out = []
        for sid in sorted(self.heard):
            n = self._ignored(recv_s, sid, vehicle, final=True)
            if n is not None:
                out.append(n)
        return out

    def _ignored(self, recv_s: float, sysid: int, vehicle: int, final: bool = False) -> Optional[Notice]:
        o = self.heard[sysid]
        if o.said or (o.heartbeat is None and not final and o.frames < OTHER_FRAMES_BEFORE_SAYING):
            return None
        o.said = True
        if o.heartbeat is None:
            what, hint = "no heartbeat heard", f"; --sysid {sysid} to monitor it instead"
        else:
            what = describe_system(*o.heartbeat)
            hint = f"; --sysid {sysid} to monitor it instead" if is_vehicle_heartbeat(o.heartbeat._asdict()) else ""
        return Notice(recv_s, "ignored", f"ignoring system {sysid} ({what}): not the monitored vehicle "
                                         f"(system {vehicle}){hint}")

    def waiting(self, now_s: float, sysid: Optional[int], asked: bool, data_arrived: bool) -> Optional[Notice]:
        """Live, while no heartbeat of the vehicle came: what is awaited, after
        :data:`WAIT_HEARTBEAT_S` and then every :data:`WAIT_HEARTBEAT_REPEAT_S`."""
        if self._wait_t0 is None:
            self._wait_t0 = now_s
            self._wait_next = now_s + WAIT_HEARTBEAT_S
            return None
        if now_s < self._wait_next:
            return None
        self._wait_next = now_s + WAIT_HEARTBEAT_REPEAT_S
        heard = [f"system {sid} ({describe_system(*o.heartbeat) if o.heartbeat else 'no heartbeat'})"
                 for sid, o in sorted(self.heard.items())]
        what = f"a heartbeat from system {sysid}" if asked else "an autopilot heartbeat"
        since = f"{now_s - self._wait_t0:.0f} s"
        if heard:
            text = f"waiting for {what} on {self.link_name} ({since}); heard only " + ", ".join(heard)
        elif asked and data_arrived:
            text = f"waiting for {what} on {self.link_name} ({since}); its data arrive, its heartbeat not"
        else:
            text = f"waiting for a heartbeat on {self.link_name} ({since}): nothing received yet"
        return Notice(now_s, "waiting_heartbeat", text)
