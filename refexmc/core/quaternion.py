"""Quaternion algebra, scalar last ``[x, y, z, w]`` (000 eq. 28).

Products are Hamilton products, the convention of ``scipy.spatial.transform.Rotation``. An
attitude quaternion ``q`` rotates body-frame vectors into the inertial frame; its kinematics are
``q_dot = 0.5 * q (x) [omega_body, 0]``, which is 000 eq. 28 with Xi(q) = [w I + [v x]; -v^T].
All functions write into caller-owned ``out`` arrays; ``out`` may alias an input only where noted.
"""

import math

from refexmc._jit import jit_noalloc
from refexmc.core import elementary


@jit_noalloc
def multiply(p, q, out):
    """Hamilton product ``out = p (x) q``; ``out`` must not alias ``p`` or ``q``."""
    px, py, pz, pw = p[0], p[1], p[2], p[3]
    qx, qy, qz, qw = q[0], q[1], q[2], q[3]
    out[0] = pw * qx + px * qw + py * qz - pz * qy
    out[1] = pw * qy - px * qz + py * qw + pz * qx
    out[2] = pw * qz + px * qy - py * qx + pz * qw
    out[3] = pw * qw - px * qx - py * qy - pz * qz


@jit_noalloc
def conj_multiply(p, q, out):
    """``out = conj(p) (x) q``: the rotation from frame ``p`` to frame ``q`` in ``p``'s axes."""
    px, py, pz, pw = -p[0], -p[1], -p[2], p[3]
    qx, qy, qz, qw = q[0], q[1], q[2], q[3]
    out[0] = pw * qx + px * qw + py * qz - pz * qy
    out[1] = pw * qy - px * qz + py * qw + pz * qx
    out[2] = pw * qz + px * qy - py * qx + pz * qw
    out[3] = pw * qw - px * qx - py * qy - pz * qz


@jit_noalloc
def normalize(q):
    """Scale ``q`` to unit norm in place."""
    n = math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    for i in range(4):
        q[i] /= n


@jit_noalloc
def rotate(q, v, out):
    """``out = R(q) v``: a body vector expressed in the inertial frame; ``out`` may alias ``v``."""
    x, y, z, w = q[0], q[1], q[2], q[3]
    vx, vy, vz = v[0], v[1], v[2]
    # t = 2 q_vec x v; v' = v + w t + q_vec x t
    tx = 2.0 * (y * vz - z * vy)
    ty = 2.0 * (z * vx - x * vz)
    tz = 2.0 * (x * vy - y * vx)
    out[0] = vx + w * tx + y * tz - z * ty
    out[1] = vy + w * ty + z * tx - x * tz
    out[2] = vz + w * tz + x * ty - y * tx


@jit_noalloc
def rotate_inverse(q, v, out):
    """``out = R(q)^T v``: an inertial vector expressed in the body frame; may alias ``v``."""
    x, y, z, w = -q[0], -q[1], -q[2], q[3]
    vx, vy, vz = v[0], v[1], v[2]
    tx = 2.0 * (y * vz - z * vy)
    ty = 2.0 * (z * vx - x * vz)
    tz = 2.0 * (x * vy - y * vx)
    out[0] = vx + w * tx + y * tz - z * ty
    out[1] = vy + w * ty + z * tx - x * tz
    out[2] = vz + w * tz + x * ty - y * tx


@jit_noalloc
def from_rotation_vector(rx, ry, rz, out):
    """Unit quaternion of a rotation by ``|r|`` about ``r / |r|`` (exponential map)."""
    angle = math.sqrt(rx * rx + ry * ry + rz * rz)
    half = 0.5 * angle
    if angle < 1e-8:
        s = 0.5 - angle * angle / 48.0  # sin(a/2)/a to second order
    else:
        s = elementary.sin(half) / angle
    out[0] = rx * s
    out[1] = ry * s
    out[2] = rz * s
    out[3] = elementary.cos(half)


@jit_noalloc
def to_rotation_vector(q, out):
    """Rotation vector of ``q`` along the shortest arc (angle in [0, pi])."""
    x, y, z, w = q[0], q[1], q[2], q[3]
    if w < 0.0:
        x, y, z, w = -x, -y, -z, -w
    s = math.sqrt(x * x + y * y + z * z)
    if s < 1e-12:
        k = 2.0 / w  # angle / sin(angle/2) -> 2 as the angle -> 0
    else:
        k = 2.0 * elementary.atan2(s, w) / s
    out[0] = k * x
    out[1] = k * y
    out[2] = k * z


