"""Orbit translation (core.orbit) and deorbit burn guidance (core.deorbit) against independent
references: Kepler's closed form, scipy's DOP853 (``solve_ivp``, rtol 1e-12, atol 1e-6 m) with
terminal events, scipy's rotations, numpy, and the slow twin in tests/naive.py.

Error budget (LEO, r ~ 6.8e6 m, orbital rate n ~ 1.1e-3 rad/s). RK4's truncation error at the
steps used here (0.1 s and 1 s) is 1e-13 m and 1e-9 m per step: every kernel-versus-reference gap
below is set by rounding or by the reference itself. Rounding: a position of 7e6 m has an ulp of
1e-9 m, and over N steps the rounding walks ~sqrt(N) ulp across track and, through the energy
(hence the period), ~1e-14 of the arc along track: 3e-7 m after 3000 s, which is what the kernel
shows against Kepler; ``KEPLER_M`` leaves 30x. DOP853 at rtol 1e-12 keeps each step's local
error below ~7e-6 m; after a few hundred steps it is 1e-5 m off Kepler itself, so ``IVP_M``
(1e-4 m) is the reference's own accuracy with 10x margin. Velocities scale by n: 1e-8 and 1e-7 m/s.
"""

import math

import naive
import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.spatial.transform import Rotation

from refexmc.core import deorbit, orbit
from refexmc.core import layout as L
from refexmc.core.layout import (
    N_GPS_POSITION_BIAS,
    N_GPS_POSITION_NOISE,
    N_GPS_VELOCITY_BIAS,
    N_GPS_VELOCITY_NOISE,
    NAV_SIZE,
    NM_POSITION,
    NM_T,
    NM_THRUST_ACCEL,
    NM_VELOCITY,
    NOMINAL_SIZE,
)

MU = 3.986004418e14
EARTH_RADIUS = 6378137.0
EARTH_RATE = 7.2921159e-5
R_ENTRY = EARTH_RADIUS + 125e3
THRUST, ISP, MASS = 40.0, 225.0, 75.0  # the SPORE service module's engine (configs/vehicles/spore-sm.yaml)
MASS_FLOW = THRUST / (ISP * orbit.G0)

KEPLER_M, KEPLER_M_S = 1e-5, 1e-8  # kernel vs closed form: rounding only (module docstring)
IVP_M, IVP_M_S = 1e-4, 1e-7  # kernel vs DOP853: DOP853's own error at rtol 1e-12 (module docstring)
CONSERVED_REL = 1e-12  # energy, angular momentum: RK4 drift (h n)^4 n t ~ 1e-15 at 0.1 s, plus rounding
IVP = {"method": "DOP853", "rtol": 1e-12, "atol": 1e-6}

ORBITS = {  # perigee and apogee radius (m)
    "circular": (EARTH_RADIUS + 400e3, EARTH_RADIUS + 400e3),
    "elliptical": (EARTH_RADIUS + 200e3, EARTH_RADIUS + 1200e3),
}


# --------------------------------------------------------------------------------------------
# references
# --------------------------------------------------------------------------------------------


def unit(v):
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v)


ORIENTATION = Rotation.from_euler("ZXZ", [0.4, 0.9, 1.3])  # node, inclination, argument of perigee


def kepler_state(r_perigee, r_apogee, t_from_perigee, mass=MASS):
    """ECI state ``[r, v, m]`` on the orbit of the given perigee and apogee radii, ``t`` seconds
    after perigee, from Kepler's equation (solved by Newton to rounding)."""
    a = 0.5 * (r_perigee + r_apogee)
    e = (r_apogee - r_perigee) / (r_apogee + r_perigee)
    n = math.sqrt(MU / a**3)
    mean = math.fmod(n * t_from_perigee, 2.0 * math.pi)
    ecc = mean
    for _ in range(50):
        ecc -= (ecc - e * math.sin(ecc) - mean) / (1.0 - e * math.cos(ecc))
    b = a * math.sqrt(1.0 - e * e)
    rate = n / (1.0 - e * math.cos(ecc))
    position = [a * (math.cos(ecc) - e), b * math.sin(ecc), 0.0]
    velocity = [-a * math.sin(ecc) * rate, b * math.cos(ecc) * rate, 0.0]
    return np.concatenate([ORIENTATION.apply(position), ORIENTATION.apply(velocity), [mass]])


def time_from_perigee(r_perigee, r_apogee, radius, descending):
    """Kepler's time of flight from perigee to ``radius`` (the first time, or the descending one)."""
    a = 0.5 * (r_perigee + r_apogee)
    e = (r_apogee - r_perigee) / (r_apogee + r_perigee)
    nu = math.acos((a * (1.0 - e * e) / radius - 1.0) / e)
    ecc = 2.0 * math.atan2(math.sqrt(1.0 - e) * math.sin(nu / 2), math.sqrt(1.0 + e) * math.cos(nu / 2))
    t = (ecc - e * math.sin(ecc)) / math.sqrt(MU / a**3)
    return 2.0 * math.pi / math.sqrt(MU / a**3) - t if descending else t


def energy(s):
    return 0.5 * s[3:6] @ s[3:6] - MU / np.linalg.norm(s[0:3])


def momentum(s):
    return np.cross(s[0:3], s[3:6])


def rhs(direction=None, thrust=0.0, mass_flow=0.0):
    """The ODE the kernels integrate; ``direction(t, y)`` gives the unit thrust direction."""

    def f(t, y):
        r = y[0:3]
        accel = -MU / np.linalg.norm(r) ** 3 * r
        if thrust:
            accel = accel + thrust / y[6] * direction(t, y)
        return np.concatenate([y[3:6], accel, [-mass_flow]])

    return f


