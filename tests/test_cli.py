"""The CLI through click's runner and as real subprocesses: the output contract
(CSV columns, audit JSON), exit statuses, and ``run`` on a real UDP stream."""

from __future__ import annotations

import csv
import json
import math
import os
import signal
import socket
import struct
import subprocess
import sys
import time
from pathlib import Path

import pytest
from click.testing import CliRunner

from mavnav.cli import main
from mavnav.ingest import TlogSource
from mavnav.sinks.csv_sink import COLUMNS
from tests.support.live import free_udp_port
from tests.support.paths import SITL_LOGS

pytestmark = [pytest.mark.integration]

LOGS = SITL_LOGS


def read_csv(path):
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def test_replay_writes_the_csv_contract(tmp_path):
    out = tmp_path / "est.csv"
    res = CliRunner().invoke(main, ["replay", str(LOGS / "px4_hover_gnss_step.tlog"), "--csv", str(out)])
    assert res.exit_code == 0, res.output
    rows = read_csv(out)
    assert tuple(rows[0].keys()) == COLUMNS
    t = [float(r["t_s"]) for r in rows]
    assert all(b > a for a, b in zip(t, t[1:]))
    assert {r["alarm"] for r in rows} <= {"nominal", "caution", "unavailable", "alarm"}
    assert {r["gnss_ok"] for r in rows} == {"0", "1"}  # the GNSS step takes GNSS out, then it comes back
    # the fused height is finite once the channels have converged, with a sigma
    late = [r for r in rows if float(r["t_s"]) > 10]
    assert all(math.isfinite(float(r["height_fused_m"])) and float(r["sigma_fused_m"]) > 0 for r in late)
    assert "gnss" in res.output and "alarm" in res.output  # the console shows alarm transitions


class FakeClock:
    """``time`` for the replay's pacing: ``sleep`` moves ``monotonic`` on, nothing waits."""

    def __init__(self):
        self.now = 1000.0
        self.slept = 0.0

    def monotonic(self):
        return self.now

    def sleep(self, s):
        assert s > 0
        self.now += s
        self.slept += s


@pytest.mark.slow
def test_replay_speed_factor_paces_by_vehicle_time(monkeypatch):
    """At 30x, each sample is released at a thirtieth of its vehicle time since the
    first: on a clock only the replay moves, the replay sleeps exactly the log's
    vehicle-time span over 30 (the span read from the same log)."""
    import mavnav.cli.run as run_mod

    log = LOGS / "px4_landing_nominal.tlog"
    stamped = [s for s in TlogSource(log) if getattr(s, "t_us", None) is not None and getattr(s, "boot", None) is not None]
    assert {s.boot for s in stamped} == {0}  # one boot: the pacing never restarts
    span_s = (stamped[-1].t_us - stamped[0].t_us) * 1e-6
    assert span_s > 55
    clock = FakeClock()
    monkeypatch.setattr(run_mod, "time", clock)
    res = CliRunner().invoke(main, ["replay", str(log), "--speed", "30"])
    assert res.exit_code == 0, res.output
    assert clock.slept == pytest.approx(span_s / 30, rel=1e-9)
    res = CliRunner().invoke(main, ["replay", str(LOGS / "px4_landing_nominal.tlog"), "--speed", "fast"])
    assert res.exit_code == 2 and "realtime, max, or a positive factor" in res.output


