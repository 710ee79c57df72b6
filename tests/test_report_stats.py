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
    assert stats.column_stat(with_nan, "three_sigma") == pytest.approx(3 * np.std(x, ddof=1))
    assert stats.column_stat(with_nan, "mean_minus_3sd") == pytest.approx(x.mean() - 3 * np.std(x, ddof=1))
    assert stats.column_stat(with_nan, "count") == 257
    k = stats.normal_tolerance_factor(257)
    assert stats.column_stat(with_nan, "tol_lower") == pytest.approx(x.mean() - k * np.std(x, ddof=1))
    assert stats.column_stat(with_nan, "tol_upper") == pytest.approx(x.mean() + k * np.std(x, ddof=1))
    assert stats.column_stat(x, "tol_lower") < stats.column_stat(x, "mean_minus_3sd")  # k > 3 at finite n
    assert math.isnan(stats.column_stat([1.0], "std"))
    assert math.isnan(stats.column_stat([1.0, np.nan], "three_sigma"))  # one finite value: no spread
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


# Wilks' one-sided 99 %/95 % sample sizes (first, second, third largest value as the bound):
# 299, 473, 628 (e.g. Wilks 1941; the GRS/BEPU tables of order-statistic tolerance limits)
WILKS_99_95 = [(298, None), (299, 1), (472, 1), (473, 2), (627, 2), (628, 3), (2000, None)]


@pytest.mark.parametrize(("n", "from_top"), WILKS_99_95)
def test_upper_tolerance_bound_is_the_wilks_order_statistic(n, from_top):
    values = np.random.default_rng(n).permutation(np.arange(float(n)))  # value = rank - 1
    bound, method = stats.tolerance_bound(values, "upper")
    if from_top is None and n < 299:
        k = stats.normal_tolerance_factor(n, 0.99)
        assert bound == pytest.approx(values.mean() + k * values.std(ddof=1))
        assert method.startswith("normal: mean + ")
        return
    rank = stats.order_statistic_upper_rank(n, 0.99)
    # coverage of the chosen rank from the binomial terms, independently of scipy
    assert 1 - _coverage_lower(n, 0.99, rank) >= 0.95 > 1 - _coverage_lower(n, 0.99, rank - 1)
    if from_top is not None:
        assert rank == n + 1 - from_top
    assert bound == rank - 1 and method == f"order statistic: rank {rank} of {n} (distribution-free)"
    # the mirror image: the lower bound is the same rank from the bottom
    low, _ = stats.tolerance_bound(values, "lower")
    assert low == n - rank


def test_maximum_of_299_covers_99_percent_with_95_percent_confidence():
    # closed form: P(max of n >= x_0.99) = 1 - 0.99^n
    assert 1 - 0.99**298 < 0.95 <= 1 - 0.99**299


def test_normal_upper_tolerance_bound_table_and_coverage():
    # NIST/SEMATECH e-Handbook 7.2.6.3 / Natrella Table A-7: one-sided k, n = 10, 99 % coverage, 95 % confidence
    x = np.array([9.2, 10.1, 10.4, 9.8, 10.9, 10.0, 9.5, 10.6, 9.9, 10.3])
    bound, method = stats.tolerance_bound(x, "upper")
    assert bound == pytest.approx(x.mean() + 3.981 * x.std(ddof=1), abs=1e-3 * x.std(ddof=1))
    assert "3.981" in method
    # coverage by simulation: mean + k sd lies above the true 99th percentile in 95 % of samples
    rng = np.random.default_rng(17)
    n, trials = 40, 20000
    k = stats.normal_tolerance_factor(n, 0.99)
    samples = rng.standard_normal((trials, n))
    upper = samples.mean(axis=1) + k * samples.std(axis=1, ddof=1)
    hit = np.mean(upper >= sps.norm.ppf(0.99))
    assert hit == pytest.approx(0.95, abs=3 * math.sqrt(0.95 * 0.05 / trials))
    assert math.isnan(stats.tolerance_bound([1.0], "upper")[0])


def test_describe_keeps_the_worse_tail_only():
    rng = np.random.default_rng(2)
    durations = rng.exponential(1.0, 400)  # skewed, positive: mean - 3 sd < 0
    assert durations.mean() - 3 * durations.std(ddof=1) < 0
    upper = stats.describe(durations, "upper")
    assert "mean_minus_3sd" not in upper and "min" not in upper and "tol_lower" not in upper
    for percent in (95, 99, 99.865):
        assert upper[f"p{percent:g}"] == pytest.approx(np.percentile(durations, percent), abs=1e-15)
    assert upper["mean_plus_3sd"] == pytest.approx(durations.mean() + 3 * durations.std(ddof=1))
    assert upper["tolerance_99_95"] == np.sort(durations)[stats.order_statistic_upper_rank(400, 0.99) - 1]
    lower = stats.describe(durations, "lower")
    assert "max" not in lower and "mean_plus_3sd" not in lower
    assert lower["p0.135"] == pytest.approx(np.percentile(durations, 0.135), abs=1e-15)