def radius_event(r_target, direction=-1):
    def event(t, y):
        return np.linalg.norm(y[0:3]) - r_target

    event.terminal, event.direction = True, direction
    return event


def random_unit(rng, count=None):
    v = rng.normal(size=(3,) if count is None else (count, 3))
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def stage():
    return np.zeros((6, orbit.ORBIT_STATE_SIZE))


# --------------------------------------------------------------------------------------------
# 1. rk4_step / coast
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", ORBITS)
def test_coast_matches_kepler_and_dop853(name):
    """3000 s of 0.1 s coast steps on a circular and an elliptical orbit (started off perigee)."""
    rp, ra = ORBITS[name]
    start = kepler_state(rp, ra, 700.0)
    state, work = start.copy(), stage()
    for _ in range(30_000):
        orbit.coast(state, 0.1, MU, work)
    exact = kepler_state(rp, ra, 3700.0)
    assert np.abs(state[0:3] - exact[0:3]).max() <= KEPLER_M
    assert np.abs(state[3:6] - exact[3:6]).max() <= KEPLER_M_S
    reference = solve_ivp(rhs(), (0.0, 3000.0), start, **IVP).y[:, -1]
    assert np.abs(state[0:3] - reference[0:3]).max() <= IVP_M
    assert np.abs(state[3:6] - reference[3:6]).max() <= IVP_M_S
    assert abs(energy(state) / energy(start) - 1.0) <= CONSERVED_REL
    assert np.linalg.norm(momentum(state) - momentum(start)) <= CONSERVED_REL * np.linalg.norm(momentum(start))
    assert state[6] == MASS  # no thrust, no mass flow


def test_constant_thrust_along_a_fixed_direction_matches_dop853():
    """600 s of 40 N along a fixed inertial direction, mass flow included (0.1 s steps)."""
    start = kepler_state(*ORBITS["circular"], 0.0)
    d = unit([0.3, -0.8, 0.5])
    state, work = start.copy(), stage()
    steps, h = 6000, 0.1
    for _ in range(steps):
        orbit.rk4_step(state, h, MU, THRUST, MASS_FLOW, d, d, 0.0, 1.0, work)
    reference = solve_ivp(rhs(lambda t, y: d, THRUST, MASS_FLOW), (0.0, steps * h), start, **IVP).y[:, -1]
    assert np.abs(state[0:3] - reference[0:3]).max() <= IVP_M
    assert np.abs(state[3:6] - reference[3:6]).max() <= IVP_M_S
    # dm/dt is constant, so RK4 is exact for the mass: each step subtracts h/6 * 6 mdot with at
    # most a few roundings of ~ulp(75 kg) = 1.4e-14 kg; 6000 steps: below 1e-10 kg
    assert state[6] == pytest.approx(MASS - MASS_FLOW * steps * h, abs=steps * 4 * np.spacing(MASS))


def test_thrust_direction_interpolated_over_the_control_period_matches_dop853():
    """The direction goes linearly from d0 to d1 (renormalised) over each 1 s control period, flown
    in 10 RK4 steps with fractions k/10 -> (k+1)/10; DOP853 restarts at every period boundary,
    where the direction jumps to the next period's pair. d1 is d0 turned by up to 20 deg (a slew
    of 20 deg/s): RK4 at 0.1 s resolves that. (With d1 near -d0 the chord passes near zero and the
    direction swings by 180 deg within a step; no RK4 step size of the caller's would resolve it.)"""
    rng = np.random.default_rng(1)
    state, work = kepler_state(*ORBITS["elliptical"], 300.0), stage()
    reference = state.copy()
    for _ in range(30):
        d0 = random_unit(rng)
        d1 = Rotation.from_rotvec(random_unit(rng) * rng.uniform(0.0, math.radians(20.0))).apply(d0)
        for k in range(10):
            orbit.rk4_step(state, 0.1, MU, THRUST, MASS_FLOW, d0, d1, k / 10, (k + 1) / 10, work)
        reference = solve_ivp(
            rhs(lambda t, y, d0=d0, d1=d1: unit(d0 + (d1 - d0) * t), THRUST, MASS_FLOW), (0.0, 1.0), reference, **IVP
        ).y[:, -1]
    # 30 short arcs: DOP853 errs far below its 3000 s figure; the bounds still hold with margin
    assert np.abs(state[0:3] - reference[0:3]).max() <= IVP_M
    assert np.abs(state[3:6] - reference[3:6]).max() <= IVP_M_S
    assert state[6] == pytest.approx(MASS - 30.0 * MASS_FLOW, abs=300 * 4 * np.spacing(MASS))


def test_rk4_step_equals_the_slow_twin():
    """naive.orbit_rk4_step shares no code with the kernel and groups the arithmetic differently
    (mu / r**3 * x instead of mu / (r^2 sqrt(r^2)) * x), so not bit for bit: one step agrees to
    1e-15 of |r|, |v| and m (measured 1.2e-16 over 5000 random steps, i.e. an ulp or so)."""
    rng = np.random.default_rng(2)
    work = stage()
    for _ in range(300):
        state = np.concatenate(
            [
                random_unit(rng) * rng.uniform(6.5e6, 8e6),
                random_unit(rng) * rng.uniform(6e3, 9e3),
                [rng.uniform(20, 100)],
            ]
        )
        d0, d1 = random_unit(rng), random_unit(rng)
        h, f0, f1 = rng.uniform(0.01, 1.0), rng.uniform(0.0, 0.5), rng.uniform(0.5, 1.0)
        thrust, mass_flow = rng.uniform(0.0, 500.0), rng.uniform(0.0, 0.2)
        expected = np.array(naive.orbit_rk4_step(state, h, MU, thrust, mass_flow, d0, d1, f0, f1))
        kernel = state.copy()
        orbit.rk4_step(kernel, h, MU, thrust, mass_flow, d0, d1, f0, f1, work)
        scale = np.r_[[np.linalg.norm(expected[0:3])] * 3, [np.linalg.norm(expected[3:6])] * 3, expected[6]]
        assert np.all(np.abs(kernel - expected) <= 1e-15 * scale)
    # and coast is the thrust-free step: bit for bit
    coasted, stepped = state.copy(), state.copy()
    orbit.coast(coasted, 0.5, MU, work)
    orbit.rk4_step(stepped, 0.5, MU, 0.0, 0.0, d0, d1, 0.0, 1.0, work)
    assert np.array_equal(coasted, stepped)


