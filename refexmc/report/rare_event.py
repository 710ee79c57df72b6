"""The report of a rare-event study (campaign key ``rare_event``, docs/rare-events.md): the
probability of the event with its interval, the levels, and what drives the event.

The estimate is the study's record in ``manifest.json`` (written by ``refexmc run`` when the study
completes: refexmc.campaign.rare_event). What drives the event is read from the runs table: each
dispersed input's values in the flights that reached the event (every level's, each flight once)
against its values in level 0 (the prior, a random draw), sorted by the shift of the mean in prior
standard deviations, with the two-sample Kolmogorov-Smirnov distance beside it.
"""

import base64
import html as html_text
import io

import numpy as np

TOP_DRIVERS = 8
LISTED_FAILING = 10


def section(campaign):
    """summary.json's ``rare_event`` of a study output, or None for an ordinary campaign."""
    spec = campaign.resolved.get("rare_event")
    if spec is None:
        return None
    record = dict(campaign.manifest.get("rare_event") or {})
    table = campaign.study_runs if campaign.study_runs is not None else campaign.runs
    if not record:
        return {
            "event": spec["event"],
            "complete": False,
            "problem": "the study has not completed (no estimate in manifest.json): "
            "finish it with refexmc run --resume",
            "flights": int(len(table)),
        }
    margin = table["margin"].to_numpy(dtype=float)
    in_event = table[margin <= 0.0]
    errored = in_event[in_event["status"] == "error"]
    record.update(
        {
            "complete": True,
            "failing_flights": int(len(in_event)),
            "errored_in_event": int(len(errored)),
            "failing_runs": [
                {"run_id": int(row.run_id), "level": int(row.level), "margin": float(row.margin)}
                for row in in_event.sort_values(["margin", "run_id"]).head(LISTED_FAILING).itertuples()
            ],
            "drivers": drivers(table[table["level"] == 0], in_event, campaign.parameter_columns),
        }
    )
    return record


def drivers(prior, failing, columns):
    """Each input's shift from the prior (level 0) to the flights in the event, most shifted first."""
    from scipy import stats

    out = []
    if len(failing) < 2:
        return out
    for column in columns:
        before = prior[column].to_numpy(dtype=float)
        after = failing[column].to_numpy(dtype=float)
        before, after = before[np.isfinite(before)], after[np.isfinite(after)]
        spread = before.std(ddof=1) if len(before) > 1 else 0.0
        if len(after) < 2 or not spread > 0.0:
            continue
        out.append(
            {
                "parameter": column,
                "prior_mean": float(before.mean()),
                "prior_std": float(spread),
                "event_mean": float(after.mean()),
                "event_std": float(after.std(ddof=1)),
                "shift_sigma": float((after.mean() - before.mean()) / spread),
                "ks_distance": float(stats.ks_2samp(before, after).statistic),
            }
        )
    return sorted(out, key=lambda d: (-abs(d["shift_sigma"]), d["parameter"]))


def _probability_text(record):
    p = record["probability"]
    if p is None:
        return (
            f"no flight reached it in {len(record['levels'])} levels: no estimate. The last level's threshold, margin "
            f"{record['last_threshold']:.4g}, has P ~ {record['last_threshold_probability']:.2g}, above the event's "
            "(raise max_levels)"
        )
    lo, hi = record["ci95"]
    return f"P = {p:.3g}, 95 % interval [{lo:.3g}, {hi:.3g}], c.o.v. {record['cov']:.2f}"


def text(summary):
    """Terminal lines of the study."""
    record = summary.get("rare_event")
    if not record:
        return ""
    if not record.get("complete"):
        return f"\nrare event {record['event']}: {record['problem']}"
    lines = [
        f"\nrare event {record['event']} (subset simulation, {record['flights']} flights in "
        f"{len(record['levels'])} levels, stopped: {record['stopped']}):",
        f"  {_probability_text(record)}",
    ]
    if record["errored_in_event"]:
        lines.append(f"  {record['errored_in_event']} errored runs count as the event (no value of their own)")
    if record["drivers"]:
        top = ", ".join(f"{d['parameter']} {d['shift_sigma']:+.1f} sd" for d in record["drivers"][:3])
        lines.append(f"  most shifted inputs in the event: {top}")
    if record["failing_runs"]:
        ids = ", ".join(str(r["run_id"]) for r in record["failing_runs"][:5])
        lines.append(f"  flights in the event (refexmc rerun OUT RUN_ID): {ids}")
    return "\n".join(lines)


