"""An onboard log's IMU samples as runs of columns (:class:`~mavnav.ingest.onboard.imurun.ImuRun`)
give the same fold as one object per sample: the same stream once expanded, the
same builder state and epochs, the same samples, epochs and alarms in the same
order in every sink, the same audit."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mavnav.audit import AuditSink, audit_file
from mavnav.config import config_from_dict
from mavnav.epochs import EpochBuilder
from mavnav.ingest.onboard.imurun import ImuRun
from mavnav.ingest.onboard.source import OnboardSource, read_record
from mavnav.pipeline import run
from mavnav.samples import BaroHeight, SpecificForceUp
from mavnav.sinks.base import Sink
from mavnav.sinks.csv_sink import CsvSink
from tests.support.paths import SHARED_FLIGHTLOGS

LOGS = ["frs_motor_failure_hexa.ulg", "frs_gps_interference.ulg", "aut_quadrotor_local.ulg",
        "SITL_wlichon_baseline_00000001.BIN"]
# the fast lane keeps a ULog and the DataFlash log expanded and one ULog folded; the rest is slow
SLOW = pytest.mark.slow
EXPAND_LOGS = [LOGS[0], pytest.param(LOGS[1], marks=SLOW), pytest.param(LOGS[2], marks=SLOW), LOGS[3]]
FOLD_LOGS = [LOGS[0]] + [pytest.param(name, marks=SLOW) for name in LOGS[1:]]

_records: dict = {}


def _record(name: str):
    p = SHARED_FLIGHTLOGS / name
    if not p.is_file():
        pytest.skip(f"committed flight log {p} not present (needs /work/shared/flightlogs next to the repo)")
    if name not in _records:
        _records[name] = read_record(p)
    return p, _records[name]


def _expanded(items) -> list:
    out = []
    for s in items:
        out += s.samples(s.lo, s.hi) if type(s) is ImuRun else [s]
    return out


@pytest.mark.realdata
@pytest.mark.parametrize("name", EXPAND_LOGS)
def test_runs_expand_to_the_per_sample_stream(name):
    p, rec = _record(name)
    cfg = config_from_dict({})
    src = OnboardSource(p, cfg.ingest, record=rec)
    ref = list(src)
    ref_stats = src.stats.to_dict()
    runs = list(src.runs())
    in_runs = sum(len(s) for s in runs if type(s) is ImuRun)
    n_imu = sum(type(s) is SpecificForceUp for s in ref)
    assert n_imu > 300 and in_runs > 0.9 * n_imu  # (almost) all IMU samples travel as runs
    assert repr(_expanded(runs)) == repr(ref)
    assert src.stats.to_dict() == ref_stats


class _Recorder(Sink):
    """Every hook's call in order; with ``runs``, it takes IMU runs (expanded into the record)."""

    def __init__(self, runs: bool):
        self.log: list = []
        if runs:
            self.imu_run = lambda run, i, j: self.log.extend(("sample", s) for s in run.samples(i, j))

    def sample(self, s):
        self.log.append(("sample", s))

    def epoch(self, r):
        self.log.append(("epoch", r))

    def alarm(self, ev):
        self.log.append(("alarm", ev))


class _Counting(OnboardSource):
    """Counts the items the pipeline read through ``runs()``."""

    def runs(self):
        self.run_items = 0
        for s in super().runs():
            self.run_items += type(s) is ImuRun
            yield s


@pytest.mark.realdata
@pytest.mark.parametrize("name", FOLD_LOGS)
def test_pipeline_through_runs_is_the_per_sample_fold(name, tmp_path):
    p, rec = _record(name)
    cfg = config_from_dict({})
    out = {}
    for runs in (False, True):
        src = _Counting(p, cfg.ingest, record=rec)
        rec_sink = _Recorder(runs)
        csv = CsvSink(tmp_path / f"{runs}.csv")
        summary = run(src, cfg, [AuditSink(), rec_sink, csv])
        assert (getattr(src, "run_items", 0) > 100) == runs  # the run path is taken, or not
        out[runs] = (repr(rec_sink.log), summary.epochs, summary.spans, summary.monitor_counters,
                     (csv._recv_s, csv._flushed_recv_s), (tmp_path / f"{runs}.csv").read_bytes())
    assert out[True][1] > 100
    for a, b in zip(out[False], out[True]):
        assert a == b


@pytest.mark.realdata
@pytest.mark.parametrize("fault,whole", [("accel_bias_step:magnitude=0.5", False),
                                         ("baro_step:magnitude=5", True),
                                         ("baro_ramp:magnitude=0.5", True)])
