"""Say what happens, on a real UDP link (127.0.0.1) and in the real commands:

* nothing arrives: "waiting for a heartbeat on udpin:127.0.0.1:PORT", and what
  was heard instead (a ground station only; another system than --sysid);
* which vehicle is monitored and which systems are ignored;
* every reboot on the console, in the CSV (a boot column and an event row),
  and a summary whose time span is right across it;
* a lost link in the CSV as an event row while it lasts, flushed.
"""

from __future__ import annotations

import csv
import socket
import threading
import time
from pathlib import Path

import pytest
from click.testing import CliRunner
from pymavlink.dialects.v20 import common as mav2

from mavnav.cli import main
from mavnav.cli.run import AlarmPrinter, print_summary
from mavnav.config import Config, IngestConfig
from mavnav.ingest import LiveSource
from mavnav.pipeline import run
from mavnav.samples import Notice
from mavnav.sinks.base import Sink
from mavnav.sinks.csv_sink import COLUMNS, CsvSink
from tests.support.live import tlog_records
from tests.support.live import ReceiveClock, wait_until, send_all
from tests.support.paths import SITL_LOGS

pytestmark = [pytest.mark.integration]

LOGS = SITL_LOGS


class Notes(Sink):
    name = "notes"

    def __init__(self):
        self.notes = []

    def sample(self, s):
        if isinstance(s, Notice):
            self.notes.append(s)

    def texts(self, kind=None):
        return [n.text for n in self.notes if kind is None or n.kind == kind]


def _heartbeat(sysid, mav_type, autopilot, seq=0):
    m = mav2.MAVLink(None, srcSystem=sysid, srcComponent=1 if sysid != 255 else 190)
    m.seq = seq
    return m.heartbeat_encode(mav_type, autopilot, 0, 0, 4, 3).pack(m)


def _start(src, sinks):
    done = {}
    th = threading.Thread(target=lambda: done.setdefault("s", run(src, Config(), sinks, info={"live": True})),
                          daemon=True)
    th.start()
    return th, done


def test_waiting_for_a_heartbeat_then_the_vehicle_chosen_and_the_ignored(capsys):
    clock = ReceiveClock()
    src = LiveSource("udpin:127.0.0.1:0", IngestConfig(), clock=clock)
    port = src.local_address[1]
    notes = Notes()
    th, _ = _start(src, [AlarmPrinter(), notes])
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        time.sleep(0.2)
        clock.skip(2.2)  # 2.2 s of silence on the receive clock
        assert wait_until(lambda: notes.texts("waiting_heartbeat"))
        assert notes.texts("waiting_heartbeat")[0] == (
            f"waiting for a heartbeat on udpin:127.0.0.1:{port} (2 s): nothing received yet")
        # a ground station only: no vehicle yet, and said so
        sock.sendto(_heartbeat(255, 6, 8), src.local_address)
        assert wait_until(lambda: src._reader.frames == 1)
        clock.skip(10.5)
        assert wait_until(lambda: len(notes.texts("waiting_heartbeat")) == 2)
        assert notes.texts("waiting_heartbeat")[1].endswith("heard only system 255 (ground station)")
        # two vehicles: the first autopilot heartbeat is the one monitored, the other is said to be ignored
        recs = tlog_records(LOGS / "px4_hover_gnss_step.tlog")[:400]
        for i, (_, frame) in enumerate(recs):
            sock.sendto(frame, src.local_address)
            if i == 300:  # after system 1's first heartbeat
                sock.sendto(_heartbeat(2, 1, 3, seq=7), src.local_address)  # an ArduPlane, system 2
        assert wait_until(lambda: len(notes.texts("ignored")) == 2)
        assert notes.texts("vehicle") == [
            f"monitoring system 1 (quadrotor, PX4, component 1) on udpin:127.0.0.1:{port}: the first autopilot heartbeat"]
        assert sorted(notes.texts("ignored")) == [
            "ignoring system 2 (fixed wing, ArduPilot): not the monitored vehicle (system 1); "
            "--sysid 2 to monitor it instead",
            "ignoring system 255 (ground station): not the monitored vehicle (system 1)"]
    finally:
        sock.close()
        src.close()
        th.join(10)
    err = capsys.readouterr().err
    assert "waiting for a heartbeat on udpin:127.0.0.1:" in err and "monitoring system 1" in err
    assert "ignoring system 2" in err


