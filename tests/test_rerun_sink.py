"""Rerun sink: what is saved to an .rrd, read back with rerun's own reader,
equals what the monitor reported (values, vehicle times, states, alarms).

Expectations are written out here from the report fields, independently of
the sink's own row functions.
"""

from __future__ import annotations

import math
from collections import defaultdict

import numpy as np
import pytest

from mavnav import pipeline
from tests.support import synthetic
from mavnav.cli.viewer_options import make_viewer_sinks
from mavnav.config import Config
from mavnav.report import (
    CHANNEL_NAMES,
    PAIR_NAMES,
    SOURCES,
    AlarmEvent,
    ChannelReport,
    EpochReport,
    PairReport,
    SourceStatus,
)
from mavnav.samples import (
    AutopilotHeight,
    BaroHeight,
    Gap,
    GnssHeight,
    LinkLost,
    LinkRecovered,
    Notice,
    RangeHeight,
    Reboot,
    Rejected,
    SpecificForceUp,
)
from mavnav.sinks.rerun_sink import BootClock
from tests.support.rerun import read_rrd, same, Capture

NAN = math.nan


# --------------------------------------------------------------------------
# Reading an .rrd back


# --------------------------------------------------------------------------
# What the monitor said, captured


RAW = {BaroHeight: ("baro", "baro_ins", None, "height_ref_m"), GnssHeight: ("gnss", "gnss", 0, "height_ref_m"),
       RangeHeight: ("rangefinder", "rangefinder", 1, "height_agl_m")}


def raw_split(order) -> dict:
    """Where each raw height (boot 0) belongs, written out from the contract: judged at the first
    epoch after it in the stream whose time is not before its own; refused (heights/rejected/...)
    when its source is in alarm there, or usable with no row of its sensor in its channel (NaN)."""
    exp = defaultdict(list)
    pending = []
    for item in order:
        if type(item) in RAW:
            pending.append(item)
        elif isinstance(item, EpochReport):
            later = []
            for s in pending:
                if s.t_us > item.t_us:
                    later.append(s)
                    continue
                sensor, source, ch, attr = RAW[type(s)]
                state = item.sources[source].state
                used = state != "alarm"
                if ch is not None and state in ("nominal", "caution") and math.isnan(item.channels[ch].norm_innov_aux):
                    used = False
                if s.boot == 0:
                    exp[f"heights/{'raw' if used else 'rejected'}/{sensor}"].append((s.t_us * 1000, (getattr(s, attr),)))
            pending = later
    for s in pending:  # never judged: shown as used
        sensor, _, _, attr = RAW[type(s)]
        if s.boot == 0:
            exp[f"heights/raw/{sensor}"].append((s.t_us * 1000, (getattr(s, attr),)))
    return exp


def fin(x: float) -> float:
    return x if math.isfinite(x) else NAN


def expected_scalars(epochs, samples, ns=lambda r: r.t_us * 1000, order=None) -> dict:
    """Rows the viewer should hold; non-finite values are NaN, invalid pairs NaN."""
    exp = defaultdict(list)
    for r in epochs:
        t = ns(r)
        for ch in r.channels:
            exp[f"heights/channel/{ch.name}"].append((t, (ch.height_ref_m,)))
            exp[f"integrity/nis/{ch.name}"].append((t, (ch.nis if ch.dof > 0 else NAN,)))
            exp[f"integrity/norm_innov/{ch.name}"].append((t, (ch.norm_innov_baro, ch.norm_innov_aux)))
        h, s = fin(r.height_fused_m), fin(r.sigma_fused_m)
        exp["heights/fused"].append((t, (h,)))
        exp["heights/fused_sigma"].append((t, (h - s, h + s)))
        for p in r.pairs:
            d, thr = (p.diff_m, p.threshold_m) if p.valid else (NAN, NAN)
            exp[f"integrity/pairs/{p.name}/diff"].append((t, (d,)))
            exp[f"integrity/pairs/{p.name}/threshold"].append((t, (thr, -thr)))
        for src, st in r.sources.items():
            w = (st.window_stat, st.window_low, st.window_high)
            if not all(math.isnan(x) for x in w):
                exp[f"integrity/window/{src}"].append((t, w))
        exp["integrity/vpl"].append((t, (fin(r.vpl_m),)))
        exp["integrity/alert_limit"].append((t, (r.alert_limit_m,)))
    for s in samples:
        if type(s) is AutopilotHeight and s.boot == 0:
            exp["heights/autopilot"].append((s.t_us * 1000, (s.height_ref_m,)))
    if order is not None:
        for entity, rows in raw_split(order).items():
            exp[entity] = sorted(rows, key=lambda r: r[0])
    return exp


