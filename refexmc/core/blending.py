"""Propellant-minimal blending of thrusters with aerodynamic surfaces (003 eq. 5-10).

Each control period chooses the surface deflections d = (left flap, right flap, rudder) and
thruster moments t (3) so that surfaces and thrusters together give the commanded moment, with
the least thruster propellant rate (003 eq. 5):

    minimise  sum_i w_i |t_i|       w_i = b_th K_i (kg/s per N m)
    subject to  t = tau_c - (B d + offset),   lower <= d <= upper

B d + offset is the surfaces' moment (003 eq. 6, 10; :func:`surface_moments`): the flaps act
through elevon delta_e = (left + right) / 2 and aileron delta_a = (left - right) / 2. A flap
blocked at delta_block has lower = upper = delta_block, which gives 003 eq. 7 (delta_a =
delta_e - delta_block for the right flap blocked); with both flaps free the same program blends
elevon, aileron and rudder. As an LP in the 3-row standard form of core.lp_allocation's bounded
simplex:

    B d + t_plus - t_minus = tau_c - offset,   t_plus, t_minus >= 0,   lower <= d <= upper

with costs w_i on t_plus_i and t_minus_i and none on d (free bounded variables). The surfaces
start at their lower bounds and the thruster parts absorb the rest: a feasible first basis with
no artificials. The thruster moments are not bounded here: what the thrusters cannot give is
their own allocation's saturation (003 bounds the surfaces only). A surface that may not move (a
blocked flap, a rudder above Mach 6 or on a vehicle without rudders) has lower = upper: it never
enters the basis.
"""

from refexmc._jit import jit_noalloc
from refexmc.core.lp_allocation import _invert_basis, _refine, _simplex

N_SURFACE_VARIABLES = 3  # 0: left flap, 1: right flap, 2: rudders (deflected together)
SURFACE_LEFT_FLAP, SURFACE_RIGHT_FLAP, SURFACE_RUDDER = 0, 1, 2
BLEND_COLUMNS = N_SURFACE_VARIABLES + 6  # then t_plus (l, m, n), t_minus (l, m, n)
THRUSTER_MOMENT_BOUND = 1e30  # N m: no bound (documented above); finite so that no step is inf


def scratch_shape():
    """Shape of :func:`blend`'s float scratch."""
    return (11, BLEND_COLUMNS)


@jit_noalloc
def surface_moments(
    qbar_s_l, roll_aileron, pitch_elevon, yaw_aileron, roll_rudder, yaw_rudder, trim, effectiveness, offset
):
    """Write B (3 x 3, N m/rad) and offset (3, N m) of the surfaces' moment B d + offset for d =
    (left flap, right flap, rudder) (003 eq. 6, 10): delta_e = (left + right) / 2, delta_a =
    (left - right) / 2, pitch through delta_e - ``trim`` (eq. 6). Derivatives per rad of
    delta_a, delta_e, delta_r; ``qbar_s_l`` = q S L."""
    effectiveness[0, 0] = 0.5 * qbar_s_l * roll_aileron
    effectiveness[1, 0] = 0.5 * qbar_s_l * pitch_elevon
    effectiveness[2, 0] = 0.5 * qbar_s_l * yaw_aileron
    effectiveness[0, 1] = -0.5 * qbar_s_l * roll_aileron
    effectiveness[1, 1] = 0.5 * qbar_s_l * pitch_elevon
    effectiveness[2, 1] = -0.5 * qbar_s_l * yaw_aileron
    effectiveness[0, 2] = qbar_s_l * roll_rudder
    effectiveness[1, 2] = 0.0
    effectiveness[2, 2] = qbar_s_l * yaw_rudder
    offset[0] = 0.0
    offset[1] = -qbar_s_l * pitch_elevon * trim
    offset[2] = 0.0


@jit_noalloc
def blend(effectiveness, offset, torque, lower, upper, weights, deflection, thruster_torque, work, basis, in_basis):
    """Surface deflections ``deflection`` (3, rad) and thruster moments ``thruster_torque`` (3, N m)
    realising ``torque`` (N m) with the least propellant rate sum w_i |t_i|, which it returns
    (kg/s for w in kg/s per N m). ``work``: :func:`scratch_shape` floats; ``basis``: (3,) int64;
    ``in_basis``: (BLEND_COLUMNS,) bool."""
    n = BLEND_COLUMNS
    a = work[0:3]
    low, high, cost, x, rhs = work[3], work[4], work[5], work[6], work[7]
    binv = work[8:11, 0:3]
    w = work[8, 3:6]
    for j in range(n):
        in_basis[j] = False
    for j in range(N_SURFACE_VARIABLES):
        for i in range(3):
            a[i, j] = effectiveness[i, j]
        low[j] = lower[j]
        high[j] = upper[j] if upper[j] > lower[j] else lower[j]
        cost[j] = 0.0
        x[j] = low[j]
    for i in range(3):
        plus = N_SURFACE_VARIABLES + i
        minus = N_SURFACE_VARIABLES + 3 + i
        for k in range(3):
            a[k, plus] = 1.0 if k == i else 0.0
            a[k, minus] = -1.0 if k == i else 0.0
        low[plus] = 0.0
        low[minus] = 0.0
        high[plus] = THRUSTER_MOMENT_BOUND
        high[minus] = THRUSTER_MOMENT_BOUND
        cost[plus] = weights[i]
        cost[minus] = weights[i]
        rhs[i] = torque[i] - offset[i]
        residual = rhs[i]
        for j in range(N_SURFACE_VARIABLES):
            residual -= effectiveness[i, j] * x[j]
        if residual >= 0.0:
            x[plus], x[minus] = residual, 0.0
            basis[i] = plus
        else:
            x[plus], x[minus] = 0.0, -residual
            basis[i] = minus
        in_basis[basis[i]] = True
    _simplex(a, low, high, cost, x, basis, in_basis, binv, w)
    if _invert_basis(a, basis, binv):
        _refine(a, basis, binv, x, rhs)
    rate = 0.0
    for j in range(N_SURFACE_VARIABLES):
        d = x[j]
        deflection[j] = low[j] if d < low[j] else (high[j] if d > high[j] else d)
    for i in range(3):
        t = rhs[i]
        for j in range(N_SURFACE_VARIABLES):
            t -= effectiveness[i, j] * deflection[j]
        thruster_torque[i] = t
        rate += weights[i] * abs(t)
    return rate
