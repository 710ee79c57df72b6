"""The report's numbers as one JSON-ready dict (``OUT/report/summary.json``)."""

import math
import shlex

import numpy as np

from refexmc.core.layout import MODE_NAMES
from refexmc.report import data, stats
from refexmc.report.requirements import CAMPAIGN_METRICS, split_metric

KEY_COLUMNS = ("fuel_remaining", "fuel_used_kg", "theta_t_handover_deg", "t_end_s", "pulses_total")
SENSITIVITY_OUTPUTS = ("fuel_used_kg", "theta_t_handover_deg")
WORST_CASES = (  # (column, "low"/"high": which end is worst, what it means)
    ("fuel_remaining", "low", "least propellant remaining"),
    ("theta_t_handover_deg", "high", "largest total angle error at hand-over"),
    ("t_end_s", "high", "longest flight"),
)
WORST_COUNT = 5

# 000 Table 4: the thruster failures the ReFEx allocation compensates (8 thrusters)
PAPER_COMPENSABLE = frozenset(
    [(1,), (2,), (3,), (4,), (7,), (8,), (1, 2), (3, 4), (1, 3), (2, 4), (7, 8), (1, 8), (2, 8), (3, 7), (4, 7)]
)
LISTED_RUNS = 20


def campaign_metrics(campaign):
    """Counts, success rate and its Clopper-Pearson bounds (errored runs excluded from the rate)."""
    runs = campaign.runs
    ok = campaign.ok
    n_ok = len(ok)
    successes = int(ok["success"].astype(bool).sum())
    rate = successes / n_ok if n_ok else math.nan
    lower = stats.clopper_pearson_lower(successes, n_ok)
    return {
        "runs": float(len(runs)),
        "ok_count": float(n_ok),
        "error_count": float(len(runs) - n_ok),
        "error_rate": (len(runs) - n_ok) / len(runs) if len(runs) else math.nan,
        "success_count": float(successes),
        "failure_count": float(n_ok - successes),
        "success_rate": rate,
        "success_rate_lower95": lower,
        "success_rate_upper95": stats.clopper_pearson_upper(successes, n_ok),
        "failure_rate_upper95": 1.0 - lower,
    }


def metric_value(campaign, metric, level=None):
    """The value of a metric of the grammar in ``refexmc.report.requirements`` (already checked)."""
    if metric in CAMPAIGN_METRICS:
        return (level or campaign_metrics(campaign))[metric]
    column, stat = split_metric(metric)
    return stats.column_stat(campaign.ok[column].to_numpy(dtype=float), stat)


def success_section(campaign, level):
    n = int(level["ok_count"])
    k = int(level["success_count"])
    low, high = stats.clopper_pearson(k, n)
    section = {
        "successes": k,
        "ok_runs": n,
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
        section["statement"] = (
            f"{n - k} of {n} runs failed: success rate {100 * k / n:.4g} %, 95 % interval "
            f"[{100 * low:.4g}, {100 * high:.4g}] %"
        )
    return section


def column_sections(campaign):
    ok = campaign.ok
    columns = [c for c in KEY_COLUMNS if c in ok]
    columns += [c for c in data.MODE_TIME_COLUMNS if c in ok]
    columns += [c for c in ok.columns if c.startswith("pulses_") and c[7:].isdigit()]
    return {c: stats.describe(ok[c].to_numpy(dtype=float)) for c in columns}


def propellant_bounds_note(n):
    k = stats.normal_tolerance_factor(n)
    return {
        "tol_lower": (
            "one-sided normal tolerance bound mean - k sd, k = "
            + (f"{k:.3f}" if math.isfinite(k) else "n/a")
            + f" for N = {n}: with 95 % confidence at least 99.865 % of flights keep more "
            "(the confidence bound of the 3-sigma-low value mean - 3 sd; assumes a normal distribution)"
        ),
        "p0.135_lower95": (
            "distribution-free 95 % lower confidence bound of the 0.135th percentile (an order statistic); "
            "needs N >= 2218 runs"
        ),
    }


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
    for column, worst, meaning in WORST_CASES:
        if column not in ok:
            continue
        finite = ok[np.isfinite(ok[column].to_numpy(dtype=float))]
        picked = finite.nsmallest(count, column) if worst == "low" else finite.nlargest(count, column)
        result[column] = {
            "meaning": meaning,
            "runs": [_run_entry(campaign, row, column) for row in picked.to_dict("records")],
        }
    failed = ok[~ok["success"].astype(bool)]
    result["unsuccessful"] = {
        "meaning": f"runs that did not succeed (first {LISTED_RUNS})",
        "count": len(failed),
        "runs": [_run_entry(campaign, row) for row in failed.head(LISTED_RUNS).to_dict("records")],
    }
    errored = campaign.errored
    result["errored"] = {
        "meaning": f"runs that raised errors, excluded from the statistics (first {LISTED_RUNS})",
        "count": len(errored),
        "runs": [_run_entry(campaign, row) for row in errored.head(LISTED_RUNS).to_dict("records")],
    }
    return result


def build(campaign):
    """Every number of the report except the requirement verdicts."""
    level = campaign_metrics(campaign)
    n_ok = int(level["ok_count"])
    notes = []
    if level["error_count"]:
        notes.append(
            f"{int(level['error_count'])} of {int(level['runs'])} runs raised errors; they are excluded from every "
            "statistic (see 'errored' under worst cases)"
        )
    expected = campaign.resolved.get("runs")
    if expected is not None and len(campaign.runs) < expected:
        notes.append(f"incomplete campaign: {len(campaign.runs)} of {expected} runs stored")
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
            "manifest_status": campaign.manifest.get("status"),
            "refexmc": campaign.manifest.get("refexmc"),
        },
        "counts": {
            key: int(level[key]) for key in ("runs", "ok_count", "error_count", "success_count", "failure_count")
        },
        "metrics": level,
        "success": success_section(campaign, level),
        "columns": column_sections(campaign),
        "propellant_bounds": propellant_bounds_note(n_ok),
        "nominal": None
        if nominal_row is None
        else {
            "run_id": int(nominal),
            "success": bool(nominal_row["success"]),
            **{c: float(nominal_row[c]) for c in KEY_COLUMNS if c in nominal_row},
        },
        "failure_sets": sets,
        "failure_sets_vs_000_table4": paper_table4_agreement(campaign, sets),
        "sensitivity": sensitivity(campaign) if campaign.parameter_columns and n_ok >= 3 else None,
        "convergence": convergence(campaign) if n_ok >= 2 else None,
        "worst_cases": worst_cases(campaign),
        "modes": list(MODE_NAMES),
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
