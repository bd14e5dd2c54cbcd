"""Commands: only MAV_CMD_SET_MESSAGE_INTERVAL, only with --allow-commands, ACKs checked.

The vehicle is a pymavlink peer on 127.0.0.1 that answers COMMAND_LONG
with COMMAND_ACK according to a per-message policy.
"""

from __future__ import annotations

import logging
import time

import pytest

from mavnav.errors import ConfigError
from mavnav.report import RunSummary
from mavnav.config import config_from_dict
from mavnav.ingest.systems import is_vehicle_heartbeat
from mavnav.sinks.mavlink_commands import is_autopilot_heartbeat, needed_rates, parse_rate
from mavnav.sinks.mavlink_out import MavlinkOutSink
from tests.support.emit import Peer, emit_config, udp_sink
from tests.support.emit import R, autopilot_heartbeat, Autopilot, run_until

pytestmark = [pytest.mark.integration]

ACCEPTED, TEMP, DENIED, UNSUPPORTED, IN_PROGRESS = (
    R.MAV_RESULT_ACCEPTED, R.MAV_RESULT_TEMPORARILY_REJECTED, R.MAV_RESULT_DENIED, R.MAV_RESULT_UNSUPPORTED,
    R.MAV_RESULT_IN_PROGRESS)


@pytest.mark.slow
def test_requests_are_checked_retried_and_refusals_reported(caplog):
    ap_peer = Peer(sysid=1, compid=1)
    specs = ("HIGHRES_IMU:50", "ATTITUDE:40", "SCALED_PRESSURE:20", "GPS_RAW_INT:5", "DISTANCE_SENSOR:10")
    rates = tuple(parse_rate(s) for s in specs)
    ids = {r.name: r.msg_id for r in rates}
    ap = Autopilot(ap_peer, {
        ids["HIGHRES_IMU"]: [ACCEPTED],
        ids["ATTITUDE"]: [UNSUPPORTED],
        ids["SCALED_PRESSURE"]: [None],  # never answers
        ids["GPS_RAW_INT"]: [TEMP, ACCEPTED],
        ids["DISTANCE_SENSOR"]: [(IN_PROGRESS, ACCEPTED)],
    })
    sink = udp_sink(ap_peer, allow_commands=True, message_rates=specs, command_timeout_s=0.15, command_attempts=3)
    try:
        with caplog.at_level(logging.INFO, logger="mavnav.sinks.mavlink_out"):
            sink.start({})
            assert run_until(sink, lambda: sink.requester.done)
            sink.close(RunSummary())  # reports what was not granted
        assert sink.requester.target == (1, 1)
        assert sink.requester.results == {
            "HIGHRES_IMU": "accepted",
            "ATTITUDE": "refused: UNSUPPORTED",
            "SCALED_PRESSURE": "no answer",
            "GPS_RAW_INT": "accepted",
            "DISTANCE_SENSOR": "accepted",
        }
        cmds = ap.commands
        assert {c.command for c in cmds} == {R.MAV_CMD_SET_MESSAGE_INTERVAL}
        assert all((c.get_srcSystem(), c.get_srcComponent()) == (1, 191) for c in cmds)
        assert all((c.target_system, c.target_component) == (1, 1) for c in cmds)
        by_msg = {}
        for c in cmds:
            by_msg.setdefault(int(c.param1), []).append(c)
        assert [len(by_msg[ids[n]]) for n in ids] == [1, 1, 3, 2, 1]
        assert [c.confirmation for c in by_msg[ids["SCALED_PRESSURE"]]] == [0, 1, 2]
        assert by_msg[ids["HIGHRES_IMU"]][0].param2 == 20_000  # interval in us
        assert by_msg[ids["DISTANCE_SENSOR"]][0].param2 == 100_000
        assert all(c.param7 == 0 for c in cmds)  # the flight stack's default address
        warnings = [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING]
        assert "MAVLink output: SET_MESSAGE_INTERVAL ATTITUDE 40 Hz: refused: UNSUPPORTED" in warnings
        assert "MAVLink output: SET_MESSAGE_INTERVAL SCALED_PRESSURE 20 Hz: no answer" in warnings
        assert any("not granted" in w and "SCALED_PRESSURE no answer" in w for w in warnings)
        infos = [r.getMessage() for r in caplog.records if r.levelno == logging.INFO]
        assert "MAVLink output: SET_MESSAGE_INTERVAL HIGHRES_IMU 50 Hz: accepted" in infos
    finally:
        sink.close(RunSummary())
        ap_peer.close()


