"""The coupled 6-DOF entry (core.entry_flight: 003 eq. 3 and eq. 4 through the aerodynamic
angles of the body attitude) flown open loop, surfaces held and thrusters silent, against
``solve_ivp`` (DOP853, rtol 1e-12) on a right-hand side written here: the angles from a rotation
matrix and vectors built with numpy, the coefficients by scipy's interpolator, Euler's equation
with the full inertia (I_xz) solved by numpy, the quaternion rate q_dot = q (x) (omega, 0) / 2.

Tolerance: the kernel integrates with RK4 at 0.02 s; over 60 s of glide its error
is ~1e-7 relative (measured 9e-8); 1e-6 of each component's largest magnitude (as tests/test_entry.py) holds with
margin while a wrong sign, axis or inertia term is off by orders more.
"""

import math
from pathlib import Path

import naive
import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.interpolate import RegularGridInterpolator

from refexmc.config import entry as config_entry
from refexmc.config.load import load_vehicle
from refexmc.core import entry_attitude
from refexmc.core import entry_flight as ef

ROOT = Path(__file__).resolve().parents[1]
DT_S = 0.02
DURATION_S = 60.0
DEFLECTION = np.radians([16.0, 12.0, 3.0])  # left, right, rudder: held
COMPONENT_REL = 1e-6


def flown():
    vehicle = load_vehicle(ROOT / "configs/vehicles/x38.yaml")
    return vehicle, config_entry.entry_vehicle(vehicle, [(1.0, 40.0)], [(1.0, 60.0)])


def initial_state(model):
    x = np.zeros(ef.FLIGHT_STATE_SIZE)
    x[:6] = [75_000.0, 1.0, -0.4, 7_000.0, math.radians(-1.0), 0.8]
    scratch = np.zeros(entry_attitude.AXES_SCRATCH)
    entry_attitude.attitude_from_angles(x[:6], 0.0, model.planet[2], math.radians(38.0), 0.01, 0.9, scratch, x[6:10])
    x[10:13] = [0.01, -0.005, 0.02]
    return x


def rotation_matrix(q):
    x, y, z, w = q / np.linalg.norm(q)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def reference_rhs(vehicle, model, inertia, thruster=np.zeros(3)):  # noqa: B008 - read only
    """The right-hand side of the 6-DOF entry; ``thruster``: the thrusters' body moment (N m)."""
    tables = vehicle["entry_aerodynamics"]
    alpha_axis = np.radians(tables["alpha_deg"])
    mach_axis = np.array(tables["mach"])
    # one interpolator of the 11 coefficient tables stacked: the same bilinear weights on each
    # (scipy's vector path rounds apart from its scalar one by <= 5e-16 relative, measured), one
    # call in each right-hand side instead of 11 (0.6 ms against 3.4 ms)
    keys = list(tables["coefficients"])
    interpolator = RegularGridInterpolator(
        (alpha_axis, mach_axis), np.stack([np.array(tables["coefficients"][key]) for key in keys], axis=-1)
    )
    atmosphere = model.atmosphere
    radius, mu, omega = model.planet
    area, length = model.reference
    mass = vehicle["mass_kg"]

    def rhs(t, y):
        h, lon, lat, v, gamma, chi = y[:6]
        q, w = y[6:10], y[10:13]
        lon_i = lon + omega * t
        up = np.array([math.cos(lat) * math.cos(lon_i), math.cos(lat) * math.sin(lon_i), math.sin(lat)])
        east = np.array([-math.sin(lon_i), math.cos(lon_i), 0.0])
        north = np.cross(up, east)
        along = math.cos(gamma) * (math.cos(chi) * north + math.sin(chi) * east) + math.sin(gamma) * up
        body_to_inertial = rotation_matrix(q)
        vb = body_to_inertial.T @ along
        alpha, beta = math.atan2(vb[2], vb[0]), math.asin(vb[1])
        lift_dir = body_to_inertial @ np.array([math.sin(alpha), 0.0, -math.cos(alpha)])
        lift0 = up - (up @ along) * along
        lift0 /= np.linalg.norm(lift0)
        bank = math.atan2(lift_dir @ np.cross(along, lift0), lift_dir @ lift0)
        rho = math.exp(np.interp(h, atmosphere[:, 0], atmosphere[:, 1]))
        mach = v / np.interp(h, atmosphere[:, 0], atmosphere[:, 2])
        point = [[min(max(alpha, alpha_axis[0]), alpha_axis[-1]), min(max(mach, mach_axis[0]), mach_axis[-1])]]
        c = {key: float(value) for key, value in zip(keys, interpolator(point)[0], strict=True)}
        qbar = 0.5 * rho * v * v

        def forces(_rho, _v, _sound):
            return qbar * area * c["lift"], qbar * area * c["drag"], qbar * area * c["side_force_per_beta_rad"] * beta

        translation = naive.entry_derivative(y[:6], radius, mu, omega, lambda _h: (rho, 0.0), forces, mass, bank)
        moment = naive.entry_aero_moment(c, qbar * area * length, beta, DEFLECTION)
        w_dot = np.linalg.solve(inertia, moment + thruster - np.cross(w, inertia @ w))
        qx, qy, qz, qw = q
        wx, wy, wz = w
        q_dot = 0.5 * np.array(  # q (x) (omega, 0), scalar last
            [
                qw * wx + qy * wz - qz * wy,
                qw * wy + qz * wx - qx * wz,
                qw * wz + qx * wy - qy * wx,
                -(qx * wx + qy * wy + qz * wz),
            ]
        )
        return np.concatenate([translation, q_dot, w_dot])

    return rhs


