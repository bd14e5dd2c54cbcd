"""A baro that comes back after its own fault brings its changes, not its offset.

A baro step that stays passes every windowed test once it is past, so the
baro is readmitted at its new level; the aux channels that ran without it
take that level as the baro's bias (``ChannelBank.rebase_baro_bias``) and
keep their height. Checked on the algebra and on a real flight."""

from __future__ import annotations

import numpy as np
import pytest

from mavnav.bank import PAIRS, ChannelBank
from mavnav.channel import DH, H, N_STATES, Model
from mavnav.config import config_from_dict
from mavnav.ingest import open_log
from mavnav.pipeline import run
from mavnav.sim.effects import SampleFaults
from mavnav.sim.faults import parse_fault
from mavnav.sinks.base import Sink
from tests.support.paths import SHARED_FLIGHTLOGS

DKLA = SHARED_FLIGHTLOGS / "dkla_log171.bin"  # ArduCopter 3.3, GPS with VZ at 5 Hz
QUAD = SHARED_FLIGHTLOGS / "aut_quadrotor_local.ulg"  # PX4 1.16, baro and IMU only (no GNSS fix)


def _spd(rng, n):
    a = rng.normal(size=(n, n))
    return a @ a.T + n * np.eye(n)


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_the_rebased_bias_carries_the_channels_height_error_and_the_samples_noise(seed):
    rng = np.random.default_rng(seed)
    bank = ChannelBank(Model.from_config(config_from_dict({})))
    n, nch = N_STATES, bank.x.shape[0]
    full = _spd(rng, n * nch)  # one joint covariance of the three channels' errors
    for a in range(nch):
        bank.P[a] = full[a * n:(a + 1) * n, a * n:(a + 1) * n]
        bank.x[a] = rng.normal(size=n)
    for p, (i, j) in enumerate(PAIRS):
        bank.Pc[p] = full[i * n:(i + 1) * n, j * n:(j + 1) * n]
    c, z, r = 0, 7.5, 0.09
    h = bank.x[c, H]
    bank.rebase_baro_bias(c, z, r)
    assert bank.x[c, DH] == pytest.approx(z - h)
    # the error map: e_dH' = -e_H - n, every other state unchanged
    A = np.eye(n * nch)
    A[c * n + DH, :] = 0.0
    A[c * n + DH, c * n + H] = -1.0
    want = A @ full @ A.T
    want[c * n + DH, c * n + DH] += r
    np.testing.assert_allclose(bank.P[c], want[c * n:(c + 1) * n, c * n:(c + 1) * n], rtol=1e-12, atol=1e-12)
    for p, (i, j) in enumerate(PAIRS):
        np.testing.assert_allclose(bank.Pc[p], want[i * n:(i + 1) * n, j * n:(j + 1) * n], rtol=1e-12, atol=1e-12)


class _Out(Sink):
    def __init__(self):
        self.t, self.h, self.state, self.baro = [], [], [], []

    def epoch(self, r):
        self.t.append(r.t_us * 1e-6)
        self.h.append(r.height_fused_m)
        self.state.append(r.overall)
        self.baro.append(r.baro_height_ref_m)


def _fly(path, spec=None, **monitor):
    cfg = config_from_dict({"monitor": monitor})
    src = open_log(str(path), cfg.ingest)
    if spec:
        src = SampleFaults([parse_fault(spec)]).apply(src)
    out = _Out()
    summary = run(src, cfg, [out])
    return out, summary


@pytest.mark.realdata
@pytest.mark.slow
@pytest.mark.skipif(not DKLA.exists(), reason="no shared flight logs")
@pytest.mark.parametrize("path,onset,length", [(DKLA, 120.0, 60.0), (QUAD, 128.0, 40.0)],
                         ids=["gnss_doppler", "baro_and_imu_only"])
