"""Simulated faults start at their configured vehicle time and touch only their source.

Method: simulate the same scenario and seed with and without one fault (the
random streams are keyed per sensor, so the two runs share all noise), decode
both tlogs with pymavlink and compare message by message.
"""

from __future__ import annotations

from collections import defaultdict

import numpy as np
import pytest

from mavnav.sim import read_truth_csv, scenario_from_dict, simulate
from tests.support.tlog_decode import decode

_TIME_FIELDS = ("time_boot_ms", "time_usec")


def _t(m):
    if hasattr(m, "time_boot_ms"):
        return m.time_boot_ms / 1e3
    return m.time_usec / 1e6


def by_time(msgs):
    """{type: {vehicle time: field tuple}} for messages that carry a time."""
    out = defaultdict(dict)
    for m in msgs:
        if not any(hasattr(m, f) for f in _TIME_FIELDS):
            continue
        d = m.to_dict()
        d.pop("mavpackettype")
        out[m.get_type()][round(_t(m), 6)] = tuple(sorted((k, str(v)) for k, v in d.items()))
    return out


BASE = {
    "duration_s": 25,
    "seed": 21,
    "profile": "px4",
    "trajectory": {"kind": "hover", "height_m": 12, "takeoff": False},
    "rates_hz": {"HIGHRES_IMU": 50},
}


@pytest.fixture(scope="module")
def clean(tmp_path_factory):
    return by_time(decode(tmp_path_factory.mktemp("clean"), simulate(scenario_from_dict(BASE)).tlog, "a.tlog"))

# kind, fault spec (onset 15 s), message types allowed to change, message interval there;
# one fault of each source in the fast lane, the others slow (pytest.param(..., marks=SLOW))
SLOW = pytest.mark.slow
CASES = [
    ({"kind": "gnss_step", "magnitude": 10.0}, {"GPS_RAW_INT"}, 0.1),
    pytest.param({"kind": "gnss_ramp", "magnitude": 0.5}, {"GPS_RAW_INT"}, 0.1, marks=SLOW),
    pytest.param({"kind": "gnss_noise", "magnitude": 3.0}, {"GPS_RAW_INT"}, 0.1, marks=SLOW),
    pytest.param({"kind": "gnss_dropout", "mode": "nofix"}, {"GPS_RAW_INT"}, 0.1, marks=SLOW),
    pytest.param({"kind": "gnss_dropout", "mode": "silent"}, {"GPS_RAW_INT"}, 0.1, marks=SLOW),
    ({"kind": "rng_dropout", "mode": "invalid"}, {"DISTANCE_SENSOR"}, 0.05),
    pytest.param({"kind": "rng_dropout", "mode": "silent"}, {"DISTANCE_SENSOR"}, 0.05, marks=SLOW),
    pytest.param({"kind": "rng_stuck"}, {"DISTANCE_SENSOR"}, 0.05, marks=SLOW),
    pytest.param({"kind": "rng_spikes", "magnitude": 8.0, "probability": 1.0}, {"DISTANCE_SENSOR"}, 0.05, marks=SLOW),
    pytest.param({"kind": "rng_out_of_range", "magnitude": 5.0}, {"DISTANCE_SENSOR"}, 0.05, marks=SLOW),
    ({"kind": "baro_step", "magnitude": 4.0}, {"SCALED_PRESSURE", "HIGHRES_IMU"}, 0.04),
    pytest.param({"kind": "baro_ramp", "magnitude": 0.4}, {"SCALED_PRESSURE", "HIGHRES_IMU"}, 0.04, marks=SLOW),
    pytest.param({"kind": "baro_freeze"}, {"SCALED_PRESSURE", "HIGHRES_IMU"}, 0.04, marks=SLOW),
    ({"kind": "accel_bias_step", "magnitude": 0.3}, {"HIGHRES_IMU"}, 0.02),
    ({"kind": "rate_drop", "magnitude": 0.25, "messages": ["GPS_RAW_INT"]}, {"GPS_RAW_INT"}, 0.1 * 4),
]


@pytest.mark.parametrize("spec,allowed,interval", CASES, ids=lambda c: c.get("kind", "") + (c.get("mode") or "") if isinstance(c, dict) else None)
def test_fault_onset_and_scope(tmp_path, clean, spec, allowed, interval):
    onset, duration = 10.0, 6.0
    fault = dict(spec, onset_s=onset, duration_s=duration)
    faulty = simulate(scenario_from_dict(dict(BASE, faults=[fault])))
    a = clean
    b = by_time(decode(tmp_path, faulty.tlog, "b.tlog"))
    changed_types = set()
    first, last = np.inf, -np.inf
    for typ in set(a) | set(b):
        for t in set(a[typ]) | set(b[typ]):
            if a[typ].get(t) != b[typ].get(t):
                changed_types.add(typ)
                first, last = min(first, t), max(last, t)
    assert changed_types and changed_types <= allowed, changed_types
    jitter = 0.03 * interval  # sample-time jitter of the scenario (2 %) and ms rounding
    assert onset - 1e-3 <= first <= onset + interval + jitter + 1e-3, first
    # HIGHRES_IMU repeats the latest baro sample until the next one (25 Hz)
    tail = 0.04 * 1.03 if spec["kind"].startswith("baro") else 0.0
    assert last < onset + duration + tail, last
    # the truth CSV flags the fault from the first row at or after onset, with its source
    truth = faulty.truth
    active = truth["fault_active"] == 1
    assert truth["t_s"][active].min() == pytest.approx(onset, abs=1e-9)
    assert truth["t_s"][active].max() < onset + duration
    src = {"gnss": "gnss", "rng": "rangefinder", "baro": "baro_ins", "accel": "baro_ins", "rate": "input"}
    assert set(truth["fault_source"][active]) == {src[spec["kind"].split("_")[0]]}
    assert set(truth["fault_kind"][active]) == {spec["kind"]}