def test_radius_and_climb_rate():
    """|r| and d|r|/dt = r.v / |r| (a dot product and a norm: 1e-15 relative, bound 1e-13), and
    the climb rate equals a central difference of Kepler's motion."""
    rng = np.random.default_rng(3)
    for _ in range(50):
        state = np.concatenate([random_unit(rng) * 7e6, random_unit(rng) * 7.5e3, [MASS]])
        r = np.linalg.norm(state[0:3])
        assert orbit.radius(state) == pytest.approx(r, rel=1e-15)
        assert orbit.climb_rate(state) == pytest.approx(state[0:3] @ state[3:6] / r, rel=1e-13, abs=1e-12)
    before, after = kepler_state(*ORBITS["elliptical"], 999.99), kepler_state(*ORBITS["elliptical"], 1000.01)
    central = (np.linalg.norm(after[0:3]) - np.linalg.norm(before[0:3])) / 0.02
    # central difference: truncation (0.01 s)^2 r''' / 6 ~ 1e-8 m/s, rounding 1e-9 m / 0.02 s = 5e-8 m/s
    assert orbit.climb_rate(kepler_state(*ORBITS["elliptical"], 1000.0)) == pytest.approx(central, abs=1e-6)


# --------------------------------------------------------------------------------------------
# 2. coast_to_radius
# --------------------------------------------------------------------------------------------

CROSSING_TIME_S = 1e-7  # a 1e-5 m disagreement in position over a climb rate of >= 100 m/s
CROSSING_M = 1e-5  # DOP853 over a few seconds: a few steps of <= 7e-6 m local error


@pytest.mark.parametrize("descending", [True, False], ids=["descending", "ascending"])
@pytest.mark.parametrize("lead", [0.05, 0.5, 1.0, 5.0])
def test_coast_to_radius_reaches_the_target_where_dop853_does(lead, descending):
    """From a state ``lead`` seconds (Kepler) before the orbit passes R_entry, with the guess 0.5 s
    (the kernel's callers guess half a step and the crossing lies within that step)."""
    rp, ra = EARTH_RADIUS + 50e3, EARTH_RADIUS + 400e3
    t_cross = time_from_perigee(rp, ra, R_ENTRY, descending)
    start = kepler_state(rp, ra, t_cross - lead)
    kept, out, work = start.copy(), np.zeros(orbit.ORBIT_STATE_SIZE), stage()
    h = orbit.coast_to_radius(start, R_ENTRY, 0.5, MU, work, out)
    assert np.array_equal(start, kept)  # ``start`` is left alone
    assert abs(np.linalg.norm(out[0:3]) - R_ENTRY) <= 1e-6  # the documented convergence
    assert out[6] == start[6]
    event = radius_event(R_ENTRY, -1 if descending else 1)
    reference = solve_ivp(rhs(), (0.0, 60.0), start, events=event, **IVP)
    assert h == pytest.approx(reference.t_events[0][0], abs=CROSSING_TIME_S)
    assert h == pytest.approx(lead, abs=CROSSING_TIME_S)  # and Kepler's time of flight
    assert np.abs(out[0:3] - reference.y_events[0][0][0:3]).max() <= CROSSING_M
    assert np.abs(out[3:6] - reference.y_events[0][0][3:6]).max() <= CROSSING_M * 1e-3


def test_coast_to_radius_at_the_target_returns_zero():
    start = kepler_state(*ORBITS["elliptical"], 500.0)
    out = np.zeros(orbit.ORBIT_STATE_SIZE)
    # a guess of exactly 0 is a zero-length coast: the start is already there
    assert orbit.coast_to_radius(start, np.linalg.norm(start[0:3]), 0.0, MU, stage(), out) == 0.0
    assert np.array_equal(out, start)


# --------------------------------------------------------------------------------------------
# 3. entry_state
# --------------------------------------------------------------------------------------------


def entry_reference(state, t, earth_rate):
    """Longitude, latitude, Earth-relative speed, flight-path angle, heading (deg) with scipy and
    numpy: the Earth-fixed frame is the ECI one turned by earth_rate * t about z; east is z x r,
    north is r x east, the flight-path angle comes from the angle between r and v_rel."""
    r, v = state[0:3], state[3:6]
    v_rel = v - np.cross([0.0, 0.0, earth_rate], r)
    to_earth = Rotation.from_rotvec([0.0, 0.0, earth_rate * t]).inv()
    r_e, v_e = to_earth.apply(r), to_earth.apply(v_rel)
    longitude = np.degrees(np.arctan2(r_e[1], r_e[0]))
    latitude = np.degrees(np.arctan2(r_e[2], np.hypot(r_e[0], r_e[1])))
    up = unit(r_e)
    east = unit(np.cross([0.0, 0.0, 1.0], r_e))
    north = np.cross(up, east)
    fpa = 90.0 - np.degrees(np.arctan2(np.linalg.norm(np.cross(up, v_e)), up @ v_e))
    heading = np.degrees(np.arctan2(v_e @ east, v_e @ north)) % 360.0
    return np.array([longitude, latitude, np.linalg.norm(v_e), fpa, heading])


