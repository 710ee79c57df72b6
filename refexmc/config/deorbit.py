"""The nominal deorbit plan of an ``orbit`` mission (004 sec. III), computed once per campaign.

From the mission's initial circular orbit and its entry target this finds

1. the burn duration: a bisection on the constant-thrust burn time until the entry flight-path
   angle at the entry interface equals the target (004 sec. III, "a bisection root solver is
   wrapped around the trajectory code");
2. the phasing: the argument of latitude and the node's longitude at t = 0 that put the nominal
   entry point at the target latitude (on the pass asked for) and longitude. Two-body motion is
   symmetric under rotations, so moving the orbit along itself and about the Earth's axis moves
   the entry point exactly, at the same time;
3. the nominal burn table the flight software steers to (``core.deorbit``).

The nominal is flown with the core's own integrators at the control period, so that an
undispersed run follows it to rounding.
"""

import math
from typing import NamedTuple

import numpy as np

from refexmc import crmath
from refexmc.config.errors import ConfigError
from refexmc.core import deorbit, orbit
from refexmc.core import layout as L

COAST_STEP_S = 1.0  # RK4 step of the coast to the entry interface: ~0.03 m over an orbit
MAX_COAST_ORBITS = 2.0  # no entry within two orbital periods: the burn is too short


class Plan(NamedTuple):
    state0: np.ndarray  # [r, v, m] at t = 0, ECI
    ignition_s: float
    burn_duration_s: float
    table: np.ndarray  # layout.NOMINAL rows at the guidance period
    entry: np.ndarray  # nominal entry state: longitude, latitude (deg), speed (m/s), fpa, heading (deg)
    entry_time_s: float


def _crmath_sin(x):
    return float(crmath.sin(x))  # correctly rounded: math.sin is glibc's, whose variant depends on the CPU


def _crmath_cos(x):
    return float(crmath.cos(x))


def _crmath_asin(x):
    return float(crmath.asin(x))


def _crmath_atan2(y, x):
    return float(crmath.atan2(y, x))


def _circular_state(radius, mu, inclination, node, latitude_argument, mass):
    """ECI state of a circular orbit (right ascension ``node``, argument of latitude)."""
    speed = math.sqrt(mu / radius)
    cu, su = _crmath_cos(latitude_argument), _crmath_sin(latitude_argument)
    ci, si = _crmath_cos(inclination), _crmath_sin(inclination)
    co, so = _crmath_cos(node), _crmath_sin(node)
    position = radius * np.array([co * cu - so * su * ci, so * cu + co * su * ci, su * si])
    velocity = speed * np.array([-co * su - so * cu * ci, -so * su + co * cu * ci, cu * si])
    return np.concatenate([position, velocity, [mass]])


class _Flight:
    """The nominal flight of one burn duration, from a given state at t = 0."""

    def __init__(self, vehicle, mission, fsw_period, guidance_period):
        earth, plan = mission["earth"], mission["orbit"]
        engine = vehicle["main_engine"]
        self.mu = earth["mu_m3_s2"]
        self.earth_rate = earth.get("rotation_rate_rad_s", 0.0)
        self.r_entry = earth["radius_m"] + plan["entry_interface_altitude_m"]
        self.thrust = engine["thrust_n"]
        self.mass_flow = engine["thrust_n"] / (engine["isp_s"] * orbit.G0)
        self.approach = deorbit.APPROACHES[plan["deorbit"]["approach"]]
        self.step = fsw_period
        self.guidance_period = guidance_period
        self.ignition = plan["deorbit"]["burn_start_s"]
        self.stage = np.zeros((6, orbit.ORBIT_STATE_SIZE))
        self.prev = np.zeros(orbit.ORBIT_STATE_SIZE)
        orbit_radius = earth["radius_m"] + plan["altitude_m"]
        self.period = 2 * math.pi * math.sqrt(orbit_radius * orbit_radius * orbit_radius / self.mu)

    def at_ignition(self, state0):
        """Coast from t = 0 to ignition with the core's step (the control period)."""
        state = state0.copy()
        steps = round(self.ignition / self.step)
        for _ in range(steps):
            orbit.coast(state, self.step, self.mu, self.stage)
        return state

    def table(self, ignition_state, duration):
        rows = max(2, math.ceil(duration / self.guidance_period - 1e-9) + 1)
        table = np.zeros((rows, L.NOMINAL_SIZE))
        state = ignition_state.copy()
        deorbit.nominal_burn(
            state,
            self.ignition,
            duration,
            self.thrust,
            self.mass_flow,
            self.approach,
            self.mu,
            self.step,
            table,
            self.stage,
        )
        return state, table

    def entry(self, ignition_state, duration):
        """(entry time, entry state array) of a burn of ``duration``; time NaN without entry."""
        cutoff, _ = self.table(ignition_state, duration) if duration > 0 else (ignition_state.copy(), None)
        out = np.zeros(orbit.ORBIT_STATE_SIZE)
        coast = deorbit.coast_to_entry(
            cutoff, self.r_entry, self.mu, COAST_STEP_S, MAX_COAST_ORBITS * self.period, self.stage, self.prev, out
        )
        t = self.ignition + duration + coast
        values = np.full(5, np.nan)
        if math.isfinite(coast):
            orbit.entry_state(out, t, self.earth_rate, values)
        return t, values, out


