"""No burst loss: a tlog played at 4x into a real UDP socket on 127.0.0.1, one
MAVLink frame per datagram, while the consumer stalls as it does at start-up
(the filter bank compiled at the first epoch took seconds on a cold cache and
lost 2098 of 13650 datagrams and 229 epochs at 4x). A receive thread drains
the socket into a queue: every datagram arrives (sequence numbers), and the
epochs equal a replay of the same file."""

from __future__ import annotations

import threading
import time

import pytest

from mavnav.config import Config
from mavnav.ingest import LiveSource, TlogSource
from mavnav.ingest.stream_reader import StreamReader
from mavnav.pipeline import run
from mavnav.sinks.base import Sink
from tests.support.live import Sender, tlog_records
from tests.support.paths import SITL_LOGS

pytestmark = [pytest.mark.integration, pytest.mark.slow]

LOGS = SITL_LOGS


class Epochs(Sink):
    name = "epochs"

    def __init__(self, stall_s: float = 0.0):
        self.rows = []
        self.stall_s = stall_s

    def epoch(self, r):
        if not self.rows and self.stall_s:
            time.sleep(self.stall_s)  # a first epoch as slow as a cold JIT compile
        self.rows.append((r.t_us, r.boot, r.height_fused_m, r.sigma_fused_m, r.overall))


def _prefix(tmp_path, seconds):
    recs = tlog_records(LOGS / "px4_hover_gnss_step.tlog")
    t0 = recs[0][0]
    recs = [r for r in recs if r[0] - t0 <= seconds]
    path = tmp_path / "prefix.tlog"
    path.write_bytes(b"".join(int(round(t * 1e6)).to_bytes(8, "big") + fr for t, fr in recs))
    return path, recs


def test_stalled_consumer_loses_no_datagram_at_4x(tmp_path):
    path, recs = _prefix(tmp_path, 30.0)
    cfg = Config()
    want = Epochs()
    run(TlogSource(path, cfg.ingest), cfg, [want])
    file_reader = StreamReader(())
    file_reader.feed(b"".join(fr for _, fr in recs), 0.0)

    src = LiveSource("udpin:127.0.0.1:0", cfg.ingest)
    sender = Sender(recs, src.local_address, speed=4.0, batch_s=0.0)  # one frame per datagram
    got = Epochs(stall_s=3.0)  # 3 s at 4x: 12 s of telemetry, ~2700 datagrams, arrive meanwhile
    peak = {"backlog": 0}

    def backlog():
        return getattr(src, "backlog_bytes", 0)

    def stop_later():
        try:
            while sender.is_alive():
                peak["backlog"] = max(peak["backlog"], backlog())
                time.sleep(0.05)
            deadline = time.monotonic() + 20.0
            while backlog() and time.monotonic() < deadline:
                time.sleep(0.05)
            time.sleep(0.5)
        finally:
            src.close()

    sender.start()
    threading.Thread(target=stop_later, daemon=True).start()
    run(src, cfg, [got], info={"live": True})
    assert src._reader.frames == len(recs)  # every datagram sent was received
    assert src.stats.seq_missing == file_reader.seq_missing  # no sequence gap the file does not have
    assert src.stats.dropped_chunks == 0
    assert peak["backlog"] > 50_000  # the stall did build a backlog, and it was kept
    assert len(want.rows) > 600 and got.rows == want.rows


def test_receive_buffer_is_enlarged():
    src = LiveSource("udpin:127.0.0.1:0", Config().ingest)
    try:
        assert src.rcvbuf_bytes is not None and src.rcvbuf_bytes >= 1 << 20
    finally:
        src.close()


def test_bounded_backlog_counts_what_it_drops(tmp_path):
    # a consumer that never catches up: the queue stops at its bound and says what it dropped
    path, recs = _prefix(tmp_path, 4.0)
    src = LiveSource("udpin:127.0.0.1:0", Config().ingest, max_backlog_bytes=20_000)
    src._start_receiver()  # receiving, nobody consuming
    sender = Sender(recs, src.local_address, speed=50.0, batch_s=0.0)
    sender.start()
    sender.join()
    time.sleep(0.3)
    try:
        assert 0 < src.backlog_bytes <= 20_000
        assert src.stats.dropped_chunks > 0
    finally:
        src.close()