def angle_gap(a, b):
    """|a - b| in degrees, modulo 360."""
    return abs((a - b + 180.0) % 360.0 - 180.0)


def entry(state, t, earth_rate):
    out = np.zeros(5)
    orbit.entry_state(np.ascontiguousarray(state, dtype=float), t, earth_rate, out)
    return out


# Both sides round ~10 operations at 1e-16 and feed atan2 / asin arguments kept away from the
# poles and from vertical flight (|sin| < 0.99): 1e-14 rad, i.e. 1e-12 deg; 1e-10 deg leaves margin.
ANGLE_DEG = 1e-10


def test_entry_state_matches_scipy_on_random_states():
    rng = np.random.default_rng(4)
    checked = 0
    while checked < 300:
        r = random_unit(rng) * rng.uniform(R_ENTRY - 1e3, R_ENTRY + 1e3)
        v = random_unit(rng) * rng.uniform(7e3, 8e3)
        t = rng.uniform(0.0, 2e4)
        state = np.concatenate([r, v, [MASS]])
        expected = entry_reference(state, t, EARTH_RATE)
        if abs(expected[1]) > 80.0 or abs(expected[3]) > 80.0:  # asin ill-conditioned there
            continue
        got = entry(state, t, EARTH_RATE)
        assert -180.0 <= got[0] <= 180.0 and 0.0 <= got[4] < 360.0
        assert angle_gap(got[0], expected[0]) <= ANGLE_DEG
        assert got[1] == pytest.approx(expected[1], abs=ANGLE_DEG)
        assert got[2] == pytest.approx(expected[2], rel=1e-13)
        assert got[3] == pytest.approx(expected[3], abs=ANGLE_DEG)
        assert angle_gap(got[4], expected[4]) <= ANGLE_DEG
        checked += 1


R0 = EARTH_RADIUS + 125e3
V0 = 7500.0


@pytest.mark.parametrize(
    ("velocity", "heading", "fpa"),
    [
        ((0.0, V0, 0.0), 90.0, 0.0),  # due east on the equator at longitude 0
        ((0.0, 0.0, V0), 0.0, 0.0),  # due north
        ((0.0, -V0, 0.0), 270.0, 0.0),  # due west
        ((0.0, 0.0, -V0), 180.0, 0.0),  # due south
        ((0.0, V0, V0), 45.0, 0.0),  # north-east
        ((-V0, V0, 0.0), 90.0, -45.0),  # east and down at 45 deg
        ((V0 * math.sin(math.radians(5.0)), V0 * math.cos(math.radians(5.0)), 0.0), 90.0, 5.0),  # climbing 5 deg
    ],
)
def test_entry_state_conventions_on_the_equator(velocity, heading, fpa):
    """Heading 0 = north, 90 = east, clockwise; flight-path angle positive up (earth rate 0)."""
    got = entry([R0, 0.0, 0.0, *velocity, MASS], 123.0, 0.0)
    assert got[0] == pytest.approx(0.0, abs=1e-12) and got[1] == pytest.approx(0.0, abs=1e-12)
    assert got[2] == pytest.approx(np.linalg.norm(velocity), rel=1e-15)
    assert angle_gap(got[4], heading) <= 1e-12 and got[3] == pytest.approx(fpa, abs=1e-12)


def test_entry_state_turns_with_the_earth():
    """After a quarter turn of the Earth the ECI +y axis is Greenwich; a prograde equatorial
    speed loses w R to the Earth's rotation; a point above 30 deg N, 60 deg E at t = 0 is over
    longitude 60 - 15 = 45 deg E one hour later at 15 deg/h."""
    quarter = 0.5 * math.pi / EARTH_RATE
    got = entry([0.0, R0, 0.0, -V0, 0.0, 0.0, MASS], quarter, EARTH_RATE)
    assert got[0] == pytest.approx(0.0, abs=1e-9) and got[1] == pytest.approx(0.0, abs=1e-12)
    assert got[2] == pytest.approx(V0 - EARTH_RATE * R0, rel=1e-14)
    assert got[3] == pytest.approx(0.0, abs=1e-12) and angle_gap(got[4], 90.0) <= 1e-12
    rate = math.radians(15.0) / 3600.0
    lat, lon = math.radians(30.0), math.radians(60.0)
    r = R0 * np.array([math.cos(lat) * math.cos(lon), math.cos(lat) * math.sin(lon), math.sin(lat)])
    east = unit(np.cross([0.0, 0.0, 1.0], r))
    v = np.cross([0.0, 0.0, rate], r) + 100.0 * unit(r) + 100.0 * east  # relative: 100 m/s up, 100 m/s east
    got = entry([*r, *v, MASS], 3600.0, rate)
    assert got[0] == pytest.approx(45.0, abs=1e-9) and got[1] == pytest.approx(30.0, abs=1e-12)
    # v_rel is a difference of 3.4e2 m/s terms: ~1e-13 m/s of rounding in 141 m/s; angles 1e-12 rad
    assert got[2] == pytest.approx(100.0 * math.sqrt(2.0), rel=1e-12)
    assert got[3] == pytest.approx(45.0, abs=1e-9) and angle_gap(got[4], 90.0) <= 1e-9


def test_entry_state_of_a_vertical_climb_is_90_degrees():
    """At rest over the ground at 30 deg N, 60 deg E, climbing 100 m/s (Earth rate 15 deg/h)."""
    rate = math.radians(15.0) / 3600.0
    lat, lon = math.radians(30.0), math.radians(60.0)
    r = R0 * np.array([math.cos(lat) * math.cos(lon), math.cos(lat) * math.sin(lon), math.sin(lat)])
    v = np.cross([0.0, 0.0, rate], r) + 100.0 * unit(r)
    got = entry([*r, *v, MASS], 3600.0, rate)
    assert got[3] == pytest.approx(90.0, abs=1e-6)


