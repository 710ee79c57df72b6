"""`refexmc report OUT`: does the design hold? Statistics, requirement verdicts, figures, one HTML page.

``make_report(out, require=(), html=True)`` reads OUT (runs table whole, histories batch by
batch), writes ``OUT/report/summary.json`` and, with ``html``, ``OUT/report/index.html`` (and
the figures as ``OUT/report/figures/*.png``), and returns a dict:

- ``summary``: everything in summary.json;
- ``requirements``: one verdict dict per requirement (campaign file first, then ``require``);
- ``verdict``: PASS, FAIL, INCOMPLETE (not every planned run stored), ERRORED (some runs
  errored) or NO REQUIREMENTS (``refexmc.report.requirements.overall_verdict``);
- ``passed``: the verdict is PASS or NO REQUIREMENTS (the CLI exits 1 otherwise);
- ``text``: the terminal summary;
- ``report_dir``, ``files``: where it wrote.

Bad input (OUT not a campaign output, a malformed requirement, an unknown metric, a
``published`` column the stored runs table lacks) raises ``refexmc.config.errors.ConfigError``
before anything is written. The metric grammar is in
``refexmc.report.requirements``.
"""

import json
from pathlib import Path

import numpy as np

from refexmc.campaign.storage import write_text_atomic
from refexmc.report import data, pointing, rare_event, studies
from refexmc.report import summary as summary_module
from refexmc.report import text as text_module
from refexmc.report.requirements import CAMPAIGN_METRICS, evaluate, overall_verdict, parse_requirement, split_metric


def load_requirements(campaign, require=()):
    """Requirements of the campaign file (with file and line) and of ``require``, parsed and checked."""
    columns = list(campaign.runs.columns)
    resolved = campaign.out / "campaign.resolved.yaml"
    listed = campaign.resolved.get("requirements") or []
    parsed = []
    for i, text in enumerate(listed):
        if isinstance(text, dict):  # a pointing requirement (report.pointing)
            continue
        line = campaign.resolved_lines.get(("requirements", i))
        parsed.append(parse_requirement(text, columns, "campaign", file=resolved, line=line, path=("requirements", i)))
    for text in require:
        parsed.append(parse_requirement(text, columns, "--require", path=("--require",)))
    return parsed


def make_report(out, require=(), html=True):
    """Build the report of campaign output ``out``; see the module docstring."""
    sweep = studies.sweep_record(out)
    if sweep is not None:  # a sweep: each point's report, and the curve over the points
        return studies.sweep_report(out, sweep, make_report, require=require, html=html)
    campaign = data.load(out)
    requirements = load_requirements(campaign, require)
    verdicts = [evaluate(r, campaign, summary_module.campaign_metrics(campaign)) for r in requirements]
    summary = summary_module.build(campaign, verdicts)
    pointed = [pointing.evaluate(r, campaign) for r in pointing.requirements_of(campaign)]
    verdicts += pointed  # ECSS pointing requirements beside the 'METRIC OP VALUE' ones (docs/pointing.md)
    summary["requirements"] = verdicts
    summary["verdict"], summary["passed"], summary["banner"] = overall_verdict(summary["completeness"], verdicts)
    if studies.stopping(campaign):  # flown with --until-decided: how many runs, why it stopped
        summary["until_decided"] = studies.stopping(campaign)
    if "rare_event" in campaign.resolved:  # a rare-event study (issue 36): P, its levels, what drives it
        summary["rare_event"] = rare_event.section(campaign)
    sobol_indices = studies.sobol_section(campaign, summary["outputs"])  # sampling saltelli: Sobol' indices
    if sobol_indices is not None:
        summary["sobol"] = sobol_indices
    report_dir = Path(out) / "report"
    report_dir.mkdir(parents=True, exist_ok=True)
    files = []
    if html:
        figures = render_figures(campaign, summary)
        summary["figures"] = [title for title, _, _, _ in figures]
        figure_dir = report_dir / "figures"
        figure_dir.mkdir(exist_ok=True)
        for _, _, png_bytes, name in figures:
            path = figure_dir / f"{name}.png"
            path.write_bytes(png_bytes)
            files.append(path)
        from refexmc.report import html as html_module

        page = html_module.page(summary, [(t, c, b) for t, c, b, _ in figures])
        page = studies.insert_section(page, studies.stopping_html(summary), "<h2>Requirements</h2>")
        page = studies.insert_section(page, studies.sobol_html(summary), "</body>")
        page = studies.insert_section(page, pointing.html_section(pointed), "</body>")
        if summary.get("rare_event"):
            page = studies.insert_section(page, rare_event.html(summary), "<h2>Requirements</h2>")
        write_text_atomic(page, report_dir / "index.html")
        files.append(report_dir / "index.html")
    clean = summary_module.json_ready(summary)
    write_text_atomic(json.dumps(clean, indent=2, allow_nan=False) + "\n", report_dir / "summary.json")
    files.append(report_dir / "summary.json")
    text = (
        text_module.format_summary(summary, report_dir) + studies.stopping_text(summary) + studies.sobol_text(summary)
    )
    if pointed:
        text += "\n\npointing requirements (docs/pointing.md):\n" + "\n".join(pointing.text_lines(pointed))
    if summary.get("rare_event"):
        text += rare_event.text(summary)
    return {
        "summary": clean,
        "requirements": clean["requirements"],
        "verdict": summary["verdict"],
        "passed": summary["passed"],
        "text": text,
        "report_dir": report_dir,
        "files": files,
    }


