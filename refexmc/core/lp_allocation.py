"""Fuel-optimal thruster allocation by linear programming (004 eq. 2-5).

    minimise sum(u)  subject to  H u = tau,  0 <= u <= u_max

for any thruster geometry (H: 3 x n torque arms times direction, N m per N). A small
bounded-variable primal simplex on caller-owned arrays, Bland's rule against cycling.

Policy when tau is not attainable (outside the thrusters' torque polytope, or a direction they
cannot produce): the largest attainable torque along tau, s* tau with s* in [0, 1] maximal, then
the least propellant for it. Both come from one LP in (u, s):

    H u - s tau = 0,  0 <= u <= u_max,  0 <= s <= 1

phase A maximises s from the feasible start u = 0, s = 0 (three artificial variables fixed at
zero form the first basis, so no feasibility phase is needed); phase B fixes s = s* and
minimises sum(u) from phase A's basis. An attainable tau gives s* = 1 and 004's solution.
Thrusters that have failed undetected stay in H: the flight software does not know (000 sec. 5).
One whose failure it knows (a detected failure) has a zero column in H (``allocation.nominal_arms``),
which never enters the basis: the result is that of the LP without it.

The actuation ``lp_pwm`` family's flight step lives here too (docs/families.md): its work arrays
(:class:`Optimiser`, allocated by :func:`optimiser`) and :func:`pulse_width`, the LP allocation
realised as one pulse per thruster per control period, which the run loop (core.flight) calls.
"""

from typing import NamedTuple

import numpy as np

from refexmc._jit import jit, jit_noalloc
from refexmc.core import allocation, arena, elementary, rcs
from refexmc.core.layout import F_CONTROL_PERIOD, F_MIN_ON, LV_THRUST_DESIGN
from refexmc.core.status import MASK_ACTIVE, MASK_OPEN

N_ROWS = 3  # torque components
MAX_ITERATIONS = 200
COST_TOLERANCE = 1e-12  # reduced costs below this (times the cost scale) count as zero
PIVOT_TOLERANCE = 1e-12
# work layout: columns 0..n-1 thrusters, n the scale s, n+1..n+3 artificials


def work_columns(n_thrusters):
    """Columns of the LP's work arrays for ``n_thrusters`` thrusters."""
    return n_thrusters + 1 + N_ROWS


@jit_noalloc
def _invert_basis(a, basis, binv):
    """binv = inverse of the 3 x 3 basis matrix (Gauss-Jordan with partial pivoting)."""
    m = N_ROWS
    # build [B | I] in place: binv holds I, and a copy of B is reduced in the first 3x3 of scratch
    for i in range(m):
        for j in range(m):
            binv[i, j] = 1.0 if i == j else 0.0
    b00, b01, b02 = a[0, basis[0]], a[0, basis[1]], a[0, basis[2]]
    b10, b11, b12 = a[1, basis[0]], a[1, basis[1]], a[1, basis[2]]
    b20, b21, b22 = a[2, basis[0]], a[2, basis[1]], a[2, basis[2]]
    c00 = b11 * b22 - b12 * b21
    c01 = b02 * b21 - b01 * b22
    c02 = b01 * b12 - b02 * b11
    det = b00 * c00 + b10 * c01 + b20 * c02
    if det == 0.0:
        return False
    inv_det = 1.0 / det
    binv[0, 0] = c00 * inv_det
    binv[0, 1] = c01 * inv_det
    binv[0, 2] = c02 * inv_det
    binv[1, 0] = (b12 * b20 - b10 * b22) * inv_det
    binv[1, 1] = (b00 * b22 - b02 * b20) * inv_det
    binv[1, 2] = (b02 * b10 - b00 * b12) * inv_det
    binv[2, 0] = (b10 * b21 - b11 * b20) * inv_det
    binv[2, 1] = (b01 * b20 - b00 * b21) * inv_det
    binv[2, 2] = (b00 * b11 - b01 * b10) * inv_det
    return True


