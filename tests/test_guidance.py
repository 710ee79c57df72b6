"""Guidance profiles (000 sec. 3) against the naive polynomials and the equations' boundary
conditions, and the reference attitudes of SAM and EAM.

Polynomial values are O(1) sums of a few float64 terms: ``POLY = 1e-12`` (relative to the
scale of each quantity). Finite differences use a central step ``FD_STEP``; their truncation
error O(step^2 f''') is quoted at each use.
"""

import math

import naive
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from refexmc.core import guidance, layout, quaternion

POLY = 1e-12  # see module docstring
FD_STEP = 1e-4  # s
ACCEL_MAX = slice(layout.LV_ACCEL_MAX, layout.LV_ACCEL_MAX + 3)  # omega_dot_max of a level (000 eq. 2)
MARGIN = 0.65  # guidance uses 65 % of omega_dot_max (000 eq. 13)


# --- quintic h(t), 000 eq. 5-9 -----------------------------------------------------------------


@pytest.mark.parametrize("t1", [0.7, 12.0, 41.3])
def test_quintic_boundary_conditions_eq_5_6(t1):
    assert guidance.quintic(0.0, t1) == (0.0, 0.0, 0.0)
    h, h_dot, h_ddot = guidance.quintic(t1 * (1 - 1e-12), t1)
    assert h == pytest.approx(1.0, abs=1e-10)
    assert abs(h_dot) * t1 < 1e-10 and abs(h_ddot) * t1**2 < 1e-9
    assert guidance.quintic(t1, t1) == (1.0, 0.0, 0.0)
    assert guidance.quintic(2 * t1, t1) == (1.0, 0.0, 0.0), "final state held after t1 (000 sec. 3.1)"
    # just after 0 the profile starts like 10 (t/t1)^3: no jump in h, h', h''
    h, h_dot, h_ddot = guidance.quintic(1e-6 * t1, t1)
    assert h < 1e-16 and h_dot * t1 < 1e-10 and h_ddot * t1**2 < 1e-4


@pytest.mark.parametrize("t1", [0.7, 12.0, 41.3])
def test_quintic_matches_naive_polynomial_and_finite_differences(t1):
    for s in np.linspace(0.01, 0.99, 37):
        t = s * t1
        h, h_dot, h_ddot = guidance.quintic(t, t1)
        ref = naive.quintic(t, t1)
        assert h == pytest.approx(ref[0], abs=POLY)
        assert h_dot * t1 == pytest.approx(ref[1] * t1, abs=POLY)
        assert h_ddot * t1**2 == pytest.approx(ref[2] * t1**2, abs=POLY)
        # central differences with a step of 1e-4 t1: in units of s = t/t1 the truncation error
        # is 1e-8 max|h'''(s)| / 6 = 1e-7 for h' and 1e-8 max|h''''(s)| / 6 = 6e-7 for h''
        d = 1e-4 * t1
        hp, hm = guidance.quintic(t + d, t1)[0], guidance.quintic(t - d, t1)[0]
        assert (hp - hm) / (2 * d) * t1 == pytest.approx(h_dot * t1, abs=1e-6)
        dp, dm = guidance.quintic(t + d, t1)[1], guidance.quintic(t - d, t1)[1]
        assert (dp - dm) / (2 * d) * t1**2 == pytest.approx(h_ddot * t1**2, abs=1e-6)


# --- cubic rate profile, 000 eq. 15-18 --------------------------------------------------------


