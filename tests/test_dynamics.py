"""Attitude dynamics (000 eq. 28-29) and their RK4 integrator against scipy's DOP853.

The reference right-hand side is written here from the paper, not taken from the core:
q_dot = 1/2 Xi(q) omega with Xi(q) = [[w I + [v x]], [-v^T]] (Markley, scalar last), and
omega_dot = J^-1 (u - omega x J omega). The reference inertia has a product of inertia.
"""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import solve_ivp
from scipy.spatial.transform import Rotation

from refexmc.core import dynamics, layout

REFERENCE_TOL = {"method": "DOP853", "rtol": 1e-12, "atol": 1e-12}  # the brief's tight reference


def xi(q):
    """Xi(q) of 000 eq. 28 (Markley & Crassidis, scalar last)."""
    x, y, z, w = q
    return np.array([[w, -z, y], [z, w, -x], [-y, x, w], [-x, -y, -z]])


def reference_rhs(inertia, torque=lambda t: np.zeros(3)):
    inertia_inv = np.linalg.inv(inertia)

    def rhs(t, state):
        q, omega = state[:4], state[4:]
        q_dot = 0.5 * xi(q) @ omega  # 000 eq. 28
        omega_dot = inertia_inv @ (torque(t) - np.cross(omega, inertia @ omega))  # 000 eq. 29
        return np.concatenate([q_dot, omega_dot])

    return rhs


def attitude_error(q_a, q_b):
    """Angle (rad) between two attitudes, insensitive to quaternion sign and norm drift."""
    return (Rotation.from_quat(q_a).inv() * Rotation.from_quat(q_b)).magnitude()


@pytest.fixture(scope="module")
def inertia(inputs):
    return inputs.vehicle[layout.V_INERTIA : layout.V_INERTIA + 9].reshape(3, 3).copy()


def test_reference_inertia_has_products(inertia):
    assert inertia[0, 2] != 0.0, "the tumbling test must exercise the products of inertia"


def test_derivative_matches_paper_equations(inertia):
    rng = np.random.default_rng(7)
    rhs = reference_rhs(inertia, lambda t: np.array([0.3, -1.0, 2.0]))
    out = np.empty(7)
    for _ in range(20):
        state = np.concatenate([Rotation.random(random_state=rng).as_quat(), rng.normal(0.0, 0.5, 3)])
        dynamics.derivative(state, np.array([0.3, -1.0, 2.0]), inertia, np.linalg.inv(inertia), out)
        np.testing.assert_allclose(out, rhs(0.0, state), rtol=1e-12, atol=1e-14)


# Separation rates (reference-model sec. 5) and a vigorous tumble, ten times faster in roll.
TUMBLES = {"separation": np.radians([3.0, -2.0, 1.5]), "fast": np.array([0.5, -0.3, 0.2])}


@pytest.mark.parametrize("name", TUMBLES)
def test_torque_free_tumble_matches_dop853(inertia, name):
    """100 s of free tumbling at the flight's 25 ms step: attitude error below 1e-6 rad."""
    omega0 = TUMBLES[name]
    q0 = Rotation.from_rotvec([0.2, -0.4, 0.9]).as_quat()
    x = np.concatenate([q0, omega0])
    reference = solve_ivp(reference_rhs(inertia), (0.0, 100.0), x.copy(), **REFERENCE_TOL)
    q_ref, omega_ref = reference.y[:4, -1], reference.y[4:, -1]
    work = np.empty((8, 7))
    steps = dynamics.propagate_torque_free(x, 100.0, 0.025, inertia, np.linalg.inv(inertia), work)
    assert steps == 4000
    # Required bound; RK4 at 25 ms gives ~5e-12 rad (separation) and ~1.5e-8 rad (fast) here,
    # and rate errors of ~6e-14 and ~2.4e-9 rad/s (bound 1e-7 rad/s).
    assert attitude_error(x[:4], q_ref) < 1e-6
    np.testing.assert_allclose(x[4:], omega_ref, rtol=0.0, atol=1e-7)


