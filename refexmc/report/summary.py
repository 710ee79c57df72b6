"""The report's numbers as one JSON-ready dict (``OUT/report/summary.json``)."""

import math
import shlex

import numpy as np

from refexmc.report import data, published, stats, tails
from refexmc.report.requirements import campaign_metric_covers

KEY_COLUMNS = (  # those a runs table has, in this order
    "fuel_remaining",
    "fuel_used_kg",
    "theta_t_handover_deg",
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
SENSITIVITY_OUTPUTS = ("fuel_used_kg", "theta_t_handover_deg")
WORST_CASES = (  # (column, what its worst end means); the end is the column's worse tail (tails.py)
    ("fuel_remaining", "least propellant remaining"),
    ("theta_t_handover_deg", "largest total angle error at hand-over"),
    ("t_end_s", "longest flight"),
)
WORST_COUNT = 5

# 000 Table 4: the thruster failures the ReFEx allocation compensates (8 thrusters)
PAPER_COMPENSABLE = frozenset(
    [(1,), (2,), (3,), (4,), (7,), (8,), (1, 2), (3, 4), (1, 3), (2, 4), (7, 8), (1, 8), (2, 8), (3, 7), (4, 7)]
)
LISTED_RUNS = 20
FAILURE_EXAMPLES = 5
REASON_CHARACTERS = 160


def campaign_metrics(campaign):
    """Counts, success rate and its Clopper-Pearson bounds over every stored run (an errored run
    counts as unsuccessful)."""
    runs = campaign.runs
    n = len(runs)
    n_ok = len(campaign.ok)
    successes = len(campaign.successful)
    lower = stats.clopper_pearson_lower(successes, n)
    return {
        "runs": float(n),
        "ok_count": float(n_ok),
        "error_count": float(n - n_ok),
        "error_rate": (n - n_ok) / n if n else math.nan,
        "success_count": float(successes),
        "failure_count": float(n_ok - successes),
        "success_rate": successes / n if n else math.nan,
        "success_rate_lower95": lower,
        "success_rate_upper95": stats.clopper_pearson_upper(successes, n),
        "failure_rate_upper95": 1.0 - lower,
    }


def success_section(campaign, level):
    n = int(level["runs"])
    k = int(level["success_count"])
    failed, errored = int(level["failure_count"]), int(level["error_count"])
    low, high = stats.clopper_pearson(k, n)
    section = {
        "successes": k,
        "runs": n,
        "failed_flights": failed,
        "errored_runs": errored,
        "covers": campaign_metric_covers(campaign),
        "rate": level["success_rate"],
        "ci95": [low, high],
        "lower95": level["success_rate_lower95"],
        "failure_rate_upper95": level["failure_rate_upper95"],
        "method": "Clopper-Pearson (exact binomial): two-sided 95 % interval; one-sided 95 % lower bound",
    }
    if n and k == n:
        rule_of_three = f"; rule of three: 3/N = {100 * 3 / n:.3g} %" if n >= 30 else ""
        section["statement"] = (
            f"no failure in {n} run{'s' if n > 1 else ''}: failure probability < "
            f"{100 * level['failure_rate_upper95']:.3g} % at 95 % confidence (one-sided Clopper-Pearson, "
            f"1 - 0.05^(1/{n}){rule_of_three})"
        )
    elif n:
        kinds = ", ".join(
            text for count, text in ((failed, f"{failed} failed"), (errored, f"{errored} errored")) if count
        )
        section["statement"] = (
            f"{n - k} of {n} runs did not succeed ({kinds}): success rate {100 * k / n:.4g} %, 95 % interval "
            f"[{100 * low:.4g}, {100 * high:.4g}] %"
        )
    return section


def statistics_columns(campaign):
    """The runs columns of the statistics tables, in display order: those with a declared tail; a
    key column no run has a value in is one the mission does not produce (a hand-over angle without
    a hand-over, a propellant fraction without propellant) and is left out."""
    runs = campaign.runs
    columns = [c for c in KEY_COLUMNS if c in runs and np.isfinite(runs[c].to_numpy(dtype=float)).any()]
    columns += [c for c in campaign.mode_time_columns if c in runs]
    columns += [c for c in runs.columns if c.startswith("pulses_") and c[7:].isdigit()]
    return [c for c in columns if tails.worse_tail(c) is not None]


def column_sections(campaign):
    """Statistics of each output column over the successful flights, for the column's worse tail.

    Each entry also says which runs it covers (``covers``, ``n``) and its ``tail``.
    """
    successful = campaign.successful
    n_runs = len(campaign.runs)
    left_out = n_runs - len(successful)
    result = {}
    for column in statistics_columns(campaign):
        values = successful[column].to_numpy(dtype=float)
        tail = tails.worse_tail(column)
        section = stats.describe(values, tail)
        n = int(section["count"])
        covers = f"{n} successful flight{'s' if n != 1 else ''}"
        if n < len(successful):
            covers += f" with a value (of {len(successful)})"
        if left_out:
            covers += f"; {left_out} of {n_runs} runs not included (failed or errored)"
        result[column] = {"covers": covers, "n": n, "tail": tail, **section}
    return result


def statistics_notes(campaign):
    """What the columns of the statistics tables are, for the text and the page."""
    coverage = f"{100 * stats.TOLERANCE_COVERAGE:g} %"
    return {
        "population": (
            "successful flights only (status ok, success true); failed flights and errored runs are in the "
            "failure-reason table and count as failing every requirement"
        ),
        "tails": (
            "upper tail (larger is worse): durations, angle errors, pulses, propellant used; lower tail "
            "(smaller is worse): propellant remaining (docs/report.md)"
        ),
        "tolerance_99_95": (
            f"one-sided tolerance bound: with 95 % confidence at least {coverage} of successful flights lie on "
            "its good side; the order statistic (distribution-free) when n allows it (n >= 299), else the normal "
            "bound mean +- k sd"
        ),
        "mean_3sd": "mean +- 3 sd: the normal 3-sigma value (0.135 % tail), no confidence margin",
        "percentiles": "numpy's linear interpolation (Hyndman-Fan type 7)",
    }


def failure_reasons(campaign, examples=FAILURE_EXAMPLES):
    """Failed flights and errored runs counted per reason, most frequent first, with example run ids."""
    rows = []
    for kind, group in (("failed flight", campaign.failed), ("errored run", campaign.errored)):
        if group.empty:
            continue
        reasons = group["failure_reason"].map(reason_text)
        for reason, ids in group["run_id"].groupby(reasons, sort=False):
            rows.append(
                {
                    "kind": kind,
                    "status": "ok" if kind == "failed flight" else "error",
                    "reason": reason,
                    "count": len(ids),
                    "example_run_ids": sorted(int(i) for i in ids)[:examples],
                }
            )
    rows.sort(key=lambda r: (r["kind"] != "failed flight", -r["count"], r["reason"]))
    return rows


def reason_text(reason, limit=REASON_CHARACTERS):
    """A failure reason as one short line (an error's first line, cut at ``limit`` characters)."""
    if reason is None or (isinstance(reason, float) and math.isnan(reason)) or not str(reason).strip():
        return "(no reason recorded)"
    line = str(reason).strip().splitlines()[0]
    return line if len(line) <= limit else line[: limit - 3] + "..."


def failure_sets(campaign):
    """Success and propellant per failed-thruster set, when the sets vary; else None."""
    ok = campaign.ok
    if "failed_thrusters" not in ok or ok["failed_thrusters"].nunique() < 2:
        return None
    rows = []
    for key, group in ok.groupby("failed_thrusters", sort=False):
        n = len(group)
        k = int(group["success"].astype(bool).sum())
        fuel = group["fuel_remaining"].to_numpy(dtype=float)
        finite = fuel[np.isfinite(fuel)]
        reasons = group.loc[~group["success"].astype(bool), "failure_reason"].dropna()
        rows.append(
            {
                "failed_thrusters": key,
                "size": len(key.split(",")) if key else 0,
                "runs": n,
                "successes": k,
                "success_rate": k / n,
                "success_rate_ci95": list(stats.clopper_pearson(k, n)),
                "fuel_remaining_min": float(finite.min()) if len(finite) else math.nan,
                "fuel_remaining_median": float(np.median(finite)) if len(finite) else math.nan,
                "failure_reasons": sorted(set(reasons)),
            }
        )
    rows.sort(key=lambda r: (r["size"], [int(t) for t in r["failed_thrusters"].split(",") if t]))
    return rows


WHEEL_SET_COLUMNS = (  # (runs column, statistic) per failed-wheel set; those the table has
    ("pointing_rms_x_arcsec", "median"),
    ("pointing_rms_x_arcsec", "p99"),
    ("pointing_rms_y_arcsec", "p99"),
    ("pointing_rms_z_arcsec", "p99"),
    ("pointing_max_arcsec", "p99"),
    ("wheel_momentum_peak_n_m_s", "max"),
    ("wheel_saturated_s", "median"),
)


def wheel_failure_sets(campaign):
    """Per failed-wheel set (``failed_wheels``; "" = none): runs, successes and the pointing and
    wheel statistics over its flown runs, so the penalty of a failure reads against the runs
    without one; None when the sets do not vary."""
    ok = campaign.ok
    if "failed_wheels" not in ok or ok["failed_wheels"].nunique() < 2:
        return None
    columns = [(c, s) for c, s in WHEEL_SET_COLUMNS if c in ok]
    rows = []
    for key, group in ok.groupby("failed_wheels", sort=True):
        n = len(group)
        k = int(group["success"].astype(bool).sum())
        row = {"failed_wheels": key, "runs": n, "successes": k, "success_rate_ci95": list(stats.clopper_pearson(k, n))}
        for column, stat in columns:
            row[f"{column}.{stat}"] = stats.column_stat(group[column].to_numpy(dtype=float), stat)
        rows.append(row)
    detected = bool((campaign.resolved.get("wheel_failures") or {}).get("detected", False))
    return {"detected": detected, "statistics": [f"{c}.{s}" for c, s in columns], "sets": rows}


def paper_table4_agreement(campaign, sets):
    """For a ReFEx failure sweep: which flown single/double sets agree with 000 Table 4; else None.

    A set agrees when "compensable" in 000 Table 4 equals "every run of the set succeeded".
    """
    vehicle = (campaign.resolved.get("vehicle") or {}).get("name")
    if not sets or vehicle != "refex" or campaign.thruster_count != 8:
        return None
    compared, disagree = 0, []
    for s in sets:
        ids = tuple(int(t) for t in s["failed_thrusters"].split(",") if t)
        if not 1 <= len(ids) <= 2:
            continue
        compared += 1
        if (ids in PAPER_COMPENSABLE) != (s["successes"] == s["runs"]):
            disagree.append(s["failed_thrusters"])
    if not compared:
        return None
    return {"compared": compared, "agree": compared - len(disagree), "disagree": disagree}


def sensitivity(campaign):
    """Spearman rank correlation of every varying ``p.`` column with each output, by |rho|."""
    ok = campaign.ok
    n = len(ok)
    result = {"method": "Spearman rank correlation over the ok runs", "runs": n}
    result["critical_abs_rho_95"] = stats.spearman_critical(n)
    for output in SENSITIVITY_OUTPUTS:
        if output not in ok:
            continue
        y = ok[output].to_numpy(dtype=float)
        rows = []
        for column in campaign.parameter_columns:
            x = ok[column].to_numpy(dtype=float)
            rho, p = stats.spearman(x, y)
            if math.isfinite(rho):
                rows.append({"parameter": column, "rho": rho, "p_value": p})
        rows.sort(key=lambda r: -abs(r["rho"]))
        result[output] = rows
    return result


def convergence(campaign):
    """Running statistics over the first n ok runs (in run-id order) at log-spaced n."""
    ok = campaign.ok
    success = ok["success"].astype(bool).to_numpy()
    fuel = ok["fuel_remaining"].to_numpy(dtype=float)
    points = stats.convergence_points(len(ok))
    out = {"n": points.tolist(), "success_rate": [], "success_ci95_low": [], "success_ci95_high": []}
    fuel_stats = ("mean", "p1", "mean_minus_3sd", "tol_lower", "min")
    for name in fuel_stats:
        out[f"fuel_remaining.{name}"] = []
    for n in points:
        k = int(success[:n].sum())
        low, high = stats.clopper_pearson(k, int(n))
        out["success_rate"].append(k / n)
        out["success_ci95_low"].append(low)
        out["success_ci95_high"].append(high)
        for name in fuel_stats:
            out[f"fuel_remaining.{name}"].append(stats.column_stat(fuel[:n], name))
    return out


def rerun_command(out, run_id):
    return f"refexmc rerun {shlex.quote(str(out))} {int(run_id)}"


def _run_entry(campaign, row, column=None):
    entry = {
        "run_id": int(row["run_id"]),
        "success": bool(row["success"]),
        "failure_reason": row.get("failure_reason"),
        "failed_thrusters": row.get("failed_thrusters", ""),
        "command": rerun_command(campaign.out, row["run_id"]),
    }
    if column is not None:
        entry[column] = float(row[column])
    return entry


def worst_cases(campaign, count=WORST_COUNT):
    ok = campaign.ok
    result = {}
    for column, meaning in WORST_CASES:
        if column not in ok:
            continue
        finite = ok[np.isfinite(ok[column].to_numpy(dtype=float))]
        low = tails.worse_tail(column) == "lower"
        picked = finite.nsmallest(count, column) if low else finite.nlargest(count, column)
        result[column] = {
            "meaning": f"{meaning} (among the flown runs, status ok)",
            "runs": [_run_entry(campaign, row, column) for row in picked.to_dict("records")],
        }
    failed = ok[~ok["success"].astype(bool)]
    result["unsuccessful"] = {
        "meaning": f"flown runs (status ok) that did not succeed (first {LISTED_RUNS})",
        "count": len(failed),
        "runs": [_run_entry(campaign, row) for row in failed.head(LISTED_RUNS).to_dict("records")],
    }
    errored = campaign.errored
    result["errored"] = {
        "meaning": (
            f"runs that raised errors: not in the statistics tables, failing every requirement (first {LISTED_RUNS})"
        ),
        "count": len(errored),
        "runs": [_run_entry(campaign, row) for row in errored.head(LISTED_RUNS).to_dict("records")],
    }
    return result


def against_nominal(campaign, nominal_row, column="fuel_used_kg"):
    """How many flown dispersed runs used more propellant than the nominal run (000 sec. 6.2: "most")."""
    if nominal_row is None or column not in campaign.ok:
        return None
    dispersed = campaign.ok[campaign.ok["run_id"] != nominal_row["run_id"]][column].dropna()
    if dispersed.empty or not (dispersed > 0.0).any() and nominal_row[column] == 0.0:  # no propellant used
        return None
    more = int((dispersed > nominal_row[column]).sum())
    return {
        "column": column,
        "more_than_nominal": more,
        "of": int(len(dispersed)),
        "share": more / len(dispersed),
        "covers": "flown dispersed runs (status ok), failed flights included",
    }


def build(campaign):
    """Every number of the report except the requirement verdicts and the overall verdict."""
    level = campaign_metrics(campaign)
    n_ok = int(level["ok_count"])
    notes = []
    expected = campaign.resolved.get("runs")
    nominal = campaign.nominal_run_id
    if nominal is not None:
        notes.append("run 0 is the undispersed nominal case; it counts as a run in every statistic")
    nominal_row = campaign.ok[campaign.ok["run_id"] == nominal].iloc[0] if nominal is not None else None
    sets = failure_sets(campaign)
    summary = {
        "campaign": {
            "name": campaign.name,
            "out": str(campaign.out),
            "runs_planned": expected,
            "seed": campaign.resolved.get("seed"),
            "sampling": campaign.resolved.get("sampling"),
            "nominal_first": campaign.resolved.get("nominal_first", True),
            "failures": (campaign.resolved.get("failures") or {}).get("mode", "none"),
            "failures_detected": bool((campaign.resolved.get("failures") or {}).get("detected", False)),
            "manifest_status": campaign.manifest.get("status"),
            "refexmc": campaign.manifest.get("refexmc"),
        },
        "completeness": data.completeness(campaign),
        "counts": {
            key: int(level[key]) for key in ("runs", "ok_count", "error_count", "success_count", "failure_count")
        },
        "metrics": level,
        "success": success_section(campaign, level),
        "columns": column_sections(campaign),
        "statistics_notes": statistics_notes(campaign),
        "failure_reasons": failure_reasons(campaign),
        "nominal": None
        if nominal_row is None
        else {
            "run_id": int(nominal),
            "success": bool(nominal_row["success"]),
            **{c: float(nominal_row[c]) for c in KEY_COLUMNS if c in nominal_row},
            "propellant_used_vs_dispersed": against_nominal(campaign, nominal_row),
        },
        "failure_sets": sets,
        "failure_sets_vs_000_table4": paper_table4_agreement(campaign, sets),
        "wheel_failure_sets": wheel_failure_sets(campaign),
        "sensitivity": sensitivity(campaign) if campaign.parameter_columns and n_ok >= 3 else None,
        "convergence": convergence(campaign) if n_ok >= 2 else None,
        "worst_cases": worst_cases(campaign),
        "published": published.sections(campaign, published.load_published(campaign)),
        "modes": list(campaign.modes),
        "notes": notes,
    }
    return summary


def json_ready(value):
    """NaN and inf -> None, numpy scalars -> Python, recursively (strict JSON)."""
    if isinstance(value, dict):
        return {str(k): json_ready(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_ready(v) for v in value]
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value
