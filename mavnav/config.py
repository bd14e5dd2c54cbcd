"""Typed, frozen configuration loaded from YAML.

Every section is a frozen pydantic model that forbids unknown keys, so a
misspelt option is refused with its dotted name instead of being silently
ignored. :func:`load_config` turns every failure (missing file, bad YAML,
unknown key, bad value) into a one-line :class:`~mavnav.errors.ConfigError`.

Units are in the key names, as everywhere in mavnav.
"""

from __future__ import annotations

from pathlib import Path
from typing import Literal, Optional, Union

import annotated_types
import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

from .constants import G0_MPS2
from .errors import ConfigError

# The vehicle clock stepping back by more than this is a reboot (the default of
# ingest.reboot_jump_s; the rule itself is mavnav.ingest.clock.is_reboot).
REBOOT_JUMP_S = 2.0


class _Section(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, strict=False)


# ---------------------------------------------------------------- sensors
#
# Each sensor is described twice, on purpose: by the estimator's model of it
# (SensorsConfig below) and by the simulator's truth (the scenario's
# ``sensors:``, mavnav.sim.scenario.SimSensorsConfig), which must stay free to
# differ from the model. The quantities both give are declared once, in the
# *Noise sections: their key (unit in the name), meaning and bounds. The
# model's sections extend them with what only the model has; the simulator's
# extend them with what only the truth has and declare their own defaults
# with truth_field, which keeps the key's bounds.


class InsNoise(_Section):
    """The INS vertical specific-force noise (MODEL.md eq. 1-2)."""

    # sigma_a 0.1 m/s^2 at alpha_a 1: above every real flight here whose IMU and
    # Doppler agree (fitted 0.035 at the median, 0.081 at the 90th percentile;
    # bench/ins_stats.py, docs/error_models.md)
    sigma_a_mps2: float = Field(0.1, gt=0)  # RMS of the acceleration noise
    alpha_a_per_s: float = Field(1.0, gt=0)  # spectrum width of that noise


class BaroNoise(_Section):
    """The barometric altimeter's Gauss-Markov noise u (MODEL.md eq. 3-5)."""

    # sigma_bb 0.2 m: measured on 69 real flights with bench/estimator_real.py
    # (BENCHMARKS.md, docs/error_models.md)
    sigma_bb_m: float = Field(0.2, gt=0)  # RMS of the Gauss-Markov noise u
    gamma_bb_per_s: float = Field(0.5, gt=0)  # its inverse correlation time


class GnssNoise(_Section):
    """The GNSS altitude's white noise."""

    sigma_z_m: float = Field(2.0, gt=0)  # vertical noise when v_acc is not used


class RangefinderNoise(_Section):
    """The rangefinder's white noise."""

    sigma_m: float = Field(0.05, gt=0)


def truth_field(section: type[BaseModel], key: str, default: Optional[float] = None, *, zero_ok: bool = False):
    """The field ``key`` of ``section`` as the simulator's truth of the same
    quantity declares it: the same bounds, its own ``default`` (None: the
    model's), and with ``zero_ok`` a bound > 0 relaxed to >= 0 (a noise-free
    simulated sensor; the model's noise must stay positive)."""
    f = section.model_fields[key]
    bounds = {}
    for m in f.metadata:
        if isinstance(m, annotated_types.Gt):
            bounds["ge" if zero_ok and m.gt == 0 else "gt"] = m.gt
        elif isinstance(m, annotated_types.Ge):
            bounds["ge"] = m.ge
        elif isinstance(m, annotated_types.Lt):
            bounds["lt"] = m.lt
        elif isinstance(m, annotated_types.Le):
            bounds["le"] = m.le
        else:
            raise TypeError(f"{section.__name__}.{key}: {m!r} is not a bound truth_field carries")
    return Field(f.default if default is None else default, **bounds)


class InsConfig(InsNoise):
    """INS vertical specific-force error model (MODEL.md eq. 1-2)."""

    bias_rw_mps2_per_sqrt_s: float = Field(0.002, ge=0)  # random walk on da (0: constant, as the paper)


class BaroConfig(BaroNoise):
    """Barometric altimeter error model (MODEL.md eq. 3-5)."""

    # the bias walk 0.02 m/sqrt(s): measured on 69 real flights with
    # bench/estimator_real.py (BENCHMARKS.md, docs/error_models.md)
    bias_rw_m_per_sqrt_s: float = Field(0.02, ge=0)  # random walk on dH (0: constant, as the paper)
    # White noise on top of u, measured at run time from the sensor's own
    # samples (robust spread of second differences over white_window
    # samples) and held within [white_min_m, white_max_m]: real baros range
    # from 0.1 m (ArduPilot, 10 Hz) to 0.45 m (PX4 vehicle_air_data, 5 Hz),
    # see docs/error_models.md. white_max_m 0 turns it off (paper mode).
    # Until five second differences exist the filters take white_prior_m (the
    # noisiest real baros' 90th percentile, 0.43 m: a baro not yet measured is
    # not trusted as a clean one), then the window's own estimate while it
    # fills; the significance test against the model's u decides once it is
    # full. Passing none until then, the first differenced rows of a noisy
    # 5 Hz PX4 baro set a vehicle at rest climbing at 0.9 m/s
    # (flug_1x_wo_Last_5m, BENCHMARKS.md session 25).
    white_min_m: float = Field(0.0, ge=0)
    white_max_m: float = Field(1.0, ge=0)
    white_window: int = Field(61, ge=5)
    white_prior_m: float = Field(0.43, ge=0)


class GnssConfig(GnssNoise):
    """GNSS vertical error: white noise (sigma_z_m, or the receiver's v_acc)
    plus a first-order Gauss-Markov error (gm_sigma_m, gm_tau_s), the slow
    wander of GNSS altitude (multipath, satellite geometry) seen on real
    flights. gm_sigma_m 0 turns the Gauss-Markov state off (paper mode)."""

    # On from the start in adaptive mode (paper mode: off). 4 m / 300 s gives the
    # median flight's baro-GNSS structure function (docs/error_models.md). The
    # state follows a slow GNSS ramp as it follows the wander: the ramp is the
    # drift tests' to catch, against the receiver's Doppler (monitor/doppler.py)
    # or, without one, against the baro (monitor/drift.py).
    gm_sigma_m: float = Field(4.0, ge=0)  # RMS of the Gauss-Markov error
    gm_tau_s: float = Field(300.0, gt=0)  # its correlation time
    use_v_acc: bool = True  # take sigma from the receiver's v_acc when it reports one
    v_acc_floor_m: float = Field(0.3, ge=0)  # never trust a receiver more than this


