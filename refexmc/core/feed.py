"""Cold-gas feed: the tank pressure behind the valves, and the thrust and gas flow it gives (002 sec. 2-3).

The tank is isothermal (002 sec. 2.1): P V = m R T (eq. 1), so the gas in it is P V / (R T) and
dP/dt = (R T / V) dm/dt (eq. 2). Each open nozzle is choked (eq. 10, 13b):
mdot_i = L_i s_i A_t P_c Gamma / sqrt(R T), Gamma = sqrt(gamma (2 / (gamma + 1))^((gamma + 1) / (gamma - 1))),
with L_i the valve's normalised level (core.rcs) and s_i its thrust scale, and its thrust is eq. 15,
F_i = L_i s_i A_t (C_F P_c - epsilon P_a), C_F the vacuum thrust coefficient (eq. 15's bracket).

- ``blow_down`` (002 sec. 3.2): the nozzle sits on the tank, P_c = P, so
  dP/dt = -P S(t) / tau with S = sum_i L_i s_i and tau = V / (A_t Gamma sqrt(R T)) (eq. 16).
- ``regulated``: P_c = min(P, P_reg d(n)), P_reg the set pressure of the thrust level flown
  (``layout.LV_REGULATOR_PRESSURE``: its thrust_n / (C_F A_t)) and d(n) the vehicle's derating
  with n valves open (000 sec. 2.1: the pressure reducers' flow limit); above it the tank falls
  linearly, dP/dt = -P_reg d S(t) / tau, below it the regulator is wide open and the tank blows
  down. The loop sets the level's set pressure every control period (core.flight._fly).

Between two valve breakpoints every level is linear in time (core.rcs), so S is linear and its
integral over a segment is exactly the trapezoid: the tank pressure at a segment's end is the
closed form (:func:`pressure_after`), the gas used is its drop times V / (R T), and the impulse
is c * gas - epsilon P_a A_t * integral of S, with c = C_F sqrt(R T) / Gamma the vacuum exhaust
velocity (the pressure integral of eq. 15 is tau times the pressure drop). No step size enters.
The torques at a segment's two ends are exact; the attitude integrator interpolates linearly
between them (core.flight._integrate), an error of order (segment / tau)^2 of the torque.

The work tuple :class:`Tank` exists in the flight kernel of a vehicle whose ``rcs.feed`` is not
``constant`` only (docs/families.md); the constant feed flies ``core.rcs.segment_thrust``.
"""

import math
from typing import NamedTuple

import numpy as np

from refexmc._jit import jit, jit_noalloc
from refexmc.core import arena, elementary
from refexmc.core.bits import lowest_bit
from refexmc.core.layout import (
    T_SCALE,
    V_FEED_AMBIENT_PRESSURE,
    V_FEED_EXPANSION_RATIO,
    V_FEED_FLOW_FACTOR,
    V_FEED_GAS_CONSTANT,
    V_FEED_INITIAL_PRESSURE,
    V_FEED_TANK_VOLUME,
    V_FEED_TEMPERATURE,
    V_FEED_THROAT_AREA,
    V_FEED_THRUST_COEFFICIENT,
)
from refexmc.core.rcs import derating_factor, level_at, open_count

# Tank.state slots
TK_PRESSURE = 0  # tank pressure now (Pa)
TK_TAU = 1  # blow-down time constant tau = V / (A_t Gamma sqrt(R T)) (s), per unit of S
TK_EXHAUST_VELOCITY = 2  # c = C_F sqrt(R T) / Gamma (m/s)
TK_FORCE_PER_PA = 3  # C_F A_t (N/Pa)
TK_AMBIENT_FORCE = 4  # epsilon P_a A_t (N)
TK_REGULATOR = 5  # set pressure P_reg of the level flown (Pa); inf: blow-down
TK_GAS_PER_PA = 6  # V / (R T) (kg/Pa)
TK_IMPULSE = 7  # total impulse delivered so far, sum of |F_i| dt (N s)
TANK_SIZE = 8


class Tank(NamedTuple):
    """The feed's work: ``state`` (TK_*)."""

    state: np.ndarray


@jit
def tank():
    """Allocate the feed's work."""
    return carve_tank(np.zeros(TANK_SIZE), 0)[0]


@jit
def carve_tank(f, at):
    """The feed's work as a view of ``f`` from ``at`` (core.arena): (Tank, cursor after)."""
    state, at = arena.vector(f, at, TANK_SIZE)
    return Tank(state), at


@jit_noalloc
def start(vehicle, tank):
    """The tank full at its initial pressure, and the constants the segments use."""
    s = tank.state
    sqrt_rt = math.sqrt(vehicle[V_FEED_GAS_CONSTANT] * vehicle[V_FEED_TEMPERATURE])
    flow_factor = vehicle[V_FEED_FLOW_FACTOR]
    area = vehicle[V_FEED_THROAT_AREA]
    s[TK_PRESSURE] = vehicle[V_FEED_INITIAL_PRESSURE]
    s[TK_TAU] = vehicle[V_FEED_TANK_VOLUME] / (area * flow_factor * sqrt_rt)
    s[TK_EXHAUST_VELOCITY] = vehicle[V_FEED_THRUST_COEFFICIENT] * sqrt_rt / flow_factor
    s[TK_FORCE_PER_PA] = vehicle[V_FEED_THRUST_COEFFICIENT] * area
    s[TK_AMBIENT_FORCE] = vehicle[V_FEED_EXPANSION_RATIO] * vehicle[V_FEED_AMBIENT_PRESSURE] * area
    s[TK_REGULATOR] = math.inf  # the level's, set by the loop every period
    s[TK_GAS_PER_PA] = vehicle[V_FEED_TANK_VOLUME] / (vehicle[V_FEED_GAS_CONSTANT] * vehicle[V_FEED_TEMPERATURE])
    s[TK_IMPULSE] = 0.0


