"""A lost live link is said while it lasts: console and STATUSTEXT report "link lost"
as soon as the receive clock passes the timeout, before any data returns, and
"recovered" when it does. Real UDP on 127.0.0.1; the receive clock is injected
(the test moves it forward) so no wall-clock window decides the outcome."""

from __future__ import annotations

import socket
import threading

import pytest
from pymavlink.dialects.v20 import common as mavlink2

from mavnav.cli.run import AlarmPrinter
from mavnav.config import Config, IngestConfig
from mavnav.ingest import LiveSource
from mavnav.pipeline import run
from mavnav.sinks.csv_sink import CsvSink
from tests.support.emit import Peer, texts_of, udp_sink
from tests.support.live import tlog_records
from tests.support.live import ReceiveClock, wait_until, send_all
from tests.support.paths import SITL_LOGS

pytestmark = [pytest.mark.integration]

LOGS = SITL_LOGS


def test_link_loss_is_reported_while_it_lasts(tmp_path, capsys):
    recs = tlog_records(LOGS / "px4_hover_gnss_step.tlog")[:4000]
    clock = ReceiveClock()
    src = LiveSource("udpin:127.0.0.1:0", IngestConfig(link_timeout_s=2.0), clock=clock)
    peer = Peer()
    sink = udp_sink(peer, statustext_interval_s=0.0)
    done = {}
    runner = threading.Thread(target=lambda: done.setdefault("summary", run(
        src, Config(), [AlarmPrinter(), CsvSink(tmp_path / "live.csv"), sink],
        info={"live": True, "source": "udp"})), daemon=True)
    runner.start()
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)

    def send(part):
        send_all(sock, src, part)

    def lost_texts():
        return [t for t in texts_of(peer.msgs, strict=False) if "LINK LOST" in t.text]

    try:
        send(recs[:2000])
        assert not lost_texts()
        n_before = len(peer.msgs)
        clock.skip(5.0)  # five seconds of silence on the receive clock
        assert wait_until(lambda: lost_texts())
        # said while the link is down: nothing was sent to mavnav since
        assert src._reader.frames == 2000
        lost = lost_texts()[0]
        assert lost.severity == mavlink2.MAV_SEVERITY_ERROR and lost.text.startswith("mavnav input LINK LOST")
        assert peer.msgs.index(lost.first) >= n_before
        console = capsys.readouterr().err
        assert "LINK LOST: no data from the vehicle for 5.0 s" in console
        assert "recovered" not in console
        # the data comes back
        send(recs[2000:])
        assert wait_until(lambda: any("LINK RECOVERED" in t.text for t in texts_of(peer.msgs, strict=False)))
        rec = next(t for t in texts_of(peer.msgs, strict=False) if "LINK RECOVERED" in t.text)
        assert rec.severity == mavlink2.MAV_SEVERITY_NOTICE and "after 5.0 s" in rec.text
    finally:
        sock.close()
        src.close()
        runner.join(10)
        peer.close()
    assert "link recovered after 5.0 s" in capsys.readouterr().err
    assert done["summary"].epochs > 100
