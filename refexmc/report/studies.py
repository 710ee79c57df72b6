"""The report's sections for studies, hooked into :func:`refexmc.report.make_report` by a few
lines so that the report's own modules stay as they are:

- how a campaign stopped when decided (``refexmc run --until-decided``, refexmc.campaign.decided);
- a sweep's report (refexmc.campaign.sweep): each point's own report in its folder, and over the
  points a table and a curve of P(success) with its 95 % Clopper-Pearson band and the chosen
  metrics' percentiles against the swept value (``OUT/report/``: summary.json, index.html, sweep.png).
"""

import base64
import html as html_text
import io
import json
import math
from pathlib import Path

import numpy as np

MANIFEST_KEY = "until_decided"  # refexmc.campaign.decided.MANIFEST_KEY (which imports this package)


def format_stopping(record):
    from refexmc.campaign.decided import format_stopping as format_record

    return format_record(record)


def insert_section(page, section, before):
    """``page`` with ``section`` (HTML) inserted before the first ``before``, else before ``</body>``."""
    if not section:
        return page
    marker = before if before in page else "</body>"
    return page.replace(marker, section + marker, 1)


def sweep_record(out):
    """The manifest's ``sweep`` of a sweep's output, or None (refexmc.campaign.sweep)."""
    path = Path(out) / "manifest.json"
    if not path.is_file():
        return None
    try:
        info = json.loads(path.read_text())
    except ValueError:
        return None  # the plain report says what is wrong with it (report.data.read_manifest)
    return info.get("sweep") if isinstance(info, dict) else None


def stopping(campaign):
    """The stopping record of a campaign flown with ``--until-decided`` (manifest.json), or None."""
    return campaign.manifest.get(MANIFEST_KEY)


def stopping_text(summary):
    """Lines for the terminal summary ('' for a campaign flown without ``--until-decided``)."""
    record = summary.get(MANIFEST_KEY)
    return "\n" + format_stopping(record) if record else ""


def stopping_html(summary):
    """An HTML section for the report page ('' without a stopping record)."""
    from html import escape

    record = summary.get(MANIFEST_KEY)
    if not record:
        return ""
    return (
        "<section id='until-decided'><h2>Stopping when decided</h2><pre>"
        + escape(format_stopping(record))
        + "</pre><p>Group-sequential rule: one-sided Clopper-Pearson bounds with the alpha of each "
        "requirement spent over the looks (Lan-DeMets, Pocock type); docs/studies.md.</p></section>"
    )


# --- sweeps ------------------------------------------------------------------------------------

SWEEP_PERCENTILES = ("p1", "p50", "p99")  # per metric and point, over the successful flights


def point_statistics(point, result, runs, metrics):
    """One point's row of the sweep summary from its report ``result`` and runs table."""
    from refexmc.report import stats

    n = int(len(runs))
    successes = int((runs["success"].fillna(False).astype(bool) & (runs["status"] == "ok")).sum())
    low, high = stats.clopper_pearson(successes, n)
    successful = runs[(runs["status"] == "ok") & runs["success"].fillna(False).astype(bool)]
    return {
        "point": point["point"],
        "values": point["values"],
        "folder": point["folder"],
        "runs": n,
        "successes": successes,
        "success_rate": successes / n if n else math.nan,
        "success_ci95": [low, high],
        "verdict": result["verdict"],
        "requirements": [
            {"requirement": r["requirement"], "passed": r["passed"], "metric": r.get("metric"), "value": r.get("value")}
            for r in result["requirements"]
        ],
        "metrics": {
            metric: {q: stats.column_stat(successful[metric].to_numpy(dtype=float), q) for q in SWEEP_PERCENTILES}
            for metric in metrics
        },
    }


