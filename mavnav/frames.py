"""Attitude and frames: body FRD, navigation NED, heights up.

``mat_nb`` rotates body-frame vectors into NED (``v_n = mat_nb @ v_b``).
Euler angles are MAVLink's ATTITUDE convention (roll, pitch, yaw; Z-Y-X);
quaternions are MAVLink's ATTITUDE_QUATERNION ``q1..q4`` = (w, x, y, z),
body to NED. Pure functions, floats and tuples: these run once per IMU
sample, where numpy's call overhead would dominate.
"""

from __future__ import annotations

import math
from typing import Tuple

Quat = Tuple[float, float, float, float]


def quat_from_euler(roll: float, pitch: float, yaw: float) -> Quat:
    cr, sr = math.cos(roll / 2), math.sin(roll / 2)
    cp, sp = math.cos(pitch / 2), math.sin(pitch / 2)
    cy, sy = math.cos(yaw / 2), math.sin(yaw / 2)
    return (
        cr * cp * cy + sr * sp * sy,
        sr * cp * cy - cr * sp * sy,
        cr * sp * cy + sr * cp * sy,
        cr * cp * sy - sr * sp * cy,
    )


def down_row_from_euler(roll: float, pitch: float) -> Tuple[float, float, float]:
    """Third row of ``mat_nb`` (the NED 'down' component of a body vector).

    Yaw does not enter: ``(mat_nb v_b)_down = -sin(p) x + sin(r)cos(p) y + cos(r)cos(p) z``.
    """
    sp, cp = math.sin(pitch), math.cos(pitch)
    sr, cr = math.sin(roll), math.cos(roll)
    return (-sp, sr * cp, cr * cp)


def down_row_from_quat(q: Quat) -> Tuple[float, float, float]:
    """Third row of ``mat_nb`` from a unit quaternion (w, x, y, z)."""
    w, x, y, z = q
    n = math.sqrt(w * w + x * x + y * y + z * z)
    if not n > 0.0:
        raise ValueError("zero quaternion")
    w, x, y, z = w / n, x / n, y / n, z / n
    return (2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y))


def f_up_from_body(f_b: Tuple[float, float, float], down_row: Tuple[float, float, float]) -> float:
    """Vertical specific force, positive up: ``-(mat_nb f_b)_down`` (~ +9.81 at rest)."""
    return -(down_row[0] * f_b[0] + down_row[1] * f_b[1] + down_row[2] * f_b[2])


def cos_tilt(down_row: Tuple[float, float, float]) -> float:
    """Cosine of the angle between the body z axis (down) and the vertical."""
    return down_row[2]


def slerp(q0: Quat, q1: Quat, frac: float) -> Quat:
    """Spherical interpolation between two unit quaternions, ``frac`` in [0, 1]."""
    dot = sum(a * b for a, b in zip(q0, q1))
    if dot < 0.0:
        q1 = tuple(-c for c in q1)  # type: ignore[assignment]
        dot = -dot
    if dot > 0.9995:
        out = tuple(a + frac * (b - a) for a, b in zip(q0, q1))
    else:
        theta = math.acos(dot)
        s0 = math.sin((1 - frac) * theta) / math.sin(theta)
        s1 = math.sin(frac * theta) / math.sin(theta)
        out = tuple(s0 * a + s1 * b for a, b in zip(q0, q1))
    n = math.sqrt(sum(c * c for c in out))
    return tuple(c / n for c in out)  # type: ignore[return-value]