@pytest.mark.parametrize("t1", [0.5, 8.0, 30.0])
def test_cubic_rate_boundary_conditions_eq_15_16(t1):
    assert guidance.cubic_rate(0.0, t1) == (1.0, 0.0)  # omega(0) = omega_0, omega_dot(0) = 0
    factor, factor_dot = guidance.cubic_rate(t1 * (1 - 1e-12), t1)
    assert abs(factor) < 1e-10 and abs(factor_dot) * t1 < 1e-10
    assert guidance.cubic_rate(t1, t1) == (0.0, 0.0)
    assert guidance.cubic_rate(3 * t1, t1) == (0.0, 0.0)
    for s in np.linspace(0.01, 0.99, 25):
        t = s * t1
        factor, factor_dot = guidance.cubic_rate(t, t1)
        ref = naive.cubic_rate(t, t1)
        assert factor == pytest.approx(ref[0], abs=POLY)
        assert factor_dot * t1 == pytest.approx(ref[1] * t1, abs=POLY)
        fd = (guidance.cubic_rate(t + FD_STEP, t1)[0] - guidance.cubic_rate(t - FD_STEP, t1)[0]) / (2 * FD_STEP)
        assert fd * t1 == pytest.approx(factor_dot * t1, abs=1e-6)  # step^2 * 12 / t1^3 / 6


# --- quartic spin-up, 000 eq. 20-27 -----------------------------------------------------------


@pytest.mark.parametrize("t1", [0.5, 6.0, 27.0])
def test_quartic_spin_up_boundary_conditions_eq_20_21(t1):
    assert guidance.quartic_spin_up(0.0, t1) == (0.0, 0.0, 0.0)
    angle, rate, accel = guidance.quartic_spin_up(t1, t1)
    assert (rate, accel) == (1.0, 0.0)  # omega(t1) = omega_1, omega_dot(t1) = 0
    assert angle == pytest.approx(0.5 * t1, rel=POLY)  # phi(t1) = t1/2 omega_1 from eq. 22
    # approaching t1 from below meets the same values: the profile is continuous at t1
    below = guidance.quartic_spin_up(t1 * (1 - 1e-12), t1)
    assert below == pytest.approx((0.5 * t1, 1.0, 0.0), abs=1e-9 * max(1.0, t1))


@pytest.mark.parametrize("t1", [0.5, 6.0, 27.0])
def test_quartic_spin_up_matches_naive_and_continues_linearly_eq_25_27(t1):
    for s in np.concatenate([np.linspace(0.01, 0.99, 25), [1.0, 1.5, 3.0]]):
        t = s * t1
        got = guidance.quartic_spin_up(t, t1)
        ref = naive.quartic_spin_up(t, t1)
        assert got[0] == pytest.approx(ref[0], abs=POLY * max(1.0, t))
        assert got[1] == pytest.approx(ref[1], abs=POLY)
        assert got[2] * t1 == pytest.approx(ref[2] * t1, abs=POLY)
        angle_fd = (guidance.quartic_spin_up(t + FD_STEP, t1)[0] - guidance.quartic_spin_up(t - FD_STEP, t1)[0]) / (
            2 * FD_STEP
        )
        assert angle_fd == pytest.approx(got[1], abs=1e-6)
        if s < 1.0:
            rate_fd = (guidance.quartic_spin_up(t + FD_STEP, t1)[1] - guidance.quartic_spin_up(t - FD_STEP, t1)[1]) / (
                2 * FD_STEP
            )
            assert rate_fd * t1 == pytest.approx(got[2] * t1, abs=1e-6)


# --- durations t1, 000 eq. 13-14 and 19 -------------------------------------------------------

S_PEAK_QUINTIC = (3.0 - math.sqrt(3.0)) / 6.0  # where h'' = 60 s (1 - s)(1 - 2 s) / t1^2 peaks


def peak(values):
    return float(np.max(np.abs(values)))


