"""``OUT/report/index.html``: one self-contained page (inline CSS, figures as base64 PNG, no network)."""

import base64
import html

from refexmc.report import outputs
from refexmc.report.requirements import requirement_label
from refexmc.report.text import (
    TABLE_STATS,
    TAIL_TITLES,
    constant_line,
    not_produced_line,
    number,
    percent,
    pulse_table,
    row_digits,
)

STYLE = """
body { font-family: system-ui, sans-serif; margin: 1.5em auto; max-width: 1300px; color: #222; }
h1 { margin-bottom: 0.2em; } h2 { border-bottom: 1px solid #ccc; margin-top: 1.6em; }
table { border-collapse: collapse; margin: 0.6em 0; font-size: 0.9em; max-width: 100%; }
th, td { border: 1px solid #ccc; padding: 0.25em 0.6em; text-align: right; overflow-wrap: anywhere; }
th { font-weight: 600; overflow-wrap: normal; }
.wide { max-width: 100%; overflow-x: auto; }
td.fail, span.fail { background: #f6d0d0; }
th:first-child, td:first-child { text-align: left; }
td.text { text-align: left; }
.pass { background: #d8f0d8; } .fail { background: #f6d0d0; } .none { background: #eeeeee; }
.verdict { font-size: 1.3em; padding: 0.5em 0.8em; display: inline-block; border-radius: 4px; }
code { background: #f2f2f2; padding: 0 0.2em; }
figure { margin: 1em 0; } figcaption { font-size: 0.9em; color: #444; max-width: 1100px; }
img { max-width: 100%; }
.note { color: #8a5a00; }
.banner { background: #f6d0d0; border: 2px solid #b00000; color: #600000; font-weight: bold; padding: 0.6em 0.8em; }
.incomplete, .errored { background: #f3d9a8; }
tr.failing-row, span.failing-row { background: #fbeaea; }
td.failing-cell, span.failing-cell { background: #e08a8a; font-weight: 700; }
"""


def e(value):
    return html.escape(str(value), quote=True)


def breakable(text):
    """Escaped text that may wrap after ``_`` and ``.`` (long column names in table headers)."""
    return e(text).replace("_", "_<wbr>").replace(".", ".<wbr>")


def table(headers, rows, classes=None, cell_classes=None):
    """An HTML table in a box that scrolls sideways rather than widen the page; ``rows`` of
    already-escaped cell strings; ``classes`` per row, ``cell_classes`` per cell (or None)."""
    out = ['<div class="wide"><table><tr>' + "".join(f"<th>{breakable(h)}</th>" for h in headers) + "</tr>"]
    for k, row in enumerate(rows):
        cls = f' class="{classes[k]}"' if classes and classes[k] else ""
        cells = []
        for j, cell in enumerate(row):
            cell_class = cell_classes[k][j] if cell_classes and cell_classes[k] and cell_classes[k][j] else ""
            cells.append(f'<td class="{cell_class}">{cell}</td>' if cell_class else f"<td>{cell}</td>")
        out.append(f"<tr{cls}>" + "".join(cells) + "</tr>")
    out.append("</table></div>")
    return "\n".join(out)


def image(png_bytes, alt):
    encoded = base64.b64encode(png_bytes).decode("ascii")
    return f'<img alt="{e(alt)}" src="data:image/png;base64,{encoded}">'


def requirements_section(summary):
    reqs = summary["requirements"]
    if not reqs:
        return (
            "<p>No requirements: add <code>requirements:</code> to the campaign file or use <code>--require</code>.</p>"
        )
    rows, classes = [], []
    for r in reqs:
        actual = number(r["actual"], 6) if r["actual"] is not None else "-"
        if r["actual_successful_flights"] is not None and r["actual"] != r["actual_successful_flights"]:
            actual += f" (successful flights alone: {number(r['actual_successful_flights'], 6)})"
        rows.append(
            [
                requirement_label(r, summary["verdict"]),
                f"<code>{e(r['requirement'])}</code>",
                actual,
                f'<span class="text">{e(r["covers"])}</span>',
                e(r["note"]),
                e(r["source"]),
            ]
        )
        classes.append("pass" if r["passed"] else "fail")
    return table(["verdict", "requirement", "actual", "runs covered", "note", "source"], rows, classes)


