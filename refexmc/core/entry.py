"""Entry flight over a rotating spherical Earth (003 eq. 3), lift, drag and side force from the
aerodynamic tables (core.aerodynamics) and the standard atmosphere (core.atmosphere).

State ``[h, lambda, delta, V, gamma, chi]``: altitude (m), longitude and geocentric latitude
(rad), speed relative to the Earth (and to the air, which turns with it) (m/s), flight-path
angle and heading (rad; heading from north towards east). The aerodynamic angles alpha, beta and
the bank mu are inputs; a positive bank turns the lift to the right (heading grows).

003 eq. 3 as printed has the longitude and latitude rates swapped (the 1/cos(delta) belongs to
the longitude) and the sign of the centripetal term in gamma-dot reversed; this module flies the
consistent form (heading from north, as in Vinh, *Hypersonic and Planetary Entry Flight
Mechanics*, ch. 2), which ``tests/test_entry.py`` checks against an independent Cartesian
Earth-centred propagation. The
deorbit module's thrust (003's T_deorbit) is off: it is jettisoned before the entry interface.
Gravity is central, g = mu / r^2.
"""

from typing import NamedTuple

import numpy as np

from refexmc._jit import jit_noalloc
from refexmc.core import aerodynamics, atmosphere, elementary
from refexmc.core.aerodynamics import AC_DRAG, AC_LIFT, AC_SIDE_BETA

ENTRY_STATE_SIZE = 6
EN_ALTITUDE, EN_LONGITUDE, EN_LATITUDE, EN_SPEED, EN_FLIGHT_PATH, EN_HEADING = range(ENTRY_STATE_SIZE)
PLANET_RADIUS = 0  # m
PLANET_MU = 1  # gravitational parameter, m^3/s^2
PLANET_ROTATION = 2  # rad/s
REF_AREA = 0  # aerodynamic reference area S, m^2
REF_LENGTH = 1  # reference length for moments, m


class EntryModel(NamedTuple):
    """What the entry equations need besides the state: planet, air and the aerodynamic tables."""

    planet: np.ndarray  # (3,) PLANET_*
    atmosphere: np.ndarray  # (n, 4) core.atmosphere table
    alpha_axis: np.ndarray  # (n_alpha,) rad
    mach_axis: np.ndarray  # (n_mach,)
    coefficients: np.ndarray  # (AERO_COEFFICIENTS, n_alpha, n_mach)
    reference: np.ndarray  # (2,) REF_*


@jit_noalloc
def air_data(model, state):
    """Density (kg/m^3), dynamic pressure (Pa) and Mach number at ``state``."""
    rho, sound, _ = atmosphere.properties(model.atmosphere, state[EN_ALTITUDE])
    v = state[EN_SPEED]
    return rho, 0.5 * rho * v * v, v / sound


@jit_noalloc
def aerodynamic_forces(model, state, alpha, beta):
    """Lift, drag and side force (N) at the aerodynamic angles ``alpha``, ``beta`` (rad)."""
    _, qbar, mach = air_data(model, state)
    qs = qbar * model.reference[REF_AREA]
    lift = qs * aerodynamics.coefficient(model.alpha_axis, model.mach_axis, model.coefficients, AC_LIFT, alpha, mach)
    drag = qs * aerodynamics.coefficient(model.alpha_axis, model.mach_axis, model.coefficients, AC_DRAG, alpha, mach)
    side_beta = aerodynamics.coefficient(
        model.alpha_axis, model.mach_axis, model.coefficients, AC_SIDE_BETA, alpha, mach
    )
    return lift, drag, qs * side_beta * beta


@jit_noalloc
def derivative(model, state, mass, alpha, beta, bank, out):
    """d/dt of the entry state, 003 eq. 3 (corrected as in the module docstring)."""
    lift, drag, side = aerodynamic_forces(model, state, alpha, beta)
    equations_of_motion(model, state, mass, bank, lift, drag, side, out)


