"""MAVLink output sink: what a pymavlink peer on 127.0.0.1 receives and decodes.

The peer and the hand-made reports are in :mod:`tests.support.emit`.
"""

from __future__ import annotations

import logging
import math
import socket
import time

import numpy as np
import pytest
from pymavlink.dialects.v20 import common as mavlink2

from mavnav.cli.emit_options import open_link
from mavnav.report import RunSummary
from mavnav.samples import LinkLost, Reboot, ReferenceSet
from mavnav.sinks.base import SinkSet
from mavnav.sinks.mavlink_out import DEBUG_NAMES, MavlinkOutSink
from tests.support.emit import F32, Peer, emit_config, event, feed, report, reports_every, texts_of, udp_sink

pytestmark = [pytest.mark.integration]


# --------------------------------------------------------------------------- heartbeat


def test_heartbeat_is_an_onboard_controller_at_1hz_of_vehicle_time(peer):
    sink = udp_sink(peer, sysid=42, compid=191)
    sink.start({})
    feed(sink, reports_every(0.02, 5.0))  # vehicle t = 0 .. 4.98 s
    sink.close(RunSummary())
    assert peer.wait_for(lambda: len(peer.of("ALTITUDE")) == 25)
    hbs = peer.of("HEARTBEAT")
    assert len(hbs) == 1 + 5  # one at start, then t = 0, 1, 2, 3, 4 s
    for hb in hbs:
        assert hb.type == mavlink2.MAV_TYPE_ONBOARD_CONTROLLER
        assert hb.autopilot == mavlink2.MAV_AUTOPILOT_INVALID
        assert hb.get_srcSystem() == 42 and hb.get_srcComponent() == 191
        assert hb.base_mode == 0 and hb.custom_mode == 0
    assert hbs[0].system_status == mavlink2.MAV_STATE_STANDBY
    assert {hb.system_status for hb in hbs[1:]} == {mavlink2.MAV_STATE_ACTIVE}
    assert all(len(m.get_msgbuf()) == 10 + m.get_header().mlen + 2 for m in hbs)  # whole unsigned frames
    assert all(m.get_msgbuf()[0] == 0xFD for m in hbs)  # MAVLink 2 frames


def test_heartbeat_reports_critical_in_alarm(peer):
    sink = udp_sink(peer)
    sink.start({})
    feed(sink, [report(0), report(1_000_000, overall="alarm"), report(2_000_000, overall="caution")])
    assert peer.wait_for(lambda: len(peer.of("HEARTBEAT")) == 4)
    assert [h.system_status for h in peer.of("HEARTBEAT")] == [
        mavlink2.MAV_STATE_STANDBY, mavlink2.MAV_STATE_ACTIVE, mavlink2.MAV_STATE_CRITICAL, mavlink2.MAV_STATE_ACTIVE]


def test_compid_of_the_autopilot_is_refused():
    from mavnav.errors import ConfigError

    with pytest.raises(ConfigError, match="autopilot"):
        emit_config(compid=1)


# --------------------------------------------------------------------------- ALTITUDE


@pytest.mark.parametrize("rate_hz,epoch_dt_s", [(5.0, 0.02), (2.0, 0.02), (10.0, 0.01), (4.0, 0.0333)])
def test_altitude_at_the_configured_rate_of_vehicle_time(peer, rate_hz, epoch_dt_s):
    sink = udp_sink(peer, altitude_rate_hz=rate_hz)
    sink.start({})
    fed = feed(sink, reports_every(epoch_dt_s, 6.0, t0_s=100.0))
    span_s = (fed[-1].t_us - fed[0].t_us) * 1e-6
    expected = int(math.floor(span_s * rate_hz + 1e-9)) + 1
    assert peer.wait_for(lambda: len(peer.of("ALTITUDE")) >= expected)
    sink.close(RunSummary())
    alts = peer.of("ALTITUDE")
    assert abs(len(alts) - expected) <= 1
    t = np.array([a.time_usec for a in alts], dtype=np.int64)
    gaps = np.diff(t) * 1e-6
    assert np.all(gaps >= 1 / rate_hz - epoch_dt_s - 1e-6) and np.all(gaps <= 1 / rate_hz + epoch_dt_s + 1e-6)
    assert abs(np.mean(gaps) - 1 / rate_hz) < epoch_dt_s / 2


