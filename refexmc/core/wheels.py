"""Reaction wheels (001 sec. 4, 8-10): coupled body-wheel dynamics, friction, distribution, limits.

State: the body's ``x = [q, omega]`` (core.dynamics) and, per wheel, its axial angular momentum in
inertial space ``h_i = I_w (Omega_i + a_i . omega)`` (``Omega_i``: rotor speed relative to the body,
``a_i``: spin axis, a column of 001's W). With ``J`` the vehicle's inertia (rotors included) and
``J_b = J - sum_i I_w a_i a_i^T`` the total angular momentum is ``L = J_b omega + sum_i a_i h_i``.

    dh_i/dt = tau_m,i + tau_f,i(Omega_i)                               motor + friction (001 eq. 1)
    J_b domega/dt = -omega x L - sum_i a_i dh_i/dt + tau_ext           (001 eq. 5-6)

001 eq. 5-6 is this with u = -sum_i a_i dh_i/dt - omega x sum_i a_i h_i, the wheels' torque on the
body; the inertial ``R(q) L`` changes only by ``R(q) tau_ext``, which the integrator also
accumulates (three more state components, ``IMPULSE``) so that every run checks it.

The flight software commands ``u`` (the controller) and the wheels realise it:
``tau_m = -D (u + omega x sum_i a_i h_i)`` (001 sec. 9.1, eq. 6), D the distribution matrix
(pseudo-inverse of W). Each command is held over the control period (torque-commanded wheels).
In the run loop (core.flight) the wheels family's work arrays are a :class:`Plant` (:func:`plant`)
and its control step is :func:`drive` (docs/families.md).

001 sec. 9.1 distributes momentum as ``H_W = W^+ H_B + n``, n any vector in W's null space. The
pseudo-inverse alone leaves n to whatever friction makes of it; :func:`null_space_torque` (the
flight software's null-space momentum management, optional) drives it to a target with torques in
that null space, which the body does not feel (with the axes the flight software knows).
"""

import math
from typing import NamedTuple

import numpy as np

from refexmc._jit import jit, jit_noalloc
from refexmc.core import arena, dynamics, elementary, quaternion
from refexmc.core.layout import (
    HISTORY_PER_WHEEL,
    HISTORY_SIZE,
    HW_MOMENTUM,
    HW_TORQUE,
    W_AXIS,
    W_COULOMB,
    W_COULOMB_DESIGN,
    W_COULOMB_WIDTH,
    W_FAILED,
    W_MOMENTUM0,
    W_MOMENTUM_MAX,
    W_NULL_SPACE_BIAS,
    W_NULL_SPACE_DEADBAND,
    W_NULL_SPACE_GIVE_UP,
    W_NULL_SPACE_RATE,
    W_NULL_SPACE_TORQUE_MAX,
    W_SPIN_INERTIA,
    W_TORQUE_MAX,
    W_VISCOUS,
    W_VISCOUS_DESIGN,
)
from refexmc.core.status import ST_WHEEL_SATURATED, ST_WHEEL_TORQUE_PEAK

IMPULSE = 3  # the state array of the wheels is [h_1 .. h_n, p_x, p_y, p_z]: p = int R(q) tau_ext dt


class Plant(NamedTuple):
    """The wheels of one flight: their table, state, held commands, and what integrating needs."""

    table: np.ndarray  # one layout.WHEEL row per wheel
    h: np.ndarray  # axial momenta (inertial), then the inertial external impulse (IMPULSE)
    motor: np.ndarray  # motor torques held over the control period (N m)
    demand: np.ndarray  # the distribution's demand before limits (N m)
    inertia: np.ndarray  # J, 3x3 (rotors included): the gravity gradient's
    inertia_b: np.ndarray  # J - sum I_w a a^T
    inertia_b_inv: np.ndarray
    gravity: np.ndarray  # [k = sum mu / r^3, direction (unit, inertial)] of 001 eq. 11; k = 0: none
    xwork: np.ndarray  # (6, 7) RK4 scratch; row 5: x at the last accepted point (:func:`step`)
    hwork: np.ndarray  # (8, len(h)) RK4 scratch; row 5: h there, rows 6, 7: the wheels' speeds there and their rates
    scratch: np.ndarray  # (7, 3); rows 5, 6: a sub-step's external torques (:func:`step`)
    momentum: np.ndarray  # (3, 3): total angular momentum (inertial) at t = 0, at the end; scratch
    null_space: np.ndarray  # (2,): [1 once null-space management gave up, its error |e_n| last period]