@jit_noalloc
def angle_between(p, q):
    """Angle in rad of the single-axis rotation from attitude ``p`` to attitude ``q`` (000 sec. 6.1)."""
    d = abs(p[0] * q[0] + p[1] * q[1] + p[2] * q[2] + p[3] * q[3])
    if d > 1.0:
        d = 1.0
    return 2.0 * elementary.acos(d)


@jit_noalloc
def slerp_arc(q0, q1):
    """Sign of ``q1`` for the shortest arc, the arc's angle and its sine (000 eq. 4, sec. 3.1).

    The angle is 0 where the attitudes are so close (dot > 1 - 1e-12) that :func:`slerp_on_arc`
    interpolates linearly. A SLERP reference computes this once per reorientation.
    """
    dot = q0[0] * q1[0] + q0[1] * q1[1] + q0[2] * q1[2] + q0[3] * q1[3]
    sign = 1.0
    if dot < 0.0:  # q1 and -q1 are the same attitude: take the shorter arc (000 sec. 3.1)
        sign = -1.0
        dot = -dot
    if dot > 1.0 - 1e-12:
        return sign, 0.0, 0.0
    omega = elementary.acos(dot)
    return sign, omega, elementary.sin(omega)


@jit_noalloc
def slerp_on_arc(q0, q1, sign, omega, sin_omega, h, out):
    """:func:`slerp` with the arc from :func:`slerp_arc` (acos > 1e-6 rad unless linear)."""
    if omega == 0.0:
        for i in range(4):
            out[i] = (1.0 - h) * q0[i] + h * sign * q1[i]
        normalize(out)
        return
    if h == 1.0:  # held at the end: sin(0) / sin(omega) and sign * sin(omega) / sin(omega), exactly
        a = 0.0
        b = sign
    else:
        a = elementary.sin((1.0 - h) * omega) / sin_omega
        b = sign * elementary.sin(h * omega) / sin_omega
    for i in range(4):
        out[i] = a * q0[i] + b * q1[i]


@jit_noalloc
def slerp(q0, q1, h, out):
    """Spherical linear interpolation along the shortest arc, 000 eq. 4; ``h`` in [0, 1]."""
    sign, omega, sin_omega = slerp_arc(q0, q1)
    slerp_on_arc(q0, q1, sign, omega, sin_omega, h, out)


@jit_noalloc
def from_axes(x_axis, y_axis, z_axis, out):
    """Quaternion of the rotation whose matrix has the given (orthonormal) body axes as columns."""
    m00, m01, m02 = x_axis[0], y_axis[0], z_axis[0]
    m10, m11, m12 = x_axis[1], y_axis[1], z_axis[1]
    m20, m21, m22 = x_axis[2], y_axis[2], z_axis[2]
    trace = m00 + m11 + m22
    if trace > 0.0:
        s = 2.0 * math.sqrt(trace + 1.0)
        out[3] = 0.25 * s
        out[0] = (m21 - m12) / s
        out[1] = (m02 - m20) / s
        out[2] = (m10 - m01) / s
    elif m00 > m11 and m00 > m22:
        s = 2.0 * math.sqrt(1.0 + m00 - m11 - m22)
        out[3] = (m21 - m12) / s
        out[0] = 0.25 * s
        out[1] = (m01 + m10) / s
        out[2] = (m02 + m20) / s
    elif m11 > m22:
        s = 2.0 * math.sqrt(1.0 + m11 - m00 - m22)
        out[3] = (m02 - m20) / s
        out[0] = (m01 + m10) / s
        out[1] = 0.25 * s
        out[2] = (m12 + m21) / s
    else:
        s = 2.0 * math.sqrt(1.0 + m22 - m00 - m11)
        out[3] = (m10 - m01) / s
        out[0] = (m02 + m20) / s
        out[1] = (m12 + m21) / s
        out[2] = 0.25 * s
    if out[3] < 0.0:
        for i in range(4):
            out[i] = -out[i]