@pytest.mark.parametrize(
    "theta",
    [np.array([0.3, -1.2, 0.4]), np.array([-2.0, 0.1, 0.05]), np.array([0.0, 0.0, -0.8])],
)
def test_slerp_duration_eq_13_peak_acceleration_is_the_margined_limit(inputs, theta):
    """t1 = max_i sqrt(20 |theta_i| / (sqrt(12) a_i)): on the limiting axis the peak of
    |theta_i h''(t)| equals a_i = 0.65 omega_dot_max,i (000 eq. 13); on the others it is lower."""
    accel = MARGIN * inputs.levels[0, ACCEL_MAX]  # low thrust, margined
    t1 = guidance.slerp_duration(theta, accel, 0.0)
    times = np.linspace(0.0, t1, 20001)
    h_ddot = np.array([guidance.quintic(t, t1)[2] for t in times])
    peaks = np.abs(theta) * max(peak(h_ddot), abs(guidance.quintic(S_PEAK_QUINTIC * t1, t1)[2]))
    limiting = int(np.argmax(np.abs(theta) / accel))
    assert peaks[limiting] == pytest.approx(accel[limiting], rel=1e-9)
    assert np.all(peaks <= accel * (1 + 1e-9))
    # the design time wins when longer (eq. 14)
    assert guidance.slerp_duration(theta, accel, 10 * t1) == 10 * t1
    assert guidance.slerp_duration(theta, accel, 0.5 * t1) == t1


@pytest.mark.parametrize("omega0", [np.radians([3.0, -2.0, 1.5]), np.array([0.0, 0.1, -0.02])])
def test_rate_profile_duration_eq_19_peak_acceleration_is_the_limit(inputs, omega0):
    accel = MARGIN * inputs.levels[0, ACCEL_MAX]
    t1 = guidance.rate_profile_duration(omega0, accel)
    times = np.linspace(0.0, t1, 20001)  # includes t1/2, where the cubic's acceleration peaks
    factor_dot = np.array([guidance.cubic_rate(t, t1)[1] for t in times[:-1]])
    peaks = np.abs(omega0) * peak(factor_dot)
    limiting = int(np.argmax(np.abs(omega0) / accel))
    assert peaks[limiting] == pytest.approx(accel[limiting], rel=1e-9)
    assert np.all(peaks <= accel * (1 + 1e-9))


def test_rate_damping_reference_follows_eq_17_18():
    state = np.zeros(guidance.GUIDANCE_STATE_SIZE)
    omega0 = np.array([0.05, -0.03, 0.02])
    accel = np.array([0.024, 0.012, 0.006])
    guidance.start_rate_damping(state, 10.0, omega0, accel)
    t1 = state[guidance.G_T1]
    assert t1 == pytest.approx(max(1.5 * abs(omega0) / accel), rel=1e-15)
    rate, acc = np.empty(3), np.empty(3)
    for tau in (0.0, 0.3 * t1, 0.5 * t1, t1, 2 * t1):
        guidance.rate_damping_reference(state, 10.0 + tau, rate, acc)
        factor, factor_dot = naive.cubic_rate(tau, t1)
        np.testing.assert_allclose(rate, factor * omega0, atol=1e-15)
        np.testing.assert_allclose(acc, factor_dot * omega0, atol=1e-15)


# --- SLERP reference, 000 eq. 4, 10-12 --------------------------------------------------------


def body_rate_from_fd(q_of_t, t, step=FD_STEP):
    """omega_body = 2 vec(conj(q) (x) q_dot), q_dot by central differences (error ~ step^2)."""
    q_dot = (q_of_t(t + step) - q_of_t(t - step)) / (2 * step)
    q = q_of_t(t)
    out = np.empty(4)
    quaternion.conj_multiply(q, q_dot, out)
    return 2.0 * out[:3]


@pytest.fixture
def slerp_state():
    q0 = Rotation.from_rotvec([0.3, -0.2, 0.5]).as_quat()
    q1 = -Rotation.from_rotvec([-0.9, 0.7, 1.1]).as_quat()  # opposite sign: shortest arc needed
    state = np.zeros(guidance.GUIDANCE_STATE_SIZE)
    accel = np.array([0.024, 0.0124, 0.0059])
    guidance.start_slerp(state, 50.0, q0, q1, accel, 0.0, np.empty(4))
    return state, q0, q1


