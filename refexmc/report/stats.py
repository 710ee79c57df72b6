"""Statistics of a campaign: binomial intervals (refexmc.binomial), sample statistics, tolerance bounds, sensitivity,
and the intervals and tests that compare two campaigns (``refexmc compare``).

Every function takes plain numbers or numpy arrays; NaN means "not computable" (too few runs).
"""

import math

import numpy as np
from scipy import stats as sps

from refexmc.binomial import CONFIDENCE, clopper_pearson, clopper_pearson_lower, clopper_pearson_upper  # noqa: F401
from refexmc.config.requirements import (  # noqa: F401
    BASIC_STATS,
    BOUND_STATS,
    MOMENT_STATS,
    PERCENTILE_STATS,
    parse_percentile_stat,
)

THREE_SIGMA_LOW_FRACTION = 0.00135  # P(Z < -3) of a normal distribution: the "3-sigma" tail, 0.135 %
THREE_SIGMA_COVERAGE = 1.0 - THREE_SIGMA_LOW_FRACTION
TOLERANCE_COVERAGE = 0.99  # the statistics tables' tolerance bound: 99 % of flights, 95 % confidence
# the statistics of each tail (refexmc.report.tails): summary.json "columns" holds these
TAIL_STATS = {
    "upper": (
        "count",
        "median",
        "mean",
        "std",
        "p95",
        "p99",
        "p99.865",
        "max",
        "mean_plus_3sd",
        "tol_upper",
        "p99_upper95",
        "p99.865_upper95",
    ),
    "lower": (
        "count",
        "median",
        "mean",
        "std",
        "p5",
        "p1",
        "p0.135",
        "min",
        "mean_minus_3sd",
        "tol_lower",
        "p1_lower95",
        "p0.135_lower95",
    ),
    "both": (  # an output without a bad end (an entry state): both ends
        "count",
        "median",
        "mean",
        "std",
        "p0.135",
        "p1",
        "min",
        "p99",
        "p99.865",
        "max",
        "mean_minus_3sd",
        "mean_plus_3sd",
    ),
}


def normal_tolerance_factor(n, coverage=THREE_SIGMA_COVERAGE, confidence=CONFIDENCE):
    """One-sided normal tolerance factor k: mean - k sd lies below the `coverage` quantile's complement.

    With probability `confidence`, at least `coverage` of a normal population exceeds
    mean - k sd (and lies below mean + k sd). k = t'_{confidence}(n - 1, z_coverage sqrt(n)) / sqrt(n),
    the noncentral t quantile (ISO 16269-6; NIST e-Handbook 7.2.6.3). NaN for n < 2.
    """
    if n < 2:
        return math.nan
    z = sps.norm.ppf(coverage)
    return float(sps.nct.ppf(confidence, n - 1, z * math.sqrt(n)) / math.sqrt(n))


def order_statistic_lower_rank(n, fraction, confidence=CONFIDENCE):
    """Largest rank r (1-based) with P(X_(r) <= x_fraction) >= confidence; 0 when none exists.

    Distribution-free: X_(r) <= x_p exactly when at least r of the n runs fall below x_p, a
    Binomial(n, p) count, so P = P(Binomial(n, p) >= r) = binom.sf(r - 1, n, p), decreasing in r.
    """
    if n < 1:
        return 0
    coverage = sps.binom.sf(np.arange(n), n, fraction)  # index r - 1
    return int(np.count_nonzero(coverage >= confidence))


def order_statistic_upper_rank(n, fraction, confidence=CONFIDENCE):
    """Smallest rank s (1-based) with P(X_(s) >= x_fraction) >= confidence; n + 1 when none exists.

    P(X_(s) >= x_p) = P(Binomial(n, p) <= s - 1) = binom.cdf(s - 1, n, p), increasing in s.
    """
    if n < 1:
        return n + 1
    coverage = sps.binom.cdf(np.arange(n), n, fraction)  # index s - 1
    return int(n - np.count_nonzero(coverage >= confidence) + 1)