def _column_verdicts(summary):
    """{column: passed} over the requirements on each runs column (all of them met)."""
    result = {}
    for column in (summary.get("outputs") or {}).get("requirement_columns", ()):
        judged = outputs.requirements_of(column, summary["requirements"])  # pointing records included
        result[column] = all(r["passed"] for r in judged)
    return result


def _statistics_tables(summary, columns, verdicts=None):
    """One table per worse tail; what the rows cover and how tol99/95 was computed once per table
    (per row only where rows differ)."""
    parts = []
    labels = (summary.get("outputs") or {}).get("labels", {})
    units = (summary.get("outputs") or {}).get("units", {})
    for tail, entries in TABLE_STATS.items():
        chosen = [c for c in columns if summary["columns"].get(c, {}).get("tail") == tail]
        if not chosen:
            continue
        covers = {summary["columns"][c]["covers"] for c in chosen}
        methods = {summary["columns"][c]["tolerance_99_95_method"] for c in chosen}
        rows, classes = [], []
        for column in chosen:
            values = summary["columns"][column]
            unit = f" [{units[column]}]" if units.get(column) else ""
            row = [
                f"<code>{e(column)}</code>{e(unit)}<br><small>{e(labels.get(column, ''))}</small>",
                str(values["n"]),
                *(number(values[key], row_digits(values)) for key, _ in entries),
            ]
            if len(covers) > 1:
                row.insert(1, e(values["covers"]))
            if len(methods) > 1:
                row.append(e(values["tolerance_99_95_method"]))
            rows.append(row)
            classes.append(None if verdicts is None else ("pass" if verdicts.get(column) else "fail"))
        headers = ["column", "n", *(h for _, h in entries)]
        if len(covers) > 1:
            headers.insert(1, "runs covered")
        if len(methods) > 1:
            headers.append("tol99/95 method")
        note = []
        if len(covers) == 1:
            note.append(f"over {covers.pop()}")
        if len(methods) == 1 and tail != "both":
            note.append(f"tol99/95: {methods.pop()}")
        parts.append(
            f"<h3>{e(TAIL_TITLES[tail])}</h3>"
            + (f"<p>{e('; '.join(note))}.</p>" if note else "")
            + table(headers, rows, classes)
        )
    return "\n".join(parts)


def statistics_section(summary):
    """The other outputs' tables, the constant outputs in one line and the pulse counts in one table."""
    plan = summary.get("outputs") or {}
    parts = [_statistics_tables(summary, [c for c in plan.get("other_columns", ()) if c in summary["columns"]])]
    constants = constant_line(summary)
    if constants:
        parts.append(f"<p>The same in every successful flight: {e(constants)}.</p>")
    thrusters, pulse_rows = pulse_table(summary)
    if thrusters:
        rows = [[e(h), *(number(v) for v in values)] for h, values in pulse_rows]
        parts.append("<h3>Valve pulses per thruster</h3>" + table(["thruster", *thrusters], rows))
    if not_produced_line(summary):
        parts.append(f"<p>{e(not_produced_line(summary)).capitalize()}.</p>")
    return "\n".join(parts)


def inputs_section(inputs):
    rows = []
    for row in inputs["rows"]:
        drawn = "; ".join(
            (f"{d['component']}: " if d["component"] else "") + f"{number(d['min'])} … {number(d['max'])}"
            for d in row["drawn"]
        )
        rows.append(
            [f"<code>{e(row['parameter'])}</code>", e(row["distribution"]), e(row["parameters"]), e(drawn or "-")]
        )
    if not rows:
        return "<p>No dispersed parameter: every run flies the same inputs.</p>"
    return f"<p>Drawn range: min … max over the {e(inputs['covers'])}.</p>" + table(
        ["parameter", "distribution", "parameters", "drawn range"], rows
    )


def failure_reasons_section(reasons):
    if not reasons:
        return "<p>No failed flight and no errored run.</p>"
    rows = []
    for r in reasons:
        ids = ", ".join(str(i) for i in r["example_run_ids"]) + (
            ", ..." if r["count"] > len(r["example_run_ids"]) else ""
        )
        rows.append([e(r["kind"]), f'<span class="text">{e(r["reason"])}</span>', str(r["count"]), e(ids)])
    return table(["kind", "reason", "runs", "example run ids"], rows, ["fail"] * len(rows))