@pytest.mark.parametrize("name", TUMBLES)
def test_torque_free_conserves_momentum_and_energy(inertia, name):
    """Inertial angular momentum R(q) J omega and 1/2 omega.J omega stay constant.

    Both drift only by RK4 truncation, O(h^4) per unit time; at 25 ms over 100 s the observed
    relative drift is ~1e-13 (separation) and ~6e-10 (fast tumble). The bound 1e-8 still catches
    any wrong sign or index in the gyroscopic term, which makes them drift at O(1).
    """
    x = np.concatenate([Rotation.from_rotvec([0.2, -0.4, 0.9]).as_quat(), TUMBLES[name]])

    def invariants(state):
        h_body = inertia @ state[4:]
        return Rotation.from_quat(state[:4]).apply(h_body), 0.5 * state[4:] @ h_body

    h0, e0 = invariants(x)
    work = np.empty((8, 7))
    inertia_inv = np.linalg.inv(inertia)
    for _ in range(10):
        dynamics.propagate_torque_free(x, 10.0, 0.025, inertia, inertia_inv, work)
        h, e = invariants(x)
        assert np.linalg.norm(h - h0) <= 1e-8 * np.linalg.norm(h0)
        assert abs(e - e0) <= 1e-8 * e0
        assert abs(np.linalg.norm(x[:4]) - 1.0) <= 1e-15 * 4, "renormalised every step"


@settings(deadline=None, max_examples=30)
@given(
    st.lists(st.floats(min_value=-1.0, max_value=1.0), min_size=3, max_size=3),
    st.lists(st.floats(min_value=-3.0, max_value=3.0), min_size=3, max_size=3),
)
def test_rk4_step_keeps_unit_quaternion_and_free_momentum(omega, rotvec):
    inertia = np.array([[20.04, 0.0, -1.5], [0.0, 243.85, 0.0], [-1.5, 0.0, 247.6]])
    x = np.concatenate([Rotation.from_rotvec(rotvec).as_quat(), omega])
    h0 = Rotation.from_quat(x[:4]).apply(inertia @ x[4:])
    work = np.empty((8, 7))
    zero = np.zeros(3)
    for _ in range(40):
        dynamics.rk4_step(x, 0.025, zero, zero, inertia, np.linalg.inv(inertia), work)
        assert abs(np.linalg.norm(x[:4]) - 1.0) <= 4e-16 * 4
    h1 = Rotation.from_quat(x[:4]).apply(inertia @ x[4:])
    # 1 s at up to 1.7 rad/s: RK4 drift ~ (h omega)^4 omega t ~ 1e-7 relative at worst
    assert np.linalg.norm(h1 - h0) <= 1e-6 * max(np.linalg.norm(h0), 1e-12) + 1e-14


# --- convergence with a piecewise-linear torque (reference-model sec. 6) ----------------------

# Kinks at times that lie on no uniform grid; torques of the size high thrust gives (N m).
BREAK_TIMES = np.array([0.0, 0.137, 0.41, 0.77, 1.203, 1.6, 2.0])
BREAK_TORQUES = np.array([[0, 0, 0], [4, -20, 8], [4, -20, 8], [-3, 10, -9], [2, 25, 3], [0, 0, 0], [1, 1, 1]], float)
X0 = np.concatenate([Rotation.from_rotvec([0.1, 0.2, -0.3]).as_quat(), [0.5, -0.3, 0.2]])


def torque_profile(t):
    return np.array([np.interp(t, BREAK_TIMES, BREAK_TORQUES[:, k]) for k in range(3)])


@pytest.fixture(scope="module")
def kinked_reference(inertia):
    """DOP853 solution at t = 2 s, restarted at every kink so it never steps across one."""
    rhs = reference_rhs(inertia, torque_profile)
    state = X0.copy()
    for a, b in zip(BREAK_TIMES[:-1], BREAK_TIMES[1:], strict=True):
        state = solve_ivp(rhs, (a, b), state, **REFERENCE_TOL).y[:, -1]
    return state


