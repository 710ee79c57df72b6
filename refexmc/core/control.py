"""Attitude controllers: commanded torque from measured state and guidance reference.

The controller is chosen by ``controller_id`` (layout.CONTROLLER_*); new laws add a branch to
:func:`torque_command` and leave the run loop alone.
"""

from refexmc._jit import jit_inline
from refexmc.core import elementary, quaternion
from refexmc.core.layout import CONTROLLER_PD, CONTROLLER_PD_FEEDBACK_LINEARISATION, CONTROLLER_SMC


@jit_inline
def control_errors(q_meas, rate_meas, q_ref, rate_ref, q_error, rate_error):
    """Quaternion error q_e = conj(q_ref) (x) q_meas (shortest arc) and rate error (000 eq. 35)."""
    quaternion.conj_multiply(q_ref, q_meas, q_error)
    if q_error[3] < 0.0:
        for i in range(4):
            q_error[i] = -q_error[i]
    for i in range(3):
        rate_error[i] = rate_meas[i] - rate_ref[i]


@jit_inline
def linearised(inertia, a0, a1, a2, rate, out):
    """u = J a + omega x J omega: the torque that gives the body the angular acceleration ``a``
    (000 eq. 30; 001 eq. 12's J (...) + omega x J omega)."""
    wx, wy, wz = rate[0], rate[1], rate[2]
    hx = inertia[0, 0] * wx + inertia[0, 1] * wy + inertia[0, 2] * wz
    hy = inertia[1, 0] * wx + inertia[1, 1] * wy + inertia[1, 2] * wz
    hz = inertia[2, 0] * wx + inertia[2, 1] * wy + inertia[2, 2] * wz
    out[0] = inertia[0, 0] * a0 + inertia[0, 1] * a1 + inertia[0, 2] * a2 + (wy * hz - wz * hy)
    out[1] = inertia[1, 0] * a0 + inertia[1, 1] * a1 + inertia[1, 2] * a2 + (wz * hx - wx * hz)
    out[2] = inertia[2, 0] * a0 + inertia[2, 1] * a1 + inertia[2, 2] * a2 + (wx * hy - wy * hx)


@jit_inline
def pd_feedback_linearisation(q_error, rate_error, rate_meas, accel_ref, kp, kd, inertia, attitude_controlled, out):
    """u = J v + omega x J omega with v = omega_dot_g - Kd omega_e - Kp q_e,vec (000 eq. 30, 35).

    In rate damping the attitude is not controlled (000 sec. 3.2): the Kp term is left out.
    """
    v0 = accel_ref[0] - kd[0] * rate_error[0]
    v1 = accel_ref[1] - kd[1] * rate_error[1]
    v2 = accel_ref[2] - kd[2] * rate_error[2]
    if attitude_controlled:
        v0 -= kp[0] * q_error[0]
        v1 -= kp[1] * q_error[1]
        v2 -= kp[2] * q_error[2]
    linearised(inertia, v0, v1, v2, rate_meas, out)


@jit_inline
def pd(q_error, rate_error, kp, kd, attitude_controlled, out):
    """M_i = -Kp,i q_e,i - Kd,i omega_e,i (004 eq. 1), gains in N m and N m s; rates only in rate damping."""
    for i in range(3):
        out[i] = -kd[i] * rate_error[i]
        if attitude_controlled:
            out[i] -= kp[i] * q_error[i]


@jit_inline
def sat(value, width):
    """001 eq. 12's sat(sigma, epsilon): sigma / epsilon inside the boundary layer, its sign outside."""
    ratio = value / width
    return elementary.smaller(1.0, elementary.larger(-1.0, ratio))


@jit_inline
def sliding_mode(q_error, rate_error, rate_meas, accel_ref, smc, inertia, attitude_controlled, out):
    """001 eq. 12: u = J (-Lambda dq_e/dt + omega_dot_d) + omega x J omega - J G sat(sigma, epsilon),
    sigma = omega_e + Lambda sign(q_e4) q_e,vec; ``smc`` rows: Lambda, G, epsilon per axis.

    q_e has q_e4 >= 0 (control_errors), so sign(q_e4) = 1; dq_e,vec/dt = (q_e4 omega_e + q_e,vec x
    omega_e) / 2 (the error's kinematics). In rate damping the attitude terms are left out.
    """
    slope, gain, layer = smc[0], smc[1], smc[2]
    ex, ey, ez, e4 = q_error[0], q_error[1], q_error[2], q_error[3]
    wx, wy, wz = rate_error[0], rate_error[1], rate_error[2]
    qd0 = 0.5 * (e4 * wx + ey * wz - ez * wy)
    qd1 = 0.5 * (e4 * wy + ez * wx - ex * wz)
    qd2 = 0.5 * (e4 * wz + ex * wy - ey * wx)
    a0, a1, a2 = accel_ref[0], accel_ref[1], accel_ref[2]
    s0, s1, s2 = wx, wy, wz
    if attitude_controlled:
        a0 -= slope[0] * qd0
        a1 -= slope[1] * qd1
        a2 -= slope[2] * qd2
        s0 += slope[0] * ex
        s1 += slope[1] * ey
        s2 += slope[2] * ez
    a0 -= gain[0] * sat(s0, layer[0])
    a1 -= gain[1] * sat(s1, layer[1])
    a2 -= gain[2] * sat(s2, layer[2])
    linearised(inertia, a0, a1, a2, rate_meas, out)


@jit_inline
def torque_command(
    controller_id, q_error, rate_error, rate_meas, accel_ref, kp, kd, smc, inertia, attitude_controlled, out
):
    """Commanded torque (N m, body axes) of the configured controller."""
    if controller_id == CONTROLLER_PD_FEEDBACK_LINEARISATION:
        pd_feedback_linearisation(q_error, rate_error, rate_meas, accel_ref, kp, kd, inertia, attitude_controlled, out)
    elif controller_id == CONTROLLER_PD:
        pd(q_error, rate_error, kp, kd, attitude_controlled, out)
    elif controller_id == CONTROLLER_SMC:
        sliding_mode(q_error, rate_error, rate_meas, accel_ref, smc, inertia, attitude_controlled, out)
    else:
        for i in range(3):
            out[i] = 0.0
