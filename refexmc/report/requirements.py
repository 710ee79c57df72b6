"""Requirement verdicts for the report. The grammar (``'METRIC OP VALUE'``, metric names,
statistics) belongs to the campaign file and lives in :mod:`refexmc.config.requirements`.
"""

import math

from refexmc.config.requirements import (  # noqa: F401 - the grammar, as the report modules use it
    CAMPAIGN_METRICS,
    OPERATORS,
    Requirement,
    check_metric,
    parse_requirement,
    split_metric,
)


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
