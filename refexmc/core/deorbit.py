"""Deorbit burn guidance (004 sec. III): steering toward a precomputed nominal burn.

The flight software holds the nominal burn as a table (``layout.NOMINAL`` rows at the guidance
period, from ignition to cut-off). Every guidance period it measures position and velocity
(GPS: truth + bias + white noise) and commands the thrust direction

    a_cmd = a_nom(t) - k_r (r_gps - r_nom(t)) - k_v (v_gps - v_nom(t)),   d_cmd = a_cmd / |a_cmd|,

the PD law on the position and velocity errors of 004 sec. III added to the nominal thrust
acceleration (the engine's thrust is constant, so only the direction is steered; the gains weigh
position against velocity error). Two open-loop laws fly the same plan without feedback
(``steer``'s ``law``: along -v_gps, or along the plan's own thrust direction) for the readings of
004 Table 2 in docs/spore.md. The attitude reference puts the engine's nominal axis along
``d_cmd`` with a second body axis toward the orbit normal. The nominal burn itself is flown here
too (:func:`nominal_burn`), either opposite to the velocity or along the fixed "Hohmann
direction" (tangential, opposite to the velocity at ignition, fixed in inertial space), 004 Fig. 7.
"""

import math

from refexmc._jit import jit_noalloc
from refexmc.core import orbit, quaternion, rng
from refexmc.core.layout import (
    GUIDANCE_LAW_OPEN_LOOP_RETROGRADE,
    GUIDANCE_LAW_PD,
    N_GPS_POSITION_BIAS,
    N_GPS_POSITION_NOISE,
    N_GPS_VELOCITY_BIAS,
    N_GPS_VELOCITY_NOISE,
    NM_POSITION,
    NM_T,
    NM_THRUST_ACCEL,
    NM_VELOCITY,
    NOMINAL_SIZE,
)

APPROACH_OPPOSITE_VELOCITY = 0  # thrust along -v throughout (flight-path angle loss free)
APPROACH_HOHMANN_DIRECTION = 1  # thrust along the ignition's -v_horizontal, fixed inertial
APPROACHES = {"opposite_velocity": APPROACH_OPPOSITE_VELOCITY, "hohmann_direction": APPROACH_HOHMANN_DIRECTION}


@jit_noalloc
def nominal_at(table, t, out):
    """The nominal row at ``t`` (linear between rows, held beyond the ends) into ``out``."""
    n = table.shape[0]
    spacing = table[1, NM_T] - table[0, NM_T] if n > 1 else 1.0
    x = (t - table[0, NM_T]) / spacing
    if x <= 0.0 or n == 1:
        k, f = 0, 0.0
    elif x >= n - 1:
        k, f = n - 2, 1.0
    else:
        k = int(x)
        f = x - k
    for i in range(NOMINAL_SIZE):
        out[i] = table[k, i] + (table[k + 1, i] - table[k, i]) * f if n > 1 else table[0, i]


@jit_noalloc
def measure(state, nav, rng_state, out):
    """GPS position and velocity (``out[0:6]``): truth + bias + white noise per axis."""
    sigma_r = nav[N_GPS_POSITION_NOISE]
    sigma_v = nav[N_GPS_VELOCITY_NOISE]
    for i in range(3):
        out[i] = state[i] + nav[N_GPS_POSITION_BIAS + i]
        out[3 + i] = state[3 + i] + nav[N_GPS_VELOCITY_BIAS + i]
        if sigma_r > 0.0:
            out[i] += sigma_r * rng.next_normal(rng_state)
        if sigma_v > 0.0:
            out[3 + i] += sigma_v * rng.next_normal(rng_state)


@jit_noalloc
def steer(measured, nominal, law, position_gain, velocity_gain, out):
    """Commanded thrust direction (unit, inertial) of guidance law ``law`` (layout.GUIDANCE_LAW_*)
    from the measured state and the nominal row:

    - ``GUIDANCE_LAW_PD``: a_nom - k_r (r_gps - r_nom) - k_v (v_gps - v_nom), 004 sec. III;
    - ``GUIDANCE_LAW_OPEN_LOOP_RETROGRADE``: -v_gps, 004 sec. III's "opposite to velocity thrusting"
      flown without the nominal (the burn time stays the plan's);
    - ``GUIDANCE_LAW_OPEN_LOOP_PLANNED``: the plan's own thrust direction at t, no feedback (with
      the ``hohmann_direction`` approach the fixed inertial "Hohmann direction thrusting").
    """
    if law == GUIDANCE_LAW_OPEN_LOOP_RETROGRADE:
        for i in range(3):
            out[i] = -measured[3 + i]
    elif law == GUIDANCE_LAW_PD:
        for i in range(3):
            out[i] = (
                nominal[NM_THRUST_ACCEL + i]
                - position_gain * (measured[i] - nominal[NM_POSITION + i])
                - velocity_gain * (measured[3 + i] - nominal[NM_VELOCITY + i])
            )
    else:
        for i in range(3):
            out[i] = nominal[NM_THRUST_ACCEL + i]
    n = math.sqrt(out[0] * out[0] + out[1] * out[1] + out[2] * out[2])
    for i in range(3):
        out[i] /= n


@jit_noalloc
def _unit_cross(a, b, out):
    x = a[1] * b[2] - a[2] * b[1]
    y = a[2] * b[0] - a[0] * b[2]
    z = a[0] * b[1] - a[1] * b[0]
    n = math.sqrt(x * x + y * y + z * z)
    out[0], out[1], out[2] = x / n, y / n, z / n


