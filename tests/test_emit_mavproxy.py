"""A real ground set-up: vehicle <-> MAVProxy <-> mavnav, all on 127.0.0.1.

The vehicle is a pymavlink peer that replays a simulated tlog (paced, 5x
real time) into MAVProxy's master port and answers commands. MAVProxy
(``--daemon --non-interactive``) forwards the telemetry to its outputs and
what its outputs send back to the vehicle, as it does for any ground
station. mavnav listens on one output with :class:`~mavnav.ingest.LiveSource`
through the pipeline, and emits either on a second MAVProxy port
(``--emit udpout:...``) or back out of its input link (``--emit input``).
"""

from __future__ import annotations

import os
import subprocess
import sys
import threading
import time

import pytest
from pymavlink import mavutil
from pymavlink.dialects.v20 import common as mavlink2

from mavnav.config import Config
from mavnav.ingest import LiveSource
from mavnav.pipeline import run
from mavnav.report import RunSummary
from mavnav.sinks.mavlink_out import MavlinkOutSink
from tests.support.emit import Autopilot
from tests.support.live import LiveRun, free_udp_ports, send_paced, tlog_frames
from tests.support.emit import Peer, emit_config, texts_of

pytestmark = [pytest.mark.integration, pytest.mark.slow]

pytest.importorskip("MAVProxy", reason="MAVProxy is not installed (pip install MAVProxy)")

SPEED = 5.0
REPLAY_S = 12.0




@pytest.fixture(scope="module")
def ground(tmp_path_factory):
    """MAVProxy between a vehicle peer and three outputs; yields the ports and the vehicle."""
    tmp = tmp_path_factory.mktemp("mavproxy")
    vehicle = Peer(sysid=1, compid=1)
    env = dict(os.environ, HOME=str(tmp))
    hb = mavlink2.MAVLink_heartbeat_message(mavlink2.MAV_TYPE_QUADROTOR, mavlink2.MAV_AUTOPILOT_PX4, 0, 0, 3, 3)
    proc = log = None
    try:
        # MAVProxy is up when it answers the vehicle's heartbeat with its own. A third-party
        # process that does not (seen once in a whole-suite run: "link 1 down" though the
        # vehicle kept sending) is started once more, on fresh ports, before the test fails.
        for attempt in range(2):
            master, live_in, emit_in, raw_in = free_udp_ports(4)
            cmd = [sys.executable, "-m", "MAVProxy.mavproxy", f"--master=udpin:127.0.0.1:{master}",
                   f"--out=udpout:127.0.0.1:{live_in}",   # mavnav's input (LiveSource)
                   f"--out=udpin:127.0.0.1:{emit_in}",    # mavnav's own emit port
                   f"--out=udpout:127.0.0.1:{raw_in}",    # an input link for --emit input
                   "--daemon", "--non-interactive", "--nowait", "--streamrate=-1"]
            log = open(tmp / f"mavproxy{attempt}.out", "w")
            proc = subprocess.Popen(cmd, cwd=tmp, env=env, stdout=log, stderr=subprocess.STDOUT,
                                    stdin=subprocess.DEVNULL)
            deadline = time.monotonic() + 30
            while not vehicle.of("HEARTBEAT") and time.monotonic() < deadline and proc.poll() is None:
                vehicle.send(hb, ("127.0.0.1", master))
                vehicle.wait_for(lambda: bool(vehicle.of("HEARTBEAT")), 0.2)
            if vehicle.of("HEARTBEAT"):
                break
            _stop(proc, log)
        else:
            pytest.fail(f"MAVProxy did not come up: {(tmp / 'mavproxy1.out').read_text()[-2000:]}")
        yield {"master": master, "live_in": live_in, "emit_in": emit_in, "raw_in": raw_in, "vehicle": vehicle,
               "dir": tmp}
    finally:
        if proc is not None:
            _stop(proc, log)
        vehicle.close()


