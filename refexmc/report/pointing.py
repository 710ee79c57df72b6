"""Verdicts of pointing requirements (config.pointing, docs/pointing.md) over a campaign's runs.

Each run's value is its runs column (computed in the flight at the control rate, core.pointing).
A run the requirement judges (``runs``: all, or failure_free: no failed thruster or wheel) that
did not fly, did not succeed or has no value counts against the requirement:

- temporal (the run's P_C time quantile) and ensemble (its largest error): a run is within when its
  value is at most the bound; the one-sided Clopper-Pearson lower bound (at ``confidence``) on
  the fraction of runs within must reach ``runs_fraction`` (temporal) or P_C (ensemble). With no
  run outside, n runs give (1 - confidence)^(1/n): the runs needed are
  ceil(ln(1 - confidence) / ln(threshold)) (1109 for 99.73 % at 95 %);
- mixed (the run's fraction of window time above the bound): the upper one-sided Student-t
  confidence bound on the mean fraction over runs (the runs are the independent samples, never
  the time samples) must be at most 1 - P_C; a run that did not fly counts as fraction 1.

The margin of a run is bound - value (mixed: 1 - P_C - fraction); the report lists the
distribution and the worst runs with the command that flies them again.
"""

import math

import numpy as np
import scipy.stats as sps

from refexmc.config import pointing as config_pointing
from refexmc.report import stats
from refexmc.report.data import rerun_command

WORST_RUNS = 5


def requirements_of(campaign):
    """The campaign's pointing requirements (from OUT/campaign.resolved.yaml), checked."""
    resolved = campaign.resolved
    listed = resolved.get("requirements") or []
    if not any(config_pointing.is_pointing(item) for item in listed):
        return []
    return config_pointing.parse(
        listed,
        resolved.get("mission") or {"modes": []},
        resolved.get("dispersions") or {},
        campaign.out / "campaign.resolved.yaml",
        campaign.resolved_lines,
    )


def runs_needed(threshold, confidence):
    """Runs with none outside for the Clopper-Pearson lower bound to reach ``threshold``."""
    return int(math.ceil(math.log(1.0 - confidence) / math.log(threshold) - 1e-12))


def judged_runs(campaign, req):
    """The runs table rows the requirement judges."""
    runs = campaign.runs
    if req.runs == "all":
        return runs
    mask = runs["failed_thrusters"].fillna("") == ""
    if "failed_wheels" in runs.columns:
        mask &= runs["failed_wheels"].fillna("") == ""
    return runs[mask]


