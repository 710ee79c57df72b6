"""Quaternion kernels (scalar last, Hamilton product) against scipy.spatial.transform.

Tolerances: every kernel is a handful of float64 multiply-adds on unit-size numbers, so the
result agrees with scipy to a few ulps; ``ATOL = 1e-12`` leaves three orders of headroom and
still fails on any sign or index error (those give O(1) differences).
"""

import math

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation, Slerp

from refexmc.core import elementary, quaternion

ATOL = 1e-12  # see module docstring
# angle_between is 2 acos(|p.q|): a rounding error delta in the dot product near 1 becomes an
# angle error of 2 sqrt(2 delta); a few ulps (delta ~ 4e-16) give ~6e-8 rad. 1e-7 rad (6e-6 deg)
# is far below every angle threshold the mode logic uses (>= 1 deg).
ACOS_TOL = 1e-7

components = st.floats(min_value=-1.0, max_value=1.0, allow_nan=False, allow_infinity=False)


@st.composite
def unit_quaternions(draw):
    """Random unit quaternion [x, y, z, w] (not near the zero vector before normalising)."""
    q = np.array([draw(components) for _ in range(4)])
    n = np.linalg.norm(q)
    assume(n > 0.1)
    return q / n


vectors = st.lists(
    st.floats(min_value=-10.0, max_value=10.0, allow_nan=False, allow_infinity=False), min_size=3, max_size=3
).map(np.array)

rotation_vectors = st.lists(
    st.floats(min_value=-1.8, max_value=1.8, allow_nan=False, allow_infinity=False), min_size=3, max_size=3
).map(np.array)  # |r| <= 1.8 sqrt(3) = 3.12 < pi: the shortest-arc rotation vector is r itself


def same_rotation(p, q, atol=ATOL):
    """p and q are the same attitude (q and -q are)."""
    return min(np.abs(p - q).max(), np.abs(p + q).max()) <= atol


@settings(deadline=None)
@given(unit_quaternions(), unit_quaternions())
def test_multiply_is_scipy_composition(p, q):
    out = np.empty(4)
    quaternion.multiply(p, q, out)
    expected = (Rotation.from_quat(p) * Rotation.from_quat(q)).as_quat()
    # scipy composes by the same Hamilton product, so even the sign must agree
    np.testing.assert_allclose(out, expected, atol=ATOL)
    assert abs(np.linalg.norm(out) - 1.0) <= ATOL, "product of unit quaternions must be unit"


@settings(deadline=None)
@given(unit_quaternions(), unit_quaternions())
def test_conj_multiply_is_relative_rotation(p, q):
    out = np.empty(4)
    quaternion.conj_multiply(p, q, out)
    expected = (Rotation.from_quat(p).inv() * Rotation.from_quat(q)).as_matrix()
    np.testing.assert_allclose(Rotation.from_quat(out).as_matrix(), expected, atol=ATOL)
    # and literally conj(p) (x) q
    conj = np.array([-p[0], -p[1], -p[2], p[3]])
    direct = np.empty(4)
    quaternion.multiply(conj, q, direct)
    np.testing.assert_allclose(out, direct, atol=ATOL)


def test_multiply_convention_on_basis_quaternions():
    """i j = k in the Hamilton convention (scalar last: [1,0,0,0][0,1,0,0] = [0,0,1,0])."""
    i, j = np.array([1.0, 0, 0, 0]), np.array([0, 1.0, 0, 0])
    out = np.empty(4)
    quaternion.multiply(i, j, out)
    np.testing.assert_array_equal(out, [0, 0, 1.0, 0])
    quaternion.multiply(j, i, out)
    np.testing.assert_array_equal(out, [0, 0, -1.0, 0])


@settings(deadline=None)
@given(unit_quaternions(), vectors)
def test_rotate_and_inverse_match_scipy_apply(q, v):
    out = np.empty(3)
    quaternion.rotate(q, v, out)
    np.testing.assert_allclose(out, Rotation.from_quat(q).apply(v), atol=10 * ATOL)  # |v| up to 17
    back = np.empty(3)
    quaternion.rotate_inverse(q, v, back)
    np.testing.assert_allclose(back, Rotation.from_quat(q).apply(v, inverse=True), atol=10 * ATOL)
    # out may alias v (documented)
    w = v.copy()
    quaternion.rotate(q, w, w)
    np.testing.assert_allclose(w, out, atol=10 * ATOL)
    quaternion.rotate_inverse(q, w, w)
    np.testing.assert_allclose(w, v, atol=10 * ATOL)