def test_altitude_values_equal_the_reports_fed(peer):
    sink = udp_sink(peer, altitude_rate_hz=50.0)  # every epoch at 50 Hz
    sink.start({})
    sink.sample(ReferenceSet(t_us=0, recv_s=0.0, boot=0, kind="baro", value=101325.0, alt_ref_msl_m=None,
                             origin="startup"))
    sink.sample(ReferenceSet(t_us=0, recv_s=0.0, boot=0, kind="gnss", value=480.0, alt_ref_msl_m=480.25,
                             origin="home"))
    fed = [report(k * 20_000, h=3.0 + 0.37 * k, sigma=0.2 + 0.01 * k, baro_h=4.0 + 0.1 * k,
                  rng_agl=2.0 + 0.3 * k, rng_h=2.1 + 0.3 * k) for k in range(20)]
    fed.append(report(20 * 20_000, h=9.0, rng="alarm"))
    fed.append(report(21 * 20_000, h=math.nan, rng="unavailable"))
    feed(sink, fed)
    assert peer.wait_for(lambda: len(peer.of("ALTITUDE")) == len(fed))
    for r, a in zip(fed, peer.of("ALTITUDE")):
        assert a.get_srcComponent() == 191
        assert a.time_usec == r.t_us
        h = F32(r.height_fused_m)
        np.testing.assert_equal(F32(a.altitude_local), h)
        np.testing.assert_equal(F32(a.altitude_relative), h)
        np.testing.assert_equal(F32(a.altitude_amsl), F32(480.25 + r.height_fused_m))
        np.testing.assert_equal(F32(a.altitude_monotonic), F32(r.baro_height_ref_m))
        if r.ok("rangefinder"):
            np.testing.assert_equal(F32(a.altitude_terrain), F32(r.channels[1].height_ref_m))
            np.testing.assert_equal(F32(a.bottom_clearance), F32(r.range_height_agl_m))
        else:
            assert math.isnan(a.altitude_terrain) and math.isnan(a.bottom_clearance)
    assert math.isnan(peer.of("ALTITUDE")[-1].altitude_local)


def test_altitude_amsl_is_nan_without_a_known_reference_and_after_a_reboot(peer):
    sink = udp_sink(peer, altitude_rate_hz=50.0)
    sink.start({})
    sink.epoch(report(0))
    sink.sample(ReferenceSet(t_us=20_000, recv_s=0.0, boot=0, kind="baro", value=1e5, alt_ref_msl_m=100.0,
                             origin="config"))
    sink.epoch(report(20_000, h=5.0))
    sink.sample(Reboot(t_us=1000, recv_s=1.0, boot=1, last_t_us=40_000))
    sink.epoch(report(1000, h=6.0, boot=1))
    assert peer.wait_for(lambda: len(peer.of("ALTITUDE")) == 3)
    a = peer.of("ALTITUDE")
    assert math.isnan(a[0].altitude_amsl) and a[1].altitude_amsl == 105.0 and math.isnan(a[2].altitude_amsl)
    assert a[2].time_usec == 1000  # the decimation restarted with the vehicle clock


# --------------------------------------------------------------------------- STATUSTEXT


@pytest.mark.parametrize("state,previous,severity", [
    ("alarm", "nominal", mavlink2.MAV_SEVERITY_CRITICAL),
    ("unavailable", "nominal", mavlink2.MAV_SEVERITY_ERROR),
    ("caution", "nominal", mavlink2.MAV_SEVERITY_WARNING),
    ("nominal", "alarm", mavlink2.MAV_SEVERITY_NOTICE),
])
def test_statustext_severity_names_the_source(peer, state, previous, severity):
    sink = udp_sink(peer)
    sink.start({})
    feed(sink, [report(2_900_000)])  # the rangefinder has been in use: no longer starting
    reason = "range disagrees with GNSS and baro by 4.2 m over 1.0 s"
    sink.alarm(event(3.0, source="rangefinder", state=state, previous=previous, reason=reason))
    assert peer.wait_for(lambda: len(peer.of("STATUSTEXT")) == 2)
    msgs = peer.of("STATUSTEXT")
    assert all(m.severity == severity and m.get_srcComponent() == 191 for m in msgs)
    # too long for one message: MAVLink 2 chunks, cut between words, never mid-word
    assert msgs[0].id == msgs[1].id != 0 and [m.chunk_seq for m in msgs] == [0, 1]
    whole = f"mavnav rangefinder {state.upper()}: {reason}"
    # every chunk but the last fills the field (a NUL would end the text there), padded between words
    assert len(msgs[0].text) == 50 and len(msgs[1].text) < 50
    assert whole.split() == msgs[0].text.split() + msgs[1].text.split()
    assert [t.text for t in texts_of(peer.msgs)] == [whole]


