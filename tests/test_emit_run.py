"""The commands themselves: ``mavnav replay --csv --emit`` and a live ``mavnav run`` process.

* ALTITUDE on the wire equals the CSV of the same replay.
* A live ``mavnav run`` sends nothing without ``--emit``; with ``--emit
  input`` its output comes back out of the link it listens on; with
  ``--emit CONNECTION`` it sends a command only with ``--allow-commands``.
"""

from __future__ import annotations

import csv
import threading
import time

import numpy as np
import pytest
from click.testing import CliRunner
from pymavlink import mavutil

from mavnav.cli import main
from tests.support.emit import Autopilot
from tests.support.emit import Peer
from tests.support.live import tlog_frames, send_paced, LiveRun

pytestmark = [pytest.mark.integration, pytest.mark.slow]



@pytest.fixture(scope="module")
def gnss_step(simulated_tlog):
    return simulated_tlog("px4_hover_gnss_step", 11)[0]


@pytest.fixture(scope="module")
def frames(gnss_step):
    return tlog_frames(gnss_step, 6.0)


# --------------------------------------------------------------------------- replay


def test_replay_altitude_equals_the_csv_of_the_same_run(gnss_step, tmp_path):
    peer = Peer()
    try:
        out = tmp_path / "run.csv"
        res = CliRunner().invoke(main, ["replay", str(gnss_step), "--csv", str(out), "--emit", peer.url,
                                        "--altitude-rate", "5"])
        assert res.exit_code == 0, res.output
        rows = list(csv.DictReader(out.open()))
        by_t = {int(round(float(r["t_s"]) * 1e6)): r for r in rows}
        t = sorted(by_t)
        expected = int((t[-1] - t[0]) * 5e-6) + 1
        assert peer.wait_for(lambda: len(peer.of("ALTITUDE")) >= expected - 1)
        peer.wait_for(lambda: len(peer.of("ALTITUDE")) > expected + 1, 0.2)  # bounded: nothing more should come
        alts = peer.of("ALTITUDE")
        assert abs(len(alts) - expected) <= 1
        for a in alts:
            row = by_t[a.time_usec]  # every ALTITUDE is an epoch of the CSV
            h = float(row["height_fused_m"])
            if np.isnan(h):
                assert np.isnan(a.altitude_local)
            else:
                assert abs(a.altitude_local - h) <= 5e-5 + 1e-6 * abs(h)  # CSV: 0.1 mm; float32
                assert a.altitude_relative == a.altitude_local
            if row["rng_ok"] == "0":
                assert np.isnan(a.bottom_clearance) and np.isnan(a.altitude_terrain)
            else:
                h_rng = float(row["height_rng_ch_m"])
                assert abs(a.altitude_terrain - h_rng) <= 5e-5 + 1e-6 * abs(h_rng)
        states = {r["alarm"] for r in rows}
        assert "alarm" in states  # the fault scenario did raise alarms ...
        assert any(m.text.startswith("mavnav gnss ALARM") for m in peer.of("STATUSTEXT"))  # ... and they went out
    finally:
        peer.close()


def test_replay_refuses_emit_input(gnss_step):
    res = CliRunner().invoke(main, ["replay", str(gnss_step), "--emit", "input"])
    assert res.exit_code == 2 and "live input link" in res.output


# --------------------------------------------------------------------------- live runs


def _live(tmp_path, frames, args, vehicle: Peer):
    run = LiveRun(tmp_path, args)
    try:
        assert run.wait_for_text("mavnav: monitoring"), run.stderr()
        send_paced(vehicle, run.port, frames)
        # the monitor worked on the telemetry: a source changed state at an epoch (the
        # rangefinder, whose readings start a few seconds in, is first unavailable)
        assert run.wait_for_text("] rangefinder"), run.stderr()
    except BaseException:
        run.stop()
        raise
    return run


def test_live_run_sends_nothing_without_emit(tmp_path, frames):
    vehicle = Peer(sysid=1, compid=1)
    try:
        run = _live(tmp_path, frames, [], vehicle)
        err = run.stop()
        assert run.proc.returncode == 0, err
        assert "mavnav run:" in err and " 0 epochs" not in err
        assert not vehicle.msgs and not vehicle.bad
    finally:
        vehicle.close()


