"""The entry attitude and control kernels against their plain-Python twins (tests/naive.py, from 003).

core.entry_attitude (alpha, beta, bank of a body attitude, and the attitude of given angles) and
the control part of core.entry_flight (outer loops on alpha, beta, bank with integral action,
dynamic inversion of 003 eq. 4, the mode program and the surfaces' bounds, the moments of eq. 6
and 10, the alignment of the free flap, the hinge-moment limit, the actuators) on random flight
states of the X-38, with and without a blocked flap, above and below the RCS-only altitude and
Mach 6.

Tolerances: kernel and twin evaluate the same float64 expressions by other routes (quaternion
rotations against matrices, an explicit kinematic inversion against a linear solve, the kernels'
bilinear tables against scipy's, brentq against closed forms); each route rounds at ~1e-16
relative per operation over some hundred operations, so 1e-9 relative (angles 1e-10 rad) holds
with a margin of 1e4 and still fails on any wrong sign, term or factor (which moves results by
far more than 1e-6).
"""

import math
from pathlib import Path

import numpy as np
import pytest
from naive import (
    entry_actuate,
    entry_aerodynamic_angles,
    entry_alignment_bias,
    entry_body_axes,
    entry_control,
    entry_hinge_limit,
    entry_trim_alpha,
    quaternion_matrix,
)

from refexmc.config import entry as config_entry
from refexmc.config.load import load_vehicle
from refexmc.core import aerodynamics as aero
from refexmc.core import entry_attitude
from refexmc.core import entry_flight as ef

ROOT = Path(__file__).resolve().parents[1]
ALPHA_SCHEDULE = [(2.0, 20.0), (5.0, 30.0), (10.0, 40.0), (30.0, 40.0)]
BANK_SCHEDULE = [(1000.0, 30.0), (3000.0, 45.0), (7000.0, 60.0)]
SAMPLES = 300
ANGLE_TOLERANCE_RAD = 1e-10
RELATIVE_TOLERANCE = 1e-9
SLOTS = config_entry.coefficient_slots()
BLOCKED_CASES = {  # name -> entry_vehicle keywords
    "both flaps free": {},
    "right blocked at 14 deg, known": {"blocked": ("right", 14.0)},
    "left blocked at 12 deg, known": {"blocked": ("left", 12.0)},
    "right blocked at 18 deg, unknown": {"blocked": ("right", 18.0), "blocked_known": False},
}


@pytest.fixture(scope="module")
def x38():
    return load_vehicle(ROOT / "configs/vehicles/x38.yaml")


def random_state(rng):
    """An entry state [h, lon, lat, V, gamma, chi] on both sides of 90 km and of Mach 6."""
    return np.array(
        [
            rng.uniform(30_000.0, 120_000.0),
            rng.uniform(-math.pi, math.pi),
            rng.uniform(-1.2, 1.2),
            rng.uniform(1_200.0, 7_500.0),
            rng.uniform(-0.1, 0.02),
            rng.uniform(-math.pi, math.pi),
        ]
    )


def random_angles(rng):
    return rng.uniform(0.1, 0.9), rng.uniform(-0.06, 0.06), rng.uniform(-1.6, 1.6)


def test_aerodynamic_angles_equal_the_twin_on_random_attitudes():
    rng = np.random.default_rng(24)
    scratch = np.zeros(entry_attitude.AXES_SCRATCH)
    rotation = 7.2921159e-5
    for _ in range(SAMPLES):
        state, t = random_state(rng), rng.uniform(0.0, 2_000.0)
        quaternion = rng.normal(size=4)
        quaternion /= np.linalg.norm(quaternion)  # any attitude, not only flyable ones
        kernel = entry_attitude.aerodynamic_angles(state, t, rotation, quaternion, scratch)
        twin = entry_aerodynamic_angles(state, t, rotation, quaternion)
        difference = np.array(kernel) - np.array(twin)
        difference[2] = (difference[2] + math.pi) % (2 * math.pi) - math.pi  # bank near +-pi
        assert np.abs(difference).max() < ANGLE_TOLERANCE_RAD, (state, quaternion, kernel, twin)


def test_the_attitude_of_given_angles_equals_the_twin():
    rng = np.random.default_rng(25)
    scratch = np.zeros(entry_attitude.AXES_SCRATCH)
    quaternion = np.zeros(4)
    rotation = 7.2921159e-5
    for _ in range(SAMPLES):
        state, t = random_state(rng), rng.uniform(0.0, 2_000.0)
        alpha, beta, bank = random_angles(rng)
        entry_attitude.attitude_from_angles(state, t, rotation, alpha, beta, bank, scratch, quaternion)
        twin = entry_body_axes(state, t, rotation, alpha, beta, bank)
        assert np.abs(quaternion_matrix(quaternion) - twin).max() < RELATIVE_TOLERANCE
        assert np.allclose(twin.T @ twin, np.eye(3), atol=1e-12)  # the twin is a rotation itself