@jit
def plant(table):
    """Work arrays for the wheels of ``table`` (zero rows: none), allocated; :func:`start` fills them."""
    size = carve_plant(table, np.zeros(0), 0)[1]
    return carve_plant(table, np.zeros(size), 0)[0]


@jit
def carve_plant(table, f, at):
    """The wheels family's work as views of ``f`` from ``at`` (core.arena): (Plant, cursor after)."""
    n = table.shape[0]
    h, at = arena.vector(f, at, n + IMPULSE)
    motor, at = arena.vector(f, at, n)
    demand, at = arena.vector(f, at, n)
    inertia, at = arena.matrix(f, at, 3, 3)
    inertia_b, at = arena.matrix(f, at, 3, 3)
    inertia_b_inv, at = arena.matrix(f, at, 3, 3)
    gravity, at = arena.vector(f, at, 4)
    xwork, at = arena.matrix(f, at, 6, 7)
    hwork, at = arena.matrix(f, at, 8, n + IMPULSE)
    scratch, at = arena.matrix(f, at, 7, 3)
    momentum, at = arena.matrix(f, at, 3, 3)
    null_space, at = arena.vector(f, at, 2)
    work = Plant(table, h, motor, demand, inertia, inertia_b, inertia_b_inv, gravity, xwork, hwork, scratch, momentum,
                 null_space)  # fmt: skip
    return work, at


@jit_noalloc
def drive(distribution, wh, rate_meas, omega, torque_cmd, compensate, active, status, dt):
    """Motor torques for this control period (core.wheels.command) and the wheel statistics; none
    when ``active`` is False (a locked mode, the program done or the run failed)."""
    if not active:
        for i in range(wh.motor.shape[0]):
            wh.motor[i] = 0.0
        return
    peak, limited = command(distribution, wh, rate_meas, omega, torque_cmd, compensate)
    status[ST_WHEEL_TORQUE_PEAK] = elementary.larger(status[ST_WHEEL_TORQUE_PEAK], peak)
    if limited:
        status[ST_WHEEL_SATURATED] += dt


@jit_noalloc
def body_inertia(inertia, wheels, out):
    """``out = J - sum_i I_w a_i a_i^T``: the inertia that multiplies omega in L (rotor spin apart)."""
    for r in range(3):
        for c in range(3):
            out[r, c] = inertia[r, c]
    for i in range(wheels.shape[0]):
        iw = wheels[i, W_SPIN_INERTIA]
        for r in range(3):
            for c in range(3):
                out[r, c] -= iw * wheels[i, W_AXIS + r] * wheels[i, W_AXIS + c]


@jit_noalloc
def relative_momentum(wheels, i, h, omega):
    """``I_w Omega_i``: wheel ``i``'s momentum relative to the body (what its speed limit bounds)."""
    return h[i] - wheels[i, W_SPIN_INERTIA] * _along(wheels, i, omega)


