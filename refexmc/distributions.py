"""The distributions' arithmetic: what a draw of a checked dispersion is (``transform``), how many
uniforms it takes, and the exact support of its draws (the uniforms are drawn inside
[UNIFORM_EPS, 1 - UNIFORM_EPS]).

Below both ``refexmc.config`` (which checks each dispersion's support against its path's physical
range) and ``refexmc.campaign`` (whose sampler draws through :func:`transform_rows`): one
arithmetic, so a support the checks accept is the one the draws reach. No numpy transcendental
ufunc and no BLAS: exp, sin, cos and atan2 are correctly rounded (refexmc.crmath), products are
written out, so the same bits on every CPU.
"""

import itertools
import math
import statistics

import numpy as np

from refexmc import crmath
from refexmc.smallmatrix import symmetric_eigen  # the nominal inertia's principal axes

INERTIA_INDEX = ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2))
INERTIA_ROWS, INERTIA_COLUMNS = (list(index) for index in zip(*INERTIA_INDEX, strict=True))
# Uniforms are drawn inside [UNIFORM_EPS, 1 - UNIFORM_EPS], so a standard normal draw never
# exceeds Z_MAX (8.2) in size: the exact support of normal and lognormal draws, checked
# against each path's physical range.
UNIFORM_EPS = 2.0**-53
Z_MAX = -statistics.NormalDist().inv_cdf(UNIFORM_EPS) * (1.0 + 1e-12)  # 8.2095, rounded outward


def uniforms_per_draw(spec, n_components):
    """Uniforms one draw of ``spec`` (a checked distribution) consumes."""
    dist = spec["dist"]
    if dist == "constant":
        return 0
    if dist == "choice":
        return n_components if spec["per_component"] else 1
    if dist == "uniform_so3":
        return 3
    if dist == "inertia":
        return 6
    return n_components


def inertia_matrix(values):
    """3x3 tensor from the (xx, yy, zz, xy, xz, yz) components."""
    j = np.empty((3, 3))
    for v, (a, b) in zip(values, INERTIA_INDEX, strict=True):
        j[a, b] = j[b, a] = v
    return j


def inertia_tensors(rows):
    """n x 3 x 3 tensors from the rows (xx, yy, zz, xy, xz, yz) of an n x 6 array (:func:`inertia_matrix` of each)."""
    j = np.empty((len(rows), 3, 3))
    j[:, INERTIA_ROWS, INERTIA_COLUMNS] = rows
    j[:, INERTIA_COLUMNS, INERTIA_ROWS] = rows
    return j


def _normal_cdf(z):
    return 0.5 * math.erfc(-z / math.sqrt(2.0))


def _lowest_draw_below(bound_z):
    """Lowest standard draw of a normal truncated to (-inf, bound_z] that uniforms >= UNIFORM_EPS
    reach: the inverse CDF at UNIFORM_EPS * Phi(bound_z), rounded outward; -inf where the
    sampler's arithmetic underflows (a bound some 38 sigma on the far side of the mean)."""
    p = UNIFORM_EPS * _normal_cdf(bound_z)
    if p < 1e-300:
        return -math.inf
    return statistics.NormalDist().inv_cdf(p) * (1.0 + 1e-12)


def truncnorm_support(mean, sigma, low, high):
    """(lowest, highest) truncnorm draw per component: a given bound, or for a missing one
    (+-inf) the exact extreme of the draws (Z_MAX-like, beyond 8.2 sigma when the other bound
    cuts the distribution short)."""
    lowest = [
        lo if math.isfinite(lo) else m + s * _lowest_draw_below((hi - m) / s)
        for m, s, lo, hi in zip(mean, sigma, low, high, strict=True)
    ]
    highest = [
        hi if math.isfinite(hi) else m - s * _lowest_draw_below((m - lo) / s)
        for m, s, lo, hi in zip(mean, sigma, low, high, strict=True)
    ]
    return np.array(lowest), np.array(highest)


