"""Blending thrusters with aerodynamic surfaces (core.blending, 003 eq. 5-10) against scipy's
HiGHS and a vertex enumeration (tests/naive.py).

Tolerances: the kernel and HiGHS both return vertices of the same polyhedron, so their optimal
propellant rates agree to rounding; 1e-9 relative (issue 24) leaves room for HiGHS's own
feasibility tolerance (1e-7 absolute on rows of order 1e3-1e5 N m gives ~1e-11 relative). The
kernel recomputes its thruster moments from its deflections, so surfaces plus thrusters give the
commanded moment to rounding (1e-9 N m on moments of 1e4 N m).
"""

import math

import naive
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from lp_reference import highs_minima
from scipy.optimize import linprog

from refexmc.core import blending

OBJECTIVE_REL = 1e-9
MOMENT_N_M = 1e-9
DEFLECTION_RAD = 1e-9


class Blender:
    def __init__(self):
        self.work = np.zeros(blending.scratch_shape())
        self.basis = np.zeros(3, dtype=np.int64)
        self.in_basis = np.zeros(blending.BLEND_COLUMNS, dtype=np.bool_)
        self.deflection = np.zeros(blending.N_SURFACE_VARIABLES)
        self.thrusters = np.zeros(3)

    def __call__(self, b, offset, torque, lower, upper, weights):
        rate = blending.blend(
            b,
            offset,
            torque,
            lower,
            upper,
            weights,
            self.deflection,
            self.thrusters,
            self.work,
            self.basis,
            self.in_basis,
        )
        return rate, self.deflection.copy(), self.thrusters.copy()


FLAP_LIMITS_RAD = (math.radians(-20.0), math.radians(40.0))
RUDDER_LIMITS_RAD = (math.radians(-20.0), math.radians(20.0))


def random_condition(rng, rudders, blocked=True):
    """A flight condition as 003 flies it: q S L, control derivatives per rad (C_m_delta_e < 0:
    flaps down pitch the nose down; the others of either sign), either flap blocked within
    10-20 deg (or both free), flaps within [-20, 40] deg, rudders +-20 deg below Mach 6 (else
    neutral: lower = upper = 0)."""
    qbar = rng.uniform(50.0, 15_000.0)
    qsl = qbar * 22.7 * rng.uniform(2.0, 9.0)
    derivatives = rng.uniform(-0.3, 0.3, 5)
    derivatives[1] = -abs(derivatives[1]) - 0.05
    if not rudders:
        derivatives[3:] = 0.0
    trim = math.radians(rng.uniform(0.0, 20.0))
    b, offset = np.zeros((3, 3)), np.zeros(3)
    blending.surface_moments(qsl, *derivatives, trim, b, offset)
    lower = np.array([FLAP_LIMITS_RAD[0], FLAP_LIMITS_RAD[0], RUDDER_LIMITS_RAD[0] if rudders else 0.0])
    upper = np.array([FLAP_LIMITS_RAD[1], FLAP_LIMITS_RAD[1], RUDDER_LIMITS_RAD[1] if rudders else 0.0])
    if blocked:
        flap = rng.integers(0, 2)
        lower[flap] = upper[flap] = math.radians(rng.uniform(10.0, 20.0))
    torque = rng.normal(0.0, 1.0, 3) * qsl * 0.02 + rng.normal(0.0, 2_000.0, 3)
    weights = rng.uniform(0.2, 1.0, 3) * 1e-4  # kg/s per N m: b_th K_i
    return b, offset, torque, lower, upper, weights


def highs(b, offset, torque, lower, upper, weights):
    """The same LP for scipy: variables d (3), t_plus (3), t_minus (3)."""
    a_eq = np.hstack([b, np.eye(3), -np.eye(3)])
    cost = np.concatenate([np.zeros(3), weights, weights])
    bounds = [(lower[j], upper[j]) for j in range(3)] + [(0.0, None)] * 6
    result = linprog(cost, A_eq=a_eq, b_eq=torque - offset, bounds=bounds, method="highs")
    assert result.status == 0
    return result.fun


def highs_rates(conditions):
    """:func:`highs`'s minimum of each condition, the LPs solved at once (tests/lp_reference.py)."""
    b, offset, torque, lower, upper, weights = (np.array(values) for values in zip(*conditions, strict=True))
    count = len(conditions)
    a_eq = np.concatenate([b, np.broadcast_to(np.eye(3), (count, 3, 3)), np.broadcast_to(-np.eye(3), (count, 3, 3))], 2)
    cost = np.hstack([np.zeros((count, 3)), weights, weights])
    thrusters_low, thrusters_high = np.zeros((count, 6)), np.full((count, 6), np.inf)
    return highs_minima(
        cost, a_eq, torque - offset, np.hstack([lower, thrusters_low]), np.hstack([upper, thrusters_high])
    )


