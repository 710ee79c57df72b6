"""The orbit trajectory family's flight steps (trajectory ``orbit``, 004 sec. III).

The run loop (core.flight) takes these steps when it flies the orbit trajectory: at the start
:func:`start`; in a burn mode, every control period, :func:`steer` (core.deorbit at the guidance
rate); before the attitude is integrated, :func:`engine_period` (the engine's on-time and the
disturbance torque); after it, :func:`translate` (core.orbit over the same period, the thrust
direction following the body). :class:`Orbit` holds their work arrays, :func:`work` allocates
them; no other family's kernel compiles this module's functions (docs/families.md).
"""

import math
from typing import NamedTuple

import numpy as np

from refexmc._jit import jit, jit_noalloc
from refexmc.core import arena, deorbit, elementary, orbit, quaternion
from refexmc.core.layout import (
    F_ENGINE_AXIS,
    F_GUIDANCE_LAW,
    F_GUIDANCE_PERIOD,
    F_GUIDANCE_POSITION_GAIN,
    F_GUIDANCE_VELOCITY_GAIN,
    M_BURN_DURATION,
    M_BURN_START,
    M_EARTH_MU,
    M_EARTH_RADIUS,
    M_EARTH_RATE,
    M_ENTRY_ALTITUDE,
    M_ORBIT_STATE,
    NOMINAL_SIZE,
    S_BURN_POINTING_MAX,
    S_BURN_POINTING_RMS,
    S_ENTRY,
    S_ENTRY_TIME,
    V_COM_OFFSET,
    V_ENGINE_DIRECTION,
    V_ENGINE_ISP,
    V_ENGINE_POSITION,
    V_ENGINE_PROPELLANT,
    V_ENGINE_THRUST,
    V_MASS,
)
from refexmc.core.status import (
    ST_ENGINE_OFF,
    ST_ENGINE_ON,
    ST_ENTERED,
    ST_GUIDANCE_TICK,
    ST_POINTING_COUNT,
    ST_POINTING_MAX,
    ST_POINTING_SUM2,
)


class Orbit(NamedTuple):
    """The orbit trajectory (core.orbit) and the deorbit burn guidance (core.deorbit)."""

    state: np.ndarray  # [r, v, m], ECI
    prev: np.ndarray  # the state at the start of the control period
    stage: np.ndarray  # (6, 7) RK4 scratch
    measured: np.ndarray  # GPS position and velocity at the last guidance step
    nominal: np.ndarray  # the nominal row then
    command: np.ndarray  # commanded thrust direction (unit, ECI)
    thrust_dirs: np.ndarray  # (2, 3) true thrust direction at the period's start and end (ECI)
    torque: np.ndarray  # gravity-gradient + engine torque over the period (body, N m)
    crossing: np.ndarray  # the state at the entry interface
    work: np.ndarray  # (9, 3) scratch


@jit
def work():
    """The orbit family's work arrays, allocated."""
    size = carve_work(np.zeros(0), 0)[1]
    return carve_work(np.zeros(size), 0)[0]


@jit
def carve_work(f, at):
    """The orbit family's work as views of ``f`` from ``at`` (core.arena): (Orbit, cursor after)."""
    n = orbit.ORBIT_STATE_SIZE
    state, at = arena.vector(f, at, n)
    start, at = arena.vector(f, at, n)
    stage, at = arena.matrix(f, at, 6, n)
    measured, at = arena.vector(f, at, 6)
    nominal, at = arena.vector(f, at, NOMINAL_SIZE)
    command, at = arena.vector(f, at, 3)
    thrust_dirs, at = arena.matrix(f, at, 2, 3)
    torque, at = arena.vector(f, at, 3)
    crossing, at = arena.vector(f, at, n)
    work, at = arena.matrix(f, at, 9, 3)
    return Orbit(state, start, stage, measured, nominal, command, thrust_dirs, torque, crossing, work), at


@jit_noalloc
def start(mission, vehicle, orb, status, summary):
    """Orbit state at t = 0 (mass: the vehicle's, main-engine propellant included); outputs NaN."""
    for i in range(6):
        orb.state[i] = mission[M_ORBIT_STATE + i]
    orb.state[6] = vehicle[V_MASS]
    status[ST_GUIDANCE_TICK] = -math.inf
    for i in range(5):
        summary[S_ENTRY + i] = math.nan
    summary[S_ENTRY_TIME] = math.nan
    summary[S_BURN_POINTING_RMS] = math.nan
    summary[S_BURN_POINTING_MAX] = math.nan


@jit_noalloc
def thrust_direction(vehicle, q, out):
    """The engine's true force direction in ECI at attitude ``q``."""
    quaternion.rotate(q, vehicle[V_ENGINE_DIRECTION : V_ENGINE_DIRECTION + 3], out)