class RangefinderConfig(RangefinderNoise):
    # Height-proportional part of the noise (scale error, uneven ground): the
    # sigma used is sqrt(sigma_m^2 + (scale_sigma_frac * height)^2).
    scale_sigma_frac: float = Field(0.03, ge=0)


class SensorsConfig(_Section):
    ins: InsConfig = InsConfig()
    baro: BaroConfig = BaroConfig()
    gnss: GnssConfig = GnssConfig()
    rangefinder: RangefinderConfig = RangefinderConfig()


# ---------------------------------------------------------------- filter


class InitialCovariance(_Section):
    height_m2: float = Field(300.0, gt=0)
    vel_m2ps2: float = Field(20.0, gt=0)
    # 2 m: the baro reference is taken against the autopilot's height at start,
    # so the bias is small by construction (625 m^2 kept sigma at 25 m for whole flights)
    baro_bias_m2: float = Field(4.0, gt=0)
    # The same when the baro reference was taken at the datum (ReferenceSet.at_datum):
    # the mean of ~2 s of baro samples on the ground, so its error is the baro's
    # own noise over that window (white 0.1-0.45 m and u 0.2 m, correlation 2 s:
    # about 0.2 m); 0.3 m keeps a margin. Adaptive mode only; paper mode keeps P0.
    baro_bias_at_datum_m2: float = Field(0.09, gt=0)
    # The vertical speed's prior at such a start: the vehicle is on the ground,
    # at rest (0.5 m/s covers a take-off already under way within at_datum_max_m).
    # With vel_m2ps2 (4.5 m/s) the first differenced baro row, its sample-to-sample
    # noise over 0.04 s, set the speed to 4-6 m/s on simulated ground starts, the
    # next rows could not take it back within 3 s, and the output sat 3 m below
    # the ground at 'nominal' (session 19). Since the IMU is no longer dropped
    # before the first epoch (session 21) the general prior leaves 2.45 m
    # instead of 1.79 m on the worst of 12 seeds, not 3 m. Adaptive mode only.
    vel_at_datum_m2ps2: float = Field(0.25, gt=0)
    acc_bias_m2ps4: float = Field(0.01, gt=0)


class FilterConfig(_Section):
    # "consistent": q_a = sigma_a sqrt(2 / (alpha_a T)) (MODEL.md erratum);
    # "printed": q_a = sigma_a sqrt(2 T / alpha_a), only to reproduce the paper.
    accel_noise_form: Literal["consistent", "printed"] = "consistent"
    p0: InitialCovariance = InitialCovariance()
    # Covariance analysis and simulation step.
    step_s: float = Field(0.02, gt=0)
    # Longest interval between two filter epochs before the epoch builder
    # forces an epoch without a baro sample (and restarts the differencing):
    # the larger of max_epoch_gap_s and epoch_gap_intervals baro intervals
    # (a 2 Hz telemetry baro is slow, not in a gap).
    max_epoch_gap_s: float = Field(0.25, gt=0)
    epoch_gap_intervals: float = Field(3.0, gt=1)
    # A GNSS/rangefinder sample older than its latency limit at its epoch is
    # dropped as late. The limit is the larger of max_meas_latency_s and
    # meas_latency_intervals times (baro interval + the stream's own
    # interval), never above max_meas_age_s.
    max_meas_latency_s: float = Field(0.25, gt=0)
    meas_latency_intervals: float = Field(2.0, gt=0)
    max_meas_age_s: float = Field(1.5, gt=0)
    # An IMU sample is held (zero-order hold) at most this long, or
    # imu_hold_intervals of the IMU's own interval if longer; beyond, the
    # vertical acceleration is unknown (kinematic model: zero mean, RMS
    # kinematic_accel_sigma_mps2 with correlation time kinematic_accel_tau_s).
    imu_hold_max_s: float = Field(0.5, gt=0)
    imu_hold_intervals: float = Field(3.0, gt=1)
    kinematic_accel_sigma_mps2: float = Field(3.0, gt=0)
    kinematic_accel_tau_s: float = Field(1.0, gt=0)
    # The scatter of consecutive IMU samples (what a snapshot misses of the
    # acceleration between samples) is averaged over this much vehicle time.
    imu_scatter_window_s: float = Field(5.0, gt=0)
    # A baro sample repeating the previous pressure exactly within this long is
    # the same measurement sent again (telemetry faster than the sensor), not
    # a new one, and makes no epoch. Off (0) by default: a noise-free or
    # coarsely quantised baro at rest repeats genuinely (ArduPilot SITL
    # repeats 88 % of its samples on the ground) and skipping those slows the
    # epochs, and with them the time-to-alarm, to 1 s.
    baro_repeat_max_s: float = Field(0.0, ge=0)
    # Condition the prior on the first baro sample (exactly equivalent to the
    # state-augmented filter); otherwise the first sample only starts differencing.
    init_from_first_baro: bool = True
    # Height prior at start. "diffuse": nothing known of H but what the first
    # baro sample says (H = baro, var P0_dH + sigma_bb^2, cov(H, dH) = -P0_dH),
    # so a start in flight is as good as one on the ground. "p0": the paper's
    # zero-mean P0 conditioned on the first baro sample (a start near the
    # reference point).
    height_prior: Literal["diffuse", "p0"] = "diffuse"
    # Gravity used in the control input W = [f_up, g].
    gravity_mps2: float = Field(G0_MPS2, gt=0)


# ---------------------------------------------------------------- ingestion