def percentile_bound(sorted_values, percent, side, confidence=CONFIDENCE):
    """Distribution-free one-sided confidence bound on the `percent` percentile (order statistics).

    ``side`` "lower": a value that the true percentile exceeds with probability >= confidence;
    "upper": one it stays below. NaN when the sample is too small (a lower bound on the 0.135th
    percentile at 95 % needs n >= 2218: 1 - (1 - 0.00135)^n >= 0.95).
    """
    n = len(sorted_values)
    fraction = percent / 100.0
    if side == "lower":
        r = order_statistic_lower_rank(n, fraction, confidence)
        return float(sorted_values[r - 1]) if r >= 1 else math.nan
    s = order_statistic_upper_rank(n, fraction, confidence)
    return float(sorted_values[s - 1]) if s <= n else math.nan


def percentile_bound_runs(percent, side, confidence=CONFIDENCE):
    """The fewest runs for which :func:`percentile_bound` exists: the extreme run is the bound once
    1 - (1 - p)^n >= confidence (lower, p the percentile's fraction; upper: 1 - p), so n >=
    ln(1 - confidence) / ln(1 - p); found with the rank functions themselves from there."""
    fraction = percent / 100.0
    tail = fraction if side == "lower" else 1.0 - fraction
    if not 0.0 < tail < 1.0:
        return None
    n = max(1, int(math.floor(math.log(1.0 - confidence) / math.log(1.0 - tail))) - 1)

    def exists(k):
        if side == "lower":
            return order_statistic_lower_rank(k, fraction, confidence) >= 1
        return order_statistic_upper_rank(k, fraction, confidence) <= k

    while not exists(n):
        n += 1
    return n


def percentile(values, percent):
    """numpy's default (linear, Hyndman-Fan type 7) percentile; NaN for no values."""
    return float(np.percentile(values, percent)) if len(values) else math.nan


def column_stat(values, stat, confidence=CONFIDENCE):
    """One statistic of a column (finite values only): the ``<stat>`` of ``<column>.<stat>``.

    See ``refexmc.config.requirements`` for the grammar. ``values`` is a 1-D float array.
    """
    values = np.asarray(values, dtype=float)
    values = values[np.isfinite(values)]
    n = len(values)
    if stat == "count":
        return float(n)
    if n == 0:
        return math.nan
    if stat == "min":
        return float(values.min())
    if stat == "max":
        return float(values.max())
    if stat == "mean":
        return float(values.mean())
    if stat == "median":
        return float(np.median(values))
    if stat in ("std", "three_sigma", "mean_minus_3sd", "mean_plus_3sd", "tol_lower", "tol_upper"):
        if n < 2:
            return math.nan
        mean, sd = float(values.mean()), float(values.std(ddof=1))
        if stat == "std":
            return sd
        if stat == "three_sigma":
            return 3.0 * sd
        if stat == "mean_minus_3sd":
            return mean - 3.0 * sd
        if stat == "mean_plus_3sd":
            return mean + 3.0 * sd
        k = normal_tolerance_factor(n, THREE_SIGMA_COVERAGE, confidence)
        return mean - k * sd if stat == "tol_lower" else mean + k * sd
    percent, bound = parse_percentile_stat(stat)
    if bound is None:
        return percentile(values, percent)
    return percentile_bound(np.sort(values), percent, bound, confidence)


def tolerance_bound(values, side, coverage=TOLERANCE_COVERAGE, confidence=CONFIDENCE):
    """One-sided tolerance bound and how it was computed: (value, method).

    With probability ``confidence`` at least ``coverage`` of the population lies below the bound
    (``side`` "upper") or above it ("lower"). Distribution-free when n allows: the order statistic
    that is a ``confidence`` bound of the ``coverage`` quantile (Wilks; at 99 %/95 % the maximum
    needs n >= 299: 1 - 0.99^n >= 0.95). Otherwise the normal bound mean +- k sd with
    k = ``normal_tolerance_factor(n, coverage, confidence)``, which assumes normality. NaN for n < 2.
    """
    values = np.asarray(values, dtype=float)
    values = np.sort(values[np.isfinite(values)])
    n = len(values)
    if side == "upper":
        rank = order_statistic_upper_rank(n, coverage, confidence)
        if 1 <= rank <= n:
            return float(values[rank - 1]), f"order statistic: rank {rank} of {n} (distribution-free)"
    else:
        rank = order_statistic_lower_rank(n, 1.0 - coverage, confidence)
        if rank >= 1:
            return float(values[rank - 1]), f"order statistic: rank {rank} of {n} (distribution-free)"
    if n < 2:
        return math.nan, "not computable (fewer than 2 values)"
    k = normal_tolerance_factor(n, coverage, confidence)
    sd = float(values.std(ddof=1))
    value = float(values.mean()) + (k if side == "upper" else -k) * sd
    sign = "+" if side == "upper" else "-"
    return value, f"normal: mean {sign} {k:.3f} sd (n = {n} too few for the order statistic; assumes normality)"


