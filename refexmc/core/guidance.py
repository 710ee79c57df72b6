"""Guidance: reference attitude, rate and acceleration for each mode (000 sec. 3).

SAM/EAM: SLERP (eq. 4) paced by the quintic h(t) (eq. 7-9), t1 from eq. 13-14.
RDM: cubic rate profile (eq. 17-18), t1 from eq. 19. SSM: quartic spin-up (eq. 22-27).
For t > t1 the final state is held. The guidance state is a caller-owned float array.
"""

import math

from refexmc._jit import jit_noalloc
from refexmc.core import quaternion

G_T0 = 0  # mode start time
G_T1 = 1  # transition duration
G_Q0 = 2  # start attitude (4)
G_Q1 = 6  # final attitude (4)
G_VECTOR = 10  # SLERP rotation vector theta = e * angle, or RDM omega_0, or SSM omega_1 (3)
G_ARC = 13  # SLERP: sign of q1, arc angle and its sine (quaternion.slerp_arc) (3)
GUIDANCE_STATE_SIZE = 16


@jit_noalloc
def quintic(t, t1):
    """h, h_dot, h_ddot of 000 eq. 7-9; held at (1, 0, 0) for t >= t1."""
    if t <= 0.0:
        return 0.0, 0.0, 0.0
    if t >= t1:
        return 1.0, 0.0, 0.0
    s = t / t1
    h = s * s * s * (10.0 - 15.0 * s + 6.0 * s * s)
    h_dot = 30.0 * s * s * (1.0 - s) * (1.0 - s) / t1
    h_ddot = 60.0 * s * (1.0 - s) * (1.0 - 2.0 * s) / (t1 * t1)
    return h, h_dot, h_ddot


@jit_noalloc
def cubic_rate(t, t1):
    """Rate factor and its derivative of 000 eq. 17-18; (0, 0) for t >= t1."""
    if t <= 0.0:
        return 1.0, 0.0
    if t >= t1:
        return 0.0, 0.0
    s = t / t1
    return 2.0 * s * s * s - 3.0 * s * s + 1.0, 6.0 * s * (s - 1.0) / t1


@jit_noalloc
def quartic_spin_up(t, t1):
    """Angle, rate and acceleration factors of 000 eq. 22-27 (multiply by omega_1)."""
    if t <= 0.0:
        return 0.0, 0.0, 0.0
    if t >= t1:
        return 0.5 * t1 + (t - t1), 1.0, 0.0  # eq. 25-27; phi(t1) = t1/2 * omega_1
    s = t / t1
    angle = t * (s * s - 0.5 * s * s * s)
    rate = 3.0 * s * s - 2.0 * s * s * s
    accel = 6.0 * s * (1.0 - s) / t1
    return angle, rate, accel


@jit_noalloc
def slerp_duration(theta, accel_max, t1_design):
    """t1 of 000 eq. 13-14: the slowest axis at the given (already margined) accelerations."""
    t1 = t1_design
    for i in range(3):
        if accel_max[i] > 0.0:
            t_axis = math.sqrt(20.0 * abs(theta[i]) / (math.sqrt(12.0) * accel_max[i]))
            if t_axis > t1:
                t1 = t_axis
    return t1


@jit_noalloc
def rate_profile_duration(omega, accel_max):
    """t1 of 000 eq. 19 (also used for SSM with omega_1)."""
    t1 = 0.0
    for i in range(3):
        if accel_max[i] > 0.0:
            t_axis = 1.5 * abs(omega[i]) / accel_max[i]
            if t_axis > t1:
                t1 = t_axis
    return t1


@jit_noalloc
def start_slerp(state, t0, q_start, q_final, accel_max, t1_design, work4):
    """Begin a SLERP reorientation (SAM, EAM) from ``q_start`` to ``q_final``."""
    state[G_T0] = t0
    for i in range(4):
        state[G_Q0 + i] = q_start[i]
        state[G_Q1 + i] = q_final[i]
    quaternion.conj_multiply(q_start, q_final, work4)
    quaternion.to_rotation_vector(work4, state[G_VECTOR : G_VECTOR + 3])
    state[G_T1] = slerp_duration(state[G_VECTOR : G_VECTOR + 3], accel_max, t1_design)
    sign, omega, sin_omega = quaternion.slerp_arc(state[G_Q0 : G_Q0 + 4], state[G_Q1 : G_Q1 + 4])
    state[G_ARC] = sign
    state[G_ARC + 1] = omega
    state[G_ARC + 2] = sin_omega


@jit_noalloc(force_inline=True)
def slerp_reference(state, t, q_out, rate_out, accel_out):
    """Reference of a SLERP reorientation at time ``t`` (000 eq. 4, 10-12)."""
    h, h_dot, h_ddot = quintic(t - state[G_T0], state[G_T1])
    quaternion.slerp_on_arc(
        state[G_Q0 : G_Q0 + 4], state[G_Q1 : G_Q1 + 4], state[G_ARC], state[G_ARC + 1], state[G_ARC + 2], h, q_out
    )
    for i in range(3):
        rate_out[i] = state[G_VECTOR + i] * h_dot
        accel_out[i] = state[G_VECTOR + i] * h_ddot