def _bisect_duration(flight, ignition_state, target_fpa, max_duration, where):
    def fpa(duration):
        t, values, _ = flight.entry(ignition_state, duration)
        return values[3] if math.isfinite(t) else math.inf  # no entry: as shallow as can be

    if fpa(max_duration) > target_fpa:
        raise ConfigError(
            f"the main engine's propellant ({max_duration:.0f} s of burn) cannot reach an entry flight-path "
            f"angle of {target_fpa:g} deg",
            **where,
        )
    low, high = 0.0, max_duration
    while high - low > 1e-7:
        mid = 0.5 * (low + high)
        if fpa(mid) > target_fpa:
            low = mid
        else:
            high = mid
    return 0.5 * (low + high)


def plan(vehicle, mission, fsw_period, guidance_period, where=None):
    """The nominal deorbit :class:`Plan` (ConfigError when the target cannot be reached)."""
    where = where or {}
    spec = mission["orbit"]
    target = spec["deorbit"]
    flight = _Flight(vehicle, mission, fsw_period, guidance_period)
    radius = mission["earth"]["radius_m"] + spec["altitude_m"]
    inclination = math.radians(spec["inclination_deg"])
    mass = vehicle["mass_kg"]
    latitude = math.radians(target["entry_latitude_deg"])
    if abs(_crmath_sin(latitude)) > _crmath_sin(inclination) + 1e-12:
        raise ConfigError(
            f"an orbit inclined {spec['inclination_deg']:g} deg never reaches latitude "
            f"{target['entry_latitude_deg']:g} deg",
            **where,
        )
    max_duration = vehicle["main_engine"]["propellant_kg"] / flight.mass_flow
    u_target = _crmath_asin(max(-1.0, min(1.0, _crmath_sin(latitude) / _crmath_sin(inclination))))
    if target["pass"] == "descending":
        u_target = math.pi - u_target
    # The burn time sets the inertial entry; the Earth-relative flight-path angle also depends a
    # little on where the entry lies (the Earth's rotation): alternate bisection and phasing.
    node, u0 = 0.0, 0.0
    for _ in range(3):
        state0 = _circular_state(radius, flight.mu, inclination, node, u0, mass)
        duration = _bisect_duration(
            flight, flight.at_ignition(state0), target["entry_flight_path_angle_deg"], max_duration, where
        )
        for _ in range(2):  # phasing: exact in one step for two-body motion; repeated to absorb rounding
            state0 = _circular_state(radius, flight.mu, inclination, node, u0, mass)
            _, values, entry = flight.entry(flight.at_ignition(state0), duration)
            u0 += _wrap(u_target - _latitude_argument(entry[:3], inclination, node))
            state0 = _circular_state(radius, flight.mu, inclination, node, u0, mass)
            _, values, _ = flight.entry(flight.at_ignition(state0), duration)
            node += math.radians(_wrap_deg(target["entry_longitude_deg"] - values[0]))
    state0 = _circular_state(radius, flight.mu, inclination, node, u0, mass)
    ignition_state = flight.at_ignition(state0)
    _, table = flight.table(ignition_state, duration)
    t_entry, values, _ = flight.entry(ignition_state, duration)
    return Plan(state0, flight.ignition, duration, table, values, t_entry)


def _latitude_argument(position, inclination, node):
    """Argument of latitude of ``position`` in the orbit plane (node, inclination)."""
    co, so = _crmath_cos(node), _crmath_sin(node)
    x = co * position[0] + so * position[1]  # toward the ascending node
    y = (-so * position[0] + co * position[1]) * _crmath_cos(inclination) + position[2] * _crmath_sin(inclination)
    return _crmath_atan2(y, x)


def _wrap(angle):
    return (angle + math.pi) % (2 * math.pi) - math.pi


def _wrap_deg(angle):
    return (angle + 180.0) % 360.0 - 180.0