def describe(values, tail, confidence=CONFIDENCE):
    """The statistics of one column for its worse ``tail`` ("upper" or "lower"): a dict (NaN where
    not computable), with ``tolerance_99_95`` and ``tolerance_99_95_method`` from :func:`tolerance_bound`."""
    result = {name: column_stat(values, name, confidence) for name in TAIL_STATS[tail]}
    if tail == "both":
        lower, method = tolerance_bound(values, "lower", TOLERANCE_COVERAGE, confidence)
        upper, _ = tolerance_bound(values, "upper", TOLERANCE_COVERAGE, confidence)
        result.update(tolerance_99_95=math.nan, tolerance_99_95_lower=lower, tolerance_99_95_upper=upper)
        result["tolerance_99_95_method"] = method
        return result
    bound, method = tolerance_bound(values, tail, TOLERANCE_COVERAGE, confidence)
    result["tolerance_99_95"] = bound
    result["tolerance_99_95_method"] = method
    return result


def sorted_percentile(sorted_values, percent):
    """numpy's linear (type 7) percentile of sorted values that may hold -inf or +inf.

    Between a finite value and an infinite one the infinite one wins (the interpolation has no
    finite answer); with only finite values it is ``np.percentile``.
    """
    n = len(sorted_values)
    if n == 0:
        return math.nan
    if np.isfinite(sorted_values).all():
        return percentile(sorted_values, percent)
    position = (n - 1) * percent / 100.0
    below = int(math.floor(position))
    above = min(below + 1, n - 1)
    fraction = position - below
    a, b = float(sorted_values[below]), float(sorted_values[above])
    if fraction == 0.0 or a == b:
        return a
    if math.isinf(a):
        return a
    if math.isinf(b):
        return b
    return a + fraction * (b - a)


def column_stat_with_failing(values, failing, stat, failing_side, confidence=CONFIDENCE):
    """``column_stat`` over ``values`` and ``failing`` runs that have no acceptable value.

    The failing runs (failed flights, errored runs) stand at the end of the distribution where
    they fail the requirement: ``failing_side`` "low" (-inf: for METRIC >= VALUE) or "high" (+inf:
    for METRIC <= VALUE); ``None`` (for ==): any failing run makes the statistic NaN. Order
    statistics (min, max, median, p<q>, p<q>_lower95/_upper95) rank them with the others, so a
    percentile tolerates the failing runs its tail can hold; moment statistics (mean, std, three_sigma,
    mean_minus_3sd, mean_plus_3sd, tol_lower, tol_upper) have no room for a run without a value
    and are infinite on the failing side; count counts the values only.
    """
    values = np.asarray(values, dtype=float)
    values = values[np.isfinite(values)]
    if stat == "count" or failing == 0:
        return column_stat(values, stat, confidence)
    if failing_side is None:
        return math.nan
    worst = -math.inf if failing_side == "low" else math.inf
    if stat in MOMENT_STATS:
        return worst
    ranked = np.sort(np.concatenate([values, np.full(int(failing), worst)]))
    if stat == "min":
        return float(ranked[0])
    if stat == "max":
        return float(ranked[-1])
    if stat == "median":
        return sorted_percentile(ranked, 50.0)
    percent, bound = parse_percentile_stat(stat)
    if bound is None:
        return sorted_percentile(ranked, percent)
    return percentile_bound(ranked, percent, bound, confidence)


def spearman(x, y):
    """Spearman rank correlation and its two-sided p-value (t approximation, as scipy.stats.spearmanr).

    Pairs where either value is not finite are dropped; (nan, nan) for fewer than 3 pairs or a
    constant input.
    """
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    keep = np.isfinite(x) & np.isfinite(y)
    x, y = x[keep], y[keep]
    n = len(x)
    if n < 3 or np.ptp(x) == 0 or np.ptp(y) == 0:
        return math.nan, math.nan
    rx = sps.rankdata(x) - (n + 1) / 2.0
    ry = sps.rankdata(y) - (n + 1) / 2.0
    rho = float(np.dot(rx, ry) / math.sqrt(np.dot(rx, rx) * np.dot(ry, ry)))
    rho = min(1.0, max(-1.0, rho))
    if abs(rho) == 1.0:
        return rho, 0.0
    t = rho * math.sqrt((n - 2) / ((1.0 - rho) * (1.0 + rho)))
    return rho, float(2.0 * sps.t.sf(abs(t), n - 2))