def wheel_failure_sets_section(wheel_sets):
    """One row per failed-wheel set, coloured by the requirements judged on its runs; a statistic
    that fails its requirement is marked in its cell."""
    names = wheel_sets["statistics"]
    required = wheel_sets.get("requirements", {})
    rows, classes, cells = [], [], []
    for s in wheel_sets["sets"]:
        label = f"[{s['failed_wheels']}]" if s["failed_wheels"] else "none"
        verdicts = s.get("verdicts", {})
        rows.append([e(label), str(s["runs"]), f"{s['successes']}/{s['runs']}", *(number(s[n]) for n in names)])
        cells.append(
            [
                None,
                None,
                None if s["successes"] == s["runs"] else "failing-cell",
                *("failing-cell" if verdicts.get(n) is False else None for n in names),
            ]
        )
        classes.append("pass" if s.get("passed", s["successes"] == s["runs"]) else "failing-row")
    meanings = wheel_sets.get("meanings", {})

    def header(name):
        if name in meanings:  # a pointing record: the share of the set's runs within its bound
            return f"{name}: {meanings[name]}; {required[name]}"
        if name in required:
            text = required[name]
            return f"{name} (required {text.split(name, 1)[1].strip() if text.startswith(name) else text})"
        return name

    headers = ["failed wheels", "runs", "success", *(header(n) for n in names)]
    legend = (
        '<p>Rows: <span class="pass">&nbsp;green&nbsp;</span> the set meets every requirement, '
        '<span class="failing-row">&nbsp;pale red&nbsp;</span> it fails one; a cell in '
        '<span class="failing-cell">&nbsp;deep red&nbsp;</span> is the statistic that fails.</p>'
    )
    return legend + table(headers, rows, classes, cells)


def failure_sets_section(sets):
    rows = []
    for s in sets:
        low, high = s["success_rate_ci95"]
        rows.append(
            [
                e(f"[{s['failed_thrusters']}]" if s["failed_thrusters"] else "none"),
                str(s["runs"]),
                f"{s['successes']}/{s['runs']}",
                f"{percent(low)} - {percent(high)}",
                percent(s["fuel_remaining_min"]),
                percent(s["fuel_remaining_median"]),
                e(", ".join(s["failure_reasons"])),
            ]
        )
    classes = ["pass" if s["success_rate"] == 1 else "fail" for s in sets]
    return table(
        ["failed thrusters", "runs", "success", "95 % CI", "min propellant", "median propellant", "failure reasons"],
        rows,
        classes,
    )


def published_section(entries):
    """One table per published entry: column, our statistic with its n, the source's value, the ratio."""
    parts = []
    for entry in entries:
        rows = [
            [
                f"<code>{e(row['column'])}</code>",
                str(row["n"]),
                number(row["ours"]),
                number(row["published"]),
                number(row["ratio_published_to_ours"], 3),
            ]
            for row in entry["rows"]
        ]
        parts += [
            f"<h3>{e(entry['source'])}</h3>",
            f"<p><code>{e(entry['statistic'])}</code>: {e(entry['statistic_meaning'])}, ours over "
            f"{e(entry['covers'])}.</p>",
            table(["column", "n", f"ours ({entry['statistic']})", "published", "published / ours"], rows),
        ]
    return "\n".join(parts)


def worst_section(worst, show_thrusters=True, show_wheels=False):
    parts = []
    for key, section in worst.items():
        if not section["runs"]:
            if key in ("unsuccessful", "errored"):
                parts.append(f"<p>{e(section['meaning'])}: none.</p>")
            continue
        count = f" ({section['count']} in all)" if "count" in section else ""
        parts.append(f"<h3>{e(section['meaning'])}{e(count)}</h3>")
        column = section.get("column")
        rows = []
        for run in section["runs"]:
            row = [str(run["run_id"])]
            if column:
                row.append(number(run[column], 6))
            row.append(e(run["failure_reason"] or ""))
            if show_thrusters:
                row.append(e(run.get("failed_thrusters") or ""))
            if show_wheels:
                row.append(e(run.get("failed_wheels") or ""))
            row.append(f"<code>{e(run['command'])}</code>")
            rows.append(row)
        headers = ["run", *([column] if column else []), "failure reason"]
        headers += ["failed thrusters"] * show_thrusters + ["failed wheels"] * show_wheels + ["re-fly it"]
        parts.append(table(headers, rows))
    return "\n".join(parts)


