"""Sobol' indices of a ``sampling: saltelli`` campaign (refexmc.campaign.saltelli): first-order
and total indices of each dispersed parameter for each metric, with bootstrap confidence
intervals, estimated by SALib (Saltelli et al. 2010 estimators, Jansen's for the total index).

A metric is analysed only where every run of the design has a value (a failed flight has none:
then the metric ``success``, 1 for a successful flight and 0 otherwise, says which parameters
drive the failures). The nominal run (run 0) is not part of the design.
"""

import numpy as np

CONFIDENCE = 0.95
RESAMPLES = 1000  # bootstrap resamples of the confidence intervals
DEFAULT_METRICS = ("success", "fuel_used_kg", "theta_t_handover_deg", "t_end_s")


def indices(groups, outputs, seed=0, resamples=RESAMPLES, confidence=CONFIDENCE):
    """{group: {first, first_conf, total, total_conf}} of ``outputs`` (one per design row, SALib's
    order) over ``groups`` [(name, uniforms)]; ``*_conf`` is the half-width of the bootstrap
    interval at ``confidence`` (SALib: normal approximation of the bootstrap distribution)."""
    from SALib.analyze import sobol

    from refexmc.campaign.saltelli import problem

    result = sobol.analyze(
        problem(list(groups)),
        np.asarray(outputs, dtype=float),
        calc_second_order=False,
        num_resamples=resamples,
        conf_level=confidence,
        seed=seed,
    )
    names = [name for name, _ in groups]
    return {
        name: {
            "first": float(result["S1"][k]),
            "first_conf": float(result["S1_conf"][k]),
            "total": float(result["ST"][k]),
            "total_conf": float(result["ST_conf"][k]),
        }
        for k, name in enumerate(names)
    }


def campaign_indices(resolved, runs, metrics=DEFAULT_METRICS, seed=0):
    """The Sobol' section of a saltelli campaign's report: per metric its indices (or why not).

    ``resolved``: the resolved campaign; ``runs``: its runs table (any order)."""
    from refexmc.campaign.saltelli import layout

    groups = layout(resolved)
    runs = runs.sort_values("run_id")
    offset = 1 if resolved.get("nominal_first", True) else 0
    design = runs[runs["run_id"] >= offset]
    ok = (design["status"] == "ok").to_numpy() & design["success"].fillna(False).to_numpy(dtype=bool)
    base = len(design) // (len(groups) + 2)  # the design's N: N (G + 2) rows (refexmc.campaign.saltelli)
    section = {"groups": [name for name, _ in groups], "runs": int(len(design)), "base_samples": base, "metrics": {}}
    for metric in metrics:
        if metric == "success":
            values = ok.astype(float)
        elif metric in design.columns:
            values = design[metric].to_numpy(dtype=float)
        else:
            continue
        missing = int(np.count_nonzero(~np.isfinite(values)))
        if missing:
            section["metrics"][metric] = {"skipped": f"{missing} runs without a value (failed or errored)"}
            continue
        if np.ptp(values) == 0.0:
            section["metrics"][metric] = {"skipped": "the same value in every run: no variance to apportion"}
            continue
        section["metrics"][metric] = {"indices": indices(groups, values, seed=seed)}
    return section


def ranking(metric_section):
    """Group names by total index, largest first."""
    table = metric_section["indices"]
    return sorted(table, key=lambda name: -table[name]["total"])


def text(section, top=8):
    """Terminal lines: per metric the parameters with the largest total indices."""
    groups, base = len(section["groups"]), section["base_samples"]
    lines = [
        f"Sobol' indices (Saltelli design over {groups} parameters: N ({groups} + 2) = {section['runs']} runs "
        f"with N = {base} base samples; 95 % bootstrap CI)"
    ]
    for metric, entry in section["metrics"].items():
        if "skipped" in entry:
            lines.append(f"  {metric}: not analysed ({entry['skipped']})")
            continue
        lines.append(f"  {metric}, largest total indices:")
        lines.append(f"    {'parameter':>42}  {'first ± 95 % CI':>15}  {'total ± 95 % CI':>15}")
        for name in ranking(entry)[:top]:
            s = entry["indices"][name]
            first, total = f"{s['first']:.3f} ± {s['first_conf']:.3f}", f"{s['total']:.3f} ± {s['total_conf']:.3f}"
            lines.append(f"    {name:>42}  {first:>15}  {total:>15}")
    return "\n".join(lines)


def figure(section, top=10):
    """Bar chart of first and total indices with their CIs, one panel per analysed metric; PNG bytes or None."""
    import io

    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    analysed = [(m, e) for m, e in section["metrics"].items() if "indices" in e]
    if not analysed:
        return None
    fig = Figure(figsize=(5.5 * len(analysed), 0.35 * top + 1.5), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(1, len(analysed), squeeze=False)[0]
    for ax, (metric, entry) in zip(axes, analysed, strict=True):
        names = ranking(entry)[:top][::-1]
        s = [entry["indices"][n] for n in names]
        y = np.arange(len(names))
        ax.barh(
            y + 0.2, [v["total"] for v in s], 0.4, xerr=[v["total_conf"] for v in s], label="total", color="#4c72b0"
        )
        ax.barh(
            y - 0.2, [v["first"] for v in s], 0.4, xerr=[v["first_conf"] for v in s], label="first", color="#dd8452"
        )
        ax.set_yticks(y, names, fontsize="small")
        ax.set_title(metric)
        ax.set_xlim(min(0.0, *(v["first"] - v["first_conf"] for v in s)), max(1.0, *(v["total"] for v in s)))
        ax.axvline(0.0, color="black", lw=0.5)
    axes[0].legend(fontsize="small")
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=100)
    return buffer.getvalue()