@pytest.mark.slow
def test_the_coupled_open_loop_flight_equals_solve_ivp():
    vehicle, vehicle_arrays = flown()
    x0 = initial_state(vehicle_arrays.model)
    wk = ef.work()
    wk.state[:] = x0
    wk.deflection[:] = DEFLECTION
    wk.thruster[:] = 0.0
    t = 0.0
    for _ in range(round(DURATION_S / DT_S)):
        ef.rk4_step(vehicle_arrays, wk, t, DT_S)
        t += DT_S
    rhs = reference_rhs(vehicle, vehicle_arrays.model, vehicle_arrays.inertia)
    reference = solve_ivp(rhs, (0.0, DURATION_S), x0, method="DOP853", rtol=1e-12, atol=1e-12)
    assert reference.success
    scale = np.maximum(np.abs(reference.y).max(axis=1), 1e-3)
    error = np.abs(wk.state - reference.y[:, -1]) / scale
    assert error.max() <= COMPONENT_REL, f"relative errors {error}"
    # the attitude did move: the comparison covers the coupling, not a resting body
    assert np.abs(reference.y[10:13, -1] - x0[10:13]).max() > 1e-3


@pytest.mark.slow
def test_a_delayed_thruster_moment_equals_solve_ivp_switching_at_the_delay():
    """core.entry_flight.advance with an RCS delay (issue 24): each period's thruster moment acts
    from the delay after the control instant, the previous one until then. The reference is
    solve_ivp (DOP853, rtol 1e-12) on the independent right-hand side above, restarted at every
    switch with the moment then acting. The kernel's RK4 steps are 0.015 s and 0.035 s here, so
    its error stays near the open-loop test's (1e-6 of each component's largest magnitude)."""
    vehicle, vehicle_arrays = flown()
    x0 = initial_state(vehicle_arrays.model)
    period, delay, periods = 0.05, 0.015, 200  # 10 s
    moments = [np.array([300.0 * math.sin(k), -400.0 * math.cos(0.7 * k), 250.0]) for k in range(periods)]
    wk = ef.work()
    wk.state[:] = x0
    wk.deflection[:] = DEFLECTION
    y, t = x0.copy(), 0.0
    for k in range(periods):
        wk.thruster[:] = moments[k]
        ef.advance(vehicle_arrays, wk, t, period, delay)
        previous = moments[k - 1] if k > 0 else np.zeros(3)
        for start, end, moment in ((t, t + delay, previous), (t + delay, t + period, moments[k])):
            rhs = reference_rhs(vehicle, vehicle_arrays.model, vehicle_arrays.inertia, moment)
            segment = solve_ivp(rhs, (start, end), y, method="DOP853", rtol=1e-12, atol=1e-12)
            assert segment.success
            y = segment.y[:, -1]
        t = (k + 1) * period
    scale = np.maximum(np.abs(np.stack([x0, y])).max(axis=0), 1e-3)
    error = np.abs(wk.state - y) / scale
    assert error.max() <= COMPONENT_REL, f"relative errors {error}"
    # the delay matters at this tolerance: the same moments without it end elsewhere
    undelayed = ef.work()
    undelayed.state[:] = x0
    undelayed.deflection[:] = DEFLECTION
    for k in range(periods):
        undelayed.thruster[:] = moments[k]
        ef.advance(vehicle_arrays, undelayed, k * period, period, 0.0)
    assert (np.abs(undelayed.state - y) / scale).max() > 100 * COMPONENT_REL