def test_the_twins_are_not_blind_to_the_bank_sign():
    """The bank convention of the twin: a positive bank turns the lift (-z_w) to the right (y_k)."""
    state = np.array([60_000.0, 0.3, 0.2, 6_000.0, -0.02, 0.7])
    body = entry_body_axes(state, 0.0, 0.0, 0.5, 0.0, 0.4)
    from naive import body_from_wind, entry_trajectory_axes

    lift = -(body @ body_from_wind(0.5, 0.0)[:, 2])
    assert lift @ entry_trajectory_axes(state, 0.0, 0.0)[:, 1] == pytest.approx(math.sin(0.4))


def prepared(x38, keywords):
    return config_entry.entry_vehicle(x38, ALPHA_SCHEDULE, BANK_SCHEDULE, **keywords)


@pytest.mark.parametrize("case", list(BLOCKED_CASES))
def test_control_equals_the_twin_on_random_flight_states(x38, case):
    """The outer loops, the dynamic inversion of eq. 4, the mode program and bounds, eq. 6/10's
    surface moments, and the blend's optimum (the twin's vertex enumeration) where no thruster
    saturates; the thrusters' share clipped at their capacity where one does."""
    from naive import blend_candidates, blend_rate

    vehicle = prepared(x38, BLOCKED_CASES[case])
    ct = vehicle.control
    rng = np.random.default_rng(sum(map(ord, case)))
    scratch = np.zeros(entry_attitude.AXES_SCRATCH)
    wk = ef.work()
    rotation = vehicle.model.planet[2]
    modes_seen, saturated = set(), 0
    for _ in range(SAMPLES):
        state = np.zeros(ef.FLIGHT_STATE_SIZE)
        state[:6] = random_state(rng)
        t = rng.uniform(0.0, 2_000.0)
        angles = random_angles(rng)
        entry_attitude.attitude_from_angles(state[:6], t, rotation, *angles, scratch, state[6:10])
        limits = ct[ef.CT_INTEGRAL_LIMIT : ef.CT_INTEGRAL_LIMIT + 3]
        deflection = rng.uniform(-0.3, 0.3, 3)
        if rng.uniform() < 0.5:  # far from the commands: large moments, the thrusters saturate
            state[10:13] = rng.uniform(-0.05, 0.05, 3)
            integral = rng.uniform(-1.2, 1.2, 3) * limits  # some beyond the clamp
            alpha_cmd, bank_cmd = rng.uniform(0.3, 0.8), rng.uniform(-1.2, 1.2)
        else:  # near the commands: moments the blend gives within the thrusters' capacity
            state[10:13] = rng.uniform(-2e-4, 2e-4, 3)
            integral = rng.uniform(-1e-3, 1e-3, 3) * limits
            alpha_cmd, bank_cmd = angles[0] + rng.normal(0.0, 1e-3), angles[2] + rng.normal(0.0, 1e-3)
        wk.state[:] = state
        wk.integral[:] = integral
        wk.deflection[:] = deflection
        rate, alpha, beta, bank, mach, qbar, mode = ef.control(vehicle, wk, t, alpha_cmd, bank_cmd)
        twin = entry_control(vehicle, state, t, deflection, integral, alpha_cmd, bank_cmd, qbar, mach, SLOTS)
        difference = np.array((alpha, beta, bank)) - np.array(twin["angles"])
        difference[2] = (difference[2] + math.pi) % (2 * math.pi) - math.pi
        assert np.abs(difference).max() < ANGLE_TOLERANCE_RAD
        assert np.allclose(wk.integral, twin["integral"], rtol=RELATIVE_TOLERANCE, atol=1e-12)
        scale = np.abs(twin["moment"]).max() + 1.0
        assert np.abs(wk.torque - twin["moment"]).max() < RELATIVE_TOLERANCE * scale, (case, state)
        assert mode == twin["mode"]
        modes_seen.add(mode)
        assert np.allclose(wk.lower, twin["lower"], rtol=1e-12, atol=1e-14)
        assert np.allclose(wk.upper, twin["upper"], rtol=1e-12, atol=1e-14)
        size = np.abs(twin["effectiveness"]).max() + 1.0
        assert np.abs(wk.effectiveness - twin["effectiveness"]).max() < RELATIVE_TOLERANCE * size
        assert np.abs(wk.offset - twin["offset"]).max() < RELATIVE_TOLERANCE * (np.abs(twin["offset"]).max() + 1.0)
        weights = ct[ef.CT_WEIGHTS : ef.CT_WEIGHTS + 3]
        capacity = ct[ef.CT_RCS_CAPACITY : ef.CT_RCS_CAPACITY + 3]
        assert (np.abs(wk.thruster) <= capacity).all()
        assert rate == pytest.approx(float(weights @ np.abs(wk.thruster)), rel=1e-12)
        assert (twin["lower"] - 1e-12 <= wk.command).all() and (wk.command <= twin["upper"] + 1e-12).all()
        unsaturated = twin["moment"] - (twin["effectiveness"] @ wk.command + twin["offset"])
        if (np.abs(unsaturated) < capacity).all():
            best = min(
                blend_rate(twin["effectiveness"], twin["offset"], twin["moment"], weights, d)
                for d in blend_candidates(
                    twin["effectiveness"], twin["offset"], twin["moment"], twin["lower"], twin["upper"]
                )
            )
            assert rate == pytest.approx(best, rel=1e-9, abs=1e-15)  # the LP optimum (issue 24: 1e-9)
            assert np.allclose(wk.thruster, unsaturated, rtol=1e-9, atol=1e-9 * scale)
        else:
            saturated += 1
            assert np.allclose(wk.thruster, np.clip(unsaturated, -capacity, capacity), rtol=1e-9, atol=1e-9 * scale)
    assert modes_seen == {0, 1, 2}, f"the random states must cover every mode, saw {modes_seen}"
    assert 30 <= saturated <= SAMPLES - 30, f"both branches need samples: {saturated} of {SAMPLES} saturated"