def support(spec):
    """(lowest, highest) draw per component of a checked distribution ``spec`` (parameters as
    arrays, one per component): the sampler's own arithmetic at the extreme uniforms (each
    transform is monotone in u); None where there is no interval (any rotation; an inertia
    tensor, redrawn until physical)."""
    dist = spec["dist"]
    if dist == "constant":
        return spec["value"], spec["value"]
    if dist == "normal":
        mean, sigma = spec["mean"], spec["sigma"]
        return mean - Z_MAX * sigma, mean + Z_MAX * sigma
    if dist == "truncnorm":
        return truncnorm_support(spec["mean"], spec["sigma"], spec["low"], spec["high"])
    if dist == "uniform":
        low, width = spec["low"], spec["high"] - spec["low"]
        return low + width * UNIFORM_EPS, low + width * (1.0 - UNIFORM_EPS)
    if dist == "lognormal":
        spread = crmath.exp(Z_MAX * spec["sigma"])  # the sampler's exp: the same bits on every CPU
        return spec["median"] / spread, spec["median"] * spread
    if dist == "choice":
        return spec["values"].min(axis=0), spec["values"].max(axis=0)
    return None


def so3_rotation_vector_deg(u):
    """Uniformly random rotation (Shoemake 1992, 'Uniform random rotations') as a rotation vector."""
    return so3_rotation_vectors_deg(np.asarray(u, dtype=float)[np.newaxis, :])[0]


def so3_rotation_vectors_deg(u):
    """:func:`so3_rotation_vector_deg` of each row of ``u`` (n x 3): Shoemake's quaternion
    (x, y, z, w) = (r1 sin a, r1 cos a, r2 sin b, r2 cos b), r1 = sqrt(1 - u0), r2 = sqrt(u0),
    a = 2 pi u1, b = 2 pi u2, turned into the rotation vector of angle 2 atan2(|(x, y, z)|, |w|)
    (the shorter of q and -q). Correctly rounded sin, cos and atan2 (refexmc.crmath): the same
    bits on every CPU."""
    r1, r2 = np.sqrt(1.0 - u[:, 0]), np.sqrt(u[:, 0])
    a, b = (2.0 * math.pi) * u[:, 1], (2.0 * math.pi) * u[:, 2]
    vector = np.stack([r1 * crmath.sin(a), r1 * crmath.cos(a), r2 * crmath.sin(b)], axis=1)
    w = r2 * crmath.cos(b)
    vector[w < 0.0] *= -1.0
    norm = np.sqrt(vector[:, 0] * vector[:, 0] + vector[:, 1] * vector[:, 1] + vector[:, 2] * vector[:, 2])
    angle_deg = (2.0 * crmath.atan2(norm, np.abs(w))) * (180.0 / math.pi)
    scale = np.divide(angle_deg, norm, out=np.zeros_like(norm), where=norm > 0.0)
    return vector * scale[:, np.newaxis]


def rotation_matrices(rotvec_rad):
    """n x 3 x 3 rotation matrices of the rotation vectors (rows, radians): the unit quaternion
    (sin(angle/2) axis, cos(angle/2)) and its matrix, elementwise (correctly rounded sin and cos)."""
    x, y, z = rotvec_rad[:, 0], rotvec_rad[:, 1], rotvec_rad[:, 2]
    angle = np.sqrt(x * x + y * y + z * z)
    half = 0.5 * angle
    scale = np.divide(crmath.sin(half), angle, out=np.full_like(angle, 0.5), where=angle > 0.0)
    qx, qy, qz, qw = scale * x, scale * y, scale * z, crmath.cos(half)
    r = np.empty((len(angle), 3, 3))
    r[:, 0, 0] = 1.0 - 2.0 * (qy * qy + qz * qz)
    r[:, 0, 1] = 2.0 * (qx * qy - qz * qw)
    r[:, 0, 2] = 2.0 * (qx * qz + qy * qw)
    r[:, 1, 0] = 2.0 * (qx * qy + qz * qw)
    r[:, 1, 1] = 1.0 - 2.0 * (qx * qx + qz * qz)
    r[:, 1, 2] = 2.0 * (qy * qz - qx * qw)
    r[:, 2, 0] = 2.0 * (qx * qz - qy * qw)
    r[:, 2, 1] = 2.0 * (qy * qz + qx * qw)
    r[:, 2, 2] = 1.0 - 2.0 * (qx * qx + qy * qy)
    return r


def dispersed_inertia(nominal_components, spec, u):
    """Principal moments scaled by (1 + sigma z), principal axes turned by a small rotation."""
    return dispersed_inertia_rows(nominal_components, spec, u[np.newaxis, :])[0]


