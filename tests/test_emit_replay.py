"""End to end: a simulated fault scenario replayed through the pipeline, emitted to a pymavlink peer."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mavnav.config import Config
from mavnav.ingest import TlogSource
from mavnav.pipeline import run
from mavnav.report import AlarmEvent
from mavnav.samples import LinkLost, LinkRecovered, Notice, Reboot, ReferenceSet
from mavnav.sim import load_scenario, simulate
from mavnav.sinks.base import Sink
from mavnav.sinks.mavlink_statustext import SEVERITY_FOR_STATE, StatusTextLimiter, format_text
from pymavlink.dialects.v20 import common as mavlink2
from tests.support.emit import Peer, texts_of, udp_sink
from tests.support.paths import SCENARIOS, SITL_LOGS

pytestmark = [pytest.mark.integration, pytest.mark.slow]

F32 = np.float32


class Recorder(Sink):
    name = "recorder"

    def __init__(self):
        self.reports, self.events, self.order, self.references = [], [], [], []

    def sample(self, s):
        if isinstance(s, ReferenceSet):
            self.references.append(s)
        elif isinstance(s, (LinkLost, LinkRecovered, Reboot, Notice)):
            self.order.append(s)

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


def expected_texts(order, interval_us=0):
    """(text, severity, event) the sink must send for the pipeline's items in order: an
    unavailable source that no epoch of its boot has yet shown in use is starting up
    (INFO, worded STARTING); texts are compared with the chunk padding collapsed."""
    used = set()
    lim = StatusTextLimiter(interval_us)
    out = []

    def send(items):
        for ev, n in items:
            starting = ev.state == "unavailable" and (ev.boot, ev.source) not in used
            sev = mavlink2.MAV_SEVERITY_INFO if starting else SEVERITY_FOR_STATE[ev.state]
            out.append((" ".join(format_text(ev, n, starting).split()), sev, ev))

    for item in order:
        if isinstance(item, AlarmEvent):
            send(lim.offer(item))
        elif isinstance(item, LinkLost):  # said at once, pending texts first
            send(lim.flush())
            out.append((f"mavnav input LINK LOST: no data for {item.silent_s:.1f} s", mavlink2.MAV_SEVERITY_ERROR, item))
        elif isinstance(item, LinkRecovered):
            out.append((f"mavnav input LINK RECOVERED after {item.outage_s:.1f} s", mavlink2.MAV_SEVERITY_NOTICE, item))
        elif isinstance(item, Reboot):  # said at once, the old boot's pending texts first
            send(lim.flush())
            out.append((f"mavnav input VEHICLE REBOOTED: its time restarted at {item.t_us * 1e-6:.1f} s after "
                        f"{item.last_t_us * 1e-6:.1f} s (boot {item.boot}); the monitor starts again",
                        mavlink2.MAV_SEVERITY_NOTICE, item))
        elif isinstance(item, Notice):
            sev = mavlink2.MAV_SEVERITY_NOTICE if item.kind == "clock_step" else mavlink2.MAV_SEVERITY_INFO
            out.append((" ".join(f"mavnav input {item.text}".split()), sev, item))
        else:
            used.update((item.boot, k) for k, st in item.sources.items() if st.state != "unavailable")
            send(lim.due(item.boot, item.t_us))
    send(lim.flush())
    return out


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
    n_text = len(expected_texts(rec.order))  # every transition, and what the input said (the vehicle chosen)
    assert n_text > len(rec.events)
    first, last = rec.reports[0].t_us, rec.reports[-1].t_us
    sent = sink.counts["ALTITUDE"]
    assert peer.wait_for(lambda: len(texts_of(peer.msgs, strict=False)) == n_text and len(peer.of("ALTITUDE")) == sent)
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
    texts = texts_of(peer.msgs)
    want = expected_texts(rec.order)
    assert [(t.text, t.severity) for t in texts] == [(w[0], w[1]) for w in want]
    assert any(w[1] == mavlink2.MAV_SEVERITY_INFO for w in want)  # start-up: sources wait for data
    assert any(t.text.startswith("mavnav input monitoring system 1") and t.severity == mavlink2.MAV_SEVERITY_INFO
               for t in texts)
    texts = [t for t, w in zip(texts, want) if isinstance(w[2], AlarmEvent)]  # the transitions
    assert len(texts) == len(rec.events)
    for ev, st in zip(rec.events, texts):
        i = seq.index(st.first)
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
    expected = expected_texts(rec.order, 30_000_000)
    assert peer.wait_for(lambda: len(texts_of(peer.msgs, strict=False)) >= len(expected))
    texts = [t.text for t in texts_of(peer.msgs)]
    assert texts == [e[0] for e in expected]
    assert len([t for t in texts if not t.startswith("mavnav input monitoring")]) < len(rec.events)  # coalesced
    # the last STATUSTEXT of each source names the state it ended in
    final = {}
    for ev in rec.events:
        final[ev.source] = ev.state
    for src, state in final.items():
        mine = [t for t in texts if t.startswith(f"mavnav {src} ")]
        assert mine[-1].startswith(f"mavnav {src} {state.upper()}") or (
            state == "unavailable" and mine[-1].startswith(f"mavnav {src} STARTING"))




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
        want = expected_texts(rec.order)  # every transition, and a recorded link loss as it happened
        assert peer.wait_for(lambda: len(texts_of(peer.msgs, strict=False)) == len(want)
                             and len(peer.of("ALTITUDE")) == sent)
        texts = texts_of(peer.msgs)
        assert [(t.text, t.severity) for t in texts] == [(w[0], w[1]) for w in want]
        # never cut: every chunk but the last fills the field; words are whole
        for t in texts:
            assert t.id != 0 or len(t.parts) == 1
            assert all(len(p) == 50 for _, p in sorted(t.parts)[:-1])
        seq = [m for m in peer.msgs if m.get_type() in ("ALTITUDE", "STATUSTEXT")]
        where = _wire_positions(rec, seq)
        pos = {id(item): k for k, item in enumerate(rec.order)}
        for (_, _, ev), st in zip(want, texts):
            i = seq.index(st.first)
            before = [w for w in where[:i] if w is not None]
            after = [w for w in where[i:] if w is not None]
            assert not before or before[-1] < pos[id(ev)]
            assert not after or pos[id(ev)] < after[0]
        if summary.reboots:
            times = [m.time_usec for m in peer.of("ALTITUDE")]
            assert any(b < a for a, b in zip(times, times[1:]))  # the vehicle clock restarted on the wire too
            # every reboot said, at NOTICE: starting again is no error
            said = [t for t in texts if "VEHICLE REBOOTED" in t.text]
            assert len(said) == summary.reboots and all(t.severity == mavlink2.MAV_SEVERITY_NOTICE for t in said)
        # nothing the input says about itself, nor a source starting up, is an ERROR
        for (_, _, item), t in zip(want, texts):
            if isinstance(item, (Reboot, Notice)) or "STARTING" in t.text:
                assert t.severity >= mavlink2.MAV_SEVERITY_NOTICE, t.text
    finally:
        peer.close()
