"""Seeded sample streams from the paper's sensor models, with truth.

This produces :mod:`mavnav.samples` objects directly (no MAVLink), for the
estimator's consistency tests and ``bench/estimator.py`` (test data, not
shipped in the package); :mod:`mavnav.sim` is the simulator that writes real
MAVLink telemetry. Truth follows the filter's own discrete model on the IMU
grid (zero-order hold of the true acceleration), so normalised-error
statistics have exact expectations when every IMU sample is also a baro
epoch, and close ones otherwise.

Sensors (``../shared/docs/MODEL.md`` section 2): IMU ``f_up = a + g + da + q n`` with
``q = sigma_a sqrt(2 / (alpha_a tau))`` per IMU interval ``tau``; baro
``H + dH + u`` with ``u`` first-order Gauss-Markov, exactly discretised
between baro samples; GNSS ``H + sigma_z n``; rangefinder ``H + sigma_r n``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable, Optional, Sequence

import numpy as np

from mavnav.constants import G0_MPS2
from mavnav.samples import BaroHeight, GnssHeight, RangeHeight, SpecificForceUp



@dataclass(frozen=True)
class TrueSensors:
    sigma_a_mps2: float = 0.1
    alpha_a_per_s: float = 1.0
    acc_bias_mps2: float = 0.05
    sigma_bb_m: float = 1.0
    gamma_bb_per_s: float = 10.0
    baro_bias_m: float = 3.0
    sigma_z_m: float = 2.0
    gnss_v_acc_m: Optional[float] = None  # reported v_acc (None: not reported)
    sigma_rng_m: float = 0.1


@dataclass(frozen=True)
class Schedule:
    """When each sensor samples, on the IMU grid."""

    duration_s: float = 60.0
    imu_dt_s: float = 0.02
    irregular: float = 0.0  # IMU interval jitter as a fraction of imu_dt_s (uniform +-)
    baro_every: int = 1  # one baro sample every N IMU samples
    gnss_every: int = 5
    rng_every: int = 2
    # (start_s, end_s) windows with no samples of the kind
    gaps: dict = field(default_factory=dict)  # {"baro": [(t0, t1)], "gnss": [...], "rng": [...]}


@dataclass
class Flight:
    samples: list
    t_us: np.ndarray  # IMU grid
    height_ref_m: np.ndarray
    vel_up_mps: np.ndarray
    baro_bias_m: float
    acc_bias_mps2: float

    def truth_at(self, t_us: int) -> tuple[float, float]:
        i = int(np.searchsorted(self.t_us, t_us))
        if i >= len(self.t_us) or self.t_us[i] != t_us:
            raise KeyError(t_us)
        return float(self.height_ref_m[i]), float(self.vel_up_mps[i])


def gentle_climbs(t: np.ndarray) -> np.ndarray:
    """True vertical acceleration: smooth climbs and descents (m/s^2)."""
    return 0.6 * np.sin(2 * np.pi * t / 20.0) + 0.3 * np.sin(2 * np.pi * t / 7.0 + 1.0)


def _in_gap(t: float, windows: Sequence[tuple[float, float]]) -> bool:
    return any(a <= t < b for a, b in windows)


def paper_flight(
    seed: int,
    sensors: TrueSensors = TrueSensors(),
    schedule: Schedule = Schedule(),
    accel: Callable[[np.ndarray], np.ndarray] = gentle_climbs,
    h0_m: float = 0.0,
    v0_mps: float = 0.0,
    t0_us: int = 1_000_000,
) -> Flight:
    rng = np.random.default_rng(seed)
    n = int(round(schedule.duration_s / schedule.imu_dt_s)) + 1
    dts = np.full(n - 1, schedule.imu_dt_s)
    if schedule.irregular > 0:
        dts = dts * (1.0 + schedule.irregular * rng.uniform(-1, 1, n - 1))
    dt_us = np.maximum(np.round(dts * 1e6).astype(np.int64), 1)
    t_us = t0_us + np.concatenate([[0], np.cumsum(dt_us)])
    tau = np.diff(t_us) * 1e-6
    t_s = (t_us - t0_us) * 1e-6
    a = accel(t_s)
    H = np.empty(n)
    V = np.empty(n)
    H[0], V[0] = h0_m, v0_mps
    for i in range(n - 1):
        H[i + 1] = H[i] + V[i] * tau[i] + 0.5 * a[i] * tau[i] ** 2
        V[i + 1] = V[i] + a[i] * tau[i]
    s = sensors
    # IMU noise over each hold interval (the last sample gets the nominal interval)
    tau_f = np.concatenate([tau, [schedule.imu_dt_s]])
    q = s.sigma_a_mps2 * np.sqrt(2.0 / (s.alpha_a_per_s * tau_f))
    f_up = a + G0_MPS2 + s.acc_bias_mps2 + q * rng.standard_normal(n)
    gaps = schedule.gaps
    samples: list = []
    u = s.sigma_bb_m * rng.standard_normal()
    last_baro_t: Optional[int] = None
    for i in range(n):
        ti = int(t_us[i])
        tsec = float(t_s[i])
        recv = 1.7e9 + tsec
        samples.append(SpecificForceUp(ti, recv, 0, float(f_up[i]), "synthetic"))
        if i % schedule.gnss_every == 0 and not _in_gap(tsec, gaps.get("gnss", ())):
            z = float(H[i] + s.sigma_z_m * rng.standard_normal())
            samples.append(GnssHeight(ti, recv, 0, z, z, s.gnss_v_acc_m, 3, 12))
        if i % schedule.rng_every == 0 and not _in_gap(tsec, gaps.get("rng", ())):
            z = float(H[i] + s.sigma_rng_m * rng.standard_normal())
            samples.append(RangeHeight(ti, recv, 0, z, z, "synthetic"))
        # baro last, so the aux samples of this instant are used at its epoch (age 0)
        if i % schedule.baro_every == 0 and not _in_gap(tsec, gaps.get("baro", ())):
            if last_baro_t is not None:
                T = (ti - last_baro_t) * 1e-6
                phi = math.exp(-s.gamma_bb_per_s * T)
                u = phi * u + s.sigma_bb_m * math.sqrt(1 - phi * phi) * rng.standard_normal()
            last_baro_t = ti
            samples.append(BaroHeight(ti, recv, 0, float(H[i] + s.baro_bias_m + u), 0.0, 1))
    return Flight(samples, t_us, H, V, s.baro_bias_m, s.acc_bias_mps2)
