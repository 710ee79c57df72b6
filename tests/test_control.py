"""PD control with partial feedback linearisation (000 eq. 30, 35, 36) against its twin and closed forms."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from naive import pd_feedback_linearisation_torque

from refexmc.core import control, layout

# An inertia in kg m^2 with off-diagonal products (refex.yaml-like, not its numbers): every term
# of J v + omega x J omega is exercised.
INERTIA = np.array([[88.0, -1.2, 3.4], [-1.2, 410.0, 0.8], [3.4, 0.8, 420.0]])
KP, KD = np.array([0.5, 0.3, 0.3]), np.array([1.4, 1.1, 1.1])
# Kernel and twin sum the same products in different orders: they agree to a few ulp of the largest
# term (|J| |v| + |omega|^2 |J| <= ~1e4 here), so 1e-12 relative to that scale.
RTOL = 1e-12


def flown(q_error, rate_error, rate_meas, accel_ref, attitude_controlled=True, kp=KP, kd=KD, inertia=INERTIA):
    """The torque the flight software commands (torque_command with the eq. 30/35 controller)."""
    out = np.zeros(3)
    control.torque_command(
        layout.CONTROLLER_PD_FEEDBACK_LINEARISATION,
        np.asarray(q_error, float),
        np.asarray(rate_error, float),
        np.asarray(rate_meas, float),
        np.asarray(accel_ref, float),
        kp,
        kd,
        np.zeros((3, 3)),
        inertia,
        attitude_controlled,
        out,
    )
    return out


NO_ERROR = np.array([0.0, 0.0, 0.0, 1.0])
ZERO = np.zeros(3)


def test_guidance_acceleration_is_fed_forward():
    """No errors, at rest: u = J omega_dot_g (eq. 35's feed-forward through eq. 30)."""
    accel = np.array([0.01, -0.02, 0.005])
    assert np.allclose(flown(NO_ERROR, ZERO, ZERO, accel), INERTIA @ accel, rtol=RTOL, atol=0)


def test_gyroscopic_torque_is_cancelled():
    """No errors, no guidance acceleration, spinning: u = omega x J omega (eq. 30)."""
    rate = np.array([0.3, -0.1, 0.2])
    expected = np.cross(rate, INERTIA @ rate)
    assert np.all(np.abs(expected) > 0.1)  # the term is not negligible on any axis for this J and rate
    assert np.allclose(flown(NO_ERROR, ZERO, rate, ZERO), expected, rtol=RTOL, atol=1e-12)


def test_attitude_error_alone_gives_eq_36():
    """At rest with no rate error or feed-forward: tau_c = -J Kp q_e (000 eq. 36)."""
    q_error = np.array([0.01, -0.004, 0.002, 1.0])
    assert np.allclose(flown(q_error, ZERO, ZERO, ZERO), -INERTIA @ (KP * q_error[:3]), rtol=RTOL, atol=0)


def test_rate_damping_has_no_proportional_term():
    """In rate damping (attitude not controlled, 000 sec. 3.2) the quaternion error does not act:
    u = J (omega_dot_g - Kd omega_e) + omega x J omega."""
    rate_error, rate, accel = np.array([0.02, -0.01, 0.03]), np.array([0.05, 0.0, -0.02]), np.array([1e-3, 0, 0])
    q_error = np.array([0.2, -0.1, 0.05, 0.97])
    damping = flown(q_error, rate_error, rate, accel, attitude_controlled=False)
    expected = INERTIA @ (accel - KD * rate_error) + np.cross(rate, INERTIA @ rate)
    assert np.allclose(damping, expected, rtol=RTOL, atol=1e-14)
    assert np.array_equal(damping, flown(NO_ERROR, rate_error, rate, accel, attitude_controlled=False))
    assert not np.allclose(damping, flown(q_error, rate_error, rate, accel, attitude_controlled=True))


small = st.floats(-0.5, 0.5)
vector = st.tuples(small, small, small)
gains = st.tuples(*[st.floats(0.0, 5.0)] * 3)


@settings(deadline=None, max_examples=200)
@given(
    q_vec=st.tuples(*[st.floats(-0.3, 0.3)] * 3),
    rate_error=vector,
    rate=vector,
    accel=vector,
    kp=gains,
    kd=gains,
    attitude_controlled=st.booleans(),
)
def test_controller_matches_its_twin(q_vec, rate_error, rate, accel, kp, kd, attitude_controlled):
    q_error = np.append(q_vec, np.sqrt(1.0 - np.dot(q_vec, q_vec)))
    kp, kd = np.array(kp), np.array(kd)
    out = flown(q_error, rate_error, rate, accel, attitude_controlled, kp, kd)
    twin = pd_feedback_linearisation_torque(q_error, rate_error, rate, accel, kp, kd, INERTIA, attitude_controlled)
    scale = np.abs(INERTIA).max() * (1.0 + np.abs(accel).max() + 5.0 * (np.abs(rate_error).max() + 0.3)) + 1e3
    assert np.allclose(out, twin, rtol=0, atol=RTOL * scale), (out, twin)


@pytest.mark.parametrize("attitude_controlled", [True, False])
def test_the_kernel_itself_matches_the_dispatch(attitude_controlled):
    """pd_feedback_linearisation called directly gives what torque_command dispatches to."""
    args = (
        np.array([0.01, 0.02, -0.01, 0.9997]),
        np.array([0.1, 0, 0]),
        np.array([0.2, 0.1, 0]),
        np.array([0, 0.01, 0]),
    )
    out = np.zeros(3)
    control.pd_feedback_linearisation(*args, KP, KD, INERTIA, attitude_controlled, out)
    assert np.array_equal(out, flown(*args, attitude_controlled))


def test_sliding_mode_uses_each_axis_own_slope_gain_and_layer():
    """001 eq. 12 against its twin (tests/naive.py) with a different Lambda, G and epsilon on every
    axis, inside and outside the boundary layer: an axis reading another axis' constant shows."""
    from naive import sliding_mode_torque

    smc = np.array([[0.05, 0.08, 0.11], [0.002, 0.003, 0.005], [1e-4, 3e-4, 7e-4]])
    rng = np.random.default_rng(26)
    for scale in (1e-5, 3e-4, 1e-2):
        for _ in range(20):
            q_vec = rng.normal(0, scale, 3)
            q_error = np.append(q_vec, np.sqrt(1.0 - q_vec @ q_vec))
            rate_error, accel = rng.normal(0, scale, 3), rng.normal(0, 1e-5, 3)
            rate = rate_error + rng.normal(0, 1e-3, 3)
            for attitude_controlled in (True, False):
                out = np.zeros(3)
                control.torque_command(
                    layout.CONTROLLER_SMC,
                    q_error,
                    rate_error,
                    rate,
                    accel,
                    KP,
                    KD,
                    smc,
                    INERTIA,
                    attitude_controlled,
                    out,
                )
                if attitude_controlled:
                    expected = sliding_mode_torque(q_error, rate_error, rate, accel, *smc, INERTIA)
                else:  # rate damping: no attitude terms (Lambda = 0 in the twin)
                    expected = sliding_mode_torque(q_error, rate_error, rate, accel, 0.0 * smc[0], *smc[1:], INERTIA)
                np.testing.assert_allclose(out, expected, rtol=1e-12, atol=1e-15)


def test_an_unknown_controller_commands_no_torque():
    out = np.full(3, 7.0)
    control.torque_command(
        99, NO_ERROR, np.ones(3), np.ones(3), np.ones(3), KP, KD, np.ones((3, 3)), INERTIA, True, out
    )
    assert np.array_equal(out, np.zeros(3))


def test_control_errors_are_the_shortest_arc_from_reference_to_measurement():
    """q_e = conj(q_ref) (x) q_meas with q_e4 >= 0 (000 eq. 35's q_e, the shortest arc; scipy's
    composition as the reference) and omega_e = omega_meas - omega_ref."""
    from scipy.spatial.transform import Rotation

    rng = np.random.default_rng(35)
    for _ in range(50):
        q_ref, q_meas = Rotation.random(2, random_state=rng).as_quat()
        rate_meas, rate_ref = rng.normal(size=3), rng.normal(size=3)
        q_error, rate_error = np.zeros(4), np.zeros(3)
        control.control_errors(q_meas, rate_meas, q_ref, rate_ref, q_error, rate_error)
        expected = (Rotation.from_quat(q_ref).inv() * Rotation.from_quat(q_meas)).as_quat()
        expected *= 1.0 if expected[3] >= 0 else -1.0
        assert q_error[3] >= 0.0
        assert np.allclose(q_error, expected, rtol=0, atol=1e-15)
        assert np.array_equal(rate_error, rate_meas - rate_ref)