@jit_noalloc
def start(plant, inertia, x, gg_coefficient, gg_direction):
    """Initial state at body state ``x``: each wheel's momentum from its relative momentum in the
    table, the impulse zero, no motor torque; the inertias, the gravity gradient, and the total
    angular momentum at t = 0."""
    table, h = plant.table, plant.h
    n = table.shape[0]
    for r in range(3):
        for c in range(3):
            plant.inertia[r, c] = inertia[r, c]
    body_inertia(inertia, table, plant.inertia_b)
    dynamics.invert_3x3(plant.inertia_b, plant.inertia_b_inv)
    plant.gravity[0] = gg_coefficient
    for r in range(3):
        plant.gravity[1 + r] = gg_direction[r]
    for i in range(n):
        h[i] = table[i, W_MOMENTUM0] + table[i, W_SPIN_INERTIA] * _along(table, i, x[4:7])
        plant.motor[i] = 0.0
        plant.demand[i] = 0.0
    for k in range(IMPULSE):
        h[n + k] = 0.0
    plant.null_space[0] = 0.0
    plant.null_space[1] = math.inf  # no last period: the first cannot count as growing
    angular_momentum(x, plant, plant.momentum[0:2])


@jit_noalloc
def _along(table, i, v):
    """``a_i . v``."""
    return table[i, W_AXIS] * v[0] + table[i, W_AXIS + 1] * v[1] + table[i, W_AXIS + 2] * v[2]


@jit_noalloc
def friction(wheels, i, relative):
    """The true friction torque on wheel ``i`` (see :func:`friction_law`)."""
    speed = relative / wheels[i, W_SPIN_INERTIA]
    return friction_law(speed, wheels[i, W_COULOMB], wheels[i, W_VISCOUS], wheels[i, W_COULOMB_WIDTH])


@jit_noalloc
def friction_law(speed, coulomb, viscous, width):
    """001 eq. 1: -tau_e sign(Omega) - tau_v Omega at wheel speed ``speed`` (rad/s), the sign made
    linear within +-``width`` (001 sec. 4.1: eq. 1 does not hold near zero speed). The law is
    continuous but its slope jumps at +-``width``: a step across an edge loses RK4's order, so
    :func:`step` ends sub-steps on the edges."""
    drag = -viscous * speed
    if speed >= width:
        return drag - coulomb
    if speed <= -width:
        return drag + coulomb
    return drag - coulomb * speed / width


@jit_noalloc
def angular_momentum(x, plant, out):
    """Total angular momentum in inertial axes, ``R(q) (J_b omega + sum_i a_i h_i)``, in ``out[0]``
    (``out[1]``: scratch)."""
    body = out[1]
    w = x[4:7]
    jb, table, h = plant.inertia_b, plant.table, plant.h
    for r in range(3):
        body[r] = jb[r, 0] * w[0] + jb[r, 1] * w[1] + jb[r, 2] * w[2]
    for i in range(table.shape[0]):
        for r in range(3):
            body[r] += table[i, W_AXIS + r] * h[i]
    quaternion.rotate(x[0:4], body, out[0])


@jit_noalloc
def momentum_residual(x, plant):
    """|L(t) - L(0) - p(t)| / max |L|: how far the integrated state is from conserving the total
    angular momentum against the external impulse p (0 without wheels)."""
    n = plant.table.shape[0]
    if n == 0:
        return 0.0
    angular_momentum(x, plant, plant.momentum[1:3])
    change, size = 0.0, 0.0
    for i in range(3):
        d = plant.momentum[1, i] - plant.momentum[0, i] - plant.h[n + i]
        change += d * d
        size = elementary.larger(elementary.larger(size, abs(plant.momentum[0, i])), abs(plant.momentum[1, i]))
    return math.sqrt(change) / size if size > 0.0 else 0.0


@jit_noalloc
def gravity_gradient(q, coefficient, direction, inertia, scratch, out):
    """Gravity-gradient torque about the CoM (body axes) of bodies along ``direction`` (unit,
    inertial): ``3 k c x J c``, ``c`` that direction in body axes, ``k = sum mu / r^3`` (001 eq. 11;
    001 prints the opposite sign, see docs/irassi.md). Adds into ``out``; ``scratch`` (2, 3)."""
    c = scratch[0]
    jc = scratch[1]
    quaternion.rotate_inverse(q, direction, c)
    for r in range(3):
        jc[r] = inertia[r, 0] * c[0] + inertia[r, 1] * c[1] + inertia[r, 2] * c[2]
    k3 = 3.0 * coefficient
    out[0] += k3 * (c[1] * jc[2] - c[2] * jc[1])
    out[1] += k3 * (c[2] * jc[0] - c[0] * jc[2])
    out[2] += k3 * (c[0] * jc[1] - c[1] * jc[0])