@jit_noalloc
def pressure_after(pressure, open_time, tau, regulator):
    """Tank pressure after ``open_time`` = integral of S dt (s) from ``pressure``: blow-down
    P exp(-open_time / tau) (002 eq. 16); above the regulator's set pressure a linear fall at
    P_reg / tau first."""
    if pressure > regulator:
        drop = regulator * open_time / tau
        if pressure - drop >= regulator:
            return pressure - drop
        open_time -= (pressure - regulator) * tau / regulator
        pressure = regulator
    return pressure * elementary.exp(-open_time / tau)


@jit_noalloc
def chamber_pressure(pressure, regulator):
    """The nozzles' chamber pressure: the tank's, at most the regulator's set pressure."""
    return pressure if pressure < regulator else regulator


@jit_noalloc
def open_sum(valve_state, thrusters, t, active):
    """S(t) = sum of level times thrust scale of the thrusters in the bit mask ``active``."""
    n = thrusters.shape[0]
    total = 0.0
    m = active & ((1 << n) - 1)
    while m != 0:
        i = lowest_bit(m)
        m &= m - 1
        total += level_at(valve_state, i, t) * thrusters[i, T_SCALE]
    return total


@jit_noalloc
def _torque(valve_state, thrusters, arms, t, force_per_level, active, out):
    """Sum of (r x d) s_i L_i(t) force_per_level (N m) over the thrusters in ``active``."""
    n = thrusters.shape[0]
    sx, sy, sz = 0.0, 0.0, 0.0
    m = active & ((1 << n) - 1)
    while m != 0:
        i = lowest_bit(m)
        m &= m - 1
        f = force_per_level * thrusters[i, T_SCALE] * level_at(valve_state, i, t)
        sx += f * arms[i, 0]
        sy += f * arms[i, 1]
        sz += f * arms[i, 2]
    out[0], out[1], out[2] = sx, sy, sz


@jit_noalloc
def _thrust(tank, pressure, regulator):
    s = tank.state
    f = s[TK_FORCE_PER_PA] * chamber_pressure(pressure, regulator) - s[TK_AMBIENT_FORCE]
    return f if f > 0.0 else 0.0


@jit_noalloc
def thrust_per_level(tank, pressure):
    """Thrust (N) of one thruster fully open at tank ``pressure`` (002 eq. 15), at least 0 (at the
    level's set pressure, not derated)."""
    return _thrust(tank, pressure, tank.state[TK_REGULATOR])


@jit_noalloc
def segment(valve_state, thrusters, vehicle, arms, tank, t_start, t_end, tau_start, tau_end, active):
    """Advance the tank over a segment without valve breakpoints; the torques at both ends in
    ``tau_start``/``tau_end``; returns the gas used (kg). A regulator's set pressure is derated
    by the number of valves open at the segment's midpoint (constant within it, as in core.rcs)."""
    s = tank.state
    p0 = s[TK_PRESSURE]
    regulator = s[TK_REGULATOR]
    if regulator < math.inf:
        n_open = open_count(valve_state, thrusters.shape[0], active, 0.5 * (t_start + t_end))
        regulator *= derating_factor(vehicle, n_open)
    open_time = 0.5 * (
        open_sum(valve_state, thrusters, t_start, active) + open_sum(valve_state, thrusters, t_end, active)
    )
    open_time *= t_end - t_start
    p1 = pressure_after(p0, open_time, s[TK_TAU], regulator)
    _torque(valve_state, thrusters, arms, t_start, _thrust(tank, p0, regulator), active, tau_start)
    _torque(valve_state, thrusters, arms, t_end, _thrust(tank, p1, regulator), active, tau_end)
    s[TK_PRESSURE] = p1
    used = (p0 - p1) * s[TK_GAS_PER_PA]
    s[TK_IMPULSE] += used * s[TK_EXHAUST_VELOCITY] - s[TK_AMBIENT_FORCE] * open_time
    return used


@jit_noalloc
def pressure_within(valve_state, thrusters, vehicle, tank, pressure_start, t_start, t_end, t, active):
    """Tank pressure at ``t`` inside the segment [t_start, t_end] that :func:`segment` advances
    from ``pressure_start``: the same regulator and the same closed form, over [t_start, t]."""
    regulator = tank.state[TK_REGULATOR]
    if regulator < math.inf:
        n_open = open_count(valve_state, thrusters.shape[0], active, 0.5 * (t_start + t_end))
        regulator *= derating_factor(vehicle, n_open)
    open_time = 0.5 * (open_sum(valve_state, thrusters, t_start, active) + open_sum(valve_state, thrusters, t, active))
    return pressure_after(pressure_start, open_time * (t - t_start), tank.state[TK_TAU], regulator)


@jit_noalloc
def gas(tank):
    """Gas in the tank now (kg), 002 eq. 1."""
    return tank.state[TK_PRESSURE] * tank.state[TK_GAS_PER_PA]
