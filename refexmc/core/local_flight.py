"""Translation near a small body (trajectory ``local``): position and velocity in a local frame
under a uniform gravity vector, the thrusters' force through the body attitude, and the
time-optimal translation law of 002 (core.time_optimal) per body axis in ``translate`` modes.

The local frame is the attitude's inertial frame. Each control period the navigation measures
position, velocity (local frame) and tank pressure, each the truth plus white noise of the
mission's ``navigation`` sigmas (drawn from the run's navigation stream, core.rng, only where a
sigma is non-zero); the exit predicates read the measured values. The flight software takes the
measured position error (position minus the mission's target) and velocity into body axes
(measured attitude) and runs eq. 44 per axis on the scaled state of core.time_optimal.scale,
with the measured tank pressure, the design's force per pascal and
time constant per axis (config.pack: n C_F A_t and tau / n, n thrusters pushing along the axis)
and the mass the pressure implies (dry mass + P V / (R T), eq. 1): u = +1 opens the axis's '+'
thrusters, -1 its '-' ones. Inside the deadband (|e| and |v| of an axis below the
flight_software.translation deadband) the axis coasts: 002 stops its simulation on arrival, and
the sampled law, left on, chatters about the origin and spends the tank (docs/cold-gas.md).
The axes share one tank and fire at the same time; each law sees the pressure the others leave.

Within a segment (no valve breakpoint) the thrust acceleration is evaluated at its start,
midpoint and end, each the force at the tank pressure there (core.feed) over the mass there,
and taken as quadratic in between (:func:`advance`). A blow-down tank's acceleration k P L / m
changes with the time constant tau / S (the pressure), the valve ramps (L linear) and m / mdot
(the mass, much longer): the quadratic's error is of order (segment / tau)^4 of the segment's
impulse (Simpson's rule: h^4 a^(4) / 2880 per unit of a h). Both ends with a linear acceleration
would err by (segment / tau)^2 / 12: 1.2e-7 m at 002 Fig. 8's 1 ms segments on tau = 1 s.
"""

import math
from typing import NamedTuple

import numpy as np

from refexmc._jit import jit, jit_noalloc
from refexmc.core import arena, elementary, feed, quaternion, rng, time_optimal
from refexmc.core.bits import lowest_bit
from refexmc.core.layout import (
    F_TRANSLATION_DEADBAND,
    F_TRANSLATION_DRY_MASS,
    F_TRANSLATION_FORCE_PER_PA,
    F_TRANSLATION_GAS_PER_PA,
    F_TRANSLATION_LAW,
    F_TRANSLATION_MASKS,
    F_TRANSLATION_PD_GAINS,
    F_TRANSLATION_PWM_STEPS,
    F_TRANSLATION_TAU,
    H_POSITION,
    H_POSITION_ERROR,
    H_SPEED,
    H_TRANSLATION_COMMAND,
    H_VELOCITY,
    M_LOCAL_GRAVITY,
    M_LOCAL_POSITION,
    M_LOCAL_RESERVE,
    M_LOCAL_VELOCITY,
    MD_LOCAL_TARGET,
    N_LOCAL_POSITION_NOISE,
    N_LOCAL_VELOCITY_NOISE,
    N_TANK_PRESSURE_NOISE,
    S_LOCAL_POSITION_ERROR,
    S_LOCAL_SPEED,
    S_SWITCHES,
    S_TANK_PRESSURE_END,
    T_DIRECTION,
    T_SCALE,
    TRANSLATION_BANG_BANG,
    TRANSLATION_PD_PWM,
    V_MASS,
)
from refexmc.core.modes import NOW_POSITION_ERROR, NOW_SPEED
from refexmc.core.rcs import level_at

LS_GAS0 = 0  # gas in the tank at t = 0 (kg): the mass lost since is gas0 - gas
LS_U = 1  # 3: the law's last command per body axis
LS_SWITCHES = 4  # 3: command changes per body axis
LS_STEP = 7  # pd_pwm: control periods since the translate mode began
LS_PWM = 8  # 3: pd_pwm: signed control periods to fire in this modulation period
LOCAL_STATUS_SIZE = 11


