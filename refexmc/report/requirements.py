"""Metric grammar and requirement verdicts: ``'METRIC OP VALUE'``, e.g. ``fuel_remaining.min >= 0.20``.

METRIC is either a campaign-level metric (``CAMPAIGN_METRICS``) or ``<column>.<stat>``:

- ``<column>``: a numeric column of the ``runs`` table (``fuel_remaining``, ``fuel_used_kg``,
  ``t_end_s``, ``t_<mode>_s``, ``theta_t_handover_deg``, ``modes_completed``, ``pulses_<k>``,
  ``p.<path>``), or the derived ``pulses_total`` (sum of the thrusters' pulse counts);
- ``<stat>``, over the runs with status ``ok`` (errored runs excluded), NaN values dropped:
  ``count min max mean median std`` (std with ddof 1); ``mean_minus_3sd mean_plus_3sd``;
  ``p<q>`` the q-th percentile, 0 <= q <= 100 (``p0.135 p1 p50 p99 p99.865``; numpy's linear
  interpolation); ``tol_lower tol_upper`` the one-sided normal tolerance bounds, 99.865 % coverage
  at 95 % confidence (the confidence bound of the 3-sigma value, assuming normality);
  ``p<q>_lower95 p<q>_upper95`` distribution-free 95 % confidence bounds on the q-th percentile
  (order statistics; NaN when the campaign has too few runs for one).

OP is one of ``>= <= > < ==``; VALUE a number. A metric that is not computable (NaN: no runs,
too few runs for a bound) fails its requirement. Unknown metrics are bad input (ConfigError).
"""

import difflib
import math
import operator
import re
from dataclasses import dataclass

from refexmc.config.errors import ConfigError
from refexmc.report import stats

CAMPAIGN_METRICS = {
    "runs": "runs in the runs table (ok and errored)",
    "ok_count": "runs with status ok",
    "error_count": "runs with status error (excluded from every other statistic)",
    "error_rate": "error_count / runs",
    "success_count": "ok runs that succeeded",
    "failure_count": "ok runs that did not succeed",
    "success_rate": "success_count / ok_count",
    "success_rate_lower95": "one-sided 95 % Clopper-Pearson lower bound of the success probability",
    "success_rate_upper95": "one-sided 95 % Clopper-Pearson upper bound of the success probability",
    "failure_rate_upper95": "1 - success_rate_lower95: the failure probability bound",
}

NAMED_STATS = stats.BASIC_STATS + stats.BOUND_STATS
SUGGESTED_STATS = NAMED_STATS + stats.PERCENTILE_STATS + ("p0.135_lower95", "p99.865_upper95")
DERIVED_COLUMNS = ("pulses_total",)
NOT_METRIC_COLUMNS = ("run_id", "seed")

OPERATORS = {">=": operator.ge, "<=": operator.le, ">": operator.gt, "<": operator.lt, "==": operator.eq}

_REQUIREMENT = re.compile(r"^\s*(?P<metric>[^\s<>=!]+)\s*(?P<op>[<>=!]+)\s*(?P<value>\S+)\s*$")
_PERCENTILE_TAIL = re.compile(r"\.(p\d+(?:\.\d+)?(?:_lower95|_upper95)?)$")
_NAMED_TAIL = re.compile(r"\.([a-z_0-9]+)$")


@dataclass(frozen=True)
class Requirement:
    text: str
    metric: str
    op: str
    value: float
    source: str  # "campaign" (OUT/campaign.resolved.yaml) or "--require"


def split_metric(metric):
    """``'fuel_remaining.p0.135'`` -> ``('fuel_remaining', 'p0.135')``; a campaign metric -> (metric, None)."""
    if metric in CAMPAIGN_METRICS:
        return metric, None
    match = _PERCENTILE_TAIL.search(metric) or _NAMED_TAIL.search(metric)
    if not match:
        return None, None
    return metric[: match.start()], match.group(1)


def valid_stat(stat):
    if stat in NAMED_STATS:
        return True
    try:
        stats.parse_percentile_stat(stat)
    except ValueError:
        return False
    return True


def check_metric(metric, columns, file=None, line=None, path=()):
    """ConfigError (with did-you-mean) unless ``metric`` names a metric of a campaign with ``columns``."""
    columns = [c for c in columns if c not in NOT_METRIC_COLUMNS] + list(DERIVED_COLUMNS)
    column, stat = split_metric(metric)
    if column is not None and (stat is None or (column in columns and valid_stat(stat))):
        return
    if column in columns:
        guess = difflib.get_close_matches(stat, SUGGESTED_STATS, n=1, cutoff=0.5)
        hint = f"did you mean '{column}.{guess[0]}'?" if guess else f"statistics: {', '.join(SUGGESTED_STATS)}, p<q>"
        raise ConfigError(f"unknown statistic '{stat}' in metric '{metric}'; {hint}", file=file, line=line, path=path)
    candidates = list(CAMPAIGN_METRICS)
    if stat is not None and valid_stat(stat):
        candidates += [f"{c}.{stat}" for c in columns]
    else:
        candidates += [f"{c}.{s}" for c in columns for s in ("min", "max", "mean", "median")]
    guess = difflib.get_close_matches(metric, candidates, n=1, cutoff=0.6)
    hint = f"did you mean '{guess[0]}'?" if guess else "expected a campaign metric or '<runs column>.<statistic>'"
    raise ConfigError(
        f"unknown metric '{metric}'; {hint} (campaign metrics: {', '.join(CAMPAIGN_METRICS)})",
        file=file,
        line=line,
        path=path,
    )


def parse_requirement(text, columns, source="--require", file=None, line=None, path=()):
    """Parse ``'METRIC OP VALUE'`` against the runs ``columns``; ConfigError for bad input."""
    where = {"file": file, "line": line, "path": path}
    if not isinstance(text, str):
        raise ConfigError(f"expected a string 'METRIC OP VALUE', got {text!r}", **where)
    match = _REQUIREMENT.match(text)
    if not match:
        raise ConfigError(f"expected 'METRIC OP VALUE' (e.g. 'fuel_remaining.min >= 0.2'), got '{text}'", **where)
    metric, op, value_text = match.group("metric", "op", "value")
    if op not in OPERATORS:
        raise ConfigError(f"unknown operator '{op}' in '{text}'; expected one of {', '.join(OPERATORS)}", **where)
    try:
        value = float(value_text)
    except ValueError:
        raise ConfigError(f"expected a number after '{op}', got '{value_text}' in '{text}'", **where) from None
    if not math.isfinite(value):
        raise ConfigError(f"expected a finite number after '{op}', got '{value_text}' in '{text}'", **where)
    check_metric(metric, columns, **where)
    return Requirement(text=text.strip(), metric=metric, op=op, value=value, source=source)


def evaluate(requirement, metric_value):
    """The verdict of one requirement as a dict (JSON-ready); NaN fails ("not computable")."""
    actual = float(metric_value)
    computable = math.isfinite(actual)
    passed = computable and bool(OPERATORS[requirement.op](actual, requirement.value))
    return {
        "requirement": requirement.text,
        "source": requirement.source,
        "metric": requirement.metric,
        "op": requirement.op,
        "value": requirement.value,
        "actual": actual if computable else None,
        "passed": passed,
        "note": "" if computable else "not computable (no runs, or too few runs for this bound)",
    }