def average_ranks(values):
    """Ranks 1..n of ``values`` (ties: their average rank)."""
    return sps.rankdata(np.asarray(values, dtype=float))


def rank_eta2(ranks, labels):
    """(eta^2, p, levels) of the ``ranks`` of an output over the levels of a factor ``labels``.

    eta^2 = between-level / total sum of squares of the ranks: the share of the rank variance the
    factor explains, rho^2 of a two-level factor's indicator. p: the Kruskal-Wallis test, whose
    statistic with average ranks (tie-corrected) is exactly H = (n - 1) eta^2, on chi^2 with
    levels - 1 degrees of freedom (Kruskal and Wallis 1952). (nan, nan, levels) when the ranks
    do not vary or the factor has one level.
    """
    ranks = np.asarray(ranks, dtype=float)
    _, codes = np.unique(np.asarray(labels).astype(str), return_inverse=True)
    levels = int(codes.max()) + 1 if len(codes) else 0
    centred = ranks - ranks.mean()
    total = float(np.dot(centred, centred))
    if levels < 2 or total == 0.0:
        return math.nan, math.nan, levels
    counts = np.bincount(codes, minlength=levels)
    sums = np.bincount(codes, weights=centred, minlength=levels)
    between = float(np.sum(sums**2 / counts))
    eta2 = min(1.0, max(0.0, between / total))
    h = (len(ranks) - 1) * eta2
    return eta2, float(sps.chi2.sf(h, levels - 1)), levels


GRAM_CHUNK_ROWS = 16384  # rows per block of the rank products: small float64 blocks, exact integer sums
GRAM_THREAD_ROWS = 1 << 17  # rows of the rank products per thread task


def doubled_centred_ranks(values):
    """2 rank - (n + 1) of each value (average ranks of ties): integers (so int32 storage is exact and
    half the memory of float64) whose mean is 0; correlations of them are those of the ranks."""
    values = np.asarray(values, dtype=float)
    return np.rint(2.0 * sps.rankdata(values) - (len(values) + 1)).astype(np.int32)


def _gram_rows(ranks, output_ranks, start, stop, block_rows, dtype=np.int64):
    """The rank products of rows start..stop, as exact integer sums (``dtype``: int64, or object,
    Python's integers, where int64 could overflow) of exact float64 blocks."""
    k = ranks.shape[1]
    gram = np.zeros((k + 1, k + 1), dtype=dtype)
    block = np.empty((min(stop - start, block_rows), k + 1))
    for first in range(start, stop, block_rows):
        rows = min(block_rows, stop - first)
        block[:rows, :k] = ranks[first : first + rows]
        block[:rows, k] = output_ranks[first : first + rows]
        products = np.einsum("ij,ik->jk", block[:rows], block[:rows]).astype(np.int64)
        gram += products if dtype is np.int64 else products.astype(object)  # object: Python ints, no np.int64
    return gram


