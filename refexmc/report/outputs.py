"""What the mission declares and produces: the report's metrics, their order, labels and words.

The report is built from the campaign, not from one reference mission:

- **requirement metrics** first: the runs columns the requirements judge (``<column>.<stat>``, and
  the runs column of each pointing record, docs/pointing.md), in the order of the requirements,
  each labelled by its requirement(s);
- then the **other outputs** the runs table has (numeric, not an input ``p.``, not a per-thruster
  pulse count), in table order;
- columns with the same value in every successful flight are **constant** and summarised in one
  line (a requirement metric keeps its row even when constant);
- columns without a finite value in any run are outputs the mission does **not produce** (a
  propellant fraction without propellant, an end-of-flight angle of an orbit mission) and are left
  out; so is the propellant used of a mission without a propellant load (``fuel_remaining`` not
  produced) when it is 0 in every flown run (a wheel vehicle);
- the per-thruster pulse counts ``pulses_<k>`` are **folded** into one table.

Words: a column's description comes from ``tails.TAIL_RULES``; the angle at the end of the flight
(``attitude_error_end_deg``) is described by the mission's last mode, and only the ReFEx vehicle
(``vehicle.name == "refex"``, the mission of 000) gets 000's words ("hand-over", "separation",
"000 Fig.").
"""

import math
from fnmatch import fnmatchcase

import numpy as np
import pandas as pd

from refexmc.config.requirements import CAMPAIGN_METRICS, split_metric
from refexmc.report import tails

REFEX_VEHICLE = "refex"
INPUT_PREFIX = "p."
NOT_OUTPUTS = ("run_id", "seed", "modes_completed")
UNITS = (  # (column suffix, unit as shown); the first match decides
    ("_arcsec", "arcsec"),
    ("_deg_s", "deg/s"),
    ("_deg", "deg"),
    ("_n_m_s", "N m s"),
    ("_n_m", "N m"),
    ("_m_s", "m/s"),
    ("_kg", "kg"),
    ("_m", "m"),
    ("_s", "s"),
)
END_ANGLE_COLUMN = "attitude_error_end_deg"
PROPELLANT_USED_COLUMNS = ("fuel_used_kg",)  # not produced when 0 in every flown run without a propellant load
DISPLAY_ORDER = (  # the other outputs a runs table has come in this order, then the rest in table order
    "fuel_remaining",
    "fuel_used_kg",
    "attitude_error_end_deg",
    "burn_pointing_max_deg",
    "burn_pointing_rms_deg",
    "engine_propellant_used_kg",
    "pointing_max_arcsec",
    "pointing_rms_x_arcsec",
    "pointing_rms_y_arcsec",
    "pointing_rms_z_arcsec",
    "pointing_end_x_arcsec",
    "pointing_end_y_arcsec",
    "pointing_end_z_arcsec",
    "wheel_momentum_peak_n_m_s",
    "wheel_momentum_end_n_m_s",
    "wheel_torque_demand_peak_n_m",
    "wheel_saturated_s",
    "angular_momentum_residual",
    "t_end_s",
    "pulses_total",
)


def is_refex(campaign):
    """The ReFEx vehicle of 000: the only mission whose report uses 000's words and figure numbers."""
    return (campaign.resolved.get("vehicle") or {}).get("name") == REFEX_VEHICLE


def unit(column):
    """The unit of a runs column from its name (``pointing_max_arcsec`` -> ``arcsec``); '' if none."""
    if column == "fuel_remaining":
        return "fraction of the load"
    for suffix, text in UNITS:
        if column.endswith(suffix):
            return text
    return ""


def is_pulse_column(column):
    return column.startswith("pulses_") and column[7:].isdigit()


def judged_column(verdict):
    """The runs column a verdict judges, or None (a campaign metric, an input ``p.``): the column of
    ``<column>.<stat>``, or the runs column of a pointing record (``kind: pointing``, docs/pointing.md:
    its ``metric`` is the column itself, e.g. ``ape_total_temporal_arcsec``, bounded from above)."""
    metric = verdict["metric"]
    if verdict.get("kind") == "pointing":
        return metric
    if metric in CAMPAIGN_METRICS:
        return None
    column, _ = split_metric(metric)
    if column is None or column.startswith(INPUT_PREFIX):
        return None
    return column


def requirement_columns(verdicts):
    """Runs columns judged by the requirements (not campaign metrics, not inputs), in requirement
    order; a pointing record's column counts like any other."""
    columns = []
    for verdict in verdicts:
        column = judged_column(verdict)
        if column is not None and column not in columns:
            columns.append(column)
    return columns


def requirements_of(column, verdicts):
    """The verdicts that judge ``column`` (pointing records included)."""
    return [v for v in verdicts if judged_column(v) == column]


def column_tail(column, verdicts=()):
    """Worse tail of a column: ``tails.worse_tail``; else from its requirements (``<=`` upper,
    ``>=`` lower, both kinds "both"); else "both" (an output without a bad end, e.g. an entry state)."""
    tail = tails.worse_tail(column)
    if tail is not None:
        return tail
    sides = {
        "upper" if v["op"] in ("<=", "<") else "lower" for v in requirements_of(column, verdicts) if v["op"] != "=="
    }
    return sides.pop() if len(sides) == 1 else "both"


