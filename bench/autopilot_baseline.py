"""What the autopilots do: a small, honest model of EKF3 / EKF2 height logic.

The scorecard's third contender (``bench/integrity.py``). It is driven by the
same normalised mavnav samples (:class:`mavnav.ingest.TlogSource`) as the
monitor, so all contenders see identical data, and it reports in mavnav's
own types (:class:`mavnav.report.AlarmEvent`, sources ``gnss``,
``rangefinder``, ``baro_ins``), so the same metrics score it.

The model (docs MAVLINK.md, "What the autopilots do"):

* **One filter** fusing every height source, as PX4 EKF2 does: state
  ``[H, Vz, dH, da]`` (height above the reference, vertical speed, baro bias,
  vertical accelerometer bias), the IMU's vertical specific force as the
  control input (``a = f_up - g - da``), white acceleration noise of
  spectral density ``2 sigma_a^2 / alpha_a`` and random walks on both
  biases. Baro measures ``H + dH``; GNSS and the rangefinder measure ``H``
  (flat ground at the reference, as MODEL.md assumes), so the baro bias is
  estimated against GNSS and the rangefinder ("baro bias estimated against
  GNSS"). The barometer's coloured noise is treated as white, as both EKFs
  do. Noise figures are those of mavnav's ``SensorsConfig`` (the same
  knowledge the monitor gets): baro ``sigma_bb_m``, GNSS the receiver's
  ``v_acc`` (floored) or ``sigma_z_m``, rangefinder
  ``sqrt(sigma_m^2 + (scale_sigma_frac H)^2)``.
* **Innovation gates** of 5 sigma on every sample (``EK3_HGT_I_GATE``,
  ``EKF2_BARO_GATE``/``EKF2_GPS_P_GATE``/``EKF2_RNG_GATE`` = 5): a sample
  with ``|r| > 5 sqrt(S)`` is not fused.
* **Fallback when a source goes stale**: a source with no sample for its
  stale time (rangefinder 0.5 s, GNSS 2 s, baro 0.5 s as in EKF3) is
  ``unavailable`` and simply no longer fused; the others carry the height.
  It is ``nominal`` again with its next sample that passes the gate.
  Staleness is a timeout, not an alarm: EKF3 switches source when a sensor
  goes *stale*, not when it is *inconsistent*.
* **"Alarm"** only when a source's samples have failed the gate continuously
  for ``fail_s`` (default 5 s: EKF3's height-innovation timeout, EKF2's
  "rangefinder declared faulty after 5 s of inconsistency"): the source
  goes to ``alarm`` (EKF3 reports a height-source failure), stays out of
  the fusion and is ``nominal`` again after ``recover_s`` of samples that
  pass the gate. A single sample that passes resets the failure timer (the
  EKFs time from the last *passed* sample).

What it leaves out, deliberately (it is a reference, not a reimplementation):
the horizontal states and the magnetometer, IMU lanes and lane switching,
EKF2's separate bias estimators for non-reference height sources and its
terrain state, EKF3's reset of the height to the active source after a
timeout, range-finder "conditional" use by speed/height, and the GCS-side
failsafe thresholds on test ratios. The contender therefore cannot be
worse than the autopilots for the reasons it omits, and it alarms by the
same rule they report a height-source failure.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Iterable, List, Optional

import numpy as np

from mavnav.config import SensorsConfig
from mavnav.constants import G0_MPS2
from mavnav.report import AlarmEvent
from mavnav.samples import BaroHeight, GnssHeight, RangeHeight, Reboot, SpecificForceUp

SOURCES = ("gnss", "rangefinder", "baro_ins")


@dataclass(frozen=True)
class BaselineConfig:
    gate_sigma: float = 5.0  # innovation gate, in sigma of the innovation
    stale_rng_s: float = 0.5  # EKF3: rangefinder stale after 500 ms
    stale_gnss_s: float = 2.0  # EKF3: GPS stale after 2 s
    stale_baro_s: float = 0.5
    fail_s: float = 5.0  # gate failing this long = height-source failure (EKF3 / EKF2)
    recover_s: float = 1.0  # passing this long after a failure = healthy again
    gravity_mps2: float = G0_MPS2
    gnss_v_acc_floor_m: float = 0.3
    use_v_acc: bool = True
    # initial variances (as mavnav's filter.p0)
    p0_height_m2: float = 300.0
    p0_vel_m2ps2: float = 20.0
    p0_baro_bias_m2: float = 625.0
    p0_acc_bias_m2ps4: float = 0.01
    max_dt_s: float = 0.25  # a longer prediction step is split (no IMU for a while)


@dataclass
class _SourceState:
    state: str = "nominal"
    last_seen_us: Optional[int] = None
    last_pass_us: Optional[int] = None
    fail_since_us: Optional[int] = None  # first rejected sample of the current run of rejections
    pass_since_us: Optional[int] = None  # first passing sample after a failure


@dataclass
class BaselineResult:
    t_s: np.ndarray  # vehicle time of each output (after each baro sample)
    height_m: np.ndarray
    sigma_m: np.ndarray
    alarms: List[AlarmEvent] = field(default_factory=list)
    fused: dict = field(default_factory=dict)  # samples fused per source
    rejected: dict = field(default_factory=dict)  # samples rejected by the gate per source
    states: List[tuple] = field(default_factory=list)  # (t_s, {source: state}) at each output


class AutopilotBaseline:
    """One height filter with 5-sigma gates, stale fallback and timeout "alarms"."""

    def __init__(self, sensors: SensorsConfig, cfg: BaselineConfig = BaselineConfig()):
        self.s = sensors
        self.c = cfg
        self.acc_psd = 2.0 * sensors.ins.sigma_a_mps2 ** 2 / sensors.ins.alpha_a_per_s
        self.baro_rw2 = sensors.baro.bias_rw_m_per_sqrt_s ** 2
        self.acc_rw2 = sensors.ins.bias_rw_mps2_per_sqrt_s ** 2
        self.alarms: List[AlarmEvent] = []
        self.out_t: List[float] = []
        self.out_h: List[float] = []
        self.out_sig: List[float] = []
        self.out_states: List[tuple] = []
        self.fused = {s: 0 for s in SOURCES}
        self.rejected = {s: 0 for s in SOURCES}
        self._reset(0)

    # ------------------------------------------------------------ filter

    def _reset(self, boot: int) -> None:
        self.boot = boot
        self.x: Optional[np.ndarray] = None
        self.P: Optional[np.ndarray] = None
        self.t_us: Optional[int] = None
        self.f_up: Optional[float] = None
        self.src = {s: _SourceState() for s in SOURCES}

    def _predict(self, t_us: int) -> None:
        if self.t_us is None or t_us <= self.t_us:
            return
        dt_total = (t_us - self.t_us) * 1e-6
        a_in = 0.0 if self.f_up is None else self.f_up - self.c.gravity_mps2
        n = max(1, int(math.ceil(dt_total / self.c.max_dt_s)))
        dt = dt_total / n
        F = np.array([[1.0, dt, 0.0, -0.5 * dt * dt], [0.0, 1.0, 0.0, -dt], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]])
        q = self.acc_psd
        Q = np.zeros((4, 4))
        Q[0, 0] = q * dt ** 3 / 3.0
        Q[0, 1] = Q[1, 0] = q * dt ** 2 / 2.0
        Q[1, 1] = q * dt
        Q[2, 2] = self.baro_rw2 * dt
        Q[3, 3] = self.acc_rw2 * dt
        for _ in range(n):
            x = self.x
            self.x = F @ x + np.array([0.5 * dt * dt * a_in, dt * a_in, 0.0, 0.0])
            self.P = F @ self.P @ F.T + Q
        self.t_us = t_us

    def _innovation(self, row: int, z: float, var: float):
        # row 0: H = [1 0 1 0] (baro); row 1: H = [1 0 0 0] (GNSS, rangefinder)
        x, P = self.x, self.P
        if row == 0:
            pred = x[0] + x[2]
            HP = P[0] + P[2]
            hph = HP[0] + HP[2]
        else:
            pred = x[0]
            HP = P[0]
            hph = HP[0]
        S = hph + var
        return z - pred, S, HP

    def _update(self, r: float, S: float, HP: np.ndarray) -> None:
        K = HP / S
        self.x = self.x + K * r
        self.P = self.P - np.outer(K, HP)
        self.P = 0.5 * (self.P + self.P.T)

    # ------------------------------------------------------------ source health

    def _set(self, name: str, state: str, t_us: int, reason: str) -> None:
        st = self.src[name]
        if st.state != state:
            self.alarms.append(AlarmEvent(t_us=t_us, boot=self.boot, source=name, state=state,  # type: ignore[arg-type]
                                          previous=st.state, reason=reason))  # type: ignore[arg-type]
            st.state = state

    def _check_stale(self, t_us: int) -> None:
        for name, limit in (("gnss", self.c.stale_gnss_s), ("rangefinder", self.c.stale_rng_s),
                            ("baro_ins", self.c.stale_baro_s)):
            st = self.src[name]
            if st.state == "alarm":
                continue  # a failed source stays failed until it passes again
            if st.last_seen_us is None or (t_us - st.last_seen_us) * 1e-6 > limit:
                if st.state != "unavailable":
                    self._set(name, "unavailable", t_us, f"stale: no sample for {limit:g} s")

    def _measure(self, name: str, row: int, z: float, var: float, t_us: int) -> None:
        st = self.src[name]
        st.last_seen_us = t_us
        r, S, HP = self._innovation(row, z, var)
        passed = r * r <= (self.c.gate_sigma ** 2) * S
        if passed:
            st.fail_since_us = None
            st.last_pass_us = t_us
            if st.state == "alarm":
                if st.pass_since_us is None:
                    st.pass_since_us = t_us
                if (t_us - st.pass_since_us) * 1e-6 >= self.c.recover_s:
                    self._set(name, "nominal", t_us, f"innovations inside the gate for {self.c.recover_s:g} s")
                    st.pass_since_us = None
                else:
                    return  # still out of the fusion
            elif st.state == "unavailable":
                self._set(name, "nominal", t_us, "fresh sample inside the gate")
            self._update(r, S, HP)
            self.fused[name] += 1
        else:
            self.rejected[name] += 1
            st.pass_since_us = None
            if st.fail_since_us is None:
                st.fail_since_us = t_us
            if st.state != "alarm" and (t_us - st.fail_since_us) * 1e-6 >= self.c.fail_s:
                self._set(name, "alarm", t_us,
                          f"innovation {r:+.2f} m > {self.c.gate_sigma:g} sigma for {self.c.fail_s:g} s")

    # ------------------------------------------------------------ samples

    def _init(self, s: BaroHeight) -> None:
        c = self.c
        self.x = np.array([s.height_ref_m, 0.0, 0.0, 0.0])
        self.P = np.diag([c.p0_height_m2, c.p0_vel_m2ps2, c.p0_baro_bias_m2, c.p0_acc_bias_m2ps4])
        self.t_us = s.t_us
        r, S, HP = self._innovation(0, s.height_ref_m, self.s.baro.sigma_bb_m ** 2)
        self._update(r, S, HP)

    def push(self, s) -> None:
        if isinstance(s, Reboot):
            self._reset(s.boot)
            return
        if isinstance(s, SpecificForceUp):
            if self.x is not None:
                self._predict(s.t_us)
            self.f_up = s.f_up_mps2
            return
        if not isinstance(s, (BaroHeight, GnssHeight, RangeHeight)):
            return
        if self.x is None:
            if isinstance(s, BaroHeight):
                self._init(s)
                self.src["baro_ins"].last_seen_us = s.t_us
                self._record(s.t_us)
            return
        self._predict(s.t_us)
        t = s.t_us
        if isinstance(s, BaroHeight):
            self._measure("baro_ins", 0, s.height_ref_m, self.s.baro.sigma_bb_m ** 2, t)
        elif isinstance(s, GnssHeight):
            g = self.s.gnss
            if self.c.use_v_acc and g.use_v_acc and s.sigma_m is not None and s.sigma_m > 0:
                sig = max(s.sigma_m, self.c.gnss_v_acc_floor_m)
            else:
                sig = g.sigma_z_m
            self._measure("gnss", 1, s.height_ref_m, sig * sig, t)
        else:
            rf = self.s.rangefinder
            h = max(self.x[0], 0.0)
            var = rf.sigma_m ** 2 + (rf.scale_sigma_frac * h) ** 2
            self._measure("rangefinder", 1, s.height_agl_m, var, t)
        self._check_stale(t)
        if isinstance(s, BaroHeight):
            self._record(t)

    def _record(self, t_us: int) -> None:
        self.out_t.append(t_us * 1e-6)
        self.out_h.append(float(self.x[0]))
        self.out_sig.append(float(math.sqrt(max(self.P[0, 0], 0.0))))
        self.out_states.append((t_us * 1e-6, {k: v.state for k, v in self.src.items()}))

    def result(self) -> BaselineResult:
        return BaselineResult(np.asarray(self.out_t), np.asarray(self.out_h), np.asarray(self.out_sig),
                              list(self.alarms), dict(self.fused), dict(self.rejected), list(self.out_states))


def run_baseline(samples: Iterable, sensors: SensorsConfig, cfg: BaselineConfig = BaselineConfig()) -> BaselineResult:
    """Fold ``samples`` (mavnav samples and events, in order) through the baseline."""
    b = AutopilotBaseline(sensors, cfg)
    for s in samples:
        b.push(s)
    return b.result()