class ReferenceConfig(_Section):
    """Where a height reference comes from: a configured value, the autopilot's
    home (HOME_POSITION, GLOBAL_POSITION_INT's alt - relative_alt, or the EKF
    origin of GPS_GLOBAL_ORIGIN with LOCAL_POSITION_NED), or the start-up mean."""

    source: Literal["config", "home", "startup"] = "home"
    value: Optional[float] = None  # Pa for the baro reference, m for the GNSS reference
    startup_window_s: float = Field(2.0, gt=0)
    # With source "home": how long (vehicle time after the first sample that
    # needs the reference) to wait for the autopilot's home (any of the three
    # above) before falling back to the start-up mean. Bounds the memory held
    # while waiting.
    home_wait_s: float = Field(30.0, gt=0)
    # A baro reference taken while the autopilot's height above its reference
    # point is within this is taken at the datum (on the ground at home): it
    # ties the baro to the datum within its noise (ReferenceSet.at_datum,
    # filter.p0.baro_bias_at_datum_m2). Beyond it (a log or link joined in
    # flight) the tie is only as good as the autopilot's height then.
    at_datum_max_m: float = Field(1.0, ge=0)

    @model_validator(mode="after")
    def _value_with_config(self) -> "ReferenceConfig":
        if self.source == "config" and self.value is None:
            raise ValueError("source 'config' needs a value")
        return self


class IngestConfig(_Section):
    baro_instance: Literal[1, 2, 3] = 1
    gnss_altitude: Literal["msl", "ellipsoid"] = "msl"
    min_fix_type: int = Field(3, ge=2, le=8)
    baro_reference: ReferenceConfig = ReferenceConfig()
    gnss_reference: ReferenceConfig = ReferenceConfig()
    link_timeout_s: float = Field(2.0, gt=0)
    rangefinder_stuck_s: float = Field(2.0, gt=0)  # identical readings for this long while moving = stuck
    imu_source: Literal["auto", "HIGHRES_IMU", "SCALED_IMU", "SCALED_IMU2", "SCALED_IMU3", "RAW_IMU"] = "auto"
    # Downward rangefinder and autopilot-height sources: one of each, like the IMU.
    range_source: Literal["auto", "DISTANCE_SENSOR", "RANGEFINDER"] = "auto"
    autopilot_source: Literal["auto", "GLOBAL_POSITION_INT", "LOCAL_POSITION_NED"] = "auto"
    # "auto" choices are made this long (vehicle time) after the first candidate.
    source_select_s: float = Field(1.0, gt=0)
    # IMU samples wait this long (vehicle time) for a bracketing attitude, then
    # take the nearest one; with no attitude within attitude_max_age_s they are refused.
    attitude_wait_s: float = Field(0.1, gt=0)
    attitude_max_age_s: float = Field(1.0, gt=0)
    # Limits for RANGEFINDER, which carries none (DISTANCE_SENSOR has its own).
    rangefinder_min_m: float = Field(0.05, ge=0)
    rangefinder_max_m: float = Field(100.0, gt=0)
    rangefinder_max_tilt_deg: float = Field(60.0, gt=0, lt=90)
    # Stuck = rangefinder_stuck_s of identical readings while the baro height moves this much.
    rangefinder_stuck_min_move_m: float = Field(1.0, gt=0)
    # ArduPilot sends its downward rangefinder twice (DISTANCE_SENSOR and
    # RANGEFINDER): a reading of the chosen one that differs from the other's,
    # received within range_cross_max_age_s, by more than range_cross_tol_m or
    # range_cross_tol_frac of the larger is refused ("disagrees").
    range_cross_max_age_s: float = Field(0.3, gt=0)
    range_cross_tol_m: float = Field(0.1, ge=0)
    range_cross_tol_frac: float = Field(0.05, ge=0)
    # A stream is in a gap when silent longer than max(gap_min_s, gap_factor * its usual interval).
    gap_min_s: float = Field(0.5, gt=0)
    gap_factor: float = Field(5.0, gt=1)
    # Vehicle time jumping back more than this (confirmed by the next messages) is a reboot:
    # the reboot rule, mavnav.ingest.clock.is_reboot (the fault injector uses it too).
    reboot_jump_s: float = Field(REBOOT_JUMP_S, gt=0)
    # Messages held (per link) until the first autopilot heartbeat selects the vehicle.
    preselect_max_frames: int = Field(20000, ge=0)
    # The reference point follows the autopilot's home when it moves (a new home set at
    # arming): heights are then reported above the new home; the filters keep the point
    # their references were fixed at (samples.ReferenceMoved). A change of the home's
    # altitude up to home_move_min_m is no move (HOME_POSITION is in mm; a re-sent home).
    follow_home: bool = True
    home_move_min_m: float = Field(0.05, gt=0)


# ---------------------------------------------------------------- monitor


class AdaptiveFeatures(_Section):
    """Each addition of the adaptive monitor over the paper, switchable."""

    covariance_thresholds: bool = True  # thresholds k*sqrt(P_a + P_b - 2 P_ab), else the paper's fixed metres
    innovation_gating: bool = True  # chi-square gate on each GNSS/rangefinder sample before it enters
    window_test: bool = True  # the aux innovations' sequential test, a two-sided CUSUM (slow drifts, small steps)
    isolation_2of3: bool = True  # blame baro+INS when GNSS and rangefinder agree against it
    validated_feedback: bool = True  # feed back only channels validated over a window, rate-limited
    readmission: bool = True  # readmit an excluded source after it has been consistent for readmit_s
    inverse_variance: bool = True  # fuse by inverse (co)variance, else the arithmetic mean
    kink_isolation: bool = True  # an aux-baro drift pinned on whichever bent against the INS (monitor/kink.py)
    doppler_check: bool = True  # GNSS altitude against its own Doppler velocity (monitor/doppler.py)
    ins_doppler_check: bool = True  # the INS's velocity change against the Doppler's (monitor/doppler.py)
    baro_doppler_check: bool = True  # the baro's change against the Doppler's integral (alerts only)
    gnss_drift_check: bool = True  # without a Doppler: the GNSS's drift rate against the baro (monitor/drift.py)
    # the protection level also bounds a fault of each source in the output that the
    # channel comparison cannot see (solution separation, monitor/protection.py)
    separation_protection: bool = True
    # ...and a subset without the baro is no better than the sensors left in it
    # that report a 1-sigma beyond monitor.alert_limit_m: their channels take the
    # baro's changes, so they cannot vouch for it at that limit (monitor/protection.py)
    own_sensor_floor: bool = True
    # the baro's level against each aux channel on its measured scale (never
    # below the model's threshold): a baro whose error exceeds the model's u
    # (sigma_bb) is not a fault
    level_scale: bool = True
    # the baro's slow error u measured at run time from a short baro/INS second
    # difference (monitor/baronoise.py): the level tests (and the baro's
    # readmission against them) take it in place of the model's sigma_bb where
    # the flight's baro is significantly noisier
    baro_u_measured: bool = True
    # the sudden-jump rule against the measured scatter of an aux stream's
    # sample-to-sample innovation changes, not the innovations' own sigma
    # (consecutive innovations share the channel's error: their change is small)
    sudden_jump_measured: bool = True
    sudden_jump_persist: bool = True
    # near the ground the flight started on, a baro departure below a test's
    # threshold is ground effect, not a suspicion (monitor.ground_effect_height_m)
    ground_effect_watch: bool = True
    # and for baro_doppler_window_s after it, above the ground, the baro/Doppler
    # test's suspicion alone: its window's start still holds the baro read in
    # the wash (flug_log_28's caution 3.4 % -> 0, rrc_hover_good_1's 3.9 ->
    # 2.6 %). Every baro suspicion waived so long let a fast baro fault just
    # after a take-off waive its own and its level be given back at
    # readmission (tests/test_monitor_baro_rebase.py; BENCHMARKS.md session 25).
    ground_effect_window: bool = True