class Local(NamedTuple):
    """The local trajectory's work."""

    state: np.ndarray  # [position (3), velocity (3)], local frame
    target: np.ndarray  # the target of the mode flown (MD_LOCAL_TARGET), local frame
    accel: np.ndarray  # (3, 3): thrust acceleration (m/s^2, body axes) at the segment's start, midpoint, end
    scratch: np.ndarray  # (3, 3)
    status: np.ndarray  # LS_*
    measured: np.ndarray  # what the navigation measures: [position (3), velocity (3), tank pressure]


@jit
def work():
    """Allocate the local trajectory's work."""
    size = carve_work(np.zeros(0), 0)[1]
    return carve_work(np.zeros(size), 0)[0]


@jit
def carve_work(f, at):
    """The local trajectory's work as views of ``f`` from ``at`` (core.arena): (Local, cursor after)."""
    state, at = arena.vector(f, at, 6)
    target, at = arena.vector(f, at, 3)
    accel, at = arena.matrix(f, at, 3, 3)
    scratch, at = arena.matrix(f, at, 3, 3)
    status, at = arena.vector(f, at, LOCAL_STATUS_SIZE)
    measured, at = arena.vector(f, at, 7)
    return Local(state, target, accel, scratch, status, measured), at


@jit_noalloc
def start(mission, program, loc, tank):
    """The mission's initial position and velocity, the first mode's target; the tank's initial gas."""
    for i in range(3):
        loc.state[i] = mission[M_LOCAL_POSITION + i]
        loc.state[3 + i] = mission[M_LOCAL_VELOCITY + i]
    target(program[0], loc)
    for k in range(LOCAL_STATUS_SIZE):
        loc.status[k] = 0.0
    loc.status[LS_GAS0] = feed.gas(tank)


@jit_noalloc
def target(mode, loc):
    """The target of the mode (its MD_LOCAL_TARGET) is the one the law and the predicates use."""
    for i in range(3):
        loc.target[i] = mode[MD_LOCAL_TARGET + i]


@jit_noalloc
def navigate(nav, loc, tank, rng_state, now):
    """Measured position, velocity and tank pressure into ``loc.measured``; the position error and
    speed the exit predicates read, from the measured values."""
    measure(nav, loc.state, tank.state[feed.TK_PRESSURE], rng_state, loc.measured)
    e2, v2 = 0.0, 0.0
    for i in range(3):
        e = loc.measured[i] - loc.target[i]
        e2 += e * e
        v2 += loc.measured[3 + i] * loc.measured[3 + i]
    now[NOW_POSITION_ERROR] = math.sqrt(e2)
    now[NOW_SPEED] = math.sqrt(v2)


@jit_noalloc
def measure(nav, state, pressure, rng_state, out):
    """Truth plus white noise: position and velocity (1 sigma per axis), then the pressure (a
    measured pressure below zero reads zero). A zero sigma draws nothing: the truth, bit for bit."""
    sigma_position = nav[N_LOCAL_POSITION_NOISE]
    sigma_velocity = nav[N_LOCAL_VELOCITY_NOISE]
    sigma_pressure = nav[N_TANK_PRESSURE_NOISE]
    for i in range(3):
        out[i] = state[i]
        if sigma_position > 0.0:
            out[i] += sigma_position * rng.next_normal(rng_state)
    for i in range(3):
        out[3 + i] = state[3 + i]
        if sigma_velocity > 0.0:
            out[3 + i] += sigma_velocity * rng.next_normal(rng_state)
    out[6] = pressure
    if sigma_pressure > 0.0:
        out[6] = elementary.larger(pressure + sigma_pressure * rng.next_normal(rng_state), 0.0)