def test_statustext_that_fits_is_one_message_with_id_zero(peer):
    sink = udp_sink(peer)
    sink.start({})
    sink.alarm(event(3.0, "gnss", "alarm", "caution", reason="step 9 m"))
    assert peer.wait_for(lambda: len(peer.of("STATUSTEXT")) == 1)
    m = peer.of("STATUSTEXT")[0]
    assert (m.text, m.id, m.chunk_seq) == ("mavnav gnss ALARM: step 9 m", 0, 0)


def test_unavailable_at_start_up_is_info_not_error(peer):
    """At start-up sources wait for their first data: that is not an error. Once a
    source has been in use, losing it is; alarms stay CRITICAL from the start."""
    sink = udp_sink(peer, statustext_interval_s=0.0)
    sink.start({})
    # first epoch: no rangefinder data yet
    sink.alarm(event(0.05, "rangefinder", "unavailable", "nominal", reason="no recent data"))
    feed(sink, [report(50_000, rng="unavailable")])
    feed(sink, [report(100_000, rng="unavailable")])
    sink.alarm(event(0.15, "gnss", "alarm", "nominal", reason="step 9 m"))
    sink.alarm(event(3.0, "rangefinder", "nominal", "unavailable", reason="consistent"))
    feed(sink, [report(3_000_000)])
    sink.alarm(event(9.0, "rangefinder", "unavailable", "nominal", reason="no recent data"))
    # a reboot: the new boot starts up again
    sink.alarm(event(0.05, "rangefinder", "unavailable", "nominal", reason="no recent data", boot=1))
    assert peer.wait_for(lambda: len(peer.of("STATUSTEXT")) == 5)
    got = [(t.text, t.severity) for t in texts_of(peer.msgs)]
    assert got == [
        ("mavnav rangefinder STARTING: no recent data", mavlink2.MAV_SEVERITY_INFO),
        ("mavnav gnss ALARM: step 9 m", mavlink2.MAV_SEVERITY_CRITICAL),
        ("mavnav rangefinder NOMINAL: consistent", mavlink2.MAV_SEVERITY_NOTICE),
        ("mavnav rangefinder UNAVAILABLE: no recent data", mavlink2.MAV_SEVERITY_ERROR),
        ("mavnav rangefinder STARTING: no recent data", mavlink2.MAV_SEVERITY_INFO),
    ]


def test_statustext_rate_limit_coalesces_and_keeps_the_latest_state(peer):
    sink = udp_sink(peer, statustext_interval_s=1.0)
    sink.start({})
    sink.alarm(event(10.0, "gnss", "caution", "nominal"))          # sent at once
    sink.alarm(event(10.1, "gnss", "alarm", "caution"))            # held
    sink.alarm(event(10.2, "gnss", "caution", "alarm"))            # replaces it
    sink.alarm(event(10.3, "rangefinder", "alarm", "nominal"))     # another source: not delayed
    sink.alarm(event(10.4, "gnss", "alarm", "caution", reason="step 9 m"))  # the latest gnss state
    assert peer.wait_for(lambda: len(peer.of("STATUSTEXT")) == 2)
    feed(sink, [report(int(t * 1e6)) for t in np.arange(10.4, 10.99, 0.02)])
    time.sleep(0.05)  # bounded check that nothing else went out before the interval passed
    assert len(peer.of("STATUSTEXT")) == 2
    feed(sink, [report(11_000_000)])  # the gnss interval has passed
    assert peer.wait_for(lambda: len(peer.of("STATUSTEXT")) == 3)
    texts = [m.text for m in peer.of("STATUSTEXT")]
    assert texts[0].startswith("mavnav gnss CAUTION")
    assert texts[1].startswith("mavnav rangefinder ALARM")
    assert texts[2] == "mavnav gnss ALARM (+2): step 9 m"
    assert peer.of("STATUSTEXT")[2].severity == mavlink2.MAV_SEVERITY_CRITICAL
    # a pending change is flushed at the end of the run
    sink.alarm(event(11.1, "gnss", "nominal", "alarm", reason="consistent again"))
    sink.close(RunSummary())
    assert peer.wait_for(lambda: len(peer.of("STATUSTEXT")) == 4)
    assert peer.of("STATUSTEXT")[3].text == "mavnav gnss NOMINAL: consistent again"