@pytest.mark.slow
def test_link_loss_removes_everything_but_the_vehicle_keeps_counting(tmp_path):
    scn = scenario_from_dict(dict(BASE, faults=[{"kind": "link_loss", "onset_s": 10.0, "duration_s": 3.0}]))
    msgs = decode(tmp_path, simulate(scn).tlog, "l.tlog")
    timed = [(m, _t(m)) for m in msgs if any(hasattr(m, f) for f in _TIME_FIELDS)]
    assert not [m for m, t in timed if 10.0 <= t < 13.0]
    before = max(t for m, t in timed if t < 10.0)
    after = min(t for m, t in timed if t >= 13.0)
    assert before > 9.95 and after < 13.02
    # receive time has the same gap; sequence numbers jump (messages were sent, not received)
    recv = np.array([m._timestamp for m in msgs])
    assert np.all(np.diff(recv) >= 0)
    gap = np.argmax(np.diff(recv))
    assert 2.9 < recv[gap + 1] - recv[gap] < 3.2
    assert (msgs[gap + 1].get_seq() - msgs[gap].get_seq()) % 256 != 1


@pytest.mark.slow
def test_reboot_restarts_the_boot_clock_and_sequence(tmp_path):
    scn = scenario_from_dict(dict(BASE, boot_time_at_start_s=100.0,
                                  faults=[{"kind": "reboot", "onset_s": 120.0, "duration_s": 2.5}]))
    res = simulate(scn)
    msgs = decode(tmp_path, res.tlog, "r.tlog")
    att = [m for m in msgs if m.get_type() == "ATTITUDE"]
    t = np.array([m.time_boot_ms for m in att]) / 1e3
    drop = int(np.argmax(t[1:] < t[:-1])) + 1
    assert t[drop - 1] == pytest.approx(120.0, abs=0.03)  # first boot, until the onset
    assert t[drop] == pytest.approx(2.5, abs=0.03)  # new boot: silent for 2.5 s, clock from 0 at onset
    assert t[0] == pytest.approx(100.0, abs=0.03)
    i = msgs.index(att[drop])
    first_after = min(j for j, m in enumerate(msgs) if m._timestamp >= att[drop]._timestamp - 0.05 and j > msgs.index(att[drop - 1]))
    assert msgs[first_after].get_seq() == 0
    assert att[drop]._timestamp - att[drop - 1]._timestamp == pytest.approx(2.5, abs=0.05)
    assert i >= first_after
    # truth: t_s is the same clock as the messages, boot counts the reboot
    tr = res.truth
    assert tr["t_s"][0] == pytest.approx(100.0)
    after = tr["boot"] == 1
    assert np.allclose(tr["t_s"][after], tr["t_sim_s"][after] - 20.0)


def test_same_seed_same_bytes_other_seed_other_bytes():
    scn = scenario_from_dict(dict(BASE, duration_s=10, faults=[{"kind": "rng_spikes", "onset_s": 2, "magnitude": 3}]))
    a, b, c = simulate(scn, 5), simulate(scn, 5), simulate(scn, 6)
    assert a.tlog == b.tlog
    assert a.tlog != c.tlog
    assert np.array_equal(a.truth["true_height_ref_m"], c.truth["true_height_ref_m"])


def test_receive_time_is_vehicle_time_plus_start_plus_latency(tmp_path):
    scn = scenario_from_dict(dict(BASE, duration_s=20, link={"latency_s": 0.02, "latency_jitter_s": 0.005}))
    msgs = decode(tmp_path, simulate(scn).tlog, "t.tlog")
    att = [m for m in msgs if m.get_type() == "ATTITUDE"]
    lat = np.array([m._timestamp - scn.link.start_unix_s - m.time_boot_ms / 1e3 for m in att])
    assert lat.min() >= 0.02 - 1e-3
    assert 0.02 < np.median(lat) < 0.02 + 0.005 * 3
    recv = np.array([m._timestamp for m in msgs])
    assert np.all(np.diff(recv) >= 0)


def test_truth_csv_round_trip(tmp_path):
    scn = scenario_from_dict(dict(BASE, duration_s=12, truth_rate_hz=20,
                                  faults=[{"kind": "gnss_step", "onset_s": 5, "duration_s": 2, "magnitude": 3},
                                          {"kind": "baro_step", "onset_s": 6, "duration_s": 2, "magnitude": 3}]))
    res = simulate(scn)
    path = tmp_path / "truth.csv"
    res.truth.to_csv(path)
    back = read_truth_csv(path)
    assert len(back["t_s"]) == 12 * 20 + 1
    assert np.allclose(back["true_height_ref_m"], res.truth["true_height_ref_m"], atol=1e-5)
    assert np.allclose(back["true_alt_msl_m"] - back["true_height_ref_m"], scn.home.alt_msl_m, atol=1e-4)
    both = (back["t_s"] >= 6) & (back["t_s"] < 7)
    assert set(back["fault_kind"][both]) == {"gnss_step+baro_step"}
    assert set(back["fault_source"][both]) == {"gnss+baro_ins"}
    v = back["true_vel_up_mps"]
    h = back["true_height_ref_m"]
    assert np.allclose(np.gradient(h, back["t_sim_s"]), v, atol=0.02)
