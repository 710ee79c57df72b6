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

from refexmc.campaign.storage import write_text_atomic
from refexmc.report import data, studies
from refexmc.report import summary as summary_module
from refexmc.report import text as text_module
from refexmc.report.requirements import evaluate, overall_verdict, parse_requirement

SENSITIVITY_LABELS = {
    "fuel_used_kg": "propellant used (fuel_used_kg)",
    "theta_t_handover_deg": "angle error at hand-over (theta_t_handover_deg)",
}


def load_requirements(campaign, require=()):
    """Requirements of the campaign file (with file and line) and of ``require``, parsed and checked."""
    columns = list(campaign.runs.columns)
    resolved = campaign.out / "campaign.resolved.yaml"
    listed = campaign.resolved.get("requirements") or []
    parsed = []
    for i, text in enumerate(listed):
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
    summary = summary_module.build(campaign)
    verdicts = [evaluate(r, campaign, summary["metrics"]) for r in requirements]
    summary["requirements"] = verdicts
    summary["verdict"], summary["passed"], summary["banner"] = overall_verdict(summary["completeness"], verdicts)
    if studies.stopping(campaign):  # flown with --until-decided: how many runs, why it stopped
        summary["until_decided"] = studies.stopping(campaign)
    sobol_indices = studies.sobol_section(campaign)  # sampling saltelli: Sobol' indices
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

        page = html_module.page(summary, [(t, c, b) for t, c, b, _ in figures], SENSITIVITY_LABELS)
        page = studies.insert_section(page, studies.stopping_html(summary), "<h2>Requirements</h2>")
        page = studies.insert_section(page, studies.sobol_html(summary), "</body>")
        write_text_atomic(page, report_dir / "index.html")
        files.append(report_dir / "index.html")
    clean = summary_module.json_ready(summary)
    write_text_atomic(json.dumps(clean, indent=2, allow_nan=False) + "\n", report_dir / "summary.json")
    files.append(report_dir / "summary.json")
    text = (
        text_module.format_summary(summary, report_dir) + studies.stopping_text(summary) + studies.sobol_text(summary)
    )
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
    """(value, label) of the lower limits that requirements put on propellant remaining."""
    out = []
    for r in summary["requirements"]:
        if r["metric"].startswith("fuel_remaining.") and r["op"] in (">=", ">"):
            out.append((r["value"], r["requirement"]))
    return out


def render_figures(campaign, summary):
    """[(title, caption, png bytes, file stem)] of every figure the campaign has data for."""
    from refexmc.report import aggregate, figures

    result = []
    histories = aggregate.aggregate_histories(campaign)
    nominal = "nominal (run 0, black)" if campaign.nominal_run_id is not None else "no nominal run"
    modes_png = figures.modes_figure(histories) if histories is not None else None
    if modes_png is not None:
        result.append(
            (
                "Angle and rate errors per mode (000 Fig. 11 analogue)",
                "Total angle error θ_t to the mode's final attitude and norm of the measured rate |ω_m|, every "
                "run aligned at the start of each mode (from the runs table's time per mode). Gray bands: min-max "
                f"and 1-99 % of the ok runs at each time since mode start, line: median; {nominal}. Envelopes are "
                f"read from per-bin histograms of {histories['rows']} history samples (80 bins per decade).",
                modes_png,
                "modes",
            )
        )
    result.append(
        (
            "Propellant remaining (000 Fig. 9 and 12 analogue)",
            "Left: propellant remaining over time since separation (bands min-max and 1-99 % of the runs still "
            f"flying, median line; {nominal}). Right: distribution at the end of each run. Dashed red: "
            "propellant requirements.",
            figures.propellant_figure(campaign, histories, fuel_thresholds(summary)),
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
            vehicle = (campaign.resolved.get("vehicle") or {}).get("name")
            show_paper = vehicle == "refex" and thrusters == 8
            result.append(
                (
                    "Thruster failure matrix (000 Table 4 analogue)",
                    "Single failures on the diagonal, pairs off it (symmetric): success and minimum propellant "
                    "remaining." + (" Framed cells: compensable according to 000 Table 4." if show_paper else ""),
                    figures.failure_matrix_figure(sets, thrusters, show_paper),
                    "failure_matrix",
                )
            )
    section = summary["sensitivity"]
    if section and any(section.get(k) for k in SENSITIVITY_LABELS):
        result.append(
            (
                "Sensitivity (Spearman rank correlation)",
                "Dispersed parameters with the largest |Spearman ρ| against propellant used and against the "
                "angle error at hand-over. Gray band: |ρ| not significantly different from 0 at the 5 % level.",
                figures.sensitivity_figure(section, SENSITIVITY_LABELS),
                "sensitivity",
            )
        )
    if summary["convergence"] and len(summary["convergence"]["n"]) >= 2:
        result.append(
            (
                "Convergence with the number of runs",
                "Statistics over the first n ok runs (run-id order). A statistic that still moves at the right edge "
                "needs more runs.",
                figures.convergence_figure(summary["convergence"]),
                "convergence",
            )
        )
    return result