def test_trim_alpha_and_the_alignment_bias_equal_the_twins(x38):
    vehicle = prepared(x38, {"blocked": ("right", 14.0)})
    model, ct = vehicle.fsw_model, vehicle.control
    slots = (aero.AC_PITCH, aero.AC_PITCH_ELEVON)
    rng = np.random.default_rng(7)
    wk = ef.work()
    found = 0
    for _ in range(SAMPLES):
        mach, deflection = rng.uniform(2.0, 25.0), math.radians(rng.uniform(5.0, 20.0))
        kernel = ef.trim_alpha(model, mach, deflection, -1.0)
        twin = entry_trim_alpha(model, slots, mach, deflection, -1.0)
        assert kernel == pytest.approx(twin, abs=1e-12)  # brentq to 1e-15 on a linear cell
        found += kernel != -1.0
        # one alignment step below the RCS-only altitude from a random bias and free-flap deflection
        wk.state[:6] = random_state(rng)
        wk.state[0] = rng.uniform(30_000.0, 85_000.0)
        wk.alpha_bias[0] = rng.uniform(-0.2, 0.2)
        wk.deflection[0] = rng.uniform(-0.1, 0.4)  # the free (left) flap
        bias = wk.alpha_bias[0]
        vehicle.surfaces[ef.SF_BLOCKED_DEFLECTION] = deflection
        command = ef.align(vehicle, wk, mach, 1, -1.0)
        base = entry_trim_alpha(model, slots, mach, deflection, -1.0)
        expected = entry_alignment_bias(
            model,
            slots,
            mach,
            base + bias,
            wk.deflection[0],
            deflection,
            bias,
            ct[ef.CT_ALIGN_GAIN],
            ct[ef.CT_PERIOD],
            ct[ef.CT_ALIGN_LIMIT],
        )
        assert wk.alpha_bias[0] == pytest.approx(expected, rel=1e-9, abs=1e-12)
        assert command == pytest.approx(base + expected, rel=1e-9, abs=1e-12)
    assert found > SAMPLES // 2, "most conditions must have a trim alpha for the test to mean something"


def test_hinge_limit_and_actuators_equal_the_twins(x38):
    rng = np.random.default_rng(11)
    for _ in range(SAMPLES):
        qbar, alpha = rng.uniform(0.0, 60_000.0), rng.uniform(0.1, 0.9)
        kernel = ef.hinge_limit(qbar, alpha, 25_881.0, 0.44)  # 003 Table 1; x38.yaml's S_f c
        assert kernel == pytest.approx(entry_hinge_limit(qbar, alpha, 25_881.0, 0.44), abs=1e-12)
    vehicle = prepared(x38, {})
    vehicle_surfaces = vehicle.surfaces  # changed in place below: this test's own vehicle
    wk = ef.work()
    for _ in range(SAMPLES):
        blocked = int(rng.integers(-1, 2))
        rates = rng.uniform(0.05, 0.5, 2)
        vehicle_surfaces[ef.SF_FLAP_RATE], vehicle_surfaces[ef.SF_RUDDER_RATE] = rates
        vehicle_surfaces[ef.SF_TIME_CONSTANT] = rng.choice([0.0, rng.uniform(0.02, 0.5)])
        vehicle_surfaces[ef.SF_BLOCKED_FLAP] = blocked
        vehicle_surfaces[ef.SF_BLOCKED_DEFLECTION] = rng.uniform(0.1, 0.3)
        wk.command[:] = rng.uniform(-0.4, 0.4, 3)
        wk.deflection[:] = rng.uniform(-0.4, 0.4, 3)
        before = wk.deflection.copy()
        dt = rng.uniform(0.02, 0.2)
        ef.actuate(vehicle, wk, dt)
        twin = entry_actuate(
            wk.command,
            before,
            blocked,
            vehicle_surfaces[ef.SF_BLOCKED_DEFLECTION],
            (rates[0], rates[0], rates[1]),
            vehicle_surfaces[ef.SF_TIME_CONSTANT],
            dt,
        )
        assert np.allclose(wk.deflection, twin, rtol=1e-14, atol=1e-15)
