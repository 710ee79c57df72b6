"""Our subset simulation against OpenTURNS' ``SubsetSampling`` (an independent implementation of
Au & Beck 2001) on the limit states of tests/test_subset.py. A dev extra: skipped without
OpenTURNS (``.venv/bin/pip install -e '.[reference]'``; not in ``make test``'s install).
"""

import math

import numpy as np
import pytest

from refexmc.campaign import subset
from tests.test_subset import BETA_LINEAR, BETA_PARABOLA, CURVATURE, linear, parabola, parabola_probability

ot = pytest.importorskip("openturns")
STUDIES = 10


def openturns_study(formula, seed):
    """(P, c.o.v.) of one OpenTURNS SubsetSampling study: 1000 samples per level, p0 0.1."""
    ot.RandomGenerator.SetSeed(seed)
    model = ot.SymbolicFunction(["z1", "z2"], [formula])
    output = ot.CompositeRandomVector(model, ot.RandomVector(ot.Normal(2)))
    algorithm = ot.SubsetSampling(ot.ThresholdEvent(output, ot.LessOrEqual(), 0.0))
    algorithm.setMaximumOuterSampling(1000)
    algorithm.setBlockSize(1)
    algorithm.setConditionalProbability(0.1)
    algorithm.run()
    result = algorithm.getResult()
    return result.getProbabilityEstimate(), result.getCoefficientOfVariation()


@pytest.mark.parametrize(
    ("formula", "limit_state", "probability"),
    [
        (f"{BETA_LINEAR} - (z1 + z2) / sqrt(2)", linear, None),
        (f"{BETA_PARABOLA} - {0.5 * CURVATURE} * z1 ^ 2 - z2", parabola, "parabola"),
    ],
    ids=["linear", "parabola"],
)
def test_openturns_subset_sampling_agrees_within_both_intervals(formula, limit_state, probability):
    from scipy import stats

    exact = parabola_probability() if probability else stats.norm.cdf(-BETA_LINEAR)
    ours = [subset.subset_simulation(subset.Design(1000, 0.1), 100 + k, 2, limit_state) for k in range(STUDIES)]
    theirs = [openturns_study(formula, 100 + k) for k in range(STUDIES)]
    ours_mean = np.mean([s.probability for s in ours])
    theirs_mean = np.mean([p for p, _ in theirs])
    # the means of 10 studies each: c.o.v. ~0.35 / sqrt(10) ~ 0.11 each, so within 2.5 sd of their difference
    assert abs(math.log(ours_mean / theirs_mean)) < 2.5 * math.hypot(0.11, 0.11), (ours_mean, theirs_mean)
    # each mean's interval (the mean c.o.v. / sqrt(10), 95 %) holds the other mean
    ours_cov = np.mean([s.cov for s in ours]) / math.sqrt(STUDIES)
    theirs_cov = np.mean([c for _, c in theirs]) / math.sqrt(STUDIES)
    assert abs(ours_mean - theirs_mean) <= 1.96 * math.hypot(ours_cov * ours_mean, theirs_cov * theirs_mean)
    # and both know the answer
    for mean in (ours_mean, theirs_mean):
        assert abs(mean / exact - 1.0) < 0.3
