"""Subset simulation (refexmc.campaign.subset, Au & Beck 2001) on limit states whose failure
probability is known without it: a linear one (closed form), a parabola (numerical integration).

Acceptance (issue 36): over 50 independent studies, the estimates' mean is within 20 % of P and
the stated 95 % interval covers P in at least 85 % of them. The coverage is counted over 200
studies (the first 50 of which give the mean): Au & Beck's c.o.v. treats the levels as
independent and is a little low (measured: ~0.28 stated against ~0.35 observed on the parabola),
so the interval covers ~88-92 % (docs/rare-events.md sec. 4), and 50 studies alone would fall
below 85 % one time in four (binomial sd 4.6 %). The pure function is the campaign's own algorithm
(refexmc.campaign.rare_event calls it with flown margins).
"""

import math

import numpy as np
import pytest
from scipy import integrate, stats

from refexmc.campaign import subset
from refexmc.config import rare_event

BETA_LINEAR = 4.26  # P = Phi(-4.26) ~ 1.02e-5 (the case)
BETA_PARABOLA, CURVATURE = 4.0, 0.3  # failure z2 >= beta - curvature z1^2 / 2
STUDIES = 50  # the count, for the mean
COVERAGE_STUDIES = 200  # for the interval's coverage (module docstring)


def linear(level, step, z, index):
    """beta - sum(z) / sqrt(d): a hyperplane at distance beta from the origin, P = Phi(-beta)."""
    return BETA_LINEAR - z.sum(axis=1) / math.sqrt(z.shape[1])


def parabola(level, step, z, index):
    return BETA_PARABOLA - 0.5 * CURVATURE * z[:, 0] ** 2 - z[:, 1]


def parabola_probability():
    """P = int phi(z1) Phi(-(beta - c z1^2 / 2)) dz1 (quad, relative error 1e-10)."""

    def integrand(x):
        return stats.norm.pdf(x) * stats.norm.sf(BETA_PARABOLA - 0.5 * CURVATURE * x * x)

    return integrate.quad(integrand, -np.inf, np.inf, epsabs=0.0, epsrel=1e-10)[0]


def _studies(limit_state, dims, design):
    return [subset.subset_simulation(design, seed, dims, limit_state) for seed in range(COVERAGE_STUDIES)]


@pytest.mark.slow
@pytest.mark.parametrize(
    ("limit_state", "dims", "probability"),
    [(linear, 2, stats.norm.cdf(-BETA_LINEAR)), (linear, 10, stats.norm.cdf(-BETA_LINEAR)), (parabola, 2, None)],
    ids=["linear-2d", "linear-10d", "parabola-2d"],
)
def test_fifty_studies_estimate_a_known_probability_and_their_intervals_cover_it(limit_state, dims, probability):
    probability = parabola_probability() if probability is None else probability
    studies = _studies(limit_state, dims, subset.Design(per_level=1000, p0=0.1))
    estimates = np.array([s.probability for s in studies[:STUDIES]])
    covered = sum(s.ci95[0] <= probability <= s.ci95[1] for s in studies)
    # the acceptance: mean within 20 % (the estimator's bias is O(1/N), its spread ~0.35/sqrt(50))
    assert abs(estimates.mean() / probability - 1.0) < 0.20, (estimates.mean(), probability)
    assert covered >= 0.85 * len(studies), f"the 95 % interval covered P in {covered} of {len(studies)} studies"
    # a few thousand evaluations, not the 1e5-1e6 crude Monte Carlo needs
    assert max(s.flights for s in studies) <= 6000
    # the stated c.o.v. is of the order of the spread the studies show (Au & Beck's is a lower bound)
    spread = estimates.std(ddof=1) / estimates.mean()
    assert 0.5 * spread < np.mean([s.cov for s in studies]) < 2.0 * spread


def test_modified_metropolis_estimates_the_linear_event_too():
    """The component-wise modified Metropolis proposal (Au & Beck sec. 3) of ``proposal: mma``; fewer
    studies (its correctly rounded exp per component is slower): the mean within 20 %."""
    design = subset.Design(per_level=1000, p0=0.1, proposal="mma")
    estimates = [subset.subset_simulation(design, seed, 10, linear).probability for seed in range(15)]
    assert abs(np.mean(estimates) / stats.norm.cdf(-BETA_LINEAR) - 1.0) < 0.20


def test_a_level_whose_samples_already_fail_ends_the_study_with_the_crude_fraction():
    """P = 0.3: level 0 already has more than p0 N failures, P is their fraction, one level."""
    study = subset.subset_simulation(
        subset.Design(per_level=200, p0=0.1), 3, 1, lambda level, step, z, index: z[:, 0] - stats.norm.ppf(0.3)
    )
    assert len(study.levels) == 1 and study.flights == 200
    failing = np.sum(subset.level0_normals(3, 200, 1)[:, 0] <= stats.norm.ppf(0.3))
    assert study.probability == failing / 200


def test_chains_stay_in_the_level_and_proposals_outside_the_support_are_rejected():
    """Every state of a level satisfies margin <= threshold; a proposal the support check refuses is
    never evaluated and its chain stays (here: the support is z0 <= 1.5)."""
    evaluated = []

    def limit_state(level, step, z, index):
        evaluated.append(z.copy())
        return linear(level, step, z, index)

    study = subset.subset_simulation(
        subset.Design(per_level=500, p0=0.1), 11, 2, limit_state, in_support=lambda z: z[:, 0] <= 1.5
    )
    assert all((z[:, 0] <= 1.5).all() for z in evaluated[1:])
    assert sum(level.outside_support for level in study.levels) > 0
    assert (study.margins <= study.levels[-1].threshold).all()
    # run indices: level 0 is 0..N-1, each later round's chains follow
    assert study.index.min() >= 0 and study.index.max() < study.flights + 500


def test_a_round_depends_on_the_seed_and_its_keys_only():
    """The same seed gives the same study bit for bit; another seed another one."""
    design = subset.Design(per_level=300, p0=0.1)
    a, b = (subset.subset_simulation(design, 5, 3, linear) for _ in range(2))
    c = subset.subset_simulation(design, 6, 3, linear)
    assert a.probability == b.probability and np.array_equal(a.z, b.z)
    assert a.probability != c.probability


def test_an_unreachable_event_stops_at_max_levels_and_says_so():
    study = subset.subset_simulation(
        subset.Design(per_level=200, p0=0.1, max_levels=3), 1, 2, lambda level, step, z, index: 40.0 - z[:, 0]
    )
    assert study.stopped == "max_levels" and len(study.levels) == 3
    assert study.probability == 0.0 and math.isnan(study.ci95[1])


@pytest.mark.parametrize(
    ("per_level", "p0", "words"),
    [(1000, 0.0, "0 < p0 <= 0.5"), (1000, 0.6, "0 < p0 <= 0.5"), (50, 0.1, "at least 10"), (1005, 0.1, "equal")],
)
def test_design_problems_are_named(per_level, p0, words):
    assert words in rare_event.design_problem(per_level, p0)


def test_interval_is_lognormal_and_positive():
    lo, hi = subset.interval(1e-5, 0.3)
    assert 0.0 < lo < 1e-5 < hi
    assert math.isclose(math.log(hi / 1e-5), -math.log(lo / 1e-5))
    assert math.isclose(math.log(hi / 1e-5), subset.Z95 * math.sqrt(math.log(1.09)))
