"""Analytic truth trajectories: height, vertical speed and acceleration, attitude.

The vertical motion is a chain of *cosine blends*: over a piece of length
``tau`` the vertical speed goes from ``v0`` to ``v1`` as
``v = v0 + dv (1 - cos(pi s)) / 2`` (``s = (t - t0) / tau``), so
``a = dv pi / (2 tau) sin(pi s)`` and
``h = h0 + v0 (t - t0) + dv / 2 ((t - t0) - tau / pi sin(pi s))``.
A constant-speed piece is a blend with ``dv = 0``. Height, speed and
acceleration are exact and mutually consistent at any time, so the IMU's
specific force integrates to the true height.

Horizontal motion: on a landing approach the ground speed follows the glide
slope, ``v_h = -v_up / tan(slope)`` along the heading; otherwise a slow
sinusoidal wander. Attitude: sinusoidal roll/pitch excursions about a pitch
offset, faded to level on the ground (below 1 m), and a yaw oscillation about
the heading. Attitude is chosen independently of the accelerations (this is
not a flight-dynamics model); the IMU output ``f_b = R_bn (a_n - g_n)`` is
exactly consistent with both. Times are simulation seconds from the start.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import List, Tuple

import numpy as np

from .scenario import (
    AttitudeMotion,
    HoverTrajectory,
    LandingTrajectory,
    Scenario,
    StepsTrajectory,
)


@dataclass(frozen=True)
class Kinematics:
    """Truth at an array of simulation times (all arrays of the same shape)."""

    t_s: np.ndarray
    height_m: np.ndarray  # above the reference point, up
    vel_up_mps: np.ndarray
    acc_up_mps2: np.ndarray
    pos_n_m: np.ndarray
    pos_e_m: np.ndarray
    vel_n_mps: np.ndarray
    vel_e_mps: np.ndarray
    acc_n_mps2: np.ndarray
    acc_e_mps2: np.ndarray
    roll_rad: np.ndarray
    pitch_rad: np.ndarray
    yaw_rad: np.ndarray
    roll_rate_radps: np.ndarray  # Euler angle rates
    pitch_rate_radps: np.ndarray
    yaw_rate_radps: np.ndarray


class VerticalProfile:
    """Piecewise cosine-blend vertical motion (see the module docstring)."""

    def __init__(self, start_height_m: float) -> None:
        self._t0: List[float] = []
        self._tau: List[float] = []
        self._v0: List[float] = []
        self._v1: List[float] = []
        self._h0: List[float] = []
        self.t_end = 0.0
        self.h_end = float(start_height_m)
        self.v_end = 0.0

    def _piece(self, tau: float, v1: float) -> None:
        if tau <= 0:
            return
        v0 = self.v_end
        self._t0.append(self.t_end)
        self._tau.append(tau)
        self._v0.append(v0)
        self._v1.append(v1)
        self._h0.append(self.h_end)
        self.h_end += v0 * tau + (v1 - v0) / 2 * tau
        self.t_end += tau
        self.v_end = v1

    def hold(self, seconds: float) -> "VerticalProfile":
        self._piece(seconds, self.v_end)
        return self

    def move_to(self, height_m: float, speed_mps: float, blend_in_s: float, blend_out_s: float) -> "VerticalProfile":
        """From rest, reach ``height_m`` and stop there: blend up, cruise, blend down."""
        dh = height_m - self.h_end
        if abs(dh) < 1e-9:
            return self
        v = math.copysign(speed_mps, dh)
        blend_dist = abs(v) * (blend_in_s + blend_out_s) / 2
        if blend_dist > abs(dh):  # too short to reach full speed
            v = dh / ((blend_in_s + blend_out_s) / 2)
            cruise = 0.0
        else:
            cruise = (abs(dh) - blend_dist) / abs(v)
        self._piece(blend_in_s, v)
        self._piece(cruise, v)
        self._piece(blend_out_s, 0.0)
        self.h_end = float(height_m)  # remove rounding drift
        return self

    def evaluate(self, t: np.ndarray) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
        t = np.asarray(t, dtype=float)
        if not self._t0:
            z = np.zeros_like(t)
            return z + self.h_end, z, z
        t0 = np.asarray(self._t0)
        idx = np.clip(np.searchsorted(t0, t, side="right") - 1, 0, len(t0) - 1)
        pt0 = t0[idx]
        tau = np.asarray(self._tau)[idx]
        v0 = np.asarray(self._v0)[idx]
        dv = np.asarray(self._v1)[idx] - v0
        h0 = np.asarray(self._h0)[idx]
        dt = t - pt0
        before = dt < 0  # before the first piece: hold the start
        after = dt > tau  # after this piece (only the last one): constant v1
        s = np.clip(dt / tau, 0.0, 1.0)
        sin_ps = np.sin(np.pi * s)
        dt_in = np.clip(dt, 0.0, tau)
        h = h0 + v0 * dt_in + dv / 2 * (dt_in - tau / np.pi * sin_ps)
        v = v0 + dv * (1 - np.cos(np.pi * s)) / 2
        a = dv * np.pi / (2 * tau) * sin_ps
        extra = np.where(after, dt - tau, 0.0)
        h = h + v * extra
        a = np.where(after | before, 0.0, a)
        return h, v, a


def _smoothstep(x: np.ndarray) -> np.ndarray:
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3 - 2 * x)


def _attitude(att: AttitudeMotion, heading_deg: float, t: np.ndarray, height: np.ndarray):
    d = math.radians
    w = _smoothstep(height / 1.0)  # level on the ground
    roll = w * d(att.roll_amplitude_deg) * np.sin(2 * np.pi * t / att.roll_period_s + 0.4)
    pitch = w * (d(att.pitch_offset_deg) + d(att.pitch_amplitude_deg) * np.sin(2 * np.pi * t / att.pitch_period_s + 1.1))
    yaw = d(heading_deg) + d(att.yaw_amplitude_deg) * np.sin(2 * np.pi * t / att.yaw_period_s)
    yaw = (yaw + np.pi) % (2 * np.pi) - np.pi
    return roll, pitch, yaw


class TruthTrajectory:
    """Evaluate the scenario's truth at any simulation times."""

    def __init__(self, scenario: Scenario) -> None:
        self.scenario = scenario
        tr = scenario.trajectory
        self._tr = tr
        if isinstance(tr, LandingTrajectory):
            prof = VerticalProfile(tr.start_height_m).hold(tr.hold_s)
            prof.move_to(0.0, tr.descent_speed_mps, tr.blend_s, tr.flare_s)
        elif isinstance(tr, HoverTrajectory):
            if tr.takeoff:
                prof = VerticalProfile(0.0).hold(tr.ground_s)
                prof.move_to(tr.height_m, tr.climb_speed_mps, tr.blend_s, tr.blend_s)
            else:
                prof = VerticalProfile(tr.height_m)
            self._hover_start = prof.t_end
        elif isinstance(tr, StepsTrajectory):
            prof = VerticalProfile(tr.start_height_m)
            for h in tr.heights_m:
                prof.move_to(h, tr.vertical_speed_mps, tr.blend_s, tr.blend_s)
                prof.hold(tr.hold_s)
        else:  # pragma: no cover - the schema admits no other kind
            raise TypeError(type(tr))
        self.profile = prof

    def _vertical(self, t: np.ndarray):
        h, v, a = self.profile.evaluate(t)
        tr = self._tr
        if isinstance(tr, HoverTrajectory) and tr.wander_m > 0:
            # Smoothly switched-on oscillation after reaching the hover: h += A g(t) sin(w t')
            ts = np.maximum(t - self._hover_start, 0.0)
            om = 2 * np.pi / tr.wander_period_s
            ramp_T = tr.wander_period_s
            # g rises 0 -> 1 over one period with a cosine (C1), sin starts at 0
            x = np.clip(ts / ramp_T, 0, 1)
            g = (1 - np.cos(np.pi * x)) / 2
            gd = np.where(x < 1, np.pi / (2 * ramp_T) * np.sin(np.pi * x), 0.0)
            gdd = np.where(x < 1, (np.pi / ramp_T) ** 2 / 2 * np.cos(np.pi * x), 0.0)
            s, c = np.sin(om * ts), np.cos(om * ts)
            A = tr.wander_m
            h = h + A * g * s
            v = v + A * (gd * s + g * om * c)
            a = a + A * (gdd * s + 2 * gd * om * c - g * om * om * s)
        return h, v, a

    def _horizontal(self, t: np.ndarray, v_up: np.ndarray, a_up: np.ndarray, h: np.ndarray):
        tr = self._tr
        psi = math.radians(tr.heading_deg)
        if isinstance(tr, LandingTrajectory):
            k = 1.0 / math.tan(math.radians(tr.glide_slope_deg))
            s = -h * k  # along-track position, 0 at touchdown
            vs, as_ = -v_up * k, -a_up * k
            return (s * math.cos(psi), s * math.sin(psi), vs * math.cos(psi), vs * math.sin(psi),
                    as_ * math.cos(psi), as_ * math.sin(psi))
        A = tr.horizontal_wander_m
        w1, w2 = 2 * np.pi / 23.0, 2 * np.pi / 31.0
        n, e = A * np.sin(w1 * t), A * np.sin(w2 * t + 0.7)
        vn, ve = A * w1 * np.cos(w1 * t), A * w2 * np.cos(w2 * t + 0.7)
        an, ae = -A * w1 * w1 * np.sin(w1 * t), -A * w2 * w2 * np.sin(w2 * t + 0.7)
        return n, e, vn, ve, an, ae

    def sample(self, t) -> Kinematics:
        t = np.atleast_1d(np.asarray(t, dtype=float))
        h, v, a = self._vertical(t)
        h = np.maximum(h, 0.0)  # never below the ground (rounding at touchdown)
        n, e, vn, ve, an, ae = self._horizontal(t, v, a, h)
        tr = self._tr
        roll, pitch, yaw = _attitude(tr.attitude, tr.heading_deg, t, h)
        # Euler rates by a central difference of the closed form (only for gyros)
        dt = 1e-4
        hp = np.maximum(self._vertical(t + dt)[0], 0.0)
        hm = np.maximum(self._vertical(t - dt)[0], 0.0)
        rp, pp, yp = _attitude(tr.attitude, tr.heading_deg, t + dt, hp)
        rm, pm, ym = _attitude(tr.attitude, tr.heading_deg, t - dt, hm)
        dyaw = (yp - ym + np.pi) % (2 * np.pi) - np.pi
        return Kinematics(
            t_s=t,
            height_m=h,
            vel_up_mps=v,
            acc_up_mps2=a,
            pos_n_m=n,
            pos_e_m=e,
            vel_n_mps=vn,
            vel_e_mps=ve,
            acc_n_mps2=an,
            acc_e_mps2=ae,
            roll_rad=roll,
            pitch_rad=pitch,
            yaw_rad=yaw,
            roll_rate_radps=(rp - rm) / (2 * dt),
            pitch_rate_radps=(pp - pm) / (2 * dt),
            yaw_rate_radps=dyaw / (2 * dt),
        )


def ground_height_m(terrain, t_scenario_s) -> np.ndarray:
    """Ground height above the reference under the vehicle at scenario times (0 off every patch)."""
    t = np.atleast_1d(np.asarray(t_scenario_s, dtype=float))
    g = np.zeros(t.shape)
    for p in terrain:
        g = np.where((t >= p.from_s) & (t < p.to_s), p.height_m, g)
    return g