@jit_noalloc
def start_rate_damping(state, t0, omega0, accel_max):
    """Begin rate damping from the measured rates ``omega0`` (000 eq. 15-19)."""
    state[G_T0] = t0
    for i in range(3):
        state[G_VECTOR + i] = omega0[i]
    state[G_T1] = rate_profile_duration(omega0, accel_max)


@jit_noalloc
def rate_damping_reference(state, t, rate_out, accel_out):
    """Reference rate and acceleration of rate damping at ``t`` (000 eq. 17-18)."""
    factor, factor_dot = cubic_rate(t - state[G_T0], state[G_T1])
    for i in range(3):
        rate_out[i] = state[G_VECTOR + i] * factor
        accel_out[i] = state[G_VECTOR + i] * factor_dot


@jit_noalloc
def start_spin_up(state, t0, q_start, omega1, accel_max):
    """Begin the sun-scanning spin-up from attitude ``q_start`` to rate ``omega1`` (eq. 20-21)."""
    state[G_T0] = t0
    for i in range(4):
        state[G_Q0 + i] = q_start[i]
    for i in range(3):
        state[G_VECTOR + i] = omega1[i]
    state[G_T1] = rate_profile_duration(omega1, accel_max)


@jit_noalloc(force_inline=True)
def spin_up_reference(state, t, q_out, rate_out, accel_out, work4):
    """Reference of the SSM at ``t``: q = q_start (x) rotation(phi(t)) (000 eq. 22-27)."""
    angle, rate, accel = quartic_spin_up(t - state[G_T0], state[G_T1])
    quaternion.from_rotation_vector(
        angle * state[G_VECTOR], angle * state[G_VECTOR + 1], angle * state[G_VECTOR + 2], work4
    )
    quaternion.multiply(state[G_Q0 : G_Q0 + 4], work4, q_out)
    for i in range(3):
        rate_out[i] = state[G_VECTOR + i] * rate
        accel_out[i] = state[G_VECTOR + i] * accel


@jit_noalloc
def entry_attitude(velocity_pitch, alpha, beta, bank, q_out, work):
    """Attitude with aerodynamic angles (alpha, beta, bank) to a velocity in the x-z plane.

    ``velocity_pitch`` is the angle of the velocity above the inertial x axis (about +y).
    q = Ry(velocity_pitch) (x) Rx(bank) (x) Rz(-beta) (x) Ry(alpha); ``work`` is (3, 4).
    """
    a = work[0]
    b = work[1]
    c = work[2]
    quaternion.from_rotation_vector(0.0, velocity_pitch, 0.0, a)
    quaternion.from_rotation_vector(bank, 0.0, 0.0, b)
    quaternion.multiply(a, b, c)
    quaternion.from_rotation_vector(0.0, 0.0, -beta, a)
    quaternion.multiply(c, a, b)
    quaternion.from_rotation_vector(0.0, alpha, 0.0, a)
    quaternion.multiply(b, a, q_out)


@jit_noalloc
def aerodynamic_rotations(alpha, beta, bank, out):
    """The constant factors Rx(bank), Rz(-beta), Ry(alpha) of :func:`entry_attitude`, rows of ``out``."""
    quaternion.from_rotation_vector(bank, 0.0, 0.0, out[0])
    quaternion.from_rotation_vector(0.0, 0.0, -beta, out[1])
    quaternion.from_rotation_vector(0.0, alpha, 0.0, out[2])


@jit_noalloc(force_inline=True)
def entry_attitude_from(velocity_pitch, rotations, q_out, work):
    """:func:`entry_attitude` with its constant factors from :func:`aerodynamic_rotations`.

    The same products in the same order, so the same result to the bit; ``work`` is (2, 4).
    """
    a = work[0]
    c = work[1]
    quaternion.from_rotation_vector(0.0, velocity_pitch, 0.0, a)
    quaternion.multiply(a, rotations[0], c)
    quaternion.multiply(c, rotations[1], a)
    quaternion.multiply(a, rotations[2], q_out)


@jit_noalloc
def sun_attitude(sun, horizontal, q_out, work):
    """Body +y at the sun, body x as close as possible to ``horizontal`` (reference-model sec. 4).

    ``sun`` and ``horizontal`` are unit inertial vectors; ``work`` is (3, 3).
    """
    x_axis = work[0]
    y_axis = work[1]
    z_axis = work[2]
    dot = horizontal[0] * sun[0] + horizontal[1] * sun[1] + horizontal[2] * sun[2]
    norm = 0.0
    for i in range(3):
        y_axis[i] = sun[i]
        x_axis[i] = horizontal[i] - dot * sun[i]
        norm += x_axis[i] * x_axis[i]
    norm = math.sqrt(norm)
    for i in range(3):
        x_axis[i] /= norm
    z_axis[0] = x_axis[1] * y_axis[2] - x_axis[2] * y_axis[1]
    z_axis[1] = x_axis[2] * y_axis[0] - x_axis[0] * y_axis[2]
    z_axis[2] = x_axis[0] * y_axis[1] - x_axis[1] * y_axis[0]
    quaternion.from_axes(x_axis, y_axis, z_axis, q_out)