def test_pending_statustext_goes_out_on_link_loss(peer):
    sink = udp_sink(peer, statustext_interval_s=5.0)
    sink.start({})
    sink.alarm(event(1.0, "input", "caution", "nominal", reason="IMU 8 Hz < 25 Hz"))
    sink.alarm(event(1.5, "input", "alarm", "caution", reason="link lost"))
    assert peer.wait_for(lambda: len(peer.of("STATUSTEXT")) == 1)
    sink.sample(LinkLost(recv_s=100.0, silent_s=3.0))
    assert peer.wait_for(lambda: len(peer.of("STATUSTEXT")) == 3)
    assert peer.of("STATUSTEXT")[1].text == "mavnav input ALARM: link lost"
    # then the loss itself, at once (the receive clock's timeout, not the next epoch)
    lost = texts_of(peer.msgs)[2]
    assert lost.text == "mavnav input LINK LOST: no data for 3.0 s"
    assert lost.severity == mavlink2.MAV_SEVERITY_ERROR


# --------------------------------------------------------------------------- optional messages


def test_debug_values_and_fusable_are_off_by_default(peer):
    sink = udp_sink(peer)
    sink.start({})
    feed(sink, reports_every(0.02, 1.0))
    assert peer.wait_for(lambda: len(peer.of("ALTITUDE")) == 5)
    assert not peer.of("NAMED_VALUE_FLOAT") and not peer.of("ODOMETRY")
    assert {m.get_type() for m in peer.msgs} == {"HEARTBEAT", "ALTITUDE"}


def test_debug_named_values(peer):
    sink = udp_sink(peer, debug_values=True, altitude_rate_hz=1.0)
    sink.start({})
    r = report(2_500_000)
    sink.epoch(r)
    assert peer.wait_for(lambda: len(peer.of("NAMED_VALUE_FLOAT")) == len(DEBUG_NAMES))
    got = {m.name: m for m in peer.of("NAMED_VALUE_FLOAT")}
    assert set(got) == set(DEBUG_NAMES) and all(len(n) <= 10 for n in got)
    assert all(m.time_boot_ms == 2500 for m in got.values())
    assert got["nis_rng"].value == r.channels[1].nis
    assert got["dH_gns_bar"].value == r.pairs[1].diff_m
    assert got["win_gnss"].value == r.sources["gnss"].window_stat
    np.testing.assert_equal(F32(got["sig_fused"].value), F32(r.sigma_fused_m))
    assert got["vpl"].value == r.vpl_m


def test_odometry_carries_height_and_variance_and_fails_in_alarm(peer):
    sink = udp_sink(peer, fusable=True, altitude_rate_hz=50.0)
    sink.start({})
    feed(sink, [report(0, h=12.5, sigma=0.4), report(20_000, h=12.75, sigma=0.5, overall="alarm"),
                report(40_000, h=math.nan, sigma=math.nan, overall="unavailable")])
    assert peer.wait_for(lambda: len(peer.of("ODOMETRY")) == 3)
    ok, alarm, lost = peer.of("ODOMETRY")
    assert ok.z == -12.5 and F32(ok.pose_covariance[11]) == F32(0.4 * 0.4) and ok.quality == 100
    assert ok.frame_id == mavlink2.MAV_FRAME_LOCAL_NED and ok.time_usec == 0
    assert math.isinf(ok.pose_covariance[0]) and math.isnan(ok.x) and math.isnan(ok.vz)
    assert ok.estimator_type == mavlink2.MAV_ESTIMATOR_TYPE_UNKNOWN
    assert alarm.z == -12.75 and alarm.quality == -1 and math.isinf(alarm.pose_covariance[11])
    assert math.isnan(lost.z) and lost.quality == -1


# --------------------------------------------------------------------------- the input link