def describe(column, campaign):
    """What a column is, in the mission's words."""
    if column == END_ANGLE_COLUMN:
        modes = campaign.modes
        if is_refex(campaign):
            return "total angle error at hand-over"
        return f"total angle error when the last mode ({modes[-1]}) ends" if modes else "total angle error at the end"
    for pattern, _, text in tails.TAIL_RULES:
        if fnmatchcase(column, pattern):
            return text
    if column.startswith("entry_"):
        return f"entry state: {column[6:].rsplit('_', 1)[0].replace('_', ' ')}"
    return column.replace("_", " ")


def numeric_output_columns(runs):
    return [
        c
        for c in runs.columns
        if c not in NOT_OUTPUTS
        and not c.startswith(INPUT_PREFIX)
        and pd.api.types.is_numeric_dtype(runs[c])
        and not pd.api.types.is_bool_dtype(runs[c])
    ]


def plan(campaign, verdicts):
    """The report's metrics (JSON-ready dict): ``requirement_columns``, ``other_columns``,
    ``constant_columns`` {column: value}, ``pulse_columns``, ``not_produced``, and per column
    ``labels`` (what it is, with its unit and requirements), ``tails`` and ``units``."""
    runs = campaign.runs
    successful = campaign.successful
    ok = campaign.ok
    judged = [c for c in requirement_columns(verdicts) if c in runs]
    others, constants, not_produced, pulses = [], {}, [], []
    for column in numeric_output_columns(runs):
        if column in judged:
            continue
        if is_pulse_column(column):
            pulses.append(column)
            continue
        flown = ok[column].to_numpy(dtype=float)
        if not np.isfinite(flown).any():
            not_produced.append(column)
            continue
        values = successful[column].to_numpy(dtype=float)
        values = values[np.isfinite(values)]
        if len(values) and np.ptp(values) == 0.0:
            constants[column] = float(values[0])
            continue
        others.append(column)
    if "fuel_remaining" in not_produced:  # no propellant load (a wheel vehicle): its zero use is no output
        for column in [c for c in others + list(constants) if c in PROPELLANT_USED_COLUMNS]:
            if (ok[column].to_numpy(dtype=float) == 0.0).all():
                others = [c for c in others if c != column]
                constants.pop(column, None)
                not_produced.append(column)
    position = {c: k for k, c in enumerate(runs.columns)}
    others.sort(key=lambda c: (DISPLAY_ORDER.index(c) if c in DISPLAY_ORDER else len(DISPLAY_ORDER), position[c]))
    if pulses:
        total = successful["pulses_total"].to_numpy(dtype=float) if "pulses_total" in successful else np.zeros(0)
        if "pulses_total" in constants or (len(total) and np.ptp(total) == 0.0):
            constants.pop("pulses_total", None)
            constants["pulses_total"] = float(total[0]) if len(total) else math.nan
            others = [c for c in others if c != "pulses_total"]
    columns = judged + others + list(constants) + pulses
    labels, column_tails, units = {}, {}, {}
    for column in columns:
        reqs = requirements_of(column, verdicts)
        text = describe(column, campaign)
        if reqs:
            text += "; required: " + ", ".join(v["requirement"] for v in reqs)
        labels[column] = text
        column_tails[column] = column_tail(column, verdicts)
        units[column] = unit(column)
    return {
        "requirement_columns": judged,
        "other_columns": others,
        "constant_columns": constants,
        "pulse_columns": pulses,
        "not_produced": not_produced,
        "labels": labels,
        "tails": column_tails,
        "units": units,
    }


def _pointing_margin(v):
    """A pointing record's margin: its verdict's bound (the Clopper-Pearson lower bound on the runs
    within, or the t bound on the mean fraction above) against its threshold, relative to the threshold."""
    actual, threshold = v.get("actual"), v.get("threshold")
    if actual is None or threshold is None or not math.isfinite(actual):
        return -math.inf
    scale = max(abs(threshold), abs(actual), 1e-300)
    if v.get("interpretation") == "mixed":  # an upper bound on the fraction above must stay below
        return (threshold - actual) / scale
    return (actual - threshold) / scale


def margins(verdicts):
    """Requirement columns ordered from failing to closest-to-failing: [(column, margin)], margin the
    requirement's actual value's distance to its bound relative to the bound's size (negative: failing);
    a pointing record's from its verdict's bound against its threshold."""
    best = {}
    for v in verdicts:
        column = judged_column(v)
        if column is None:
            continue
        if v.get("kind") == "pointing":
            margin = _pointing_margin(v)
            if not v["passed"]:
                margin = min(margin, -0.0)
            best[column] = min(best.get(column, math.inf), margin)
            continue
        actual, bound = v["actual"], v["value"]
        if actual is None or not math.isfinite(actual):
            margin = -math.inf
        else:
            scale = max(abs(bound), abs(actual), 1e-300)
            margin = (bound - actual) / scale if v["op"] in ("<=", "<") else (actual - bound) / scale
            if v["op"] == "==":
                margin = -abs(actual - bound) / scale
            if not v["passed"]:
                margin = min(margin, -0.0)
        best[column] = min(best.get(column, math.inf), margin)
    return sorted(best.items(), key=lambda item: item[1])