def test_live_run_emits_back_out_of_its_input_link(tmp_path, frames):
    vehicle = Peer(sysid=1, compid=1)
    try:
        run = _live(tmp_path, frames, ["--emit", "input", "--emit-sysid", "1"], vehicle)
        try:
            assert vehicle.wait_for(lambda: len(vehicle.of("ALTITUDE", 191)) >= 5 and vehicle.of("STATUSTEXT", 191))
        finally:
            err = run.stop()
        assert run.proc.returncode == 0, err
        hb = vehicle.of("HEARTBEAT", 191)
        assert hb and all(h.type == 18 and h.autopilot == 8 for h in hb)
        alts = vehicle.of("ALTITUDE", 191)
        assert all(0 <= a.time_usec <= 7_000_000 for a in alts)
        assert {m.get_type() for m in vehicle.msgs} <= {"HEARTBEAT", "ALTITUDE", "STATUSTEXT"}
        assert all(m.get_srcComponent() == 191 for m in vehicle.msgs)
    finally:
        vehicle.close()


def test_live_run_sends_no_command_without_allow_commands(tmp_path, frames):
    """With --emit CONNECTION but without --allow-commands: no command, and nothing on the input link.

    (The same process with --allow-commands does send them: tests/test_emit_mavproxy.py drives the
    pipeline through MAVProxy, and test_emit_cli checks the flag reaches the sink.)
    """
    vehicle = Peer(sysid=1, compid=1)
    autopilot = Peer(sysid=1, compid=1)  # the vehicle's end of mavnav's emit link
    ap = Autopilot(autopilot, {})
    try:
        run = _live(tmp_path, frames, ["--emit", autopilot.url], vehicle)
        try:
            assert autopilot.wait_for(lambda: len(autopilot.of("ALTITUDE", 191)) >= 5)
            assert ap.heartbeats_sent == 1  # mavnav heard an autopilot, and still sent no command
        finally:
            err = run.stop()
        assert run.proc.returncode == 0, err
        assert not ap.commands and not autopilot.of("COMMAND_LONG")
        assert {m.get_type() for m in autopilot.msgs} == {"HEARTBEAT", "ALTITUDE", "STATUSTEXT"}
        assert not vehicle.msgs and not vehicle.bad
    finally:
        vehicle.close()
        autopilot.close()


