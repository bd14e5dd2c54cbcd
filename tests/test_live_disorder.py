"""Reordered, stale and re-stamped packets on a real UDP link (127.0.0.1):

* 5 % of datagrams swapped with their neighbour lost 2-3 % of epochs (the late
  samples refused as out of order): frames are put back in MAVLink sequence
  order, and the epochs equal a replay of the file;
* two packets stamped 5 s old caused a false reboot (the second "confirmed"
  the first): a new time base is confirmed only by several messages, and an
  isolated stale packet is dropped and counted;
* a vehicle clock stepping back 1 s lost 1 s of samples (out of order until
  time caught up): a step confirmed like a reboot keeps one timeline.
"""

from __future__ import annotations

import random
import socket
import threading
import time

import pytest
from pymavlink.dialects.v20 import common as mav2

from mavnav.config import Config
from mavnav.ingest import LiveSource, TlogSource
from mavnav.pipeline import run
from mavnav.samples import Notice, Reboot, Rejected
from mavnav.sim.inject import reframe
from mavnav.sinks.base import Sink
from tests.support.live import tlog_records
from tests.support.paths import SITL_LOGS

pytestmark = [pytest.mark.integration, pytest.mark.slow]

LOGS = SITL_LOGS
ATTITUDE = 30


class Record(Sink):
    name = "record"

    def __init__(self):
        self.rows = []
        self.events = []

    def epoch(self, r):
        self.rows.append((r.t_us, r.boot, r.height_fused_m, r.sigma_fused_m, r.overall))

    def sample(self, s):
        if isinstance(s, (Reboot, Notice)) or (isinstance(s, Rejected) and s.kind not in ("invalid_quality",)):
            self.events.append(s)


def _msgid(frame: bytes) -> int:
    return frame[5] if frame[0] == 0xFE else frame[7] | (frame[8] << 8) | (frame[9] << 16)


def _replay(path):
    cfg = Config()
    rec = Record()
    run(TlogSource(path, cfg.ingest), cfg, [rec])
    return rec


def _live(datagrams):
    """Send datagrams in this order (flow-controlled, not paced) into a LiveSource running the
    whole pipeline; close once everything was parsed and handled."""
    cfg = Config()
    src = LiveSource("udpin:127.0.0.1:0", cfg.ingest)
    rec = Record()
    done = {}
    runner = threading.Thread(target=lambda: done.setdefault("s", run(src, cfg, [rec], info={"live": True})),
                              daemon=True)
    runner.start()
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        for i, d in enumerate(datagrams):
            sock.sendto(d, src.local_address)
            if i % 20 == 19:
                time.sleep(0.002)  # flow control for the kernel buffer, not pacing
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline and (src.backlog_bytes or not src._queue.empty()):
            time.sleep(0.02)
        time.sleep(0.4)  # held frames of a sequence gap expire
    finally:
        sock.close()
        src.close()
        runner.join(20)
    return rec, src.stats


def _batched(recs, batch_s=0.02):
    out = []
    for t, f in recs:
        if out and t - out[-1][0] <= batch_s:
            out[-1][1].extend(f)
        else:
            out.append([t, bytearray(f)])
    return [bytes(b) for _, b in out]


def _write(path, recs):
    path.write_bytes(b"".join(int(round(t * 1e6)).to_bytes(8, "big") + f for t, f in recs))
    return path


def test_five_percent_reordered_datagrams_lose_no_epoch(tmp_path):
    recs = tlog_records(LOGS / "px4_hover_gnss_step.tlog")
    want = _replay(LOGS / "px4_hover_gnss_step.tlog")
    dg = _batched(recs)
    rng = random.Random(5)
    swapped, i = 0, 0
    while i < len(dg) - 1:
        if rng.random() < 0.05:
            dg[i], dg[i + 1] = dg[i + 1], dg[i]
            swapped += 1
            i += 2
        else:
            i += 1
    assert swapped > 0.04 * len(dg)
    got, st = _live(dg)
    assert not [e for e in got.events if isinstance(e, Rejected) and e.kind in ("out_of_order", "duplicate")]
    assert len(got.rows) == len(want.rows) and got.rows == want.rows
    assert st.seq_missing == 0  # every gap was filled by its late datagram


def test_two_stale_packets_are_no_reboot(tmp_path):
    recs = tlog_records(LOGS / "px4_hover_gnss_step.tlog")
    want = _replay(LOGS / "px4_hover_gnss_step.tlog")
    # two ATTITUDE packets of 5 s ago arrive again at 30 s (a radio flushing its buffer)
    old = [k for k, (t, f) in enumerate(recs) if _msgid(f) == ATTITUDE and abs(t - recs[0][0] - 25.0) < 0.1][:2]
    at = next(k for k, (t, f) in enumerate(recs) if t - recs[0][0] >= 30.0)
    dg = [f for _, f in recs[:at]] + [recs[k][1] for k in old] + [f for _, f in recs[at:]]
    got, st = _live(dg)
    assert st.reboots == 0 and not [e for e in got.events if isinstance(e, Reboot)]
    stale = [e for e in got.events if isinstance(e, Rejected) and e.kind == "stale"]
    assert len(stale) == 2 and st.rejected["stale"] == 2
    assert got.rows == want.rows


def _restamp(frame: bytes, dt_us: int) -> bytes:
    """The same message with its vehicle time fields moved by ``dt_us``."""
    m = mav2.MAVLink(None)
    m.robust_parsing = True
    msg = m.parse_char(frame)
    if msg is None:
        return frame
    changed = False
    if hasattr(msg, "time_boot_ms") and msg.time_boot_ms:
        msg.time_boot_ms = max(0, msg.time_boot_ms + dt_us // 1000)
        changed = True
    if hasattr(msg, "time_usec") and 0 < msg.time_usec < 10**15:
        msg.time_usec = max(0, msg.time_usec + dt_us)
        changed = True
    return reframe(frame, msg) if changed else frame


def test_vehicle_clock_stepping_back_one_second_loses_nothing(tmp_path):
    recs = tlog_records(LOGS / "px4_hover_gnss_step.tlog")
    want = _replay(LOGS / "px4_hover_gnss_step.tlog")
    t0 = recs[0][0]
    stepped = [(t, _restamp(f, -1_000_000) if t - t0 >= 30.0 else f) for t, f in recs]
    got, st = _live(_batched(stepped))
    assert st.reboots == 0
    dropped = [e for e in got.events if isinstance(e, Rejected) and e.kind in ("out_of_order", "duplicate", "stale")]
    assert len(dropped) <= 5, dropped[:5]
    steps = [e for e in got.events if isinstance(e, Notice) and e.kind == "clock_step"]
    assert len(steps) == 1 and st.clock_steps == 1
    back_s = float(steps[0].text.split("stepped back ")[1].split(" s")[0])
    assert abs(back_s - 1.0) <= 0.05  # the last old time and the first new one, 1 s back less a sample
    # one timeline: as many epochs as the unstepped file, the same before the step
    assert abs(len(got.rows) - len(want.rows)) <= 3
    cut = 30_000_000
    assert [r for r in got.rows if r[0] < cut - 500_000] == [r for r in want.rows if r[0] < cut - 500_000]
    assert all(b[0] > a[0] for a, b in zip(got.rows, got.rows[1:]))