def test_a_faulted_source_gives_runs_that_are_its_samples(fault, whole):
    """``--inject`` on an onboard log: FaultedSource's runs expand to exactly
    the samples of iterating it, IMU runs passing whole where the fault cannot
    touch the IMU and going through the fault sample by sample where it can."""
    from mavnav.sim.effects import FaultedSource
    from mavnav.sim.faults import parse_faults

    p, rec = _record("frs_gps_interference.ulg")
    cfg = config_from_dict({})
    onset = int(rec.imu.t_us[0] * 1e-6) + 30
    faults = parse_faults([f"{fault},onset={onset},duration=20"])
    per_sample = FaultedSource(OnboardSource(p, cfg.ingest, record=rec), faults)
    ref = list(per_sample)
    modified = per_sample.injector.report()[0]["samples_modified"]
    assert modified > 20
    src = FaultedSource(OnboardSource(p, cfg.ingest, record=rec), faults)
    items = list(src.runs())
    assert any(type(s) is ImuRun for s in items) == whole
    assert _expanded(items) == ref
    assert src.injector.report()[0]["samples_modified"] == modified
    # and the pipeline reads them: the same audit either way
    a, b = AuditSink(), AuditSink()
    run(ref, cfg, [a])
    run(FaultedSource(OnboardSource(p, cfg.ingest, record=rec), faults), cfg, [b])
    assert (a.alarms, a.availability(), a.epochs) == (b.alarms, b.availability(), b.epochs)
    assert a.input_counts == b.input_counts


@pytest.mark.realdata
def test_audit_through_runs_equals_the_per_sample_audit(monkeypatch):
    p, _ = _record("frs_motor_failure_hexa.ulg")
    cfg = config_from_dict({})
    fast = audit_file(p, cfg)
    monkeypatch.setattr(AuditSink, "imu_run", None)  # a sink without runs: sample by sample
    ref = audit_file(p, cfg)
    assert fast["epochs"] > 100
    assert fast == ref


def _builder_pair(samples, j_max=None, arrays=False):
    """Epochs, counters and state of an EpochBuilder fed ``samples`` one by one,
    and of one fed the IMU stretches through ``_on_imu_run`` (at most ``j_max``
    samples offered per call). With ``arrays``, as an onboard source offers
    them: every stretch a range of the same columns, lists and arrays (the
    builder keeps spans of the arrays)."""
    cfg = config_from_dict({})
    one, many = EpochBuilder(cfg), EpochBuilder(cfg)
    eps_one, eps_many = [], []
    stretches = [s for s in samples if isinstance(s, list)]
    all_t, all_f = [t for s in stretches for t, _ in s], [f for s in stretches for _, f in s]
    t_arr, f_arr = np.array(all_t, dtype=np.int64), np.array(all_f, dtype=np.float64)
    at = 0  # the first column index of the next stretch
    for s in samples:
        if isinstance(s, list):  # an IMU stretch
            for t, f in s:
                eps_one += one.push(SpecificForceUp(t, t * 1e-6, 0, f, "imu"))
            if arrays:
                ts, fs, i, end, cols = all_t, all_f, at, at + len(s), (t_arr, f_arr)
            else:
                ts, fs, i, end, cols = [t for t, _ in s], [f for _, f in s], 0, len(s), ()
            at += len(s)
            while i < end:
                j = end if j_max is None else min(end, i + j_max)
                k, eps = many._on_imu_run(ts, fs, i, j, *cols)
                assert i < k <= j
                eps_many += eps
                i = k
        else:
            eps_one += one.push(s)
            eps_many += many.push(s)

    def state(b):
        if b._span is not None:
            b._span_to_lists()  # the samples waiting, as lists
        return (b.counters, b._raw_t, b._raw_f, b._last_imu_t, b._epoch_t, b._ht[:b._hn].tolist(),
                b._hf[:b._hn].tolist(), b._ks.tolist(), b._ki.tolist())

    return (repr(eps_one), repr(state(one))), (repr(eps_many), repr(state(many)))


