"""Scalar references for the simulator's vectorised rotations (:mod:`mavnav.sim.sensors`):
the body->NED matrix and the body rates from Z-Y-X Euler angles, written out
element by element (MAVLink's ATTITUDE convention, as :mod:`mavnav.frames`)."""

from __future__ import annotations

import math
from typing import Tuple


def mat_nb_from_euler(
    roll: float, pitch: float, yaw: float
) -> Tuple[Tuple[float, float, float], Tuple[float, float, float], Tuple[float, float, float]]:
    """Full body->NED rotation ``mat_nb`` (rows N, E, D) from Z-Y-X Euler angles.

    Its third row equals :func:`mavnav.frames.down_row_from_euler`; ``mat_bn`` is its transpose.
    """
    sr, cr = math.sin(roll), math.cos(roll)
    sp, cp = math.sin(pitch), math.cos(pitch)
    sy, cy = math.sin(yaw), math.cos(yaw)
    return (
        (cp * cy, sr * sp * cy - cr * sy, cr * sp * cy + sr * sy),
        (cp * sy, sr * sp * sy + cr * cy, cr * sp * sy - sr * cy),
        (-sp, sr * cp, cr * cp),
    )


def body_rates_from_euler_rates(
    roll: float, pitch: float, roll_rate: float, pitch_rate: float, yaw_rate: float
) -> Tuple[float, float, float]:
    """Body angular rates (p, q, r) from Z-Y-X Euler angle rates."""
    sr, cr = math.sin(roll), math.cos(roll)
    sp, cp = math.sin(pitch), math.cos(pitch)
    return (
        roll_rate - yaw_rate * sp,
        pitch_rate * cr + yaw_rate * sr * cp,
        -pitch_rate * sr + yaw_rate * cr * cp,
    )
