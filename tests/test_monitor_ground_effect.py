"""Near the ground the flight started on, a baro departure below a test's
threshold is ground effect, not a suspicion (features.ground_effect_watch,
monitor.ground_effect_height_m): on a real flight the baro's cautions at
take-off and touchdown go and nothing else moves; failures still count, so
every alarm of the flight, and of the same flight with a baro ramp injected,
is the same with and without the watch. (A fused height below the ground is
not near it: tests/test_monitor_baro_rebase.py's baro dive.)"""

from __future__ import annotations

import pytest

from mavnav.config import config_from_dict
from mavnav.ingest import open_log
from mavnav.pipeline import run
from mavnav.sim.effects import SampleFaults
from mavnav.sim.faults import parse_fault
from mavnav.sinks.base import Sink
from tests.support.paths import SHARED_FLIGHTLOGS

FLIGHT = SHARED_FLIGHTLOGS / "frs_gps_interference.ulg"  # PX4 1.x, starts on the ground at its datum


class _Epochs(Sink):
    name = "epochs"

    def __init__(self):
        self.rows = []

    def epoch(self, r):
        self.rows.append((r.t_us * 1e-6, r.height_fused_m, r.sources["baro_ins"].state))


def _audit(watch: bool, fault=None):
    cfg = config_from_dict({"monitor": {"features": {"ground_effect_watch": watch}}})
    samples = open_log(str(FLIGHT), cfg.ingest)
    if fault is not None:
        samples = SampleFaults([parse_fault(fault)]).apply(samples)
    sink = _Epochs()
    alarms = [(round(ev.t_s, 6), ev.source, ev.previous, ev.state) for ev in run(list(samples), cfg, [sink]).alarms
              if ev.state == "alarm" or ev.previous == "alarm"]
    return sink.rows, alarms


@pytest.mark.realdata
@pytest.mark.skipif(not FLIGHT.exists(), reason="no shared flight logs")
def test_the_baro_cautions_on_the_ground_go_and_nothing_else_moves():
    h_ge = config_from_dict({}).monitor.ground_effect_height_m
    off, alarms_off = _audit(False)
    on, alarms_on = _audit(True)
    caution_off = [(t, h) for t, h, st in off if st == "caution"]
    caution_on = [(t, h) for t, h, st in on if st == "caution"]
    assert len(caution_off) >= 3
    # each caution the watch takes away began where the fused height was within h_ge of the ground
    t0 = off[0][0]
    starts = [t for (t, _), prev in zip(caution_off, [None] + caution_off[:-1])
              if prev is None or t - prev[0] > 1.0]
    prev_h = {t: off[i - 1][1] for i, (t, _, _) in enumerate(off) if i}
    waived = [t for t in starts if t not in {c[0] for c in caution_on}]
    assert waived and all(abs(prev_h[t]) < h_ge for t in waived), [(t - t0, prev_h[t]) for t in waived]
    assert len(caution_on) < len(caution_off)
    assert alarms_on == alarms_off
    # away from the ground the two runs are the same epoch for epoch
    assert [r for r in on if r[1] >= h_ge + 1.0] == [r for r in off if r[1] >= h_ge + 1.0]


@pytest.mark.realdata
@pytest.mark.slow
@pytest.mark.skipif(not FLIGHT.exists(), reason="no shared flight logs")
@pytest.mark.parametrize("onset_rel_s", [3.0, 30.0])
def test_a_baro_ramp_is_alarmed_as_soon_with_the_watch(onset_rel_s):
    cfg = config_from_dict({})
    t0 = next(s.t_us for s in open_log(str(FLIGHT), cfg.ingest) if getattr(s, "t_us", None) is not None) * 1e-6
    fault = f"baro_ramp:onset={t0 + onset_rel_s:.3f},duration=20,magnitude=0.5"
    _, alarms_off = _audit(False, fault)
    _, alarms_on = _audit(True, fault)
    assert any(src == "baro_ins" and st == "alarm" for _, src, _, st in alarms_on)
    assert alarms_on == alarms_off


SITL = SHARED_FLIGHTLOGS / "SITL_wlichon_baseline_00000001.BIN"  # ArduCopter SITL, GPS VZ at 5 Hz, lifts off at 3.6 s


def _baro_events(offset_m: float, window: bool):
    """The baro's state changes on the SITL flight with its baro reading
    ``offset_m`` off on the ground (1.0 s to the lift-off at 3.6 s: the
    propellers' wash), its events in seconds from its first baro sample."""
    from mavnav.samples import BaroHeight

    cfg = config_from_dict({"monitor": {"features": {"ground_effect_window": window}}})
    t0 = next(s.t_us for s in open_log(str(SITL), cfg.ingest) if isinstance(s, BaroHeight)) * 1e-6
    fault = f"baro_step:magnitude={offset_m},onset={t0 + 1.0:.3f},duration=2.6"
    samples = SampleFaults([parse_fault(fault)]).apply(open_log(str(SITL), cfg.ingest))
    return [(round(ev.t_s - t0, 1), ev.state) for ev in run(list(samples), cfg, []).alarms
            if ev.source == "baro_ins"]


@pytest.mark.realdata
@pytest.mark.skipif(not SITL.exists(), reason="no shared flight logs")
def test_the_baro_doppler_window_just_up_from_the_ground_is_no_suspicion():
    """The baro/Doppler test reads a 10 s window: for 10 s after the lift-off
    its start still holds the baro read on the ground in the wash, and a
    departure below the threshold there is ground effect, not a suspicion
    (``features.ground_effect_window``). Without it the 1.6 m read on the
    ground is a caution 11-15 s into the flight, 8 s up."""
    assert [st for _, st in _baro_events(-1.6, False)] == ["caution", "nominal"]
    assert _baro_events(-1.6, True) == []
    # failures still count: 1.8 m is past the threshold, alarmed with or without it
    assert _baro_events(-1.8, True) == _baro_events(-1.8, False)
    assert "alarm" in [st for _, st in _baro_events(-1.8, True)]
