"""The terminal summary: the lines `refexmc report` prints."""

import math

from refexmc.core.layout import MODE_NAMES

TABLE_STATS = ("min", "p0.135", "p1", "median", "mean", "mean_minus_3sd", "tol_lower", "max")
TABLE_HEADERS = ("min", "p0.135", "p1", "p50", "mean", "mean-3sd", "tol_lower", "max")
TABLE_COLUMNS = ("fuel_remaining", "fuel_used_kg", "theta_t_handover_deg", "t_end_s", "pulses_total")


def number(value, digits=4):
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "-"
    return f"{value:.{digits}g}"


def percent(value):
    return "-" if value is None or not math.isfinite(value) else f"{100 * value:.4g} %"


def format_summary(summary, report_dir=None):
    """A one-screen summary: counts, success, key statistics, mode times, requirements, verdict."""
    counts = summary["counts"]
    success = summary["success"]
    lines = [
        f"campaign {summary['campaign']['name']}: {counts['runs']} runs, {counts['ok_count']} ok, "
        f"{counts['error_count']} errored" + (f" -> {report_dir}" if report_dir else ""),
    ]
    lines += [f"note: {note}" for note in summary["notes"]]
    low, high = success["ci95"]
    lines.append(
        f"success: {success['successes']}/{success['ok_runs']} = {percent(success['rate'])} "
        f"(95 % Clopper-Pearson [{percent(low)}, {percent(high)}]; one-sided lower bound {percent(success['lower95'])})"
    )
    if success.get("statement"):
        lines.append(f"  {success['statement']}")
    width = max(len(c) for c in TABLE_COLUMNS) + 2
    lines.append("")
    lines.append("".ljust(width) + "".join(h.rjust(10) for h in TABLE_HEADERS))
    for column in TABLE_COLUMNS:
        values = summary["columns"].get(column)
        if values:
            lines.append(column.ljust(width) + "".join(number(values[s]).rjust(10) for s in TABLE_STATS))
    lines.append(
        "  (over the ok runs; tol_lower: one-sided normal tolerance bound, 99.865 % of flights above it "
        "with 95 % confidence)"
    )
    modes = []
    for name in MODE_NAMES:
        values = summary["columns"].get(f"t_{name.lower()}_s")
        if values:
            modes.append(f"{name} {number(values['median'], 3)}/{number(values['max'], 3)}")
    if modes:
        lines.append("time in mode [s], median/max: " + ", ".join(modes))
    sets = summary.get("failure_sets")
    if sets:
        complete = sum(s["successes"] == s["runs"] for s in sets)
        lines.append(f"failure sets: {len(sets)}, every run succeeded in {complete}")
        table4 = summary.get("failure_sets_vs_000_table4")
        if table4:
            lines.append(
                f"  against 000 Table 4: {table4['agree']} of {table4['compared']} single/double sets agree"
                + (f"; differ: {'; '.join(f'[{d}]' for d in table4['disagree'])}" if table4["disagree"] else "")
            )
    worst = summary["worst_cases"].get("fuel_remaining", {}).get("runs")
    if worst:
        run = worst[0]
        lines.append(f"least propellant: run {run['run_id']} ({number(run['fuel_remaining'])}): {run['command']}")
    worst = summary["worst_cases"].get("theta_t_handover_deg", {}).get("runs")
    if worst:
        run = worst[0]
        lines.append(
            f"largest hand-over angle error: run {run['run_id']} ({number(run['theta_t_handover_deg'])} deg): "
            f"{run['command']}"
        )
    requirements = summary["requirements"]
    if requirements:
        lines.append("")
        lines.append("requirements:")
        width = max(len(r["requirement"]) for r in requirements) + 2
        for r in requirements:
            verdict = "PASS" if r["passed"] else "FAIL"
            detail = f"actual {number(r['actual'], 6)}" if r["actual"] is not None else r["note"]
            lines.append(f"  {verdict}  {r['requirement'].ljust(width)}{detail}  ({r['source']})")
        failed = sum(not r["passed"] for r in requirements)
        lines.append(
            f"verdict: {'PASS' if not failed else 'FAIL'} "
            f"({len(requirements) - failed} of {len(requirements)} requirements met)"
        )
    else:
        lines.append("no requirements (add `requirements:` to the campaign file or --require 'METRIC OP VALUE')")
    return "\n".join(lines)
