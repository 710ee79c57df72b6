"""refexmc.smallmatrix, the fixed-order linear algebra of what feeds a run (issue 32), against
numpy.linalg and scipy.linalg (LAPACK's SVD) within tolerances from the rounding error bounds."""

import math

import numpy as np
import pytest
import scipy.linalg
from hypothesis import given, settings
from hypothesis import strategies as st

from refexmc import smallmatrix
from refexmc.config import derived
from refexmc.config.load import load_vehicle

EPS = np.finfo(float).eps
RNG = np.random.default_rng(32)
IRASSI = "configs/vehicles/irassi.yaml"


def test_dot_norm_and_unit_are_numpys_within_the_summation_bound():
    """|fl(sum) - sum| <= n eps sum |a_i b_i| (Higham, Accuracy and Stability, eq. 3.5)."""
    for n in (1, 3, 4, 7):
        a, b = RNG.normal(size=(2, 200, n))
        for x, y in zip(a, b, strict=True):
            bound = n * EPS * float(np.sum(np.abs(x * y)))
            assert abs(smallmatrix.dot(x, y) - float(np.dot(x, y))) <= bound
            assert smallmatrix.norm(x) == pytest.approx(float(np.linalg.norm(x)), rel=(n + 1) * EPS, abs=0.0)
            assert smallmatrix.norm(smallmatrix.unit(x)) == pytest.approx(1.0, abs=(n + 2) * EPS)
    assert smallmatrix.dot([1.0, 2.0, 3.0], [4.0, 5.0, 6.0]) == 32.0
    assert smallmatrix.norm([3.0, 4.0]) == 5.0
    np.testing.assert_array_equal(smallmatrix.unit_rows([[2.0, 0.0, 0.0], [0.0, 0.0, -3.0]]), [[1, 0, 0], [0, 0, -1]])


def test_dot_sums_left_to_right():
    """The order is the contract (the same bits anywhere): (1e16 + 1) - 1e16 is 0 in binary64,
    1e16 - 1e16 + 1 would be 1."""
    assert smallmatrix.dot([1e16, 1.0, -1e16], [1.0, 1.0, 1.0]) == 0.0
    assert smallmatrix.dot([1e16, -1e16, 1.0], [1.0, 1.0, 1.0]) == 1.0


def test_cross_is_numpys_to_the_bit():
    """The same two products and one difference per component as np.cross: no rounding apart."""
    a, b = RNG.normal(size=(2, 500, 3))
    mine = np.array([smallmatrix.cross(x, y) for x, y in zip(a, b, strict=True)])
    np.testing.assert_array_equal(mine, np.cross(a, b))


def test_matmul_is_numpys_within_the_summation_bound():
    for shape_a, shape_b in [((3, 4), (4, 3)), ((4, 3), (3,)), ((3, 3), (3, 5)), ((1, 2), (2, 1))]:
        a, b = RNG.normal(size=shape_a), RNG.normal(size=shape_b)
        bound = shape_a[1] * EPS * (np.abs(a) @ np.abs(b))
        mine = smallmatrix.matmul(a, b)
        assert mine.shape == (a @ b).shape
        assert np.all(np.abs(mine - a @ b) <= bound)


@pytest.mark.parametrize("n", [1, 2, 3])
def test_inverse_is_numpys_within_the_condition_number(n):
    """A backward-stable inverse is within ~cond(A) eps |A^-1| of the exact one; both are, so they
    are within twice that of each other (the constant 10 covers the cofactors' few roundings)."""
    for _ in range(300):
        a = RNG.normal(size=(n, n)) + n * np.eye(n) * RNG.choice([-1.0, 1.0])
        expected = np.linalg.inv(a)
        bound = 10.0 * np.linalg.cond(a) * EPS * np.abs(expected).max()
        np.testing.assert_allclose(smallmatrix.inverse(a), expected, rtol=0.0, atol=bound)
    np.testing.assert_array_equal(smallmatrix.inverse(np.diag([2.0, 4.0, 0.5])), np.diag([0.5, 0.25, 2.0]))
    with pytest.raises(ValueError, match="3 x 3"):
        smallmatrix.inverse(np.eye(4))