def test_no_command_without_allow_commands():
    ap_peer = Peer(sysid=1, compid=1)
    ap = Autopilot(ap_peer, {})
    sink = udp_sink(ap_peer)  # allow_commands defaults to False
    try:
        sink.start({})
        assert run_until(sink, lambda: len(ap_peer.of("ALTITUDE")) >= 10)
        assert ap_peer.last_from is not None and ap_peer.of("HEARTBEAT", 191)
        assert not ap.commands and sink.requester is None
        assert {m.get_type() for m in ap_peer.msgs} == {"HEARTBEAT", "ALTITUDE"}
    finally:
        sink.close(RunSummary())
        ap_peer.close()


def test_no_command_before_an_autopilot_is_heard(caplog):
    gcs_peer = Peer(sysid=255, compid=190)
    gcs_peer.handler = lambda p, m: (
        p.send(R.MAVLink_heartbeat_message(R.MAV_TYPE_GCS, R.MAV_AUTOPILOT_INVALID, 0, 0, 0, 3))
        if m.get_type() == "HEARTBEAT" else None)
    sink = udp_sink(gcs_peer, allow_commands=True, command_timeout_s=0.05)
    try:
        sink.start({})
        assert run_until(sink, lambda: len(gcs_peer.of("ALTITUDE")) >= 10)
        assert sink.requester.target is None and not gcs_peer.of("COMMAND_LONG")
        with caplog.at_level(logging.WARNING, logger="mavnav.sinks.mavlink_out"):
            sink.close(RunSummary())
        assert any("no autopilot heard: no message rate was requested" in r.getMessage() for r in caplog.records)
    finally:
        gcs_peer.close()


def test_commands_on_the_input_link_use_the_sources_tap():
    from pymavlink import mavutil

    vehicle = Peer(sysid=3, compid=1)
    ap = Autopilot(vehicle, {})
    link = mavutil.mavlink_connection("udpin:127.0.0.1:0")
    taps = []
    specs = ("HIGHRES_IMU:50", "ATTITUDE:50")
    rates = tuple(parse_rate(s) for s in specs)
    try:
        port = link.port.getsockname()[1]
        vehicle.send(autopilot_heartbeat(), ("127.0.0.1", port))
        sink = MavlinkOutSink(None, emit_config(sysid=3, message_rates=specs, command_timeout_s=0.2),
                              allow_commands=True, use_input_link=True)

        def pump():  # what the live source does with the replies: decode and hand them on
            seen = []
            while True:
                m = link.recv_msg()
                if m is None:
                    return seen
                seen.append(m.get_type())
                if m.get_type() in ("HEARTBEAT", "COMMAND_ACK"):
                    for cb in taps:
                        cb(m)

        deadline = time.monotonic() + 5
        while "HEARTBEAT" not in pump() and time.monotonic() < deadline:
            link.select(0.05)
        sink.start({"link": link, "link_tap": taps.append})
        assert len(taps) == 1
        vehicle.send(autopilot_heartbeat(), ("127.0.0.1", port))  # heard through the tap

        def done():
            pump()
            return sink.requester.done

        assert run_until(sink, done)
        assert sink.requester.results == {"HIGHRES_IMU": "accepted", "ATTITUDE": "accepted"}
        assert [int(c.param1) for c in ap.commands] == [r.msg_id for r in rates]
        assert all(c.target_system == 3 for c in ap.commands)
        sink.close(RunSummary())
    finally:
        link.close()
        vehicle.close()


