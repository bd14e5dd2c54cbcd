"""The systems on a link (mavnav.ingest.systems): which heartbeat is a vehicle's,
and what is said, once, about the others."""

from __future__ import annotations

from mavnav.ingest.systems import (HEARTBEAT, OTHER_FRAMES_BEFORE_SAYING, OtherSystems, describe_system,
                                   is_vehicle_heartbeat)

GCS = {"type": 6, "autopilot": 8}
QUAD_APM = {"type": 2, "autopilot": 3}


def _systems():
    return OtherSystems("udp:14550", lambda payload: payload)  # the "payload" is the decoded fields here


def test_which_heartbeat_is_a_vehicle():
    assert is_vehicle_heartbeat(QUAD_APM)
    assert not is_vehicle_heartbeat(GCS)
    assert not is_vehicle_heartbeat({"type": 2, "autopilot": 8})
    companion = {"type": 18, "autopilot": 3}  # MAV_TYPE_ONBOARD_CONTROLLER naming ArduPilot
    assert is_vehicle_heartbeat(companion)  # the normaliser's choice: unchanged
    assert not is_vehicle_heartbeat(companion, onboard_controller=False)  # the commands' target
    assert is_vehicle_heartbeat(QUAD_APM, onboard_controller=False)
    assert not is_vehicle_heartbeat(GCS, onboard_controller=False)
    assert describe_system(2, 3) == "quadrotor, ArduPilot"
    assert describe_system(6, 8) == "ground station"


def test_another_system_is_said_once_when_its_heartbeat_comes():
    s = _systems()
    assert s.frame(1.0, HEARTBEAT, 255, GCS, vehicle=None) is None  # no vehicle yet: nothing to say
    [n] = s.vehicle_chosen(1.5, vehicle=1)
    assert n.kind == "ignored" and n.text == ("ignoring system 255 (ground station): not the monitored vehicle "
                                              "(system 1)")
    assert s.frame(2.0, HEARTBEAT, 255, GCS, vehicle=1) is None  # said already
    n = s.frame(2.0, HEARTBEAT, 7, QUAD_APM, vehicle=1)
    assert n.text.endswith("(quadrotor, ArduPilot): not the monitored vehicle (system 1); --sysid 7 to monitor "
                           "it instead")


def test_a_silent_system_is_said_after_some_frames():
    s = _systems()
    said = [s.frame(1.0 + k, 0, 9, b"", vehicle=1) for k in range(OTHER_FRAMES_BEFORE_SAYING)]
    assert said[:-1] == [None] * (OTHER_FRAMES_BEFORE_SAYING - 1)
    assert "system 9 (no heartbeat heard)" in said[-1].text


def test_waiting_for_the_vehicles_heartbeat():
    s = _systems()
    assert s.waiting(100.0, None, False, False) is None  # the first tick starts the wait
    assert s.waiting(101.0, None, False, False) is None
    n = s.waiting(102.0, None, False, False)
    assert n.kind == "waiting_heartbeat" and n.text == "waiting for a heartbeat on udp:14550 (2 s): nothing received yet"
    assert s.waiting(103.0, None, False, False) is None  # then every 10 s
    s.frame(104.0, HEARTBEAT, 255, GCS, vehicle=None)
    n = s.waiting(112.0, 3, True, True)
    assert n.text == ("waiting for a heartbeat from system 3 on udp:14550 (12 s); heard only system 255 "
                      "(ground station)")