def test_emit_input_writes_back_to_the_live_link():
    from pymavlink import mavutil

    vehicle = Peer(sysid=1, compid=1)
    link = mavutil.mavlink_connection("udpin:127.0.0.1:0")
    try:
        port = link.port.getsockname()[1]
        # the vehicle talks first, as on a real link; the source (here: us) reads it
        vehicle.send(mavlink2.MAVLink_heartbeat_message(2, 3, 0, 0, 4, 3), ("127.0.0.1", port))
        deadline = time.monotonic() + 5
        while time.monotonic() < deadline and link.recv_match(type="HEARTBEAT", blocking=True, timeout=0.1) is None:
            pass
        sink = MavlinkOutSink(None, use_input_link=True)
        sink.start({"link": link})
        feed(sink, reports_every(0.02, 0.5))
        assert vehicle.wait_for(lambda: len(vehicle.of("ALTITUDE", compid=191)) == 3)
        assert vehicle.of("HEARTBEAT", compid=191)[0].type == mavlink2.MAV_TYPE_ONBOARD_CONTROLLER
        sink.close(RunSummary())
        assert link.port.fileno() >= 0  # not ours to close
    finally:
        link.close()
        vehicle.close()


def test_emit_input_without_a_live_link_is_reported_and_dropped():
    summary = RunSummary()
    sinks = SinkSet([MavlinkOutSink(None, use_input_link=True)], summary)
    sinks.start({"mode": "adaptive"})
    assert not sinks.active
    assert "live input link" in summary.sink_failures["mavlink-out"]


# --------------------------------------------------------------------------- failing sends


def test_closed_socket_is_reported_once_and_the_monitor_goes_on(peer, caplog):
    sink = udp_sink(peer)
    summary = RunSummary()
    sinks = SinkSet([sink], summary)
    sinks.start({})
    sinks.epoch(report(0))
    assert peer.wait_for(lambda: len(peer.of("ALTITUDE")) == 1)
    sink._link.port.close()  # the socket goes away under the sink
    with caplog.at_level(logging.WARNING, logger="mavnav.sinks.mavlink_out"):
        for r in reports_every(0.02, 3.0, t0_s=1.0):
            sinks.epoch(r)
        sinks.alarm(event(2.0))
        sinks.close()
    warnings = [r for r in caplog.records if "send failed" in r.getMessage()]
    assert len(warnings) == 1 and "socket closed" in warnings[0].getMessage()
    assert sinks.active == [sink] and not summary.sink_failures
    assert sink.writer.failures >= 15 + 3 + 1 and sink.writer.outages == 1


def _tcp_server(port: int = 0) -> socket.socket:
    srv = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    srv.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    srv.bind(("127.0.0.1", port))
    srv.listen(1)
    srv.settimeout(5)
    return srv


def test_tcp_peer_gone_is_reported_once_and_sending_resumes(caplog):
    srv = _tcp_server()
    port = srv.getsockname()[1]
    c = emit_config()
    sink = MavlinkOutSink(open_link(f"tcp:127.0.0.1:{port}", c.emit.sysid, c.emit.compid), c)
    t = [0]

    def step(n=1):
        for _ in range(n):
            sink.epoch(report(t[0]))
            t[0] += 200_000

    try:
        conn, _ = srv.accept()
        sink.start({})
        sink.writer.retry_s = 0.05
        conn.settimeout(5)
        assert conn.recv(4096)[0] == 0xFD  # the start HEARTBEAT arrived
        conn.close()
        srv.close()  # the peer is gone: connections are refused
        with caplog.at_level(logging.WARNING, logger="mavnav.sinks.mavlink_out"):
            deadline = time.monotonic() + 10
            while sink.writer.failures == 0 and time.monotonic() < deadline:
                step()
            assert sink.writer.failures > 0
            step(20)  # more failing sends: counted, not logged again
            warned = [r.getMessage() for r in caplog.records if "send failed" in r.getMessage()]
            assert len(warned) == 1
            # the peer comes back: sending resumes after a retry interval
            srv = _tcp_server(port)
            conn = None
            deadline = time.monotonic() + 10
            while sink.writer._failing and time.monotonic() < deadline:
                step()
                time.sleep(0.01)
            assert not sink.writer._failing
            conn, _ = srv.accept()
            step(5)
            conn.settimeout(5)
            assert conn.recv(4096)[0] == 0xFD
        assert any("sending again" in r.getMessage() for r in caplog.records)
        assert sink.writer.outages == 1
        if conn is not None:
            conn.close()
    finally:
        sink.close(RunSummary())
        srv.close()