def expected_states(epochs) -> dict:
    exp = defaultdict(list)
    last = {}
    for r in epochs:
        lanes = {f"state/source/{s}": r.sources[s].state for s in SOURCES if s in r.sources}
        lanes["state/overall"] = r.overall
        for ch in r.channels:
            lanes[f"state/channel/{ch.name}"] = "used" if ch.used else ("available" if ch.available else "unavailable")
        for entity, state in lanes.items():
            if last.get(entity) != state:
                last[entity] = state
                exp[entity].append((r.t_us * 1000, state))
    return exp


@pytest.fixture(scope="module")
def flight():
    return synthetic.paper_flight(seed=3, schedule=synthetic.Schedule(duration_s=20.0))


@pytest.fixture(scope="module")
def replayed(flight, tmp_path_factory):
    path = tmp_path_factory.mktemp("rrd") / "replay.rrd"
    capture = Capture()
    sinks = make_viewer_sinks("none", None, str(path), live=False)
    summary = pipeline.run(flight.samples, Config(), [capture, *sinks], info={"source": "paper_flight(3)"})
    assert summary.sink_failures == {}
    return capture, read_rrd(path), summary


# --------------------------------------------------------------------------
# Replay of a monitored flight, read back


def test_replay_rrd_has_every_entity_with_the_reported_values(replayed):
    capture, rec, summary = replayed
    assert len(capture.epochs) == summary.epochs > 100
    exp = expected_scalars(capture.epochs, capture.samples, order=capture.order)
    assert exp["heights/raw/gnss"] and exp["heights/raw/baro"] and exp["heights/raw/rangefinder"]
    # every raw height is on one of the two entities
    n_gnss = sum(1 for s in capture.samples if isinstance(s, GnssHeight))
    assert len(rec.scalars["heights/raw/gnss"]) + len(rec.scalars.get("heights/rejected/gnss", [])) == n_gnss
    # every channel, pair and source is there
    for ch in CHANNEL_NAMES:
        assert f"heights/channel/{ch}" in rec.scalars and f"integrity/nis/{ch}" in rec.scalars
    for pair in PAIR_NAMES:
        assert f"integrity/pairs/{pair}/diff" in rec.scalars
    for entity, rows in exp.items():
        assert same(rec.scalars[entity], rows), entity
    assert rec.timelines == {"vehicle_time"}


def test_replay_rrd_state_lanes_are_the_reported_states_at_their_changes(replayed):
    capture, rec, _ = replayed
    exp = expected_states(capture.epochs)
    assert set(exp) == set(rec.states)
    for entity, rows in exp.items():
        assert rec.states[entity] == rows, entity
    # the states at the last epoch can be read off the lanes
    last = capture.epochs[-1]
    for src in SOURCES:
        assert rec.states[f"state/source/{src}"][-1][1] == last.sources[src].state


def test_replay_rrd_alarms_are_text_entries_with_levels(replayed):
    capture, rec, summary = replayed
    assert len(summary.alarms) == len(capture.alarms) > 0
    levels = {"nominal": "INFO", "caution": "WARN", "unavailable": "WARN", "alarm": "ERROR"}
    got = rec.texts["alarms"]
    assert [t for t, _, _ in got] == [e.t_us * 1000 for e in capture.alarms]
    for (t, text, level), e in zip(got, capture.alarms):
        assert text.startswith(f"{e.source}: {e.previous} -> {e.state}")
        assert level == levels[e.state]


def test_replay_rrd_input_rates_match_the_schedule(replayed, flight):
    _, rec, _ = replayed
    # paper_flight: IMU every 20 ms, baro every IMU sample, GNSS every 5th, rangefinder every 2nd
    for kind, rate in (("imu", 50.0), ("baro", 50.0), ("gnss", 10.0), ("range", 25.0)):
        rows = rec.scalars[f"input/rate/{kind}"]
        assert len(rows) >= 18
        inner = [v[0] for _, v in rows[1:]]  # the first second may be partial
        assert inner == [rate] * len(inner), kind
        assert all(t % 1_000_000_000 == 0 for t, _ in rows)


def test_replay_rrd_names_and_colours_every_series_once(replayed):
    _, rec, _ = replayed
    for entity in rec.scalars:
        comps = rec.static[entity]
        assert any(c.endswith(":names") for c in comps), entity
        assert any(c.endswith(":colors") for c in comps), entity
    for entity in rec.states:
        assert "StateConfiguration:colors" in rec.static[entity]


# --------------------------------------------------------------------------
# Hand-made reports: events, reboots, live rows = replay columns