def rank_gram(ranks, output_ranks):
    """Gram matrix [k + 1, k + 1] of the columns of ``ranks`` [n, k] and ``output_ranks`` (doubled
    centred ranks, |r| < n), exact: each float64 block of rows sums integer products below 2^53
    (``GRAM_CHUNK_ROWS`` rows, fewer above ~70,000 runs), the blocks add up as integers (int64 up
    to ~2 million runs, n^3 < 2^63; Python's beyond), so the sum is the same in any order, and row
    ranges are summed on threads (einsum releases the GIL); rounded to float64 once. einsum, not
    BLAS: OpenBLAS's first call starts a thread pool, seconds on a busy machine, and its float sums
    depend on the CPU's kernels."""
    n, k = ranks.shape
    largest = max(n, 1) ** 2  # a product of two ranks, at most
    block_rows = max(1, min(GRAM_CHUNK_ROWS, (1 << 53) // largest))
    dtype = np.int64 if n**3 < 1 << 63 else object
    from refexmc.report import data  # the report's thread count; imported here: refexmc.report imports stats

    parts = data.map_on_threads(
        lambda start: _gram_rows(ranks, output_ranks, start, min(n, start + GRAM_THREAD_ROWS), block_rows, dtype),
        range(0, n, GRAM_THREAD_ROWS),
    )
    return np.sum(parts, axis=0, dtype=dtype).astype(float) if parts else np.zeros((k + 1, k + 1))


def _rank_correlation_p(rho, dof):
    """Two-sided p-value of rank correlations ``rho`` with ``dof`` degrees of freedom (t approximation)."""
    with np.errstate(invalid="ignore", divide="ignore"):
        t = rho * np.sqrt(dof / ((1.0 - rho) * (1.0 + rho)))
        return np.where(np.abs(rho) == 1.0, 0.0, 2.0 * sps.t.sf(np.abs(t), dof))


def spearman_from_gram(gram, n):
    """Spearman rho and p (as ``spearman``) of each input with the output from ``rank_gram``; NaN for
    a constant input."""
    k = gram.shape[0] - 1
    squares = np.diag(gram)[:k]
    with np.errstate(invalid="ignore", divide="ignore"):
        rho = np.clip(gram[:k, k] / np.sqrt(squares * gram[k, k]), -1.0, 1.0)
    rho[squares == 0] = np.nan
    return rho, _rank_correlation_p(rho, n - 2)


def prcc_from_gram(gram, n):
    """Partial rank correlation (``partial_rank_correlation``) of each input from ``rank_gram``: NaN
    when n < k + 3, an input is constant or the inputs are linearly dependent."""
    k = gram.shape[0] - 1
    rho, p = np.full(k, np.nan), np.full(k, np.nan)
    scale = np.sqrt(np.diag(gram))
    if k == 0 or n < k + 3 or not (scale > 0).all():
        return rho, p
    correlation = gram / np.outer(scale, scale)
    if not np.isfinite(correlation).all() or np.linalg.cond(correlation) > 1e12:
        return rho, p
    precision = np.linalg.inv(correlation)
    rho = np.clip(-precision[:k, k] / np.sqrt(np.diag(precision)[:k] * precision[k, k]), -1.0, 1.0)
    return rho, _rank_correlation_p(rho, n - 2 - (k - 1))


def _ranked_inputs(inputs):
    ranks = np.empty(inputs.shape, dtype=np.int32)
    for j in range(inputs.shape[1]):
        ranks[:, j] = doubled_centred_ranks(inputs[:, j])
    return ranks


def spearman_columns(inputs, output):
    """``spearman`` of each column of ``inputs`` [n, k] with ``output``: (rho, p) arrays. The inputs
    are ranked once for all columns when every value is finite (the usual case), else column by column."""
    inputs = np.asarray(inputs, dtype=float)
    output = np.asarray(output, dtype=float)
    k = inputs.shape[1]
    n = len(output)
    if not (np.isfinite(inputs).all() and np.isfinite(output).all()) or n < 3 or np.ptp(output) == 0:
        pairs = [spearman(inputs[:, j], output) for j in range(k)]
        return np.array([r for r, _ in pairs], dtype=float), np.array([q for _, q in pairs], dtype=float)
    return spearman_from_gram(rank_gram(_ranked_inputs(inputs), doubled_centred_ranks(output)), n)


def partial_rank_correlation(inputs, output):
    """Partial rank correlation (PRCC) of each input column with the output, and its p-value.

    Ranks of every input and of the output; the PRCC of input j is the correlation of the parts of
    rank(x_j) and rank(y) that the other inputs' ranks do not explain linearly (Marino et al. 2008,
    J. Theor. Biol. 254, eq. 2), computed as -P_jy / sqrt(P_jj P_yy) with P the inverse of the rank
    correlation matrix. p-value: t = r sqrt(dof / (1 - r^2)), dof = n - 2 - (k - 1) for k inputs.
    ``inputs``: array [n, k] of inputs that vary; rows with a non-finite value are dropped.
    Returns two arrays of k values, NaN where not computable (n < k + 3, or inputs linearly dependent).
    """
    inputs = np.asarray(inputs, dtype=float)
    output = np.asarray(output, dtype=float)
    keep = np.isfinite(inputs).all(axis=1) & np.isfinite(output)
    inputs, output = inputs[keep], output[keep]
    n, k = inputs.shape
    if k == 0 or n < k + 3 or np.ptp(output) == 0:
        return np.full(k, np.nan), np.full(k, np.nan)
    return prcc_from_gram(rank_gram(_ranked_inputs(inputs), doubled_centred_ranks(output)), n)


def spearman_critical(n, confidence=CONFIDENCE):
    """|rho| above which a rank correlation differs from 0 at the two-sided level 1 - confidence."""
    if n < 4:
        return math.nan
    t = sps.t.ppf(1 - (1 - confidence) / 2, n - 2)
    return float(t / math.sqrt(n - 2 + t * t))


def convergence_points(n, count=40, start=10):
    """Run counts at which running statistics are evaluated: about `count` log-spaced values up to n."""
    if n <= 0:
        return np.zeros(0, dtype=int)
    start = min(start, n)
    points = np.unique(np.round(np.geomspace(start, n, count)).astype(int))
    return points


# --- two-sample comparisons (refexmc.report.compare) ---------------------------------------------


def wilson_interval(successes, n, confidence=CONFIDENCE):
    """Wilson score interval of a binomial proportion; (nan, nan) for n = 0."""
    if n == 0:
        return math.nan, math.nan
    z = float(sps.norm.ppf(1.0 - (1.0 - confidence) / 2.0))
    centre = (successes + z * z / 2.0) / (n + z * z)
    half = z * math.sqrt(successes * (n - successes) / n + z * z / 4.0) / (n + z * z)
    return max(0.0, centre - half), min(1.0, centre + half)


def newcombe_interval(x1, n1, x2, n2, confidence=CONFIDENCE):
    """Newcombe's hybrid score interval of p1 - p2 (x1/n1 - x2/n2); (nan, nan) if either n is 0.

    Newcombe, Statistics in Medicine 17 (1998) 873-890, method 10: with Wilson intervals
    [l_i, u_i] of each rate, d - sqrt((p1 - l1)^2 + (u2 - p2)^2) ... d + sqrt((u1 - p1)^2 + (p2 - l2)^2).
    """
    if n1 == 0 or n2 == 0:
        return math.nan, math.nan
    p1, p2 = x1 / n1, x2 / n2
    l1, u1 = wilson_interval(x1, n1, confidence)
    l2, u2 = wilson_interval(x2, n2, confidence)
    d = p1 - p2
    return d - math.sqrt((p1 - l1) ** 2 + (u2 - p2) ** 2), d + math.sqrt((u1 - p1) ** 2 + (p2 - l2) ** 2)


def welch_interval(baseline, current, confidence=CONFIDENCE):
    """mean(current) - mean(baseline) and its Welch (unequal variances) t interval; NaN below 2 values."""
    baseline, current = np.asarray(baseline, float), np.asarray(current, float)
    nb, nc = len(baseline), len(current)
    if nb < 2 or nc < 2:
        d = current.mean() - baseline.mean() if nb and nc else math.nan
        return float(d), (math.nan, math.nan)
    d = float(current.mean() - baseline.mean())
    vb, vc = baseline.var(ddof=1) / nb, current.var(ddof=1) / nc
    se = math.sqrt(vb + vc)
    if se == 0.0:
        return d, (d, d)
    df = (vb + vc) ** 2 / (vb**2 / (nb - 1) + vc**2 / (nc - 1))
    t = float(sps.t.ppf(1.0 - (1.0 - confidence) / 2.0, df))
    return d, (d - t * se, d + t * se)


def median_interval(values, confidence=CONFIDENCE):
    """Median and its distribution-free two-sided interval (order statistics, as the sign test).

    Each side is a one-sided bound at (1 + confidence) / 2 from :func:`percentile_bound`;
    (nan, nan) with fewer than 6 values at 95 %.
    """
    values = np.sort(np.asarray(values, float))
    if len(values) == 0:
        return math.nan, (math.nan, math.nan)
    side = 1.0 - (1.0 - confidence) / 2.0
    low = percentile_bound(values, 50.0, "lower", side)
    high = percentile_bound(values, 50.0, "upper", side)
    return float(np.median(values)), (low, high)


def wilcoxon_p(differences):
    """Two-sided Wilcoxon signed-rank p-value of paired differences (zeros dropped); 1 when all are 0."""
    differences = np.asarray(differences, float)
    if len(differences) == 0:
        return math.nan
    if not np.any(differences != 0.0):
        return 1.0
    return float(sps.wilcoxon(differences).pvalue)


def ks_p(baseline, current):
    """Two-sided two-sample Kolmogorov-Smirnov p-value; NaN when a sample is empty."""
    if len(baseline) == 0 or len(current) == 0:
        return math.nan
    return float(sps.ks_2samp(baseline, current).pvalue)


# --- tests whose p-value and printed interval are one construction (refexmc compare) -------------


def sign_test_p(differences):
    """Two-sided exact sign-test p-value of paired differences, the inversion of
    :func:`median_interval`: the interval excludes 0 exactly when p <= 1 - confidence.

    The lower bound X_(r) is > 0 when at most r - 1 differences are <= 0, i.e. when
    P(Binomial(n, 1/2) <= #(d <= 0)) <= (1 - confidence) / 2 (``order_statistic_lower_rank``);
    mirrored for the upper bound. Zeros count against both sides (a zero difference never
    shows a change); p = 2 min(both tails), at most 1. NaN without differences.
    """
    differences = np.asarray(differences, float)
    n = len(differences)
    if n == 0:
        return math.nan
    not_positive = int(np.count_nonzero(differences <= 0.0))
    not_negative = int(np.count_nonzero(differences >= 0.0))
    tail = min(sps.binom.cdf(not_positive, n, 0.5), sps.binom.cdf(not_negative, n, 0.5))
    return float(min(1.0, 2.0 * tail))


def welch_p(baseline, current):
    """Two-sided Welch t-test p-value of mean(current) - mean(baseline), the inversion of
    :func:`welch_interval` (p < 1 - confidence exactly when the interval excludes 0)."""
    baseline, current = np.asarray(baseline, float), np.asarray(current, float)
    nb, nc = len(baseline), len(current)
    if nb < 2 or nc < 2:
        return math.nan
    d = float(current.mean() - baseline.mean())
    vb, vc = baseline.var(ddof=1) / nb, current.var(ddof=1) / nc
    se = math.sqrt(vb + vc)
    if se == 0.0:
        return 1.0 if d == 0.0 else 0.0
    df = (vb + vc) ** 2 / (vb**2 / (nb - 1) + vc**2 / (nc - 1))
    return float(2.0 * sps.t.sf(abs(d) / se, df))


def newcombe_p(x1, n1, x2, n2, iterations=60):
    """Two-sided p-value of p1 - p2 by inverting :func:`newcombe_interval`: 1 - the confidence at
    which the interval just reaches 0 (bisection; the intervals nest as the confidence grows)."""
    if n1 == 0 or n2 == 0:
        return math.nan
    if x1 * n2 == x2 * n1:
        return 1.0
    low, high = 0.0, 1.0 - 1e-15  # confidences: the interval excludes 0 at ``low``, holds it at ``high``
    widest = newcombe_interval(x1, n1, x2, n2, high)
    if widest[0] > 0.0 or widest[1] < 0.0:
        return 1e-15  # excludes 0 at any confidence computable in float64
    for _ in range(iterations):
        middle = (low + high) / 2.0
        a, b = newcombe_interval(x1, n1, x2, n2, middle)
        if a > 0.0 or b < 0.0:
            low = middle
        else:
            high = middle
    return float(1.0 - (low + high) / 2.0)


def mcnemar_exact(lost, won, confidence=CONFIDENCE):
    """Exact McNemar test of a paired binary outcome: of the ``lost + won`` discordant pairs
    (outcome 1 in the baseline only, in the current only), ``won`` ~ Binomial(m, pi), pi = 1/2
    when nothing changed. Returns (p, (low, high)): the central two-sided p-value 2 min(tails)
    and the Clopper-Pearson interval of pi, which excludes 1/2 exactly when p < 1 - confidence."""
    m = lost + won
    if m == 0:
        return 1.0, (0.0, 1.0)
    tail = min(sps.binom.cdf(won, m, 0.5), sps.binom.sf(won - 1, m, 0.5))
    return float(min(1.0, 2.0 * tail)), clopper_pearson(won, m, confidence)
