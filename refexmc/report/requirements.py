"""Requirement verdicts and the campaign's overall verdict. The grammar (``'METRIC OP VALUE'``,
metric names, statistics) belongs to the campaign file and lives in :mod:`refexmc.config.requirements`.

How the report evaluates a metric (docs/report.md):

- campaign metrics (``success_rate``, ``success_rate_lower95``, ...) are over every stored run;
  an errored run counts as unsuccessful;
- ``<column>.<stat>`` of an output column is over every stored run: the successful flights give
  their values, and every failed flight (success false) and errored run counts as failing the
  requirement. It stands at the failing end of the distribution (-inf for ``>=``/``>``, +inf for
  ``<=``/``<``): min and max fail with one such run, a percentile fails when its tail reaches
  them, moment statistics (mean, std, three_sigma, mean_minus_3sd, mean_plus_3sd, tol_lower, tol_upper) fail
  with one, and ``==`` cannot be met by them (stats.column_stat_with_failing); ``count`` counts
  the successful flights' values;
- ``<column>.<stat>`` of an input column (``p.<path>``) is over every run's value.

The overall verdict is INCOMPLETE (not every planned run stored), ERRORED (some runs errored),
FAIL, PASS or NO REQUIREMENTS; only PASS and NO REQUIREMENTS exit 0.
"""

import math

from refexmc.config.requirements import (  # noqa: F401 - the grammar, as the report modules use it
    CAMPAIGN_METRICS,
    OPERATORS,
    Requirement,
    check_metric,
    parse_percentile_stat,
    parse_requirement,
    split_metric,
)
from refexmc.report import stats

FAILING_SIDE = {">=": "low", ">": "low", "<=": "high", "<": "high", "==": None}
LISTED_IDS = 10
INPUT_PREFIX = "p."


def plural(count, word):
    return f"{count} {word}{'' if count == 1 else 's'}"


def listed_ids(ids, limit=LISTED_IDS):
    ids = [int(i) for i in ids]
    text = ", ".join(str(i) for i in ids[:limit])
    return text + (f", ... ({len(ids)} in all)" if len(ids) > limit else "")


def failing_description(failed_ids, errored_ids):
    """``"failed flights 3, 11 and errored runs 7"`` (ids listed, truncated)."""
    parts = []
    if len(failed_ids):
        parts.append(f"failed flight{'s' if len(failed_ids) > 1 else ''} {listed_ids(failed_ids)}")
    if len(errored_ids):
        parts.append(f"errored run{'s' if len(errored_ids) > 1 else ''} {listed_ids(errored_ids)}")
    return " and ".join(parts)


def campaign_metric_covers(campaign):
    n = len(campaign.runs)
    errored = len(campaign.errored)
    return f"all {plural(n, 'run')}" + (f" ({plural(errored, 'errored run')} count as unsuccessful)" if errored else "")


def _too_few_runs(metric, runs):
    """Why a percentile's confidence bound has no value: the runs it needs (None for another statistic,
    or with runs enough)."""
    _, stat = split_metric(metric)
    try:
        percent, side = parse_percentile_stat(stat or "")
    except ValueError:
        side = None
    needed = stats.percentile_bound_runs(percent, side) if side else None
    if needed is not None and runs < needed:
        return f"not computable: {stat} needs at least {needed} runs, this campaign has {runs}"
    return None


def evaluate(requirement, campaign, level):
    """The verdict of one requirement as a dict (JSON-ready); ``level``: summary.campaign_metrics."""
    verdict = {
        "requirement": requirement.text,
        "source": requirement.source,
        "metric": requirement.metric,
        "op": requirement.op,
        "value": requirement.value,
    }
    failing_ids, note = [], ""
    actual_successful = None
    if requirement.metric in CAMPAIGN_METRICS:
        actual = float(level[requirement.metric])
        covers = campaign_metric_covers(campaign)
        failing_ids = campaign_metric_failing_ids(requirement.metric, campaign)
    else:
        column, stat = split_metric(requirement.metric)
        if column.startswith(INPUT_PREFIX):
            actual = stats.column_stat(campaign.runs[column].to_numpy(dtype=float), stat)
            covers = f"all {plural(len(campaign.runs), 'run')} (an input: every run has its value)"
        else:
            values = campaign.successful[column].to_numpy(dtype=float)
            failed_ids = campaign.failed["run_id"].to_numpy()
            errored_ids = campaign.errored["run_id"].to_numpy()
            failing = len(failed_ids) + len(errored_ids)
            side = FAILING_SIDE[requirement.op]
            actual = stats.column_stat_with_failing(values, failing, stat, side)
            finite = int(stats.column_stat(values, "count"))
            covers = f"all {plural(len(campaign.runs), 'run')}: {plural(finite, 'successful flight')}"
            if finite < len(values):
                covers += f" with a value ({len(values) - finite} without)"
            if failing:
                covers += f"; {failing_description(failed_ids, errored_ids)} count as failing"
                failing_ids = sorted(int(i) for i in (*failed_ids, *errored_ids))
                alone = stats.column_stat(values, stat)
                actual_successful = alone if math.isfinite(alone) else None
                if stat != "count":
                    if math.isinf(actual) or (side is None and math.isnan(actual)):
                        note = f"fails because of the {failing_description(failed_ids, errored_ids)}"
                    else:
                        end = "low" if side == "low" else "high"
                        note = f"{plural(failing, 'failing run')} ranked at the {end} end"
    computable = math.isfinite(actual)
    passed = computable and bool(OPERATORS[requirement.op](actual, requirement.value))
    if not computable:
        needs = _too_few_runs(requirement.metric, len(campaign.runs))
        if needs:
            note = f"{note}; {needs}" if note else needs
        elif not note:
            note = "not computable (no runs, or too few runs for this bound)"
    if requirement.metric == "success_rate" and requirement.op in (">=", ">"):
        if passed:
            note = _estimate_only(level, requirement.value) or note
        elif computable:
            note = _failed_by_estimate_only(level, requirement.value, requirement.op) or note
    verdict.update(
        actual=actual if computable else None,
        passed=passed,
        covers=covers,
        failing_count=len(failing_ids),
        failing_run_ids=failing_ids[: LISTED_IDS * 2],
        actual_successful_flights=actual_successful,
        note=note,
    )
    return verdict