class MonitorConfig(_Section):
    mode: Literal["adaptive", "paper"] = "adaptive"
    # Paper mode (and adaptive with covariance_thresholds off): fixed thresholds
    # on |H_ch - H_baro| (MODEL.md section 5).
    delta_gnss_m: float = Field(10.0, gt=0)
    delta_ra_m: float = Field(5.0, gt=0)
    time_to_alarm_s: float = Field(1.0, gt=0)
    # The input rates the time-to-alarm needs besides the aux sensors': an IMU
    # below min_imu_rate_hz is too sparse to integrate between baro samples (its
    # snapshots miss the motion), a baro below min_baro_rate_hz too slow to show
    # a step in time. Below either, monitoring is degraded (unavailable); below
    # the IMU's, the INS is no witness either: its tests say nothing (no
    # caution, no alarm, no clearing); below the baro's, a baro the tests
    # isolate is held out of the output in caution, not alarmed (slow inputs
    # never make a sensor faulty).
    min_imu_rate_hz: float = Field(10.0, gt=0)
    min_baro_rate_hz: float = Field(5.0, gt=0)
    # A stream counts as at a required rate down to this fraction of it (a
    # nominal 10 Hz stream jitters): the rate check, the audit's verdict on the
    # inputs and the slow-baro rule read the same number.
    rate_tolerance_frac: float = Field(0.9, gt=0, le=1)
    features: AdaptiveFeatures = AdaptiveFeatures()
    # Probability of a false alarm of one channel-comparison test (two-sided normal).
    false_alarm_prob: float = Field(1e-5, gt=0, lt=0.5)
    # Probability of rejecting a good GNSS/rangefinder sample (chi-square, 1 dof).
    gate_prob: float = Field(1e-4, gt=0, lt=0.5)
    # The sliding window the rejected samples are counted in (caution_rejections, alarm_rejections).
    window_s: float = Field(5.0, gt=0)
    # A single baro sample this improbable (chi-square, 1 dof) is a baro jump:
    # an alarm at once, so the level is far stricter than gate_prob.
    baro_jump_prob: float = Field(1e-8, gt=0, lt=0.5)
    # After a (re)start the filters converge for this long: gates still
    # protect the states, but no window statistic or comparison raises alarms.
    warmup_s: float = Field(5.0, ge=0)
    # A start whose own baro rows are gated this many in a row within warmup_s
    # took its speed from a glitch (the first difference sets it: a baro that
    # settles after boot read as 22 m/s, and every later row was gated): the
    # filters start again on the latest sample, at most start_restarts_max
    # times (an erratic baro is then the tests' business).
    start_restart_rows: int = Field(3, ge=1)
    start_restarts_max: int = Field(3, ge=0)
    # A source in caution returns to nominal only after this long clean.
    clear_s: float = Field(1.0, ge=0)
    # Rejected samples in the window before a source is in caution / alarm.
    caution_rejections: int = Field(2, ge=1)
    alarm_rejections: int = Field(4, ge=1)
    # A disagreement must persist this long before it is an alarm (caution before).
    persist_s: float = Field(0.2, ge=0)
    # An excluded source is readmitted after this long consistent.
    readmit_s: float = Field(5.0, gt=0)
    # A sequential test whose failure the monitor cannot pin on one source is
    # held this long, then restarts; the hold is released once the restarted
    # test has run as long again without failing. 0: never restarted (the hold
    # lasts while the test fails). Measured on the real flights (BENCHMARKS.md,
    # session 6): 5 s cuts the time in caution on healthy flights from 11-12 %
    # to 6-7 %, and raises the injected runs with hazardous output from 37 to
    # 53 of 765 (a slow ramp the channels absorb is released into the output);
    # integrity first, so off by default.
    hold_restart_s: float = Field(0.0, ge=0)
    # Feedback into the baro+INS channel from channels validated this long.
    validate_s: float = Field(3.0, ge=0)
    feedback_interval_s: float = Field(1.0, gt=0)
    feedback_inflation: float = Field(4.0, ge=1.0)
    # A source with no accepted sample for this long is unavailable (cf. EKF3).
    stale_gnss_s: float = Field(2.0, gt=0)
    stale_rng_s: float = Field(0.5, gt=0)
    stale_baro_s: float = Field(0.5, gt=0)
    # A channel whose height sigma exceeds this takes no part in comparisons.
    max_channel_sigma_m: float = Field(5.0, gt=0)
    # Integrity: vertical protection level k * sigma against the alert limit.
    alert_limit_m: float = Field(4.0, gt=0)
    integrity_risk: float = Field(1e-5, gt=0, lt=0.5)
    # The prior probability that a height source is faulty while in the output
    # (features.separation_protection): a fault of source i goes undetected
    # with probability integrity_risk / fault_prior_prob, which sets the
    # missed-detection quantile of its protection level (1e-3: 3.29 sigma).
    fault_prior_prob: float = Field(1e-2, gt=0, le=1)
    # Height sensors (baro, GNSS, rangefinder) that must be in use beside the
    # INS for integrity: with the baro alone, a slow baro error passes every
    # test against the INS (0.5 m/s ramps on the real baro-only flights were
    # seen only when they ended, 20 s later), so the monitoring is degraded,
    # not nominal (adaptive mode).
    min_height_sensors: int = Field(2, ge=1)
    profile: str = "small_drone"
    # --- fault hypotheses (mavnav/monitor/hypotheses.py) ---
    # Sequential test (two-sided CUSUM) of each sensor's normalised innovations:
    # drift k (sigma), a clip on each residual (sigma), and the false-alert
    # budget per hour that sets its threshold at the stream's own rate.
    cusum_k_sigma: float = Field(0.5, gt=0)
    cusum_clip_sigma: float = Field(5.0, gt=0)
    cusum_false_alerts_per_h: float = Field(0.01, gt=0)
    # Its fast arms, tuned to steps of 2 k sigma: a 3 sigma step in about three
    # samples instead of six (the 1 s time-to-alarm at 5 Hz); 0 turns them off.
    # Their own false-alert budget, beside the slow arms'.
    cusum_fast_k_sigma: float = Field(1.5, ge=0)
    cusum_fast_false_alerts_per_h: float = Field(0.01, gt=0)
    # Baro against the INS: the baro's change over this window against the
    # INS-propagated change of the baro+INS channel (ramps, steps, accelerometer faults).
    ins_window_s: float = Field(2.0, gt=0)
    # A test past this fraction of its threshold is a suspect (caution); below
    # clear_frac it rules out the sources it would have seen.
    suspect_frac: float = Field(0.8, gt=0, le=1)
    clear_frac: float = Field(0.5, gt=0, le=1)
    # An aux channel that went this long without its sensor is re-initialised
    # from the baro+INS channel when the sensor returns (it never gates out its
    # own sensor after coasting, and a rangefinder back in range finds its ground).
    coast_reinit_s: float = Field(3.0, gt=0)
    # An aux channel that ran with a baro the monitor then excludes carries what
    # that baro's fault pulled into its vertical speed before the fault was
    # caught (a 0.5 m/s ramp, several seconds): its speed is made this much
    # less certain (1 sigma, m/s), so that it settles on its own sensor
    # (else its innovations drift as the pulled speed runs out, and the
    # healthy sensor is blamed next).
    baro_exclusion_vel_sigma_mps: float = Field(1.0, ge=0)
    # Ramp onset against the INS (mavnav/monitor/kink.py): over this window, a
    # kink of aux - baro with |z| past kink_min_z (its onset) is pinned on the
    # aux sensor or the baro by whose height bent against the INS, when their
    # squared kink z differ by more than chi2_gate(kink_isolation_prob). The kink
    # scatter is measured every kink_learn_interval_s at an onset a third of the
    # window back while the monitor is clear (time constant kink_learn_tau_s),
    # and the test acts only after kink_min_learned such measurements.
    kink_window_s: float = Field(30.0, gt=0)
    kink_min_pre_s: float = Field(5.0, gt=0)
    kink_min_post_s: float = Field(1.0, gt=0)
    kink_min_z: float = Field(0.0, ge=0)
    kink_isolation_prob: float = Field(1e-5, gt=0, lt=0.5)
    kink_learn_interval_s: float = Field(1.0, gt=0)
    kink_learn_tau_s: float = Field(120.0, gt=0)
    kink_min_learned: int = Field(30, ge=2)
    # A kink fit needs this many samples and its series to span this fraction
    # of the window (a series restarted by a baro gap is not read at once).
    kink_min_samples: int = Field(8, ge=4)
    kink_min_fill_frac: float = Field(0.7, gt=0, le=1)
    # GNSS altitude against the receiver's Doppler vertical velocity
    # (mavnav/monitor/doppler.py): the altitude's change over doppler_window_s
    # less the velocity's integral, against k(false_alarm_prob) times
    # doppler_sigma_m times its measured scale (it only widens, up to
    # residual_scale_max). doppler_sigma_m: the 99th percentile of |e| over 5 s
    # on the healthy modern receivers here is 0.3-1.1 m (docs/integrity.md).
    # Samples further apart than doppler_max_gap_s restart the integral.
    doppler_window_s: float = Field(5.0, gt=0)
    doppler_sigma_m: float = Field(0.35, gt=0)
    doppler_max_gap_s: float = Field(1.5, gt=0)
    # The INS's velocity change against the Doppler's over the same window,
    # against k(false_alarm_prob) times sqrt(ins_doppler_sigma_mps^2 + the
    # measured IMU scatter over the window) times its measured scale.
    # ins_doppler_sigma_mps: the 99th percentile of |e_v| over 5 s on the
    # modern IMUs here is 0.3-1.0 m/s (docs/integrity.md).
    ins_doppler_sigma_mps: float = Field(0.25, gt=0)
    # The baro's change against the Doppler's integral over the same window
    # (features.baro_doppler_check): the 99th percentile of |e| over 5 s on the
    # modern receivers here is 0.5-1.8 m.
    baro_doppler_sigma_m: float = Field(0.4, gt=0)
    # Its own window: the baro's difference from the Doppler's integral hardly
    # grows from 5 to 10 s on the real flights (99th percentile 0.8-2.8 m and
    # 0.6-2.9 m on the modern receivers, bench/doppler_stats.py) while a ramp's
    # doubles, so a 0.5 m/s baro ramp clears the threshold sooner over 10 s.
    baro_doppler_window_s: float = Field(10.0, gt=0)
    # With a span, the baro at that window's start is the median of its
    # samples over the span centred there, at its end the median of its last
    # baro_doppler_end_samples within it, each carried to the GNSS sample's
    # time along the Doppler integral (monitor/barolevel.py); 0: the latest
    # sample alone at both ends. Off by default: at 1 s it takes cautions off
    # the noisy 5 Hz baros (caution gnss/baro 2.1/3.5 -> 1.6/3.2 % on the real
    # flights) but on erle_copter_10-11-2014_104, whose GNSS runs 3-6 m from
    # its baro, the GNSS then stays in the output and pulls it (RMS against
    # the autopilot 0.43 -> 1.56 m), and four injected faults there end with
    # the output 3.5 m from the unfaulted flight's while nominal for up to
    # 20 s (BENCHMARKS.md, session 22).
    baro_doppler_level_span_s: float = Field(0.0, ge=0)
    baro_doppler_end_samples: int = Field(3, ge=1)
    # Within this height of the ground the flight started on (the fused height
    # above its datum), the baro reads the propellers' downwash: on the ground
    # before take-off, at take-off and at touchdown the real flights' baros
    # depart by 0.5-2 m from the GNSS Doppler and the INS for a second or two
    # (autopilots waive it too: ArduPilot's EK3_GND_EFF_DZ, PX4's
    # EKF2_GND_EFF_DZ within EKF2_GND_MAX_HGT). There a test implicating the
    # baro that is past its suspect level but not its threshold is no
    # suspicion (features.ground_effect_watch); failures still count.
    ground_effect_height_m: float = Field(1.0, ge=0)
    # The baro at each end of that window is the mean of its samples over
    # this span (each carried by the Doppler velocity to the GNSS sample's time).
    baro_doppler_smooth_s: float = Field(1.0, ge=0)
    # The baro's height change is good to a fraction of the distance moved:
    # its scale (the air temperature against the standard atmosphere's, a few
    # per cent), the static-pressure error of the climb or descent and ground
    # effect at take-off and landing. Added to baro_doppler_sigma_m in
    # quadrature, times the Doppler's integral over the span read. Measured
    # (bench/doppler_stats.py, its scale column): the baro's change falls
    # short of the Doppler's by 8 % of the distance moved (RMS over 24 real
    # flights; -19 % to +11 %, and not steady within a flight). Off by
    # default: 0.1 takes the climb cautions off five modern flights but a
    # 0.5 m/s baro ramp in a descent then alarms up to 4 s later, and 8
    # injected baro ramps put the output 3 m off while nominal (session 23);
    # 0.05 lets a ramp from touchdown through while the window holds the
    # landing (session 9). A ramp in a steady descent and a scale error are
    # the same reading: this test cannot tell them apart by itself.
    baro_doppler_scale_frac: float = Field(0.0, ge=0, le=1)
    # Beside the whole window, the test also reads its latest span of this
    # length and keeps the reading larger against its own error (0: off), so
    # a window that still holds a landing does not hide a ramp begun after
    # it. With 4 s and the distance term at 0.1 it adds cautions on the 2 Hz
    # receivers (flug_log_70, flug_log_91) and an alarm on aut_quad_v6xrt.
    baro_doppler_recent_span_s: float = Field(0.0, ge=0)
    # The GNSS altitude's drift against the baro where the receiver reports no
    # Doppler velocity (features.gnss_drift_check, monitor/drift.py): the slope
    # of GNSS - baro fitted over gnss_drift_window_s, against k(false_alarm_prob)
    # times the fit's white-noise error, gnss_drift_sigma_mps and the baro's
    # slow error u through the fit (the sensor model's, sensors.baro.sigma_bb_m
    # at gamma_bb_per_s) in quadrature, times its measured scale
    # (it only widens). The slope over 10 s stays within 0.02-0.23 m/s on the
    # healthy flights here (99.9th percentile; bench/drift_stats.py), 0.23
    # being 4.4 sigma at 0.05 m/s; of that the shipped baro model's u (0.2 m at
    # 0.5 /s) is 0.031 m/s, so gnss_drift_sigma_mps, the receiver's own drift
    # rate, is the rest: sqrt(0.05^2 - 0.031^2).
    gnss_drift_window_s: float = Field(10.0, gt=0)
    gnss_drift_sigma_mps: float = Field(0.0395, gt=0)
    # Rangefinder envelope: readings refused below its minimum (or above its
    # maximum) while the other sources put the vehicle more than margin inside
    # its range, for most of a window, are a rangefinder failure.
    range_envelope_window_s: float = Field(2.0, gt=0)
    range_envelope_margin_m: float = Field(1.5, ge=0)
    range_envelope_min_refused: int = Field(5, ge=1)
    range_envelope_frac: float = Field(0.2, gt=0, le=1)
    # A baro sample past the jump gate is a step only if the baro stays there:
    # after this long and this many samples it must still sit this fraction of
    # the jump away from the clean samples before it, carried by the INS (a
    # spike of prop wash returns).
    baro_jump_confirm_s: float = Field(0.5, ge=0)
    baro_jump_confirm_samples: int = Field(2, ge=1)
    baro_jump_stay_frac: float = Field(0.5, gt=0, le=1)
    # ... and it must have settled there: a jump whose level still moves from one
    # sample to the next (past the gate at the row's noise) waits up to this much
    # longer, and is no step if it never settles.
    baro_jump_settle_s: float = Field(1.0, ge=0)
    # A step is given back at a readmission with no aux channel only if it was
    # measured from a level no test had doubted for this long before its jump
    # opened (the baro/Doppler window): a baro that was in caution while another
    # source took the blame had its ramp followed, and its snapping back is no step.
    baro_step_trust_s: float = Field(10.0, ge=0)
    # The clean samples a jump is measured from: the median of this many, each
    # carried to the jump's time by the INS (one noisy sample is no reference).
    baro_jump_reference_samples: int = Field(5, ge=1)
    # The raw GNSS - rangefinder check (monitor/rawcheck.py) averages this long.
    raw_check_window_s: float = Field(1.0, gt=0)
    # The operator's word that the ground under the rangefinder lies at the
    # reference elevation (a flight over a known flat field: the paper's
    # premise). A start on the ground at the datum shows it; a flight joined
    # in the air does not, and without this word the ground is what one
    # window of the raw check places, no better than the GNSS, so the
    # rangefinder's absolute height carries that uncertainty
    # (monitor/rawcheck.py) and such a flight is mostly unavailable against a
    # 4 m alert limit. With it, a flight joined in the air keeps the ground at
    # the reference as known, and a raw GNSS - rangefinder difference there is
    # a fault, as at the datum.
    ground_at_reference: bool = False
    # The measured scale of each test's normalised residuals (monitor/scale.py):
    # forgetting time, and how far the data may sharpen (min) or dull (max) a
    # test against the filters' own covariance.
    residual_scale_tau_s: float = Field(60.0, gt=0)
    # The Doppler window tests' scales forget slower: consecutive windows
    # overlap, so 60 s holds only 6-12 independent values, and a 0.5 m/s baro
    # ramp below the freeze level had taught the baro/Doppler test to widen
    # from 1.3 to 2.6 times in 10 s (rrc_hover_cut20mm_1, 11 s to alert).
    window_scale_tau_s: float = Field(300.0, gt=0)
    # The baro level tests' scale (features.level_scale) learns from the second
    # difference of their statistic over this lag: longer than the statistic's
    # correlation time (2-4 s with a 1 s baro noise, as the channel follows part
    # of it), short against the time it learns over...
    level_scale_lag_s: float = Field(4.0, gt=0)
    # ...and forgets over this long: a ramp cannot teach a second difference (the
    # kink at its onset teaches it a few per cent before the test freezes), so
    # it may learn a baro noisier than the model within the first minute. It
    # starts from the model: the level tests are what sees a slow baro ramp
    # without a Doppler, and a start at the noisiest real baro's ratio (2) took
    # simulated 0.5 m/s baro ramps from 5.8 to 7.6-7.9 s (past 3 m of error).
    level_scale_tau_s: float = Field(20.0, gt=0)
    # It may narrow a measured u (features.baro_u_measured) this far: an aux
    # channel follows part of the baro's slow error into its dH, so the level
    # moves less than u (a simulated 0.5 m baro read 0.53 m, and the level's own
    # scale 0.35-0.42 m). Its twenty seconds hold five independent readings at
    # the 4 s lag: free to narrow to the model, it did (a baro ramp then alarmed
    # as early as before, but the hover's cautions rose from 0.6 to 5.2 %).
    level_scale_min: float = Field(0.75, gt=0, le=1)
    # The baro/INS test's scale (its statistic a second difference too) starts
    # from this variance ratio against the model until the flight shows its own
    # baro: the noisiest real baro here reads 2.05 on it (aut_quad_v6xrt.ulg;
    # 0.44-2.05 over the real flights). It sees steps, not ramps: 5 m baro steps
    # on the 5 Hz PX4 baros are alerted in 0.55-0.8 s instead of 0.25-0.54 s.
    ins_scale_prior_m2: float = Field(2.0, ge=1)
    # The baro's u measured at run time (features.baro_u_measured,
    # monitor/baronoise.py): a baro/INS second difference over two windows of
    # about baro_u_window_s / 2..1 (at a 1 s lag the simulator's 0.5 m, 1 s baro
    # reads ten times the model's variance: seen in seconds, where the 4 s test's
    # scale needs a minute), the median of |e| / sigma over the last
    # baro_u_memory_s (at least baro_u_min_samples, readings past
    # baro_u_outlier_sigma left out: a step's onset); a variance ratio within
    # baro_u_significance_sigma of its own scatter above 1 is the model's.
    # (Every median scale is recomputed at most once per median_scale_update_s.)
    baro_u_window_s: float = Field(1.0, gt=0)
    baro_u_memory_s: float = Field(60.0, gt=0)
    baro_u_min_samples: int = Field(50, ge=5)
    baro_u_outlier_sigma: float = Field(6.0, gt=0)
    baro_u_significance_sigma: float = Field(1.0, ge=0)
    median_scale_update_s: float = Field(1.0, gt=0)
    # The sudden-jump rule (features.sudden_jump_measured): an aux innovation
    # jumping from one sample to the next by sqrt(gate) times the measured
    # scatter of those jumps (the median over sudden_jump_memory_s, at least
    # sudden_jump_min_samples) while the baro row is clean: neither the baro nor
    # the INS can make it. The measured scatter sharpens the rule at most
    # sudden_jump_sharpen_max times against the innovations' own sigmas: a
    # stream that repeats its values (the SITL receivers' 5 Hz altitude read at
    # 10 Hz) has a median jump near 0, and each update would read as a jump.
    sudden_jump_memory_s: float = Field(30.0, gt=0)
    sudden_jump_min_samples: int = Field(20, ge=5)
    sudden_jump_sharpen_max: float = Field(4.0, ge=1)
    # A clean jump that holds (features.sudden_jump_persist): past the jump
    # threshold from the previous sample and from where the stream stood (the
    # median of its last sudden_jump_level_samples innovations), and every later
    # sample still at least sudden_jump_persist_frac of the jump from there,
    # for sudden_jump_persist_s and sudden_jump_persist_samples samples, is a
    # step of the sensor (monitor/jumps.py).
    sudden_jump_persist_s: float = Field(0.2, gt=0)
    sudden_jump_persist_frac: float = Field(0.5, gt=0, le=1)
    sudden_jump_persist_samples: int = Field(2, ge=1)
    # where the stream stood before a jump: the median of its last this many innovations
    sudden_jump_level_samples: int = Field(5, ge=3)
    residual_scale_min: float = Field(0.5, gt=0, le=1)
    residual_scale_max: float = Field(5.0, ge=1)
    # the largest lag-one correlation the aux innovation scale believes (its
    # long-run factor sqrt((1 + phi) / (1 - phi)) is 6.2 at 0.95)
    residual_scale_max_phi: float = Field(0.95, ge=0, lt=1)
    # A pass rules out faults larger than its statistic plus this many of its
    # sigmas; a failure's size is its innovation averaged over this time.
    clear_margin_sigma: float = Field(2.0, ge=0)
    fail_size_tau_s: float = Field(1.0, gt=0)


