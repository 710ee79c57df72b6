"""The terminal summary: the lines `refexmc report` prints."""

import math

from refexmc.report.data import mode_time_column
from refexmc.report.requirements import requirement_label
from refexmc.report.summary import KEY_COLUMNS

# the statistics tables: (stat key, header) per worse tail (refexmc.report.tails)
TABLE_STATS = {
    "upper": (
        ("median", "p50"),
        ("mean", "mean"),
        ("p99", "p99"),
        ("p99.865", "p99.865"),
        ("max", "max"),
        ("mean_plus_3sd", "mean+3sd"),
        ("tolerance_99_95", "tol99/95"),
    ),
    "lower": (
        ("median", "p50"),
        ("mean", "mean"),
        ("p1", "p1"),
        ("p0.135", "p0.135"),
        ("min", "min"),
        ("mean_minus_3sd", "mean-3sd"),
        ("tolerance_99_95", "tol99/95"),
    ),
}
TAIL_TITLES = {"upper": "larger is worse (upper tail)", "lower": "smaller is worse (lower tail)"}
TABLE_COLUMNS = KEY_COLUMNS  # those the summary has are shown, in this order


def wheel_failure_lines(wheel_sets):
    """The failed-wheel sets, one line each: runs, successes and the set's statistics."""
    kind = "detected (redistributed)" if wheel_sets["detected"] else "undetected"
    names = wheel_sets["statistics"]
    width = max(len(n) for n in names) if names else 0
    header = "  " + "set".ljust(8) + "runs  ok    " + "  ".join(n.rjust(width) for n in names)
    lines = [f"failed wheels ({kind}), per set:", header]
    for s in wheel_sets["sets"]:
        label = f"[{s['failed_wheels']}]" if s["failed_wheels"] else "none"
        values = "  ".join(number(s[n]).rjust(width) for n in names)
        lines.append(f"  {label.ljust(8)}{str(s['runs']).rjust(4)}  {str(s['successes']).rjust(4)}  {values}")
    return lines


def number(value, digits=4):
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "-"
    return f"{value:.{digits}g}"


def percent(value):
    return "-" if value is None or not math.isfinite(value) else f"{100 * value:.4g} %"


def statistics_lines(summary, columns=TABLE_COLUMNS):
    """The terminal statistics tables: one per worse tail, each row with the runs it covers."""
    lines = []
    width = max(len(c) for c in columns) + 2
    for tail, entries in TABLE_STATS.items():
        rows = [c for c in columns if summary["columns"].get(c, {}).get("tail") == tail]
        if not rows:
            continue
        lines.append(f"{TAIL_TITLES[tail]}:")
        lines.append("".ljust(width) + "n".rjust(6) + "".join(h.rjust(10) for _, h in entries))
        for column in rows:
            values = summary["columns"][column]
            cells = "".join(number(values[key]).rjust(10) for key, _ in entries)
            lines.append(column.ljust(width) + str(values["n"]).rjust(6) + cells)
    covers = {summary["columns"][c]["covers"] for c in columns if c in summary["columns"]}
    for text in sorted(covers):
        lines.append(f"  over {text}")
    lines.append(
        "  tol99/95: one-sided tolerance bound, 99 % of successful flights on its good side with 95 % confidence "
        "(order statistic from n = 299, else normal mean +- k sd)"
    )
    return lines


def failure_reason_lines(summary):
    reasons = summary["failure_reasons"]
    if not reasons:
        return []
    lines = ["failure reasons:"]
    width = max(len(r["reason"]) for r in reasons) + 2
    for r in reasons:
        ids = ", ".join(str(i) for i in r["example_run_ids"]) + (
            ", ..." if r["count"] > len(r["example_run_ids"]) else ""
        )
        lines.append(f"  {r['kind'].ljust(14)}{r['reason'].ljust(width)}{str(r['count']).rjust(6)}  runs {ids}")
    return lines


PUBLISHED_WIDTHS = (6, 12, 12, 16)  # n, ours, published, published/ours


def _cells(texts, widths=PUBLISHED_WIDTHS):
    return "".join(text.rjust(w) for text, w in zip(texts, widths, strict=True))


