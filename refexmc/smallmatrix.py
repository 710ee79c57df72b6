"""Small vectors and matrices (3-vectors, 3 x N) in a fixed order of + - * / and sqrt: the same
bits on every CPU.

What feeds a run must not depend on the machine that packs it. numpy's products (``@``,
``np.dot``, ``np.linalg.norm`` of a vector) and ``np.linalg`` (pinv, svd, inv, ...) go to
OpenBLAS/LAPACK, whose kernels OpenBLAS picks per CPU at load time (``OPENBLAS_CORETYPE``): the
Haswell kernels fuse multiply-adds (FMA) and sum in another order than the Nehalem ones, so the
IRASSI wheels' distribution matrix (a pseudo-inverse) differed in its last bits between CPUs
(issue 32). Here every sum runs left to right over plain Python floats (IEEE binary64, each
operation correctly rounded, no FMA), so the result is one value whatever the CPU. The sizes are
tiny (3 x 4 for IRASSI): speed is no concern; each function is twinned by numpy.linalg in
``tests/test_smallmatrix.py``.
"""

import math

import numpy as np

# a column (or row) whose part outside the span of the earlier ones is below this fraction of its
# length counts as dependent: unit wheel axes 1e-9 rad from coplanar would need 1e9 N m of wheel
# torque per N m of body torque, far beyond any wheel
RANK_TOLERANCE = 1e-9


def dot(a, b):
    """sum a[i] b[i], i ascending."""
    total = 0.0
    for x, y in zip(a, b, strict=True):
        total += float(x) * float(y)
    return total


def norm(v):
    """Euclidean length of a vector (``np.linalg.norm`` without its BLAS dot)."""
    return math.sqrt(dot(v, v))


def unit(v):
    """``v`` over its length (float array)."""
    v = np.asarray(v, dtype=float)
    return v / norm(v.ravel())


def unit_rows(m):
    """Each row of a 2-D array over its length."""
    m = np.asarray(m, dtype=float)
    return np.array([unit(row) for row in m], dtype=float).reshape(m.shape)


def cross(a, b):
    """a x b of two 3-vectors (float array)."""
    a1, a2, a3 = (float(x) for x in a)
    b1, b2, b3 = (float(x) for x in b)
    return np.array([a2 * b3 - a3 * b2, a3 * b1 - a1 * b3, a1 * b2 - a2 * b1])


def matmul(a, b):
    """a b of two 2-D arrays (or a matrix and a vector): each entry a :func:`dot`."""
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    if b.ndim == 1:
        return np.array([dot(row, b) for row in a], dtype=float).reshape(a.shape[0])
    columns = b.T
    return np.array([[dot(row, column) for column in columns] for row in a], dtype=float).reshape(
        a.shape[0], b.shape[1]
    )


def inverse(m):
    """Inverse of a 1 x 1, 2 x 2 or 3 x 3 matrix: the adjugate (cofactors) over the determinant.
    Raises ZeroDivisionError for a singular one (determinant exactly 0)."""
    m = np.asarray(m, dtype=float)
    n = m.shape[0]
    if m.shape != (n, n) or not 1 <= n <= 3:
        raise ValueError(f"expected a 1 x 1, 2 x 2 or 3 x 3 matrix, got shape {m.shape}")
    a = m.tolist()
    if n == 1:
        return np.array([[1.0 / a[0][0]]])
    if n == 2:
        det = a[0][0] * a[1][1] - a[0][1] * a[1][0]
        return np.array([[a[1][1] / det, -a[0][1] / det], [-a[1][0] / det, a[0][0] / det]])
    # cofactor C[i][j] = (-1)^(i+j) minor(i, j); the inverse is C^T / det
    cof = [[0.0] * 3 for _ in range(3)]
    for i in range(3):
        r1, r2 = (i + 1) % 3, (i + 2) % 3  # cyclic order carries the sign
        for j in range(3):
            c1, c2 = (j + 1) % 3, (j + 2) % 3
            cof[i][j] = a[r1][c1] * a[r2][c2] - a[r1][c2] * a[r2][c1]
    det = a[0][0] * cof[0][0] + a[0][1] * cof[0][1] + a[0][2] * cof[0][2]
    return np.array([[cof[j][i] / det for j in range(3)] for i in range(3)])