def _report(k: int, t_us: int, boot: int, gnss_state: str) -> EpochReport:
    chans = tuple(
        ChannelReport(name=n, height_ref_m=10.0 + 0.01 * k + i, sigma_height_m=0.5, vel_up_mps=0.1, baro_bias_m=1.0,
                      acc_bias_mps2=0.01, available=i != 1 or k < 5, used=i == 0, nis=0.25 * (k % 4),
                      dof=0 if k % 3 == 0 else 2, norm_innov_baro=0.1 * k, norm_innov_aux=NAN if i == 2 else -0.1 * k)
        for i, n in enumerate(CHANNEL_NAMES)
    )
    pairs = tuple(PairReport(p, diff_m=0.2 * k - j, threshold_m=3.0 + j, exceeded=False, valid=k % 5 != 1)
                  for j, p in enumerate(PAIR_NAMES))
    sources = {s: SourceStatus("nominal", 0.0, "") for s in SOURCES}
    sources["gnss"] = SourceStatus(gnss_state, 0.0, "test", window_stat=1.5 * k, window_low=0.5, window_high=9.0)
    return EpochReport(t_us=t_us, boot=boot, height_fused_m=NAN if k == 4 else 10.0 + 0.01 * k, sigma_fused_m=0.4,
                       channels=chans, pairs=pairs, sources=sources, overall=gnss_state, vpl_m=math.inf if k == 2 else 2.0 + 0.1 * k,
                       alert_limit_m=5.0)


def _feed(sink) -> tuple[list, list]:
    """Boot 0 up to 3.0 s, reboot, boot 1 from 0.5 s; events of every kind."""
    sink.start({"source": "hand-made", "live": False})
    epochs, alarms = [], []
    k = 0
    state = "nominal"
    for boot, t0, t1 in ((0, 1_000_000, 3_000_000), (1, 500_000, 2_000_000)):
        if boot == 1:
            sink.sample(Reboot(t_us=t0, recv_s=0.0, boot=1, last_t_us=3_000_000))
        for t in range(t0, t1 + 1, 100_000):
            sink.sample(SpecificForceUp(t, 0.0, boot, 9.8, "HIGHRES_IMU"))
            sink.sample(BaroHeight(t, 0.0, boot, 10.0 + t * 1e-7, 100000.0, 1))
            if t % 200_000 == 0:
                sink.sample(AutopilotHeight(t, 0.0, boot, 9.0, "GLOBAL_POSITION_INT"))
            if k in (7, 25):  # once in each boot
                sink.sample(Rejected(recv_s=0.0, kind="crc", detail="bad crc"))
                sink.sample(Rejected(recv_s=0.0, kind="out of range", detail="x", t_us=t, boot=boot))
                sink.sample(Gap(t, 0.0, boot, "gnss", 1.25))
                sink.sample(LinkLost(recv_s=0.0, silent_s=2.0))
                sink.sample(LinkRecovered(recv_s=0.0, outage_s=2.5))
                sink.sample(Notice(recv_s=0.0, kind="ignored", text=f"ignoring system 2 ({boot})"))
            new_state = "alarm" if 10 <= k < 15 else "nominal"
            if new_state != state:
                ev = AlarmEvent(t, boot, "gnss", new_state, state, "window statistic high")
                sink.alarm(ev)
                alarms.append(ev)
                state = new_state
            r = _report(k, t, boot, state)
            sink.epoch(r)
            epochs.append(r)
            k += 1
    return epochs, alarms


def _write(tmp_path, live: bool, name: str, **kw):
    [sink] = make_viewer_sinks("none", None, str(tmp_path / name), live=live, **kw)
    epochs, alarms = _feed(sink)
    sink.close(None)
    return epochs, alarms, read_rrd(tmp_path / name)


def test_hand_made_reports_with_a_reboot_read_back(tmp_path):
    epochs, alarms, rec = _write(tmp_path, live=False, name="hand.rrd")
    # boot 1 is shifted to continue where boot 0 ended (3.0 s), from its first time 0.5 s
    def ns(r):
        return r.t_us * 1000 + (2_500_000_000 if r.boot == 1 else 0)

    exp = expected_scalars(epochs, [], ns=ns)
    for entity, rows in exp.items():
        assert same(rec.scalars[entity], rows), entity
    times = [t for t, _ in rec.scalars["heights/fused"]]
    assert times == sorted(times) and len(set(times)) == len(times) - 1  # 3.0 s and boot 1's 0.5 s meet
    assert any("reboot: boot 1" in x for _, x, _ in rec.texts["input/events"])
    # events
    crc = rec.scalars["input/rejected/crc"]
    assert [v for _, v in crc] == [(1.0,), (2.0,)]  # cumulative
    assert crc[0][0] == 1_700_000_000  # no vehicle time of its own: the latest seen
    assert "input/rejected/out_of_range" in rec.scalars
    assert [v for _, v in rec.scalars["input/gaps/gnss"]] == [(1.25,), (1.25,)]
    texts = [x for _, x, _ in rec.texts["input/events"]]
    assert sum("link lost" in x for x in texts) == 2 and sum("link recovered" in x for x in texts) == 2
    assert sum("gap: no gnss" in x for x in texts) == 2
    assert [x for x in texts if x.startswith("ignoring")] == ["ignoring system 2 (0)", "ignoring system 2 (1)"]
    # alarms, with levels
    assert [(t, lv) for t, _, lv in rec.texts["alarms"]] == [(ns(e), "ERROR" if e.state == "alarm" else "INFO")
                                                           for e in alarms]
    # autopilot height (boot 0 part)
    assert rec.scalars["heights/autopilot"][:3] == [(1_000_000_000, (9.0,)), (1_200_000_000, (9.0,)),
                                                   (1_400_000_000, (9.0,))]
    assert [s for _, s in rec.states["state/source/gnss"]] == ["nominal", "alarm", "nominal"]