SUCCESS_METRICS = (  # campaign metrics counting successes: the unsuccessful runs count as failing them
    "success_rate",
    "success_rate_lower95",
    "success_rate_upper95",
    "failure_rate_upper95",
    "success_count",
    "failure_count",
)
ERROR_METRICS = ("ok_count", "error_count", "error_rate")  # the errored runs count as failing them


def campaign_metric_failing_ids(metric, campaign):
    """The runs that count as failing a campaign metric (``failing_run_ids``, docs/report.md): the
    unsuccessful ones (failed flights and errored runs) for the success metrics, the errored ones for
    the error metrics, none for ``runs``."""
    if metric in SUCCESS_METRICS:
        ids = (*campaign.failed["run_id"].to_numpy(), *campaign.errored["run_id"].to_numpy())
    elif metric in ERROR_METRICS:
        ids = campaign.errored["run_id"].to_numpy()
    else:
        return []
    return sorted(int(i) for i in ids)


def _failed_by_estimate_only(level, value, op):
    """The note of a success rate below its bound by the estimate whose one-sided 95 % upper bound
    still reaches the bound ('' when the upper bound is below it too): the runs do not show it met,
    nor missed; not demonstrated either way (the mirror of ``_estimate_only``)."""
    upper = float(level["success_rate_upper95"])
    if not OPERATORS[op](upper, value):
        return ""
    return (
        f"failed by the estimate only: the one-sided 95 % upper bound is {upper:.3g} over "
        f"{plural(int(level['runs']), 'run')}, so the rate may still be {op} {value:g}: not demonstrated either "
        f"way; 'success_rate_upper95 < {value:g}' would show the failure with confidence"
    )


def _estimate_only(level, value):
    """The note of a success rate met by its estimate but not by its 95 % lower bound ('' if met
    by both): how to require it with confidence, and the runs that takes without a failure
    (one-sided Clopper-Pearson with none: value^n <= 0.05)."""
    lower = float(level["success_rate_lower95"])
    if not lower < value:
        return ""
    note = (
        f"met by the estimate only: the one-sided 95 % lower bound is {lower:.3g} over "
        f"{plural(int(level['runs']), 'run')}; 'success_rate_lower95 >= {value:g}' requires it with confidence"
    )
    if 0.0 < value < 1.0:
        note += f" (at least {math.ceil(math.log(0.05) / math.log(value))} runs without a failure)"
    return note


def overall_verdict(completeness, verdicts):
    """(verdict, passed, banner): the campaign's verdict, whether it exits 0, and the banner text ('' if none)."""
    met = sum(v["passed"] for v in verdicts)
    judged = f"requirements: {met} of {len(verdicts)} met" + (" on the stored runs" if verdicts else "")
    if not completeness["complete"]:
        planned = completeness["runs_planned"]
        stored = f"{completeness['runs_stored']} of {planned} planned runs stored" if planned is not None else ""
        detail = "; ".join(filter(None, [stored, *completeness["problems"]]))
        if completeness["missing_run_count"]:
            detail += f"; missing run ids {completeness['missing_run_ids']}"
        if completeness["errored_count"]:
            detail += f"; {plural(completeness['errored_count'], 'errored run')}"
        banner = (
            f"INCOMPLETE campaign: {detail}. No verdict until every planned run has flown "
            f"(finish it with `{completeness.get('resume_command') or 'refexmc run CAMPAIGN -o OUT --resume'}`)."
        )
        return "INCOMPLETE", False, banner + f" {judged}."
    if completeness["errored_count"]:
        count = completeness["errored_count"]
        banner = (
            f"ERRORED runs: {count} of {completeness['runs_stored']} runs raised errors "
            f"(run ids {listed_ids(completeness['errored_run_ids'][:LISTED_IDS])}"
            + (", ..." if count > LISTED_IDS else "")
            + "); they count as failing every requirement, and the campaign cannot be accepted while runs are errored."
        )
        return "ERRORED", False, banner + f" {judged}."
    if not verdicts:
        return "NO REQUIREMENTS", True, ""
    if met == len(verdicts):
        return "PASS", True, ""
    return "FAIL", False, ""


def requirement_label(verdict, overall):
    """PASS/FAIL of one requirement; a met requirement of an incomplete or errored campaign says "met"."""
    if not verdict["passed"]:
        return "FAIL"
    return "PASS" if overall in ("PASS", "FAIL") else "met"