def _independent_columns(m):
    """Indices of the columns of ``m`` that Gram-Schmidt keeps: each whose part outside the span
    of the kept ones exceeds RANK_TOLERANCE of its length (left to right)."""
    basis, kept = [], []
    for j, column in enumerate(np.asarray(m, dtype=float).T):
        length = norm(column)
        if length == 0.0:
            continue
        rest = _orthogonal_part(column, basis)
        size = norm(rest)
        if size > RANK_TOLERANCE * length:
            basis.append(rest / size)
            kept.append(j)
    return kept


def _orthogonal_part(v, basis):
    """``v`` less its projections on the orthonormal ``basis`` (modified Gram-Schmidt, twice: the
    second pass removes what rounding left of the first)."""
    rest = np.asarray(v, dtype=float).copy()
    for _ in range(2):
        for q in basis:
            rest = rest - dot(q, rest) * q
    return rest


def rank(m):
    """Number of linearly independent columns of ``m`` (:data:`RANK_TOLERANCE`)."""
    return len(_independent_columns(m))


def pseudo_inverse(m):
    """Moore-Penrose pseudo-inverse of a matrix with at most 3 rows (or at most 3 columns), in
    closed form: W^T (W W^T)^-1 when the rows are independent (001 sec. 9.1), (W^T W)^-1 W^T when
    the columns are, and otherwise F^T (F F^T)^-1 (C^T C)^-1 C^T of the full-rank factorisation
    W = C F, C the independent columns (MacDuffee's formula)."""
    w = np.asarray(m, dtype=float)
    rows, columns = w.shape
    largest = float(np.abs(w).max()) if w.size else 0.0
    if largest == 0.0:
        return np.zeros((columns, rows))
    # computed on W 2^-e, largest entry in [0.5, 1): the products cannot under- or overflow (a
    # 1e-162 column squared would), and a power of two changes no bit of the result otherwise
    _, exponent = math.frexp(largest)
    w = np.ldexp(w, -exponent)
    kept = _independent_columns(w)
    r = len(kept)
    if r == 0:
        return np.zeros((columns, rows))
    return np.ldexp(_full_rank_pseudo_inverse(w, kept, rows, columns), -exponent)


def _full_rank_pseudo_inverse(w, kept, rows, columns):
    """:func:`pseudo_inverse` of ``w`` whose independent columns are ``kept``."""
    r = len(kept)
    if r == rows:
        return matmul(w.T, inverse(matmul(w, w.T)))
    if r == columns:
        return matmul(inverse(matmul(w.T, w)), w.T)
    c = w[:, kept]
    ctc_inverse = inverse(matmul(c.T, c))
    f = matmul(ctc_inverse, matmul(c.T, w))  # W = C F (F r x columns)
    return matmul(matmul(f.T, inverse(matmul(f, f.T))), matmul(ctc_inverse, c.T))


def null_space(m):
    """Orthonormal basis (columns x (columns - rank)) of the vectors ``m`` maps to zero: the unit
    vectors e_1, e_2, ... less their parts in the row space of ``m`` and along the basis vectors
    found before (Gram-Schmidt), each with its first clear entry positive."""
    w = np.asarray(m, dtype=float)
    n = w.shape[1]
    row_space = []
    for j in _independent_columns(w.T):
        rest = _orthogonal_part(w[j], row_space)
        row_space.append(rest / norm(rest))
    basis = []
    for j in range(n):
        if len(row_space) + len(basis) == n:
            break
        rest = _orthogonal_part(np.eye(n)[j], row_space + basis)
        size = norm(rest)
        if size > RANK_TOLERANCE:
            basis.append(rest / size)
    out = np.array(basis, dtype=float).reshape(len(basis), n)
    for row in out:  # a basis vector's sign is arbitrary: make the first clear entry positive
        if row[np.argmax(np.abs(row) > RANK_TOLERANCE)] < 0.0:
            row *= -1.0
    return out.T