def test_the_live_source_taps_the_vehicles_heartbeat_and_command_acks():
    """LiveSource.tap: the monitored vehicle's HEARTBEAT and COMMAND_ACK as pymavlink messages, in the
    iterating thread; another autopilot's on the same link are not passed on."""
    import threading

    from mavnav.ingest import LiveSource

    src = LiveSource("udpin:127.0.0.1:0")
    got = []
    src.tap(lambda m: got.append((m.get_type(), m.get_srcSystem(), m.get_srcComponent(),
                                  threading.current_thread().name, m)))
    vehicle, other = Peer(sysid=3, compid=1), Peer(sysid=4, compid=1)
    addr = ("127.0.0.1", src.local_address[1])
    seen = []
    th = threading.Thread(target=lambda: seen.extend(src), name="iterating", daemon=True)
    th.start()
    try:
        vehicle.send(autopilot_heartbeat(), addr)  # the first autopilot heard: the vehicle
        other.send(autopilot_heartbeat(), addr)
        other.send(R.MAVLink_command_ack_message(511, ACCEPTED, 0, 0, 1, 191), addr)
        vehicle.send(R.MAVLink_command_ack_message(511, DENIED, 0, 0, 1, 191), addr)
        deadline = time.monotonic() + 5
        while len(got) < 2 and time.monotonic() < deadline:
            time.sleep(0.01)  # bounded wait for the datagrams to be parsed
    finally:
        src.close()
        th.join(5)
        vehicle.close()
        other.close()
    assert [g[:4] for g in got] == [("HEARTBEAT", 3, 1, "iterating"), ("COMMAND_ACK", 3, 1, "iterating")]
    hb, ack = got[0][4], got[1][4]
    assert hb.autopilot == R.MAV_AUTOPILOT_ARDUPILOTMEGA and hb.type == R.MAV_TYPE_QUADROTOR
    assert (ack.command, ack.result, ack.target_system, ack.target_component) == (511, DENIED, 1, 191)
    assert src.stats.vehicle.sysid == 3


def test_input_link_without_a_tap_sends_no_command(caplog):
    from pymavlink import mavutil

    vehicle = Peer(sysid=1, compid=1)
    ap = Autopilot(vehicle, {})
    link = mavutil.mavlink_connection("udpin:127.0.0.1:0")
    try:
        vehicle.send(autopilot_heartbeat(), ("127.0.0.1", link.port.getsockname()[1]))
        deadline = time.monotonic() + 5
        while link.recv_match(type="HEARTBEAT", blocking=True, timeout=0.1) is None and time.monotonic() < deadline:
            pass
        sink = MavlinkOutSink(None, allow_commands=True, use_input_link=True)
        with caplog.at_level(logging.WARNING, logger="mavnav.sinks.mavlink_out"):
            sink.start({"link": link})
        assert any("link_tap" in r.getMessage() for r in caplog.records)
        assert run_until(sink, lambda: len(vehicle.of("ALTITUDE", 191)) >= 10)
        assert not ap.commands
        sink.close(RunSummary())
    finally:
        link.close()
        vehicle.close()


@pytest.mark.parametrize("spec,match", [
    ("HIGHRES_IMU", "NAME:HZ"), ("NO_SUCH_MSG:5", "no MAVLink message named NO_SUCH_MSG"),
    ("ATTITUDE:fast", "not a number"), ("ATTITUDE:0", r"\(0, 1000\]"), ("ATTITUDE:nan", r"\(0, 1000\]"),
])
def test_wrong_rate_requests_are_refused_by_name(spec, match):
    with pytest.raises(ConfigError, match=match):
        parse_rate(spec)