def test_slerp_reference_starts_and_ends_on_the_attitudes(slerp_state):
    state, q0, q1 = slerp_state
    q, rate, acc = np.empty(4), np.empty(3), np.empty(3)
    guidance.slerp_reference(state, 50.0, q, rate, acc)
    np.testing.assert_allclose(q, q0, atol=1e-15)
    assert not rate.any() and not acc.any()
    t1 = state[guidance.G_T1]
    for t in (50.0 + t1, 50.0 + 3 * t1):
        guidance.slerp_reference(state, t, q, rate, acc)
        assert quaternion.angle_between(q, q1) < 1e-7  # acos precision, see test_quaternion
        assert not rate.any() and not acc.any()
    # the rotation vector is the shortest arc from q0 to q1 in q0's body axes
    expected = (Rotation.from_quat(q0).inv() * Rotation.from_quat(q1)).as_rotvec()
    np.testing.assert_allclose(state[guidance.G_VECTOR : guidance.G_VECTOR + 3], expected, atol=1e-12)


def test_slerp_reference_rate_and_accel_match_finite_differences(slerp_state):
    """Rate = theta h' (eq. 11) is the body rate of the SLERP attitude (eq. 4), and accel =
    theta h'' (eq. 12) its derivative. FD error ~ step^2 |theta| h''' ~ 1e-8 / t1^3 rad/s."""
    state, _, _ = slerp_state
    t1 = state[guidance.G_T1]

    def attitude(t):
        q, rate, acc = np.empty(4), np.empty(3), np.empty(3)
        guidance.slerp_reference(state, t, q, rate, acc)
        return q

    def rate_at(t):
        q, rate, acc = np.empty(4), np.empty(3), np.empty(3)
        guidance.slerp_reference(state, t, q, rate, acc)
        return rate, acc

    for s in (0.1, 0.25, 0.5, 0.8, 0.95):
        t = 50.0 + s * t1
        rate, acc = rate_at(t)
        np.testing.assert_allclose(body_rate_from_fd(attitude, t), rate, atol=1e-9)
        acc_fd = (rate_at(t + FD_STEP)[0] - rate_at(t - FD_STEP)[0]) / (2 * FD_STEP)
        np.testing.assert_allclose(acc_fd, acc, atol=1e-9)


def test_spin_up_reference_attitude_and_rate(inputs):
    """SSM: q = q_start (x) rot(phi(t) omega_1 axis); body rate = omega_1 rate factor (eq. 22-27)."""
    q_start = Rotation.from_rotvec([0.2, 0.4, -0.1]).as_quat()
    omega1 = np.array([math.radians(5.0), 0.0, 0.0])
    accel = MARGIN * inputs.levels[0, ACCEL_MAX]
    state = np.zeros(guidance.GUIDANCE_STATE_SIZE)
    guidance.start_spin_up(state, 20.0, q_start, omega1, accel)
    t1 = state[guidance.G_T1]
    assert t1 == pytest.approx(1.5 * omega1[0] / accel[0], rel=1e-15)  # eq. 19 with omega_1

    def reference(t):
        q, rate, acc = np.empty(4), np.empty(3), np.empty(3)
        guidance.spin_up_reference(state, t, q, rate, acc, np.empty(4))
        return q, rate, acc

    for tau in (0.0, 0.3 * t1, t1, t1 + 7.0):
        q, rate, acc = reference(20.0 + tau)
        angle, rate_factor, accel_factor = naive.quartic_spin_up(tau, t1)
        expected = Rotation.from_quat(q_start) * Rotation.from_rotvec(angle * omega1)
        assert quaternion.angle_between(q, expected.as_quat()) < 1e-7
        np.testing.assert_allclose(rate, rate_factor * omega1, atol=1e-15)
        np.testing.assert_allclose(acc, accel_factor * omega1, atol=1e-15)
        if tau > 0:
            np.testing.assert_allclose(body_rate_from_fd(lambda t: reference(t)[0], 20.0 + tau), rate, atol=1e-9)


# --- reference attitudes ------------------------------------------------------------------------


