"""``OUT/report/index.html``: one self-contained page (inline CSS, figures as base64 PNG, no network)."""

import base64
import html
import math

from refexmc.core.layout import MODE_NAMES
from refexmc.report.text import TABLE_HEADERS, TABLE_STATS, number, percent

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
        actual = number(r["actual"], 6) if r["actual"] is not None else e(r["note"])
        rows.append(["PASS" if r["passed"] else "FAIL", f"<code>{e(r['requirement'])}</code>", actual, e(r["source"])])
        classes.append("pass" if r["passed"] else "fail")
    return table(["verdict", "requirement", "actual", "source"], rows, classes)


def statistics_section(summary):
    rows = []
    for column, values in summary["columns"].items():
        rows.append([f"<code>{e(column)}</code>"] + [number(values[s]) for s in TABLE_STATS] + [number(values["std"])])
    return table(["column", *TABLE_HEADERS, "std"], rows)


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
    passed = summary["passed"]
    if reqs:
        verdict = f"{'PASS' if passed else 'FAIL'}: {sum(r['passed'] for r in reqs)} of {len(reqs)} requirements met"
        verdict_class = "pass" if passed else "fail"
    else:
        verdict, verdict_class = "no requirements to judge", "none"
    body = [
        f"<h1>Campaign {e(c['name'])}</h1>",
        f"<p>{counts['runs']} runs ({counts['ok_count']} ok, {counts['error_count']} errored), seed {e(c['seed'])}, "
        f"sampling {e(c['sampling'])}, failures {e(c['failures'])}; output <code>{e(c['out'])}</code>; "
        f"refexmc {e(c['refexmc'])}.</p>",
        f'<p class="verdict {verdict_class}">{e(verdict)}</p>',
    ]
    body += [f'<p class="note">{e(note)}</p>' for note in summary["notes"]]
    body += ["<h2>Requirements</h2>", requirements_section(summary)]
    low, high = success["ci95"]
    body += [
        "<h2>Success</h2>",
        f"<p>{success['successes']} of {success['ok_runs']} ok runs succeeded: {percent(success['rate'])}, "
        f"95 % Clopper-Pearson interval [{percent(low)}, {percent(high)}], one-sided 95 % lower bound "
        f"{percent(success['lower95'])}.</p>",
    ]
    if success.get("statement"):
        body.append(f"<p>{e(success['statement'])}.</p>")
    body += [
        "<h2>Statistics over the ok runs</h2>",
        statistics_section(summary),
        "<p>Percentiles: numpy's linear interpolation. "
        f"<code>tol_lower</code>: {e(summary['propellant_bounds']['tol_lower'])}. "
        f"<code>p0.135_lower95</code>: {e(summary['propellant_bounds']['p0.135_lower95'])}. "
        "Time in each mode: <code>t_&lt;mode&gt;_s</code>; hand-over angle error over the runs that reached "
        "hand-over.</p>",
    ]
    for title, caption, png_bytes in figures:
        body += [
            f"<h2>{e(title)}</h2>",
            f"<figure>{image(png_bytes, title)}<figcaption>{e(caption)}</figcaption></figure>",
        ]
    if summary["failure_sets"]:
        body += ["<h2>Failure sets</h2>", failure_sets_section(summary["failure_sets"])]
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
    body.append(f"<p>Modes: {e(' → '.join(MODE_NAMES))}. Numbers: <code>summary.json</code> beside this page.</p>")
    return (
        '<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8">'
        f"<title>refexmc report: {e(c['name'])}</title><style>{STYLE}</style></head><body>\n"
        + "\n".join(body)
        + "\n</body></html>\n"
    )
