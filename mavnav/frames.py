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
    """Spherical interpolation between two unit quaternions, ``frac`` in [0, 1].

    Written out component by component (one call per IMU sample); the sums
    run left to right as :func:`slerp_reference`'s, so the floats are the same."""
    a0, a1, a2, a3 = q0
    b0, b1, b2, b3 = q1
    dot = a0 * b0 + a1 * b1 + a2 * b2 + a3 * b3
    if dot < 0.0:
        b0, b1, b2, b3 = -b0, -b1, -b2, -b3
        dot = -dot
    if dot > 0.9995:
        c0, c1, c2, c3 = a0 + frac * (b0 - a0), a1 + frac * (b1 - a1), a2 + frac * (b2 - a2), a3 + frac * (b3 - a3)
    else:
        theta = math.acos(dot)
        s0 = math.sin((1 - frac) * theta) / math.sin(theta)
        s1 = math.sin(frac * theta) / math.sin(theta)
        c0, c1, c2, c3 = s0 * a0 + s1 * b0, s0 * a1 + s1 * b1, s0 * a2 + s1 * b2, s0 * a3 + s1 * b3
    n = math.sqrt(c0 * c0 + c1 * c1 + c2 * c2 + c3 * c3)
    return (c0 / n, c1 / n, c2 / n, c3 / n)


def slerp_reference(q0: Quat, q1: Quat, frac: float) -> Quat:
    """The readable form of :func:`slerp` (``tests/test_frames_slerp.py``: the same floats)."""
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