@pytest.mark.parametrize("live_batch_s", [0.0, 0.25], ids=["rows", "quarter-second-batches"])
def test_live_records_the_same_as_replay_columns(tmp_path, live_batch_s):
    *_, cols = _write(tmp_path, live=False, name="cols.rrd")
    *_, live = _write(tmp_path, live=True, name="live.rrd", live_batch_s=live_batch_s)
    assert cols.data_entities == live.data_entities
    for entity in cols.scalars:
        assert same(cols.scalars[entity], live.scalars[entity]), entity
    assert cols.texts == live.texts
    assert cols.states == live.states
    assert cols.docs == live.docs and len(cols.docs["pilot/readout"]) > 5  # the pilot's readout, rows or columns


def test_live_sends_every_quarter_second_of_vehicle_time_and_at_once_after_an_alarm(tmp_path):
    [sink] = make_viewer_sinks("none", None, str(tmp_path / "live.rrd"), live=True)
    sent = []  # vehicle time of the newest epoch when the writer sent (or queued a batch, sent one entity a message)
    newest = [0]
    flush, queue_batch = sink.writer.flush, sink.writer._queue_batch
    sink.writer.flush = lambda: (sent.append(newest[0]), flush())[1]
    sink.writer._queue_batch = lambda: (sent.append(newest[0]), queue_batch())[1]
    epoch, alarm = sink.epoch, sink.alarm
    alarm_times, checked = set(), []

    def spy_alarm(e):
        alarm_times.add((e.boot, e.t_us))
        alarm(e)

    def spy_epoch(r):
        newest[0] = r.t_us
        epoch(r)
        if (r.boot, r.t_us) in alarm_times:
            assert sink.writer.pending() == 0  # the alarm and its state change are out
            checked.append(r.t_us)

    sink.epoch, sink.alarm = spy_epoch, spy_alarm
    _, alarms = _feed(sink)
    sink.close(None)
    assert len(checked) == len(alarms) == 2
    # about 2.0 s + 1.5 s of flight in 0.25 s batches, plus the alarm epochs
    assert 12 <= len(sent) <= 20
    gaps = np.diff([t for t in sent if t])
    assert gaps[gaps > 0].max() <= 400_000


def test_replay_sends_columns_in_batches_with_the_same_result(tmp_path):
    [sink] = make_viewer_sinks("none", None, str(tmp_path / "small.rrd"), live=False)
    sink.writer.batch_rows = 50  # many send_columns calls during the run
    calls = []
    flush = sink.writer.flush
    sink.writer.flush = lambda: (calls.append(sink.writer.pending()), flush())[1]
    _feed(sink)
    sink.close(None)
    assert len(calls) > 10
    *_, whole = _write(tmp_path, live=False, name="whole.rrd")
    small = read_rrd(tmp_path / "small.rrd")
    for entity in whole.scalars:
        assert same(whole.scalars[entity], small.scalars[entity]), entity
    assert whole.states == small.states and whole.texts == small.texts


def test_boot_clock_is_monotonic_across_reboots():
    c = BootClock()
    assert c.ns(0, 1_000) == 1_000_000
    assert c.ns(0, 5_000_000) == 5_000_000_000
    c.reboot(1, 200_000, 5_100_000)  # vehicle time restarted at 0.2 s; boot 0 ended at 5.1 s
    assert c.ns(1, 200_000) == 5_100_000_000
    assert c.ns(1, 300_000) == 5_200_000_000
    # a late report of boot 0 keeps its own place
    assert c.ns(0, 5_050_000) == 5_050_000_000
    # a boot seen without a Reboot event continues from the last time of the boot before
    assert c.ns(2, 100_000) == 5_200_000_000
    # events without a vehicle time sit at the latest time seen
    assert c.ns(None, None) == 5_200_000_000
    assert np.all(np.diff([c.ns(2, t) for t in range(100_000, 1_000_000, 100_000)]) > 0)