def symmetric_eigen(matrix):
    """(eigenvalues ascending, unit eigenvectors as columns) of a symmetric 3 x 3 matrix.

    Cyclic Jacobi rotations (Golub & Van Loan, *Matrix Computations*, 4th ed., Algorithms 8.5.1
    and 8.5.3) in Python floats: + - * / and sqrt only, so the same bits on every CPU (LAPACK's
    eigh runs the BLAS kernels of the CPU, FMA or not). A diagonal matrix keeps its axes.
    """
    a = [[float(value) for value in row] for row in np.asarray(matrix, dtype=float)]
    v = [[1.0 if i == k else 0.0 for k in range(3)] for i in range(3)]
    for _sweep in range(64):
        rotated = False
        for p, q in ((0, 1), (0, 2), (1, 2)):
            if abs(a[p][q]) <= 2.0**-60 * (abs(a[p][p]) + abs(a[q][q])):
                a[p][q] = a[q][p] = 0.0
                continue
            rotated = True
            tau = (a[q][q] - a[p][p]) / (2.0 * a[p][q])
            t = (1.0 if tau >= 0.0 else -1.0) / (abs(tau) + math.sqrt(1.0 + tau * tau))
            c = 1.0 / math.sqrt(1.0 + t * t)
            s = t * c
            for k in range(3):  # A J: columns p and q
                akp, akq = a[k][p], a[k][q]
                a[k][p], a[k][q] = c * akp - s * akq, s * akp + c * akq
            for k in range(3):  # J^T (A J): rows p and q
                apk, aqk = a[p][k], a[q][k]
                a[p][k], a[q][k] = c * apk - s * aqk, s * apk + c * aqk
            a[p][q] = a[q][p] = 0.0
            for k in range(3):
                vkp, vkq = v[k][p], v[k][q]
                v[k][p], v[k][q] = c * vkp - s * vkq, s * vkp + c * vkq
        if not rotated:
            break
    order = sorted(range(3), key=lambda i: (a[i][i], -i))  # equal moments: the later axis first, as LAPACK's eigh
    values = np.array([a[i][i] for i in order])
    vectors = np.array([[v[k][i] for i in order] for k in range(3)])
    return values, vectors


def symmetric_eigenvalues(tensors):
    """Eigenvalues (ascending) of each symmetric 3 x 3 matrix of an n x 3 x 3 stack: the rotations
    of :func:`symmetric_eigen`, elementwise over the stack (the same operations, so the same bits
    as one matrix at a time; ~20 times faster for a campaign chunk's inertia draws)."""
    a = np.array(tensors, dtype=float).reshape(-1, 3, 3)
    for _sweep in range(64):
        rotated = False
        for p, q in ((0, 1), (0, 2), (1, 2)):
            apq, app, aqq = a[:, p, q], a[:, p, p], a[:, q, q]
            small = np.abs(apq) <= 2.0**-60 * (np.abs(app) + np.abs(aqq))
            a[small, p, q] = a[small, q, p] = 0.0
            turn = ~small
            if not turn.any():
                continue
            rotated = True
            m = a[turn]
            tau = (m[:, q, q] - m[:, p, p]) / (2.0 * m[:, p, q])
            t = np.where(tau >= 0.0, 1.0, -1.0) / (np.abs(tau) + np.sqrt(1.0 + tau * tau))
            c = 1.0 / np.sqrt(1.0 + t * t)
            s = t * c
            c, s = c[:, None], s[:, None]
            mp, mq = m[:, :, p].copy(), m[:, :, q].copy()  # A J: columns p and q
            m[:, :, p], m[:, :, q] = c * mp - s * mq, s * mp + c * mq
            mp, mq = m[:, p, :].copy(), m[:, q, :].copy()  # J^T (A J): rows p and q
            m[:, p, :], m[:, q, :] = c * mp - s * mq, s * mp + c * mq
            m[:, p, q] = m[:, q, p] = 0.0
            a[turn] = m
        if not rotated:
            break
    return np.sort(np.diagonal(a, axis1=1, axis2=2), axis=1)