def state_error(x, reference):
    return max(attitude_error(x[:4], reference[:4]), np.abs(x[4:] - reference[4:]).max())


def integrate_aligned(inertia, substeps):
    """What the run loop does: steps end on every kink, each segment cut into equal substeps."""
    x, work, inertia_inv = X0.copy(), np.empty((8, 7)), np.linalg.inv(inertia)
    for a, b in zip(BREAK_TIMES[:-1], BREAK_TIMES[1:], strict=True):
        h = (b - a) / substeps
        for j in range(substeps):
            dynamics.rk4_step(
                x, h, torque_profile(a + j * h), torque_profile(a + (j + 1) * h), inertia, inertia_inv, work
            )
    return x


def integrate_uniform(inertia, h):
    """Fixed steps that straddle the kinks, torque linear between the step ends."""
    x, work, inertia_inv = X0.copy(), np.empty((8, 7)), np.linalg.inv(inertia)
    for j in range(int(round(BREAK_TIMES[-1] / h))):
        dynamics.rk4_step(x, h, torque_profile(j * h), torque_profile((j + 1) * h), inertia, inertia_inv, work)
    return x


def test_segment_aligned_rk4_converges_at_fourth_order(inertia, kinked_reference):
    """Halving every step divides the error by ~16 (observed order 3.5..4.5).

    Errors run from ~3e-6 (2 substeps) to ~1e-9 (16): far above DOP853's ~1e-12, so the
    observed order is the integrator's, not the reference's.
    """
    errors = [state_error(integrate_aligned(inertia, n), kinked_reference) for n in (2, 4, 8, 16)]
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all((orders > 3.5) & (orders < 4.5)), f"errors {errors}, observed orders {orders}"


def test_steps_straddling_kinks_are_much_worse(inertia, kinked_reference):
    """Steps ending on the kinks beat steps across them by far, even with fewer steps.

    24 aligned steps (4 per segment, longest 0.11 s) against 80 uniform 25 ms steps: a step
    across a kink sees the wrong torque over part of the step, an O(h^2) error per kink.
    Observed: ~2e-7 against ~3e-4; 100x is a conservative separation.
    """
    aligned = state_error(integrate_aligned(inertia, 4), kinked_reference)
    straddling = state_error(integrate_uniform(inertia, 0.025), kinked_reference)
    assert straddling > 100.0 * aligned, f"aligned {aligned:.3g}, straddling {straddling:.3g}"


def test_linear_torque_is_integrated_exactly_in_rate_without_gyroscopic_term():
    """With omega along a principal axis and torque on it, omega(t) is the torque's integral.

    RK4 with the torque linear over the step integrates a linear input exactly (Simpson's rule
    is exact to cubics), so one 0.3 s step reproduces the trapezoid impulse to rounding.
    """
    inertia = np.diag([20.0, 240.0, 250.0])
    x = np.array([0.0, 0.0, 0.0, 1.0, 0.1, 0.0, 0.0])
    work = np.empty((8, 7))
    dynamics.rk4_step(x, 0.3, np.array([1.0, 0, 0]), np.array([3.0, 0, 0]), inertia, np.linalg.inv(inertia), work)
    assert x[4] == pytest.approx(0.1 + 0.5 * (1.0 + 3.0) * 0.3 / 20.0, rel=1e-14)
    assert x[5] == 0.0 and x[6] == 0.0
    # the angle is the double integral of the torque; q's kinematics are not polynomial, so RK4
    # truncation remains there (~1e-8 rad for this 0.3 s step), checked to 1e-6 relative
    t = 0.3
    angle = 0.1 * t + (t**2 / 2 + (2 / 0.3) * t**3 / 6) / 20.0
    assert 2 * math.atan2(x[0], x[3]) == pytest.approx(angle, rel=1e-6)
