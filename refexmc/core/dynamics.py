"""Rigid-body attitude dynamics and their integrator.

State ``x = [q_x, q_y, q_z, q_w, omega_x, omega_y, omega_z]``: attitude quaternion (body to
inertial, scalar last) and body rates in rad/s. Kinematics 000 eq. 28, Euler's equation
000 eq. 29 with every external torque. The integrator is classical RK4 with the torque varying
linearly over the step: the run loop places step boundaries on the thrust-profile breakpoints,
where thrust is piecewise linear in time, so each step sees a smooth right-hand side.
"""

import math

from refexmc._jit import jit_noalloc

STATE_SIZE = 7


@jit_noalloc
def kinematics(x, out):
    """``out[0:4] = dq/dt`` of the state ``x = [q, omega]``: 000 eq. 28, q_dot = 0.5 Xi(q) omega."""
    qx, qy, qz, qw = x[0], x[1], x[2], x[3]
    wx, wy, wz = x[4], x[5], x[6]
    out[0] = 0.5 * (qw * wx - qz * wy + qy * wz)
    out[1] = 0.5 * (qz * wx + qw * wy - qx * wz)
    out[2] = 0.5 * (-qy * wx + qx * wy + qw * wz)
    out[3] = -0.5 * (qx * wx + qy * wy + qz * wz)


@jit_noalloc
def derivative(x, torque, inertia, inertia_inv, out):
    """``out = dx/dt`` for torque (N m, body axes); ``inertia``/``inertia_inv`` are 3x3."""
    kinematics(x, out)
    wx, wy, wz = x[4], x[5], x[6]
    # 000 eq. 29: omega_dot = J^-1 (u - omega x J omega)
    hx = inertia[0, 0] * wx + inertia[0, 1] * wy + inertia[0, 2] * wz
    hy = inertia[1, 0] * wx + inertia[1, 1] * wy + inertia[1, 2] * wz
    hz = inertia[2, 0] * wx + inertia[2, 1] * wy + inertia[2, 2] * wz
    mx = torque[0] - (wy * hz - wz * hy)
    my = torque[1] - (wz * hx - wx * hz)
    mz = torque[2] - (wx * hy - wy * hx)
    out[4] = inertia_inv[0, 0] * mx + inertia_inv[0, 1] * my + inertia_inv[0, 2] * mz
    out[5] = inertia_inv[1, 0] * mx + inertia_inv[1, 1] * my + inertia_inv[1, 2] * mz
    out[6] = inertia_inv[2, 0] * mx + inertia_inv[2, 1] * my + inertia_inv[2, 2] * mz


@jit_noalloc
def invert_3x3(m, out):
    """``out = m^-1`` for a 3x3 matrix by cofactors (no LAPACK, no allocation)."""
    c00 = m[1, 1] * m[2, 2] - m[1, 2] * m[2, 1]
    c01 = m[1, 2] * m[2, 0] - m[1, 0] * m[2, 2]
    c02 = m[1, 0] * m[2, 1] - m[1, 1] * m[2, 0]
    det = m[0, 0] * c00 + m[0, 1] * c01 + m[0, 2] * c02
    out[0, 0] = c00 / det
    out[1, 0] = c01 / det
    out[2, 0] = c02 / det
    out[0, 1] = (m[0, 2] * m[2, 1] - m[0, 1] * m[2, 2]) / det
    out[1, 1] = (m[0, 0] * m[2, 2] - m[0, 2] * m[2, 0]) / det
    out[2, 1] = (m[0, 1] * m[2, 0] - m[0, 0] * m[2, 1]) / det
    out[0, 2] = (m[0, 1] * m[1, 2] - m[0, 2] * m[1, 1]) / det
    out[1, 2] = (m[0, 2] * m[1, 0] - m[0, 0] * m[1, 2]) / det
    out[2, 2] = (m[0, 0] * m[1, 1] - m[0, 1] * m[1, 0]) / det


@jit_noalloc
def rk4_step(x, h, torque_start, torque_end, inertia, inertia_inv, work):
    """Advance ``x`` in place by ``h`` seconds, torque linear from start to end of the step.

    ``work`` is a caller-owned (8, 7) scratch array. The quaternion is renormalised afterwards.
    """
    k1 = work[0]
    k2 = work[1]
    k3 = work[2]
    k4 = work[3]
    stage = work[4]
    tau = work[5]
    for i in range(3):
        tau[i] = torque_start[i]
    derivative(x, tau, inertia, inertia_inv, k1)
    for i in range(3):
        tau[i] = 0.5 * (torque_start[i] + torque_end[i])
    for i in range(STATE_SIZE):
        stage[i] = x[i] + 0.5 * h * k1[i]
    derivative(stage, tau, inertia, inertia_inv, k2)
    for i in range(STATE_SIZE):
        stage[i] = x[i] + 0.5 * h * k2[i]
    derivative(stage, tau, inertia, inertia_inv, k3)
    for i in range(3):
        tau[i] = torque_end[i]
    for i in range(STATE_SIZE):
        stage[i] = x[i] + h * k3[i]
    derivative(stage, tau, inertia, inertia_inv, k4)
    for i in range(STATE_SIZE):
        x[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])
    n = math.sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2] + x[3] * x[3])
    for i in range(4):
        x[i] /= n


@jit_noalloc
def propagate_torque_free(x, duration, step, inertia, inertia_inv, work):
    """Propagate with zero torque by fixed RK4 steps (``duration / step`` rounded up).

    Returns the number of steps taken. A bare reference for tests and benchmarks.
    """
    n = int(duration / step + 0.999999)
    h = duration / n
    zero = work[6]
    for i in range(3):
        zero[i] = 0.0
    for _ in range(n):
        rk4_step(x, h, zero, zero, inertia, inertia_inv, work)
    return n
