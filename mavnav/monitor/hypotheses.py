"""``mode: adaptive`` (the default): fault hypotheses, tests that return
verdicts, one decision table.

Every epoch the tests below each return a :class:`~.verdict.Verdict`;
:func:`.table.judge` turns them into one situation (isolated, ambiguous,
inconsistent, suspect, clear) and :data:`.table.TABLE` into states and
actions. The tests, with the hypotheses a failure implicates:

* ``gnss`` / ``rangefinder`` innovation (each sensor in its own channel):
  a chi-square gate per sample (a rejected sample never enters) and a
  two-sided CUSUM for ramps and small steps; implicates the sensor and the
  baro (the channel's prediction rests on the baro; the INS between samples
  is held by the baro rows, so an INS fault shows first in the baro/INS
  test), or the sensor and the INS when the baro is excluded; a sudden jump
  of the innovation (against the stream's measured sample-to-sample
  scatter) while the same epoch's baro row is clean implicates the sensor
  alone;
* ``baro/INS`` (:mod:`.inscheck`): the baro's change over a window against the
  INS, and a per-sample jump gate; implicates the baro and the INS, and a
  clear pass rules both out;
* ``raw GNSS-rangefinder`` (:mod:`.rawcheck`): the two raw aux heights, no
  baro and no INS; implicates those two, and a clear pass rules both out;
* ``rangefinder envelope``: readings refused at the bottom (or top) of the
  rangefinder's range, or frozen, while the other sources put the vehicle
  inside it; implicates the rangefinder alone. Entering and leaving the range
  is normal and raises nothing.

No latch: an excluded source is readmitted after ``readmit_s`` of raw
consistency (an aux sensor against the others' fused height; the baro
against the INS and, where a channel runs without it, against that
channel's level). An aux channel that went ``coast_reinit_s`` without its
sensor, or whose sigma passed ``max_channel_sigma_m``, is re-initialised from
the baro+INS channel when the sensor returns. The fused output holds only
channels whose sources the evidence clears; with none, it is NaN and the
monitor is unavailable.
"""

from __future__ import annotations

import dataclasses
import math
import statistics
from collections import deque
from typing import Callable, Optional

import numpy as np

from ..bank import BARO, GNSS, PAIRS, RNG, ChannelBank
from ..channel import EpochInputs
from ..config import Config
# the sensor words (the names GNSS, RNG, BARO are the bank's channel indices here)
from ..sensors import BARO as BARO_S, BARO_INS as BARO_INS_S, GNSS as GNSS_S, INS as INS_S
from ..sensors import RANGEFINDER as RANGEFINDER_S
from .barolevel import BaroLevel
from .baronoise import BaroNoiseMeter
from .cusum import Cusum, threshold_for
from .decision import Decision, diff_sigmas, pair_reports_scaled
from .doppler import MIN_SPAN_FRAC, DopplerCheck, Exceedance, InsDopplerCheck
from .drift import DriftCheck, gm_slope_var_factor
from .fusion import fuse_heights
from .inscheck import InsBaroCheck
from .jumps import Jump, new_jump
from .kink import KinkSeries, MeanSquare, isolate, kink_fit, onsets
from .levels import chi2_gate, normal_k
from .protection import protection_level
from .rawcheck import RawAuxCheck
from .scale import LagSeries, MedianScale, ResidualScale
from .table import Judgement, judge
from .tracker import SourceTracker
from .verdict import SENSOR_SOURCES, Verdict, live_hypotheses
from .window import RejectionWindow

AUX = ((GNSS, GNSS_S), (RNG, RANGEFINDER_S))
LABEL = {s: s.word for s in SENSOR_SOURCES}  # GNSS, rangefinder, baro+INS
CHANNEL_OF = {GNSS_S: GNSS, RANGEFINDER_S: RNG, BARO_INS_S: BARO}
REFUSAL_KINDS = ("out_of_range", "invalid_status", "stuck", "impossible")
_LEVEL_IMPLICATES = {name: frozenset((BARO_S, name)) for _, name in AUX}
_LEVEL_TEST = {name: f"baro level against {LABEL[name]}" for _, name in AUX}
_LEVEL_SCALE = {name: f"level_{name}" for _, name in AUX}
_INV_SQRT6 = 1.0 / math.sqrt(6.0)
_KINK_KEYS = {name: (f"{name}-ins", f"{name}-baro") for _, name in AUX}
_DISPLAY_TEST = {GNSS_S: "gnss innovation", RANGEFINDER_S: "rangefinder innovation", BARO_INS_S: "baro/INS"}
_ONLY = {name: frozenset((name,)) for _, name in AUX}
_WITH_BARO = {name: frozenset((name, BARO_S)) for _, name in AUX}
_WITH_BARO_INS = {name: frozenset((name, BARO_S, INS_S)) for _, name in AUX}
_WITH_INS = {name: frozenset((name, INS_S)) for _, name in AUX}
_BARO_AND_INS = frozenset((BARO_S, INS_S))
_INS_ONLY = frozenset((INS_S,))
_BARO_ONLY = frozenset((BARO_S,))
_NOTHING: frozenset = frozenset()
_DOUBTED = ("caution", "alarm")


def _last(q: deque, n: int) -> list:
    """``list(q)[-n:]`` without copying the whole deque."""
    return [q[i] for i in range(-min(n, len(q)), 0)]


# A stream's rate: the mean of its intervals, each new one weighted this much,
# and the rate assumed before the second sample.
RATE_EMA_WEIGHT = 0.1
RATE_BEFORE_DATA_HZ = 10.0
# CUSUM thresholds are computed once per rate step of this many hertz.
CUSUM_RATE_STEP_HZ = 0.5
# How far back (in clean baro samples) the baro offset scale looks for
# references at least baro_jump_confirm_s old.
OFFSET_SEARCH_SAMPLES = 16


class _Rate:
    """Samples per second of one stream, from its own intervals (EMA)."""

    def __init__(self) -> None:
        self.last_us: Optional[int] = None
        self.interval_s = math.nan

    def push(self, t_us: int) -> None:
        if self.last_us is not None and t_us > self.last_us:
            dt = (t_us - self.last_us) * 1e-6
            self.interval_s = (dt if self.interval_s != self.interval_s
                               else (1.0 - RATE_EMA_WEIGHT) * self.interval_s + RATE_EMA_WEIGHT * dt)
        self.last_us = t_us

    @property
    def hz(self) -> float:
        if self.interval_s == self.interval_s and self.interval_s > 0:
            return 1.0 / self.interval_s
        return RATE_BEFORE_DATA_HZ