SENTINEL = 1e12  # far beyond every value below: numpy's percentile then shows where a failing run lands


@pytest.mark.parametrize("n_failing", [0, 1, 3, 10])
@pytest.mark.parametrize("stat", ["min", "max", "median", "p1", "p5", "p50", "p95", "p99", "p99_upper95", "p1_lower95"])
@pytest.mark.parametrize("side", ["low", "high"])
def test_failing_runs_rank_at_the_failing_end_like_a_far_sentinel(stat, side, n_failing):
    values = np.random.default_rng(4).normal(0.5, 0.05, 400)
    got = stats.column_stat_with_failing(values, n_failing, stat, side)
    sentinel = -SENTINEL if side == "low" else SENTINEL
    with_sentinel = np.sort(np.concatenate([values, np.full(n_failing, sentinel)]))
    if stat in ("min", "max", "median"):
        reference = {"min": with_sentinel[0], "max": with_sentinel[-1], "median": np.median(with_sentinel)}[stat]
    elif stat.endswith(("_lower95", "_upper95")):
        percent, bound = stats.parse_percentile_stat(stat)
        reference = stats.percentile_bound(with_sentinel, percent, bound)
    else:
        reference = np.percentile(with_sentinel, float(stat[1:]))
    if abs(reference) > 1e6:  # numpy's interpolation reached the sentinel: the statistic is the failing run's
        assert got == (-math.inf if side == "low" else math.inf)
    else:
        assert got == pytest.approx(reference, rel=1e-12)


def test_failing_runs_fail_moments_and_equality_and_are_not_counted():
    values = np.linspace(1.0, 2.0, 50)
    for stat in ("mean", "std", "three_sigma", "mean_minus_3sd", "mean_plus_3sd", "tol_lower", "tol_upper"):
        assert stats.column_stat_with_failing(values, 1, stat, "low") == -math.inf
        assert stats.column_stat_with_failing(values, 1, stat, "high") == math.inf
        assert stats.column_stat_with_failing(values, 0, stat, "low") == stats.column_stat(values, stat)
    assert math.isnan(stats.column_stat_with_failing(values, 1, "median", None))
    assert stats.column_stat_with_failing(values, 4, "count", "low") == 50
    # p99 over 1,000 runs holds 9 failing runs at the top, not 10 (h = 999 * 0.99 = 989.01)
    thousand = np.arange(1000.0)
    assert math.isfinite(stats.column_stat_with_failing(thousand[:991], 9, "p99", "high"))
    assert stats.column_stat_with_failing(thousand[:990], 10, "p99", "high") == math.inf


def test_sorted_percentile_with_infinities():
    assert stats.sorted_percentile(np.array([-math.inf, 1.0, 2.0]), 50) == 1.0
    assert stats.sorted_percentile(np.array([-math.inf, 1.0, 2.0]), 25) == -math.inf
    assert stats.sorted_percentile(np.array([1.0, 2.0, math.inf]), 75) == math.inf
    assert stats.sorted_percentile(np.array([-math.inf, -math.inf, 2.0]), 25) == -math.inf  # no inf - inf
    assert math.isnan(stats.sorted_percentile(np.array([]), 50))


# --- two-sample comparisons (refexmc compare) ----------------------------------------------------


@pytest.mark.parametrize(
    ("x1", "n1", "x2", "n2", "low", "high"),
    [  # Newcombe, Statistics in Medicine 17 (1998) 873, Table II, method 10
        (56, 70, 48, 80, 0.0524, 0.3339),
        (9, 10, 3, 10, 0.1705, 0.8090),
        (6, 7, 2, 7, 0.0582, 0.8062),
        (5, 56, 0, 29, -0.0381, 0.1926),
    ],
)
def test_newcombe_interval_matches_the_published_examples(x1, n1, x2, n2, low, high):
    got = stats.newcombe_interval(x1, n1, x2, n2)
    assert got == pytest.approx((low, high), abs=5e-5)


@pytest.mark.parametrize(("x", "n"), [(0, 20), (20, 20), (17, 20), (1, 3), (55, 58)])
def test_wilson_interval_matches_scipy(x, n):
    expected = sps.binomtest(x, n).proportion_ci(confidence_level=0.95, method="wilson")
    assert stats.wilson_interval(x, n) == pytest.approx((expected.low, expected.high), abs=1e-12)