def _stop(proc, log) -> None:
    if proc.poll() is None:
        proc.terminate()
        try:
            proc.wait(10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(5)
    log.close()


@pytest.fixture(scope="module")
def frames(simulated_tlog):
    """(record-time offset s, frame bytes) of a simulated hover, its first REPLAY_S seconds."""
    path, _ = simulated_tlog("px4_hover_gnss_step", 3)
    return tlog_frames(path, REPLAY_S)


def replay(vehicle: Peer, port: int, frames, stop: threading.Event) -> None:
    start = time.monotonic()
    for t, buf in frames:
        if stop.is_set():
            return
        wait = start + t / SPEED - time.monotonic()
        if wait > 0:
            time.sleep(wait)  # pacing the vehicle's clock, not waiting for a result
        vehicle.sock.sendto(buf, ("127.0.0.1", port))


def test_mavnav_behind_mavproxy_reaches_the_vehicle(ground, frames):
    vehicle: Peer = ground["vehicle"]
    ap = Autopilot(vehicle, {105: [mavlink2.MAV_RESULT_UNSUPPORTED]})
    source = LiveSource(f"udpin:127.0.0.1:{ground['live_in']}")
    cfg = emit_config(message_rates=("HIGHRES_IMU:50", "SCALED_PRESSURE:20"), command_timeout_s=0.5)
    link = mavutil.mavlink_connection(f"udpout:127.0.0.1:{ground['emit_in']}", source_system=1,
                                      source_component=191)
    sink = MavlinkOutSink(link, cfg, allow_commands=True, description="udpout to MAVProxy")
    result = {}
    runner = threading.Thread(target=lambda: result.setdefault(
        "summary", run(source, Config(), [sink], info={"live": True})), daemon=True)
    stop = threading.Event()
    replayer = threading.Thread(target=replay, args=(vehicle, ground["master"], frames, stop), daemon=True)
    runner.start()
    replayer.start()
    try:
        def from_mavnav(t):
            return vehicle.of(t, compid=191)

        ok = vehicle.wait_for(lambda: len(from_mavnav("ALTITUDE")) >= 10 and from_mavnav("STATUSTEXT")
                              and sink.requester.done, timeout=REPLAY_S / SPEED + 15)
        assert ok, (len(from_mavnav("ALTITUDE")), from_mavnav("STATUSTEXT"), sink.requester.results)
    finally:
        stop.set()
        replayer.join(10)
        source.close()
        runner.join(10)
    summary: RunSummary = result["summary"]
    assert summary.epochs > 0 and not summary.sink_failures
    hbs = from_mavnav("HEARTBEAT")
    assert hbs and all(h.type == mavlink2.MAV_TYPE_ONBOARD_CONTROLLER and h.get_srcSystem() == 1 for h in hbs)
    # the ALTITUDE the vehicle got is the monitor's height: near the simulated hover, on vehicle time
    alts = from_mavnav("ALTITUDE")
    assert all(0 <= a.time_usec <= REPLAY_S * 1e6 + 1e6 for a in alts)
    assert all(-3.0 < a.altitude_local < 20.0 for a in alts if a.altitude_local == a.altitude_local)
    texts = [t.text for t in texts_of(from_mavnav("STATUSTEXT"))]  # chunks joined
    assert all(t.startswith("mavnav ") for t in texts) and all(len(m.text) <= 50 for m in from_mavnav("STATUSTEXT"))
    # the sources' transitions, and what the input said (the vehicle monitored)
    assert {e.source for e in summary.alarms} | {"input"} >= {t.split()[1] for t in texts}
    assert any(t.startswith("mavnav input monitoring system 1") for t in texts)
    # commands went through MAVProxy to the vehicle, and its ACKs came back (MAVProxy's own
    # COMMAND_LONGs, which a busy machine lets arrive inside the run, are not mavnav's)
    ours = [c for c in ap.commands if (c.get_srcSystem(), c.get_srcComponent()) == (1, 191)]
    assert [int(c.param1) for c in ours] == [105, 29]
    assert all(c.command == 511 and c.target_system == 1 and c.target_component == 1 for c in ours)
    assert sink.requester.results == {"HIGHRES_IMU": "refused: UNSUPPORTED", "SCALED_PRESSURE": "accepted"}
    # the vehicle got nothing else from mavnav
    assert {m.get_type() for m in vehicle.msgs if m.get_srcComponent() == 191} == {
        "HEARTBEAT", "ALTITUDE", "STATUSTEXT", "COMMAND_LONG"}
    vehicle.handler = None


def test_mavnav_run_emit_input_behind_mavproxy(ground, frames, tmp_path):
    """``mavnav run udpin:... --emit input`` on a MAVProxy output: its output reaches the vehicle."""
    vehicle: Peer = ground["vehicle"]
    vehicle.handler = None
    vehicle.clear()
    live = LiveRun(tmp_path, ["--emit", "input"], port=ground["raw_in"])
    try:
        assert live.wait_for_text("mavnav: monitoring"), live.stderr()
        send_paced(vehicle, ground["master"], frames[: len(frames) // 2], SPEED)
        assert vehicle.wait_for(lambda: len(vehicle.of("ALTITUDE", 191)) >= 5 and vehicle.of("STATUSTEXT", 191),
                                timeout=15), live.stderr()
    finally:
        err = live.stop()
    assert live.proc.returncode == 0, err
    mine = [m for m in vehicle.msgs if m.get_srcComponent() == 191]
    assert {m.get_type() for m in mine} == {"HEARTBEAT", "ALTITUDE", "STATUSTEXT"}
    assert all(m.get_srcSystem() == 1 for m in mine)
    assert all(0 <= a.time_usec <= REPLAY_S * 1e6 for a in vehicle.of("ALTITUDE", 191))