@jit_noalloc
def desired(fsw, mission, loc, q_meas):
    """The valves the law opens this control period (bit mask), 002 eq. 44 per body axis."""
    error, velocity = loc.scratch[0], loc.scratch[1]
    for i in range(3):
        loc.scratch[2, i] = loc.measured[i] - loc.target[i]
    quaternion.rotate_inverse(q_meas, loc.scratch[2], error)
    quaternion.rotate_inverse(q_meas, loc.measured[3:6], velocity)
    pressure = loc.measured[6]  # the pressure transducer
    mass = fsw[F_TRANSLATION_DRY_MASS] + pressure * fsw[F_TRANSLATION_GAS_PER_PA]  # the gas left, 002 eq. 1
    law = fsw[F_TRANSLATION_LAW]
    bang_bang = law == TRANSLATION_BANG_BANG
    steps = int(fsw[F_TRANSLATION_PWM_STEPS])
    phase = int(loc.status[LS_STEP]) % steps if law == TRANSLATION_PD_PWM else 0
    loc.status[LS_STEP] += 1.0
    mask = 0
    for i in range(3):
        k = fsw[F_TRANSLATION_FORCE_PER_PA + i] / mass
        tau = fsw[F_TRANSLATION_TAU + i]
        if k <= 0.0:  # no thrusters along this axis
            continue
        if abs(error[i]) <= fsw[F_TRANSLATION_DEADBAND] and abs(velocity[i]) <= fsw[F_TRANSLATION_DEADBAND + 1]:
            u = 0.0  # arrived on this axis: a bang-off-bang law would chatter about the origin
        elif law == TRANSLATION_PD_PWM:
            u = _pd_pwm(fsw, loc, i, error[i], velocity[i], k * pressure, phase, steps)
        else:
            x1, x2, x3 = time_optimal.scale(error[i], velocity[i], k, pressure, tau, 1.0)
            reserve = k * mission[M_LOCAL_RESERVE] * tau * tau
            u = time_optimal.command(x1, x2, x3, reserve, bang_bang)
        if u > 0.0:
            mask |= int(fsw[F_TRANSLATION_MASKS + 2 * i])
        elif u < 0.0:
            mask |= int(fsw[F_TRANSLATION_MASKS + 2 * i + 1])
        u = 1.0 if u > 0.0 else (-1.0 if u < 0.0 else 0.0)
        if u != loc.status[LS_U + i]:
            loc.status[LS_SWITCHES + i] += 1.0
            loc.status[LS_U + i] = u
    return mask


@jit_noalloc
def _pd_pwm(fsw, loc, axis, error, velocity, accel_available, phase, steps):
    """The comparison law: a = -kp e - kd v, fired as a pulse of round(|a| / a_available * steps)
    control periods at the start of each modulation period of ``steps`` periods; u this period."""
    if phase == 0:
        accel = -fsw[F_TRANSLATION_PD_GAINS] * error - fsw[F_TRANSLATION_PD_GAINS + 1] * velocity
        fraction = elementary.smaller(abs(accel) / accel_available, 1.0) if accel_available > 0.0 else 0.0
        loc.status[LS_PWM + axis] = math.copysign(math.floor(fraction * steps + 0.5), accel)
    width = loc.status[LS_PWM + axis]
    if phase < abs(width):
        return 1.0 if width > 0.0 else -1.0
    return 0.0


@jit_noalloc
def force_at(valve_state, thrusters, thrust_per_level, t, active, out):
    """Thrust force (N, body axes) of the thrusters in ``active`` at ``t``."""
    n = thrusters.shape[0]
    fx, fy, fz = 0.0, 0.0, 0.0
    m = active & ((1 << n) - 1)
    while m != 0:
        i = lowest_bit(m)
        m &= m - 1
        f = thrust_per_level * thrusters[i, T_SCALE] * level_at(valve_state, i, t)
        fx += f * thrusters[i, T_DIRECTION]
        fy += f * thrusters[i, T_DIRECTION + 1]
        fz += f * thrusters[i, T_DIRECTION + 2]
    out[0], out[1], out[2] = fx, fy, fz