@jit_noalloc
def derivative(x, h, torque, plant, dx, dh):
    """``dx, dh`` of the coupled state for the held motor torques and the external torque
    ``torque`` (body axes) plus the gravity gradient at this attitude."""
    wheels, motor, scratch = plant.table, plant.motor, plant.scratch
    inertia_b, inertia_b_inv, gravity = plant.inertia_b, plant.inertia_b_inv, plant.gravity
    n = wheels.shape[0]
    dynamics.kinematics(x, dx)
    wx, wy, wz = x[4], x[5], x[6]
    tau = scratch[2]
    for r in range(3):
        tau[r] = torque[r]
    if gravity[0] != 0.0:
        gravity_gradient(x[0:4], gravity[0], gravity[1:4], plant.inertia, scratch[0:2], tau)
    # L = J_b omega + sum a_i h_i ; m = tau_ext - omega x L - sum a_i dh_i/dt
    lx = inertia_b[0, 0] * wx + inertia_b[0, 1] * wy + inertia_b[0, 2] * wz
    ly = inertia_b[1, 0] * wx + inertia_b[1, 1] * wy + inertia_b[1, 2] * wz
    lz = inertia_b[2, 0] * wx + inertia_b[2, 1] * wy + inertia_b[2, 2] * wz
    mx, my, mz = tau[0], tau[1], tau[2]
    for i in range(n):
        a0, a1, a2 = wheels[i, W_AXIS], wheels[i, W_AXIS + 1], wheels[i, W_AXIS + 2]
        hi = h[i]
        lx += a0 * hi
        ly += a1 * hi
        lz += a2 * hi
        relative = hi - wheels[i, W_SPIN_INERTIA] * (a0 * wx + a1 * wy + a2 * wz)
        dh[i] = motor[i] + friction(wheels, i, relative)
        mx -= a0 * dh[i]
        my -= a1 * dh[i]
        mz -= a2 * dh[i]
    mx -= wy * lz - wz * ly
    my -= wz * lx - wx * lz
    mz -= wx * ly - wy * lx
    dx[4] = inertia_b_inv[0, 0] * mx + inertia_b_inv[0, 1] * my + inertia_b_inv[0, 2] * mz
    dx[5] = inertia_b_inv[1, 0] * mx + inertia_b_inv[1, 1] * my + inertia_b_inv[1, 2] * mz
    dx[6] = inertia_b_inv[2, 0] * mx + inertia_b_inv[2, 1] * my + inertia_b_inv[2, 2] * mz
    quaternion.rotate(x[0:4], tau, scratch[3])  # the external impulse, inertial axes
    for k in range(IMPULSE):
        dh[n + k] = scratch[3][k]


