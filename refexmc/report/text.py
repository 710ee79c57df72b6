"""The terminal summary: the lines `refexmc report` prints."""

import math

from refexmc.report.data import mode_time_column
from refexmc.report.requirements import requirement_label

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
    "both": (
        ("median", "p50"),
        ("mean", "mean"),
        ("std", "std"),
        ("min", "min"),
        ("p0.135", "p0.135"),
        ("p99.865", "p99.865"),
        ("max", "max"),
    ),
}
TAIL_TITLES = {
    "upper": "larger is worse (upper tail)",
    "lower": "smaller is worse (lower tail)",
    "both": "both ends matter (two-sided)",
}
PULSE_STATS = (("median", "p50"), ("p99", "p99"), ("max", "max"))


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


MAX_DIGITS = 10


def row_digits(values, digits=4):
    """Significant digits that show a row's spread: 4, or 3 digits of the standard deviation when the
    values are large against it (SPORE's entry flight-path angle: -5.0000043 with sd 1.4e-6)."""
    sd, centre = values.get("std"), values.get("median")
    if sd is None or centre is None or not (math.isfinite(sd) and math.isfinite(centre)) or sd <= 0:
        return digits
    ratio = max(abs(centre), sd) / sd
    if not math.isfinite(ratio):
        return MAX_DIGITS
    return int(min(MAX_DIGITS, max(digits, math.ceil(math.log10(ratio)) + 3)))


def number(value, digits=4):
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "-"
    return f"{value:.{digits}g}"


def percent(value):
    return "-" if value is None or not math.isfinite(value) else f"{100 * value:.4g} %"


def table_columns(summary):
    """The columns with a statistics row: the requirements' metrics, then the other outputs that vary."""
    plan = summary.get("outputs") or {}
    listed = [*plan.get("requirement_columns", ()), *plan.get("other_columns", ())]
    return [c for c in listed if c in summary["columns"]]


def constant_line(summary):
    """The outputs with one value in every successful flight, in one line ('' when none)."""
    constants = (summary.get("outputs") or {}).get("constant_columns") or {}
    return ", ".join(f"{column} = {number(value, 6)}" for column, value in constants.items())


def not_produced_line(summary):
    """The columns this mission does not produce (no value in any flown run; a propellant used without a
    propellant load), in one line ('' when none); the terminal and the page say the same."""
    columns = (summary.get("outputs") or {}).get("not_produced") or []
    if not columns:
        return ""
    return f"not produced by this mission, left out: {', '.join(columns)}"


def pulse_table(summary):
    """Per-thruster pulse counts folded into one table: [(stat header, [value per thruster])]."""
    columns = [c for c in (summary.get("outputs") or {}).get("pulse_columns", ()) if c in summary["columns"]]
    return [c[7:] for c in columns], [(h, [summary["columns"][c][k] for c in columns]) for k, h in PULSE_STATS]


def statistics_lines(summary, columns=None):
    """The terminal statistics tables: one per worse tail (requirements' metrics first), what the rows
    cover once, the constant outputs in one line and the pulse counts per thruster in one table."""
    columns = table_columns(summary) if columns is None else columns
    lines = []
    width = max((len(c) for c in columns), default=0) + 2
    for tail, entries in TABLE_STATS.items():
        rows = [c for c in columns if summary["columns"].get(c, {}).get("tail") == tail]
        if not rows:
            continue
        lines.append(f"{TAIL_TITLES[tail]}:")
        cell = max(10, *(row_digits(summary["columns"][c]) + 7 for c in rows))
        lines.append("".ljust(width) + "n".rjust(6) + "".join(h.rjust(cell) for _, h in entries))
        for column in rows:
            values = summary["columns"][column]
            digits = row_digits(values)
            cells = "".join(number(values[key], digits).rjust(cell) for key, _ in entries)
            lines.append(column.ljust(width) + str(values["n"]).rjust(6) + cells)
    covers = {summary["columns"][c]["covers"] for c in columns if c in summary["columns"]}
    for text in sorted(covers):
        lines.append(f"  over {text}")
    if columns:
        lines.append(
            "  tol99/95: one-sided tolerance bound, 99 % of successful flights on its good side with 95 % "
            "confidence (order statistic from n = 299, else normal mean +- k sd)"
        )
    constants = constant_line(summary)
    if constants:
        lines.append(f"the same in every successful flight: {constants}")
    not_produced = not_produced_line(summary)
    if not_produced:
        lines.append(not_produced)
    thrusters, pulse_rows = pulse_table(summary)
    if thrusters:
        lines.append("valve pulses per thruster " + " ".join(t.rjust(6) for t in thrusters))
        for header, values in pulse_rows:
            lines.append(f"  {header.ljust(23)} " + " ".join(number(v).rjust(6) for v in values))
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


DRIVERS_SHOWN = 3


def driver_lines(summary):
    """One line per figure target: the causes that explain most of its rank variance (eta2, p)."""
    section = summary.get("sensitivity") or {}
    lines = []
    for target in section.get("figure_targets", ()):
        rows = [r for r in section.get(target) or [] if r.get("eta2") is not None]
        unsupported = [r for r in section.get(target) or [] if r.get("eta2") is None and r.get("flag")]
        if not rows and not unsupported:
            continue
        shown = [
            f"{r['parameter']} ({'ρ²' if r.get('kind', 'input') == 'input' else 'η²'} {r['eta2']:.2f}, "
            f"p {r['p_value']:.2g})"
            for r in rows[:DRIVERS_SHOWN]
        ]
        line = f"what drives {target}: " + (", ".join(shown) or "no cause ranked")
        line += "".join(f"; {r['parameter']} {r['flag']}" for r in unsupported)
        lines.append(line)
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
    if summary["campaign"].get("failures", "none") != "none":
        lines.append(f"failures: {summary['campaign']['failures']}")
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
            f"{against.get('others', 'dispersed runs')} using more propellant than the nominal run: "
            f"{against['more_than_nominal']} of {against['of']} ({percent(against['share'])})"
        )
    for key, section in summary["worst_cases"].items():
        if key in ("unsuccessful", "errored") or not section["runs"]:
            continue
        run = section["runs"][0]
        column = section["column"]
        word = "smallest" if section["side"] == "low" else "largest"
        digits = row_digits(summary["columns"].get(column) or {})  # as its statistics row
        lines.append(f"{word} {column}: run {run['run_id']} ({number(run[column], digits)}): {run['command']}")
    lines += published_lines(summary)
    lines += driver_lines(summary)
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