def test_needed_rates_are_the_streams_the_monitor_reads_at_the_rates_the_config_needs():
    px4 = needed_rates(config_from_dict({}), R.MAV_AUTOPILOT_PX4)
    assert [(r.name, r.msg_id, r.rate_hz) for r in px4] == [
        ("HIGHRES_IMU", 105, 50.0), ("ATTITUDE", 30, 50.0), ("SCALED_PRESSURE", 29, 20.0),
        ("GPS_RAW_INT", 24, 5.0), ("DISTANCE_SENSOR", 132, 20.0)]
    # ArduPilot fills RAW_IMU (in milli-g): the IMU the normaliser uses there
    ap = needed_rates(config_from_dict({}), R.MAV_AUTOPILOT_ARDUPILOTMEGA)
    assert [r.name for r in ap] == ["RAW_IMU", "ATTITUDE", "SCALED_PRESSURE", "GPS_RAW_INT", "DISTANCE_SENSOR"]
    # the configured sources, and a stricter time-to-alarm asks for more: 4 rejections in 0.5 s
    # need 8 Hz of GNSS and rangefinder, times the margin 1.25
    cfg = config_from_dict({"monitor": {"time_to_alarm_s": 0.5},
                            "ingest": {"baro_instance": 2, "imu_source": "SCALED_IMU2", "range_source": "RANGEFINDER"},
                            "emit": {"request": {"range_rate_hz": 5.0}}})
    strict = {r.name: r.rate_hz for r in needed_rates(cfg, R.MAV_AUTOPILOT_ARDUPILOTMEGA)}
    assert strict == {"SCALED_IMU2": 50.0, "ATTITUDE": 50.0, "SCALED_PRESSURE2": 20.0, "GPS_RAW_INT": 10.0,
                      "RANGEFINDER": 10.0}
    assert parse_rate("rangefinder:10").msg_id == 173  # ArduPilot's dialect too


def test_the_command_target_is_the_vehicle_rule_without_companion_computers():
    # the sink's rule before it was the normaliser's: every type and autopilot value decides the same
    not_targets = {R.MAV_TYPE_GCS, R.MAV_TYPE_ONBOARD_CONTROLLER}
    for mav_type in range(R.MAV_TYPE_ENUM_END):
        for autopilot in range(R.MAV_AUTOPILOT_ENUM_END):
            hb = R.MAVLink_heartbeat_message(mav_type, autopilot, 0, 0, 0, 3)
            assert is_autopilot_heartbeat(hb) == (autopilot != R.MAV_AUTOPILOT_INVALID and mav_type not in not_targets)
    # a companion computer that names an autopilot: the normaliser's vehicle, never the commands' target
    companion = R.MAVLink_heartbeat_message(R.MAV_TYPE_ONBOARD_CONTROLLER, R.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 0, 0, 3)
    assert is_vehicle_heartbeat({"type": companion.type, "autopilot": companion.autopilot})
    assert not is_autopilot_heartbeat(companion)
    assert not is_autopilot_heartbeat(R.MAVLink_attitude_message(0, 0, 0, 0, 0, 0, 0))


def _heard_from(sysid: int, msg):
    """``msg`` as the link decodes it from system ``sysid`` (real pymavlink framing)."""
    frame = msg.pack(R.MAVLink(None, srcSystem=sysid, srcComponent=1))
    return R.MAVLink(None).parse_char(frame)


@pytest.mark.unit
def test_the_commands_go_to_the_autopilot_of_the_system_the_monitor_watches():
    """Two vehicles on one link: with ``--sysid 2`` the rate requests go to
    system 2's autopilot, though system 1's is heard first; without it, to the
    first autopilot heard."""
    from mavnav.sinks.mavlink_commands import IntervalRequester

    rates = [parse_rate("HIGHRES_IMU:50")]
    for vehicle, expected in ((2, (2, 1)), (None, (1, 1))):
        req = IntervalRequester(rates, (1, 191), vehicle_sysid=vehicle)
        for sysid in (1, 2):
            req.on_message(_heard_from(sysid, autopilot_heartbeat()), 0.0)
        assert req.target == expected
        cmd = req.poll(0.0)
        assert (cmd.target_system, cmd.target_component) == expected


@pytest.mark.unit
def test_the_run_hands_its_sysid_to_the_command_sink():
    from mavnav.cli.run import build_sinks
    from mavnav.config import ViewerSection

    peer = Peer()
    try:
        flags = {"emit": peer.url, "allow_commands": True}
        sinks = build_sinks(config_from_dict({}), None, True, ViewerSection(), flags, 7)
        [out] = [s for s in sinks if isinstance(s, MavlinkOutSink)]
        assert out.requester is not None and out.requester.vehicle_sysid == 7
        for s in sinks:
            s.close(RunSummary())
    finally:
        peer.close()