def test_live_run_asks_its_input_link_for_the_rates_and_says_the_answers(tmp_path, gnss_step):
    """``mavnav run --emit input --allow-commands``: SET_MESSAGE_INTERVAL for the streams the
    monitor reads from this autopilot (PX4 here), at the rates the configuration needs, sent back
    out of the link it listens on; every COMMAND_ACK verdict said on the console.

    The vehicle is a UDP endpoint on 127.0.0.1 that streams a simulated flight (re-encoded in its
    own MAVLink sequence) and answers each COMMAND_LONG between two telemetry frames, as an
    autopilot's loop does: accepted, temporarily rejected then accepted, denied, silent,
    unsupported."""
    from pymavlink.dialects.v20 import common as R

    from mavnav.config import config_from_dict
    from mavnav.sinks.mavlink_commands import needed_rates

    cfg_path = tmp_path / "commands.yaml"
    # a reply waits for the vehicle's next frame and the monitor's next turn: 1.5 s of wall clock
    # keeps a busy machine's answers in time (0.3 s lost them under load), a silent stream costs 3 s
    cfg_path.write_text("emit: {command_timeout_s: 1.5, command_attempts: 2}\n")
    rates = needed_rates(config_from_dict({}), R.MAV_AUTOPILOT_PX4)
    ids = {r.name: r.msg_id for r in rates}
    policy = {ids["HIGHRES_IMU"]: [R.MAV_RESULT_ACCEPTED],
              ids["ATTITUDE"]: [R.MAV_RESULT_TEMPORARILY_REJECTED, R.MAV_RESULT_ACCEPTED],
              ids["SCALED_PRESSURE"]: [R.MAV_RESULT_DENIED],
              ids["GPS_RAW_INT"]: [None],  # never answers
              ids["DISTANCE_SENSOR"]: [R.MAV_RESULT_UNSUPPORTED]}
    commands, replies = [], []
    lock = threading.Lock()

    def handle(peer, m):  # the receive thread: the answer waits for the vehicle's next loop
        if m.get_type() != "COMMAND_LONG":
            return
        with lock:
            commands.append(m)
            answers = policy[int(m.param1)]
            result = answers.pop(0) if len(answers) > 1 else answers[0]
            if result is not None:
                replies.append(R.MAVLink_command_ack_message(m.command, result, 0, 0, m.get_srcSystem(),
                                                             m.get_srcComponent()))

    vehicle = Peer(sysid=1, compid=1)
    vehicle.handler = handle
    log = mavutil.mavlink_connection(str(gnss_step))
    msgs = []
    while True:
        m = log.recv_msg()
        if m is None:
            break
        msgs.append((m._timestamp, m))
    log.close()
    run = LiveRun(tmp_path, ["--emit", "input", "--allow-commands", "--config", str(cfg_path)])
    try:
        assert run.wait_for_text("mavnav: monitoring"), run.stderr()
        addr = ("127.0.0.1", run.port)
        start, t0 = time.monotonic(), msgs[0][0]
        for k, (t, m) in enumerate(msgs):
            wait = start + (t - t0) / 4.0 - time.monotonic()
            if wait > 0:
                time.sleep(wait)  # the simulated vehicle's clock (4x), not a wait for a result
            with lock:
                pending, replies[:] = list(replies), []
            for ack in pending:
                vehicle.send(ack, addr)
            vehicle.send(m, addr)
            if k % 200 == 0 and "message rates not granted" in run.stderr():
                break
        else:
            pytest.fail("the run never reported its requests:\n" + run.stderr())
    finally:
        err = run.stop()
        vehicle.close()
    assert run.proc.returncode == 0, err
    # the commands: SET_MESSAGE_INTERVAL only, from mavnav's component to the autopilot, one message at a time
    assert {c.command for c in commands} == {R.MAV_CMD_SET_MESSAGE_INTERVAL}
    assert all((c.get_srcSystem(), c.get_srcComponent(), c.target_system, c.target_component) == (1, 191, 1, 1)
               for c in commands)
    asked = [(int(c.param1), c.param2, c.confirmation) for c in commands]
    us = {r.msg_id: round(1e6 / r.rate_hz) for r in rates}
    assert asked == [
        (ids["HIGHRES_IMU"], us[ids["HIGHRES_IMU"]], 0),
        (ids["ATTITUDE"], us[ids["ATTITUDE"]], 0), (ids["ATTITUDE"], us[ids["ATTITUDE"]], 1),
        (ids["SCALED_PRESSURE"], us[ids["SCALED_PRESSURE"]], 0),
        (ids["GPS_RAW_INT"], us[ids["GPS_RAW_INT"]], 0), (ids["GPS_RAW_INT"], us[ids["GPS_RAW_INT"]], 1),
        (ids["DISTANCE_SENSOR"], us[ids["DISTANCE_SENSOR"]], 0),
    ]
    # what the console says, in order
    said = [ln for ln in err.splitlines() if ln.startswith("mavnav: ") and "monitoring" not in ln]
    assert said == [
        "mavnav: asking the autopilot 1/1 for the input rates the time-to-alarm needs: HIGHRES_IMU 50 Hz, "
        "ATTITUDE 50 Hz, SCALED_PRESSURE 20 Hz, GPS_RAW_INT 5 Hz, DISTANCE_SENSOR 20 Hz",
        "mavnav: SET_MESSAGE_INTERVAL HIGHRES_IMU 50 Hz: accepted",
        "mavnav: SET_MESSAGE_INTERVAL ATTITUDE 50 Hz: accepted",
        "mavnav: SET_MESSAGE_INTERVAL SCALED_PRESSURE 20 Hz: refused: DENIED",
        "mavnav: SET_MESSAGE_INTERVAL GPS_RAW_INT 5 Hz: no answer",
        "mavnav: SET_MESSAGE_INTERVAL DISTANCE_SENSOR 20 Hz: refused: UNSUPPORTED",
        "mavnav: message rates not granted: SCALED_PRESSURE refused: DENIED; GPS_RAW_INT no answer; "
        "DISTANCE_SENSOR refused: UNSUPPORTED (the input may be too slow for the time-to-alarm: see the input "
        "source's state)",
    ]
    assert "Traceback" not in err