@jit_noalloc
def _simplex(a, lower, upper, cost, x, basis, in_basis, binv, w):
    """Bounded-variable primal simplex from the feasible basic solution ``x`` with ``basis``.

    Nonbasic variables sit at a bound. Entering: the lowest-index variable whose move improves
    the cost (Bland); leaving: the blocking basic variable with the lowest index on ties.
    Returns the number of iterations, or -1 at the iteration limit.
    """
    n = a.shape[1]
    scale = 0.0
    for j in range(n):
        scale = elementary.larger(scale, abs(cost[j]))
    tolerance = COST_TOLERANCE * elementary.larger(scale, 1.0)
    for iteration in range(MAX_ITERATIONS):
        if not _invert_basis(a, basis, binv):
            return -1
        y0 = cost[basis[0]] * binv[0, 0] + cost[basis[1]] * binv[1, 0] + cost[basis[2]] * binv[2, 0]
        y1 = cost[basis[0]] * binv[0, 1] + cost[basis[1]] * binv[1, 1] + cost[basis[2]] * binv[2, 1]
        y2 = cost[basis[0]] * binv[0, 2] + cost[basis[1]] * binv[1, 2] + cost[basis[2]] * binv[2, 2]
        entering = -1
        direction = 0.0
        for j in range(n):
            if in_basis[j] or upper[j] <= lower[j]:
                continue
            d = cost[j] - (y0 * a[0, j] + y1 * a[1, j] + y2 * a[2, j])
            if d < -tolerance and x[j] < upper[j]:
                entering, direction = j, 1.0
                break
            if d > tolerance and x[j] > lower[j]:
                entering, direction = j, -1.0
                break
        if entering < 0:
            return iteration
        for i in range(N_ROWS):  # change of x_B per unit step of the entering variable: -direction w
            w[i] = binv[i, 0] * a[0, entering] + binv[i, 1] * a[1, entering] + binv[i, 2] * a[2, entering]
        step = upper[entering] - lower[entering]  # a bound flip
        leaving = -1
        for i in range(N_ROWS):
            delta = -direction * w[i]
            k = basis[i]
            if delta < -PIVOT_TOLERANCE:
                t = (x[k] - lower[k]) / -delta
            elif delta > PIVOT_TOLERANCE:
                t = (upper[k] - x[k]) / delta
            else:
                continue
            if t < 0.0:
                t = 0.0
            if t < step or (t == step and leaving >= 0 and k < basis[leaving]):
                step = t
                leaving = i
        x[entering] += direction * step
        for i in range(N_ROWS):
            x[basis[i]] -= direction * w[i] * step
        if leaving >= 0:
            k = basis[leaving]
            x[k] = lower[k] if -direction * w[leaving] < 0.0 else upper[k]  # exactly on its bound
            in_basis[k] = False
            basis[leaving] = entering
            in_basis[entering] = True
        else:
            x[entering] = upper[entering] if direction > 0.0 else lower[entering]
    return -1


@jit_noalloc
def _refine(a, basis, binv, x, rhs):
    """Recompute the basic variables from the nonbasic ones: B x_B = rhs - N x_N (less rounding)."""
    n = a.shape[1]
    r0, r1, r2 = rhs[0], rhs[1], rhs[2]
    for j in range(n):
        if j != basis[0] and j != basis[1] and j != basis[2] and x[j] != 0.0:
            r0 -= a[0, j] * x[j]
            r1 -= a[1, j] * x[j]
            r2 -= a[2, j] * x[j]
    for i in range(N_ROWS):
        x[basis[i]] = binv[i, 0] * r0 + binv[i, 1] * r1 + binv[i, 2] * r2


@jit_noalloc
def allocate(arms, u_max, torque, u_out, work, basis, in_basis):
    """Thrust per thruster ``u_out`` (N) realising ``torque`` (N m) with the least total thrust.

    ``arms``: (3, n) torque per newton of each thruster (r x d); ``u_max``: (n,) largest thrust.
    ``work``: float scratch of :func:`scratch_shape`, ``basis``: (3,) int64, ``in_basis``:
    (n + 4,) bool. Returns the scale s* in [0, 1] of the torque realised (1: attained) and
    writes nothing but ``u_out`` and the scratch.
    """
    n = arms.shape[1]
    n_cols = n + 1 + N_ROWS
    a = work[0:3]
    lower, upper, cost, x, rhs = work[3], work[4], work[5], work[6], work[7]
    binv = work[8:11, 0:3]
    w = work[8, 3:6]
    for j in range(n_cols):
        for i in range(N_ROWS):
            a[i, j] = 0.0
        lower[j] = 0.0
        upper[j] = 0.0
        cost[j] = 0.0
        x[j] = 0.0
        in_basis[j] = False
    for j in range(n):
        for i in range(N_ROWS):
            a[i, j] = arms[i, j]
        upper[j] = u_max[j]
    s = n
    for i in range(N_ROWS):
        a[i, s] = -torque[i]
        a[i, n + 1 + i] = 1.0  # artificials, fixed at zero
        basis[i] = n + 1 + i
        in_basis[n + 1 + i] = True
        rhs[i] = 0.0
    upper[s] = 1.0
    # phase A: the largest attainable share of the torque
    cost[s] = -1.0
    _simplex(a, lower, upper, cost, x, basis, in_basis, binv, w)
    scale = elementary.smaller(elementary.larger(x[s], 0.0), 1.0)
    # phase B: that share with the least propellant
    lower[s] = scale
    upper[s] = scale
    x[s] = scale
    cost[s] = 0.0
    for j in range(n):
        cost[j] = 1.0
    _simplex(a, lower, upper, cost, x, basis, in_basis, binv, w)
    if _invert_basis(a, basis, binv):
        _refine(a, basis, binv, x, rhs)
    for j in range(n):
        u = x[j]
        u_out[j] = 0.0 if u < 0.0 else (u_max[j] if u > u_max[j] else u)
    return scale


