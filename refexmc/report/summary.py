"""The report's numbers as one JSON-ready dict (``OUT/report/summary.json``)."""

import math

import numpy as np

from refexmc.report import data, entry_histories, factors, outputs, pointing, published, stats
from refexmc.report import requirements as requirements_module
from refexmc.report.requirements import campaign_metric_covers

KEY_COLUMNS = outputs.DISPLAY_ORDER
WORST_CASES = (  # (column, what its worst end means) of outputs without a requirement, when they vary
    ("fuel_remaining", "least propellant remaining"),
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


def statistics_columns(campaign, plan=None):
    """The runs columns of the statistics tables, in display order (``outputs.plan``): the
    requirements' metrics, the other outputs, the constant ones, the per-thruster pulse counts."""
    plan = plan or outputs.plan(campaign, [])
    return [
        *plan["requirement_columns"],
        *plan["other_columns"],
        *plan["constant_columns"],
        *plan["pulse_columns"],
    ]


def column_sections(campaign, plan=None):
    """Statistics of each output column over the successful flights, for the column's worse tail.

    Each entry also says which runs it covers (``covers``, ``n``) and its ``tail``.
    """
    plan = plan or outputs.plan(campaign, [])
    successful = campaign.successful
    n_runs = len(campaign.runs)
    left_out = n_runs - len(successful)
    result = {}
    columns = statistics_columns(campaign, plan)
    values = [successful[column].to_numpy(dtype=float) for column in columns]  # views of float columns
    sections = data.map_on_threads(lambda k: stats.describe(values[k], plan["tails"][columns[k]]), range(len(columns)))
    for column, section in zip(columns, sections, strict=True):
        tail = plan["tails"][column]
        n = int(section["count"])
        covers = f"{n} successful flight{'s' if n != 1 else ''}"
        if n < len(successful):
            covers += f" with a value (of {len(successful)})"
        if left_out:
            covers += f"; {left_out} of {n_runs} runs not included (failed or errored)"
        result[column] = {"covers": covers, "n": n, "tail": tail, **section}
    return result


TAIL_WORDS = {"upper": "upper tail (larger is worse)", "lower": "lower tail (smaller is worse)", "both": "both ends"}


def tails_note(plan):
    """Which columns show which tail, in the words of this mission's own columns (a wheel vehicle
    reads no propellant, a hop no attitude words): what each tail holds, from the plan's labels."""
    held = {tail: [] for tail in TAIL_WORDS}
    for column in (*plan["requirement_columns"], *plan["other_columns"], *plan["pulse_columns"]):
        tail = plan["tails"].get(column)
        what = plan["labels"].get(column, column).split("; required: ")[0]
        if tail in held and what not in held[tail]:
            held[tail].append(what)
    parts = [f"{TAIL_WORDS[tail]}: {', '.join(whats)}" for tail, whats in held.items() if whats]
    return "; ".join(parts) + " (docs/report.md)" if parts else "docs/report.md lists each column's tail"


def statistics_notes(campaign, plan=None):
    """What the columns of the statistics tables are, for the text and the page."""
    coverage = f"{100 * stats.TOLERANCE_COVERAGE:g} %"
    plan = plan or outputs.plan(campaign, [])
    return {
        "population": (
            "successful flights only (status ok, success true); failed flights and errored runs are in the "
            "failure-reason table and count as failing every requirement"
        ),
        "tails": tails_note(plan),
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


WHEEL_SET_COLUMNS = (  # (runs column, statistic) per failed-wheel set when no requirement judges a runs column
    ("pointing_rms_x_arcsec", "median"),
    ("wheel_momentum_peak_n_m_s", "max"),
    ("wheel_saturated_s", "median"),
)
MAX_SET_STATISTICS = 8  # columns of the failed-wheel table beyond runs and success: it must fit the page


def _pointing_set_statistic(v, group, success):
    """A pointing record judged over one failed-wheel set's runs, as a point estimate beside the
    campaign's verdict: (name, value, passed, meaning). Temporal and ensemble: the share of the
    set's runs within the bound (a failed flight or a run without a value is outside) against the
    record's threshold; mixed: the mean fraction of window time above the bound (1 for such a run)
    against 1 - P_C."""
    column = v["metric"]
    values = group[column].to_numpy(dtype=float) if column in group else np.full(len(group), math.nan)
    usable = success & np.isfinite(values)
    n = len(group)
    if v.get("interpretation") == "mixed":
        value = float(np.where(usable, np.where(usable, values, 0.0), 1.0).mean()) if n else math.nan
        return (
            f"{column}.mean",
            value,
            math.isfinite(value) and value <= v["threshold"],
            (f"mean fraction of window time above the bound over the set's runs (required <= {v['threshold']:.4g})"),
        )
    within = int((usable & (np.where(usable, values, math.inf) <= v["value"])).sum())
    value = within / n if n else math.nan
    return (
        f"{column}.within",
        value,
        math.isfinite(value) and value >= v["threshold"],
        (f"share of the set's runs within {v['value']:g} {v.get('unit', '')} (required >= {v['threshold']:g})"),
    )


def wheel_failure_sets(campaign, verdicts=()):
    """Per failed-wheel set (``failed_wheels``; "" = none): runs, successes and, for each requirement
    on a runs column, its statistic over the set's runs (failed flights counting as failing, as the
    requirement does over the campaign) with its verdict; a pointing record as the share of the set's
    runs within its bound (``_pointing_set_statistic``), whatever runs the record itself judges, so
    a failure's penalty reads against the runs without one. Only when no requirement judges a runs
    column, a few wheel statistics (``WHEEL_SET_COLUMNS``) without a verdict. None when the sets
    do not vary."""
    ok = campaign.ok
    if "failed_wheels" not in ok or ok["failed_wheels"].nunique() < 2:
        return None
    judged, names = [], []
    for v in verdicts:
        if v.get("kind") == "pointing":
            if v["metric"] not in names:
                judged.append(v)
                names.append(v["metric"])
            continue
        column, stat = requirements_module.split_metric(v["metric"])
        if stat is not None and column in ok and not column.startswith("p.") and v["metric"] not in names:
            judged.append(v)
            names.append(v["metric"])
    judged = judged[:MAX_SET_STATISTICS]
    extra = [] if judged else [(c, s) for c, s in WHEEL_SET_COLUMNS if c in ok]
    rows, statistics, requirements, meanings = [], [], {}, {}
    for key, group in ok.groupby("failed_wheels", sort=True):
        n = len(group)
        success = group["success"].astype(bool).to_numpy()
        k = int(success.sum())
        row = {
            "failed_wheels": key,
            "runs": n,
            "successes": k,
            "success_rate_ci95": list(stats.clopper_pearson(k, n)),
            "verdicts": {},
        }
        for v in judged:
            if v.get("kind") == "pointing":
                name, value, passed, meaning = _pointing_set_statistic(v, group, success)
                meanings[name] = meaning
            else:
                name = v["metric"]
                column, stat = requirements_module.split_metric(name)
                side = requirements_module.FAILING_SIDE[v["op"]]
                value = stats.column_stat_with_failing(group[column].to_numpy(dtype=float)[success], n - k, stat, side)
                passed = math.isfinite(value) and requirements_module.OPERATORS[v["op"]](value, v["value"])
            row[name] = value
            row["verdicts"][name] = bool(passed)
            requirements[name] = v["requirement"]
            if name not in statistics:
                statistics.append(name)
        for column, stat in extra:
            row[f"{column}.{stat}"] = stats.column_stat(group[column].to_numpy(dtype=float), stat)
        row["passed"] = k == n and all(row["verdicts"].values())
        rows.append(row)
    detected = bool((campaign.resolved.get("wheel_failures") or {}).get("detected", False))
    return {
        "detected": detected,
        "statistics": statistics + [f"{c}.{s}" for c, s in extra],
        "requirements": requirements,
        "meanings": meanings,
        "sets": rows,
    }


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


SENSITIVITY_FIGURE_TARGETS = 4
SENSITIVITY_LISTED = 10


def varying_parameters(campaign):
    """``p.`` columns that vary over the ok runs (a constant input drives nothing)."""
    ok = campaign.ok
    columns = campaign.parameter_columns
    varies = data.map_on_threads(lambda c: np.ptp(np.nan_to_num(ok[c].to_numpy(dtype=float))) > 0, columns)
    return [c for c, varying in zip(columns, varies, strict=True) if varying]


def sensitivity_targets(plan, verdicts):
    """The outputs whose drivers the report shows: the requirement metrics from failing to
    closest-to-failing (``outputs.margins``); without any, the mission's other outputs (``outputs.plan``)."""
    ranked = [c for c, _ in outputs.margins(verdicts) if c in plan["requirement_columns"]]
    if ranked:
        return ranked
    return list(plan["other_columns"])


def sensitivity(campaign, plan=None, verdicts=()):
    """What drives each target output (``sensitivity_targets``): the Spearman rank correlation and
    partial rank correlation (PRCC) of every varying continuous ``p.`` column, and the discrete
    causes (``factors``: each failed unit, failure sets, ``choice`` inputs) with their correlation
    ratio; rows by ``eta2``, the share of the output's rank variance each explains (rho^2 for a
    continuous input), so both kinds rank on one scale.

    ``targets`` lists the outputs in order (failing first); ``figure_targets`` those the figures
    show: the failing ones and the closest-to-failing passing one.
    """
    plan = plan or outputs.plan(campaign, verdicts)
    ok = campaign.ok
    n = len(ok)
    categorical = set(factors.choice_columns(campaign))
    parameters = [c for c in varying_parameters(campaign) if c not in categorical]
    discrete = factors.factors(campaign, ok)
    targets = sensitivity_targets(plan, verdicts)
    failing = {c for c, margin in outputs.margins(verdicts) if margin < 0}
    figure_targets = [c for c in targets if c in failing]
    figure_targets += [c for c in targets if c not in failing][:1]
    result = {
        "method": "Spearman rank correlation and partial rank correlation (PRCC) over the ok runs; discrete "
        "causes (failed units, failure sets, choice inputs) by the correlation ratio of the output's ranks "
        "(Kruskal-Wallis p); ranked by eta2, the share of the output's rank variance explained (rho^2 for "
        "a continuous input)",
        "runs": n,
        "parameters": len(parameters),
        "factors": [name for name, _, _ in discrete],
        "targets": targets,
        "figure_targets": figure_targets[:SENSITIVITY_FIGURE_TARGETS],
        "critical_abs_rho_95": stats.spearman_critical(n),
        "prcc_note": (
            "PRCC: the rank correlation left when the other inputs' ranks are regressed out; "
            f"needs more runs than inputs + 2 ({len(parameters)} inputs vary)"
        ),
    }
    # the inputs are ranked once, column by column into one int32 matrix (at 100,000 runs and 50
    # inputs 20 MB); a target without a value in some run is ranked over the runs with one
    finite_inputs = np.ones(n, dtype=bool)
    for column in parameters:
        finite_inputs &= np.isfinite(ok[column].to_numpy(dtype=float))

    def ranked(keep):
        """Doubled centred ranks (int32) of every input over the runs ``keep``, column by column."""
        ranks = np.empty((int(keep.sum()), len(parameters)), dtype=np.int32)
        columns = [ok[column].to_numpy(dtype=float) for column in parameters]  # read here, ranked on threads

        def rank(j):
            ranks[:, j] = stats.doubled_centred_ranks(columns[j][keep])

        data.map_on_threads(rank, range(len(parameters)))
        return ranks

    ranks = ranked(finite_inputs) if finite_inputs.all() else None
    latest = {"keep": None, "ranks": None}  # targets with no value in the same runs (the failed flights) share ranks

    def ranked_over(keep):
        if ranks is not None and keep.all():
            return ranks
        if latest["keep"] is None or not np.array_equal(latest["keep"], keep):
            latest["ranks"] = None  # one matrix at a time: 400 MB at 10^6 runs and 100 inputs
            latest.update(keep=keep, ranks=ranked(keep))
        return latest["ranks"]

    for output in targets:
        y = ok[output].to_numpy(dtype=float)
        keep = finite_inputs & np.isfinite(y)
        count = int(keep.sum())
        if count < 3 or np.ptp(y[keep]) == 0:
            result[output] = []
            continue
        rows = []
        if parameters:
            here = ranked_over(keep)
            gram = stats.rank_gram(here, stats.doubled_centred_ranks(y[keep]))
            rhos, ps = stats.spearman_from_gram(gram, count)
            prcc, prcc_p = stats.prcc_from_gram(gram, count)
        for j, column in enumerate(parameters):
            rho, p = float(rhos[j]), float(ps[j])
            if math.isfinite(rho):
                rows.append(
                    {
                        "parameter": column,
                        "kind": "input",
                        "rho": rho,
                        "eta2": rho * rho,
                        "p_value": p,
                        "prcc": float(prcc[j]) if math.isfinite(prcc[j]) else None,
                        "prcc_p_value": float(prcc_p[j]) if math.isfinite(prcc_p[j]) else None,
                    }
                )
        rows += factors.factor_rows(discrete, y, keep)
        rows.sort(key=lambda r: (r["eta2"] is None, -(r["eta2"] or 0.0)))  # an unsupported factor last
        result[output] = rows
    return result


CONVERGENCE_STATS = {  # per tail: (statistic, legend)
    "upper": (
        ("mean", "mean"),
        ("p99", "99th percentile"),
        ("tolerance_99_95", "tolerance bound (99 %/95 %)"),
        ("max", "max"),
    ),
    "lower": (
        ("mean", "mean"),
        ("p1", "1st percentile"),
        ("tolerance_99_95", "tolerance bound (99 %/95 %)"),
        ("min", "min"),
    ),
    "both": (("mean", "mean"), ("min", "min"), ("max", "max")),
}


def convergence(campaign, column=None, tail="lower"):
    """Running statistics over the first n ok runs (in run-id order) at log-spaced n: the success
    rate with its interval and, when ``column`` is given, that column's statistics of its ``tail``
    (over the successful flights among the first n runs)."""
    ok = campaign.ok
    success = ok["success"].astype(bool).to_numpy()
    points = stats.convergence_points(len(ok))
    out = {"n": points.tolist(), "success_rate": [], "success_ci95_low": [], "success_ci95_high": []}
    out["column"], out["tail"], out["statistics"] = column, tail, {}
    values = ok[column].to_numpy(dtype=float) if column is not None else None
    for name, label in CONVERGENCE_STATS[tail] if column is not None else ():
        out["statistics"][name] = {"label": label, "values": []}
    for n in points:
        k = int(success[:n].sum())
        low, high = stats.clopper_pearson(k, int(n))
        out["success_rate"].append(k / n)
        out["success_ci95_low"].append(low)
        out["success_ci95_high"].append(high)
        if values is None:
            continue
        first = values[:n][success[:n]]
        for name, entry in out["statistics"].items():
            if name == "tolerance_99_95":
                value = stats.tolerance_bound(first, tail)[0]
            else:
                value = stats.column_stat(first, name)
            entry["values"].append(value)
    return out


def _run_entry(campaign, row, column=None):
    entry = {
        "run_id": int(row["run_id"]),
        "success": bool(row["success"]),
        "failure_reason": row.get("failure_reason"),
        "failed_thrusters": row.get("failed_thrusters", "") or "",
        "failed_wheels": row.get("failed_wheels", "") or "",
        "command": data.rerun_command(campaign.out, row["run_id"]),
    }
    if column is not None:
        entry["column"] = column
        entry[column] = float(row[column])
    return entry


def _worst(campaign, column, side, count):
    ok = campaign.ok
    values = ok[column].astype(float)
    values = values[np.isfinite(values.to_numpy())]
    index = (values.nsmallest(count) if side == "low" else values.nlargest(count)).index
    return [_run_entry(campaign, row, column) for row in ok.loc[index].to_dict("records")]


def worst_cases(campaign, plan=None, verdicts=(), count=WORST_COUNT):
    """The runs at the failing end of each requirement metric (both ends of a two-sided one), then
    of the other outputs with a bad end (``WORST_CASES``) that vary, then the unsuccessful and
    errored runs. Keys: the column, or ``<column>:lowest`` / ``<column>:highest`` for a column with
    requirements on both ends; each entry has ``column``, ``side`` (low/high), ``meaning``, ``runs``."""
    plan = plan or outputs.plan(campaign, verdicts)
    result = {}
    for column in plan["requirement_columns"]:
        reqs = outputs.requirements_of(column, verdicts)
        sides = []
        for v in reqs:
            for side in {"<=": ("high",), "<": ("high",), ">=": ("low",), ">": ("low",), "==": ("low", "high")}[
                v["op"]
            ]:
                if side not in sides:
                    sides.append(side)
        texts = ", ".join(v["requirement"] for v in reqs)
        for side in sides:
            key = column if len(sides) == 1 else f"{column}:{'lowest' if side == 'low' else 'highest'}"
            word = "smallest" if side == "low" else "largest"
            result[key] = {
                "column": column,
                "side": side,
                "meaning": f"{word} {column} ({texts}; among the flown runs, status ok)",
                "runs": _worst(campaign, column, side, count),
            }
    for column, meaning in WORST_CASES:
        if column in result or column not in plan["other_columns"]:
            continue
        side = "low" if plan["tails"][column] == "lower" else "high"
        result[column] = {
            "column": column,
            "side": side,
            "meaning": f"{meaning} (among the flown runs, status ok)",
            "runs": _worst(campaign, column, side, count),
        }
    ok = campaign.ok
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
    ok = campaign.ok
    dispersed = ok[column][(ok["run_id"] != nominal_row["run_id"]).to_numpy()].dropna()  # the column, not a table copy
    if dispersed.empty or not (dispersed > 0.0).any() and nominal_row[column] == 0.0:  # no propellant used
        return None
    more = int((dispersed > nominal_row[column]).sum())
    others = other_runs_words(campaign)
    return {
        "column": column,
        "more_than_nominal": more,
        "of": int(len(dispersed)),
        "share": more / len(dispersed),
        "others": others,
        "covers": f"flown {others} (status ok), failed flights included",
    }


def other_runs_words(campaign):
    """What the runs beside the nominal one are: "dispersed runs" when an input (``p.`` column) varies
    over them, "failure-set runs" for an undispersed enumeration of failures (a failure sweep: its
    ``constant`` inputs differ from the nominal run's at most), else "other runs"."""
    runs = campaign.runs
    others = runs[(runs["run_id"] != campaign.nominal_run_id).to_numpy()]
    for column in campaign.parameter_columns:
        values = others[column].to_numpy(dtype=float)
        values = values[np.isfinite(values)]
        if len(values) and np.ptp(values) > 0:
            return "dispersed runs"
    modes = {(campaign.resolved.get(key) or {}).get("mode", "none") for key in ("failures", "wheel_failures")}
    return "failure-set runs" if "enumerate" in modes else "other runs"


def failures_section(campaign):
    """What the campaign failed, as the runs table has it: per kind (thruster, wheel) the campaign's
    mode, whether the flight software knew, and how many runs had a failure of that kind."""
    runs = campaign.runs
    kinds = []
    for key, column, what in (
        ("failures", "failed_thrusters", "thruster"),
        ("wheel_failures", "failed_wheels", "wheel"),
    ):
        spec = campaign.resolved.get(key) or {}
        mode = spec.get("mode", "none")
        with_failure = 0
        if column in runs:
            with_failure = int((runs[column].fillna("").astype(str).str.len() > 0).sum())
        if mode == "none" and not with_failure:
            continue
        detected = bool(spec.get("detected", False))
        kinds.append(
            {
                "kind": what,
                "mode": mode,
                "detected": detected,
                "runs_with_failure": with_failure,
                "runs": len(runs),
                "text": f"{what}s {mode}, {'detected' if detected else 'undetected'} "
                f"({with_failure} of {len(runs)} runs with a failed {what})",
            }
        )
    flap = entry_histories.blocked_flap(campaign)
    if flap is not None:  # an entry's blocked body flap (issue 24): every run flies with it
        kinds.append(
            {
                "kind": "body flap",
                "mode": "dispersed" if flap["dispersed"] else "fixed",
                "detected": flap["known_to_flight_software"],
                "flap": flap["flap"],
                "deflection_deg": flap["deflection_deg"],
                "drawn_deg": list(flap["drawn"]) if flap["drawn"] else None,
                "runs_with_failure": len(runs),
                "runs": len(runs),
                "text": f"{entry_histories.blocked_flap_text(flap)} "
                f"({len(runs)} of {len(runs)} runs with a blocked flap)",
            }
        )
    return kinds


def _compact(value):
    """A dispersion's parameter as short text: numbers with 4 significant digits, lists in brackets."""
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_compact(v) for v in value) + "]"
    if isinstance(value, float):
        return f"{value:.4g}"
    return str(value)


def inputs_section(campaign):
    """Every dispersed parameter: its distribution and parameters (campaign file) and the range
    drawn (min and max over the dispersed runs, the nominal run 0 left out), per component."""
    runs = campaign.runs
    dispersed = np.ones(len(runs), dtype=bool)
    if campaign.nominal_run_id is not None and len(runs) > 1:
        dispersed = runs["run_id"].to_numpy() != campaign.nominal_run_id

    def drawn_range(column):
        values = runs[column].to_numpy(dtype=float)[dispersed]
        values = values[np.isfinite(values)]
        return (float(values.min()), float(values.max())) if len(values) else (math.nan, math.nan)

    rows = []
    for key, spec in (campaign.resolved.get("dispersions") or {}).items():
        spec = spec if isinstance(spec, dict) else {"value": spec}
        prefix = f"p.{key}"
        columns = [c for c in campaign.parameter_columns if c == prefix or c.startswith(prefix + ".")]
        drawn = [
            {"component": column[len(prefix) + 1 :], "column": column, "min": low, "max": high}
            for column, (low, high) in zip(columns, data.map_on_threads(drawn_range, columns), strict=True)
        ]
        rows.append(
            {
                "parameter": key,
                "distribution": spec.get("dist", ""),
                "parameters": ", ".join(f"{k} {_compact(v)}" for k, v in spec.items() if k != "dist"),
                "drawn": drawn,
            }
        )
    count = int(dispersed.sum())
    return {
        "covers": f"{count} dispersed runs" + (" (the nominal run 0 left out)" if count < len(runs) else ""),
        "rows": rows,
    }


def with_pointing(campaign, verdicts):
    """The verdicts the report is built around: ``verdicts`` and the campaign's pointing records
    (``report.pointing``, docs/pointing.md), in the campaign file's order, then ``--require``'s.
    A pointing record judges a runs column like ``<column>.<stat>`` does; without it here its
    column would be a mere output (two-sided, no sensitivity, no per-failure-set verdict)."""
    verdicts = list(verdicts)
    if any(v.get("kind") == "pointing" for v in verdicts):
        return verdicts
    pointed = [pointing.evaluate(r, campaign) for r in pointing.requirements_of(campaign)]
    if not pointed:
        return verdicts
    from_file = [v for v in verdicts if v.get("source") == "campaign"]
    ordered = []
    for item in campaign.resolved.get("requirements") or []:
        queue = pointed if isinstance(item, dict) else from_file
        if queue:
            ordered.append(queue.pop(0))
    ordered += from_file + pointed
    return ordered + [v for v in verdicts if not any(v is o for o in ordered)]


def thruster_failures_detected(resolved):
    """Whether the flight software knows the campaign's failed thrusters (``failures.detected``); None
    without thruster failures (an entry's blocked flap, failed wheels: their own ``failure_kinds``)."""
    failures = resolved.get("failures") or {}
    return bool(failures.get("detected", False)) if failures.get("mode", "none") != "none" else None


def build(campaign, verdicts=()):
    """Every number of the report except the overall verdict; ``verdicts``: the requirement
    verdicts (``requirements.evaluate``), which decide the metrics the report is built around,
    with the campaign's pointing records (``with_pointing``)."""
    verdicts = with_pointing(campaign, verdicts)
    level = campaign_metrics(campaign)
    n_ok = int(level["ok_count"])
    notes = []
    expected = campaign.resolved.get("runs")
    nominal = campaign.nominal_run_id
    if nominal is not None:
        notes.append("run 0 is the undispersed nominal case; it counts as a run in every statistic")
    nominal_row = campaign.ok[campaign.ok["run_id"] == nominal].iloc[0] if nominal is not None else None
    sets = failure_sets(campaign)
    plan = outputs.plan(campaign, verdicts)
    failures = failures_section(campaign)
    targets = sensitivity_targets(plan, verdicts)
    convergence_column = (
        targets[0]
        if targets
        else next((c for c in ("fuel_remaining", *plan["other_columns"]) if c in plan["other_columns"]), None)
    )
    summary = {
        "campaign": {
            "name": campaign.name,
            "out": str(campaign.out),
            "runs_planned": expected,
            "seed": campaign.resolved.get("seed"),
            "sampling": campaign.resolved.get("sampling"),
            "nominal_first": campaign.resolved.get("nominal_first", True),
            "failures": "; ".join(f["text"] for f in failures) or "none",
            "failure_kinds": failures,
            "failures_detected": thruster_failures_detected(campaign.resolved),
            "manifest_status": campaign.manifest.get("status"),
            "refexmc": campaign.manifest.get("refexmc"),
            "refex": outputs.is_refex(campaign),
        },
        "completeness": data.completeness(campaign),
        "counts": {
            key: int(level[key]) for key in ("runs", "ok_count", "error_count", "success_count", "failure_count")
        },
        "metrics": level,
        "success": success_section(campaign, level),
        "outputs": plan,
        "columns": column_sections(campaign, plan),
        "statistics_notes": statistics_notes(campaign, plan),
        "failure_reasons": failure_reasons(campaign),
        "inputs": inputs_section(campaign),
        "nominal": None
        if nominal_row is None
        else {
            "run_id": int(nominal),
            "success": bool(nominal_row["success"]),
            **{c: float(nominal_row[c]) for c in statistics_columns(campaign, plan) if c in nominal_row},
            "propellant_used_vs_dispersed": against_nominal(campaign, nominal_row),
        },
        "failure_sets": sets,
        "failure_sets_vs_000_table4": paper_table4_agreement(campaign, sets),
        "wheel_failure_sets": wheel_failure_sets(campaign, verdicts),
        "sensitivity": sensitivity(campaign, plan, verdicts)
        if n_ok >= 3 and (campaign.parameter_columns or factors.factors(campaign, campaign.ok))
        else None,
        "convergence": convergence(campaign, convergence_column, plan["tails"].get(convergence_column, "lower"))
        if n_ok >= 2
        else None,
        "worst_cases": worst_cases(campaign, plan, verdicts),
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