def test_rotate_sense_body_to_inertial():
    """+90 deg about z takes body x to inertial y (active rotation, body -> inertial)."""
    q = np.empty(4)
    quaternion.from_rotation_vector(0.0, 0.0, math.pi / 2, q)
    out = np.empty(3)
    quaternion.rotate(q, np.array([1.0, 0, 0]), out)
    np.testing.assert_allclose(out, [0, 1, 0], atol=ATOL)


@settings(deadline=None)
@given(rotation_vectors)
def test_rotation_vector_round_trip(r):
    q = np.empty(4)
    quaternion.from_rotation_vector(r[0], r[1], r[2], q)
    assert abs(np.linalg.norm(q) - 1.0) <= ATOL
    assert same_rotation(q, Rotation.from_rotvec(r).as_quat())
    back = np.empty(3)
    quaternion.to_rotation_vector(q, back)
    # atan2 recovers the angle to ~1e-15 relative; |r| <= 3.12
    np.testing.assert_allclose(back, r, atol=ATOL)


@settings(deadline=None)
@given(unit_quaternions())
def test_to_rotation_vector_is_shortest_arc(q):
    out = np.empty(3)
    quaternion.to_rotation_vector(q, out)
    assert np.linalg.norm(out) <= math.pi + ATOL
    np.testing.assert_allclose(Rotation.from_rotvec(out).as_matrix(), Rotation.from_quat(q).as_matrix(), atol=1e-9)
    minus = np.empty(3)
    quaternion.to_rotation_vector(-q, minus)
    if abs(q[3]) > 1e-9:  # at w = 0 (a half turn) +pi e and -pi e are both shortest
        np.testing.assert_allclose(minus, out, atol=ATOL)
    else:
        np.testing.assert_allclose(np.abs(minus), np.abs(out), atol=1e-8)


def test_rotation_vector_tiny_angles_use_series():
    """Below 1e-8 rad the series branch must agree with the exact formula to float precision."""
    q = np.empty(4)
    for angle in (0.0, 1e-12, 1e-9, 2e-8):
        quaternion.from_rotation_vector(angle, 0.0, 0.0, q)
        np.testing.assert_allclose(q, [math.sin(angle / 2), 0, 0, math.cos(angle / 2)], rtol=1e-15, atol=1e-300)
        back = np.empty(3)
        quaternion.to_rotation_vector(q, back)
        np.testing.assert_allclose(back, [angle, 0, 0], rtol=1e-12, atol=1e-300)


@settings(deadline=None)
@given(unit_quaternions(), unit_quaternions())
def test_angle_between_is_relative_rotation_magnitude(p, q):
    expected = (Rotation.from_quat(p).inv() * Rotation.from_quat(q)).magnitude()
    assert abs(quaternion.angle_between(p, q) - expected) <= ACOS_TOL
    assert abs(quaternion.angle_between(p, -q) - expected) <= ACOS_TOL, "sign of q must not matter"


@settings(deadline=None)
@given(unit_quaternions())
def test_from_axes_matches_from_matrix(q):
    matrix = Rotation.from_quat(q).as_matrix()
    out = np.empty(4)
    # columns of the body->inertial matrix are the body axes in inertial coordinates
    quaternion.from_axes(matrix[:, 0].copy(), matrix[:, 1].copy(), matrix[:, 2].copy(), out)
    assert out[3] >= 0.0, "from_axes returns the w >= 0 representative"
    assert same_rotation(out, Rotation.from_matrix(matrix).as_quat(), atol=1e-10)
    assert abs(np.linalg.norm(out) - 1.0) <= 1e-10


@pytest.mark.parametrize("angle", [math.pi, math.pi - 1e-6, 0.5 * math.pi])
@pytest.mark.parametrize("axis", [[1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1]])
def test_from_axes_every_branch(angle, axis):
    """Trace <= 0 cases (rotations near pi about each axis) take the other three branches."""
    r = Rotation.from_rotvec(angle * np.array(axis, float) / np.linalg.norm(axis))
    m = r.as_matrix()
    out = np.empty(4)
    quaternion.from_axes(m[:, 0].copy(), m[:, 1].copy(), m[:, 2].copy(), out)
    assert same_rotation(out, r.as_quat(), atol=1e-10)


@pytest.mark.parametrize("angle", [math.pi - 0.3, math.pi])
@pytest.mark.parametrize("axis", [[1e-6, 1, 5e-7], [5e-7, 1e-6, 1], [1e-6, 5e-7, 1], [5e-7, 1, 1e-6], [1, 1e-6, 5e-7]])
def test_from_axes_divides_by_the_largest_component(angle, axis):
    """Near a half turn about an axis a hair off a body axis, one quaternion component is ~1 and
    two are ~1e-6. Each branch of from_axes divides by 4 times one component; only the largest
    keeps the result exact (dividing by the 1e-6 one loses ~1e-5). 1e-12 against scipy's
    rotation (the matrices are exact to rounding)."""
    r = Rotation.from_rotvec(angle * np.array(axis) / np.linalg.norm(axis))
    m = r.as_matrix()
    out = np.empty(4)
    quaternion.from_axes(m[:, 0].copy(), m[:, 1].copy(), m[:, 2].copy(), out)
    assert same_rotation(out, r.as_quat(), atol=1e-12)