class HypothesisLogic:
    def __init__(self, cfg: Config, bank: ChannelBank):
        self.m = m = cfg.monitor
        self.f = m.features
        self.bank = bank
        self.k_cmp = normal_k(m.false_alarm_prob)
        self.k_ff = normal_k(m.integrity_risk)
        self.k_md = normal_k(min(m.integrity_risk / m.fault_prior_prob, 1.0))
        self.gate = chi2_gate(m.gate_prob)
        self.baro_gate = chi2_gate(m.baro_jump_prob)
        self.persist_us = int(m.persist_s * 1e6)
        self.readmit_us = int(m.readmit_s * 1e6)
        self.validate_us = int(m.validate_s * 1e6)
        self.feedback_us = int(m.feedback_interval_s * 1e6)
        self.stale_us = {GNSS: int(m.stale_gnss_s * 1e6), RNG: int(m.stale_rng_s * 1e6)}
        self.stale_baro_us = int(m.stale_baro_s * 1e6)
        self.coast_us = int(m.coast_reinit_s * 1e6)
        self.hold_restart_us = int(m.hold_restart_s * 1e6)
        self.warmup_us = int(m.warmup_s * 1e6)
        self.baro_doppler_window_us = int(m.baro_doppler_window_s * 1e6)
        self.sudden_persist_us = int(m.sudden_jump_persist_s * 1e6)
        self.kink_margin = chi2_gate(m.kink_isolation_prob)
        self.t0_us = 0
        self.glitch_restarts = 0  # starts again on a baro glitch, over this logic's life (reported by the audit)
        self._h_cache: dict[int, tuple] = {}  # rate key -> (h, slow over fast threshold)
        self._h_last: dict[str, tuple] = {}  # stream -> (its interval when last asked, (h, ratio))

    # ------------------------------------------------------------------ state

    def start(self, t_us: int, boot: int, at_datum: bool = True) -> None:
        m = self.m
        self.t0_us = t_us
        self.boot = boot
        clear_us = int(m.clear_s * 1e6)
        self.trackers = {s: SourceTracker(s, t_us, boot, clear_us=clear_us) for s in SENSOR_SOURCES}
        fast_k = m.cusum_fast_k_sigma if m.mode != "paper" else 0.0
        self.cusum = {s: Cusum(m.cusum_k_sigma, m.cusum_clip_sigma, fast_k) for s in (GNSS_S, RANGEFINDER_S)}
        self.rates = {s: _Rate() for s in (GNSS_S, RANGEFINDER_S, BARO_INS_S)}
        self.rejections = {s: RejectionWindow(m.window_s) for s in SENSOR_SOURCES}
        self.excluded: set[str] = set()
        self.last_accept_us: dict[int, Optional[int]] = {GNSS: None, RNG: None}
        self.last_seen_us: dict[int, Optional[int]] = {GNSS: None, RNG: None}
        self.last_baro_us = t_us
        self.last_baro_m: Optional[float] = None
        # the baro's robust level at each GNSS sample, for the baro/Doppler check
        self.baro_level = (BaroLevel(m.baro_doppler_level_span_s, m.baro_doppler_window_s, m.doppler_max_gap_s,
                                     m.baro_doppler_end_samples)
                           if m.baro_doppler_level_span_s > 0 else None)
        self.slow_imu_hz: Optional[float] = None  # set by the core's rate check: the IMU below min_imu_rate_hz
        self.last_z = {GNSS_S: math.nan, RANGEFINDER_S: math.nan, BARO_INS_S: math.nan}
        self.consistent_since: dict[str, Optional[int]] = {s: None for s in SENSOR_SOURCES}
        self.warm_until = {s: t_us + self.warmup_us for s in SENSOR_SOURCES}
        self.start_rejects = 0  # the baro rows gated in a row within the warm-up
        self.restarts = 0
        self.pending_raw: dict[int, Optional[tuple]] = {GNSS: None, RNG: None}
        self.sensor_var_floor = [0.0, 0.0, 0.0]
        self.bank.baro_on[:] = True
        self.ins = InsBaroCheck(m.ins_window_s)
        model = self.bank.model
        self.baro_u = BaroNoiseMeter(model.sigma_bb_m, model.gamma_bb_per_s, m.baro_u_window_s,
                                     m.baro_u_memory_s, m.baro_u_min_samples, m.baro_u_outlier_sigma,
                                     m.baro_u_significance_sigma, m.median_scale_update_s, m.residual_scale_max)
        self.ins_ex = Exceedance()  # baro/INS readings past its threshold and its suspect level
        self.raw_check = RawAuxCheck(window_s=m.raw_check_window_s, k=self.k_cmp,
                                     learn_ground=not (at_datum or m.ground_at_reference))
        self.at_datum = at_datum  # the start on the ground at the datum: the ground's height is known there
        self.last_fused_m = math.nan
        self.near_ground_us: Optional[int] = None  # the last epoch the fused height was near the ground
        self.refused: deque = deque()  # (t_us, kind, value_m, min_m, max_m, cos_tilt)
        self.range_valid: deque = deque()
        self.isolated_since: Optional[int] = None
        self.hold_since: Optional[int] = None  # an unresolved failure held since
        self.last_hold: Optional[Judgement] = None  # the failure held, until its restarted tests run clean
        self.restarted_us = {GNSS_S: -10**18, RANGEFINDER_S: -10**18}  # a held CUSUM last restarted
        self.isolated_src: frozenset = frozenset()
        self.last_feedback_us = t_us
        self.baro_white_var = 0.0
        self.dv_var = 0.0
        self.envelope_failing = False
        self.last_r_m = {GNSS_S: 0.0, RANGEFINDER_S: 0.0}
        self.last_post_r_m = {GNSS_S: 0.0, RANGEFINDER_S: 0.0}  # the last innovation less what the channel took up
        self.r_avg_m = {GNSS_S: 0.0, RANGEFINDER_S: 0.0}
        # the last few innovations of each aux stream: where it stood before a jump
        self.recent_r_m = {s: deque(maxlen=m.sudden_jump_level_samples) for s in (GNSS_S, RANGEFINDER_S)}
        self.last_sd_m = {GNSS_S: math.inf, RANGEFINDER_S: math.inf}
        self.level_since: dict[int, Optional[int]] = {GNSS: None, RNG: None}
        # the level statistics (r / sigma) while the test is clean, for the second
        # difference over level_scale_lag_s the scale learns from
        self.level_snaps: dict[int, LagSeries] = {GNSS: LagSeries(m.level_scale_lag_s),
                                                  RNG: LagSeries(m.level_scale_lag_s)}
        self.sudden: dict[str, Jump] = {}  # name -> its latest sudden jump
        # the measured scatter of each aux stream's sample-to-sample innovation change
        self.jump_scale = {s: MedianScale(m.sudden_jump_memory_s, m.sudden_jump_min_samples,
                                          m.median_scale_update_s) for s in (GNSS_S, RANGEFINDER_S)}
        self.judgement = Judgement("clear", frozenset(), frozenset(), "start")
        # measured scale of each sequential test's residuals; the INS check only
        # ever widens (its windows overlap, so only the variance ratio counts)
        sc = (m.residual_scale_tau_s, m.residual_scale_min, m.residual_scale_max)
        aux_sc = (*sc, m.residual_scale_max_phi)
        self.scale = {GNSS_S: ResidualScale(*aux_sc), RANGEFINDER_S: ResidualScale(*aux_sc),
                      INS_S: ResidualScale(sc[0], 1.0, sc[2], max_phi=0.0, prior_m2=m.ins_scale_prior_m2),
                      BARO_S: ResidualScale(sc[0], 1.0, sc[2], max_phi=0.0)}
        self.jump: Optional[list] = None  # open baro jump: [t0, size_m, sd0, offset_m, n_after, before]
        self.before_jump: deque = deque(maxlen=64)  # clean baro samples: (t, b, ins pos, ins vel, V)
        # the same offset at every clean sample (against the samples a confirm
        # time before it): its measured scatter is what a step must beat
        self.offset_scale = ResidualScale(m.residual_scale_tau_s, 0.0, math.inf, max_phi=0.0, prior_m2=0.0)
        self.baro_judged: Optional[tuple] = None  # this epoch's baro row: (r, sd, rejected)
        self.jump_confirmed: Optional[tuple] = None  # (t, cum_m, sigma)
        # every confirmed baro step: (t opened, size m, its sd m, measured from a
        # level no test doubted), for the level a baro readmitted with no aux
        # channel to rebase on comes back at
        self.baro_steps: deque = deque(maxlen=32)
        self.baro_excluded_us: Optional[int] = None
        self.baro_step_trust_us = int(m.baro_step_trust_s * 1e6)
        self.baro_readmitted_us: Optional[int] = None
        self.baro_doubted_us: Optional[int] = None  # the last epoch the baro was in caution or alarm
        self.baro_level_set = False  # that readmission set the baro's level (else: its own)
        # what readmissions with no aux channel have given back of the baro's steps, and its variance
        self.baro_given_back = (0.0, 0.0)
        # ramp onsets against the INS: the series, and each one's measured kink scatter
        keys = ("gnss-baro", "gnss-ins", "rangefinder-baro", "rangefinder-ins", "baro-ins")
        self.kink = {k: KinkSeries(m.kink_window_s) for k in keys}
        self.kink_sd = {k: MeanSquare(m.kink_learn_tau_s) for k in keys}
        self.kink_learned_s = -math.inf
        self.baro_minus_ins_m = math.nan
        # GNSS altitude against its own Doppler velocity: the check, its measured
        # scale (it only widens), consecutive GNSS samples past the threshold
        self.doppler = DopplerCheck(m.doppler_window_s, m.doppler_max_gap_s, sigma_m=m.doppler_sigma_m)
        self.scale["doppler"] = ResidualScale(m.window_scale_tau_s, 1.0, sc[2], max_phi=0.0)
        self.doppler_ex = Exceedance()
        # the baro against the same Doppler velocity (alerts, never clears)
        # reading from the GNSS test's own shortest span (the baro-Doppler scatter
        # over 5 s is that over 10 s), so a window restarted by a gap is not blind
        # for 8 s while a ramp grows
        self.baro_doppler = DopplerCheck(m.baro_doppler_window_s, m.doppler_max_gap_s,
                                         min_span_s=MIN_SPAN_FRAC * m.doppler_window_s,
                                         sigma_m=m.baro_doppler_sigma_m,
                                         scale_frac=m.baro_doppler_scale_frac,
                                         recent_span_s=m.baro_doppler_recent_span_s)
        self.scale["baro_doppler"] = ResidualScale(m.window_scale_tau_s, 1.0, sc[2], max_phi=0.0)
        self.baro_doppler_ex = Exceedance()
        # without a Doppler: the GNSS altitude's drift rate against the baro
        self.drift = DriftCheck(m.gnss_drift_window_s, m.doppler_max_gap_s)
        # the receiver's own drift rate and the model's baro u through the fit, in quadrature
        self.drift_floor_var = (m.gnss_drift_sigma_mps ** 2
                                + gm_slope_var_factor(model.gamma_bb_per_s, m.gnss_drift_window_s) * model.sigma_bb_m ** 2)
        self.scale["drift"] = ResidualScale(m.window_scale_tau_s, 1.0, sc[2], max_phi=0.0)
        self.drift_ex = Exceedance()
        # the INS's velocity change against the Doppler's: the check, its scale,
        # this epoch's Doppler sample (taken after the epoch's INS increment)
        self.ins_doppler = InsDopplerCheck(m.doppler_window_s, m.doppler_max_gap_s)
        self.scale["ins_doppler"] = ResidualScale(m.window_scale_tau_s, 1.0, sc[2], max_phi=0.0)
        # the baro's level against each aux channel: its measured scale (learnt
        # from a second difference) holds a baro whose noise exceeds the model's u,
        # and may narrow a measured u the level itself does not show; the
        # threshold never falls below the model's (_level_thr)
        for _, name in AUX:
            self.scale[_LEVEL_SCALE[name]] = ResidualScale(m.level_scale_tau_s, m.level_scale_min, sc[2],
                                                           max_phi=0.0)
        self.insdop_ex = Exceedance()
        self.pending_doppler: Optional[tuple] = None
        self.ins_excluded = False  # the baro+INS source is out for its INS (not only its baro)
        self.ins_doubt = False  # an INS test is not passing this epoch

    # ------------------------------------------------------------------ refused readings

    def on_range_refused(self, s) -> None:
        if s.kind in REFUSAL_KINDS and hasattr(self, "refused"):
            if s.kind == "stuck" and BARO_INS_S in self.excluded:
                # the ingest calls a reading stuck when the baro moved and the
                # reading did not: with the baro out for a fault of its own, its
                # moves (an injected 5 m step's return on a SITL hover) are no
                # evidence against a rangefinder holding a steady height
                return
            self.refused.append((s.t_us, s.kind, s.value_m, s.min_m, s.max_m, s.cos_tilt))

    # ------------------------------------------------------------------ before the step

    def _warm(self, name: str, t: int) -> bool:
        return t < self.warm_until[name]

    def _h(self, name: str) -> float:
        """CUSUM threshold for a stream at its own rate (cached per 0.5 Hz)."""
        return self._h_and_ratio(name)[0]

    def _h_and_ratio(self, name: str) -> tuple:
        """The slow arms' threshold and its ratio to the fast arms' (0: no fast
        arms) for a stream at its own rate (cached per 0.5 Hz)."""
        iv = self.rates[name].interval_s
        last = self._h_last.get(name)
        if last is not None and last[0] == iv:  # the same interval as last asked: the same h
            return last[1]
        pair = self._h_at_rate(name)
        self._h_last[name] = (iv, pair)
        return pair

    def _h_at_rate(self, name: str) -> tuple:
        key = int(round(self.rates[name].hz / CUSUM_RATE_STEP_HZ))
        pair = self._h_cache.get(key)
        if pair is None:
            rate_hz = max(key * CUSUM_RATE_STEP_HZ, CUSUM_RATE_STEP_HZ)
            h = threshold_for(self.m.cusum_k_sigma, self.m.cusum_false_alerts_per_h, rate_hz)
            k_fast = self.cusum[name].k_fast
            ratio = h / threshold_for(k_fast, self.m.cusum_fast_false_alerts_per_h, rate_hz) if k_fast else 0.0
            pair = self._h_cache[key] = (h, ratio)
        return pair

    def _cusum_stat(self, name: str) -> float:
        """The CUSUM statistic in its slow arms' units: the larger of the slow
        arms and the fast arms scaled by the ratio of their thresholds, so that
        either arm past its own threshold is past ``_h``."""
        cs = self.cusum[name]
        ratio = self._h_and_ratio(name)[1]
        return max(cs.stat, cs.fast_stat * ratio) if ratio else cs.stat

    def pre(self, ep: EpochInputs) -> EpochInputs:
        """Gate GNSS / rangefinder samples, judge the baro sample, keep excluded sources out."""
        t = ep.t_us
        changes: dict = {}
        baro_z = self._judge_baro(ep, t, changes) if ep.baro_m is not None else math.inf
        if baro_z == math.inf:
            baro_z = self._latest_baro_z(t)
        ground = self.raw_check.ground_m
        if ground and ep.rng is not None:
            # the ground a start away from the datum found under the rangefinder
            changes["rng"] = dataclasses.replace(ep.rng, height_m=ep.rng.height_m + ground)
        for c, name in AUX:
            aux = ep.gnss if c == GNSS else changes.get("rng", ep.rng)
            self.pending_raw[c] = None
            if aux is not None:
                self._judge_aux(ep, c, name, aux, t, baro_z, changes)
        self.dv_var = ep.dv_var_m2ps2
        return dataclasses.replace(ep, **changes) if changes else ep

    def _judge_baro(self, ep: EpochInputs, t: int, changes: dict) -> float:
        """This epoch's baro row against the INS: its |z| (inf: none), the jump
        gate, the rejection window."""
        self.rates[BARO_INS_S].push(t)
        self.last_baro_us = t
        self.last_baro_m = ep.baro_m
        if self.baro_level is not None:
            self.baro_level.push_baro(t, ep.baro_m)
        self.baro_white_var = ep.baro_white_var_m2
        # judged in the channel held best by an aux sensor (its velocity is the
        # surest); the baro+INS channel alone trades a level error for velocity
        r, S = self.bank.predicted_baro(self._anchor(t), ep)
        if not (S == S and S > 0):
            self.jump = None  # the differencing restarted
            self.before_jump.clear()
            return math.inf
        nu2 = r * r / S
        sd = math.sqrt(S)
        z = self.last_z[BARO_INS_S] = r / sd
        # the jump gate at the baro row's measured scatter (never below the model's)
        sc = self.scale[BARO_S]
        reject = self.f.innovation_gating and nu2 > self.baro_gate * sc.sd ** 2
        if t < self.warm_until[BARO_INS_S] and self._restarted_on(t, ep.baro_m, reject):
            changes["baro_restart"] = True  # differencing restarts from this sample
            return math.inf
        if not reject and self.jump is None:
            sc.push(t, z)
        if not t < self.warm_until[BARO_INS_S]:  # not self._warm(BARO_INS_S, t)
            self.rejections[BARO_INS_S].push(t, reject)
            self.baro_judged = (r, sd, reject)
        if reject:
            changes["baro_restart"] = True  # no baro row anywhere; differencing restarts
        return abs(z)

    def _restarted_on(self, t: int, baro_m: float, reject: bool) -> bool:
        """Within the warm-up: the filters start again on this sample if their
        own baro rows have been gated ``start_restart_rows`` in a row (a start
        that took its speed from a glitch rejects every sample after it, and
        would coast on the INS until its sigma takes it out of the output)."""
        self.start_rejects = self.start_rejects + 1 if reject else 0
        if self.start_rejects < self.m.start_restart_rows or self.restarts >= self.m.start_restarts_max:
            return False
        self.bank.start(t, baro_m, self.bank.start_baro_bias_m2, self.bank.start_vel_m2ps2)
        self.restarts += 1
        self.glitch_restarts += 1
        self.start_rejects = 0
        self.jump = None
        self.before_jump.clear()
        self.last_z[BARO_INS_S] = math.nan
        self.warm_until = {s: t + self.warmup_us for s in SENSOR_SOURCES}
        return True

    def _latest_baro_z(self, t: int) -> float:
        """No baro sample in this epoch (each sample has its own): the latest
        baro row, if no older than two baro intervals, says whether the baro
        stayed consistent (a baro step shows in its own row before any aux
        channel can follow it)."""
        if self.jump is not None or self.last_z[BARO_INS_S] != self.last_z[BARO_INS_S]:
            return math.inf
        iv = self.rates[BARO_INS_S].interval_s
        if iv == iv and t - self.last_baro_us <= 2e6 * iv:
            return abs(self.last_z[BARO_INS_S])
        return math.inf

    def _judge_aux(self, ep: EpochInputs, c: int, name: str, aux, t: int, baro_z: float, changes: dict) -> None:
        """One GNSS or rangefinder sample: the Doppler checks, then (unless its
        source is out) re-initialisation, the innovation, the sudden-jump
        rule, the gate and the sequential test."""
        bank = self.bank
        last = self._record_aux(c, name, aux, t)
        field_name = "gnss" if c == GNSS else "rng"
        if name in self.excluded:
            changes[field_name] = None  # the channel coasts; readmission decides later
            return
        # back after coasting without its sensor (not after rejecting it: that is
        # the tests' business), or with a sigma past the limit: start again
        absent = last is not None and t - last > self.coast_us
        if absent or bank.P[c, 0, 0] > self.m.max_channel_sigma_m ** 2:
            self._reinit_aux(c, name, t, aux.sigma_m)
        r, S = bank.predicted_aux(c, ep, aux)
        z = r / math.sqrt(S) if S > 0 else math.inf
        sd = math.sqrt(S) if S > 0 else math.inf
        if last is not None and t - last <= self.stale_us[c] and not absent:
            self._note_sudden(name, t, r, sd, baro_z)
        post_frac = aux.sigma_m * aux.sigma_m / S if S > 0 else 1.0
        self.last_z[name] = z
        self.last_r_m[name] = r
        # the failure's size: the innovation's recent mean (one sample is noise)
        w = 1.0 - math.exp(-max(t - (last or t), 0) * 1e-6 / self.m.fail_size_tau_s) if last is not None else 1.0
        self.r_avg_m[name] = r if absent else self.r_avg_m[name] + w * (r - self.r_avg_m[name])
        self.recent_r_m[name].append(r)
        self.last_sd_m[name] = sd
        # the gate at the innovations' measured scatter, never below the model's
        reject = self.f.innovation_gating and z * z > self.gate * max(1.0, self.scale[name].sd) ** 2
        if absent:
            self.scale[name].gap()
        if not self._warm(name, t):
            self._sequential(name, t, z, reject)
        if reject:
            changes[field_name] = None
            self.last_post_r_m[name] = r
        else:
            self.last_accept_us[c] = t
            # what is left of the innovation once the sample has entered: the
            # next sample's jump is measured from there, not from the innovation
            # the channel has just taken up (with its covariance opened, a GNSS
            # channel took up 9 m between two samples: no jump of the GNSS's)
            self.last_post_r_m[name] = r * post_frac

    def _record_aux(self, c: int, name: str, aux, t: int) -> Optional[int]:
        """What every sample of a stream feeds, excluded or not: its rate, the
        raw checks, the Doppler checks. Returns the previous sample's time."""
        self.rates[name].push(t)
        if c == RNG:
            self.range_valid.append(t)
        last = self.last_seen_us[c]
        self.last_seen_us[c] = t
        self.pending_raw[c] = (aux.height_m - aux.age_s * self.bank.x[c, 1], aux.sigma_m)
        self.sensor_var_floor[c] = aux.sigma_m * aux.sigma_m
        if c == GNSS and self.f.doppler_check:
            self._push_doppler(t - int(aux.age_s * 1e6), aux)
        if c == GNSS and self.f.gnss_drift_check:
            self._push_drift(t - int(aux.age_s * 1e6), aux)
        if c == GNSS and self.f.ins_doppler_check:
            self.pending_doppler = (t, aux.vel_up_mps)
        return last

    def _note_sudden(self, name: str, t: int, r: float, sd: float, baro_z: float) -> None:
        """A sudden change of the innovation while this epoch's baro row is
        clean: neither the baro nor the INS (whose errors are integrals) can
        make it."""
        prev = self.last_post_r_m[name] if self.f.sudden_jump_measured else self.last_r_m[name]
        jump = abs(r - prev)
        if jump != jump:
            return  # the channel started again since the last sample: nothing to jump from
        held = self.sudden.get(name)
        if held is not None and t > held.t_us:
            held.follow(t, r, self.m.sudden_jump_persist_frac, self.sudden_persist_us,
                        self.m.sudden_jump_persist_samples)
        js = self.jump_scale[name]
        scale = math.hypot(sd, self.last_sd_m[name])
        if self.f.sudden_jump_measured and js.sd is not None:
            scale = max(js.sd, scale / self.m.sudden_jump_sharpen_max)
        thr = math.sqrt(self.gate) * scale
        if jump > thr:
            clean = baro_z < self.m.clear_frac * math.sqrt(self.baro_gate)
            if not self.f.sudden_jump_persist:
                self.sudden[name] = new_jump(t, r, prev, jump, clean, can_hold=False)
                return
            # and from where the stream stood (the median of its last few
            # innovations), by its measured scatter: the return from a
            # one-sample spike jumps from the spike, and the chance jump of a
            # drifting stream from its last sample only
            recent = self.recent_r_m[name]
            if len(recent) < self.m.sudden_jump_level_samples or js.sd is None:
                return
            level = statistics.median(recent)
            if abs(r - level) > math.sqrt(self.gate) * js.sd:
                # one noted while the channel warms up never holds: the verdicts
                # are not heard then, and its level was still settling
                self.sudden[name] = new_jump(t, r, level, jump, clean, can_hold=not self._warm(name, t))
        elif self.f.sudden_jump_measured:
            js.push(t, jump)

    def _sequential(self, name: str, t: int, z: float, reject: bool) -> None:
        """The CUSUM (on the measured scale; frozen while the baro+INS source is
        out for its INS) and the rejection window."""
        if self.f.window_test and not (BARO_INS_S in self.excluded and self.ins_excluded):
            sc = self.scale[name]
            self.cusum[name].push(z / sc.factor)
            if not reject and self._cusum_stat(name) < self.m.suspect_frac * self._h(name):
                sc.push(t, z)  # frozen while the test leans towards a fault
        self.rejections[name].push(t, reject)

    def _window_thr(self, check, key: str) -> float:
        """A Doppler window check's threshold for its last reading: k times the
        reading's own error times the check's measured scale."""
        return self.k_cmp * check.error_m(check.last_disp_m) * self.scale[key].factor

    def _push_window(self, check, key: str, ex: Exceedance, t_meas: int, h: float, v: float,
                     start_m=None) -> None:
        """One sample into a Doppler window check: its exceedance against the
        reading's own error, and its measured scale (frozen while it leans
        towards a fault)."""
        e = check.push(t_meas, h, v, start_m)
        if e is None:
            ex.reset()
            return
        thr = self._window_thr(check, key)
        ex.update(t_meas, abs(e) > thr, abs(e) > self.m.suspect_frac * thr)
        if abs(e) <= self.m.suspect_frac * thr:
            self.scale[key].push(t_meas, e / check.error_m(check.last_disp_m))

    def _push_doppler(self, t_meas: int, aux) -> None:
        self._push_window(self.doppler, "doppler", self.doppler_ex, t_meas, aux.height_m, aux.vel_up_mps)
        level = self.baro_level
        if level is not None:
            level.push_gnss(t_meas, aux.vel_up_mps)
        if self.last_baro_m is not None:  # its verdict is optional; readmission always heeds it
            # the baro's level at the GNSS sample's time (:mod:`.barolevel`), or
            # the latest baro carried there by the Doppler velocity
            b = level.end_m(t_meas) if level is not None else None
            iv = self.rates[BARO_INS_S].interval_s
            if iv == iv and abs(t_meas - self.last_baro_us) <= 2e6 * iv:
                if b is None:
                    b = self.last_baro_m + aux.vel_up_mps * (t_meas - self.last_baro_us) * 1e-6
                self._push_window(self.baro_doppler, "baro_doppler", self.baro_doppler_ex, t_meas, b, aux.vel_up_mps,
                                  level.centred_m if level is not None else None)

    def _push_drift(self, t_meas: int, aux) -> None:
        """A GNSS sample without a Doppler velocity into the drift check
        (:mod:`.drift`): its altitude less the latest baro, carried to its time
        by the baro+INS channel's velocity. A receiver with a Doppler has the
        Doppler tests instead."""
        d = self.drift
        iv = self.rates[BARO_INS_S].interval_s
        # either sensor out: its readings then are no reference for the drift after
        if (aux.vel_up_mps == aux.vel_up_mps or self.last_baro_m is None or iv != iv
                or abs(t_meas - self.last_baro_us) > 2e6 * iv or {GNSS_S, BARO_INS_S} & self.excluded):
            d.clear()
            self.drift_ex.reset()
            return
        b = self.last_baro_m + float(self.bank.x[BARO, 1]) * (t_meas - self.last_baro_us) * 1e-6
        slope = d.push(t_meas, aux.height_m - b)
        if slope is None:
            self.drift_ex.reset()
            return
        sigma = self._drift_sigma()
        thr = self._drift_thr()
        self.drift_ex.update(t_meas, abs(slope) > thr, abs(slope) > self.m.suspect_frac * thr)
        if abs(slope) <= self.m.suspect_frac * thr:
            self.scale["drift"].push(t_meas, slope / sigma)

    def _drift_sigma(self) -> float:
        """The slope's error: the fit's white noise, the receiver's own drift
        rate and the baro's slow error ``u`` of the sensor model through the
        fit (:func:`.drift.gm_slope_var_factor`). The model's ``u``, not the
        run-time meter's (:mod:`.baronoise`): widened by a baro 2.5 times
        noisier than the real ones, the test missed 0.5 m/s GNSS ramps in 3 of
        12 simulated descents (BENCHMARKS.md, session 22)."""
        return math.sqrt(self.drift.last_white_sd_mps ** 2 + self.drift_floor_var)

    def _drift_thr(self) -> float:
        return self.k_cmp * self._drift_sigma() * self.scale["drift"].factor

    def _drift_verdict(self, t: int) -> Optional[Verdict]:
        """The GNSS altitude's drift rate against the baro (no Doppler): a
        failure implicates the GNSS and the baro; a pass rules nothing out.
        Its size: the drift over the window; as the GNSS would make it, none
        that its innovations show (the Gauss-Markov state follows a ramp), so
        a GNSS innovation pass cannot clear it."""
        d = self.drift
        if (not self.f.gnss_drift_check or {GNSS_S, BARO_INS_S} & self.excluded or self._warm(GNSS_S, t)
                or d.last_us is None or t - d.last_us > self.stale_us[GNSS] or d.last_slope_mps != d.last_slope_mps):
            return None
        thr = self._drift_thr()
        e = d.last_slope_mps
        def why() -> str:
            return (f"GNSS altitude drifted {e:+.2f} m/s against the baro over {d.last_span_s:.0f} s "
                    f"(threshold {thr:.2f} m/s)")
        return self._graded("GNSS/baro drift", abs(e), thr, self.drift_ex, t, frozenset((GNSS_S, BARO_S)), why,
                            fail_scale_m=abs(e) * d.last_span_s, sizes={GNSS_S: 0.0})

    def _doppler_verdict(self, t: int) -> Optional[Verdict]:
        """The GNSS altitude against its own Doppler velocity
        (:mod:`.doppler`): a failure implicates the GNSS alone; a pass rules
        nothing out (a fault in position and velocity together passes it).
        Its size as the GNSS would make it: none that another test's pass can
        rule out, as the drift test's (the receiver disagrees with itself; and
        its innovations cannot clear a ramp the Gauss-Markov state follows)."""
        d = self.doppler
        if (not self.f.doppler_check or GNSS_S in self.excluded or self._warm(GNSS_S, t)
                or d.last_us is None or t - d.last_us > self.stale_us[GNSS] or d.last_e_m != d.last_e_m):
            return None
        thr = self._window_thr(d, "doppler")
        e = d.last_e_m
        def why() -> str:
            return (f"GNSS altitude moved {e:+.2f} m against its own Doppler velocity over "
                    f"{self.m.doppler_window_s:g} s (threshold {thr:.2f} m)")
        return self._graded("GNSS/Doppler", abs(e), thr, self.doppler_ex, t, frozenset((GNSS_S,)), why,
                            sizes={GNSS_S: 0.0})

    def _graded(self, test: str, stat: float, thr: float, ex, t: int, implicates: frozenset, why: Callable[[], str],
                clears: frozenset = frozenset(), fail_scale_m: Optional[float] = None, sizes: Optional[dict] = None,
                pass_scale_m: float = 0.0) -> Verdict:
        """A windowed test's verdict from its statistic: fail past the threshold
        on two samples in a row held persist_s (one outlier is the gate's
        business), suspect past suspect_frac of it on two samples in a row
        (consecutive windows share all but their end samples, so one reading
        past it is one noisy sample), else pass, ruling out ``clears`` below
        clear_frac of it. ``why()`` is the text of a failure or a suspicion (a
        pass has none: it is built only for those)."""
        if stat > thr and ex.persistent(t, self.persist_us):
            return Verdict(test, "fail", implicates, stat=stat, threshold=thr, text=why(),
                           scale_m=stat if fail_scale_m is None else fail_scale_m, sizes=sizes)
        if stat > self.m.suspect_frac * thr and ex.near >= 2:
            return Verdict(test, "suspect", implicates, stat=stat, threshold=thr, text=why())
        clear = clears if stat < self.m.clear_frac * thr else _NOTHING
        return Verdict(test, "pass", implicates, clear, stat, thr, "", pass_scale_m)

    def _baro_doppler_verdict(self, t: int) -> Optional[Verdict]:
        """The baro's change against the GNSS Doppler's integral over the same
        window: a failure implicates the baro and the GNSS (its velocity); a
        pass rules nothing out (a window sees a ramp's rate, not its size:
        a slow baro ramp passes it while its error grows)."""
        d = self.baro_doppler
        if (not self.f.baro_doppler_check or {GNSS_S, BARO_INS_S} & self.excluded or self._warm(GNSS_S, t)
                or d.last_us is None or t - d.last_us > self.stale_us[GNSS] or d.last_e_m != d.last_e_m):
            return None
        thr = self._window_thr(d, "baro_doppler")
        e = d.last_e_m
        def why() -> str:
            return (f"baro moved {e:+.2f} m against the GNSS Doppler velocity over "
                    f"{d.last_span_s:.0f} s (threshold {thr:.2f} m; vehicle moved {d.last_disp_m:+.1f} m)")
        return self._graded("baro/Doppler", abs(e), thr, self.baro_doppler_ex, t, frozenset((BARO_S, GNSS_S)), why)

    def _push_ins_doppler(self, ep: EpochInputs) -> None:
        d = self.ins_doppler
        d.push_ins(ep.dt_s, ep.dv_mps, ep.dv_var_m2ps2, float(self.bank.x[BARO, 3]))
        pend, self.pending_doppler = self.pending_doppler, None
        if pend is None:
            return
        e = d.push_gnss(*pend)
        if e is None:
            self.insdop_ex.reset()
            return
        thr = self._ins_doppler_thr()
        self.insdop_ex.update(pend[0], abs(e) > thr, abs(e) > self.m.suspect_frac * thr)
        if abs(e) <= self.m.suspect_frac * thr:
            self.scale["ins_doppler"].push(pend[0], e / self._ins_doppler_sigma())

    def _ins_doppler_sigma(self) -> float:
        return math.sqrt(self.m.ins_doppler_sigma_mps ** 2 + self.ins_doppler.last_var_mps2)

    def _ins_doppler_thr(self) -> float:
        return self.k_cmp * self._ins_doppler_sigma() * self.scale["ins_doppler"].factor

    def _ins_doppler_verdict(self, t: int) -> Optional[Verdict]:
        """The INS's velocity change against the Doppler's: a failure
        implicates the INS and the GNSS (its velocity); a clear pass rules out
        the INS. Sizes: for the INS, in the baro/INS check's metres, so the two
        INS tests weigh each other (an accelerometer error ``e / W`` makes a
        second difference of ``(e / W) D^2 / 2`` over that check's span ``D``,
        taken at its shortest, ``ins_window_s``, so that a pass of the coarser
        check cannot overrule this one's failure); for the GNSS, the position a
        velocity error ``e`` makes over half the window."""
        d = self.ins_doppler
        # the INS already out for this: its failures are explained (readmission watches them)
        ins_out = BARO_INS_S in self.excluded and self.ins_excluded
        if (not self.f.ins_doppler_check or GNSS_S in self.excluded or ins_out or self._warm(GNSS_S, t)
                or d.last_us is None or t - d.last_us > self.stale_us[GNSS] or d.last_e_mps != d.last_e_mps):
            return None
        thr = self._ins_doppler_thr()
        e = d.last_e_mps
        W = self.m.doppler_window_s
        D = self.m.ins_window_s  # its shortest span: the mapping never favours the coarser test
        to_ins_m = 0.5 * D * D / W
        to_pos_m = 0.5 * W  # a GNSS velocity error e over the window: e W / 2 of position
        def why() -> str:
            return (f"INS velocity changed {-e:+.2f} m/s against the GNSS Doppler over "
                    f"{self.m.doppler_window_s:g} s (threshold {thr:.2f} m/s)")
        return self._graded("INS/Doppler", abs(e), thr, self.insdop_ex, t, frozenset((INS_S, GNSS_S)), why,
                            clears=frozenset((INS_S,)), fail_scale_m=abs(e) * to_pos_m,
                            sizes={INS_S: abs(e) * to_ins_m}, pass_scale_m=thr * to_ins_m)

    def _anchor(self, t: int) -> int:
        """The channel a baro sample is judged in: the aux channel its sensor
        holds best now (fresh: a channel coasting on the INS since its sensor
        went quiet holds nothing), else the baro+INS channel."""
        best, best_var = BARO, math.inf
        for c, name in AUX:
            last = self.last_accept_us[c]
            if (name in self.excluded or last is None or t - last > self.stale_us[c]
                    or self.trackers[name].state == "alarm"):
                continue
            if self.bank.P[c, 0, 0] < best_var:
                best, best_var = c, self.bank.P[c, 0, 0]
        return best

    def _track_jump(self, t: int, b: float, r: float, sd: float, reject: bool) -> None:
        """A baro sample past the jump gate opens a jump. Each later sample is
        compared with the last clean one carried forward by the INS and the
        channel's velocity then (no filter update in between can absorb it): the
        jump is a step if, after ``baro_jump_confirm_s`` and
        ``baro_jump_confirm_samples``, the baro still sits ``baro_jump_stay_frac``
        of the jump away; otherwise a spike (prop wash, a pressure glitch) that
        the gate alone handles."""
        m = self.m
        ins = self.ins
        j = self.jump
        if self.trackers[BARO_INS_S].state in _DOUBTED:
            self.baro_doubted_us = t
        if j is None:
            before = self.before_jump
            keep_us = 1e6 * max(1.0, 2 * m.baro_jump_confirm_s)
            while before and t - before[0][0] > keep_us:
                before.popleft()
            if reject and before:
                ref = tuple(_last(before, m.baro_jump_reference_samples))
                size = b - self._carried(ref, t)
                # and whether it is measured from a level no test doubted: a jump that
                # opens while the baro is in caution or out, or within baro_step_trust_s
                # of it (a baro in caution while another source took the blame has had its
                # ramp followed by the channel), measures from a level the channel may
                # have followed along with the fault. A readmission that set the baro's
                # level (on an aux channel, or giving back its steps) is such a level at
                # once, so that a step's return right after it still cancels the step;
                # one that left the baro at its own level is not, so that the return of a
                # step left in it is not given back either.
                trk = self.trackers[BARO_INS_S]
                doubted = self.baro_doubted_us
                trusted = trk.state == "nominal" and (doubted is None or t - doubted >= self.baro_step_trust_us
                                                      or (trk.since_us == self.baro_readmitted_us
                                                          and self.baro_level_set))
                self.jump = [t, size, sd, size, 0, ref, trusted]
            elif not reject:
                # of the last OFFSET_SEARCH_SAMPLES, the last baro_jump_reference_samples
                # that are baro_jump_confirm_s old: the first that many found walking back
                confirm_us = m.baro_jump_confirm_s * 1e6
                n_ref = m.baro_jump_reference_samples
                old = []
                for k in range(1, min(OFFSET_SEARCH_SAMPLES, len(before)) + 1):
                    e = before[-k]
                    if t - e[0] >= confirm_us:
                        old.append(e)
                        if len(old) == n_ref:
                            break
                old.reverse()
                if old:
                    self.offset_scale.push(t, b - self._carried(old, t))
                before.append((t, b, ins.pos_m, ins.vel_mps, float(self.bank.x[self._anchor(t), 1])))
            return
        moved_m = b - self._carried(j[5], t) - j[3]
        j[3] += moved_m
        j[4] += 1
        if t - j[0] < m.baro_jump_confirm_s * 1e6 or j[4] < m.baro_jump_confirm_samples:
            return
        # a step has settled: its last sample sits where the one before it did (within
        # the gate at this row's noise); a baro still moving is a transient on its way
        # somewhere (take-off prop wash dives 6 m and comes back within a second), and
        # a level read off it would be given back at readmission as the baro's offset
        if abs(moved_m) > math.sqrt(self.gate) * sd * max(1.0, self.scale[BARO_S].sd):
            if t - j[0] >= (m.baro_jump_confirm_s + m.baro_jump_settle_s) * 1e6:
                self.jump = None  # never settled: not a step (the windowed tests own drifts)
            return
        # a step stays, and beats the baro's own scatter of such offsets at the jump level
        floor = math.sqrt(self.baro_gate * max(self.offset_scale.m2, 0.0))
        if j[3] * j[1] > 0 and abs(j[3]) >= max(m.baro_jump_stay_frac * abs(j[1]), floor):
            self.jump_confirmed = (t, j[3], abs(j[1]) / j[2])
            self.baro_steps.append((j[0], j[3], j[2], j[6]))
        self.jump = None

    def _carried(self, samples, t: int) -> float:
        """The median of clean baro samples carried forward to ``t`` by the INS
        and the channel's velocity at each (one noisy sample is no reference)."""
        ins = self.ins
        out = []
        for t_b, b_b, pos_b, vel_b, v_b in samples:
            dt = (t - t_b) * 1e-6
            out.append(b_b + (ins.pos_m - pos_b) - vel_b * dt + v_b * dt)
        return statistics.median(out)  # np.median's value, without its call overhead on five numbers

    def _reinit_aux(self, c: int, name: str, t: int, sigma_m: float) -> None:
        """An aux channel back from coasting starts again from the baro+INS
        channel, its height open (a rangefinder back in range finds its ground)."""
        self.bank.reinit_from(c, BARO, extra_height_var=self.m.max_channel_sigma_m ** 2 + sigma_m * sigma_m)
        self.cusum[name].clear()
        self.rejections[name].clear()
        self.warm_until[name] = t + self.warmup_us
        self.last_accept_us[c] = t
        self.last_post_r_m[name] = math.nan
        self.recent_r_m[name].clear()

    # ------------------------------------------------------------------ the tests

    def _aux_verdict(self, c: int, name: str, t: int) -> Optional[Verdict]:
        if name in self.excluded or self._warm(name, t) or self.last_seen_us[c] is None:
            return None
        if t - self.last_seen_us[c] > self.stale_us[c]:
            return None
        m = self.m
        cs = self.cusum[name]
        h = self._h(name)
        stat = self._cusum_stat(name)
        rej = self.rejections[name].rejected
        implicates = self._aux_implicates(c, name)
        label = LABEL[name]
        sudden = self._sudden_now(name, t)
        confirmed = rej >= m.alarm_rejections or stat > h  # the innovation test fails
        if (self.f.innovation_gating and sudden is not None and sudden.clean
                and (confirmed or self._step_held(sudden))):
            why = (f"{rej} samples rejected in {m.window_s:g} s" if confirmed
                   else f"held {(sudden.last_us - sudden.t_us) * 1e-6:.2f} s")
            return Verdict(f"{name} innovation", "fail", frozenset((name,)), stat=stat, threshold=h,
                           text=f"{label} jumped {sudden.size_m:.2f} m while the baro and INS stayed consistent; "
                                f"{why}", scale_m=sudden.size_m)
        if (self.f.innovation_gating and rej >= m.alarm_rejections) or stat > h:
            why = (f"{rej} {label} samples rejected in {m.window_s:g} s" if rej >= m.alarm_rejections
                   else f"{label} innovations drift {'up' if cs.sign > 0 else 'down'} (CUSUM {stat:.1f} > {h:.1f})")
            # the failure's size: the innovations' recent mean, or, where the fast arms
            # fail, the step they have summed (the mean lags a step by fail_size_tau_s)
            size = abs(self.r_avg_m[name])
            if stat > cs.stat:
                size = max(size, cs.fast_shift * self.scale[name].factor * self.last_sd_m[name])
            return Verdict(f"{name} innovation", "fail", implicates, stat=stat, threshold=h, text=why,
                           scale_m=size)
        if rej >= m.caution_rejections or stat > m.suspect_frac * h:
            return Verdict(f"{name} innovation", "suspect", implicates, stat=stat, threshold=h,
                           text=f"{label}: {rej} rejected, CUSUM {stat:.1f} of {h:.1f}")
        return Verdict(f"{name} innovation", "pass", implicates, self._aux_clears(c, name, t, stat, h, rej),
                       stat, h, scale_m=abs(self.r_avg_m[name]) + m.clear_margin_sigma * self.last_sd_m[name])

    def _aux_clears(self, c: int, name: str, t: int, stat: float, h: float, rej: int) -> frozenset:
        """What an aux innovation pass rules out: nothing unless the test is
        well below its threshold with nothing rejected; and a CUSUM restarted on
        a held failure vouches for nothing until it has run again."""
        fresh = t - self.restarted_us[name] < self.hold_restart_us
        if stat >= self.m.clear_frac * h or rej or fresh:
            return frozenset()
        # never the INS: a channel aided at 10-20 Hz follows an accelerometer fault
        # between its samples, so its quiet innovations vouch for its sensor only
        # (with the baro out, a rangefinder pass had cleared a faulty INS and left
        # the GNSS to be blamed for it)
        return _ONLY[name]

    def _aux_implicates(self, c: int, name: str) -> frozenset:
        """What an aux channel's innovations can mean. With the baro in the
        channel, the INS between aux samples is held by the baro rows, unless an
        INS test doubts the INS: a strong accelerometer fault drifts the
        channel's innovations too (without this, the INS/Doppler test's
        failures pinned INS faults on the GNSS)."""
        if self.bank.baro_on[c]:
            return _WITH_BARO_INS[name] if self.ins_doubt else _WITH_BARO[name]
        return _WITH_INS[name]

    def _step_held(self, sudden: Jump) -> bool:
        """A jump that held: a step of the sensor. Only where the INS carries
        the channel between samples (the IMU not slow): on a 9 Hz IMU the
        prediction itself jumps by metres between samples (frs_motor_failure_hexa)."""
        return self.f.sudden_jump_persist and sudden.step and self.slow_imu_hz is None

    def _sudden_now(self, name: str, t: int) -> Optional[Jump]:
        """The sudden jump noted for this stream, while the rejection window still holds it."""
        sudden = self.sudden.get(name)
        if sudden is not None and t - sudden.t_us > self.rejections[name].length_us:
            self.sudden.pop(name)
            return None
        return sudden

    def _ins_verdict(self, t: int) -> Optional[Verdict]:
        if t < self.warm_until[BARO_INS_S] or t - self.last_baro_us > self.stale_baro_us:  # _warm, inline
            return None
        m = self.m
        implicates = _BARO_AND_INS
        rej = self.rejections[BARO_INS_S].rejected
        v = self._jump_verdict(t, implicates)
        if v is not None:
            return v
        res = self._ins_residual()
        if res is None:
            return None
        e, sigma, thr, D = res
        sc = self.scale[INS_S]
        stat = abs(e)
        if stat <= m.suspect_frac * thr:
            sc.push(t, e / sigma)  # frozen while the test leans towards a fault
        def why() -> str:
            return f"baro moved {e:+.2f} m against the INS over {D:.1f} s (threshold {thr:.2f} m)"
        # graded as the window tests are (its windows overlap as theirs do)
        self.ins_ex.update(t, stat > thr, stat > m.suspect_frac * thr)
        # a second difference is blind to a ramp: a pass rules out the INS, never the
        # baro; and with the baro excluded it rules out nothing (its reference is out,
        # and the channel's accelerometer estimate has followed whichever was wrong)
        clears = _INS_ONLY if rej == 0 and BARO_INS_S not in self.excluded else _NOTHING
        return self._graded("baro/INS", stat, thr, self.ins_ex, t, implicates, why, clears=clears,
                            pass_scale_m=thr)  # V_s follows a slow error in part

    def _jump_verdict(self, t: int, implicates: frozenset) -> Optional[Verdict]:
        """A baro step that stayed (fail) or a jump being watched (a pass that clears nothing), if any."""
        jc = self.jump_confirmed
        if jc is not None and t - jc[0] > self.rejections[BARO_INS_S].length_us:
            jc = self.jump_confirmed = None
        if not self.f.innovation_gating or BARO_INS_S in self.excluded:
            return None
        if jc is not None:
            return Verdict("baro/INS", "fail", implicates, stat=jc[2], threshold=math.sqrt(self.baro_gate),
                           text=f"baro stepped {jc[1]:+.2f} m against the INS ({jc[2]:.1f} sigma) and stayed",
                           scale_m=abs(jc[1]))
        if self.jump is not None:
            # a jump being watched is a gated sample: the gate keeps it out of every
            # channel, and it is a step (a failure) only if it stays. Until then it
            # is no evidence against the baro (a pass that rules nothing out) and
            # the window test, whose residual holds the jump, waits for the verdict
            return Verdict("baro/INS", "pass", implicates, stat=abs(self.jump[1]) / self.jump[2],
                           threshold=math.sqrt(self.baro_gate))
        return None

    def _level_verdicts(self, t: int, avail: tuple) -> list[Verdict]:
        """The baro's level against each aux channel's ``H + dH`` (the channel's
        height held by its own sensor, and its estimate of the baro's bias): a
        slowly growing baro or aux error that the differenced baro row cannot see."""
        out = []
        warm_until = self.warm_until  # _warm, inline
        if BARO_INS_S in self.excluded or self.last_baro_m is None or t < warm_until[BARO_INS_S]:
            return out
        bank = self.bank
        u_var = self.baro_u.u_var_m2
        for c, name in AUX:
            if not avail[c] or t < warm_until[name] or not bank.baro_on[c]:
                self.level_since[c] = None
                self.level_snaps[c].clear()
                continue
            x = bank.x[c].tolist()  # Python floats: the same sums, without numpy scalars
            P0, P2 = bank.P[c, 0].tolist(), bank.P[c, 2].tolist()
            x0, x2, p00, p02, p22 = x[0], x[2], P0[0], P0[2], P2[2]
            r = self.last_baro_m - (x0 + x2)
            var_rest = p00 + p22 + 2.0 * p02 + self.baro_white_var
            var = var_rest + u_var
            sc = self.scale[_LEVEL_SCALE[name]]
            thr, thr_model = self._level_thr(name, var_rest)
            implicates = _LEVEL_IMPLICATES[name]
            test = _LEVEL_TEST[name]
            stat = abs(r)
            suspect_thr = self.m.suspect_frac * thr
            # the text only where a verdict carries it (a pass has none)
            txt = (f"baro {r:+.2f} m from the {LABEL[name]} channel (threshold {thr:.2f} m)"
                   if stat > suspect_thr or stat > thr else "")
            if stat > thr:
                if self.level_since[c] is None:
                    self.level_since[c] = t
                level = "fail" if t - self.level_since[c] >= self.persist_us else "suspect"
                out.append(Verdict(test, level, implicates, _NOTHING, stat, thr, txt, stat))
                self.level_snaps[c].clear()
                continue
            self.level_since[c] = None
            if stat <= suspect_thr:
                self._learn_level(c, sc, t, r / math.sqrt(var))
            else:
                self.level_snaps[c].clear()  # frozen while the test leans towards a fault
            if stat > suspect_thr:
                out.append(Verdict(test, "suspect", implicates, _NOTHING, stat, thr, txt))
            else:
                # a pass clears the baro only, and only while the channel tracks its own
                # sensor (none rejected, its innovations not drifting): a channel gating
                # it out coasts on the baro, and one whose innovations drift has its
                # baro-bias estimate dH between the two, so H + dH follows the baro;
                # and never where the channel models the GNSS's slow error: its b_g
                # takes up a slow baro error, and H + dH follows the baro (asked in
                # that order, and only for a statistic below clear_frac of the threshold)
                # (against the model's threshold: a scale the baro's noise widened
                # makes a pass weaker evidence, not stronger)
                clear = _NOTHING
                if (stat < self.m.clear_frac * thr_model and self.rejections[name].rejected == 0
                        and self._cusum_stat(name) < self.m.clear_frac * self._h(name)
                        and not (c == GNSS and bank.model.gnss_gm_sigma_m > 0.0)):
                    clear = _BARO_ONLY
                # scale: the threshold, not less the statistic: the channel's own height
                # follows a slow baro error in part, so the margin overstates the power
                # a baro fault of size X would read about X here: faults beyond the
                # statistic plus a margin are ruled out
                out.append(Verdict(test, "pass", implicates, clear, stat, thr, "",
                                   stat + self.m.clear_margin_sigma * thr / self.k_cmp))
        return out

    def _level_thr(self, name: str, var_rest: float) -> tuple[float, float]:
        """The level test's threshold against ``name``'s channel and the
        model's, from the variance of the difference less the baro's ``u``
        (in the test and in the baro's readmission alike): the baro's ``u``
        as measured (:mod:`.baronoise`) times the level's measured scale (1
        with ``features.level_scale`` off), never below the model's. A pass
        clears the baro against the model's: a baro measured noisier makes a
        pass weaker evidence, not stronger."""
        k = self.k_cmp
        thr_model = k * math.sqrt(var_rest + self.bank.model.sigma_bb_m ** 2)
        thr = k * math.sqrt(var_rest + self.baro_u.u_var_m2)
        if self.f.level_scale:
            thr *= self.scale[_LEVEL_SCALE[name]].factor
        return (thr if thr > thr_model else thr_model), thr_model

    def _learn_level(self, c: int, sc: ResidualScale, t: int, z: float) -> None:
        """Teach the level test's scale the baro's noise, never a ramp: from the
        second difference of its normalised statistic over level_scale_lag_s,
        ``(z(t) - 2 z(t - L) + z(t - 2 L)) / sqrt(6)``, which a linear drift does
        not move (the statistic itself would teach a slow baro ramp to widen the
        test that is there to see it: a simulated 0.5 m/s ramp was alarmed 1.8-3.5 s
        later) and which reads ``z``'s own variance when its correlation time is
        shorter than the lag."""
        d2 = self.level_snaps[c].push(t, z)
        if d2 is not None:
            sc.push(t, d2 * _INV_SQRT6)

    def _raw_verdict(self, t: int) -> Optional[Verdict]:
        if {GNSS_S, RANGEFINDER_S} & self.excluded:
            return None
        rc = self.raw_check
        unknown = rc.ground_m is None
        v = rc.verdict()
        if unknown and rc.ground_m:
            # the ground is learnt: the rangefinder channel starts again on it
            self._reinit_aux(RNG, RANGEFINDER_S, t, math.sqrt(self.sensor_var_floor[RNG]))
        if v is None:
            return None
        agree, mean, sigma = v
        thr = self.k_cmp * sigma
        implicates = frozenset((GNSS_S, RANGEFINDER_S))
        if not agree:
            return Verdict("raw GNSS-rangefinder", "fail", implicates, stat=abs(mean), threshold=thr,
                           text=f"raw GNSS - rangefinder {mean:+.2f} m (threshold {thr:.2f} m)", scale_m=abs(mean))
        # a pass rules nothing out: one GNSS sample's sigma is too coarse to vouch for the rangefinder
        return Verdict("raw GNSS-rangefinder", "pass", implicates, frozenset(), abs(mean), thr)

    def _envelope_margin(self) -> float:
        """How far inside the range the baro+INS channel must put the vehicle:
        the margin plus k sigma of its height apart from the baro's bias
        against the datum (the rangefinder's ground is where the vehicle
        stood; the datum's uncertainty, and the GNSS's slow error where it is
        modelled, are common to both: counted, they kept a dead rangefinder at
        2.7 m unseen)."""
        P = self.bank.P[BARO]
        var_h = P[0, 0] - (P[0, 2] * P[0, 2] / P[2, 2] if P[2, 2] > 0 else 0.0)
        return self.m.range_envelope_margin_m + self.k_cmp * math.sqrt(max(var_h, 0.0))

    def _envelope_verdict(self, t: int) -> Optional[Verdict]:
        """Readings refused at the edge of the range (or frozen) while the
        vehicle, by the baro+INS channel, is well inside it."""
        m = self.m
        limit = t - int(m.range_envelope_window_s * 1e6)
        q, ok = self.refused, self.range_valid
        while q and (q[0][0] is None or q[0][0] <= limit):
            q.popleft()
        while ok and ok[0] <= limit:
            ok.popleft()
        if not q:
            return None
        # the height above the rangefinder's ground (learnt on a start away from the datum)
        h = float(self.bank.x[BARO, 0]) - (self.raw_check.ground_m or 0.0)
        margin = self._envelope_margin()
        bad = []
        for _, kind, v, lo, hi, cos_t in q:
            if kind == "stuck":
                bad.append(f"frozen at {v:.2f} m")
            elif kind in ("out_of_range", "invalid_status", "impossible") and v == v:
                lo = lo if lo == lo else 0.0
                hi = hi if hi == hi else math.inf
                # the maximum is a slant range: tilted, the vertical height it reaches is less
                hi_up = hi * cos_t if 0.0 < cos_t <= 1.0 else hi
                if v <= lo + 1e-6 and h > lo + margin and h < hi_up - margin:
                    bad.append(f"reads {v:.2f} m (minimum {lo:g} m)")
                elif v >= hi - 1e-6 and h < hi_up - margin:
                    bad.append(f"reads {v:.2f} m (maximum {hi:g} m)")
        n = len(q) + len(ok)
        if len(bad) >= m.range_envelope_min_refused and len(bad) >= m.range_envelope_frac * n:
            return Verdict("rangefinder envelope", "fail", frozenset((RANGEFINDER_S,)), stat=len(bad), threshold=n,
                           text=f"rangefinder {bad[-1]} in {len(bad)} of {n} readings while the vehicle is "
                                f"{h:.1f} m up by baro+INS", scale_m=0.0)  # refused readings: no pass on
                                                                              # the accepted ones clears them
        return None

    # ------------------------------------------------------------------ ramp onsets

    def _push_kinks(self, t: int, baro_m: Optional[float]) -> None:
        """Each height against the INS's chained position, and each aux height
        against the baro carried to its time by the INS; every
        ``kink_learn_interval_s`` while the monitor is clear, each series' kink
        scatter at an onset a third of the window back."""
        m = self.m
        ts = t * 1e-6
        pos = self.ins.pos_m
        if baro_m is not None:
            last = self.kink["baro-ins"].t
            if last and ts - last[-1] > m.stale_baro_s:
                for ser in self.kink.values():
                    ser.clear()  # the INS chain across a baro gap is no reference
            self.baro_minus_ins_m = baro_m - pos
            self.kink["baro-ins"].push(ts, self.baro_minus_ins_m)
        for c, name in AUX:
            raw = self.pending_raw[c]
            if raw is None:
                continue
            x = raw[0] - pos
            k_ins, k_baro = _KINK_KEYS[name]
            self.kink[k_ins].push(ts, x)
            if self.baro_minus_ins_m == self.baro_minus_ins_m:
                self.kink[k_baro].push(ts, x - self.baro_minus_ins_m)
        if ts - self.kink_learned_s < m.kink_learn_interval_s or self.judgement.situation != "clear" or self.jump:
            return
        self.kink_learned_s = ts
        first_s = -m.kink_min_fill_frac * m.kink_window_s
        onset = None
        for key, ser in self.kink.items():
            # too few samples, or the window not filled: the test on the series itself
            # (its first time less ts is the arrays' first element), before any array
            times = ser.t
            if len(times) < m.kink_min_samples or times[0] - ts > first_s:
                continue
            s, y = ser.arrays(ts)
            if onset is None:
                onset = np.array([-m.kink_window_s / 3.0])
            num, den = kink_fit(s, y, onset, quadratic=key.endswith("-ins"))
            if den[0] > 0:
                self.kink_sd[key].push(ts, float(num[0]) / math.sqrt(float(den[0])))

    def _kink(self, key: str, ts: float, tau: float) -> Optional[tuple[float, float]]:
        """A series' kink slope at onset ``tau`` and its standard deviation."""
        s, y = self.kink[key].arrays(ts)
        if s.size < self.m.kink_min_samples or s[0] > tau - self.m.kink_min_pre_s:
            return None
        num, den = kink_fit(s, y, np.array([tau]), quadratic=key.endswith("-ins"))
        if not den[0] > 0:
            return None
        return float(num[0] / den[0]), self.kink_sd[key].sd / math.sqrt(float(den[0]))

    def _kink_verdicts(self, t: int, aux, gnss_more: tuple) -> list[Verdict]:
        """For an aux test (the sensor's innovations; for the GNSS also its
        drift against the baro and the baro against its Doppler) that
        implicates its sensor and the baro: which of the two bent against the
        INS (a pass that rules the other out), if the flight's own kink
        scatter lets the INS tell."""
        if BARO_INS_S in self.excluded:
            return []
        out = []
        for v, (_, name) in zip(aux, AUX):
            if name == GNSS_S and (v is None or v.level == "pass"):
                v = next((w for w in gnss_more if w is not None and w.level != "pass"), None)
            if v is None or v.level == "pass" or BARO_S not in v.implicates:
                continue
            verdict = self._kink_verdict(t * 1e-6, name)
            if verdict is not None:
                out.append(verdict)
        return out

    def _kink_verdict(self, ts: float, name: str) -> Optional[Verdict]:
        """Whether aux sensor ``name`` or the baro bent against the INS at the
        strongest kink of their difference in the window (None: the INS cannot
        tell, or there is no kink to explain)."""
        m = self.m
        keys = (f"{name}-baro", f"{name}-ins", "baro-ins")
        if any(self.kink_sd[k].n < m.kink_min_learned for k in keys):
            return None
        s, y = self.kink[keys[0]].arrays(ts)
        if s.size < m.kink_min_samples or s[0] > -m.kink_min_fill_frac * m.kink_window_s:
            return None
        taus = onsets(s, m.kink_min_pre_s, m.kink_min_post_s)
        if taus.size == 0:
            return None
        num, den = kink_fit(s, y, taus, quadratic=False)
        good = den > 0
        if not good.any():
            return None
        sd_ab = self.kink_sd[keys[0]].sd
        z = np.where(good, num / np.sqrt(np.where(good, den, 1.0)), 0.0) / sd_ab
        j = int(np.argmax(np.abs(z)))
        if abs(z[j]) < m.kink_min_z:
            return None  # no kink to explain
        tau, a = float(taus[j]), float(num[j] / den[j])
        k_aux, k_baro = self._kink(keys[1], ts, tau), self._kink(keys[2], ts, tau)
        if k_aux is None or k_baro is None:
            return None
        d = isolate(a, *k_aux, *k_baro)
        if abs(d) < self.kink_margin:
            return None
        bent, kept = (name, BARO_S) if d > 0 else (BARO_S, name)
        return Verdict(f"{name} ramp onset", "pass", frozenset((name, BARO_S)), frozenset((kept,)),
                       abs(d), self.kink_margin,
                       text=f"{LABEL.get(bent, bent)} bent {-tau:.1f} s ago against the INS "
                            f"({a:+.2f} m/s between {LABEL[name]} and baro; {LABEL[name]}-INS "
                            f"{k_aux[0]:+.2f}, baro-INS {k_baro[0]:+.2f} m/s)", scale_m=0.0)

    # ------------------------------------------------------------------ after the step

    def _available(self, t: int) -> tuple[bool, bool, bool]:
        ph = self.bank.P[:, 0, 0].tolist()  # Python floats: the same comparisons without numpy scalars
        max_var = self.m.max_channel_sigma_m ** 2
        excluded = self.excluded
        last_g, last_r = self.last_accept_us[GNSS], self.last_accept_us[RNG]
        return (GNSS_S not in excluded and last_g is not None and t - last_g <= self.stale_us[GNSS]
                and ph[GNSS] <= max_var,
                RANGEFINDER_S not in excluded and last_r is not None and t - last_r <= self.stale_us[RNG]
                and ph[RNG] <= max_var,
                t - self.last_baro_us <= self.stale_baro_us and ph[BARO] <= max_var)

    def post(self, ep: EpochInputs, ep_used: EpochInputs, step) -> Decision:
        bank = self.bank
        t = ep.t_us
        self._advance(ep, t)
        avail = self._available(t)
        pairs = pair_reports_scaled(bank, avail, self.sensor_var_floor, self.k_cmp)
        verdicts, aux = self._verdicts(t, avail)
        live = live_hypotheses(self.excluded)
        j = judge(verdicts, live) if self.f.isolation_2of3 else self._paper_judge(verdicts, live)
        j = self.judgement = self._restart_held(t, self._slow_blame(j), aux)
        # isolation must hold persist_s before it excludes
        if j.situation == "isolated":
            if self.isolated_src != j.sources:
                self.isolated_src, self.isolated_since = j.sources, t
        else:
            self.isolated_src, self.isolated_since = frozenset(), None
        events = []
        for name in SENSOR_SOURCES:
            ev = self._source_state(name, t, j)
            if ev is not None:
                events.append(ev)
        h, sigma, used, vpl = self._fuse(j, avail)
        if self.f.validated_feedback:
            self._feedback(t, avail)
        # each source's displayed statistic and threshold: those of the first verdict of its test
        shown: dict = {}
        for v in verdicts:
            if v.test not in shown:
                shown[v.test] = v
        statuses = {}
        rejections = self.rejections
        for name, trk in self.trackers.items():
            v = shown.get(_DISPLAY_TEST[name])
            statuses[name] = trk.window_status(v.stat if v is not None else math.nan,
                                               v.threshold if v is not None else math.nan,
                                               rejections[name].rejected)
        return Decision(avail, tuple(used), pairs, statuses, h, sigma, events, vpl)

    def _advance(self, ep: EpochInputs, t: int) -> None:
        """The tests' own state after the filter step: windows, raw checks, the
        INS chains, the ramp-onset series, the open baro jump."""
        for w in self.rejections.values():
            w.expire(t)
        self.raw_check.push(t, self.pending_raw[GNSS], self.pending_raw[RNG])
        self.ins.push(t, ep.dt_s, ep.dp_m, ep.dv_mps, ep.baro_m, self.bank.x[BARO], self.bank.P[BARO])
        if self.f.baro_u_measured:
            self.baro_u.push(t, ep.dt_s, ep.dp_m, ep.dv_mps, ep.baro_m, self.bank.x[BARO], self.bank.P[BARO])
            if ep.baro_m is not None:
                self.baro_u.observe(t, self.baro_white_var, self._ins_psd(),
                                    self.bank.model.baro_bias_rw_m_per_sqrt_s ** 2)
        if self.f.ins_doppler_check:
            self._push_ins_doppler(ep)
        if self.f.kink_isolation:
            self._push_kinks(t, ep.baro_m)
        if self.baro_judged is not None:
            self._track_jump(t, ep.baro_m, *self.baro_judged)
            self.baro_judged = None

    def _verdicts(self, t: int, avail: tuple) -> tuple[list, tuple]:
        """Every test's verdict this epoch (and the aux innovation verdicts, which
        the hold rule needs); ``avail``: :meth:`_available` at ``t``."""
        envelope = self._envelope_verdict(t)
        self.envelope_failing = envelope is not None  # also holds back the rangefinder's readmission
        if RANGEFINDER_S in self.excluded:
            envelope = None
        ins_tests = (self._slow_ins(self._ins_verdict(t)), self._slow_ins(self._ins_doppler_verdict(t)))
        # an INS test that is not passing puts the INS among what an aux channel's
        # innovations can mean (the channel runs on it between its samples)
        v_ins, v_insdop = ins_tests
        self.ins_doubt = ((v_ins is not None and v_ins.level != "pass")
                          or (v_insdop is not None and v_insdop.level != "pass"))
        aux = (self._aux_verdict(GNSS, GNSS_S, t), self._aux_verdict(RNG, RANGEFINDER_S, t))
        drift = self._drift_verdict(t)
        baro_doppler = self._baro_doppler_verdict(t)
        verdicts = [v for v in (*aux, *ins_tests, self._raw_verdict(t), envelope, self._doppler_verdict(t),
                                baro_doppler, drift)
                    if v is not None] + self._level_verdicts(t, avail)
        if self.f.kink_isolation and self.slow_imu_hz is None:  # the INS witnesses the kinks
            verdicts += self._kink_verdicts(t, aux, (drift, baro_doppler))
        if self.f.ground_effect_watch:
            near = self._near_ground(t)
            if near or (self.f.ground_effect_window and self._window_from_ground(t)):
                # near it, any baro suspicion; just up from it, the baro/Doppler window's
                # alone, whose start still holds the baro read in the wash
                verdicts = [v for v in verdicts if not (v.level == "suspect" and BARO_S in v.implicates
                                                        and (near or v.test == "baro/Doppler"))]
        return verdicts, aux

    def _window_from_ground(self, t: int) -> bool:
        """The baro/Doppler test's window (``baro_doppler_window_s``) reaches
        back to where the fused height was near the ground the flight started
        on, and the fused height is above it now (never below: a baro pulling
        the output down is no take-off)."""
        last = self.near_ground_us
        return last is not None and t - last <= self.baro_doppler_window_us and self.last_fused_m > 0.0

    def _near_ground(self, t: int) -> bool:
        """The fused height within ``ground_effect_height_m`` of the ground the
        flight started on (its datum): on the ground with the propellers
        turning, at take-off and at touchdown, where the baro reads their
        downwash (ground effect) and a departure below a test's threshold is
        expected, not a suspicion. Failures still count; after a start away
        from the datum the ground is unknown and nothing is waived. A fused
        height more than that below the ground is not near it: that is a baro
        pulling the output down, and a dive fault would waive its own
        suspicion (which is also what keeps the level it pulled the channel
        to from being given back as the baro's offset at readmission).
        Near it, ``t`` is noted for :meth:`_window_from_ground`."""
        h = self.last_fused_m
        if self.at_datum and abs(h) < self.m.ground_effect_height_m:
            self.near_ground_us = t
            return True
        return False

    def _slow_ins(self, v: Optional[Verdict]) -> Optional[Verdict]:
        """An INS test while the IMU runs below ``min_imu_rate_hz`` (the core's
        rate check says so) is no evidence: snapshots that sparse miss the
        motion between them, so the INS can neither tell a baro or GNSS fault
        from its own gaps nor vouch for anything, and a slow input never makes
        a sensor faulty or suspect (the input source says monitoring is
        degraded)."""
        return v if self.slow_imu_hz is None else None

    def _slow_blame(self, j: Judgement) -> Judgement:
        """An isolation of the baro while its stream runs below
        ``min_baro_rate_hz`` (its own rate, which follows a drop within a few
        samples; the core's rate check averages over seconds) is held as
        ambiguous: out of the output, in caution, never in alarm. Samples that
        sparse leave the baro+INS channel on the INS between them, so its level
        tests cannot tell a baro fault from its gaps, and a slow input never
        makes a sensor faulty (the same rule as :meth:`_slow_ins`)."""
        hz = self.rates[BARO_INS_S].hz
        if j.situation != "isolated" or BARO_S not in j.candidates or hz >= self.m.rate_tolerance_frac * self.m.min_baro_rate_hz:
            return j
        return Judgement("ambiguous", j.candidates, j.sources,
                         f"cannot isolate: {j.reason}; the baro at {hz:.1f} Hz is too sparse to judge it")

    def _fuse(self, j: Judgement, avail) -> tuple[float, float, tuple, float]:
        """The fused height of the channels the evidence clears (NaN: none),
        its sigma, the channels used and the protection level (NaN: the
        fault-free bound, when separation_protection is off)."""
        bank = self.bank
        cleared = {n: self.trackers[n].state == "nominal" or
                   (self.trackers[n].state == "caution" and n not in self._held(j)) for n in SENSOR_SOURCES}
        baro_ok = cleared[BARO_INS_S] and avail[BARO]
        # the rangefinder's height is above the reference only once its ground is
        # placed (a start at the datum, the operator's word, or the raw check's
        # first window against the GNSS: monitor/rawcheck.py)
        used = (avail[GNSS] and cleared[GNSS_S] and (baro_ok or not bank.baro_on[GNSS]),
                avail[RNG] and cleared[RANGEFINDER_S] and (baro_ok or not bank.baro_on[RNG])
                and self.raw_check.ground_m is not None,
                baro_ok)
        idx = [c for c in range(3) if used[c]]
        h, sigma, vpl = math.nan, math.nan, math.nan
        if idx:
            cov = bank.height_cov(idx)
            if used[RNG] and self.raw_check.ground_var_m2 > 0.0:
                # the ground a start away from the datum learnt under the rangefinder
                # from the GNSS: its channel's height carries that ground's error, which
                # its filter does not know (the ground is no state of the channel)
                k = idx.index(RNG)
                cov[k][k] += self.raw_check.ground_var_m2
            h, sigma, w = fuse_heights([bank.x[c, 0] for c in idx], cov, self.f.inverse_variance)
            if self.f.separation_protection:
                lean, own = -1, None
                if self.f.own_sensor_floor and BARO in idx:
                    # the aux sensors that report worse than the alert limit: their
                    # channels take the baro's changes and cannot vouch for it there
                    lean, lim2 = idx.index(BARO), self.m.alert_limit_m ** 2
                    floor = self.sensor_var_floor
                    own = [floor[c] if c != BARO and bank.baro_on[c] and floor[c] > lim2 else 0.0 for c in idx]
                vpl, _ = protection_level(sigma, cov, w, self.k_ff, self.k_cmp, self.k_md, lean, own)
        self.last_fused_m = h
        return h, sigma, used, vpl

    def _restart_held(self, t: int, j: Judgement, aux) -> Judgement:
        """An unresolved failure held ``hold_restart_s``: the sequential tests in
        it start again (their detection is done). The hold stays until the
        restarted tests have run ``hold_restart_s`` without failing: a change
        the channels absorbed is then released, a fault that goes on fails again
        first and stays held (it never re-enters the output in between)."""
        if j.situation in ("ambiguous", "inconsistent"):
            self.last_hold = j
            if self.hold_since is None:
                self.hold_since = t
            elif self.hold_restart_us > 0 and t - self.hold_since >= self.hold_restart_us:
                self.hold_since = t
                for v, (_, name) in zip(aux, AUX):
                    if v is not None and v.failed and self._cusum_stat(name) > self._h(name):
                        self.cusum[name].clear()
                        self.restarted_us[name] = t
            return j
        self.hold_since = None
        fresh = any(t - self.restarted_us[n] < self.hold_restart_us for n in self.restarted_us)
        if self.last_hold is not None and fresh and j.situation in ("suspect", "clear"):
            h = self.last_hold
            return Judgement(h.situation, h.candidates, h.sources,
                             "held until the restarted test runs clean: " + h.reason)
        self.last_hold = None
        return j

    @staticmethod
    def _held(j: Judgement) -> frozenset:
        return j.sources if not j.enters_output else frozenset()

    def _paper_judge(self, verdicts, live) -> Judgement:
        """Isolation switched off: every failure blames its own sensor (the
        paper's rule, channel against baro+INS)."""
        for v in verdicts:
            if v.failed:
                name = v.test.split(" ")[0]
                # a test name's first word -> the source it blames
                src = {"gnss": GNSS_S, "rangefinder": RANGEFINDER_S, "baro/INS": BARO_INS_S, "raw": GNSS_S}.get(name)
                if src and src not in self.excluded:
                    return Judgement("isolated", frozenset(), frozenset((src,)), v.text)
        return judge([v for v in verdicts if not v.failed], live)

    def _source_state(self, name: str, t: int, j: Judgement):
        tr = self.trackers[name]
        if name in self.excluded:
            if (name == BARO_INS_S and not self.ins_excluded and j.situation == "isolated" and INS_S in j.candidates
                    and t - (self.isolated_since or t) >= self.persist_us):
                # out for its baro, now isolated for its INS too: what the aux
                # channels' sequential tests sum from here is the INS's doing (an
                # accelerometer bias on a flight whose baro was already out had
                # been pinned on the GNSS when it ended)
                self.ins_excluded = True
                for _, aux_name in AUX:
                    self.cusum[aux_name].clear()
            return self._maybe_readmit(name, t)
        if name == BARO_INS_S:
            if t - self.last_baro_us > self.stale_baro_us:
                return tr.set("unavailable", t, "no recent baro")
        else:
            c = CHANNEL_OF[name]
            if self.last_seen_us[c] is None or t - self.last_seen_us[c] > self.stale_us[c]:
                env = j.situation == "isolated" and j.sources == _ONLY[name]
                if not env:
                    return tr.set("unavailable", t, "no recent data")
        if name in j.sources:
            if j.situation == "isolated":
                if t - (self.isolated_since or t) >= self.persist_us:
                    if name == BARO_INS_S:
                        self.ins_excluded = INS_S in j.candidates
                    return self._exclude(name, t, j.reason)
                return tr.set("caution", t, j.reason)
            return tr.set(j.state, t, j.reason)
        return tr.set("nominal", t, "consistent")

    def _exclude(self, name: str, t: int, reason: str):
        self.excluded.add(name)
        self.consistent_since[name] = None
        if name == BARO_INS_S:
            self.baro_excluded_us = t
            # a faulty baro is taken out of every aux channel, not only the fusion,
            # and what it pulled into their speed is let go
            for c, _ in AUX:
                if self.bank.baro_on[c]:
                    self.bank.open_speed(c, self.m.baro_exclusion_vel_sigma_mps ** 2)
            self.bank.baro_on[GNSS] = self.bank.baro_on[RNG] = False
            # what the aux channels' sequential tests summed while their channel
            # rested on this source is its doing, not their sensors' (it had pinned
            # a baro ramp, then an INS fault, on the GNSS after the baro+INS source
            # was out); with the INS at fault they stay frozen until it is back
            for _, aux_name in AUX:
                self.cusum[aux_name].clear()
        else:
            self.cusum[name].clear()
            self.rejections[name].clear()
        return self.trackers[name].set("alarm", t, reason)

    # ------------------------------------------------------------------ readmission

    def _others_fused(self, exclude: int, t: int) -> Optional[tuple[float, float]]:
        """The height the other channels hold, each only where its own sensor
        does (``_available``): a rangefinder channel on a flight with no
        rangefinder, or one coasting out of range, is one more baro+INS channel,
        not a second witness (it had held the true height beside a baro+INS
        channel shifted 10 m, and a GNSS 12 m below the output was readmitted
        on their average and re-initialised onto the shifted one)."""
        bank = self.bank
        avail = self._available(t)
        idx = [c for c, n in ((GNSS, GNSS_S), (RNG, RANGEFINDER_S), (BARO, BARO_INS_S))
               if c != exclude and n not in self.excluded and avail[c]]
        if not idx:
            return None
        h, s, _ = fuse_heights([bank.x[c, 0] for c in idx], bank.height_cov(idx), True)
        return h, s

    def _consistent_for(self, name: str, t: int, ok: bool) -> bool:
        if not ok:
            self.consistent_since[name] = None
            return False
        if self.consistent_since[name] is None:
            self.consistent_since[name] = t
        return self.f.readmission and t - self.consistent_since[name] >= self.readmit_us

    def _maybe_readmit(self, name: str, t: int):
        if name == BARO_INS_S:
            return self._maybe_readmit_baro(t)
        c = CHANNEL_OF[name]
        raw = self.pending_raw[c]
        if raw is None:
            if self.last_seen_us[c] is not None and t - self.last_seen_us[c] > self.stale_us[c]:
                self.consistent_since[name] = None
            return None
        ref = self._others_fused(c, t)
        if ref is None:
            return None
        z, sigma = raw
        h, s = ref
        # a GNSS whose altitude still moves against its own Doppler velocity stays out,
        # and one whose Doppler moves against the baro in use: the Doppler is what
        # the baro's ramps are judged by, so it comes back only when it is right too
        # hysteresis: back only inside clear_frac of the threshold that excludes (a
        # GNSS 5 m off with a 1 m accuracy was readmitted at 4.4 sigma, into the output)
        ok = (abs(z - h) <= self.m.clear_frac * self.k_cmp * math.hypot(sigma, s)
              and not (c == RNG and self.envelope_failing)
              and not (c == GNSS and (self.doppler_ex.count > 0 or self._doppler_against_baro())))
        if not self._consistent_for(name, t, ok):
            return None
        self.excluded.discard(name)
        self._reinit_aux(c, name, t, sigma)
        return self.trackers[name].set("nominal", t, f"readmitted after {self.m.readmit_s:g} s consistent; "
                                                     "channel re-initialised")

    def _doppler_against_baro(self) -> bool:
        """The Doppler's integral over the baro/Doppler window, while the baro is
        in use, disagrees with the baro beyond clear_frac of that test's threshold."""
        d = self.baro_doppler
        if BARO_INS_S in self.excluded or d.last_e_m != d.last_e_m:
            return False
        return abs(d.last_e_m) > self.m.clear_frac * self._window_thr(d, "baro_doppler")

    def _maybe_readmit_baro(self, t: int):
        """Back when the baro agrees with the INS again and, where an aux
        channel runs without it, with that channel's level ``H + dH``."""
        bank = self.bank
        rej = self.rejections[BARO_INS_S].rejected
        v = self._ins_verdict_quiet(t)
        # and not while the INS, or the baro, still disagrees with the GNSS Doppler
        # (an accelerometer fault must end before the source is back, and a baro
        # ramp, which the second difference cannot see, too)
        ok = (v and rej == 0 and self.last_baro_m is not None and self.insdop_ex.count == 0
              and self.baro_doppler_ex.count == 0)
        if ok:
            for c, name in AUX:
                if name in self.excluded or not self._available(t)[c]:
                    continue
                x, P = bank.x[c], bank.P[c]
                r = self.last_baro_m - (x[0] + x[2])
                # (the level test's own threshold: a stricter readmission than the test is a latch)
                ok = ok and abs(r) <= self._level_thr(name, P[0, 0] + P[2, 2] + 2.0 * P[0, 2] + self.baro_white_var)[0]
        if not self._consistent_for(BARO_INS_S, t, bool(ok)):
            return None
        self.excluded.discard(BARO_INS_S)
        self.rejections[BARO_INS_S].clear()
        self._rebase_baro(t, aux=not self.ins_excluded)
        self.baro_readmitted_us = t
        bank.baro_on[:] = True  # differencing restarts in the aux channels
        # the aux channels' sequential tests summed innovations their channel made
        # while it rested on the faulty source: that evidence is spent
        for c, name in AUX:
            self.cusum[name].clear()
            self.rejections[name].clear()
            if self.ins_excluded and name not in self.excluded and self.last_seen_us[c] is not None:
                # and a channel that ran on the faulty INS starts again
                self._reinit_aux(c, name, t, math.sqrt(self.sensor_var_floor[c]))
        self.ins_excluded = False
        return self.trackers[BARO_INS_S].set("nominal", t, f"readmitted after {self.m.readmit_s:g} s consistent")

    def _rebase_baro(self, t: int, aux: bool) -> None:
        """The baro is back after a fault of its own, at a level that need not
        be its level before (a step stays, and passes every windowed test once
        it is past). Each aux channel that ran without it takes the baro's bias
        from this sample and its own height, and the baro+INS channel restarts
        from the surest of them: the output keeps the height the aux sensors
        held, and the baro brings back its changes, not its offset."""
        bank = self.bank
        noise = bank.model.sigma_bb_m ** 2 + self.baro_white_var
        avail = self._available(t)
        best = None
        # the baro's offset from its level before the fault, as read by the surest aux
        # channel that ran without it (its baro bias is the one from before)
        seen_m, seen_var = None, math.inf
        for c, name in AUX:
            if name in self.excluded or not avail[c] or bank.baro_on[c]:
                continue
            if bank.P[c, 0, 0] < seen_var:
                seen_m, seen_var = self.last_baro_m - (bank.x[c, 0] + bank.x[c, 2]), bank.P[c, 0, 0]
            if not aux:
                continue  # (with the INS at fault the aux channels start again instead)
            bank.rebase_baro_bias(c, self.last_baro_m, noise)
            if best is None or bank.P[c, 0, 0] < bank.P[best, 0, 0]:
                best = c
        self.baro_level_set = best is not None
        if best is not None:
            bank.reinit_from(BARO, best)
            bank.baro_prev[BARO] = math.nan  # its differencing restarts with the aux channels'
            self.baro_given_back = (0.0, 0.0)  # the level is the aux channels' now
        else:
            # nothing held the height without the baro: the baro+INS channel
            # followed the baro, so its level moves back by the steps the baro
            # made against the INS while out (a step and its return cancel).
            # Only when every step was measured from a level no test doubted:
            # one measured from a level the channel had followed along with the
            # fault (a fast ramp, then the baro snapping back) gives back the
            # fault itself. Then the baro comes back at its own level (the steps'
            # sum is not added to its uncertainty: past max_channel_sigma_m that
            # would take the only height there is out of the output for good).
            # Nor when an aux channel that ran without the baro (the INS at fault
            # too, so nothing rebased on it) reads the baro nearer its level from
            # before than that level plus the steps: the steps have gone back,
            # though the gate, anchored on that channel, saw no jump in the return
            # (a 5 m step that ended was given back as -5 m, the output at
            # 'nominal' 5 m off for the rest of the flight).
            since = (self.baro_excluded_us or t) - int(1e6 * (self.m.baro_jump_confirm_s
                                                              + self.m.baro_jump_settle_s + 1.0))
            steps = [s for s in self.baro_steps if s[0] >= since]
            if steps:
                total = sum(s[1] for s in steps)
                var = sum(s[2] * s[2] for s in steps)
                gone = seen_m is not None and abs(seen_m) < abs(seen_m - total)
                # the return of what an earlier readmission gave back cancels it, however
                # its jump was measured (a caution of the flight's own a second before a
                # 5 m step ended left the step in the output)
                back, back_var = self.baro_given_back
                returns = (back != 0.0 and abs(total + back) <= math.sqrt(self.gate * (var + back_var))
                           and not gone)
                if (all(s[3] for s in steps) and not gone) or returns:
                    bank.shift_baro_level(BARO, total, var)
                    self.baro_level_set = True
                    # (a return settles what was given back)
                    self.baro_given_back = (0.0, 0.0) if returns else (back + total, back_var + var)
                else:
                    bank.shift_baro_level(BARO, 0.0, var)
        self.baro_steps.clear()

    def _ins_residual(self) -> Optional[tuple]:
        """The baro/INS statistic (m), its sigma and threshold (m) and its window (s),
        with the noise the test itself uses: the INS model's, the measured IMU
        scatter beyond it, and the measured scale."""
        model = self.bank.model
        res = self.ins.residual(self.baro_white_var, self._ins_psd(), model.baro_bias_rw_m_per_sqrt_s ** 2,
                                model.sigma_bb_m ** 2, model.gamma_bb_per_s)
        if res is None:
            return None
        e, sigma, D = res
        return e, sigma, self.k_cmp * sigma * self.scale[INS_S].factor, D

    def _ins_psd(self) -> float:
        """The INS's position noise PSD over the baro/INS windows: the model's
        and the measured IMU scatter beyond it, at the baro's interval."""
        model = self.bank.model
        iv = self.rates[BARO_INS_S].interval_s
        T = max(iv, 1e-3) if iv == iv else 0.1
        return 2.0 * model.sigma_a_mps2 ** 2 / model.alpha_a_per_s + self.dv_var / T

    def _ins_verdict_quiet(self, t: int) -> bool:
        """Readmission: the baro agrees with the INS by the test's own noise
        model (a stricter one than the test that excluded it is a latch: on
        telemetry-rate IMUs the model alone never passed)."""
        res = self._ins_residual()
        return res is not None and abs(res[0]) <= res[2]

    # ------------------------------------------------------------------ feedback

    def _feedback(self, t: int, avail) -> None:
        """Correct the reference channel from channels nominal for validate_s
        and clearly consistent with it now: weak (``feedback_inflation``),
        rate-limited, never into a suspect baro. A channel that has begun to
        separate, before any test calls it (a frozen rangefinder in a
        descent, 0.7 m and 3 sigma from the baro channel while still
        nominal), would carry its sensor's fault into the baro channel, and
        the fused height would follow with no separation left to show it
        (the simulated frozen descent: 1.2 s of error beyond the protection
        level)."""
        if t - self.last_feedback_us < self.feedback_us:
            return
        self.last_feedback_us = t
        if BARO_INS_S in self.excluded or self.trackers[BARO_INS_S].state != "nominal":
            return
        bank = self.bank
        # each aux channel's height within clear_frac of the comparison's threshold
        # of the baro channel's (the sigma of their difference, cross terms included)
        limit = self.m.clear_frac * self.k_cmp
        sd = diff_sigmas(bank)
        src = [c for c, name in AUX if avail[c] and self.trackers[name].state == "nominal"
               and t - self.trackers[name].since_us >= self.validate_us and not self._warm(name, t)
               and abs(bank.x[c, 0] - bank.x[BARO, 0]) <= limit * sd[PAIRS.index((c, BARO))]]
        if not src:
            return
        _, _, w = fuse_heights([bank.x[c, 0] for c in src], bank.height_cov(src), True)
        bank.feedback(BARO, list(src), np.asarray(w), inflation=self.m.feedback_inflation)