@jit_noalloc
def rk4_step(x, step, torque_start, torque_end, plant):
    """Advance the body state ``x`` and the wheels' state ``plant.h`` in place by ``step`` seconds
    (classical RK4), the external torque linear from ``torque_start`` to ``torque_end`` over the
    step, the motor torques held. The quaternion is renormalised afterwards (as core.dynamics)."""
    h = plant.h
    nh = h.shape[0]
    xw, hw = plant.xwork, plant.hwork
    k1x, k2x, k3x, k4x, sx = xw[0], xw[1], xw[2], xw[3], xw[4]
    k1h, k2h, k3h, k4h, sh = hw[0], hw[1], hw[2], hw[3], hw[4]
    tau = plant.scratch[4]
    for i in range(3):
        tau[i] = torque_start[i]
    derivative(x, h, tau, plant, k1x, k1h)
    for i in range(3):
        tau[i] = 0.5 * (torque_start[i] + torque_end[i])
    for i in range(7):
        sx[i] = x[i] + 0.5 * step * k1x[i]
    for i in range(nh):
        sh[i] = h[i] + 0.5 * step * k1h[i]
    derivative(sx, sh, tau, plant, k2x, k2h)
    for i in range(7):
        sx[i] = x[i] + 0.5 * step * k2x[i]
    for i in range(nh):
        sh[i] = h[i] + 0.5 * step * k2h[i]
    derivative(sx, sh, tau, plant, k3x, k3h)
    for i in range(3):
        tau[i] = torque_end[i]
    for i in range(7):
        sx[i] = x[i] + step * k3x[i]
    for i in range(nh):
        sh[i] = h[i] + step * k3h[i]
    derivative(sx, sh, tau, plant, k4x, k4h)
    for i in range(7):
        x[i] += step / 6.0 * (k1x[i] + 2.0 * k2x[i] + 2.0 * k3x[i] + k4x[i])
    for i in range(nh):
        h[i] += step / 6.0 * (k1h[i] + 2.0 * k2h[i] + 2.0 * k3h[i] + k4h[i])
    norm = math.sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2] + x[3] * x[3])
    for i in range(4):
        x[i] /= norm


MAX_EDGE_EVENTS = 32  # edges located per integration step; past them the last trial stands
EVENT_MIN_FRACTION = 1e-9  # an edge this close to a step's start is not split off (the kink's
# error is then of order (fraction * step)^2 of the slope jump: nothing at 1e-9)


@jit_noalloc
def _wheel_speeds(x, h, wheels, out):
    """Each wheel's speed relative to the body (rad/s), ``Omega_i = h_i / I_w - a_i . omega``."""
    for i in range(wheels.shape[0]):
        out[i] = h[i] / wheels[i, W_SPIN_INERTIA] - _along(wheels, i, x[4:7])


@jit_noalloc
def _first_edge(x, h, wheels, speeds_start, rates_start, step_s):
    """The fraction (0, 1] of the trial step just taken at which the first wheel crosses an edge of
    its zero-speed zone (+-W_COULOMB_WIDTH); 2.0 when none does (a wheel that stays outside the
    zone, or inside it, crosses nothing). A crossing is a sign change of speed - edge between
    ``speeds_start`` and the state now; its time is the Newton step from the start with the
    speed's rate there (``rates_start``, the trial's first RK4 stage), which the friction beyond
    the edge does not spoil (inside the zone the friction slows the wheel, so the step falls
    short and the next trial refines it), or the speeds' linear interpolation where that step
    does not land inside the trial."""
    first = 2.0
    for i in range(wheels.shape[0]):
        if wheels[i, W_COULOMB] == 0.0:
            continue  # no Coulomb term: the friction is linear everywhere
        width = wheels[i, W_COULOMB_WIDTH]
        s0 = speeds_start[i]
        s1 = h[i] / wheels[i, W_SPIN_INERTIA] - _along(wheels, i, x[4:7])
        for edge in (width, -width):
            d0, d1 = s0 - edge, s1 - edge
            if (d0 > 0.0 and d1 < 0.0) or (d0 < 0.0 and d1 > 0.0):
                fraction = d0 / (d0 - d1)
                if rates_start[i] * d0 < 0.0:
                    newton = -d0 / (rates_start[i] * step_s)
                    if newton <= 1.0:
                        fraction = newton
                if EVENT_MIN_FRACTION < fraction < first:
                    first = fraction
    return first


@jit_noalloc
def _speed_rates(dx, dh, wheels, out):
    """d Omega_i / dt from the state's rates ``dx``, ``dh``."""
    for i in range(wheels.shape[0]):
        out[i] = dh[i] / wheels[i, W_SPIN_INERTIA] - _along(wheels, i, dx[4:7])