def figure(record, unit=""):
    """PNG: each level's margin threshold against the level, and P(margin <= threshold) on a log axis."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    levels = record["levels"]
    thresholds = [lv["threshold"] for lv in levels[1:]]
    cumulative, product = [], 1.0
    for lv in levels[:-1]:
        product *= lv["conditional_probability"]
        cumulative.append(product)
    fig = Figure(figsize=(9, 3.4))
    FigureCanvasAgg(fig)
    left, right = fig.subplots(1, 2)
    if thresholds:
        left.plot(range(1, len(levels)), thresholds, "o-", color="C0", label="level threshold b")
    left.axhline(0.0, color="red", ls="--", lw=1, label="the event: margin <= 0")
    left.set_xlabel("level")
    left.set_ylabel(f"margin threshold{f' [{unit}]' if unit else ''}")
    left.set_xticks(range(len(levels)))
    left.legend(fontsize=8)
    if thresholds:
        right.semilogy(thresholds, cumulative[: len(thresholds)], "o-", color="C0", label="P(margin <= b)")
    if record["probability"] is not None:
        lo, hi = record["ci95"]
        right.errorbar(
            [0.0],
            [record["probability"]],
            yerr=[[record["probability"] - lo], [hi - record["probability"]]],
            fmt="s",
            color="red",
            capsize=4,
            label="P(event), 95 % interval",
        )
    right.set_xlabel(f"margin threshold{f' [{unit}]' if unit else ''}")
    right.set_ylabel("probability")
    right.legend(fontsize=8)
    fig.tight_layout()
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=100)
    return buffer.getvalue()


def html(summary):
    """The HTML section of the study."""
    record = summary.get("rare_event")
    if not record:
        return ""
    e = html_text.escape
    parts = [f"<section id='rare-event'><h2>Rare event: {e(record['event'])}</h2>"]
    if not record.get("complete"):
        return parts[0] + f"<p>{e(record['problem'])}</p></section>"
    parts.append(
        f"<p><b>{e(_probability_text(record))}</b> from {record['flights']} flights in {len(record['levels'])} "
        f"levels (subset simulation, Au &amp; Beck 2001; per level {record['per_level']}, p0 {record['p0']}, "
        f"{e(record['proposal'])} proposals; stopped: {e(record['stopped'])}). Interval: {e(record['interval'])}. "
        "The campaign's requirements and statistics above are level 0's alone (a random draw); the later levels "
        "serve this estimate only (docs/rare-events.md).</p>"
    )
    if record["errored_in_event"]:
        parts.append(f"<p>{record['errored_in_event']} errored runs count as the event (no value of their own).</p>")
    encoded = base64.b64encode(figure(record)).decode("ascii")
    parts.append(
        f"<figure><img alt='levels' src='data:image/png;base64,{encoded}'><figcaption>Left: each level's margin "
        "threshold (the p0-quantile of the previous level's margins); right: the probability of reaching each "
        "threshold, and the event's probability with its interval at margin 0.</figcaption></figure>"
    )
    rows = "".join(_level_row(lv) for lv in record["levels"])
    parts.append(
        "<table><tr><th>level</th><th>threshold</th><th>conditional probability</th><th>chain correlation γ</th>"
        f"<th>flights</th><th>proposals accepted</th></tr>{rows}</table>"
    )
    if record["drivers"]:
        rows = "".join(
            f"<tr><td>{e(d['parameter'])}</td><td>{d['prior_mean']:.4g} ± {d['prior_std']:.3g}</td>"
            f"<td>{d['event_mean']:.4g} ± {d['event_std']:.3g}</td><td>{d['shift_sigma']:+.2f}</td>"
            f"<td>{d['ks_distance']:.2f}</td></tr>"
            for d in record["drivers"][:TOP_DRIVERS]
        )
        parts.append(
            f"<h3>What drives the event</h3><p>Inputs of the {record['failing_flights']} flights in the event against "
            "level 0 (the prior), most shifted first: mean ± sd, the shift of the mean in prior sd, and the "
            "Kolmogorov-Smirnov distance of the two distributions.</p><table><tr><th>input</th><th>prior</th>"
            f"<th>in the event</th><th>shift [sd]</th><th>KS</th></tr>{rows}</table>"
        )
    if record["failing_runs"]:
        items = ", ".join(
            f"{r['run_id']} (level {r['level']}, margin {r['margin']:.3g})" for r in record["failing_runs"]
        )
        parts.append(
            f"<p>Flights in the event, lowest margin first (<code>refexmc rerun OUT RUN_ID</code>): {items}</p>"
        )
    parts.append("</section>")
    return "".join(parts)


def _level_row(level):
    threshold = "-" if level["threshold"] is None else f"{level['threshold']:.4g}"
    accepted = "-" if level["accepted"] is None else f"{level['accepted']} of {level['proposals']}"
    return (
        f"<tr><td>{level['level']}</td><td>{threshold}</td><td>{level['conditional_probability']:.3g}</td>"
        f"<td>{level['gamma']:.2f}</td><td>{level['flights']}</td><td>{accepted}</td></tr>"
    )