def assert_equal_to_highs(count, seed):
    rng = np.random.default_rng(seed)
    solve = Blender()
    conditions = [random_condition(rng, rudders=k % 2 == 1, blocked=k % 3 != 0) for k in range(count)]
    for condition, minimum in zip(conditions, highs_rates(conditions), strict=True):
        b, offset, torque, lower, upper, weights = condition
        rate, d, t = solve(*condition)
        # where the surfaces give it all (optimum 0) the rate is the rounding of the moments
        rounding = weights.sum() * MOMENT_N_M * max(1.0, np.abs(torque).max())
        assert rate == pytest.approx(minimum, rel=OBJECTIVE_REL, abs=rounding)
        assert np.all(d >= lower) and np.all(d <= upper)
        assert np.abs(b @ d + offset + t - torque).max() <= MOMENT_N_M * max(1.0, np.abs(torque).max())


@pytest.mark.slow
def test_ten_thousand_conditions_equal_highs():
    """Issue 24: 10,000 random flight conditions and blocked deflections (a third with both flaps
    free), half with rudders."""
    assert_equal_to_highs(10_000, seed=24)


def test_equal_to_highs_on_a_few_hundred_conditions():
    assert_equal_to_highs(300, seed=3)


def test_the_stacked_reference_is_each_lp_solved_alone():
    """HiGHS on the stacked LP gives each condition the minimum of its own LP (to HiGHS's
    rounding: 1e-12 relative, or the moments' rounding where the minimum is 0)."""
    rng = np.random.default_rng(6)
    conditions = [random_condition(rng, rudders=k % 2 == 1, blocked=k % 3 != 0) for k in range(60)]
    for condition, minimum in zip(conditions, highs_rates(conditions), strict=True):
        rounding = condition[5].sum() * MOMENT_N_M * max(1.0, np.abs(condition[2]).max())
        assert minimum == pytest.approx(highs(*condition), rel=1e-12, abs=rounding)


def test_equal_to_the_vertex_enumeration():
    """The slow twin: eq. 8 at every candidate vertex of the box and the zero-moment planes."""
    rng = np.random.default_rng(5)
    solve = Blender()
    for k in range(400):
        condition = random_condition(rng, rudders=k % 2 == 0, blocked=k % 3 != 0)
        rate, _, _ = solve(*condition)
        b, offset, torque, lower, upper, weights = condition
        candidates = naive.blend_candidates(b, offset, torque, lower, upper)
        best = min(naive.blend_rate(b, offset, torque, weights, p) for p in candidates)
        assert rate == pytest.approx(best, rel=OBJECTIVE_REL)


def free_flap(lower, upper):
    return 0 if upper[0] > lower[0] else 1


def test_without_rudders_the_optimum_is_on_one_of_eq_9():
    """003 eq. 9a-c: with the free flap alone the minimum lies where one thruster moment is zero
    (conditions whose three roots all lie within the flap's range)."""
    rng = np.random.default_rng(9)
    solve = Blender()
    checked = 0
    while checked < 200:
        b, offset, torque, lower, upper, weights = random_condition(rng, rudders=False)
        free, blocked = free_flap(lower, upper), 1 - free_flap(lower, upper)
        roots = (torque - offset - b[:, blocked] * lower[blocked]) / b[:, free]  # eq. 9a, 9b, 9c
        if not np.all((roots > lower[free]) & (roots < upper[free])):
            continue
        rate, d, t = solve(b, offset, torque, lower, upper, weights)
        assert d[2] == 0.0 and d[blocked] == lower[blocked]
        assert np.min(np.abs(d[free] - roots)) <= DEFLECTION_RAD, f"flap {d[free]} not on eq. 9 roots {roots}"
        assert np.min(np.abs(t)) <= MOMENT_N_M * np.abs(torque - offset).max()
        points = []
        for root in roots:
            point = d.copy()
            point[free] = root
            points.append(point)
        assert rate == pytest.approx(min(naive.blend_rate(b, offset, torque, weights, p) for p in points), rel=1e-12)
        checked += 1


