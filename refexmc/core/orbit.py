"""Orbit translation with a main engine, the entry interface and gravity gradient (004 sec. III).

The ``orbit`` trajectory model: a point mass in the Earth-centred inertial frame (ECI, z along
the Earth's spin axis, x at the Greenwich meridian at t = 0) under two-body gravity and the
thrust of a constant-thrust main engine. State ``[r (3), v (3), m]`` (m, m/s, kg). The attitude
and the translation are coupled only through the thrust direction, as 004's 3+3 DOF: over one
control period the thrust direction follows the body from its start to its end attitude.
The Earth is a sphere turning at a constant rate; entry-state angles are geocentric.
"""

import math

from refexmc._jit import jit_noalloc
from refexmc.core import elementary

ORBIT_STATE_SIZE = 7
G0 = 9.80665  # standard gravity for the specific impulse (m/s^2)


@jit_noalloc
def derivative(state, mu, thrust, mass_flow, dx, dy, dz, out):
    """d/dt of ``state`` with thrust ``thrust`` (N) along the unit vector (dx, dy, dz)."""
    rx, ry, rz = state[0], state[1], state[2]
    r2 = rx * rx + ry * ry + rz * rz
    g = -mu / (r2 * math.sqrt(r2))
    a = thrust / state[6]
    out[0] = state[3]
    out[1] = state[4]
    out[2] = state[5]
    out[3] = g * rx + a * dx
    out[4] = g * ry + a * dy
    out[5] = g * rz + a * dz
    out[6] = -mass_flow


@jit_noalloc
def _direction_at(d0, d1, f, out):
    """Unit vector along ``d0 + (d1 - d0) f`` (the thrust direction a fraction ``f`` into a step)."""
    x = d0[0] + (d1[0] - d0[0]) * f
    y = d0[1] + (d1[1] - d0[1]) * f
    z = d0[2] + (d1[2] - d0[2]) * f
    n = math.sqrt(x * x + y * y + z * z)
    out[0] = x / n
    out[1] = y / n
    out[2] = z / n


@jit_noalloc
def rk4_step(state, h, mu, thrust, mass_flow, d0, d1, f0, f1, stage):
    """One RK4 step of ``h`` seconds in place; the thrust direction is ``d0 -> d1`` interpolated
    over fractions ``f0 -> f1`` of the control period. ``stage`` is (6, 7) scratch; row 5 holds
    the direction."""
    k1, k2, k3, k4, tmp, d = stage[0], stage[1], stage[2], stage[3], stage[4], stage[5]
    n = ORBIT_STATE_SIZE
    _direction_at(d0, d1, f0, d)
    derivative(state, mu, thrust, mass_flow, d[0], d[1], d[2], k1)
    for i in range(n):
        tmp[i] = state[i] + 0.5 * h * k1[i]
    _direction_at(d0, d1, 0.5 * (f0 + f1), d)
    derivative(tmp, mu, thrust, mass_flow, d[0], d[1], d[2], k2)
    for i in range(n):
        tmp[i] = state[i] + 0.5 * h * k2[i]
    derivative(tmp, mu, thrust, mass_flow, d[0], d[1], d[2], k3)
    for i in range(n):
        tmp[i] = state[i] + h * k3[i]
    _direction_at(d0, d1, f1, d)
    derivative(tmp, mu, thrust, mass_flow, d[0], d[1], d[2], k4)
    for i in range(n):
        state[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])


@jit_noalloc
def radius(state):
    return math.sqrt(state[0] * state[0] + state[1] * state[1] + state[2] * state[2])


@jit_noalloc
def climb_rate(state):
    """Rate of change of the radius (m/s)."""
    return (state[0] * state[3] + state[1] * state[4] + state[2] * state[5]) / radius(state)


@jit_noalloc
def coast(state, h, mu, stage):
    """One thrust-free RK4 step of ``h`` seconds in place (``stage``: (6, 7) scratch)."""
    d = stage[5]
    d[0], d[1], d[2] = 1.0, 0.0, 0.0
    rk4_step(state, h, mu, 0.0, 0.0, d, d, 0.0, 0.0, stage)


@jit_noalloc
def coast_to_radius(start, r_target, h_guess, mu, stage, out):
    """Time (s) from ``start`` until the radius is ``r_target`` while coasting, by Newton steps
    on RK4 propagations from ``start`` (``h_guess``: a first guess); ``out`` (not ``start``)
    receives the state there. Converges to below 1e-6 m in radius."""
    h = h_guess
    for _ in range(20):
        for i in range(ORBIT_STATE_SIZE):
            out[i] = start[i]
        if h != 0.0:
            coast(out, h, mu, stage)
        miss = radius(out) - r_target
        if abs(miss) < 1e-6:
            break
        h -= miss / climb_rate(out)
    return h


@jit_noalloc
def entry_state(state, t, earth_rate, out):
    """Earth-relative entry state at time ``t``: geocentric longitude (deg E, -180..180),
    latitude (deg N), speed (m/s), flight-path angle (deg) and heading (deg from north,
    clockwise, 0..360), into ``out[0:5]`` (the Earth turned ``earth_rate * t`` since t = 0)."""
    angle = earth_rate * t
    s, c = elementary.sincos(angle)
    rx, ry, rz = state[0], state[1], state[2]
    # relative velocity v - w x r, w = (0, 0, earth_rate); then both into the Earth-fixed frame
    vx = state[3] + earth_rate * ry
    vy = state[4] - earth_rate * rx
    vz = state[5]
    x, y = c * rx + s * ry, -s * rx + c * ry
    u, w = c * vx + s * vy, -s * vx + c * vy
    r = math.sqrt(x * x + y * y + rz * rz)
    longitude = elementary.atan2(y, x)
    latitude = elementary.asin(rz / r)
    speed = math.sqrt(u * u + w * w + vz * vz)
    # local up, east, north
    sl, cl = elementary.sincos(longitude)
    sp, cp = elementary.sincos(latitude)
    up = u * cp * cl + w * cp * sl + vz * sp
    east = -u * sl + w * cl
    north = -u * sp * cl - w * sp * sl + vz * cp
    out[0] = math.degrees(longitude)
    out[1] = math.degrees(latitude)
    out[2] = speed
    out[3] = math.degrees(elementary.atan2(up, math.sqrt(east * east + north * north)))  # asin(up / speed) can NaN
    heading = math.degrees(elementary.atan2(east, north))
    out[4] = heading + 360.0 if heading < 0.0 else heading


@jit_noalloc
def gravity_gradient_torque(r_body, mu, inertia, out):
    """Gravity-gradient torque 3 mu / r^3 (r_hat x J r_hat) (N m); ``r_body``: position in body axes."""
    r2 = r_body[0] * r_body[0] + r_body[1] * r_body[1] + r_body[2] * r_body[2]
    r = math.sqrt(r2)
    k = 3.0 * mu / (r2 * r2 * r)  # 3 mu / r^5: r_body is not normalised
    jx = inertia[0, 0] * r_body[0] + inertia[0, 1] * r_body[1] + inertia[0, 2] * r_body[2]
    jy = inertia[1, 0] * r_body[0] + inertia[1, 1] * r_body[1] + inertia[1, 2] * r_body[2]
    jz = inertia[2, 0] * r_body[0] + inertia[2, 1] * r_body[1] + inertia[2, 2] * r_body[2]
    out[0] = k * (r_body[1] * jz - r_body[2] * jy)
    out[1] = k * (r_body[2] * jx - r_body[0] * jz)
    out[2] = k * (r_body[0] * jy - r_body[1] * jx)