# --------------------------------------------------------------------------------------------
# 4. gravity_gradient_torque
# --------------------------------------------------------------------------------------------


def random_inertia(rng):
    principal = rng.uniform(1.0, 10.0, 3)
    axes = Rotation.random(random_state=rng).as_matrix()
    return np.ascontiguousarray(axes @ np.diag(principal) @ axes.T), axes


def test_gravity_gradient_torque_matches_numpy():
    """3 mu / r^3 (r_hat x J r_hat). The torque is a difference of products of size
    3 mu / r^3 |J| ~ 1e-5 N m; rounding leaves 1e-15 of that, the bound 1e-13 of it."""
    rng = np.random.default_rng(5)
    out = np.zeros(3)
    for _ in range(200):
        inertia, _ = random_inertia(rng)
        r = random_unit(rng) * rng.uniform(6.5e6, 4.2e7)
        r_hat = unit(r)
        expected = 3.0 * MU / np.linalg.norm(r) ** 3 * np.cross(r_hat, inertia @ r_hat)
        orbit.gravity_gradient_torque(r, MU, inertia, out)
        scale = 3.0 * MU / np.linalg.norm(r) ** 3 * np.abs(inertia).max()
        assert np.abs(out - expected).max() <= 1e-13 * scale


def test_gravity_gradient_torque_vanishes_along_a_principal_axis():
    rng = np.random.default_rng(6)
    out = np.zeros(3)
    diagonal = np.ascontiguousarray(np.diag([6.92, 6.92, 3.72]))
    for axis in np.eye(3):
        orbit.gravity_gradient_torque(np.ascontiguousarray(-7e6 * axis), MU, diagonal, out)
        assert not out.any()  # exact zeros: every product has a zero factor
    for _ in range(20):
        inertia, axes = random_inertia(rng)
        scale = 3.0 * MU / 7e6**3 * 10.0
        for k in range(3):
            orbit.gravity_gradient_torque(np.ascontiguousarray(7e6 * axes[:, k]), MU, inertia, out)
            assert np.abs(out).max() <= 1e-13 * scale


# --------------------------------------------------------------------------------------------
# 5. thrust_attitude
# --------------------------------------------------------------------------------------------


def attitude(direction, position, velocity, engine_axis):
    q, work = np.zeros(4), np.zeros((9, 3))
    deorbit.thrust_attitude(
        *(np.ascontiguousarray(v, dtype=float) for v in (direction, position, velocity, engine_axis)), q, work
    )
    return q


def test_thrust_attitude_points_the_engine_and_rolls_toward_the_orbit_normal():
    """Scalar-last body-to-inertial quaternion (scipy's convention): the engine axis goes onto the
    direction; the body axis least aligned with the engine axis (the first of equals) lands in the
    plane of the direction and the orbit normal n = r x v, on n's side; its part perpendicular to
    the engine axis lands on n's part perpendicular to the direction. A unit-vector map through
    a 3 x 3 rotation built from unit crosses: rounding 1e-15, bound 1e-12."""
    rng = np.random.default_rng(7)
    for _ in range(500):
        direction, engine_axis = random_unit(rng), random_unit(rng)
        position = random_unit(rng) * 6.8e6
        velocity = random_unit(rng) * 7.6e3
        normal = unit(np.cross(position, velocity))
        if abs(direction @ normal) > 0.999:  # the roll is undefined along the normal
            continue
        q = attitude(direction, position, velocity, engine_axis)
        assert abs(np.linalg.norm(q) - 1.0) <= 1e-14
        rotation = Rotation.from_quat(q)
        assert np.abs(rotation.apply(engine_axis) - direction).max() <= 1e-12
        k = int(np.argmin(np.abs(engine_axis)))
        second = rotation.apply(np.eye(3)[k])
        assert abs(second @ unit(np.cross(normal, direction))) <= 1e-12
        normal_perp = unit(normal - (normal @ direction) * direction)
        assert second @ normal_perp > 0.0
        body_perp = unit(np.eye(3)[k] - engine_axis[k] * engine_axis)
        assert np.abs(rotation.apply(body_perp) - normal_perp).max() <= 1e-12


def test_thrust_attitude_by_hand():
    """Engine on body +z; circular equatorial orbit at (R, 0, 0) moving +y (normal +z); thrust
    retrograde (-y). Body x (first of the two axes with zero engine component) goes to the normal
    +z, body z to -y, so body y = z x x goes to -x."""
    q = attitude([0.0, -1.0, 0.0], [R0, 0.0, 0.0], [0.0, V0, 0.0], [0.0, 0.0, 1.0])
    expected = np.array([[0.0, -1.0, 0.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]])  # columns: body axes
    assert np.abs(Rotation.from_quat(q).as_matrix() - expected).max() <= 1e-15


# --------------------------------------------------------------------------------------------
# 6. steer, nominal_at
# --------------------------------------------------------------------------------------------


