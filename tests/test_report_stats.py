"""Report statistics against independent computations (scipy.stats, numpy, published tables)."""

import math

import numpy as np
import pytest
from scipy import stats as sps

from refexmc.report import stats
from refexmc.report.aggregate import BinnedQuantiles, log_edges

CASES = [(0, 1), (1, 1), (0, 10), (3, 10), (10, 10), (37, 50), (99, 100), (100, 100), (9990, 10000)]


@pytest.mark.parametrize(("k", "n"), CASES)
def test_clopper_pearson_matches_scipy_exact_interval(k, n):
    expected = sps.binomtest(k, n).proportion_ci(confidence_level=0.95, method="exact")
    low, high = stats.clopper_pearson(k, n)
    assert low == pytest.approx(expected.low, abs=1e-12)
    assert high == pytest.approx(expected.high, abs=1e-12)


@pytest.mark.parametrize(("k", "n"), CASES)
def test_one_sided_bounds_match_scipy_one_sided_tests(k, n):
    lower = sps.binomtest(k, n, alternative="greater").proportion_ci(confidence_level=0.95, method="exact").low
    upper = sps.binomtest(k, n, alternative="less").proportion_ci(confidence_level=0.95, method="exact").high
    assert stats.clopper_pearson_lower(k, n) == pytest.approx(lower, abs=1e-12)
    assert stats.clopper_pearson_upper(k, n) == pytest.approx(upper, abs=1e-12)


def test_no_failure_bound_is_the_closed_form_and_near_the_rule_of_three():
    for n in (10, 100, 1000, 10000):
        lower = stats.clopper_pearson_lower(n, n)
        assert lower == pytest.approx(0.05 ** (1 / n), rel=1e-12)  # P(all n succeed | p) = p^n = 0.05
        if n >= 100:
            assert 1 - lower == pytest.approx(3 / n, rel=0.02)  # "rule of three", within 2 % at n >= 100
    assert math.isnan(stats.clopper_pearson_lower(0, 0))


def test_normal_tolerance_factor_against_published_table_and_simulation():
    # NIST/SEMATECH e-Handbook 7.2.6.3 / Natrella Table A-7, one-sided, n = 10, 95 % confidence
    assert stats.normal_tolerance_factor(10, 0.90) == pytest.approx(2.355, abs=1e-3)
    assert stats.normal_tolerance_factor(10, 0.99) == pytest.approx(3.981, abs=1e-3)
    # k -> z_p for large n
    assert stats.normal_tolerance_factor(10**6) == pytest.approx(3.0, abs=0.02)
    # coverage: mean - k sd lies below the true 0.135 % quantile in 95 % of samples
    rng = np.random.default_rng(7)
    n, trials = 30, 20000
    k = stats.normal_tolerance_factor(n)
    samples = rng.standard_normal((trials, n))
    bound = samples.mean(axis=1) - k * samples.std(axis=1, ddof=1)
    hit = np.mean(bound <= sps.norm.ppf(stats.THREE_SIGMA_LOW_FRACTION))
    assert hit == pytest.approx(0.95, abs=3 * math.sqrt(0.95 * 0.05 / trials))


def _coverage_lower(n, p, r):
    """P(at least r of n fall below the p-quantile), summed from the binomial terms."""
    log_terms = (
        math.lgamma(n + 1) - math.lgamma(j + 1) - math.lgamma(n - j + 1) + j * math.log(p) + (n - j) * math.log1p(-p)
        for j in range(r, n + 1)
    )
    return math.fsum(math.exp(t) for t in log_terms)


@pytest.mark.parametrize(("n", "p"), [(50, 0.5), (100, 0.01), (300, 0.1), (2218, 0.00135), (5000, 0.00135)])
def test_order_statistic_ranks_are_the_extreme_ones_with_95_percent_coverage(n, p):
    r = stats.order_statistic_lower_rank(n, p)
    if r:
        assert _coverage_lower(n, p, r) >= 0.95
    if r < n:
        assert _coverage_lower(n, p, r + 1) < 0.95
    s = stats.order_statistic_upper_rank(n, 1 - p)
    # by symmetry the upper bound of the (1 - p) quantile is the mirror rank of the lower bound of p
    assert s == n + 1 - r