@settings(deadline=None)
@given(unit_quaternions(), unit_quaternions(), st.floats(min_value=0.0, max_value=1.0))
def test_slerp_matches_scipy_and_takes_shortest_arc(q0, q1, h):
    dot = float(q0 @ q1)
    # at |dot| ~ 0 (a half turn) both arcs are equally short and the choice is arbitrary
    assume(abs(dot) > 1e-3)
    reference = Slerp([0.0, 1.0], Rotation.from_quat([q0, q1]))([h])[0]  # shortest path
    out = np.empty(4)
    quaternion.slerp(q0, q1, h, out)
    assert abs(np.linalg.norm(out) - 1.0) <= 1e-10
    assert same_rotation(out, reference.as_quat(), atol=1e-9)  # scipy goes through rotvecs
    # q1 given with the opposite sign is the same attitude: same path (000 sec. 3.1)
    flipped = np.empty(4)
    quaternion.slerp(q0, -q1, h, flipped)
    assert same_rotation(flipped, out, atol=1e-12)
    # equal angular steps (000 eq. 4): the angle travelled is h times the total
    total = quaternion.angle_between(q0, q1)
    assert abs(quaternion.angle_between(q0, out) - h * total) <= 2 * ACOS_TOL


def test_slerp_end_points_and_sign_choice():
    q0 = Rotation.from_rotvec([0.1, 0.2, 0.3]).as_quat()
    q1 = -Rotation.from_rotvec([-0.4, 0.5, 0.1]).as_quat()  # dot(q0, q1) < 0: long way round
    assert q0 @ q1 < 0
    out = np.empty(4)
    quaternion.slerp(q0, q1, 0.0, out)
    np.testing.assert_allclose(out, q0, atol=ATOL)
    quaternion.slerp(q0, q1, 1.0, out)
    np.testing.assert_allclose(out, -q1, atol=ATOL)  # ends on the representative near q0
    quaternion.slerp(q0, q1, 0.5, out)
    assert out @ q0 > 0 and -q1 @ out > 0, "the midpoint lies on the short arc"


@settings(deadline=None)
@given(unit_quaternions(), unit_quaternions())
def test_slerp_end_points_are_exact(q0, q1):
    """h = 1 is taken without sines (the SLERP hold phase): exactly the shortest-arc q1."""
    assume(abs(float(q0 @ q1)) < 1.0 - 1e-12)  # the linear branch normalises: not exact
    sign, omega, sin_omega = quaternion.slerp_arc(q0, q1)
    assert sign == (1.0 if q0 @ q1 >= 0.0 else -1.0) and omega > 0.0 and sin_omega == elementary.sin(omega)
    out = np.empty(4)
    quaternion.slerp(q0, q1, 1.0, out)
    assert np.array_equal(out, 0.0 * q0 + sign * q1)
    quaternion.slerp(q0, q1, 0.0, out)
    assert np.array_equal(out, q0 + sign * 0.0 * q1)


def test_slerp_nearly_identical_quaternions():
    """The linear branch (dot > 1 - 1e-12) stays unit and between the end points."""
    q0 = Rotation.from_rotvec([0.3, -0.2, 0.1]).as_quat()
    q1 = (Rotation.from_rotvec([0.3, -0.2, 0.1]) * Rotation.from_rotvec([1e-7, 0, 0])).as_quat()
    out = np.empty(4)
    quaternion.slerp(q0, q1, 0.25, out)
    assert abs(np.linalg.norm(out) - 1.0) <= 1e-15
    rel = (Rotation.from_quat(q0).inv() * Rotation.from_quat(out)).as_rotvec()
    np.testing.assert_allclose(rel, [0.25e-7, 0, 0], atol=1e-14)


@settings(deadline=None)
@given(st.lists(st.floats(min_value=-1e3, max_value=1e3), min_size=4, max_size=4))
def test_normalize_gives_unit_norm(q):
    q = np.array(q)
    assume(np.linalg.norm(q) > 1e-3)
    direction = q / np.linalg.norm(q)
    quaternion.normalize(q)
    assert abs(np.linalg.norm(q) - 1.0) <= 1e-15 * 4
    np.testing.assert_allclose(q, direction, atol=1e-15 * 4)