# ---------------------------------------------------------------- MAVLink output


class RequestRatesConfig(_Section):
    """The input rates ``run --emit input --allow-commands`` asks the autopilot for
    (MAV_CMD_SET_MESSAGE_INTERVAL). Each stream is asked for the larger of its
    rate here and ``tta_margin`` times the rate the time-to-alarm needs (the
    monitor's rule: ``mavnav.audit.required_rates_hz``), so a stricter
    time-to-alarm asks for more."""

    tta_margin: float = Field(1.25, ge=1.0)
    imu_rate_hz: float = Field(50.0, gt=0, le=1000)  # the INS drives every filter epoch
    attitude_rate_hz: float = Field(50.0, gt=0, le=1000)  # rotates each IMU sample to the vertical
    baro_rate_hz: float = Field(20.0, gt=0, le=1000)  # epochs fall on baro samples
    # GNSS: not above what receivers give (a faster stream repeats fixes, refused as duplicates)
    gnss_rate_hz: float = Field(5.0, gt=0, le=1000)
    range_rate_hz: float = Field(20.0, gt=0, le=1000)


class EmitSection(_Section):
    """What ``--emit`` sends, and as whom (mavnav/cli/emit_options.py). The
    keys below ``command_attempts`` each have a command-line flag, which wins
    when given. Only the flags turn the output on: ``--emit CONNECTION``
    (nothing is transmitted without it) and ``--allow-commands`` (no command
    is sent without it)."""

    request: RequestRatesConfig = RequestRatesConfig()
    # a COMMAND_ACK is awaited this long (wall clock: the vehicle answers in real
    # time) before the command is sent again, command_attempts times in all
    command_timeout_s: float = Field(1.0, gt=0)
    command_attempts: int = Field(3, ge=1)
    sysid: int = Field(1, ge=1, le=255)  # --emit-sysid: the system id mavnav sends as
    compid: int = Field(191, ge=1, le=255)  # --emit-compid (1, the autopilot's, is refused)
    altitude_rate_hz: float = Field(5.0, gt=0, le=100)  # --altitude-rate, on vehicle time
    statustext_interval_s: float = Field(1.0, ge=0, allow_inf_nan=False)  # --statustext-interval
    debug_values: bool = False  # --emit-debug: residuals and test statistics as NAMED_VALUE_FLOAT
    fusable: bool = False  # --emit-fusable: ODOMETRY for an autopilot to fuse
    # --request-rate NAME:HZ (with --allow-commands): instead of the rates `request` derives
    message_rates: tuple[str, ...] = ()
    signing_key: Optional[str] = None  # --signing-key FILE
    signing_link_id: int = Field(0, ge=0, le=255)  # --signing-link-id

    @field_validator("compid")
    @classmethod
    def _not_the_autopilot(cls, v: int) -> int:
        if v == 1:
            raise ValueError("1 is the autopilot's component id; mavnav never impersonates it (use e.g. 191)")
        return v