@jit_noalloc
def _torque_at(torque_start, torque_end, fraction, out):
    """The external torque, linear over the step, at ``fraction`` of it (its ends exactly)."""
    for i in range(3):
        if fraction == 0.0:
            out[i] = torque_start[i]
        elif fraction == 1.0:
            out[i] = torque_end[i]
        else:
            out[i] = torque_start[i] + (torque_end[i] - torque_start[i]) * fraction


@jit_noalloc
def _save(x, h, wheels, x_saved, h_saved, speeds):
    for i in range(7):
        x_saved[i] = x[i]
    for i in range(h.shape[0]):
        h_saved[i] = h[i]
    _wheel_speeds(x, h, wheels, speeds)


@jit_noalloc
def step(x, step_s, torque_start, torque_end, plant):
    """Advance ``x`` and ``plant.h`` by ``step_s`` as :func:`rk4_step`, the friction's kinks
    resolved: a step in which a wheel's speed crosses an edge of the zero-speed zone (001 eq. 1's
    linear zone, :func:`friction_law`) is taken again in sub-steps that end on each crossing
    (:func:`_first_edge`; each trial over the rest refines the last), so every RK4 step sees a
    smooth right-hand side but for an error of the located time's square. A step in which no
    wheel crosses an edge is the plain RK4 step, to the bit. Returns the RK4 steps taken, trials
    included."""
    wheels, h = plant.table, plant.h
    x_saved, h_saved, speeds, rates = plant.xwork[5], plant.hwork[5], plant.hwork[6], plant.hwork[7]
    tau_a, tau_b = plant.scratch[5], plant.scratch[6]
    _save(x, h, wheels, x_saved, h_saved, speeds)
    done, end = 0.0, 1.0  # fractions of the step: the last accepted point, this RK4 step's end
    taken, events = 0, 0
    while True:
        _torque_at(torque_start, torque_end, done, tau_a)
        _torque_at(torque_start, torque_end, end, tau_b)
        rk4_step(x, step_s * (end - done), tau_a, tau_b, plant)  # one call site: LLVM inlines it
        taken += 1
        if end < 1.0:  # a sub-step onto an edge: accepted, then a trial over the rest
            done, end = end, 1.0
            _save(x, h, wheels, x_saved, h_saved, speeds)
            continue
        if events == MAX_EDGE_EVENTS:
            return taken
        _speed_rates(plant.xwork[0], plant.hwork[0], wheels, rates)  # the trial's first RK4 stage
        edge = _first_edge(x, h, wheels, speeds, rates, step_s * (1.0 - done))
        end = done + (1.0 - done) * edge
        if end >= 1.0:  # no edge crossed, or one on the step's end: the trial stands
            return taken
        events += 1
        for i in range(7):  # back to the last accepted point, then on to the edge
            x[i] = x_saved[i]
        for i in range(h.shape[0]):
            h[i] = h_saved[i]