def scratch_shape(n_thrusters):
    """Shape of ``allocate``'s float scratch."""
    return (N_ROWS + 8, max(work_columns(n_thrusters), 6))


# --- actuation lp_pwm: the LP allocation family's flight step ----------------------------------


class Optimiser(NamedTuple):
    """LP allocation and its pulse-width modulation (actuation lp_pwm, core.lp_allocation)."""

    arms: np.ndarray  # (3, n) torque arms the flight software knows: nominal geometry and CoM
    u: np.ndarray  # thrust per thruster (N)
    u_max: np.ndarray  # the flight software's thrust per thruster at the level flown (N)
    scratch: np.ndarray  # lp_allocation.scratch_shape
    basis: np.ndarray  # (3,) int64
    in_basis: np.ndarray  # bool


@jit
def optimiser(n_thrusters):
    """The lp_pwm family's work arrays, allocated."""
    _, fa, ia, ba = carve_optimiser(n_thrusters, np.zeros(0), 0, np.zeros(0, np.int64), 0, np.zeros(0, np.bool_), 0)
    f, i, b = np.zeros(fa), np.zeros(ia, np.int64), np.zeros(ba, np.bool_)
    return carve_optimiser(n_thrusters, f, 0, i, 0, b, 0)[0]


@jit
def carve_optimiser(n_thrusters, f, fa, i, ia, b, ba):
    """The lp_pwm family's work as views of ``f``, ``i``, ``b`` from ``fa``, ``ia``, ``ba`` (core.arena):
    (Optimiser, the cursors after); scratch as :func:`scratch_shape`, written out: a Python function
    cannot run here."""
    arms, fa = arena.matrix(f, fa, 3, n_thrusters)
    u, fa = arena.vector(f, fa, n_thrusters)
    u_max, fa = arena.vector(f, fa, n_thrusters)
    scratch, fa = arena.matrix(f, fa, N_ROWS + 8, max(n_thrusters + 1 + N_ROWS, 6))
    basis, ia = arena.vector(i, ia, N_ROWS)
    in_basis, ba = arena.vector(b, ba, n_thrusters + 1 + N_ROWS)
    return Optimiser(arms, u, u_max, scratch, basis, in_basis), fa, ia, ba


@jit_noalloc
def pulse_width(fsw, levels, thrusters, act, opt, masks, t, level, active, pulse_counts):
    """LP allocation of the commanded torque (004 eq. 2-5), each thruster realised as one pulse
    from the start of the control period: open at ``t``, closed after its on-time
    (``allocation.pwm_on_time``; saturated thrusters stay open into the next period)."""
    n = thrusters.shape[0]
    dt = fsw[F_CONTROL_PERIOD]
    if active:
        design = levels[level, LV_THRUST_DESIGN]
        for i in range(n):
            opt.u_max[i] = design
        allocate(opt.arms, opt.u_max, act.torque_cmd, opt.u, opt.scratch, opt.basis, opt.in_basis)
    for i in range(3):
        act.pulse[i] = 0.0
    was_open = masks[MASK_OPEN]
    now_open = 0
    touched = 0
    for i in range(n):
        on = allocation.pwm_on_time(opt.u[i], opt.u_max[i], dt, fsw[F_MIN_ON]) if active else 0.0
        bit = 1 << i
        if on > 0.0:
            if was_open & bit == 0:
                rcs.command(act.valve_state, thrusters, i, True, t, level)
                pulse_counts[i] += 1
            if on < dt - 1e-12:
                rcs.command(act.valve_state, thrusters, i, False, t + on, level)
            else:
                now_open |= bit
            touched |= bit
        elif was_open & bit != 0:
            rcs.command(act.valve_state, thrusters, i, False, t, level)
            touched |= bit
    masks[MASK_OPEN] = now_open
    masks[MASK_ACTIVE] |= touched