def test_steer_is_the_normalised_pd_command():
    """A sum of three terms and a division by its norm: 1e-15 relative; the bound 1e-13."""
    rng = np.random.default_rng(8)
    out = np.zeros(3)
    for _ in range(200):
        nominal = np.zeros(NOMINAL_SIZE)
        nominal[NM_POSITION : NM_POSITION + 3] = random_unit(rng) * 6.8e6
        nominal[NM_VELOCITY : NM_VELOCITY + 3] = random_unit(rng) * 7.6e3
        nominal[NM_THRUST_ACCEL : NM_THRUST_ACCEL + 3] = random_unit(rng) * 0.55
        measured = np.concatenate(
            [
                nominal[NM_POSITION : NM_POSITION + 3] + rng.normal(0.0, 200.0, 3),
                nominal[NM_VELOCITY : NM_VELOCITY + 3] + rng.normal(0.0, 2.0, 3),
            ]
        )
        k_r, k_v = rng.uniform(0.0, 0.01), rng.uniform(0.0, 0.1)
        command = (
            nominal[NM_THRUST_ACCEL : NM_THRUST_ACCEL + 3]
            - k_r * (measured[0:3] - nominal[NM_POSITION : NM_POSITION + 3])
            - k_v * (measured[3:6] - nominal[NM_VELOCITY : NM_VELOCITY + 3])
        )
        deorbit.steer(measured, nominal, L.GUIDANCE_LAW_PD, k_r, k_v, out)
        assert np.abs(out - unit(command)).max() <= 1e-13
    # with no error the command is the nominal thrust direction
    deorbit.steer(nominal[NM_POSITION : NM_VELOCITY + 3].copy(), nominal, L.GUIDANCE_LAW_PD, 0.3, 0.7, out)
    assert np.abs(out - unit(nominal[NM_THRUST_ACCEL : NM_THRUST_ACCEL + 3])).max() <= 1e-15


def test_every_law_matches_its_naive_twin():
    """core.deorbit.steer against naive.burn_direction for each law (pack's ids), random states:
    the same sums in another grouping, 1e-15 relative; the bound 1e-13. open_loop_retrograde is
    -v_gps whatever the nominal, open_loop_planned the nominal thrust direction whatever the
    measured state and the gains."""
    from refexmc.config.pack import GUIDANCE_LAWS

    rng = np.random.default_rng(18)
    out = np.zeros(3)
    for _ in range(100):
        nominal = np.zeros(NOMINAL_SIZE)
        nominal[NM_POSITION : NM_POSITION + 3] = random_unit(rng) * 6.8e6
        nominal[NM_VELOCITY : NM_VELOCITY + 3] = random_unit(rng) * 7.6e3
        nominal[NM_THRUST_ACCEL : NM_THRUST_ACCEL + 3] = random_unit(rng) * 0.55
        measured = np.r_[
            nominal[NM_POSITION : NM_POSITION + 3] + rng.normal(0.0, 200.0, 3),
            nominal[NM_VELOCITY : NM_VELOCITY + 3] + rng.normal(0.0, 2.0, 3),
        ]
        k_r, k_v = rng.uniform(0.0, 0.01), rng.uniform(0.0, 0.1)
        for name, law in GUIDANCE_LAWS.items():
            deorbit.steer(measured, nominal, law, k_r, k_v, out)
            expected = naive.burn_direction(
                name,
                measured[0:3],
                measured[3:6],
                nominal[NM_POSITION : NM_POSITION + 3],
                nominal[NM_VELOCITY : NM_VELOCITY + 3],
                nominal[NM_THRUST_ACCEL : NM_THRUST_ACCEL + 3],
                k_r,
                k_v,
            )
            assert np.abs(out - expected).max() <= 1e-13, name
        deorbit.steer(measured, nominal, L.GUIDANCE_LAW_OPEN_LOOP_RETROGRADE, k_r, k_v, out)
        assert np.abs(out + unit(measured[3:6])).max() <= 1e-13  # anti-parallel to the measured velocity


def test_nominal_at_interpolates_like_numpy_and_holds_the_ends():
    """np.interp per column; the two formulas round differently: 1e-15 of each column's scale
    (positions 7e6 m), the bound 1e-13 of it."""
    rng = np.random.default_rng(9)
    rows = 41
    table = rng.normal(size=(rows, NOMINAL_SIZE)) * np.r_[1.0, [7e6] * 3, [7.6e3] * 3, [0.5] * 3]
    table[:, NM_T] = 300.0 + 0.5 * np.arange(rows)  # the guidance period's uniform rows
    out = np.zeros(NOMINAL_SIZE)
    scale = np.abs(table).max(axis=0)
    times = np.r_[rng.uniform(290.0, 330.0, 300), table[:, NM_T], 299.0, 300.0, 320.0, 321.0]
    for t in times:
        deorbit.nominal_at(table, t, out)
        expected = [np.interp(t, table[:, NM_T], table[:, i]) for i in range(NOMINAL_SIZE)]
        assert np.all(np.abs(out - expected) <= 1e-13 * scale)
        assert out[NM_T] == pytest.approx(min(max(t, 300.0), 320.0), abs=1e-12)
    single = table[:1].copy()
    deorbit.nominal_at(single, 1e4, out)
    assert np.array_equal(out, single[0])


# --------------------------------------------------------------------------------------------
# 7. hohmann_direction, nominal_burn
# --------------------------------------------------------------------------------------------


def hohmann_reference(state):
    r_hat = unit(state[0:3])
    return unit(-(state[3:6] - (state[3:6] @ r_hat) * r_hat))


def test_hohmann_direction_is_minus_the_horizontal_velocity():
    rng = np.random.default_rng(10)
    out = np.zeros(3)
    for _ in range(100):
        state = np.concatenate([random_unit(rng) * 6.8e6, random_unit(rng) * 7.6e3, [MASS]])
        deorbit.hohmann_direction(state, out)
        assert np.abs(out - hohmann_reference(state)).max() <= 1e-13
        assert abs(out @ unit(state[0:3])) <= 1e-13  # horizontal