@jit_noalloc
def steer(nominal, fsw, nav, vehicle, x, orb, guide, rng_state, status, t, burning):
    """Burn guidance every guidance period (core.deorbit): GPS, the nominal row, the commanded
    direction and the attitude that points the engine's nominal axis along it (the mode's target
    and reference). While the engine fires, the angle between its true force and the commanded
    direction is accumulated (004 Fig. 5)."""
    if t >= status[ST_GUIDANCE_TICK] + fsw[F_GUIDANCE_PERIOD] - 1e-9:
        status[ST_GUIDANCE_TICK] = t
        deorbit.measure(orb.state, nav, rng_state, orb.measured)
        deorbit.nominal_at(nominal, t, orb.nominal)
        deorbit.steer(
            orb.measured,
            orb.nominal,
            int(fsw[F_GUIDANCE_LAW]),
            fsw[F_GUIDANCE_POSITION_GAIN],
            fsw[F_GUIDANCE_VELOCITY_GAIN],
            orb.command,
        )
        deorbit.thrust_attitude(
            orb.command,
            orb.measured[0:3],
            orb.measured[3:6],
            fsw[F_ENGINE_AXIS : F_ENGINE_AXIS + 3],
            guide.q_final,
            orb.work,
        )
        for i in range(4):
            guide.q_ref[i] = guide.q_final[i]
    if burning:
        d = orb.work[0]
        thrust_direction(vehicle, x[0:4], d)
        c = d[0] * orb.command[0] + d[1] * orb.command[1] + d[2] * orb.command[2]
        angle = elementary.acos(elementary.larger(-1.0, elementary.smaller(1.0, c)))
        status[ST_POINTING_SUM2] += angle * angle
        status[ST_POINTING_COUNT] += 1.0
        status[ST_POINTING_MAX] = elementary.larger(status[ST_POINTING_MAX], angle)


@jit_noalloc
def engine_period(mission, vehicle, inertia, x, orb, status, t, dt, burn_mode):
    """Before the attitude is integrated over ``[t, t + dt]``: the engine's on-time in it (the
    burn mode, the planned ignition and cut-off, the propellant left), the true thrust direction
    at its start, and the disturbance torque over it (gravity gradient at its start, engine torque
    times the fraction of the period it fires)."""
    on, off = t, t
    if burn_mode:
        mass_flow = vehicle[V_ENGINE_THRUST] / (vehicle[V_ENGINE_ISP] * orbit.G0)
        left = vehicle[V_ENGINE_PROPELLANT] - (vehicle[V_MASS] - orb.state[6])
        on = elementary.larger(t, mission[M_BURN_START])
        off = elementary.smaller(
            elementary.smaller(t + dt, mission[M_BURN_START] + mission[M_BURN_DURATION]), t + left / mass_flow
        )
        if off < on:
            off = on
    status[ST_ENGINE_ON] = on
    status[ST_ENGINE_OFF] = off
    thrust_direction(vehicle, x[0:4], orb.thrust_dirs[0])
    r_body = orb.work[0]
    quaternion.rotate_inverse(x[0:4], orb.state[0:3], r_body)
    orbit.gravity_gradient_torque(r_body, mission[M_EARTH_MU], inertia, orb.torque)
    if off > on:
        force = vehicle[V_ENGINE_THRUST] * (off - on) / dt  # mean over the period
        arm = orb.work[1]
        for i in range(3):
            arm[i] = vehicle[V_ENGINE_POSITION + i] - vehicle[V_COM_OFFSET + i]
        e = vehicle[V_ENGINE_DIRECTION : V_ENGINE_DIRECTION + 3]
        orb.torque[0] += force * (arm[1] * e[2] - arm[2] * e[1])
        orb.torque[1] += force * (arm[2] * e[0] - arm[0] * e[2])
        orb.torque[2] += force * (arm[0] * e[1] - arm[1] * e[0])


@jit_noalloc
def translate(mission, vehicle, x, orb, status, summary, t, dt):
    """Integrate the orbit over ``[t, t + dt]`` after the attitude: coast / engine / coast
    segments, the thrust direction following the body from the period's start to its end (004's
    3+3 DOF); record the entry state where the radius first falls through the entry interface."""
    thrust_direction(vehicle, x[0:4], orb.thrust_dirs[1])
    for i in range(orbit.ORBIT_STATE_SIZE):
        orb.prev[i] = orb.state[i]
    mu = mission[M_EARTH_MU]
    on, off = status[ST_ENGINE_ON], status[ST_ENGINE_OFF]
    thrust = vehicle[V_ENGINE_THRUST]
    mass_flow = thrust / (vehicle[V_ENGINE_ISP] * orbit.G0)
    d0, d1 = orb.thrust_dirs[0], orb.thrust_dirs[1]
    if off <= on:
        orbit.rk4_step(orb.state, dt, mu, 0.0, 0.0, d0, d1, 0.0, 1.0, orb.stage)
    else:
        if on > t:
            orbit.rk4_step(orb.state, on - t, mu, 0.0, 0.0, d0, d1, 0.0, (on - t) / dt, orb.stage)
        orbit.rk4_step(orb.state, off - on, mu, thrust, mass_flow, d0, d1, (on - t) / dt, (off - t) / dt, orb.stage)
        if off < t + dt:
            orbit.rk4_step(orb.state, t + dt - off, mu, 0.0, 0.0, d0, d1, (off - t) / dt, 1.0, orb.stage)
    r_entry = mission[M_EARTH_RADIUS] + mission[M_ENTRY_ALTITUDE]
    if status[ST_ENTERED] == 0.0 and orbit.radius(orb.state) < r_entry and orbit.climb_rate(orb.state) < 0.0:
        status[ST_ENTERED] = 1.0  # the crossing is coasted to from the period's start (engine off)
        h = orbit.coast_to_radius(orb.prev, r_entry, 0.5 * dt, mu, orb.stage, orb.crossing)
        summary[S_ENTRY_TIME] = t + h
        orbit.entry_state(orb.crossing, t + h, mission[M_EARTH_RATE], summary[S_ENTRY : S_ENTRY + 5])