@pytest.mark.slow
def test_audit_json_contract_and_exit_statuses(tmp_path):
    fault, nominal = LOGS / "px4_hover_gnss_step.tlog", LOGS / "px4_landing_nominal.tlog"
    js = tmp_path / "audit.json"
    r = CliRunner().invoke(main, ["audit", str(fault), str(nominal), "--json", str(js)])
    assert r.exit_code == 0, r.output
    doc = json.loads(js.read_text())
    assert [Path(f["path"]).name for f in doc["files"]] == [fault.name, nominal.name]
    f0 = doc["files"][0]
    for key in ("path", "duration_s", "alarms", "rates_hz", "availability", "fused_vs_autopilot_rms_m"):
        assert key in f0
    a = [x for x in f0["alarms"] if x["state"] == "alarm"][0]
    assert set(a) >= {"t_s", "source", "state", "reason", "cleared_t_s"}
    assert a["source"] == "gnss" and a["cleared_t_s"] > a["t_s"]
    assert 55 < f0["duration_s"] < 65 and f0["rates_hz"]["HIGHRES_IMU"] > 90
    # the CSV's t_s and the audit's t_s are the same clock
    out = tmp_path / "est.csv"
    CliRunner().invoke(main, ["replay", str(fault), "--csv", str(out)])
    rows = read_csv(out)
    row = min(rows, key=lambda r: abs(float(r["t_s"]) - a["t_s"]))
    assert abs(float(row["t_s"]) - a["t_s"]) < 1e-3 and row["gnss_ok"] == "0"
    # --fail-on
    assert CliRunner().invoke(main, ["audit", str(fault), "--fail-on", "alarm"]).exit_code == 1
    assert CliRunner().invoke(main, ["audit", str(nominal), "--fail-on", "alarm"]).exit_code == 0
    # unreadable input: reported, the rest still audited, exit 2
    junk = tmp_path / "junk.tlog"
    junk.write_bytes(b"this is not a tlog at all\n" * 100)
    r = CliRunner().invoke(main, ["audit", str(junk), str(nominal), "--json", str(js)])
    assert r.exit_code == 2
    doc = json.loads(js.read_text())
    assert "error" in doc["files"][0] and "junk.tlog" in doc["files"][0]["error"]
    assert "alarms" in doc["files"][1]


@pytest.mark.slow
def test_audit_directory_and_table_as_a_real_subprocess(tmp_path):
    d = tmp_path / "fleet"
    d.mkdir()
    for name in ("px4_landing_nominal.tlog", "ardupilot_rng_dropout.tlog"):
        (d / name).write_bytes((LOGS / name).read_bytes())
    p = subprocess.run([sys.executable, "-m", "mavnav.cli", "audit", str(d)], capture_output=True, text=True,
                       timeout=300)
    assert p.returncode == 0, p.stderr
    assert "px4_landing_nominal.tlog" in p.stdout and "ardupilot_rng_dropout.tlog" in p.stdout
    assert "channels used" in p.stdout and "audited 2 file(s)" in p.stderr


def test_bad_config_and_missing_file_are_one_line_errors(tmp_path):
    bad = tmp_path / "c.yaml"
    bad.write_text("monitor:\n  modes: paper\n")
    r = CliRunner().invoke(main, ["replay", str(LOGS / "px4_landing_nominal.tlog"), "--config", str(bad)])
    assert r.exit_code == 2 and "unknown key 'monitor.modes'" in r.output and "Traceback" not in r.output
    junk = tmp_path / "x.tlog"
    junk.write_bytes(os.urandom(5000))
    r = CliRunner().invoke(main, ["replay", str(junk)])
    assert r.exit_code == 2 and "x.tlog" in r.output and "Traceback" not in r.output


# ---------------------------------------------------------------- live: real UDP on 127.0.0.1


def tlog_records(path):
    data = path.read_bytes()
    out, i = [], 0
    while i + 8 < len(data):
        t = struct.unpack(">Q", data[i:i + 8])[0]
        assert data[i + 8] == 0xFD  # the simulator writes MAVLink 2 only
        n = 12 + data[i + 9]  # 10 header bytes + payload + 2 CRC bytes
        out.append((t, data[i + 8:i + 8 + n]))
        i += 8 + n
    return out


@pytest.mark.slow
def test_run_monitors_a_live_udp_stream_and_stops_cleanly(tmp_path):
    recs = tlog_records(LOGS / "px4_hover_gnss_step.tlog")
    port = free_udp_port()
    out = tmp_path / "live.csv"
    proc = subprocess.Popen([sys.executable, "-m", "mavnav.cli", "run", f"udpin:127.0.0.1:{port}", "--csv", str(out)],
                            stderr=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    try:
        # wait for the daemon to listen
        deadline = time.monotonic() + 60
        line = ""
        while "monitoring" not in line and time.monotonic() < deadline:
            line = proc.stderr.readline()
        assert "monitoring" in line
        speed = 8.0  # ~1,800 packets/s: no drops on a loaded 2-core machine
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        t0_rec, t0 = recs[0][0], time.monotonic()
        for t, frame in recs:
            due = t0 + (t - t0_rec) * 1e-6 / speed
            d = due - time.monotonic()
            if d > 0.002:
                time.sleep(d)
            sock.sendto(frame, ("127.0.0.1", port))
        time.sleep(1.0)
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0, err
    assert "mavnav run:" in err and "epochs" in err
    rows = read_csv(out)
    assert len(rows) > 1000
    assert "gnss" in err and "-> alarm" in err  # the GNSS step of the log, live