def test_a_baro_step_that_stays_never_reaches_the_output_as_height(path, onset, length):
    """With a GNSS the aux channel that ran without the baro keeps the height;
    with nothing but the IMU the step the baro made against it is given back
    (that flight's output is offered here at one height sensor, which by
    default makes monitoring degraded: monitor.min_height_sensors)."""
    one = {"min_height_sensors": 1} if path == QUAD else {}
    clean, _ = _fly(path, **one)
    faulty, summary = _fly(path, f"baro_step:magnitude=5,onset={onset:g},duration={length:g}", **one)
    alarms = [ev for ev in summary.alarms if ev.source == "baro_ins" and ev.state == "alarm" and ev.t_s >= onset]
    assert alarms and alarms[0].t_s - onset < 1.0
    back = [ev for ev in summary.alarms if ev.source == "baro_ins" and ev.previous == "alarm"
            and ev.state == "nominal" and onset < ev.t_s < onset + length]
    assert back, "the baro is readmitted while its step stays (every windowed test passes it)"
    t, h = np.asarray(faulty.t), np.asarray(faulty.h)
    h0 = np.interp(t, np.asarray(clean.t), np.asarray(clean.h))
    # every fused height the monitor computes in and after the window, whatever its state (on dkla an
    # earlier baro alarm of the flight's own has already put the protection level over the alert limit)
    during = np.isfinite(h) & (t >= onset) & (t <= onset + length + 15.0)
    assert during.sum() > 100
    assert np.max(np.abs(h - h0)[during]) < 3.0  # the step is not height


def _readmissions(summary):
    return [ev.t_s for ev in summary.alarms
            if ev.source == "baro_ins" and ev.previous == "alarm" and ev.state == "nominal"]


@pytest.mark.realdata
@pytest.mark.skipif(not QUAD.exists(), reason="no shared flight logs")
@pytest.mark.parametrize("spec", ["baro_ramp:magnitude=-8,onset=128,duration=0.8",
                                  "baro_ramp:magnitude=6,onset=128,duration=1.2"], ids=["dive", "climb"])
def test_a_fast_ramp_that_snaps_back_is_not_given_back_as_the_baros_offset(spec):
    """The baro+INS channel follows a fast ramp the gate lets through; the
    baro snapping back to its true level is then a jump against the INS, but
    measured from a level the channel had followed along with the fault (the
    window test was already in caution): giving it back at readmission put
    the output 4.2 m (dive) and 6.3 m (climb) off for the rest of the flight."""
    one = {"min_height_sensors": 1}
    clean, _ = _fly(QUAD, **one)
    faulty, summary = _fly(QUAD, spec, **one)
    back = _readmissions(summary)
    assert back and 128.0 < back[0] < 150.0
    t, h = np.asarray(faulty.t), np.asarray(faulty.h)
    h0 = np.interp(t, np.asarray(clean.t), np.asarray(clean.h))
    after = np.isfinite(h) & (t > back[0] + 1.0)
    assert after.sum() > 100
    assert np.max(np.abs(h - h0)[after]) < 0.5


FRS_GPS = SHARED_FLIGHTLOGS / "frs_gps_interference.ulg"  # PX4, baro and IMU only at take-off


@pytest.mark.realdata
@pytest.mark.skipif(not FRS_GPS.exists(), reason="no shared flight logs")
def test_a_take_off_transient_that_dives_and_returns_is_no_step():
    """At this flight's take-off the baro dives 6.4 m below the autopilot's
    height over 0.8 s (prop wash) and is back within 0.6 s. Its jump was
    confirmed as a step of -4.8 m while still diving, the return was never a
    step of its own, and at readmission the output was put 4.8 m above the
    baro (and the autopilot) for the rest of the flight. A step must settle."""
    cfg = config_from_dict({})
    out = _Out()
    summary = run(open_log(str(FRS_GPS), cfg.ingest), cfg, [out])
    back = [s for s in _readmissions(summary) if 281.0 < s < 300.0]
    assert back, "the baro is readmitted after the take-off transient"
    t, h, b = np.asarray(out.t), np.asarray(out.h), np.asarray(out.baro)
    after = np.isfinite(h) & np.isfinite(b) & (t > back[0]) & (t < back[0] + 30.0)
    assert after.sum() > 50
    assert np.max(np.abs(h - b)[after]) < 1.0