def test_median_interval_is_the_sign_test_interval():
    values = np.random.default_rng(3).normal(size=20)
    median, (low, high) = stats.median_interval(values)
    # independent: the widest symmetric ranks (k, n + 1 - k) with P(Binomial(20, 1/2) < k) <= 2.5 %
    k = max(k for k in range(1, 11) if sps.binom.cdf(k - 1, 20, 0.5) <= 0.025)
    ordered = np.sort(values)
    assert (low, high) == (ordered[k - 1], ordered[20 - k])
    assert k == 6 and median == np.median(values)
    assert math.isnan(stats.median_interval(values[:5])[1][0])  # 5 values cannot bound a median at 95 %


def test_welch_interval_matches_scipy_and_degenerates_to_nan_or_a_point():
    rng = np.random.default_rng(4)
    baseline, current = rng.normal(0.5, 0.02, 25), rng.normal(0.48, 0.05, 18)
    difference, (low, high) = stats.welch_interval(baseline, current)
    expected = sps.ttest_ind(current, baseline, equal_var=False).confidence_interval(0.95)
    assert difference == pytest.approx(current.mean() - baseline.mean(), abs=1e-15)
    assert (low, high) == pytest.approx((expected.low, expected.high), abs=1e-12)
    assert math.isnan(stats.welch_interval(baseline, current[:1])[1][0])  # one value has no variance
    assert stats.welch_interval(np.full(5, 2.0), np.full(4, 3.0)) == (1.0, (1.0, 1.0))  # no spread: exact


def test_wilcoxon_and_ks_p_values_match_scipy_with_their_edge_cases():
    differences = np.random.default_rng(5).normal(0.3, 1.0, 30)
    assert stats.wilcoxon_p(differences) == pytest.approx(sps.wilcoxon(differences).pvalue, rel=1e-12)
    assert stats.wilcoxon_p(np.zeros(8)) == 1.0  # no change at all: scipy would refuse
    assert math.isnan(stats.wilcoxon_p([]))
    a, b = differences[:15], differences[15:] + 1.0
    assert stats.ks_p(a, b) == pytest.approx(sps.ks_2samp(a, b).pvalue, rel=1e-12)
    assert math.isnan(stats.ks_p(a, []))


def test_spearman_of_all_columns_at_once_matches_one_by_one():
    from refexmc.report import stats

    rng = np.random.default_rng(11)
    inputs = rng.normal(size=(200, 4))
    inputs[:, 2] = np.round(inputs[:, 2])  # ties
    inputs[:, 3] = 1.0  # constant: no correlation
    output = np.exp(inputs[:, 0]) + 0.3 * inputs[:, 2] + 0.1 * rng.normal(size=200)
    rho, p = stats.spearman_columns(inputs, output)
    for j in range(3):
        expected = sps.spearmanr(inputs[:, j], output)
        assert rho[j] == pytest.approx(expected.statistic, abs=1e-12)
        assert p[j] == pytest.approx(expected.pvalue, rel=1e-9)
    assert np.isnan(rho[3]) and np.isnan(p[3])
    inputs[5, 1] = np.nan  # not finite: column by column, the pair dropped
    rho, _ = stats.spearman_columns(inputs, output)
    keep = np.arange(200) != 5
    assert rho[1] == pytest.approx(sps.spearmanr(inputs[keep, 1], output[keep]).statistic, abs=1e-12)


@pytest.mark.parametrize(("percent", "side"), [(1.0, "lower"), (99.0, "upper"), (10.0, "lower"), (50.0, "upper")])
def test_the_runs_a_percentile_bound_needs_are_the_first_sample_that_has_one(percent, side):
    """Against the bound itself on samples of every size: absent below the count, present from it."""
    needed = stats.percentile_bound_runs(percent, side)
    values = np.arange(needed + 1, dtype=float)
    assert math.isnan(stats.percentile_bound(values[: needed - 1], percent, side))
    assert math.isfinite(stats.percentile_bound(values[:needed], percent, side))
    assert stats.percentile_bound_runs(1.0, "lower") == 299  # ln 0.05 / ln 0.99 = 298.07


def test_a_percentile_bound_with_too_few_runs_names_the_runs_it_needs(tmp_path):
    from test_report import synthetic_runs, write_out

    from refexmc.report import make_report

    out = write_out(tmp_path / "out", synthetic_runs(n=60), requirements=["fuel_remaining.p1_lower95 >= 0.2"])
    (verdict,) = make_report(out, html=False)["requirements"]
    assert not verdict["passed"] and verdict["actual"] is None
    assert verdict["note"].endswith("not computable: p1_lower95 needs at least 299 runs, this campaign has 60")