def sweep_report(out, record, make_point_report, require=(), html=True):
    """The report of sweep OUT (``record``: its manifest's ``sweep``); the dict of ``make_report``.

    ``make_point_report(folder, require, html)``: the plain report of one point."""
    from refexmc.campaign import storage

    out = Path(out)
    rows, incomplete, errored = [], [], []
    for point in record["points"]:
        folder = out / point["folder"]
        if not (folder / "manifest.json").is_file() or not any((folder / "runs").glob("part-*.parquet")):
            incomplete.append(point["point"])  # killed before the point started, or before its first part
            continue
        result = make_point_report(folder, require=require, html=html)
        runs = storage.read_runs_parts(sorted((folder / "runs").glob("part-*.parquet"))).to_pandas()
        rows.append(point_statistics(point, result, runs, record["metrics"]))
        if result["verdict"] == "INCOMPLETE":
            incomplete.append(point["point"])
        elif result["verdict"] == "ERRORED":
            errored.append(point["point"])
    verdict = "INCOMPLETE" if incomplete else "ERRORED" if errored else "COMPLETE"
    summary = {
        "kind": "sweep",
        "axes": record["axes"],
        "metrics": record["metrics"],
        "verdict": verdict,
        "incomplete_points": incomplete,
        "errored_points": errored,
        "points": rows,
    }
    report_dir = out / "report"
    report_dir.mkdir(parents=True, exist_ok=True)
    files = []
    if html and rows:
        png_bytes = sweep_figure(summary)
        (report_dir / "sweep.png").write_bytes(png_bytes)
        page = sweep_page(summary, png_bytes)
        (report_dir / "index.html").write_text(page)
        files += [report_dir / "sweep.png", report_dir / "index.html"]
    text = json.dumps(_json_ready(summary), indent=2, allow_nan=False) + "\n"
    (report_dir / "summary.json").write_text(text)
    files.append(report_dir / "summary.json")
    return {
        "summary": _json_ready(summary),
        "requirements": [],
        "verdict": verdict,
        "passed": verdict == "COMPLETE",
        "text": sweep_text(summary, report_dir),
        "report_dir": report_dir,
        "files": files,
    }