def test_p0135_lower_bound_needs_2218_runs():
    assert 1 - (1 - 0.00135) ** 2217 < 0.95 <= 1 - (1 - 0.00135) ** 2218
    values = np.arange(3000.0)
    assert math.isnan(stats.percentile_bound(values[:2217], 0.135, "lower"))
    assert stats.percentile_bound(values[:2218], 0.135, "lower") == 0.0  # the minimum


def test_column_stats_match_numpy():
    rng = np.random.default_rng(3)
    x = rng.normal(0.5, 0.05, 257)
    with_nan = np.concatenate([x, [np.nan]])
    for percent in (0.135, 1, 5, 50, 95, 99, 99.865):
        assert stats.column_stat(with_nan, f"p{percent:g}") == pytest.approx(np.percentile(x, percent), abs=1e-15)
    assert stats.column_stat(with_nan, "min") == x.min()
    assert stats.column_stat(with_nan, "median") == np.median(x)
    assert stats.column_stat(with_nan, "std") == pytest.approx(np.std(x, ddof=1))
    assert stats.column_stat(with_nan, "mean_minus_3sd") == pytest.approx(x.mean() - 3 * np.std(x, ddof=1))
    assert stats.column_stat(with_nan, "count") == 257
    k = stats.normal_tolerance_factor(257)
    assert stats.column_stat(with_nan, "tol_lower") == pytest.approx(x.mean() - k * np.std(x, ddof=1))
    assert stats.column_stat(with_nan, "tol_upper") == pytest.approx(x.mean() + k * np.std(x, ddof=1))
    assert stats.column_stat(x, "tol_lower") < stats.column_stat(x, "mean_minus_3sd")  # k > 3 at finite n
    assert math.isnan(stats.column_stat([1.0], "std"))
    assert math.isnan(stats.column_stat([], "min"))


def test_percentile_stat_grammar():
    assert stats.parse_percentile_stat("p0.135") == (0.135, None)
    assert stats.parse_percentile_stat("p99.865_upper95") == (99.865, "upper")
    assert stats.parse_percentile_stat("p1_lower95") == (1.0, "lower")
    for bad in ("p", "p101", "pfoo", "p1_lower90", "max"):
        with pytest.raises(ValueError):
            stats.parse_percentile_stat(bad)


def test_spearman_matches_scipy_with_ties_and_nan():
    rng = np.random.default_rng(11)
    x = rng.normal(size=200)
    y = 0.4 * x + rng.normal(size=200)
    x[::7] = np.round(x[::7])  # ties
    y[5] = np.nan
    rho, p = stats.spearman(x, y)
    keep = np.isfinite(y)
    expected = sps.spearmanr(x[keep], y[keep])
    assert rho == pytest.approx(expected.statistic, abs=1e-12)
    assert p == pytest.approx(expected.pvalue, rel=1e-9)
    assert all(math.isnan(v) for v in stats.spearman(np.ones(10), np.arange(10.0)))


def test_spearman_critical_value_is_where_the_p_value_crosses_5_percent():
    n = 100
    critical = stats.spearman_critical(n)
    t = critical * math.sqrt((n - 2) / (1 - critical**2))
    assert 2 * sps.t.sf(t, n - 2) == pytest.approx(0.05, rel=1e-9)


def test_binned_quantiles_agree_with_numpy_to_one_bin():
    rng = np.random.default_rng(5)
    values = 10 ** rng.uniform(-3, 2, 20000)
    tau = rng.uniform(0, 10, 20000)
    binned = BinnedQuantiles(1, 5, 2.0, log_edges(1e-4, 1e3), log=True)
    half = len(values) // 2  # added in two batches, as the report streams part files
    binned.add(np.zeros(half, int), tau[:half], values[:half])
    binned.add(np.zeros(len(values) - half, int), tau[half:], values[half:])
    q = binned.quantiles((0, 1, 50, 99, 100))
    bin_ratio = 10 ** (1 / 80)
    for b in range(5):
        chunk = values[(tau >= 2 * b) & (tau < 2 * b + 2)]
        for k, percent in enumerate((0, 1, 50, 99, 100)):
            exact = np.percentile(chunk, percent)
            assert exact / bin_ratio <= q[0, b, k] <= exact * bin_ratio, (b, percent)
    assert binned.sample_counts().sum() == len(values)