# ---------------------------------------------------------------- the viewer


class ViewerSection(_Section):
    """The Rerun viewer of run, replay and audit (mavnav/cli/viewer_options.py).
    Each key has a command-line flag, which wins when given."""

    viewer: Literal["spawn", "web", "none"] = "none"  # --viewer
    connect: Optional[str] = None  # --connect URL: also stream to a running viewer
    rrd: Optional[str] = None  # --rrd FILE: also save the recording
    web_port: int = Field(9090, ge=0, le=65535)  # --web-port (0: any free port)
    grpc_port: int = Field(9876, ge=0, le=65535)  # --grpc-port (0: any free port)
    bind: str = "127.0.0.1"  # --viewer-bind
    window_s: float = Field(30.0, gt=0)  # --viewer-window: live runs, seconds of vehicle time shown
    hold: bool = True  # --viewer-hold/--no-viewer-hold: the web viewer serves on after the run


class Config(_Section):
    sensors: SensorsConfig = SensorsConfig()
    filter: FilterConfig = FilterConfig()
    ingest: IngestConfig = IngestConfig()
    monitor: MonitorConfig = MonitorConfig()
    emit: EmitSection = EmitSection()
    viewer: ViewerSection = ViewerSection()


#: The keys that only say how results are shown or sent, not what they are
#: (left out of the fleet cache's key: ``mavnav.fleet.task.config_json``).
OUTPUT_ONLY_KEYS = {
    "viewer": True,
    "emit": {"sysid", "compid", "altitude_rate_hz", "statustext_interval_s", "debug_values", "fusable",
             "message_rates", "signing_key", "signing_link_id"},
}