def fuel_thresholds(summary):
    """(value, label) of the limits that requirements put on propellant remaining."""
    return [
        (r["value"], r["requirement"]) for r in summary["requirements"] if r["metric"].startswith("fuel_remaining.")
    ]


def bounds_of(column, summary, scale=1.0):
    """(value, label) of each requirement bound on ``column``, in the column's unit: a
    ``<column>.<stat>`` requirement's and a pointing record's (its verdict's metric is the column)."""
    return [
        (scale * r["value"], f"required: {r['requirement']}")
        for r in summary["requirements"]
        if r["metric"] not in CAMPAIGN_METRICS
        and (split_metric(r["metric"])[0] if r.get("kind") != "pointing" else r["metric"]) == column
    ]


ARCSEC_PER_DEG = 3600.0
SCATTER_INPUTS = 3
MAX_SCATTER_POINTS = 5000  # more points only blacken the panel and cost memory at 100,000 runs
SCATTER_WORST = 50


def scatter_runs(values, tail, limit=MAX_SCATTER_POINTS, worst=SCATTER_WORST):
    """Indices of the runs a scatter panel draws: all of them up to ``limit``; beyond, ``limit``
    evenly spaced ones and the ``worst`` at the metric's bad end(s) (``tail``), in run order."""
    n = len(values)
    if n <= limit:
        return np.arange(n)
    picked = [np.linspace(0, n - 1, limit).round().astype(np.int64)]
    order = np.argsort(np.where(np.isfinite(values), values, np.nan), kind="stable")
    finite = order[np.isfinite(values[order])]
    if tail in ("upper", "both"):
        picked.append(finite[-worst:])
    if tail in ("lower", "both"):
        picked.append(finite[:worst])
    return np.unique(np.concatenate(picked))


def _modes_caption(campaign, summary, histories, left_out, unit):
    refex = summary["campaign"].get("refex")
    rate = campaign.history_rate_hz
    caption = (
        f"Total angle error θ_t to the mode's final attitude and norm of the measured rate |ω_m| [{unit}, {unit}/s], "
        "every run aligned at the start of each mode (from the runs table's time per mode). Gray bands: min-max "
        "and 1-99 % of the flown runs at each time since mode start, line: median; black: the nominal run 0. "
        f"Envelopes from per-bin histograms of {histories['rows']} history samples (80 bins per decade; axes "
        "from the data's range)."
    )
    for quantity, modes in left_out.items():
        if modes:
            listed = ", ".join(f"{name} ({per_run:.1f} per run)" for name, per_run in modes.items())
            caption += (
                f" Left out of the {'angle' if quantity == 'theta_t_deg' else 'rate'} row for too few samples "
                f"(history every {1 / rate:.4g} s): {listed}."
            )
    if refex:
        caption += " ReFEx: 000 Fig. 11 analogue."
    return caption