def evaluate(req, campaign):
    """The verdict dict of one pointing requirement (the keys of report.requirements.evaluate's
    verdicts, and the pointing fields)."""
    runs = judged_runs(campaign, req)
    n = len(runs)
    flew = ((runs["status"] == "ok") & runs["success"].astype(bool)).to_numpy()
    values = runs[req.column].to_numpy(dtype=float) if req.column in runs.columns else np.full(n, math.nan)
    usable = flew & np.isfinite(values)
    not_judged = n - int(usable.sum())
    mixed = req.interpretation == "mixed"
    limit = (1.0 - req.p_c) if mixed else req.bound
    margins = np.where(usable, limit - np.where(usable, values, 0.0), -math.inf)
    verdict = {
        "requirement": req.text(),
        "source": "campaign",
        "metric": req.column,
        "op": "<=",
        "value": limit,  # in the column's unit (mixed: a fraction of the window's time)
        "kind": "pointing",
        "index": req.index,
        "error": req.error,
        "interpretation": req.interpretation,
        "p_c": req.p_c,
        "confidence": req.confidence,
        "window": config_pointing.describe_window(req.window),
        "runs": req.runs,
        "unit": req.unit,
        "runs_judged": n,
        "actual_successful_flights": None,
    }
    note = ""
    if mixed:
        fractions = np.where(usable, np.where(usable, values, 0.0), 1.0)
        mean = float(fractions.mean()) if n else math.nan
        if n >= 2:
            sd = float(fractions.std(ddof=1))
            upper = mean + float(sps.t.ppf(req.confidence, n - 1)) * sd / math.sqrt(n)
        else:
            upper = math.nan
        threshold = 1.0 - req.p_c
        covers = f"{n} runs ({req.runs}); upper {100 * req.confidence:g} % t bound on the mean over runs"
        if n >= 2 and sd == 0.0:  # no spread: the t bound would be the value itself, from any number of runs
            # distribution-free instead: each fraction is at most 1, so the mean is at most the share of
            # runs with any time above the bound, bounded by Clopper-Pearson (as ensemble, none above:
            # 1109 runs show 1 - P_C = 0.27 % at 95 %)
            above = int((fractions > 0.0).sum())
            upper = stats.clopper_pearson_upper(above, n, req.confidence)
            needed = runs_needed(req.p_c, req.confidence)
            verdict.update(runs_needed=needed)
            covers = (
                f"{n} runs ({req.runs}); every run the same fraction, no spread for a t bound: upper "
                f"{100 * req.confidence:g} % Clopper-Pearson bound on the share of runs with any time above "
                f"({above} of {n})"
            )
            if n < needed and above == 0:
                level = f"{100 * req.confidence:g} %"
                note = f"{n} runs without spread cannot show {threshold:g} at {level}: that needs {needed}"
        actual = upper
        passed = math.isfinite(upper) and upper <= threshold
        verdict.update(mean_fraction_above=mean, threshold=threshold)
        measure = f"mean fraction of window time above {req.bound:g} {req.unit}: {mean:.4g}"
    else:
        within = int((usable & (values <= req.bound)).sum())
        threshold = req.runs_fraction if req.interpretation == "temporal" else req.p_c
        actual = stats.clopper_pearson_lower(within, n, req.confidence)
        passed = math.isfinite(actual) and actual >= threshold
        needed = runs_needed(threshold, req.confidence)
        verdict.update(runs_within=within, threshold=threshold, runs_needed=needed)
        what = "P_C time quantile" if req.interpretation == "temporal" else "largest error in the window"
        measure = f"{within} of {n} runs have their {what} within {req.bound:g} {req.unit}"
        covers = (
            f"{n} runs ({req.runs}); {100 * req.confidence:g} % Clopper-Pearson lower bound on the fraction "
            f"within, against {threshold:g}"
        )
        if n < needed:
            level = f"{100 * req.confidence:g} %"
            note = f"{n} runs cannot show {threshold:g} at {level}: that needs {needed} with none outside"
    if not_judged:
        note = "; ".join(filter(None, [note, f"{not_judged} judged runs did not fly, fail or have no value: outside"]))
    finite = margins[np.isfinite(margins)]
    order = np.argsort(margins, kind="stable")[:WORST_RUNS]
    verdict.update(
        actual=actual if math.isfinite(actual) else None,
        passed=bool(passed),
        measure=measure,
        covers=covers,
        note=note,
        failing_count=int((margins < 0).sum()),
        failing_run_ids=[int(i) for i in runs["run_id"].to_numpy()[margins < 0][:20]],
        margin={
            "unit": "fraction" if mixed else req.unit,
            "min": float(finite.min()) if finite.size else None,
            "p1": float(np.percentile(finite, 1)) if finite.size else None,
            "p50": float(np.percentile(finite, 50)) if finite.size else None,
            "without_value": int(n - finite.size),
        },
        worst_runs=[
            {
                "run_id": int(runs["run_id"].iloc[k]),
                "value": float(values[k]) if usable[k] else None,
                "margin": float(margins[k]) if math.isfinite(margins[k]) else None,
                "command": rerun_command(campaign.out, runs["run_id"].iloc[k]),
            }
            for k in order
        ],
    )
    return verdict


def text_lines(verdicts):
    """The terminal lines of the pointing verdicts' margins and worst runs."""
    lines = []
    for v in verdicts:
        m = v["margin"]
        lines.append(f"{v['metric']}: {v['measure']}")
        if m["min"] is not None:
            lines.append(
                f"  margin ({m['unit']}): min {m['min']:.4g}, p1 {m['p1']:.4g}, median {m['p50']:.4g}"
                + (f"; {m['without_value']} runs without a value" if m["without_value"] else "")
            )
        shown = [f"{w['run_id']} ({'-' if w['value'] is None else format(w['value'], '.4g')})" for w in v["worst_runs"]]
        if shown:
            lines.append(f"  worst runs: {', '.join(shown)}; rerun one with `{v['worst_runs'][0]['command']}`")
    return [line for line in lines if line]


def html_section(verdicts):
    """An HTML section: per pointing requirement its measure, margin distribution and worst runs."""
    from html import escape

    if not verdicts:
        return ""
    parts = ["<h2>Pointing requirements</h2>", "<p>docs/pointing.md says how each verdict is computed.</p>"]
    for v in verdicts:
        m = v["margin"]
        parts.append(f"<h3><code>{escape(v['metric'])}</code>: {'PASS' if v['passed'] else 'FAIL'}</h3>")
        parts.append(f"<p>{escape(v['requirement'])}. {escape(v['measure'])}; {escape(v['covers'])}.</p>")
        if v["note"]:
            parts.append(f"<p>{escape(v['note'])}</p>")
        if m["min"] is not None:
            parts.append(
                f"<p>Margin ({escape(m['unit'])}): min {m['min']:.4g}, p1 {m['p1']:.4g}, median {m['p50']:.4g}.</p>"
            )
        rows = "".join(
            f"<tr><td>{w['run_id']}</td><td>{'-' if w['value'] is None else format(w['value'], '.4g')}</td>"
            f"<td><code>{escape(w['command'])}</code></td></tr>"
            for w in v["worst_runs"]
        )
        parts.append(f"<table><tr><th>worst run</th><th>value</th><th>fly it again</th></tr>{rows}</table>")
    return "\n".join(parts)