def dispersed_inertia_rows(nominal_components, spec, u):
    """:func:`dispersed_inertia` of each row of ``u`` (n x 6), as n x 6 components.

    J = T diag(m (1 + sigma z)) T^T with T = R(axes_sigma z) A, A the nominal principal axes:
    sums of products written out in a fixed order (no BLAS, whose kernels differ per CPU), each
    component once (the tensor is symmetric by construction). Each row gets the same operations
    batched as alone (the same bits: tests/test_sampling.py checks it).
    """
    from scipy import special

    if len(u) == 0:
        return np.empty((0, 6))
    moments, axes = symmetric_eigen(inertia_matrix(nominal_components))
    z = special.ndtri(u)
    diagonal = moments * (1.0 + spec["moments_sigma_fraction"] * z[:, :3])
    rotation = rotation_matrices((spec["axes_sigma_deg"] * z[:, 3:]) * (math.pi / 180.0))
    turn = np.empty_like(rotation)
    for i, k in itertools.product(range(3), range(3)):
        turn[:, i, k] = rotation[:, i, 0] * axes[0, k] + rotation[:, i, 1] * axes[1, k] + rotation[:, i, 2] * axes[2, k]
    out = np.empty((len(u), 6))
    for column, (i, k) in enumerate(INERTIA_INDEX):
        terms = [(turn[:, i, m] * diagonal[:, m]) * turn[:, k, m] for m in range(3)]
        out[:, column] = (terms[0] + terms[1]) + terms[2]
    return out


def truncated_normal_ppf(u, a, b):
    """Standard normal truncated to [a, b]: inverse CDF at ``u`` (scipy.stats.truncnorm.ppf, 50x faster).

    Inverts Phi(z) = Phi(a) + u (Phi(b) - Phi(a)); where the interval lies in the upper tail
    (a > 0) the mirrored form on the survival function keeps the precision.
    """
    from scipy import special

    a, b, u = np.broadcast_arrays(np.asarray(a, dtype=float), np.asarray(b, dtype=float), np.asarray(u, dtype=float))
    lower = special.ndtri(special.ndtr(a) + u * (special.ndtr(b) - special.ndtr(a)))
    upper = -special.ndtri(special.ndtr(-a) - u * (special.ndtr(-a) - special.ndtr(-b)))
    # near u = 1 the lower form rounds to ndtri(1) = inf when b = inf: the upper form is exact there
    return np.clip(np.where((a > 0.0) | np.isposinf(lower), upper, lower), a, b)


def transform(spec, u, nominal_value):
    """Values (user units) of one draw from the uniforms ``u``."""
    return transform_rows(spec, u[np.newaxis, :], nominal_value)[0]


def transform_rows(spec, u, nominal_value):
    """Values (user units, one row per draw) of the draws whose uniforms are the rows of ``u``.

    The elementwise distributions and the inertia tensors transform all rows at once, with the
    same operations on each row as alone (so the same bits). No numpy transcendental ufunc and no
    BLAS: exp, sin, cos and atan2 are correctly rounded (refexmc.crmath), the same bits on every CPU.
    """
    from scipy import special

    dist = spec["dist"]
    if dist == "constant":
        return np.repeat(np.atleast_1d(spec["value"])[np.newaxis, :], u.shape[0], axis=0)
    if dist == "normal":
        return spec["mean"] + spec["sigma"] * special.ndtri(u)
    if dist == "truncnorm":
        mean, sigma = spec["mean"], spec["sigma"]
        a, b = (spec["low"] - mean) / sigma, (spec["high"] - mean) / sigma
        return np.clip(mean + sigma * truncated_normal_ppf(u, a, b), spec["low"], spec["high"])
    if dist == "uniform":
        return spec["low"] + (spec["high"] - spec["low"]) * u
    if dist == "lognormal":
        return spec["median"] * crmath.exp(spec["sigma"] * special.ndtri(u))
    if dist == "choice":
        cumulative = np.cumsum(spec["probabilities"])
        index = np.minimum(np.searchsorted(cumulative, u, side="right"), len(cumulative) - 1)
        values = spec["values"]
        if spec["per_component"]:
            return values[index, np.arange(values.shape[1])]
        return values[index[:, 0]]
    if dist == "uniform_so3":
        return so3_rotation_vectors_deg(u)
    if dist == "inertia":
        return dispersed_inertia_rows(nominal_value, spec, u)
    raise KeyError(dist)  # pragma: no cover - the campaign was validated