@jit_noalloc
def thrust_attitude(direction, position, velocity, engine_axis, q_out, work):
    """Body-to-inertial attitude that puts ``engine_axis`` (unit, body) along ``direction`` (unit,
    inertial), the body axis nearest the engine's perpendicular toward the orbit normal
    ``r x v``. ``work`` is (9, 3) scratch."""
    a2, a3, b2, b3, normal, e = work[0], work[1], work[2], work[3], work[4], work[5]
    _unit_cross(position, velocity, normal)
    _unit_cross(normal, direction, a3)  # a3 = n x d; a2 = d x a3: n's part perpendicular to d
    _unit_cross(direction, a3, a2)
    k = 0  # body: the axis least aligned with the engine axis, made perpendicular to it
    for i in range(1, 3):
        if abs(engine_axis[i]) < abs(engine_axis[k]):
            k = i
    for i in range(3):
        e[i] = 1.0 if i == k else 0.0
    _unit_cross(e, engine_axis, b3)
    _unit_cross(engine_axis, b3, b2)
    # R = A B^T with A = [d a2 a3], B = [e b2 b3]: column j (body axis j in inertial) into work[6 + j]
    for j in range(3):
        for i in range(3):
            work[6 + j, i] = direction[i] * engine_axis[j] + a2[i] * b2[j] + a3[i] * b3[j]
    quaternion.from_axes(work[6], work[7], work[8], q_out)


@jit_noalloc
def _nominal_derivative(state, mu, thrust, mass_flow, approach, fixed, out):
    if approach == APPROACH_OPPOSITE_VELOCITY:
        v = math.sqrt(state[3] * state[3] + state[4] * state[4] + state[5] * state[5])
        orbit.derivative(state, mu, thrust, mass_flow, -state[3] / v, -state[4] / v, -state[5] / v, out)
    else:
        orbit.derivative(state, mu, thrust, mass_flow, fixed[0], fixed[1], fixed[2], out)


@jit_noalloc
def hohmann_direction(state, out):
    """Unit vector opposite to the horizontal part of the velocity (the impulsive Hohmann burn)."""
    r = orbit.radius(state)
    radial = (state[0] * state[3] + state[1] * state[4] + state[2] * state[5]) / r
    for i in range(3):
        out[i] = -(state[3 + i] - radial * state[i] / r)
    n = math.sqrt(out[0] * out[0] + out[1] * out[1] + out[2] * out[2])
    for i in range(3):
        out[i] /= n


@jit_noalloc
def nominal_burn(state, t_ignition, duration, thrust, mass_flow, approach, mu, step, table, stage):
    """Fly the nominal burn from ``state`` (at ignition, in place: at cut-off on return) and fill
    ``table`` (rows at ``duration / (rows - 1)``, the guidance period); RK4 steps of at most
    ``step`` seconds between rows. ``stage`` is (6, 7) scratch."""
    k1, k2, k3, k4, tmp, fixed = stage[0], stage[1], stage[2], stage[3], stage[4], stage[5]
    hohmann_direction(state, fixed)
    rows = table.shape[0]
    spacing = duration / (rows - 1)
    n_sub = max(1, int(math.ceil(spacing / step - 1e-9)))
    h = spacing / n_sub
    n = orbit.ORBIT_STATE_SIZE
    for row in range(rows):
        _nominal_derivative(state, mu, thrust, mass_flow, approach, fixed, k1)
        table[row, NM_T] = t_ignition + row * spacing
        for i in range(3):
            table[row, NM_POSITION + i] = state[i]
            table[row, NM_VELOCITY + i] = state[3 + i]
            table[row, NM_THRUST_ACCEL + i] = k1[3 + i] + _gravity(state, mu, i)
        if row == rows - 1:
            break
        for _ in range(n_sub):
            _nominal_derivative(state, mu, thrust, mass_flow, approach, fixed, k1)
            for i in range(n):
                tmp[i] = state[i] + 0.5 * h * k1[i]
            _nominal_derivative(tmp, mu, thrust, mass_flow, approach, fixed, k2)
            for i in range(n):
                tmp[i] = state[i] + 0.5 * h * k2[i]
            _nominal_derivative(tmp, mu, thrust, mass_flow, approach, fixed, k3)
            for i in range(n):
                tmp[i] = state[i] + h * k3[i]
            _nominal_derivative(tmp, mu, thrust, mass_flow, approach, fixed, k4)
            for i in range(n):
                state[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])


@jit_noalloc
def _gravity(state, mu, i):
    """Component ``i`` of the gravitational acceleration (its negative is added back above)."""
    r = orbit.radius(state)
    return mu * state[i] / (r * r * r)


@jit_noalloc
def coast_to_entry(state, r_entry, mu, step, max_time, stage, prev, out):
    """Coast from ``state`` until the radius falls to ``r_entry``: the time it takes (NaN if not
    within ``max_time``), the state there in ``out``. RK4 steps of ``step`` seconds, the last
    one found by :func:`orbit.coast_to_radius`; ``prev`` is a state-sized scratch."""
    n = orbit.ORBIT_STATE_SIZE
    t = 0.0
    for i in range(n):
        out[i] = state[i]
    while t < max_time:
        for i in range(n):
            prev[i] = out[i]
        orbit.coast(out, step, mu, stage)
        if orbit.radius(out) < r_entry and orbit.climb_rate(out) < 0.0:
            t_cross = t + orbit.coast_to_radius(prev, r_entry, 0.5 * step, mu, stage, out)
            return t_cross if t_cross <= max_time else math.nan
        t += step
    return math.nan