@jit_noalloc
def equations_of_motion(model, state, mass, bank, lift, drag, side, out):
    """003 eq. 3 for given lift, drag and side force (N) and bank (rad)."""
    h, delta, v, gamma, chi = (
        state[EN_ALTITUDE],
        state[EN_LATITUDE],
        state[EN_SPEED],
        state[EN_FLIGHT_PATH],
        state[EN_HEADING],
    )
    r = model.planet[PLANET_RADIUS] + h
    omega = model.planet[PLANET_ROTATION]
    g = model.planet[PLANET_MU] / (r * r)
    sin_g, cos_g = elementary.sincos(gamma)
    sin_c, cos_c = elementary.sincos(chi)
    sin_d, cos_d = elementary.sincos(delta)
    sin_m, cos_m = elementary.sincos(bank)
    centripetal = omega * omega * r * cos_d
    out[EN_ALTITUDE] = v * sin_g
    out[EN_LONGITUDE] = v * cos_g * sin_c / (r * cos_d)
    out[EN_LATITUDE] = v * cos_g * cos_c / r
    out[EN_SPEED] = -drag / mass - g * sin_g + centripetal * (sin_g * cos_d - cos_g * sin_d * cos_c)
    out[EN_FLIGHT_PATH] = (
        (lift * cos_m - side * sin_m) / (mass * v)
        + cos_g * (v / r - g / v)
        + 2.0 * omega * cos_d * sin_c
        + centripetal / v * (cos_g * cos_d + sin_g * sin_d * cos_c)
    )
    out[EN_HEADING] = (
        (lift * sin_m + side * cos_m) / (mass * v * cos_g)
        + v * cos_g * sin_c * elementary.tan(delta) / r
        - 2.0 * omega * (elementary.tan(gamma) * cos_d * cos_c - sin_d)
        + centripetal / (v * cos_g) * sin_d * sin_c
    )


@jit_noalloc
def rk4_step(model, state, dt, mass, alpha, beta, bank, stage):
    """One classical Runge-Kutta step of ``dt`` seconds in place, the aerodynamic angles and bank
    held over the step; ``stage`` is (5, ENTRY_STATE_SIZE) scratch."""
    k1, k2, k3, k4, tmp = stage[0], stage[1], stage[2], stage[3], stage[4]
    n = ENTRY_STATE_SIZE
    derivative(model, state, mass, alpha, beta, bank, k1)
    for i in range(n):
        tmp[i] = state[i] + 0.5 * dt * k1[i]
    derivative(model, tmp, mass, alpha, beta, bank, k2)
    for i in range(n):
        tmp[i] = state[i] + 0.5 * dt * k2[i]
    derivative(model, tmp, mass, alpha, beta, bank, k3)
    for i in range(n):
        tmp[i] = state[i] + dt * k3[i]
    derivative(model, tmp, mass, alpha, beta, bank, k4)
    for i in range(n):
        state[i] += dt / 6.0 * (k1[i] + 2.0 * (k2[i] + k3[i]) + k4[i])


@jit_noalloc
def ranges(start, end, radius):
    """Down-range and cross-range (m) of ``end`` from ``start`` (entry states) over a sphere of
    ``radius``: along and off the great circle leaving ``start`` at its heading, as arcs; the
    cross-range is positive to the right of that great circle. Earth-fixed longitudes."""
    lat0, lon0, chi0 = start[EN_LATITUDE], start[EN_LONGITUDE], start[EN_HEADING]
    lat1, lon1 = end[EN_LATITUDE], end[EN_LONGITUDE]
    # unit vectors: the start point p, its heading direction e, the end point x
    sin_lat0, cos_lat0 = elementary.sincos(lat0)
    sin_lon0, cos_lon0 = elementary.sincos(lon0)
    sin_chi0, cos_chi0 = elementary.sincos(chi0)
    sin_lat1, cos_lat1 = elementary.sincos(lat1)
    sin_lon1, cos_lon1 = elementary.sincos(lon1)
    px, py, pz = cos_lat0 * cos_lon0, cos_lat0 * sin_lon0, sin_lat0
    north_x, north_y, north_z = -sin_lat0 * cos_lon0, -sin_lat0 * sin_lon0, cos_lat0
    east_x, east_y, east_z = -sin_lon0, cos_lon0, 0.0
    ex = cos_chi0 * north_x + sin_chi0 * east_x
    ey = cos_chi0 * north_y + sin_chi0 * east_y
    ez = cos_chi0 * north_z + sin_chi0 * east_z
    xx, xy, xz = cos_lat1 * cos_lon1, cos_lat1 * sin_lon1, sin_lat1
    # the great circle's pole n = p x e; the right-hand side of the track is -n
    nx, ny, nz = py * ez - pz * ey, pz * ex - px * ez, px * ey - py * ex
    off = -(nx * xx + ny * xy + nz * xz)
    cross = radius * elementary.asin(min(max(off, -1.0), 1.0))
    down = radius * elementary.atan2(ex * xx + ey * xy + ez * xz, px * xx + py * xy + pz * xz)
    return down, cross
