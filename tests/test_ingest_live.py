"""Live links over real UDP on 127.0.0.1: the same samples as the file, link loss
and recovery, prompt close from another thread."""

from __future__ import annotations

import threading
import time

import pytest

from mavnav.config import IngestConfig
from mavnav.errors import InputError
from mavnav.ingest import LiveSource, TlogSource
from mavnav.samples import (
    BaroHeight, LinkLost, LinkRecovered, SpecificForceUp,
)
from tests.support.flightlog import P_GROUND_PA, FlightLog
from tests.support.live import MEASUREMENTS, Sender, no_recv, tlog_records
from tests.support.paths import SHARED_TLOGS

pytestmark = [pytest.mark.integration, pytest.mark.slow]

SITL = SHARED_TLOGS / "sitl" / "copter_rangefinder_nominal.tlog"


def run_live(records, cfg, *, speed, pause_at=None, pause_s=0.0, tail_s=0.6):
    src = LiveSource("udpin:127.0.0.1:0", cfg)
    sender = Sender(records, src.local_address, speed=speed, pause_at=pause_at, pause_s=pause_s)
    out = []

    def stop_later():
        sender.join()
        time.sleep(tail_s)
        src.close()

    stopper = threading.Thread(target=stop_later, daemon=True)
    sender.start()
    stopper.start()
    for s in src:
        out.append(s)
    stopper.join(5)
    return out, src.stats


def test_live_udp_gives_the_same_samples_as_the_file(tmp_path):
    f = FlightLog(tmp_path / "live.tlog")
    f.fly(0, 8, height_fn=lambda t: 0.0 if t < 3 else (t - 3.0))
    path = f.close()
    cfg = IngestConfig(link_timeout_s=5.0)
    want = list(TlogSource(path, cfg))
    got, stats = run_live(tlog_records(path), cfg, speed=8.0)
    assert no_recv(got) == no_recv(want)
    assert stats.samples["imu"] == 800 and stats.vehicle.sysid == 1


@pytest.mark.realdata
@pytest.mark.skipif(not SITL.is_file(), reason="shared/tlogs not beside the checkout")
def test_live_replay_of_a_recorded_sitl_flight(tmp_path):
    recs = tlog_records(SITL)
    t0 = recs[0][0]
    recs = [r for r in recs if r[0] - t0 <= 40.0]  # the first 40 s, take-off included
    prefix = tmp_path / "sitl40.tlog"
    prefix.write_bytes(b"".join(int(round(t * 1e6)).to_bytes(8, "big") + fr for t, fr in recs))
    cfg = IngestConfig(link_timeout_s=5.0)
    want = list(TlogSource(prefix, cfg))
    got, _ = run_live(recs, cfg, speed=20.0)
    assert len(no_recv(want)) > 3000
    assert no_recv(got) == no_recv(want)


def test_pause_is_link_loss_then_recovery(tmp_path):
    f = FlightLog(tmp_path / "pause.tlog")
    f.fly(0, 4)
    cfg = IngestConfig(link_timeout_s=0.4)
    # closed 0.15 s after the last datagram: before the link times out again
    got, stats = run_live(tlog_records(f.close()), cfg, speed=4.0, pause_at=0.5, pause_s=1.2, tail_s=0.15)
    lost, rec = [s for s in got if isinstance(s, LinkLost)], [s for s in got if isinstance(s, LinkRecovered)]
    assert len(lost) == 1 and len(rec) == 1 and stats.link_losses == 1
    assert got.index(lost[0]) < got.index(rec[0])
    assert lost[0].silent_s >= 0.4
    assert rec[0].outage_s == pytest.approx(1.2, abs=0.35)
    # samples keep coming after the recovery, and nothing sent was lost
    assert any(isinstance(s, BaroHeight) for s in got[got.index(rec[0]):])
    assert stats.samples["imu"] == 400


def test_close_from_another_thread_stops_promptly():
    src = LiveSource("udpin:127.0.0.1:0", IngestConfig())
    done = threading.Event()

    def consume():
        for _ in src:
            pass
        done.set()

    th = threading.Thread(target=consume, daemon=True)
    th.start()
    time.sleep(0.2)
    t = time.monotonic()
    src.close()
    assert done.wait(2.0)
    assert time.monotonic() - t < 1.0


def test_injected_clock_stamps_receive_time(tmp_path):
    f = FlightLog(tmp_path / "clock.tlog")
    f.fly(0, 1)
    ticks = iter(range(10**9))
    # a configured baro reference: nothing waits for a home this 1 s flight never sends
    cfg = IngestConfig(link_timeout_s=1e6, baro_reference={"source": "config", "value": P_GROUND_PA})
    src = LiveSource("udpin:127.0.0.1:0", cfg, clock=lambda: 1000.0 + next(ticks))
    sender = Sender(tlog_records(f.close()), src.local_address, speed=10.0)
    got = []
    sender.start()
    for s in src:
        got.append(s)
        if isinstance(s, SpecificForceUp) and len([g for g in got if isinstance(g, SpecificForceUp)]) >= 20:
            src.close()
    assert all(s.recv_s >= 1000.0 for s in got if isinstance(s, MEASUREMENTS))


def test_bad_connection_string_is_input_error():
    with pytest.raises(InputError, match="does-not-exist-mavnav,57600: cannot open"):
        LiveSource("/dev/does-not-exist-mavnav,57600", IngestConfig())