@jit_noalloc
def segment_force(vehicle, valve_state, thrusters, tank, pressure_start, t_start, t_end, active, loc):
    """The thrust acceleration at a segment's start, midpoint and end into ``loc.accel`` (body
    axes, m/s^2): each point's force (002 eq. 15 at the tank pressure there, core.feed) over the
    vehicle's mass there (the gas left is P V / (R T), 002 eq. 1). The tank is already advanced
    to ``t_end``."""
    t_mid = 0.5 * (t_start + t_end)
    pressure_end = tank.state[feed.TK_PRESSURE]
    pressure_mid = feed.pressure_within(
        valve_state, thrusters, vehicle, tank, pressure_start, t_start, t_end, t_mid, active
    )
    mass_end = vehicle[V_MASS] - (loc.status[LS_GAS0] - feed.gas(tank))
    gas_per_pa = tank.state[feed.TK_GAS_PER_PA]
    for k in range(3):
        t = t_start if k == 0 else (t_mid if k == 1 else t_end)
        pressure = pressure_start if k == 0 else (pressure_mid if k == 1 else pressure_end)
        force_at(valve_state, thrusters, feed.thrust_per_level(tank, pressure), t, active, loc.accel[k])
        mass = mass_end + (pressure - pressure_end) * gas_per_pa
        for i in range(3):
            loc.accel[k, i] /= mass


@jit_noalloc
def no_force(loc):
    for j in range(3):
        for i in range(3):
            loc.accel[j, i] = 0.0


@jit_noalloc
def advance(mission, loc, q, h):
    """Position and velocity over ``h`` with the thrust acceleration quadratic through
    loc.accel's start, midpoint and end (body axes, through the attitude ``q``), plus gravity:
    exact for a quadratic acceleration (Simpson's rule for the velocity; for the position
    int_0^h (h - s) a(s) ds = h^2 (a_start + 2 a_mid) / 6)."""
    a0, a1, a2 = loc.scratch[0], loc.scratch[1], loc.scratch[2]
    quaternion.rotate(q, loc.accel[0], a0)
    quaternion.rotate(q, loc.accel[1], a1)
    quaternion.rotate(q, loc.accel[2], a2)
    for i in range(3):
        g = mission[M_LOCAL_GRAVITY + i]
        acc_start = a0[i] + g
        acc_mid = a1[i] + g
        acc_end = a2[i] + g
        loc.state[i] += loc.state[3 + i] * h + (acc_start + 2.0 * acc_mid) * h * h / 6.0
        loc.state[3 + i] += (acc_start + 4.0 * acc_mid + acc_end) * h / 6.0


@jit_noalloc
def finish(mission, loc, tank, summary):
    """The local trajectory's summary values."""
    e2, v2 = 0.0, 0.0
    for i in range(3):
        e = loc.state[i] - loc.target[i]
        e2 += e * e
        v2 += loc.state[3 + i] * loc.state[3 + i]
        summary[S_SWITCHES + i] = loc.status[LS_SWITCHES + i]
    summary[S_LOCAL_POSITION_ERROR] = math.sqrt(e2)
    summary[S_LOCAL_SPEED] = math.sqrt(v2)
    summary[S_TANK_PRESSURE_END] = tank.state[feed.TK_PRESSURE]


@jit_noalloc
def record(loc, row):
    """The local trajectory's history columns of one row: true position and velocity, the true
    distance to the mode's target and speed, and the law's last command per body axis."""
    e2, v2 = 0.0, 0.0
    for i in range(3):
        row[H_POSITION + i] = loc.state[i]
        row[H_VELOCITY + i] = loc.state[3 + i]
        row[H_TRANSLATION_COMMAND + i] = loc.status[LS_U + i]
        e = loc.state[i] - loc.target[i]
        e2 += e * e
        v2 += loc.state[3 + i] * loc.state[3 + i]
    row[H_POSITION_ERROR] = math.sqrt(e2)
    row[H_SPEED] = math.sqrt(v2)