def test_waiting_for_the_asked_sysid_names_what_was_heard():
    clock = ReceiveClock()
    src = LiveSource("udpin:127.0.0.1:0", IngestConfig(), sysid=7, clock=clock)
    notes = Notes()
    th, _ = _start(src, [notes])
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        for _, frame in tlog_records(LOGS / "px4_hover_gnss_step.tlog")[:100]:
            sock.sendto(frame, src.local_address)
        assert wait_until(lambda: src._reader.frames == 100)
        clock.skip(2.5)
        assert wait_until(lambda: notes.texts("waiting_heartbeat"))
        text = notes.texts("waiting_heartbeat")[0]
        assert text.startswith("waiting for a heartbeat from system 7 on udpin:127.0.0.1:")
        assert text.endswith("heard only system 1 (quadrotor, PX4)")
    finally:
        sock.close()
        src.close()
        th.join(10)


def _csv(path):
    return list(csv.DictReader(Path(path).open(encoding="utf-8")))


def test_reboot_on_the_console_in_the_csv_and_in_the_summary_span(tmp_path):
    out = tmp_path / "est.csv"
    res = CliRunner().invoke(main, ["replay", str(LOGS / "ardupilot_input_faults.tlog"), "--csv", str(out)])
    assert res.exit_code == 0, res.output
    err = res.output
    assert "VEHICLE REBOOTED: its time restarted at 3.015 s after 84.987 s of boot 0" in err
    rows = _csv(out)
    assert tuple(rows[0].keys()) == COLUMNS and COLUMNS[-2:] == ("boot", "event")
    events = [r for r in rows if r["event"]]
    epochs = [r for r in rows if not r["event"]]
    reboot = [r for r in events if r["event"].startswith("reboot")]
    assert len(reboot) == 1 and reboot[0]["boot"] == "1" and reboot[0]["t_s"] == "3.015000"
    i = rows.index(reboot[0])
    assert {r["boot"] for r in rows[:i] if not r["event"]} == {"0"}
    assert {r["boot"] for r in rows[i + 1:] if not r["event"]} == {"1"}
    assert all(r["height_fused_m"] == "" for r in events) and all(r["alarm"] for r in epochs)
    # one span per boot, not "30.1-94.0 s" across the restart of vehicle time
    line = next(ln for ln in err.splitlines() if ln.startswith("mavnav replay:"))
    first0, last0 = float(epochs[0]["t_s"]), max(float(r["t_s"]) for r in epochs if r["boot"] == "0")
    first1 = min(float(r["t_s"]) for r in epochs if r["boot"] == "1")
    last1 = float(epochs[-1]["t_s"])
    assert f"vehicle time {first0:.1f}-{last0:.1f} s (boot 0), {first1:.1f}-{last1:.1f} s (boot 1)" in line
    assert f"({last0 - first0 + last1 - first1:.1f} s in all)" in line
    assert "1 reboots" in line


@pytest.mark.slow
def test_link_loss_is_an_event_row_in_the_csv_while_it_lasts(tmp_path):
    recs = tlog_records(LOGS / "px4_hover_gnss_step.tlog")[:4000]
    clock = ReceiveClock()
    src = LiveSource("udpin:127.0.0.1:0", IngestConfig(link_timeout_s=2.0), clock=clock)
    out = tmp_path / "live.csv"
    th, done = _start(src, [CsvSink(out)])
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)

    def send(part):
        send_all(sock, src, part)

    def events():
        return [r for r in _csv(out) if r["event"]]

    try:
        send(recs[:2000])
        time.sleep(0.2)
        assert not events()
        clock.skip(5.0)
        assert wait_until(lambda: events())  # in the file while the link is down
        lost = events()
        assert len(lost) == 1 and lost[0]["event"] == "link lost: no data from the vehicle for 5.0 s"
        epochs = [r for r in _csv(out) if not r["event"]]
        assert lost[0]["t_s"] == epochs[-1]["t_s"] and lost[0]["boot"] == "0"  # at the last epoch's time
        send(recs[2000:])
        assert wait_until(lambda: len(events()) == 2 or done)
    finally:
        sock.close()
        src.close()
        th.join(10)
    ev = events()
    assert [e["event"] for e in ev] == ["link lost: no data from the vehicle for 5.0 s",
                                        "link recovered after 5.0 s"]


def test_summary_span_of_one_boot_is_unchanged(capsys):
    from mavnav.report import RunSummary

    s = RunSummary(epochs=3, first_t_us=1_000_000, last_t_us=2_500_000, spans=[[0, 1_000_000, 2_500_000]])
    print_summary(s, "mavnav run")
    assert "3 epochs, vehicle time 1.0-2.5 s, 0 alarms" in capsys.readouterr().err
