"""Aerodynamic angles from the body attitude (core.entry_attitude) against vectors built
independently with numpy: the air-relative velocity in body axes is V (cos a cos b, sin b,
sin a cos b), and the lift direction (-z_w) is the zero-bank lift turned by the bank towards the
right, as tests/test_entry.py's Cartesian propagation builds it. Rounding only: 1e-12."""

import math

import numpy as np
import pytest

from refexmc.core import entry_attitude, quaternion

OMEGA = 7.2921159e-5
TOL = 1e-12


def rotation_matrix(q):
    """Body-to-inertial matrix of a scalar-last quaternion (written out, not from the core)."""
    x, y, z, w = q
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def local_vectors(state, t):
    _h, lon, lat, _v, gamma, chi = state
    lon += OMEGA * t
    up = np.array([math.cos(lat) * math.cos(lon), math.cos(lat) * math.sin(lon), math.sin(lat)])
    east = np.array([-math.sin(lon), math.cos(lon), 0.0])
    north = np.cross(up, east)
    along = math.cos(gamma) * (math.cos(chi) * north + math.sin(chi) * east) + math.sin(gamma) * up
    lift0 = up - (up @ along) * along
    lift0 /= np.linalg.norm(lift0)
    return along, lift0, np.cross(along, lift0)


def random_cases(count, seed):
    rng = np.random.default_rng(seed)
    for _ in range(count):
        state = np.array(
            [
                rng.uniform(20e3, 120e3),
                rng.uniform(-math.pi, math.pi),
                rng.uniform(-1.3, 1.3),
                rng.uniform(500.0, 7500.0),
                rng.uniform(-0.3, 0.1),
                rng.uniform(-math.pi, math.pi),
            ]
        )
        yield state, rng.uniform(0.0, 3000.0), rng.uniform(-0.5, 1.2), rng.uniform(-0.4, 0.4), rng.uniform(-3.1, 3.1)


def test_the_attitude_of_given_angles_has_the_velocity_and_lift_where_they_belong():
    scratch = np.zeros(entry_attitude.AXES_SCRATCH)
    q = np.zeros(4)
    for state, t, alpha, beta, bank in random_cases(300, seed=1):
        entry_attitude.attitude_from_angles(state, t, OMEGA, alpha, beta, bank, scratch, q)
        body_to_inertial = rotation_matrix(q)
        along, lift0, right0 = local_vectors(state, t)
        expected_velocity = [math.cos(alpha) * math.cos(beta), math.sin(beta), math.sin(alpha) * math.cos(beta)]
        assert body_to_inertial.T @ along == pytest.approx(expected_velocity, abs=TOL)
        lift = body_to_inertial @ np.array([math.sin(alpha), 0.0, -math.cos(alpha)])
        assert lift == pytest.approx(math.cos(bank) * lift0 + math.sin(bank) * right0, abs=TOL)
        assert np.linalg.norm(q) == pytest.approx(1.0, abs=TOL)


def test_angles_of_an_attitude_round_trip():
    scratch = np.zeros(entry_attitude.AXES_SCRATCH)
    q = np.zeros(4)
    for state, t, alpha, beta, bank in random_cases(300, seed=2):
        entry_attitude.attitude_from_angles(state, t, OMEGA, alpha, beta, bank, scratch, q)
        got = entry_attitude.aerodynamic_angles(state, t, OMEGA, q, scratch)
        assert got == pytest.approx((alpha, beta, bank), abs=1e-10)  # asin near |beta| 0.4: ~1e-15 / cos


def test_a_roll_about_the_velocity_changes_the_bank_only():
    """Turning the body about the air-relative velocity by phi adds phi to the bank."""
    scratch = np.zeros(entry_attitude.AXES_SCRATCH)
    q, turn, turned = np.zeros(4), np.zeros(4), np.zeros(4)
    state = np.array([70e3, 0.3, -0.4, 6500.0, -0.01, 1.0])
    entry_attitude.attitude_from_angles(state, 100.0, OMEGA, 0.7, 0.0, 0.2, scratch, q)
    along, _, _ = local_vectors(state, 100.0)
    phi = 0.5
    quaternion.from_rotation_vector(*(phi * along), turn)
    quaternion.multiply(turn, q, turned)
    alpha, beta, bank = entry_attitude.aerodynamic_angles(state, 100.0, OMEGA, turned, scratch)
    assert (alpha, beta, bank) == pytest.approx((0.7, 0.0, 0.7), abs=1e-12)