def _penrose(w, x, atol):
    """The four Moore-Penrose conditions: W X W = W, X W X = X, (W X)^T = W X, (X W)^T = X W."""
    np.testing.assert_allclose(w @ x @ w, w, rtol=0.0, atol=atol)
    np.testing.assert_allclose(x @ w @ x, x, rtol=0.0, atol=atol)
    np.testing.assert_allclose((w @ x).T, w @ x, rtol=0.0, atol=atol)
    np.testing.assert_allclose((x @ w).T, x @ w, rtol=0.0, atol=atol)


def _unit_columns(m):
    return m / np.linalg.norm(m, axis=0)


RANK_DEFICIENT = {  # unit wheel axes (columns) that span fewer than three body axes
    "two parallel of four": _unit_columns(np.array([[1.0, 1.0, 0.0, 1.0], [0.0, 0.0, 1.0, 1.0], [0.0, 0.0, 0.0, 0.0]])),
    "coplanar three": _unit_columns(np.array([[1.0, 0.0, 1.0], [0.0, 1.0, 1.0], [0.0, 0.0, 0.0]])),
    "one axis twice": _unit_columns(np.array([[0.0, 0.0], [1.0, -1.0], [0.0, 0.0]])),
}


def test_pseudo_inverse_is_lapacks_svd_pinv():
    """Against numpy.linalg.pinv (LAPACK's SVD) on random 3 x N axes of full rank (the closed
    forms of 001 sec. 9.1), 3 x 2 and 3 x 1 (independent columns) and the rank-deficient sets
    (the full-rank factorisation): within 1e-13 of entries of order 1, cond(W)^2 eps with cond
    at most ~100 for these, both being backward stable."""
    cases = [_unit_columns(RNG.normal(size=(3, n))) for n in (1, 2, 3, 4, 5, 6) for _ in range(50)]
    cases += list(RANK_DEFICIENT.values())
    for w in cases:
        x = smallmatrix.pseudo_inverse(w)
        expected = np.linalg.pinv(w)
        scale = np.linalg.cond(w[:, smallmatrix._independent_columns(w)]) ** 2
        np.testing.assert_allclose(x, expected, rtol=0.0, atol=1e-15 * max(scale, 1.0) * 100)
        _penrose(w, x, atol=1e-13 * max(1.0, np.abs(x).max()) ** 2)  # X W X scales as |X|^2
        assert smallmatrix.rank(w) == np.linalg.matrix_rank(w)
    assert smallmatrix.pseudo_inverse(np.zeros((3, 2))).tolist() == np.zeros((2, 3)).tolist()


@settings(deadline=None, max_examples=200)
@given(st.lists(st.floats(-1.0, 1.0), min_size=12, max_size=12), st.integers(1, 4))
def test_pseudo_inverse_meets_the_penrose_conditions(entries, columns):
    """Any 3 x N with independent columns or rows: the four Penrose conditions (they define the
    pseudo-inverse uniquely), within what its conditioning allows."""
    w = np.array(entries[: 3 * columns]).reshape(3, columns)
    singular = np.linalg.svd(w, compute_uv=False)
    r = smallmatrix.rank(w)
    if r < min(w.shape) or singular[r - 1] < 1e-3 * singular[0]:
        return  # ill-conditioned: the closed forms lose cond^2 digits, as documented
    x = smallmatrix.pseudo_inverse(w)
    _penrose(w, x, atol=1e-9 * max(1.0, np.abs(x).max()) ** 2)