def with_overrides(section: _Section, update: dict, origin: str) -> _Section:
    """``section`` with the keys in ``update`` replaced (the command-line flags
    given), validated as the configuration is: a bad value is a one-line
    ConfigError naming the key."""
    if not update:
        return section
    try:
        return type(section).model_validate({**section.model_dump(), **update})
    except ValidationError as exc:
        raise validation_error(exc, origin) from None


# ---------------------------------------------------------------- loading


def _loc(parts) -> str:
    out = ""
    for p in parts:
        if p == "__root__":
            continue
        out += f"[{p}]" if isinstance(p, int) else ("." if out else "") + str(p)
    return out


def describe_error(err: dict, loc: str | None = None) -> str:
    """One pydantic error as users read it: ``unknown key 'a.b'``, ``missing
    key 'a'``, or ``a.b: <message>``."""
    loc = _loc(err.get("loc", ())) if loc is None else loc
    kind = err.get("type", "")
    if kind == "extra_forbidden":
        return f"unknown key '{loc}'"
    if kind == "missing":
        return f"missing key '{loc}'"
    msg = str(err.get("msg", "invalid"))
    if msg.startswith("Value error, "):
        msg = msg[len("Value error, "):]
    return f"{loc}: {msg}" if loc else msg


def validation_error(exc: ValidationError, origin: str, describe=describe_error) -> ConfigError:
    """A ValidationError as a one-line ConfigError naming the first problem."""
    errors = exc.errors()
    more = f" (and {len(errors) - 1} more)" if len(errors) > 1 else ""
    return ConfigError(f"{origin}: {describe(errors[0])}{more}")


def read_yaml(path: Union[str, Path], kind: str = "configuration") -> tuple[object, str]:
    """``(data, origin)`` of a YAML file; any failure is a one-line ConfigError."""
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ConfigError(f"{p}: no such {kind} file") from None
    except OSError as exc:
        raise ConfigError(f"{p}: cannot read ({exc.strerror})") from None
    try:
        return yaml.safe_load(text), str(p)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" at line {mark.line + 1}" if mark is not None else ""
        raise ConfigError(f"{p}: not valid YAML{where}") from None


def config_from_dict(data: Union[dict, None], origin: str = "<dict>") -> Config:
    """Validate a plain mapping into a :class:`Config` (one-line errors)."""
    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise ConfigError(f"{origin}: top level must be a mapping, not {type(data).__name__}")
    try:
        return Config.model_validate(data)
    except ValidationError as exc:
        raise validation_error(exc, origin) from None


def load_config(path: Union[str, Path, None]) -> Config:
    """Load a YAML configuration file; ``None`` gives the defaults."""
    if path is None:
        return Config()
    data, origin = read_yaml(path, "configuration")
    return config_from_dict(data, origin=origin)