def _levels(row, shown=3):
    """A factor's levels with the highest output ranks: " (highest: [2] 7 runs, [1] 9 runs)"."""
    levels = row.get("levels_by_rank")
    if not levels:
        return ""
    text = ", ".join(f"[{entry['level'] or 'none'}] {entry['runs']} runs" for entry in levels[:shown])
    return f" <span class='text'>(highest: {e(text)})</span>"


def _flag(row):
    """Why a cause is not ranked (a factor without replication within its levels), or ''."""
    return f"<br><small>{e(row['flag'])}</small>" if row.get("flag") else ""


def sensitivity_section(section, labels=None):
    parts = [
        f"<p>{e(section['method'])}, N = {section['runs']}, {section.get('parameters', '')} inputs that vary; "
        "|ρ| above "
        f"{number(section['critical_abs_rho_95'], 3)} differs from 0 at the 5 % level (per parameter; with many "
        f"parameters some cross it by chance). {e(section.get('prcc_note', ''))}.</p>"
    ]
    if section.get("factors"):
        parts.append(
            "<p>Discrete causes ranked with the inputs: "
            + ", ".join(f"<code>{e(name)}</code>" for name in section["factors"])
            + ". η²: the share of the metric's rank variance a cause explains (ρ² for an input, the correlation "
            "ratio over a factor's levels, Kruskal-Wallis p); a failed unit's ρ is that of its indicator.</p>"
        )
    for output in section.get("targets", labels or ()):
        rows = [
            [
                f"<code>{e(r['parameter'])}</code>" + _levels(r) + _flag(r),
                e(r.get("kind", "input")),
                f"{r['eta2']:.3f}" if r.get("eta2") is not None else "-",
                "-" if r.get("rho") is None else f"{r['rho']:+.3f}",
                number(r["p_value"], 3),
                "-" if r.get("prcc") is None else f"{r['prcc']:+.3f}",
                number(r.get("prcc_p_value"), 3),
            ]
            for r in section.get(output, [])[:10]
        ]
        if rows:
            label = (labels or {}).get(output, output)
            headers = ["cause", "kind", "η²", "Spearman ρ", "p-value", "PRCC", "PRCC p-value"]
            parts.append(f"<h3>{e(label)}</h3>" + table(headers, rows))
    return "\n".join(parts)