@pytest.mark.realdata
@pytest.mark.slow
@pytest.mark.skipif(not DKLA.exists(), reason="no shared flight logs")
@pytest.mark.parametrize("spec", ["baro_step:magnitude=5", "baro_ramp:magnitude=0.5"], ids=["step", "ramp"])
def test_a_fault_that_ended_while_the_baro_was_out_is_not_given_back(spec):
    """On dkla at 132.8 s for 20 s; the flight's own INS/Doppler disagreement
    (146.8 s) puts the INS out beside the baro, so nothing rebases the baro on
    an aux channel at its readmission and the steps it made while out decide
    its level.

    * A 5 m step: its return was never seen as a jump (the gate is anchored
      on the GNSS channel, which the returning baro agrees with), and the +5 m
      step alone was given back: the output 5.2 m off the unfaulted flight at
      'nominal' for the rest of the flight. The GNSS channel reads the baro
      at its level from before, not that level plus the step.
    * A 0.5 m/s ramp: ambiguous with the GNSS for 10 s, then the GNSS blamed
      and the baro nominal with its ramp followed; its snap back (-10.6 m)
      was confirmed as a step from a level no test doubted at that instant
      and given back: the output 10.5 m off. The baro had been in caution
      within baro_step_trust_s of that jump."""
    onset, length = 132.77, 20.0
    clean, _ = _fly(DKLA)
    faulty, summary = _fly(DKLA, f"{spec},onset={onset:g},duration={length:g}")
    back = [s for s in _readmissions(summary) if s > onset + length]
    assert back, "the baro is readmitted after its fault ended"
    t, h = np.asarray(faulty.t), np.asarray(faulty.h)
    h0 = np.interp(t, np.asarray(clean.t), np.asarray(clean.h))
    after = np.isfinite(h) & (t > back[0]) & (t < back[0] + 40.0)
    assert after.sum() > 100
    assert np.max(np.abs(h - h0)[after]) < 1.0


@pytest.mark.realdata
@pytest.mark.skipif(not QUAD.exists(), reason="no shared flight logs")
def test_a_steps_return_soon_after_the_baro_came_back_cancels_the_step():
    """A 5 m baro step for 15 s on a baro-and-IMU-only flight: the step is
    given back when the baro is readmitted while it stays, and its return 5 s
    later is a step of its own, given back at the next readmission, so the
    two cancel. The return opens within baro_step_trust_s of the baro turning
    nominal, but that was a readmission, which set the baro's level: it is
    trusted (without that, the step stayed in the output, 5 m off)."""
    one = {"min_height_sensors": 1}
    clean, _ = _fly(QUAD, **one)
    faulty, summary = _fly(QUAD, "baro_step:magnitude=5,onset=128,duration=15", **one)
    back = _readmissions(summary)
    assert len(back) >= 2 and back[0] < 143.0 < back[1], back
    t, h = np.asarray(faulty.t), np.asarray(faulty.h)
    h0 = np.interp(t, np.asarray(clean.t), np.asarray(clean.h))
    after = np.isfinite(h) & (t > back[1]) & (t < back[1] + 20.0)
    assert after.sum() > 50
    assert np.max(np.abs(h - h0)[after]) < 0.5


@pytest.mark.parametrize("given_back,step,shifted", [((4.95, 0.09), -5.0, True), ((0.0, 0.0), -5.0, False),
                                                    ((4.95, 0.09), -2.0, False)],
                         ids=["returns", "nothing_given_back", "not_its_size"])
def test_the_return_of_a_step_given_back_cancels_it_however_its_jump_was_measured(given_back, step, shifted):
    """With no aux channel, a readmission gives back only steps measured from
    a level no test doubted; but a jump that cancels what an earlier
    readmission gave back (within the gate at their sigmas) is that step's
    return, however it was measured: a caution of the flight's own 1 s before
    a 5 m step ended had left the step in the output."""
    from mavnav.bank import BARO as BARO_C
    from mavnav.monitor.hypotheses import HypothesisLogic

    cfg = config_from_dict({})
    bank = ChannelBank(Model.from_config(cfg))
    logic = HypothesisLogic(cfg, bank)
    t = 100_000_000
    bank.start(0, 1.0)
    logic.start(0, 0)
    logic.last_baro_m, logic.last_baro_us, logic.baro_excluded_us = 1.0, t, t - 10_000_000
    logic.baro_steps.append((t - 9_000_000, step, 0.3, False))  # measured from a doubted level
    logic.baro_given_back = given_back
    h0 = bank.x[BARO_C, H]
    logic._rebase_baro(t, aux=False)
    assert bank.x[BARO_C, H] - h0 == pytest.approx(-step if shifted else 0.0)
    assert logic.baro_given_back == ((0.0, 0.0) if shifted else given_back)