@pytest.mark.parametrize(
    "sun",
    [np.array([0.4330127019, -0.75, -0.5]), np.array([0.0, 1.0, 0.0]), np.array([-0.3, 0.2, -0.93])],
)
def test_sun_attitude_points_y_at_the_sun_and_x_toward_the_horizontal(sun):
    sun = sun / np.linalg.norm(sun)
    horizontal = np.array([math.cos(0.1), 0.0, math.sin(0.1)])  # downrange, slightly tilted
    q = np.empty(4)
    guidance.sun_attitude(sun, horizontal, q, np.empty((3, 3)))
    r = Rotation.from_quat(q)
    body_x, body_y = r.apply([1.0, 0, 0]), r.apply([0, 1.0, 0])
    np.testing.assert_allclose(body_y, sun, atol=1e-12)
    # body x lies in the plane of the horizontal and the sun, on the horizontal's side
    assert abs(body_x @ np.cross(horizontal, sun)) < 1e-12
    assert body_x @ horizontal > 0
    # and no rotation about the sun line brings it closer to the horizontal
    for angle in (-1e-3, 1e-3):
        turned = (Rotation.from_rotvec(angle * sun) * r).apply([1.0, 0, 0])
        assert turned @ horizontal < body_x @ horizontal
    assert abs(np.linalg.norm(q) - 1.0) < 1e-12


@pytest.mark.parametrize("pitch", [-0.6, 0.0, 0.66])
@pytest.mark.parametrize("alpha", [0.0, math.radians(30.0)])
def test_entry_attitude_without_sideslip_and_bank_is_a_pitch_rotation(pitch, alpha):
    q = np.empty(4)
    guidance.entry_attitude(pitch, alpha, 0.0, 0.0, q, np.empty((3, 4)))
    expected = Rotation.from_rotvec([0.0, pitch + alpha, 0.0]).as_quat()
    assert min(np.abs(q - expected).max(), np.abs(q + expected).max()) < 1e-15 * 10
    # body x is alpha above the velocity (cos pitch, 0, -sin pitch): z is down (reference-model sec. 5)
    velocity = np.array([math.cos(pitch), 0.0, -math.sin(pitch)])
    body_x = Rotation.from_quat(q).apply([1.0, 0, 0])
    assert math.acos(np.clip(body_x @ velocity, -1, 1)) == pytest.approx(alpha, abs=1e-7)
    if alpha > 0:
        assert -body_x[2] > -velocity[2], "nose above the velocity"


@pytest.mark.parametrize("pitch", [-0.6, 0.0, 0.66])
@pytest.mark.parametrize(("alpha", "beta", "bank"), [(0.0, 0.0, 0.0), (0.5, -0.1, 0.3), (-0.2, 0.25, -1.2)])
def test_entry_attitude_from_its_constant_rotations_is_the_same_to_the_bit(pitch, alpha, beta, bank):
    """The run loop computes the alpha/beta/bank factors once and only the pitch per step."""
    rotations, q, q_from = np.empty((3, 4)), np.empty(4), np.empty(4)
    guidance.aerodynamic_rotations(alpha, beta, bank, rotations)
    guidance.entry_attitude(pitch, alpha, beta, bank, q, np.empty((3, 4)))
    guidance.entry_attitude_from(pitch, rotations, q_from, np.empty((2, 4)))
    assert np.array_equal(q, q_from)


@pytest.mark.parametrize("bank", [-0.5, 0.3, 1.2])
def test_entry_attitude_bank_turns_about_the_velocity(bank):
    """alpha = beta = 0: body x stays on the velocity whatever the bank, and the bank angle is
    the rotation of body y about it."""
    pitch = 0.4
    q = np.empty(4)
    guidance.entry_attitude(pitch, 0.0, 0.0, bank, q, np.empty((3, 4)))
    r = Rotation.from_quat(q)
    velocity = np.array([math.cos(pitch), 0.0, -math.sin(pitch)])
    np.testing.assert_allclose(r.apply([1.0, 0, 0]), velocity, atol=1e-12)
    body_y = r.apply([0, 1.0, 0])
    assert math.acos(np.clip(body_y @ [0, 1.0, 0], -1, 1)) == pytest.approx(abs(bank), abs=1e-7)