def page(summary, figures, sensitivity_labels=None):
    """The whole HTML page. ``figures``: list of (title, caption, png bytes)."""
    c = summary["campaign"]
    counts = summary["counts"]
    success = summary["success"]
    reqs = summary["requirements"]
    verdict = summary["verdict"]
    plan = summary.get("outputs") or {}
    met = f"{sum(r['passed'] for r in reqs)} of {len(reqs)} requirements met"
    if verdict in ("INCOMPLETE", "ERRORED"):
        verdict_text, verdict_class = f"{verdict}: {met} on the stored runs; no overall verdict", verdict.lower()
    elif reqs:
        verdict_text, verdict_class = f"{verdict}: {met}", verdict.lower()
    else:
        verdict_text, verdict_class = "no requirements to judge", "none"
    body = [f'<p class="banner">{e(summary["banner"])}</p>'] if summary.get("banner") else []
    body += [
        f"<h1>Campaign {e(c['name'])}</h1>",
        f"<p>{counts['runs']} runs ({counts['success_count']} successful, {counts['failure_count']} failed, "
        f"{counts['error_count']} errored), seed {e(c['seed'])}, "
        f"sampling {e(c['sampling'])}, failures: {e(c['failures'])}; output <code>{e(c['out'])}</code>; "
        f"refexmc {e(c['refexmc'])}.</p>",
        f'<p class="verdict {verdict_class}">{e(verdict_text)}</p>',
    ]
    body += [f'<p class="note">{e(note)}</p>' for note in summary["notes"]]
    body += [
        "<h2>Requirements</h2>",
        requirements_section(summary),
        "<p>Every requirement is judged over all runs: a failed flight or an errored run counts as failing it "
        "(docs/report.md says how, per statistic).</p>",
    ]
    low, high = success["ci95"]
    body += [
        "<h2>Success</h2>",
        f"<p>{success['successes']} of {success['runs']} runs succeeded: {percent(success['rate'])}, "
        f"95 % Clopper-Pearson interval [{percent(low)}, {percent(high)}], one-sided 95 % lower bound "
        f"{percent(success['lower95'])} (over {e(success['covers'])}).</p>",
    ]
    if success.get("statement"):
        body.append(f"<p>{e(success['statement'])}.</p>")
    body += ["<h2>Failure reasons</h2>", failure_reasons_section(summary["failure_reasons"])]
    notes = summary["statistics_notes"]
    judged = [c for c in plan.get("requirement_columns", ()) if c in summary["columns"]]
    if judged:
        body += [
            "<h2>The requirements' metrics over the successful flights</h2>",
            "<p>Row colour: the verdict of the column's requirements (over all runs).</p>",
            _statistics_tables(summary, judged, _column_verdicts(summary)),
        ]
    body += [
        "<h2>Other outputs over the successful flights</h2>",
        f"<p>Over the {e(notes['population'])}. Each column shows the tail where it is worse: {e(notes['tails'])}.</p>",
        statistics_section(summary),
        f"<p>Percentiles: {e(notes['percentiles'])}. <code>tol99/95</code>: {e(notes['tolerance_99_95'])}. "
        f"<code>mean±3sd</code>: {e(notes['mean_3sd'])}. Time in each mode: <code>t_&lt;mode&gt;_s</code>.</p>",
    ]
    if summary.get("published"):
        body += [
            "<h2>Published values beside this campaign's</h2>",
            "<p>Values a source reports for the same campaign (the campaign file's <code>published</code>), "
            "beside the same statistic of these runs.</p>",
            published_section(summary["published"]),
        ]
    if summary.get("inputs"):
        body += ["<h2>Dispersed inputs</h2>", inputs_section(summary["inputs"])]
    for title, caption, png_bytes in figures:
        body += [
            f"<h2>{e(title)}</h2>",
            f"<figure>{image(png_bytes, title)}<figcaption>{e(caption)}</figcaption></figure>",
        ]
    if summary.get("wheel_failure_sets"):
        kind = "detected: redistributed over the others" if summary["wheel_failure_sets"]["detected"] else "undetected"
        body += [
            f"<h2>Failed wheels ({e(kind)})</h2>",
            "<p>Per set of failed wheels: each requirement's statistic over the set's runs (failed flights "
            "counting as failing); a red cell fails its requirement, a red row has one.</p>",
            wheel_failure_sets_section(summary["wheel_failure_sets"]),
        ]
    if summary["failure_sets"]:
        kind = "detected: left out of the allocation" if summary["campaign"].get("failures_detected") else "undetected"
        body += [f"<h2>Failure sets ({e(kind)})</h2>", failure_sets_section(summary["failure_sets"])]
        table4 = summary.get("failure_sets_vs_000_table4")
        if table4:
            differ = ", ".join(f"[{d}]" for d in table4["disagree"]) or "none"
            body.append(
                f"<p>Against 000 Table 4 (compensable = every run of the set succeeded): {table4['agree']} of "
                f"{table4['compared']} single and double failure sets agree; differ: {e(differ)}.</p>"
            )
    if summary["sensitivity"]:
        body += ["<h2>Sensitivity</h2>", sensitivity_section(summary["sensitivity"], plan.get("labels"))]
    kinds = {k["kind"] for k in c.get("failure_kinds", ())}
    body += ["<h2>Worst cases</h2>", worst_section(summary["worst_cases"], "thruster" in kinds, "wheel" in kinds)]
    nominal = summary.get("nominal")
    if nominal:
        shown = [col for col in plan.get("requirement_columns", ()) if col in nominal][:6]
        values = ", ".join(f"{col} {number(nominal[col])}" for col in shown)
        body.append(f"<p>Nominal run {nominal['run_id']}" + (f": {e(values)}" if values else "") + ".</p>")
        against = nominal.get("propellant_used_vs_dispersed")
        if against:
            body.append(
                f"<p>{e(against.get('others', 'dispersed runs')).capitalize()} using more propellant than the "
                f"nominal run: {against['more_than_nominal']} of {against['of']} ({100 * against['share']:.1f} %).</p>"
            )
    body.append(
        f"<p>Modes: {e(' → '.join(summary['modes']))}. Numbers: <code>summary.json</code> beside this page.</p>"
    )
    return (
        '<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8">'
        f"<title>refexmc report: {e(c['name'])}</title><style>{STYLE}</style></head><body>\n"
        + "\n".join(body)
        + "\n</body></html>\n"
    )