BURN_APPROACHES = {
    "opposite_velocity": lambda ignition: lambda t, y: -unit(y[3:6]),
    "hohmann_direction": lambda ignition: (lambda d: lambda t, y: d)(hohmann_reference(ignition)),
}


@pytest.mark.parametrize("approach", BURN_APPROACHES)
@pytest.mark.parametrize("duration", [700.0, 812.3], ids=["whole", "fractional"])
def test_nominal_burn_matches_dop853(approach, duration):
    """The SPORE module's engine (40 N, 225 s, 75 kg) at 1 s rows and 0.1 s RK4 steps (812.3 s:
    814 rows 0.99914 s apart, 10 steps of 0.099914 s each). Ignition on the elliptical orbit,
    climbing, so that -v is not horizontal and the two approaches differ from the first row. RK4
    at 0.1 s errs by 1e-13 m per step: the gap to DOP853 is DOP853's own (module docstring)."""
    ignition = kepler_state(*ORBITS["elliptical"], 900.0)
    t_ignition = 300.0
    rows = math.ceil(duration - 1e-9) + 1
    table = np.zeros((rows, NOMINAL_SIZE))
    state = ignition.copy()
    deorbit.nominal_burn(
        state, t_ignition, duration, THRUST, MASS_FLOW, deorbit.APPROACHES[approach], MU, 0.1, table, stage()
    )
    direction = BURN_APPROACHES[approach](ignition)
    times = np.linspace(0.0, duration, rows)
    reference = solve_ivp(
        rhs(direction, THRUST, MASS_FLOW), (0.0, duration), ignition, t_eval=times, dense_output=True, **IVP
    )
    assert np.allclose(table[:, NM_T], t_ignition + times, rtol=0.0, atol=1e-12)
    assert np.abs(table[:, NM_POSITION : NM_POSITION + 3] - reference.y[0:3].T).max() <= IVP_M
    assert np.abs(table[:, NM_VELOCITY : NM_VELOCITY + 3] - reference.y[3:6].T).max() <= IVP_M_S
    last = table[-1]  # the state is returned at cut-off, the last row
    assert np.array_equal(state[0:6], np.r_[last[NM_POSITION : NM_POSITION + 3], last[NM_VELOCITY : NM_VELOCITY + 3]])
    assert np.abs(state[0:6] - reference.y[0:6, -1]).max() <= IVP_M
    assert state[6] == pytest.approx(MASS - MASS_FLOW * duration, abs=(rows - 1) * 10 * 4 * np.spacing(MASS))
    # thrust / m along the nominal direction, m = m0 - mdot (t - t_ignition). The kernel's mass has
    # up to 4 ulp (1.4e-14 kg each) of rounding per RK4 step: 8130 steps, 4.6e-10 kg in 60 kg,
    # 4e-12 m/s^2 of the 0.55 m/s^2 (measured 1e-13); adding the gravity (8.7 m/s^2) back to the
    # full derivative cancels to ~1e-15 m/s^2.
    steps = (rows - 1) * 10
    for row, t in zip(table, times, strict=True):
        y = np.r_[row[NM_POSITION : NM_POSITION + 3], row[NM_VELOCITY : NM_VELOCITY + 3]]
        mass = MASS - MASS_FLOW * t
        expected = THRUST / mass * direction(t, y)
        bound = THRUST / mass**2 * steps * 4 * np.spacing(MASS) + 1e-14
        assert np.abs(row[NM_THRUST_ACCEL : NM_THRUST_ACCEL + 3] - expected).max() <= bound


# --------------------------------------------------------------------------------------------
# 8. coast_to_entry
# --------------------------------------------------------------------------------------------


def coast_to_entry(state, step, max_time, r_entry=R_ENTRY):
    out = np.zeros(orbit.ORBIT_STATE_SIZE)
    t = deorbit.coast_to_entry(state, r_entry, MU, step, max_time, stage(), np.zeros(orbit.ORBIT_STATE_SIZE), out)
    return t, out


# (step, position m, velocity m/s, time s) of the kernel against Kepler's crossing. 1 s: rounding
# (module docstring), measured 3e-6 m. 10 s: RK4's global error, ~(n h)^4 r n t / 100 = 0.03 m
# after 5 rad of arc, measured 0.024 m and 3e-5 m/s; its time error is the radial part over the
# 170 m/s descent, measured 7e-6 s.
ENTRY_COAST = {1.0: (KEPLER_M, KEPLER_M_S, 1e-7), 10.0: (0.05, 1e-4, 1e-4)}
IVP_ENTRY_M = 5e-4  # DOP853 itself is 1.05e-4 m off Kepler after this 5000 s arc through a 50 km perigee


@pytest.mark.parametrize("step", ENTRY_COAST)
def test_coast_to_entry_matches_dop853_and_kepler(step):
    """From an elliptical orbit (perigee 50 km) 200 s after perigee, past the ascending crossing:
    nearly a whole orbit of coast to the descending one."""
    rp, ra = EARTH_RADIUS + 50e3, EARTH_RADIUS + 400e3
    start = kepler_state(rp, ra, 200.0)
    t, out = coast_to_entry(start, step, 2e4)
    t_kepler = time_from_perigee(rp, ra, R_ENTRY, descending=True)
    exact = kepler_state(rp, ra, t_kepler)
    tol_m, tol_m_s, tol_s = ENTRY_COAST[step]
    assert t == pytest.approx(t_kepler - 200.0, abs=tol_s)
    assert np.abs(out[0:3] - exact[0:3]).max() <= tol_m
    assert np.abs(out[3:6] - exact[3:6]).max() <= tol_m_s
    assert abs(np.linalg.norm(out[0:3]) - R_ENTRY) <= 1e-6 and orbit.climb_rate(out) < 0.0
    assert out[6] == start[6]
    reference = solve_ivp(rhs(), (0.0, 2e4), start, events=radius_event(R_ENTRY), **IVP)
    assert t == pytest.approx(reference.t_events[0][0], abs=max(tol_s, 1e-6))  # DOP853: 2e-8 s off Kepler
    assert np.abs(out[0:3] - reference.y_events[0][0][0:3]).max() <= max(tol_m, IVP_ENTRY_M)
    assert np.abs(out[3:6] - reference.y_events[0][0][3:6]).max() <= max(tol_m_s, IVP_ENTRY_M * 1e-3)