def _json_ready(value):
    if isinstance(value, dict):
        return {k: _json_ready(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_json_ready(v) for v in value]
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def _point_label(values):
    return ", ".join(f"{path} = {value:g}" for path, value in values.items())


def _number(value):
    return "-" if value is None or not math.isfinite(value) else f"{value:.4g}"


def sweep_rows(summary):
    """Header and rows (strings) of the per-point table."""
    header = ["point", *summary["axes"], "runs", "P(success)", "95 % CI", "verdict"]
    for metric in summary["metrics"]:
        header.append(f"{metric} p50 [p1, p99]")
    rows = []
    for row in summary["points"]:
        low, high = row["success_ci95"]
        cells = [str(row["point"]), *(f"{row['values'][a]:g}" for a in summary["axes"])]
        cells += [str(row["runs"]), _number(row["success_rate"]), f"[{_number(low)}, {_number(high)}]", row["verdict"]]
        for metric in summary["metrics"]:
            q = row["metrics"][metric]
            cells.append(f"{_number(q['p50'])} [{_number(q['p1'])}, {_number(q['p99'])}]")
        rows.append(cells)
    return header, rows


def sweep_text(summary, report_dir):
    header, rows = sweep_rows(summary)
    widths = [max(len(h), *(len(r[i]) for r in rows)) if rows else len(h) for i, h in enumerate(header)]
    lines = [f"sweep over {', '.join(summary['axes'])}: {len(summary['points'])} points"]
    lines.append("  ".join(h.rjust(w) for h, w in zip(header, widths, strict=True)))
    lines += ["  ".join(c.rjust(w) for c, w in zip(r, widths, strict=True)) for r in rows]
    lines.append(
        "P(success): every run of the point (errored runs count as unsuccessful), two-sided 95 % Clopper-Pearson"
    )
    lines.append("each point's own report: OUT/points/NNN/report/")
    if summary["incomplete_points"]:
        lines.append(
            f"INCOMPLETE points: {summary['incomplete_points']} (finish with `refexmc run CAMPAIGN -o OUT --resume`)"
        )
    if summary["errored_points"]:
        lines.append(f"points with errored runs: {summary['errored_points']}")
    lines.append(f"sweep: {summary['verdict']}; report in {report_dir}")
    return "\n".join(lines)


def _series(summary):
    """[(label, x values, rows)]: one series per value of the second axis (one series for one axis)."""
    axes, rows = summary["axes"], summary["points"]
    if len(axes) == 1:
        return [(None, [r["values"][axes[0]] for r in rows], rows)]
    series = {}
    for r in rows:
        series.setdefault(r["values"][axes[1]], []).append(r)
    return [(f"{axes[1]} = {v:g}", [r["values"][axes[0]] for r in group], group) for v, group in series.items()]


SWEEP_COLUMNS = 2  # panels per row: the figure fits the page's 1300 px at SWEEP_DPI
SWEEP_FIGURE_WIDTH_IN = 12.8
SWEEP_DPI = 100


def sweep_bounds(summary):
    """{metric: [(value, requirement)]}: the bounds of the points' requirements on each swept
    metric's statistic (every point has the campaign's requirements; the first point's are read)."""
    from refexmc.report.requirements import split_metric

    bounds = {}
    points = summary["points"]
    for r in points[0]["requirements"] if points else ():
        if not r.get("metric") or r.get("value") is None:
            continue
        column = split_metric(r["metric"])[0]
        bound = (float(r["value"]), r["requirement"])
        if (column in summary["metrics"] or column == "success_rate") and bound not in bounds.get(column, []):
            bounds.setdefault(column, []).append(bound)
    return bounds


def sweep_figure(summary):
    """:func:`sweep_matplotlib_figure` as PNG bytes."""
    buffer = io.BytesIO()
    sweep_matplotlib_figure(summary).savefig(buffer, format="png", dpi=SWEEP_DPI)
    return buffer.getvalue()


def sweep_matplotlib_figure(summary):
    """P(success) with its 95 % Clopper-Pearson band, and each metric's p50 with its p1-p99 band,
    against the first axis (one line per value of the second), at most ``SWEEP_COLUMNS`` panels
    a row; dashed red: the requirement bounds on each panel's metric."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    panels = 1 + len(summary["metrics"])
    columns = min(panels, SWEEP_COLUMNS)
    rows_of_panels = -(-panels // columns)
    width = SWEEP_FIGURE_WIDTH_IN * columns / SWEEP_COLUMNS
    figure = Figure(figsize=(width, 4.0 * rows_of_panels), layout="constrained")
    FigureCanvasAgg(figure)
    grid = figure.subplots(rows_of_panels, columns, squeeze=False).ravel()
    for ax in grid[panels:]:
        ax.remove()
    axes = grid[:panels]
    for label, x, rows in _series(summary):
        order = np.argsort(x)
        x = np.asarray(x, dtype=float)[order]
        rate = np.array([r["success_rate"] for r in rows], dtype=float)[order]
        band = np.array([r["success_ci95"] for r in rows], dtype=float)[order]
        (line,) = axes[0].plot(x, rate, marker="o", label=label or "P(success)")
        axes[0].fill_between(x, band[:, 0], band[:, 1], color=line.get_color(), alpha=0.2, lw=0)
        for ax, metric in zip(axes[1:], summary["metrics"], strict=True):
            q = {k: np.array([r["metrics"][metric][k] for r in rows], dtype=float)[order] for k in SWEEP_PERCENTILES}
            (line,) = ax.plot(x, q["p50"], marker="o", label=f"{label + ': ' if label else ''}median")
            ax.fill_between(x, q["p1"], q["p99"], color=line.get_color(), alpha=0.2, lw=0)
    axes[0].set_ylabel("95 % Clopper-Pearson band")
    axes[0].set_ylim(-0.02, 1.02)
    axes[0].set_title("P(success)")
    bounds = sweep_bounds(summary)
    for ax, metric in zip(axes[1:], summary["metrics"], strict=True):
        ax.set_title(metric)
        ax.set_ylabel("successful flights: median, 1-99 % band")
    for ax, metric in zip(axes, ["success_rate", *summary["metrics"]], strict=True):
        for value, requirement in bounds.get(metric, ()):
            ax.axhline(value, color="tab:red", ls="--", lw=1.0, label=f"required: {requirement}")
        if bounds.get(metric):
            ax.legend(fontsize="small")
    for ax in axes:
        ax.set_xlabel(summary["axes"][0])
        ax.grid(alpha=0.3)
    if not bounds.get("success_rate"):
        axes[0].legend(fontsize="small")
    return figure


def sweep_page(summary, png_bytes):
    e = html_text.escape
    header, rows = sweep_rows(summary)
    table = "<table><tr>" + "".join(f"<th>{e(h)}</th>" for h in header) + "</tr>"
    for row, point in zip(rows, summary["points"], strict=True):
        link = f"<a href='../{e(point['folder'])}/report/index.html'>{e(row[0])}</a>"
        table += "<tr>" + "".join(f"<td>{c}</td>" for c in [link, *map(e, row[1:])]) + "</tr>"
    table += "</table>"
    encoded = base64.b64encode(png_bytes).decode("ascii")
    return (
        "<!DOCTYPE html>\n<html lang='en'><head><meta charset='utf-8'><title>refexmc sweep</title>"
        "<style>body{font-family:system-ui,sans-serif;max-width:1300px;margin:1.5em auto}img{max-width:100%}"
        "table{border-collapse:collapse}td,th{border:1px solid #ccc;padding:.2em .5em;text-align:right}</style>"
        f"</head><body><h1>Sweep over {e(', '.join(summary['axes']))}</h1>"
        f"<p>Verdict: {e(summary['verdict'])}. Each point is a full Monte-Carlo campaign with the same run seeds "
        "(common random numbers); its own report is linked from the table.</p>"
        f"<figure><img alt='sweep curve' src='data:image/png;base64,{encoded}'><figcaption>P(success) with its "
        "two-sided 95 % Clopper-Pearson band (every run of the point; errored runs count as unsuccessful) and "
        "each metric's median with its 1-99 % band over the successful flights, against the swept value."
        f"</figcaption></figure>{table}</body></html>\n"
    )


# --- Sobol' indices ------------------------------------------------------------------------------


def sobol_section(campaign, plan):
    """The Sobol' indices of a ``sampling: saltelli`` campaign (refexmc.report.sobol), or None;
    ``plan``: the report's ``outputs.plan`` (the mission's metrics)."""
    if campaign.resolved.get("sampling") != "saltelli":
        return None
    from refexmc.report import sobol

    seed = int(campaign.resolved.get("seed", 0)) % 2**32
    return sobol.campaign_indices(campaign.resolved, campaign.runs, plan, seed=seed)


def sobol_text(summary):
    from refexmc.report import sobol

    return "\n" + sobol.text(summary["sobol"]) if summary.get("sobol") else ""


def sobol_html(summary):
    """An HTML section: the indices figure and, per metric, the table of first and total indices
    (flagged indices marked), or why it cannot be estimated."""
    if not summary.get("sobol"):
        return ""
    from refexmc.report import sobol

    e = html_text.escape
    section = summary["sobol"]
    parts = [
        "<section id='sobol'><h2>Sobol' indices</h2>",
        f"<p>Saltelli design over {len(section['groups'])} dispersed parameters, {section['runs']} runs, "
        f"N = {section['base_samples']} base samples; first-order and total indices with 95 % bootstrap "
        f"intervals (SALib; docs/studies.md); metrics: {e(section.get('metrics_from', ''))}. "
        "<b>?</b> marks an index this design cannot support.</p>",
    ]
    png_bytes = sobol.figure(section)
    if png_bytes:
        encoded = base64.b64encode(png_bytes).decode("ascii")
        parts.append(f"<figure><img alt='Sobol indices' src='data:image/png;base64,{encoded}'></figure>")
    for metric, entry in section["metrics"].items():
        needed = sobol.needed_text(entry)
        if "cannot_estimate" in entry:
            why = e(entry["cannot_estimate"]) + e(needed)
            parts.append(f"<h3>{e(metric)}</h3><p class='note'>cannot estimate: {why}</p>")
            continue
        rows = "".join(
            f"<tr><td>{e(name)}</td><td>{e(sobol.mark(s, 'first'))}</td><td>{e(sobol.mark(s, 'total'))}</td>"
            f"<td class='text'>{e('; '.join(s.get('flags', [])))}</td></tr>"
            for name, s in ((n, entry["indices"][n]) for n in sobol.ranking(entry))
        )
        flag = f"<p class='note'>{e(entry['flag'])}{e(needed)}</p>" if entry.get("flag") else ""
        parts.append(
            f"<h3>{e(metric)}</h3>{flag}<table><tr><th>parameter</th><th>first</th><th>total</th>"
            f"<th>not supported</th></tr>{rows}</table>"
        )
    return "".join(parts) + "</section>"
