"""Intervals of a binomial proportion (Clopper-Pearson, "exact"): the success rate of a campaign
and the probability a requirement states. Below ``refexmc.campaign`` (whose sequential stopping
rule decides on them) and ``refexmc.report`` (which prints them): one arithmetic for both.
"""

import math

from scipy.stats import beta

CONFIDENCE = 0.95


def clopper_pearson(successes, n, confidence=CONFIDENCE):
    """Two-sided Clopper-Pearson ("exact") interval of a binomial proportion; (nan, nan) for n = 0."""
    if n == 0:
        return math.nan, math.nan
    alpha = 1.0 - confidence
    low = 0.0 if successes == 0 else float(beta.ppf(alpha / 2, successes, n - successes + 1))
    high = 1.0 if successes == n else float(beta.ppf(1 - alpha / 2, successes + 1, n - successes))
    return low, high


def clopper_pearson_lower(successes, n, confidence=CONFIDENCE):
    """One-sided Clopper-Pearson lower bound: P(true rate >= bound) >= confidence.

    With no failure in n runs it is (1 - confidence)^(1/n), about 1 - 3/n at 95 % ("rule of three").
    """
    if n == 0:
        return math.nan
    if successes == 0:
        return 0.0
    return float(beta.ppf(1.0 - confidence, successes, n - successes + 1))


def clopper_pearson_upper(successes, n, confidence=CONFIDENCE):
    """One-sided Clopper-Pearson upper bound: P(true rate <= bound) >= confidence."""
    if n == 0:
        return math.nan
    if successes == n:
        return 1.0
    return float(beta.ppf(confidence, successes + 1, n - successes))