def render_figures(campaign, summary):
    """[(title, caption, png bytes, file stem)] of every figure the campaign has data for."""
    from refexmc.report import aggregate, entry_histories, family_figures, figures

    result = []
    plan = summary["outputs"]
    refex = summary["campaign"].get("refex")
    nominal_row = summary.get("nominal") or {}
    successful = campaign.successful
    panels, too_few = [], []
    for column in plan["requirement_columns"]:
        values = successful[column].to_numpy(dtype=float)
        values = values[np.isfinite(values)]
        if len(values) < 2:
            too_few.append(column)
            continue
        panels.append(
            {
                "column": column,
                "unit": plan["units"].get(column, ""),
                "values": values,
                "nominal": nominal_row.get(column),
                "bounds": bounds_of(column, summary),
            }
        )
    if panels or too_few:
        caption = (
            "Distribution of each requirement's metric over the successful flights (failed flights and errored "
            "runs have no value; they count as failing the requirement). Dashed red: the requirement's bound in "
            "the metric's own unit (marked at the edge when it lies far from the data); black: the nominal run 0."
        )
        if too_few:
            caption += f" Too few samples to draw (fewer than 2 successful flights with a value): {', '.join(too_few)}."
        if panels:
            result.append(
                ("The requirements' metrics", caption, figures.metric_distributions_figure(panels), "metrics")
            )
    summary["metric_figures"] = {p["column"]: "metrics" for p in panels}
    summary["metric_figures_too_few"] = too_few
    histories = aggregate.aggregate_histories(campaign)
    if entry_histories.is_entry(campaign):  # an entry's signals over time (issue 24)
        from refexmc.report import entry_figures

        result += entry_figures.figures_of(campaign, summary, bounds_of)
    if histories is not None:
        shown, left_out = aggregate.modes_with_samples(histories, len(campaign.ok))
        pointed = [r for r in summary["requirements"] if r.get("kind") == "pointing"]  # report.pointing
        arcsec = any(plan["units"].get(c) == "arcsec" for c in plan["requirement_columns"]) or any(
            r["unit"] == "arcsec" for r in pointed
        )
        unit, scale = ("arcsec", ARCSEC_PER_DEG) if arcsec else ("deg", 1.0)
        lines = []
        if arcsec:
            seen = set()
            for r in summary["requirements"]:
                column = split_metric(r["metric"])[0] if r["metric"] not in CAMPAIGN_METRICS else ""
                in_arcsec = (
                    r["unit"] == "arcsec" if r.get("kind") == "pointing" else plan["units"].get(column) == "arcsec"
                )
                if in_arcsec and r["value"] not in seen:
                    seen.add(r["value"])
                    lines.append((r["value"], f"{r['value']:g}″ required ({r['requirement']})"))
        png_bytes = figures.modes_figure(histories, shown, unit=unit, unit_scale=scale, lines=lines)
        if png_bytes is not None:
            title = "Angle and rate errors per mode" + (" (000 Fig. 11 analogue)" if refex else "")
            result.append((title, _modes_caption(campaign, summary, histories, left_out, unit), png_bytes, "modes"))
        summary["mode_panels"] = {
            "shown": {q: [histories["mode_names"][m] for m in modes] for q, modes in shown.items()},
            "left_out": left_out,
        }
    result += family_figures.figures_of(campaign, summary, bounds_of)  # translation, tank, wheels (issue 34)
    used = campaign.ok["fuel_used_kg"].to_numpy(dtype=float) if "fuel_used_kg" in campaign.ok else np.zeros(0)
    fuel = campaign.ok["fuel_remaining"].to_numpy(dtype=float) if "fuel_remaining" in campaign.ok else np.zeros(0)
    if np.isfinite(fuel).sum() >= 2 and (np.nan_to_num(used) > 0).any():
        start = "separation" if refex else "the start of the flight"
        result.append(
            (
                "Propellant remaining" + (" (000 Fig. 9 and 12 analogue)" if refex else ""),
                f"Left: propellant remaining over time since {start} (bands min-max and 1-99 % of the runs still "
                "flying, median line; black: the nominal run 0). Right: distribution at the end of each run. Dashed "
                "red: propellant requirements.",
                figures.propellant_figure(campaign, histories, fuel_thresholds(summary), f"time since {start} [s]"),
                "propellant",
            )
        )
    sets = summary["failure_sets"]
    if sets:
        result.append(
            (
                "Success and propellant per failure set",
                "Success rate (with its 95 % Clopper-Pearson interval when a set has several runs) and propellant "
                "remaining per set of failed thrusters.",
                figures.failure_sets_figure(sets),
                "failure_sets",
            )
        )
        thrusters = campaign.thruster_count
        if thrusters and all(s["size"] <= 2 for s in sets) and sum(s["size"] > 0 for s in sets) >= 2:
            show_paper = refex and thrusters == 8
            result.append(
                (
                    "Thruster failure matrix" + (" (000 Table 4 analogue)" if show_paper else ""),
                    "Single failures on the diagonal, pairs off it (symmetric): success and minimum propellant "
                    "remaining." + (" Framed cells: compensable according to 000 Table 4." if show_paper else ""),
                    figures.failure_matrix_figure(sets, thrusters, show_paper),
                    "failure_matrix",
                )
            )
    section = summary["sensitivity"]
    targets = [t for t in (section or {}).get("figure_targets", ()) if (section or {}).get(t)]
    if targets:
        result.append(
            (
                "What drives the failing and closest-to-failing requirements",
                "The dispersed inputs and discrete causes that explain most of the rank variance of each "
                "requirement metric that fails or is closest to failing: Spearman ρ of an input (bars), with the "
                "partial rank correlation (PRCC, diamonds) where the campaign has more runs than inputs + 2; "
                "hatched, a failed unit (the ρ of its indicator), a failure set or a choice input (√η², the "
                "correlation ratio of the metric's ranks). Gray band: |ρ| not significantly different from 0 at "
                "the 5 % level.",
                figures.sensitivity_figure(section, targets, plan["labels"]),
                "sensitivity",
            )
        )
        ok = campaign.ok
        scatter = []
        for row, target in enumerate(targets):
            y = ok[target].to_numpy(dtype=float)
            shown = scatter_runs(y, plan["tails"].get(target, "upper"))
            inputs = [entry for entry in section[target] if entry.get("kind", "input") == "input"]
            for entry in inputs[:SCATTER_INPUTS]:  # a discrete cause has no axis of values
                scatter.append(
                    {
                        "row": row,
                        "x": ok[entry["parameter"]].to_numpy(dtype=float)[shown],
                        "y": y[shown],
                        "x_label": entry["parameter"],
                        "y_label": target + (f" [{plan['units'][target]}]" if plan["units"].get(target) else ""),
                        "bounds": bounds_of(target, summary),
                        "rho": entry["rho"],
                    }
                )
        if scatter:  # none when every top entry is a discrete cause
            result.append(
                (
                    "Top inputs against the requirement metrics",
                    f"Each flown run's value of the {SCATTER_INPUTS} inputs with the largest |Spearman ρ| against the "
                    "metric (ρ over every flown run); dashed red: the requirement's bound."
                    + (
                        f" Of the {len(ok)} flown runs, {MAX_SCATTER_POINTS} evenly spaced in run-id order and the "
                        f"{SCATTER_WORST} worst of each metric are drawn."
                        if len(ok) > MAX_SCATTER_POINTS
                        else ""
                    ),
                    figures.scatter_figure(scatter),
                    "scatter",
                )
            )
    convergence = summary["convergence"]
    if convergence and len(convergence["n"]) >= 2:
        column = convergence.get("column")
        result.append(
            (
                "Convergence with the number of runs",
                "Statistics over the first n flown runs (run-id order): the success rate and"
                + (f" {column} (over the successful flights among them)" if column else " nothing else")
                + ". A statistic that still moves at the right edge needs more runs.",
                figures.convergence_figure(convergence, unit=plan["units"].get(column, "") if column else ""),
                "convergence",
            )
        )
    return result
