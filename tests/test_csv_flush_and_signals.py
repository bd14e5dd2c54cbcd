"""The CSV as the run goes: on a live link every row is in the file as soon as its
epoch is done (not at close); otherwise at least every second of receive time.
Replay stopped by SIGTERM behaves as Ctrl-C: summary, complete CSV, exit 130."""

from __future__ import annotations

import csv
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from mavnav.config import Config, IngestConfig
from mavnav.ingest import LiveSource
from mavnav.pipeline import run
from mavnav.samples import BaroHeight, LinkLost
from mavnav.sinks.base import Sink
from mavnav.sinks.csv_sink import COLUMNS, CsvSink
from tests.support.emit import report
from tests.support.live import tlog_records
from tests.support.paths import REPO

pytestmark = [pytest.mark.integration, pytest.mark.slow]

LOGS = REPO / "sitl_logs"


def _rows(path):
    """Complete rows in the file now (a half-written last line is not a row)."""
    text = Path(path).read_text(encoding="utf-8")
    lines = text.split("\n")[:-1]  # whatever follows the last newline is incomplete
    return list(csv.reader(lines))


def _baro(recv_s):
    return BaroHeight(t_us=int(recv_s * 1e6), recv_s=recv_s, boot=0, height_ref_m=0.0, pressure_pa=1e5, instance=1)


def test_recorded_csv_is_flushed_every_second_of_receive_time(tmp_path):
    out = tmp_path / "est.csv"
    sink = CsvSink(out)
    sink.start({"live": False})
    assert _rows(out) == [list(COLUMNS)]  # the header at once
    t = 1000.0
    for k in range(40):  # 25 epochs per second of receive time
        sink.sample(_baro(t + 0.04 * k))
        sink.epoch(report(int(0.04 * k * 1e6)))
    # 1.56 s of receive time: the rows of the first second are in the file, at most 1 s is pending
    n = len(_rows(out)) - 1
    assert 26 <= n <= 40
    sink.sample(LinkLost(recv_s=t + 3.0, silent_s=1.4))  # a lost link: all written so far is in the file
    rows = _rows(out)[1:]
    assert len(rows) == 41 and rows[-1][-1] == "link lost: no data from the vehicle for 1.4 s"  # and said
    sink.close(None)
    assert len(_rows(out)) - 1 == 41


class Counter(Sink):
    name = "counter"

    def __init__(self):
        self.epochs = 0

    def epoch(self, report):
        self.epochs += 1


def test_live_csv_holds_every_epoch_before_close(tmp_path):
    """Over real UDP: once the link goes quiet, every epoch computed so far is in the
    file while the monitor is still running (the old sink kept them in a buffer)."""
    recs = tlog_records(LOGS / "px4_hover_gnss_step.tlog")[:3000]  # the first seconds of a simulated flight
    cfg = Config()
    src = LiveSource("udpin:127.0.0.1:0", IngestConfig(link_timeout_s=60.0))
    out = tmp_path / "live.csv"
    counter = Counter()
    done = {}
    runner = threading.Thread(
        target=lambda: done.setdefault("summary", run(src, cfg, [counter, CsvSink(out)], info={"live": True})),
        daemon=True)
    runner.start()
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        for i, (_, frame) in enumerate(recs):
            sock.sendto(frame, src.local_address)
            if i % 25 == 24:  # flow control, not pacing: stay within the socket buffer
                _wait(lambda: src._reader.frames >= i + 1 - 50)
        assert _wait(lambda: src._reader.frames == len(recs))
        # the pipeline has consumed everything; give its thread the moment to finish the epoch
        last = -1
        while counter.epochs != last:
            last = counter.epochs
            time.sleep(0.2)
        assert counter.epochs > 50
        assert len(_rows(out)) - 1 == counter.epochs
        assert "summary" not in done  # still running: nothing was closed
    finally:
        sock.close()
        src.close()
        runner.join(10)
    assert len(_rows(out)) - 1 == done["summary"].epochs


def _wait(cond, timeout=10.0):
    deadline = time.monotonic() + timeout
    while not cond():
        if time.monotonic() > deadline:
            return False
        time.sleep(0.002)
    return True


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_replay_stopped_by_a_signal_prints_the_summary_and_completes_the_csv(tmp_path, sig):
    out = tmp_path / "est.csv"
    proc = subprocess.Popen([sys.executable, "-m", "mavnav.cli", "replay", str(LOGS / "px4_hover_gnss_step.tlog"),
                             "--speed", "2", "--csv", str(out)],
                            stderr=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    try:
        # rows reach the file while the replay runs (each second of receive time)
        assert _wait(lambda: out.exists() and len(_rows(out)) > 5, timeout=60)
        proc.send_signal(sig)
        _, err = proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 130, err
    assert "Traceback" not in err
    assert f"interrupted by {sig.name}" in err
    summary = next(ln for ln in err.splitlines() if ln.startswith("mavnav replay:") and "epochs" in ln)
    epochs = int(summary.split(":")[1].split()[0])
    rows = _rows(out)
    assert rows[0] == list(COLUMNS) and len(rows) - 1 == epochs > 5
    assert Path(out).read_text().endswith("\n")