@jit_noalloc
def null_space_torque(distribution, wheels, h, rate_meas, out):
    """Null-space momentum management: ``out = -r (1 - Z / |e_n|) e_n`` (N m per wheel) with the
    null-space error ``e_n = P (I_w Omega - b)`` when ``|e_n| > Z``, else 0; then scaled as one
    vector so that no wheel's exceeds the cap. ``r`` (1/s), ``b`` (N m s), ``Z`` (N m s) and the
    cap (N m) are the table's W_NULL_SPACE columns, ``I_w Omega`` as the tachometers and the
    measured body rate give it. ``P = I - D (D^T D)^-1 D^T`` over the wheels the distribution
    ``D`` uses (its non-zero rows; 0 for the others): with ``D = W_u^+`` the range of D is the row
    space of ``W_u``, so P projects on its null space (001 sec. 9.1's n, sec. 8.1's n_4) and
    ``W_u out = 0``: no body torque with the axes the flight software knows. P is built from D
    alone, never from the true axes. With three wheels used or fewer there is no null space and
    ``out`` is zero; so it is when the used wheels do not span the three axes (a D of rank < 3 left
    by detected failures: the attitude is lost anyway). Returns (the number of wheels D uses,
    ``|e_n|``, True when the cap scaled the torque)."""
    n = wheels.shape[0]
    used = 0
    g00, g01, g02, g11, g12, g22 = 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    s0, s1, s2 = 0.0, 0.0, 0.0
    for i in range(n):
        d0, d1, d2 = distribution[i, 0], distribution[i, 1], distribution[i, 2]
        out[i] = 0.0
        if d0 == 0.0 and d1 == 0.0 and d2 == 0.0:
            continue
        used += 1
        e = relative_momentum(wheels, i, h, rate_meas) - wheels[i, W_NULL_SPACE_BIAS]
        out[i] = e
        s0 += d0 * e
        s1 += d1 * e
        s2 += d2 * e
        g00 += d0 * d0
        g01 += d0 * d1
        g02 += d0 * d2
        g11 += d1 * d1
        g12 += d1 * d2
        g22 += d2 * d2
    if used <= 3:
        for i in range(n):
            out[i] = 0.0
        return used, 0.0, False
    # y = (D^T D)^-1 D^T e by cofactors (D^T D symmetric, positive definite when D has rank 3)
    c00 = g11 * g22 - g12 * g12
    c01 = g02 * g12 - g01 * g22
    c02 = g01 * g12 - g02 * g11
    c11 = g00 * g22 - g02 * g02
    c12 = g01 * g02 - g00 * g12
    c22 = g00 * g11 - g01 * g01
    det = g00 * c00 + g01 * c01 + g02 * c02
    trace = g00 + g11 + g22
    if det <= 1e-12 * trace * trace * trace:  # the used wheels do not span 3 axes: P undefined, no torque
        for i in range(n):
            out[i] = 0.0
        return used, 0.0, False
    y0 = (c00 * s0 + c01 * s1 + c02 * s2) / det
    y1 = (c01 * s0 + c11 * s1 + c12 * s2) / det
    y2 = (c02 * s0 + c12 * s1 + c22 * s2) / det
    size = 0.0
    for i in range(n):
        d0, d1, d2 = distribution[i, 0], distribution[i, 1], distribution[i, 2]
        if d0 == 0.0 and d1 == 0.0 and d2 == 0.0:
            continue
        out[i] = out[i] - (d0 * y0 + d1 * y1 + d2 * y2)  # e_n
        size += out[i] * out[i]
    size = math.sqrt(size)
    deadband = wheels[0, W_NULL_SPACE_DEADBAND]
    gain = 0.0 if size <= deadband else -wheels[0, W_NULL_SPACE_RATE] * (1.0 - deadband / size)
    peak = 0.0
    for i in range(n):
        out[i] *= gain
        peak = elementary.larger(peak, abs(out[i]))
    cap = wheels[0, W_NULL_SPACE_TORQUE_MAX]
    capped = peak > cap
    if capped:
        for i in range(n):
            out[i] *= cap / peak
    return used, size, capped