def published_lines(summary):
    """Each ``published`` entry of the campaign: its columns, our statistic (n), the source's value, the ratio."""
    lines = []
    for entry in summary.get("published") or []:
        lines += [
            "",
            f"published: {entry['source']}",
            f"  ours: {entry['statistic']} = {entry['statistic_meaning']}, over {entry['covers']}",
        ]
        width = max(len(row["column"]) for row in entry["rows"]) + 4
        lines.append("".ljust(width) + _cells(("n", "ours", "published", "published/ours")))
        for row in entry["rows"]:
            ratio = number(row["ratio_published_to_ours"], 3)
            cells = (str(row["n"]), number(row["ours"]), number(row["published"]), ratio)
            lines.append(f"  {row['column']}".ljust(width) + _cells(cells))
    return lines


def format_summary(summary, report_dir=None):
    """A one-screen summary: banner, counts, success, key statistics, published values beside ours,
    failure reasons, requirements, verdict."""
    counts = summary["counts"]
    success = summary["success"]
    lines = [f"*** {summary['banner']} ***", ""] if summary.get("banner") else []
    lines.append(
        f"campaign {summary['campaign']['name']}: {counts['runs']} runs, {counts['success_count']} successful, "
        f"{counts['failure_count']} failed, {counts['error_count']} errored"
        + (f" -> {report_dir}" if report_dir else "")
    )
    lines += [f"note: {note}" for note in summary["notes"]]
    low, high = success["ci95"]
    lines.append(
        f"success: {success['successes']}/{success['runs']} = {percent(success['rate'])} "
        f"(95 % Clopper-Pearson [{percent(low)}, {percent(high)}]; "
        f"one-sided lower bound {percent(success['lower95'])}; over {success['covers']})"
    )
    if success.get("statement"):
        lines.append(f"  {success['statement']}")
    lines.append("")
    lines += statistics_lines(summary)
    modes = []
    for name in summary["modes"]:
        values = summary["columns"].get(mode_time_column(name))
        if values:
            modes.append(f"{name} {number(values['median'], 3)}/{number(values['max'], 3)}")
    if modes:
        lines.append("time in mode [s], median/max: " + ", ".join(modes))
    sets = summary.get("failure_sets")
    if sets:
        complete = sum(s["successes"] == s["runs"] for s in sets)
        kind = "detected" if summary["campaign"].get("failures_detected") else "undetected"
        lines.append(f"failure sets ({kind}): {len(sets)}, every run succeeded in {complete}")
        table4 = summary.get("failure_sets_vs_000_table4")
        if table4:
            lines.append(
                f"  against 000 Table 4: {table4['agree']} of {table4['compared']} single/double sets agree"
                + (f"; differ: {'; '.join(f'[{d}]' for d in table4['disagree'])}" if table4["disagree"] else "")
            )
    wheel_sets = summary.get("wheel_failure_sets")
    if wheel_sets:
        lines += wheel_failure_lines(wheel_sets)
    against = (summary.get("nominal") or {}).get("propellant_used_vs_dispersed")
    if against:
        lines.append(
            f"dispersed runs using more propellant than the nominal run: {against['more_than_nominal']} of "
            f"{against['of']} ({percent(against['share'])})"
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
    lines += published_lines(summary)
    reasons = failure_reason_lines(summary)
    if reasons:
        lines += ["", *reasons]
    requirements = summary["requirements"]
    verdict = summary["verdict"]
    if requirements:
        lines.append("")
        lines.append("requirements (over all runs; failed flights and errored runs count as failing):")
        width = max(len(r["requirement"]) for r in requirements) + 2
        for r in requirements:
            label = requirement_label(r, verdict)
            detail = f"actual {number(r['actual'], 6)}" if r["actual"] is not None else "actual -"
            if r["note"]:
                detail += f"; {r['note']}"
            if r["actual_successful_flights"] is not None and r["actual"] != r["actual_successful_flights"]:
                detail += f" (successful flights alone: {number(r['actual_successful_flights'], 6)})"
            lines.append(f"  {label.ljust(4)}  {r['requirement'].ljust(width)}{detail}  ({r['source']})")
    else:
        lines.append("no requirements (add `requirements:` to the campaign file or --require 'METRIC OP VALUE')")
    met = sum(r["passed"] for r in requirements)
    lines.append(f"verdict: {verdict}" + (f" ({met} of {len(requirements)} requirements met)" if requirements else ""))
    if summary.get("banner"):
        lines.append(f"*** {summary['banner']} ***")
    return "\n".join(lines)
