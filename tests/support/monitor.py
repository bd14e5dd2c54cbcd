"""Run the monitor on synthetic flights (paper's sensor models, exact truth)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from mavnav.config import config_from_dict
from mavnav.pipeline import run
from mavnav.sinks.base import Sink
from tests.support.synthetic import Schedule, TrueSensors, paper_flight

from tests.support.faults import apply_fault

T0_US = 1_000_000
SENSORS = TrueSensors(sigma_a_mps2=0.1, alpha_a_per_s=1.0, sigma_bb_m=0.5, gamma_bb_per_s=1.0, sigma_z_m=1.0,
                      sigma_rng_m=0.1, baro_bias_m=2.0, acc_bias_mps2=0.02)
SCHEDULE = Schedule(duration_s=80.0, imu_dt_s=0.01, baro_every=2, gnss_every=20, rng_every=5)
SOURCE_OF = {"gnss": "gnss", "rangefinder": "rangefinder", "baro": "baro_ins"}


def hover(t):
    """Gentle vertical motion around a hover: zero-mean velocity."""
    return 0.3 * np.cos(2 * np.pi * t / 10.0)


def cfg_for(mode="adaptive", **features):
    s = SENSORS
    return config_from_dict({
        "sensors": {"ins": {"sigma_a_mps2": s.sigma_a_mps2, "alpha_a_per_s": s.alpha_a_per_s},
                    "baro": {"sigma_bb_m": s.sigma_bb_m, "gamma_bb_per_s": s.gamma_bb_per_s},
                    # the synthetic GNSS error is white: no Gauss-Markov state
                    "gnss": {"sigma_z_m": s.sigma_z_m, "use_v_acc": False, "gm_sigma_m": 0.0},
                    "rangefinder": {"sigma_m": s.sigma_rng_m, "scale_sigma_frac": 0.0}},
        # the paper's premise: the ground under the rangefinder is at the reference
        # (these flights start in the air, at 10 m, over it)
        "monitor": {"mode": mode, "features": features, "ground_at_reference": True},
    })


class Collect(Sink):
    name = "collect"

    def __init__(self):
        self.reports = []

    def epoch(self, r):
        self.reports.append(r)


@dataclass
class Outcome:
    alarms: list  # AlarmEvent
    t_s: np.ndarray  # seconds since the flight's start
    err_m: np.ndarray  # fused - truth
    first_alarm: dict = field(default_factory=dict)  # source -> first alarm time (s since start) after onset

    def rms(self, t0, t1):
        m = (self.t_s >= t0) & (self.t_s < t1) & np.isfinite(self.err_m)
        return float(np.sqrt(np.mean(self.err_m[m] ** 2)))

    def first_alarm_after(self, t0):
        out = {}
        for ev in self.alarms:
            t = (ev.t_us - T0_US) * 1e-6
            if ev.state == "alarm" and t >= t0 and ev.source not in out:
                out[ev.source] = t
        return out

    def alarms_between(self, t0, t1):
        return [ev for ev in self.alarms if ev.state == "alarm" and t0 <= (ev.t_us - T0_US) * 1e-6 < t1]


def fly(fault=None, seed=1, mode="adaptive", **features) -> Outcome:
    """``fault``: (source, kind, onset_s, duration_s, magnitude) or None."""
    flight = paper_flight(seed=seed, sensors=SENSORS, schedule=SCHEDULE, accel=hover, h0_m=10.0, t0_us=T0_US)
    samples = flight.samples
    if fault is not None:
        src, kind, onset, dur, mag = fault
        samples = apply_fault(samples, src, kind, onset, dur, mag, t0_us=T0_US)
    c = Collect()
    summary = run(samples, cfg_for(mode, **features), [c])
    t_us = np.array([r.t_us for r in c.reports])
    truth = np.array([flight.truth_at(int(t))[0] for t in t_us])
    fused = np.array([r.height_fused_m for r in c.reports])
    return Outcome(alarms=summary.alarms, t_s=(t_us - T0_US) * 1e-6, err_m=fused - truth)


def nan_to(v, default=math.inf):
    return default if v is None else v