def test_coast_to_entry_finds_a_grazing_perigee():
    """Perigee 10 m below the entry interface: the orbit spends ~20 s below it. DOP853's event
    search looks only at its (~100 s) step ends and misses it; Kepler's time of flight does not.
    1 s steps see it."""
    rp, ra = R_ENTRY - 10.0, EARTH_RADIUS + 400e3
    t, out = coast_to_entry(kepler_state(rp, ra, 1000.0), 1.0, 2e4)
    assert t == pytest.approx(time_from_perigee(rp, ra, R_ENTRY, descending=True) - 1000.0, abs=1e-5)
    assert abs(np.linalg.norm(out[0:3]) - R_ENTRY) <= 1e-6


def test_coast_to_entry_is_nan_when_the_orbit_stays_above():
    """A circular 400 km orbit never comes down to 125 km: NaN after two orbits of coast."""
    t, _ = coast_to_entry(kepler_state(*ORBITS["circular"], 0.0), 1.0, 2.0 * 5554.0)
    assert math.isnan(t)
    # an orbit that does come down, but later than max_time: NaN too
    rp, ra = EARTH_RADIUS + 50e3, EARTH_RADIUS + 400e3
    t_cross = time_from_perigee(rp, ra, R_ENTRY, descending=True) - 200.0
    t, _ = coast_to_entry(kepler_state(rp, ra, 200.0), 10.0, t_cross - 20.0)
    assert math.isnan(t)


def test_coast_to_entry_is_nan_when_the_crossing_is_just_after_max_time():
    rp, ra = EARTH_RADIUS + 50e3, EARTH_RADIUS + 400e3
    t_cross = time_from_perigee(rp, ra, R_ENTRY, descending=True) - 205.0
    step = 10.0
    max_time = step * math.floor(t_cross / step) + 1e-3  # the step that holds the crossing starts before it
    assert 5.0 < t_cross - max_time < 6.0
    t, _ = coast_to_entry(kepler_state(rp, ra, 205.0), step, max_time)
    assert math.isnan(t), f"crossing at {t:.3f} s returned with max_time {max_time:.3f} s"


# --------------------------------------------------------------------------------------------
# 9. measure
# --------------------------------------------------------------------------------------------


def navigation(position_bias, velocity_bias, position_noise, velocity_noise):
    nav = np.zeros(NAV_SIZE)
    nav[N_GPS_POSITION_BIAS : N_GPS_POSITION_BIAS + 3] = position_bias
    nav[N_GPS_VELOCITY_BIAS : N_GPS_VELOCITY_BIAS + 3] = velocity_bias
    nav[N_GPS_POSITION_NOISE] = position_noise
    nav[N_GPS_VELOCITY_NOISE] = velocity_noise
    return nav


def test_measure_without_noise_is_truth_plus_bias_exactly():
    rng = np.random.default_rng(11)
    state = np.concatenate([random_unit(rng) * 6.8e6, random_unit(rng) * 7.6e3, [MASS]])
    nav = navigation(rng.normal(0, 10, 3), rng.normal(0, 0.1, 3), 0.0, 0.0)
    seed = np.array([12345], dtype=np.uint64)
    out = np.zeros(6)
    deorbit.measure(state, nav, seed, out)
    assert np.array_equal(out[0:3], state[0:3] + nav[N_GPS_POSITION_BIAS : N_GPS_POSITION_BIAS + 3])
    assert np.array_equal(out[3:6], state[3:6] + nav[N_GPS_VELOCITY_BIAS : N_GPS_VELOCITY_BIAS + 3])
    assert seed[0] == 12345  # no noise, no draws


def test_measure_with_noise_is_reproducible_and_has_the_stated_spread():
    state = np.concatenate([[6.8e6, 0.0, 0.0], [0.0, 7.6e3, 0.0], [MASS]])
    bias_r, bias_v = np.array([5.0, -3.0, 1.0]), np.array([0.1, 0.0, -0.2])
    nav = navigation(bias_r, bias_v, 10.0, 0.05)
    first, second = np.array([99], dtype=np.uint64), np.array([99], dtype=np.uint64)
    a, b = np.zeros(6), np.zeros(6)
    deorbit.measure(state, nav, first, a)
    deorbit.measure(state, nav, second, b)
    assert np.array_equal(a, b) and first[0] == second[0] != 99  # same seed, same draws; advanced
    deorbit.measure(state, nav, first, b)
    assert not np.array_equal(a, b)  # the next call draws afresh
    samples = np.zeros((4000, 6))
    for row in samples:
        deorbit.measure(state, nav, first, row)
    errors = samples - np.r_[state[0:3] + bias_r, state[3:6] + bias_v]
    sigma = np.r_[[10.0] * 3, [0.05] * 3]
    # 4000 draws: the mean is within 5 standard errors (sigma / 63), the spread within 5 %
    assert np.all(np.abs(errors.mean(axis=0)) <= 5.0 * sigma / math.sqrt(4000))
    assert np.all(np.abs(errors.std(axis=0) / sigma - 1.0) <= 0.05)
    assert np.abs(np.corrcoef(errors.T) - np.eye(6)).max() <= 0.1  # independent axes