def test_null_space_spans_scipys():
    """An orthonormal basis of the same space as scipy.linalg.null_space (their projectors N N^T
    agree), W N = 0, and each vector's first clear entry positive."""
    cases = [_unit_columns(RNG.normal(size=(3, n))) for n in (3, 4, 5, 6) for _ in range(30)]
    cases += list(RANK_DEFICIENT.values())
    for w in cases:
        mine, expected = smallmatrix.null_space(w), scipy.linalg.null_space(w)
        assert mine.shape == expected.shape
        np.testing.assert_allclose(mine.T @ mine, np.eye(mine.shape[1]), rtol=0.0, atol=1e-14)
        np.testing.assert_allclose(w @ mine, 0.0, rtol=0.0, atol=1e-14)
        np.testing.assert_allclose(mine @ mine.T, expected @ expected.T, rtol=0.0, atol=1e-13)
        for column in mine.T:
            assert column[np.argmax(np.abs(column) > 1e-9)] > 0.0


def test_symmetric_eigen_is_lapacks_eigvalsh():
    """The inertia checks' eigenvalues (Jacobi) against LAPACK's, within 1e-13 of the scale."""
    for m in RNG.normal(size=(300, 3, 3)):
        s = m + m.T
        values, vectors = smallmatrix.symmetric_eigen(s)
        np.testing.assert_allclose(values, np.linalg.eigvalsh(s), rtol=0.0, atol=1e-13 * np.abs(s).max())
        np.testing.assert_allclose(vectors @ np.diag(values) @ vectors.T, s, rtol=0.0, atol=1e-13 * np.abs(s).max())


def test_irassis_distribution_has_the_closed_forms_zeros():
    """001 sec. 9.1's D of the IRASSI pyramid: wheel 1 and 3 turn no y, 2 and 4 no z, exactly (the
    LAPACK pinv left 2e-17 there, and other bits on other CPUs: issue 32)."""
    vehicle = load_vehicle(IRASSI)
    d = derived.wheel_distribution(vehicle)
    assert d[0, 1] == d[2, 1] == d[1, 2] == d[3, 2] == 0.0
    half = 1.0 / (2.0 * math.sqrt(0.5))  # 1 / (2 b), b = a = c = d = sqrt(1/2)
    np.testing.assert_allclose(np.sort(np.abs(d[d != 0.0])), [0.5 * half] * 4 + [half] * 4, rtol=4 * EPS)


def test_symmetric_eigenvalues_of_a_stack_are_those_of_each_matrix_to_the_bit():
    """The batched rotations are the one-matrix ones elementwise: a chunk's inertia verdicts do
    not depend on which draws share the chunk."""
    m = RNG.normal(size=(500, 3, 3))
    stack = np.concatenate([m + np.swapaxes(m, 1, 2), [np.diag([6.92, 6.92, 3.72]), np.eye(3), np.zeros((3, 3))]])
    one_at_a_time = np.array([smallmatrix.symmetric_eigen(s)[0] for s in stack])
    batched = smallmatrix.symmetric_eigenvalues(stack)
    np.testing.assert_array_equal(batched.view(np.uint64), one_at_a_time.view(np.uint64))
    assert smallmatrix.symmetric_eigenvalues(np.zeros((0, 3, 3))).shape == (0, 3)


def test_pseudo_inverse_of_a_tiny_matrix_neither_underflows_nor_changes_bits_by_scaling():
    """Hypothesis found a 1.96e-162 column whose square underflowed (pinv nan/inf): the pseudo-inverse
    is computed on W scaled by a power of two, which leaves a unit-scale matrix's bits alone."""
    w = np.zeros((3, 1))
    w[2, 0] = 1.959570537717581e-162
    np.testing.assert_allclose(smallmatrix.pseudo_inverse(w), np.linalg.pinv(w), rtol=1e-15)
    axes = _unit_columns(RNG.normal(size=(3, 4)))
    for scale in (2.0**-600, 0.5, 1.0, 2.0**600):  # exact scalings: the result scales exactly
        np.testing.assert_array_equal(
            smallmatrix.pseudo_inverse(axes * scale), smallmatrix.pseudo_inverse(axes) / scale
        )