def test_eq_7_the_free_flap_sets_elevon_and_aileron():
    """With the right flap blocked, delta_a = delta_e - delta_block (003 eq. 7): the surfaces'
    roll is C_l_delta_a (delta_e - delta_block) q S L."""
    b, offset = np.zeros((3, 3)), np.zeros(3)
    block, trim, left = math.radians(14.0), math.radians(5.0), math.radians(22.0)
    blending.surface_moments(1e5, -0.1, -0.2, 0.05, 0.08, -0.1, trim, b, offset)
    moment = b @ np.array([left, block, 0.0]) + offset
    delta_e = 0.5 * (left + block)
    assert moment[0] == pytest.approx(-0.1 * 1e5 * (delta_e - block), rel=1e-12)
    assert moment[1] == pytest.approx(-0.2 * 1e5 * (delta_e - trim), rel=1e-12)
    assert moment[2] == pytest.approx(0.05 * 1e5 * (delta_e - block), rel=1e-12)


def test_with_rudders_the_optimum_is_the_lowest_vertex_of_eq_10():
    """003 eq. 10a-c, Fig. 3: the three zero-moment lines form a triangle in (free flap, rudder);
    where it lies within the surfaces' range the optimum is its lowest vertex, two thruster
    moments zero."""
    rng = np.random.default_rng(10)
    solve = Blender()
    checked = 0
    while checked < 200:
        b, offset, torque, lower, upper, weights = random_condition(rng, rudders=True)
        vertices = naive.triangle_vertices(b, offset, torque, lower, upper)
        if not all(np.all(v >= lower) and np.all(v <= upper) for v in vertices):
            continue
        rates = [naive.blend_rate(b, offset, torque, weights, v) for v in vertices]
        lowest = vertices[int(np.argmin(rates))]
        rate, d, t = solve(b, offset, torque, lower, upper, weights)
        assert np.abs(d - lowest).max() <= DEFLECTION_RAD, f"{d} is not the lowest vertex {lowest} of {vertices}"
        assert rate == pytest.approx(min(rates), rel=1e-12)
        assert np.sort(np.abs(t))[1] <= MOMENT_N_M * np.abs(torque - offset).max()
        checked += 1


def test_a_fixed_surface_never_moves():
    """A rudder held at zero and a flap blocked (lower = upper) stay there whatever they could save."""
    b, offset = np.zeros((3, 3)), np.zeros(3)
    blending.surface_moments(1e5, -0.1, -0.2, 0.05, 0.08, -0.1, 0.0, b, offset)
    lower = np.array([-0.3, 0.25, 0.0])
    upper = np.array([0.6, 0.25, 0.0])
    rate, deflection, _ = Blender()(b, offset, np.array([5e3, 0.0, -3e3]), lower, upper, np.ones(3))
    assert deflection[1] == 0.25 and deflection[2] == 0.0 and rate > 0.0


def test_with_both_flaps_free_elevon_and_aileron_cover_pitch_and_roll():
    """Nominal (no failure): flaps alone can give any small pitch and roll; only the yaw the
    flaps cannot give independently is left to the thrusters."""
    b, offset = np.zeros((3, 3)), np.zeros(3)
    blending.surface_moments(1e5, -0.1, -0.2, 0.0, 0.0, 0.0, 0.0, b, offset)
    lower = np.array([-0.3, -0.3, 0.0])
    upper = np.array([0.6, 0.6, 0.0])
    rate, d, t = Blender()(b, offset, np.array([500.0, -800.0, 300.0]), lower, upper, np.ones(3))
    assert abs(t[0]) < 1e-9 and abs(t[1]) < 1e-9 and t[2] == pytest.approx(300.0, rel=1e-12)
    assert rate == pytest.approx(300.0, rel=1e-12)


@settings(deadline=None, max_examples=200)
@given(seed=st.integers(0, 2**32 - 1), rudders=st.booleans(), blocked=st.booleans())
def test_never_more_propellant_than_any_feasible_deflection(seed, rudders, blocked):
    """Property: the LP's rate is at most eq. 8 at any deflection within the bounds (here: the
    bounds' corners, their middle and random points), and its deflection lies within them."""
    rng = np.random.default_rng(seed)
    b, offset, torque, lower, upper, weights = random_condition(rng, rudders=rudders, blocked=blocked)
    rate, d, _ = Blender()(b, offset, torque, lower, upper, weights)
    assert np.all(d >= lower) and np.all(d <= upper)
    points = [lower, upper, 0.5 * (lower + upper), *(rng.uniform(lower, upper) for _ in range(20))]
    rounding = weights.sum() * MOMENT_N_M * max(1.0, np.abs(torque).max())
    for point in points:
        assert rate <= naive.blend_rate(b, offset, torque, weights, point) * (1 + 1e-12) + rounding