def _synthetic():
    """IMU at 200 Hz with: 700 samples before the first baro (more than the builder
    keeps waiting), baro at 10 Hz, a baro before the IMU covers it, a baro dropout of
    3 s (forced epochs), baro samples at the time of an IMU sample, an IMU sample not after the last (first of its stretch: within
    a run, times increase strictly), and an IMU gap."""
    out = []
    t = 1_000_000
    imu = []

    def f(t):
        return 9.81 + 0.3 * math.sin(t * 1e-6)

    for _ in range(700):
        imu.append((t, f(t)))
        t += 5000
    out.append(imu)
    baro_t = t - 2000
    for k in range(120):
        out.append(BaroHeight(baro_t, baro_t * 1e-6, 0, 0.01 * k, 101325.0 - k, 1))
        imu = []
        n = 20 if not 40 <= k < 70 else 0  # k in [40, 70): no baro, the IMU goes on
        end = baro_t + 100_000 * (31 if k == 40 else 1)
        if k == 90:  # an IMU gap of 0.4 s
            t += 400_000
        while t < end:
            imu.append((t, f(t)))
            t += 5000
        if n == 0 and k != 40:
            continue
        if k == 80:  # a stretch that starts with a sample not after the last: counted, dropped
            out += [imu[:3], [(imu[2][0], 0.0)] + imu[3:]]
        else:
            out.append(imu)
        baro_t = end + (3000 if k % 7 else -1000)
        if k % 10 == 3:  # at the time of an IMU sample to come
            baro_t = t + 2 * 5000
    return out


def test_builder_runs_equal_the_samples_one_by_one():
    one, many = _builder_pair(_synthetic())
    assert "forced_epochs" in one[1] and "imu_not_increasing" in one[1] and one[0].count("EpochInputs") > 80
    assert one == many


def test_builder_runs_offered_in_short_slices():
    one, many = _builder_pair(_synthetic(), j_max=7)
    assert one == many


@pytest.mark.parametrize("j_max", [None, 7, 300])
def test_builder_runs_as_array_spans(j_max):
    """The IMU stretches as ranges of one pair of array columns (the source's
    runs): the samples wait as views of them, not lists; the same epochs and state."""
    one, many = _builder_pair(_synthetic(), j_max=j_max, arrays=True)
    assert one == many


def test_builder_spans_waiting_then_one_sample():
    """A span waiting when a sample comes one by one: the span goes into the
    lists first, in order."""
    cfg = config_from_dict({})
    one, many = EpochBuilder(cfg), EpochBuilder(cfg)
    ts = [1_000_000 + 5000 * k for k in range(30)]
    fs = [9.81 + 0.01 * k for k in range(30)]
    t_arr, f_arr = np.array(ts, dtype=np.int64), np.array(fs)
    for b in (one, many):
        b.push(BaroHeight(ts[3] - 1, (ts[3] - 1) * 1e-6, 0, 0.0, 101325.0, 1))
    for t, f in zip(ts, fs):
        one.push(SpecificForceUp(t, t * 1e-6, 0, f, "imu"))
    many._on_imu_run(ts, fs, 0, 20, t_arr, f_arr)
    assert many._span is not None and not many._raw_t
    for t, f in zip(ts[20:], fs[20:]):
        many.push(SpecificForceUp(t, t * 1e-6, 0, f, "imu"))
    assert many._span is None
    assert (one._raw_t, one._raw_f, one._ht[:one._hn].tolist()) == (many._raw_t, many._raw_f, many._ht[:many._hn].tolist())


def test_builder_run_comparison_can_fail():
    """A run that skips a sample is seen (the comparison is not blind)."""
    samples = _synthetic()
    one, _ = _builder_pair(samples)
    bent = [s[:5] + s[6:] if isinstance(s, list) and len(s) > 10 else s for s in samples]
    _, many = _builder_pair(bent)
    assert one != many


def test_csv_sink_takes_a_run_as_its_samples(tmp_path):
    r = ImuRun([10, 20, 30, 40], [9.0, 9.5, 9.8, 9.7], 1, 4, "sensor_combined")
    one, many = CsvSink(tmp_path / "one.csv"), CsvSink(tmp_path / "many.csv")
    for s in r.samples(1, 3):
        one.sample(s)
    many.imu_run(r, 1, 3)
    assert (one._recv_s, one._flushed_recv_s) == (many._recv_s, many._flushed_recv_s) == (30 * 1e-6, 20 * 1e-6)
    one.sample(r.samples(3, 4)[0])
    many.imu_run(r, 3, 4)
    assert (one._recv_s, one._flushed_recv_s) == (many._recv_s, many._flushed_recv_s) == (40 * 1e-6, 20 * 1e-6)


def test_run_samples_are_the_source_objects():
    r = ImuRun([10, 20, 30], [9.0, 9.5, 9.8], 1, 3, "sensor_combined")
    assert len(r) == 2
    assert r.samples(1, 3) == [SpecificForceUp(20, 20 * 1e-6, 0, 9.5, "sensor_combined"),
                               SpecificForceUp(30, 30 * 1e-6, 0, 9.8, "sensor_combined")]