@jit_noalloc
def command(distribution, plant, rate_meas, omega, torque_cmd, compensate):
    """Motor torques for the body torque ``torque_cmd`` (001 eq. 6, sec. 9.1):
    ``demand = -D (u + omega x sum_i a_i h_i)``, then the limits: the whole vector scaled so that
    no working wheel exceeds its torque limit (the body torque keeps its direction), and a wheel at
    its momentum limit (the drive's speed limiter, on the true rate ``omega``) not driven further.
    With ``compensate`` the demand also cancels the friction the flight software assumes at the
    wheel's speed (tachometer and measured body rate; the design coefficients of the table).
    With null-space management on (the table's W_NULL_SPACE_RATE non-zero) the demand also holds
    :func:`null_space_torque`, before the limits (the scaling keeps it in the null space). It gives
    up for the rest of the flight (``plant.null_space[0] = 1``) when its torque is at the cap, the
    error beyond the deadband by more than W_NULL_SPACE_GIVE_UP and still growing: a null space
    that does not respond, as with a dead wheel the flight software does not know of.
    A failed wheel gives no torque; the flight software does not know unless D leaves it out. The
    flight software reads the wheel momenta (tachometers) exactly and the body rate as measured.
    Returns (largest |demand|, True when a limit acted)."""
    wheels, h, demand, motor = plant.table, plant.h, plant.demand, plant.motor
    n = wheels.shape[0]
    hb0, hb1, hb2 = 0.0, 0.0, 0.0
    for i in range(n):
        hb0 += wheels[i, W_AXIS] * h[i]
        hb1 += wheels[i, W_AXIS + 1] * h[i]
        hb2 += wheels[i, W_AXIS + 2] * h[i]
    w0, w1, w2 = rate_meas[0], rate_meas[1], rate_meas[2]
    v0 = torque_cmd[0] + (w1 * hb2 - w2 * hb1)
    v1 = torque_cmd[1] + (w2 * hb0 - w0 * hb2)
    v2 = torque_cmd[2] + (w0 * hb1 - w1 * hb0)
    peak = 0.0
    scale = 1.0
    manage = n > 0 and wheels[0, W_NULL_SPACE_RATE] != 0.0 and plant.null_space[0] == 0.0
    if manage:
        _, size, capped = null_space_torque(distribution, wheels, h, rate_meas, demand)
        beyond = size - wheels[0, W_NULL_SPACE_DEADBAND]
        if capped and beyond > wheels[0, W_NULL_SPACE_GIVE_UP] and size > plant.null_space[1]:
            plant.null_space[0] = 1.0
            for i in range(n):
                demand[i] = 0.0
        plant.null_space[1] = size
    for i in range(n):
        d = -(distribution[i, 0] * v0 + distribution[i, 1] * v1 + distribution[i, 2] * v2)
        if compensate:
            speed = relative_momentum(wheels, i, h, rate_meas) / wheels[i, W_SPIN_INERTIA]
            width = wheels[i, W_COULOMB_WIDTH]
            d -= friction_law(speed, wheels[i, W_COULOMB_DESIGN], wheels[i, W_VISCOUS_DESIGN], width)
        if manage:
            d += demand[i]  # the null-space torque
        demand[i] = d
        peak = elementary.larger(peak, abs(d))
        if wheels[i, W_FAILED] == 0.0 and abs(d) * scale > wheels[i, W_TORQUE_MAX]:
            scale = wheels[i, W_TORQUE_MAX] / abs(d)
    limited = scale < 1.0
    for i in range(n):
        motor[i] = 0.0 if wheels[i, W_FAILED] != 0.0 else demand[i] * scale
        relative = relative_momentum(wheels, i, h, omega)
        if abs(relative) >= wheels[i, W_MOMENTUM_MAX] and motor[i] * relative > 0.0:
            motor[i] = 0.0
            limited = True
    return peak, limited


@jit_noalloc
def largest_relative_momentum(wheels, h, omega):
    """The largest |I_w Omega_i| over the wheels (0 without wheels)."""
    peak = 0.0
    for i in range(wheels.shape[0]):
        peak = elementary.larger(peak, abs(relative_momentum(wheels, i, h, omega)))
    return peak


@jit_noalloc
def record(plant, omega, row):
    """The wheels' history columns of one row (layout.history_size): per wheel its momentum
    relative to the body and its motor torque."""
    for i in range(plant.table.shape[0]):
        column = HISTORY_SIZE + HISTORY_PER_WHEEL * i
        row[column + HW_MOMENTUM] = relative_momentum(plant.table, i, plant.h, omega)
        row[column + HW_TORQUE] = plant.motor[i]
