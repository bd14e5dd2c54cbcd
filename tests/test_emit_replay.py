"""End to end: a simulated fault scenario replayed through the pipeline, emitted to a pymavlink peer."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from mavnav.config import Config
from mavnav.ingest import TlogSource
from mavnav.pipeline import run
from mavnav.report import AlarmEvent
from mavnav.samples import ReferenceSet
from mavnav.sim import load_scenario, simulate
from mavnav.sinks.base import Sink
from mavnav.sinks.mavlink_statustext import SEVERITY_FOR_STATE, StatusTextLimiter, format_text
from test_emit_sink import Peer, udp_sink

F32 = np.float32
SCENARIOS = Path(__file__).resolve().parents[1] / "config" / "scenarios"


class Recorder(Sink):
    name = "recorder"

    def __init__(self):
        self.reports, self.events, self.order, self.references = [], [], [], []

    def sample(self, s):
        if isinstance(s, ReferenceSet):
            self.references.append(s)

    def epoch(self, report):
        self.reports.append(report)
        self.order.append(report)

    def alarm(self, event):
        self.events.append(event)
        self.order.append(event)


@pytest.fixture(scope="module")
def gnss_step_tlog(tmp_path_factory):
    scn = load_scenario(SCENARIOS / "px4_hover_gnss_step.yaml")
    res = simulate(scn, 7)
    path = tmp_path_factory.mktemp("emit") / "gnss_step.tlog"
    path.write_bytes(res.tlog)
    return path, res.faults[0]


def _replay(path, peer, **cfg):
    rec = Recorder()
    sink = udp_sink(peer, **cfg)
    summary = run(TlogSource(path), Config(), [rec, sink], info={"source": str(path), "live": False})
    return rec, sink, summary


@pytest.fixture(scope="module")
def gnss_step_run(gnss_step_tlog):
    """One replay, two MAVLink outputs: every transition (interval 0) and rate-limited (30 s)."""
    path, fault = gnss_step_tlog
    peers = {"every": Peer(), "limited": Peer()}
    sinks = {"every": udp_sink(peers["every"], altitude_rate_hz=5.0, statustext_interval_s=0.0),
             "limited": udp_sink(peers["limited"], statustext_interval_s=30.0)}
    rec = Recorder()
    summary = run(TlogSource(path), Config(), [rec, *sinks.values()], info={"source": str(path), "live": False})
    yield rec, sinks, peers, summary, fault
    for p in peers.values():
        p.close()


def test_replayed_fault_scenario_reaches_the_peer(gnss_step_run):
    rec, sinks, peers, summary, fault = gnss_step_run
    sink, peer = sinks["every"], peers["every"]
    assert not summary.sink_failures and summary.alarms == rec.events
    n_text = len(rec.events)
    first, last = rec.reports[0].t_us, rec.reports[-1].t_us
    sent = sink.counts["ALTITUDE"]
    assert peer.wait_for(lambda: len(peer.of("STATUSTEXT")) == n_text and len(peer.of("ALTITUDE")) == sent)
    seq = [m for m in peer.msgs if m.get_type() in ("ALTITUDE", "STATUSTEXT")]
    alts = peer.of("ALTITUDE")
    # ALTITUDE: 5 Hz of vehicle time, each equal to the report of its epoch
    assert abs(len(alts) - ((last - first) * 5e-6 + 1)) <= 1 and len(rec.reports) > 4 * len(alts)
    by_t = {r.t_us: r for r in rec.reports}
    refs = [x.alt_ref_msl_m for x in rec.references if x.alt_ref_msl_m is not None]
    assert refs and all(r == refs[0] for r in refs) and abs(refs[0] - 488.0) < 5  # home, or GNSS at start-up
    for a in alts:
        r = by_t[a.time_usec]
        np.testing.assert_equal(F32(a.altitude_local), F32(r.height_fused_m))
        np.testing.assert_equal(F32(a.altitude_amsl), F32(refs[0] + r.height_fused_m))
        if r.ok("rangefinder"):
            np.testing.assert_equal(F32(a.bottom_clearance), F32(r.range_height_agl_m))
        else:
            assert math.isnan(a.bottom_clearance)
    # STATUSTEXT: one per transition, in order, right where the alarm happened in the stream
    texts = peer.of("STATUSTEXT")
    for ev, st in zip(rec.events, texts):
        assert st.text == format_text(ev) and st.severity == SEVERITY_FOR_STATE[ev.state]
        i = seq.index(st)
        before = [m.time_usec for m in seq[:i] if m.get_type() == "ALTITUDE"]
        after = [m.time_usec for m in seq[i:] if m.get_type() == "ALTITUDE"]
        assert (not before or before[-1] < ev.t_us) and (not after or ev.t_us <= after[0] < ev.t_us + 200_000 + 50_000)
    # the fault: a GNSS alarm after its onset, within the monitor's alarm time, cleared after its end
    gnss = [(e, st) for e, st in zip(rec.events, texts) if e.source == "gnss"]
    alarm = next(st for e, st in gnss if e.state == "alarm" and e.t_s >= fault["onset_vehicle_s"])
    ev_alarm = next(e for e, st in gnss if st is alarm)
    assert fault["onset_vehicle_s"] < ev_alarm.t_s < fault["onset_vehicle_s"] + 3.0
    assert alarm.text.startswith("mavnav gnss ALARM") and alarm.severity == 2
    cleared = [e for e, st in gnss if e.state == "nominal" and e.t_s > ev_alarm.t_s]
    assert cleared and cleared[0].t_s > fault["onset_vehicle_s"] + fault["duration_s"]


def test_rate_limited_statustexts_keep_every_sources_latest_state(gnss_step_run):
    rec, sinks, peers, summary, _ = gnss_step_run
    peer = peers["limited"]
    # what the limiter must send, from the run's own events and epochs in the pipeline's order
    lim = StatusTextLimiter(30_000_000)
    expected = []
    for item in rec.order:
        if isinstance(item, AlarmEvent):
            expected += lim.offer(item)
        else:
            expected += lim.due(item.boot, item.t_us)
    expected += lim.flush()
    assert peer.wait_for(lambda: len(peer.of("STATUSTEXT")) >= len(expected))
    texts = [m.text for m in peer.of("STATUSTEXT")]
    assert texts == [format_text(e, n) for e, n in expected]
    assert len(texts) < len(rec.events)  # something was coalesced
    # the last STATUSTEXT of each source names the state it ended in
    final = {}
    for ev in rec.events:
        final[ev.source] = ev.state
    for src, state in final.items():
        mine = [t for t in texts if t.startswith(f"mavnav {src} ")]
        assert mine[-1].startswith(f"mavnav {src} {state.upper()}")


SITL_LOGS = Path(__file__).resolve().parents[1] / "sitl_logs"


def _wire_positions(rec: Recorder, seq):
    """Pipeline-order positions of what arrived: each ALTITUDE matched to its report in order."""
    pos = {id(item): k for k, item in enumerate(rec.order)}
    out, j = [], 0
    for m in seq:
        if m.get_type() == "ALTITUDE":
            while rec.reports[j].t_us != m.time_usec:
                j += 1  # IndexError here: an ALTITUDE that is no report, or out of order
            out.append(pos[id(rec.reports[j])])
            j += 1
        else:
            out.append(None)
    return out


@pytest.mark.parametrize("name", ["px4_baro_ramp", "ardupilot_rng_dropout", "ardupilot_input_faults"])
def test_statustext_at_every_transition_of_the_sitl_logs(name):
    path = SITL_LOGS / f"{name}.tlog"
    peer = Peer()
    try:
        rec, sink, summary = _replay(path, peer, altitude_rate_hz=5.0, statustext_interval_s=0.0)
        assert rec.events, "the scenario raised no alarm transition"
        sent = sink.counts["ALTITUDE"]
        assert peer.wait_for(lambda: len(peer.of("STATUSTEXT")) == len(rec.events)
                             and len(peer.of("ALTITUDE")) == sent)
        texts = peer.of("STATUSTEXT")
        assert [t.text for t in texts] == [format_text(e) for e in rec.events]
        assert [t.severity for t in texts] == [SEVERITY_FOR_STATE[e.state] for e in rec.events]
        seq = [m for m in peer.msgs if m.get_type() in ("ALTITUDE", "STATUSTEXT")]
        where = _wire_positions(rec, seq)
        pos = {id(item): k for k, item in enumerate(rec.order)}
        for ev, st in zip(rec.events, texts):
            i = seq.index(st)
            before = [w for w in where[:i] if w is not None]
            after = [w for w in where[i:] if w is not None]
            assert not before or before[-1] < pos[id(ev)]
            assert not after or pos[id(ev)] < after[0]
        if summary.reboots:
            times = [m.time_usec for m in peer.of("ALTITUDE")]
            assert any(b < a for a, b in zip(times, times[1:]))  # the vehicle clock restarted on the wire too
    finally:
        peer.close()
