"""``OUT/report/index.html``: one self-contained page (inline CSS, figures as base64 PNG, no network)."""

import base64
import html
import math

from refexmc.report.requirements import requirement_label
from refexmc.report.text import TABLE_STATS, TAIL_TITLES, number, percent

STYLE = """
body { font-family: system-ui, sans-serif; margin: 1.5em auto; max-width: 1300px; color: #222; }
h1 { margin-bottom: 0.2em; } h2 { border-bottom: 1px solid #ccc; margin-top: 1.6em; }
table { border-collapse: collapse; margin: 0.6em 0; font-size: 0.9em; }
th, td { border: 1px solid #ccc; padding: 0.25em 0.6em; text-align: right; }
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
"""


def e(value):
    return html.escape(str(value), quote=True)


def table(headers, rows, classes=None):
    """An HTML table; ``rows`` of already-escaped cell strings."""
    out = ["<table><tr>" + "".join(f"<th>{e(h)}</th>" for h in headers) + "</tr>"]
    for k, row in enumerate(rows):
        cls = f' class="{classes[k]}"' if classes and classes[k] else ""
        out.append(f"<tr{cls}>" + "".join(f"<td>{cell}</td>" for cell in row) + "</tr>")
    out.append("</table>")
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


def statistics_section(summary):
    """One table per worse tail; each row says which runs it covers and how its tolerance bound was computed."""
    parts = []
    for tail, entries in TABLE_STATS.items():
        rows = []
        for column, values in summary["columns"].items():
            if values["tail"] != tail:
                continue
            cells = [number(values[key]) for key, _ in entries]
            rows.append(
                [
                    f"<code>{e(column)}</code>",
                    e(values["covers"]),
                    *cells,
                    number(values["std"]),
                    e(values["tolerance_99_95_method"]),
                ]
            )
        if rows:
            headers = ["column", "runs covered", *(h for _, h in entries), "std", "tol99/95 method"]
            parts.append(f"<h3>{e(TAIL_TITLES[tail])}</h3>" + table(headers, rows))
    return "\n".join(parts)


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
    names = wheel_sets["statistics"]
    rows = []
    for s in wheel_sets["sets"]:
        label = f"[{s['failed_wheels']}]" if s["failed_wheels"] else "none"
        rows.append([e(label), str(s["runs"]), f"{s['successes']}/{s['runs']}", *(number(s[n]) for n in names)])
    classes = ["pass" if s["successes"] == s["runs"] else "fail" for s in wheel_sets["sets"]]
    return table(["failed wheels", "runs", "success", *names], rows, classes)


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


def worst_section(worst):
    parts = []
    for key, section in worst.items():
        if not section["runs"]:
            if key in ("unsuccessful", "errored"):
                parts.append(f"<p>{e(section['meaning'])}: none.</p>")
            continue
        count = f" ({section['count']} in all)" if "count" in section else ""
        parts.append(f"<h3>{e(section['meaning'])}{e(count)}</h3>")
        rows = []
        for run in section["runs"]:
            value = number(run[key], 6) if key in run else ""
            rows.append(
                [
                    str(run["run_id"]),
                    value,
                    e(run["failure_reason"] or ""),
                    e(run["failed_thrusters"] or ""),
                    f"<code>{e(run['command'])}</code>",
                ]
            )
        parts.append(
            table(
                ["run", key if key in section["runs"][0] else "", "failure reason", "failed thrusters", "re-fly it"],
                rows,
            )
        )
    return "\n".join(parts)


def sensitivity_section(section, labels):
    parts = [
        f"<p>{e(section['method'])}, N = {section['runs']}; |ρ| above "
        f"{number(section['critical_abs_rho_95'], 3)} differs from 0 at the 5 % level (per parameter; with many "
        "parameters some cross it by chance).</p>"
    ]
    for output, label in labels.items():
        rows = [
            [f"<code>{e(r['parameter'])}</code>", f"{r['rho']:+.3f}", number(r["p_value"], 3)]
            for r in section.get(output, [])[:10]
        ]
        if rows:
            parts.append(f"<h3>{e(label)}</h3>" + table(["parameter", "Spearman ρ", "p-value"], rows))
    return "\n".join(parts)


def page(summary, figures, sensitivity_labels):
    """The whole HTML page. ``figures``: list of (title, caption, png bytes)."""
    c = summary["campaign"]
    counts = summary["counts"]
    success = summary["success"]
    reqs = summary["requirements"]
    verdict = summary["verdict"]
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
        f"sampling {e(c['sampling'])}, failures {e(c['failures'])}; output <code>{e(c['out'])}</code>; "
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
    body += [
        "<h2>Statistics over the successful flights</h2>",
        f"<p>Over the {e(notes['population'])}. Each column shows the tail where it is worse: {e(notes['tails'])}.</p>",
        statistics_section(summary),
        f"<p>Percentiles: {e(notes['percentiles'])}. <code>tol99/95</code>: {e(notes['tolerance_99_95'])}. "
        f"<code>mean±3sd</code>: {e(notes['mean_3sd'])}. Time in each mode: <code>t_&lt;mode&gt;_s</code>; "
        "hand-over angle error over the flights that reached hand-over.</p>",
    ]
    if summary.get("published"):
        body += [
            "<h2>Published values beside this campaign's</h2>",
            "<p>Values a source reports for the same campaign (the campaign file's <code>published</code>), "
            "beside the same statistic of these runs.</p>",
            published_section(summary["published"]),
        ]
    for title, caption, png_bytes in figures:
        body += [
            f"<h2>{e(title)}</h2>",
            f"<figure>{image(png_bytes, title)}<figcaption>{e(caption)}</figcaption></figure>",
        ]
    if summary.get("wheel_failure_sets"):
        kind = "detected: redistributed over the others" if summary["wheel_failure_sets"]["detected"] else "undetected"
        body += [f"<h2>Failed wheels ({e(kind)})</h2>", wheel_failure_sets_section(summary["wheel_failure_sets"])]
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
        body += ["<h2>Sensitivity</h2>", sensitivity_section(summary["sensitivity"], sensitivity_labels)]
    body += ["<h2>Worst cases</h2>", worst_section(summary["worst_cases"])]
    nominal = summary.get("nominal")
    if nominal:
        body.append(
            f"<p>Nominal run {nominal['run_id']}: propellant remaining "
            f"{number(nominal.get('fuel_remaining', math.nan))}, "
            f"hand-over angle error {number(nominal.get('theta_t_handover_deg', math.nan))} deg.</p>"
        )
        against = nominal.get("propellant_used_vs_dispersed")
        if against:
            body.append(
                f"<p>Dispersed runs using more propellant than the nominal run: {against['more_than_nominal']} "
                f"of {against['of']} ({100 * against['share']:.1f} %).</p>"
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