def test_reboots_and_input_notices_are_said_at_notice_or_info(peer):
    """A reboot is said at once (the old boot's pending change first), at NOTICE; the
    input's notices at INFO (a clock step at NOTICE); none of it is an ERROR."""
    from mavnav.samples import Notice

    sink = udp_sink(peer, statustext_interval_s=5.0)
    sink.start({})
    sink.sample(Notice(recv_s=1.0, kind="vehicle", text="monitoring system 1 (quadrotor, PX4, component 1) "
                                                        "on udpin:0.0.0.0:14550: the first autopilot heartbeat"))
    sink.alarm(event(1.0, "gnss", "caution", "nominal", reason="2 samples rejected"))
    sink.alarm(event(1.5, "gnss", "alarm", "caution", reason="step 9 m"))  # held by the rate limit
    sink.sample(Notice(recv_s=2.0, kind="clock_step", text="vehicle clock stepped back 1.00 s at 2.000 s (boot 0)"))
    sink.sample(Reboot(t_us=3_015_000, recv_s=3.0, boot=1, last_t_us=84_987_000))
    assert peer.wait_for(lambda: len(texts_of(peer.msgs, strict=False)) == 5)
    got = [(t.text, t.severity) for t in texts_of(peer.msgs)]
    assert got == [
        ("mavnav input monitoring system 1 (quadrotor, PX4, component 1) on udpin:0.0.0.0:14550: the first "
         "autopilot heartbeat", mavlink2.MAV_SEVERITY_INFO),
        ("mavnav gnss CAUTION: 2 samples rejected", mavlink2.MAV_SEVERITY_WARNING),
        ("mavnav input vehicle clock stepped back 1.00 s at 2.000 s (boot 0)", mavlink2.MAV_SEVERITY_NOTICE),
        ("mavnav gnss ALARM: step 9 m", mavlink2.MAV_SEVERITY_CRITICAL),
        ("mavnav input VEHICLE REBOOTED: its time restarted at 3.0 s after 85.0 s (boot 1); the monitor starts "
         "again", mavlink2.MAV_SEVERITY_NOTICE),
    ]
    for t in texts_of(peer.msgs):  # chunked, never cut
        assert all(len(p) == 50 for _, p in sorted(t.parts)[:-1]) and len(sorted(t.parts)[-1][1]) < 50


def test_a_moved_home_is_said_and_altitude_amsl_stays_the_same_place(peer):
    """After a ReferenceMoved the heights fed are above the new home (the pipeline moved them):
    ALTITUDE's altitude_amsl adds the new home's altitude, so the same place gives the same
    altitude MSL; ODOMETRY's reset_counter counts the jump of its origin; said at NOTICE."""
    from mavnav.samples import ReferenceMoved

    sink = udp_sink(peer, altitude_rate_hz=50.0, fusable=True)
    sink.start({})
    sink.sample(ReferenceSet(t_us=0, recv_s=0.0, boot=0, kind="gnss", value=478.5, alt_ref_msl_m=478.5,
                             origin="home"))
    sink.epoch(report(20_000, h=1.5))
    sink.sample(ReferenceMoved(t_us=30_000, recv_s=0.0, boot=0, alt_ref_msl_m=480.0, shift_m=1.5, offset_m=1.5,
                               origin="home"))
    sink.epoch(report(40_000, h=0.0))
    # every stream of the two epochs in (UDP keeps no order between them)
    assert peer.wait_for(lambda: len(peer.of("ALTITUDE")) == 2 and len(peer.of("ODOMETRY")) == 2
                         and texts_of(peer.msgs, strict=False))
    a = peer.of("ALTITUDE")
    assert a[0].altitude_amsl == a[1].altitude_amsl == 480.0
    assert [o.reset_counter for o in peer.of("ODOMETRY")] == [0, 1]
    [t] = texts_of(peer.msgs)
    assert t.severity == mavlink2.MAV_SEVERITY_NOTICE
    assert t.text == ("mavnav input HOME MOVED +1.50 m to 480.00 m MSL (HOME_POSITION): heights are now above "
                      "the new home")
