"""Sobol' indices of a ``sampling: saltelli`` campaign (refexmc.campaign.saltelli): first-order
and total indices of each dispersed parameter for each of the mission's metrics, with bootstrap
confidence intervals, estimated by SALib (Saltelli et al. 2010 estimators, Jansen's for the total
index).

**Metrics**: the campaign's ``sobol: metrics:`` (checked at ``validate``: ``success`` or a runs
column the mission produces), else ``success`` (1 for a successful flight, 0 otherwise) when some
flight failed, then the runs columns the requirements judge, or, without such requirements, the
mission's other outputs (``outputs.plan``). The nominal run (run 0) is not part of the design.

**What the design cannot support is flagged, never printed as a confident number**, each with
the base sample size N that would support it (the CIs shrink as 1 / sqrt(N)):

- an index whose CI half-width exceeds ``TARGET_HALF_WIDTH``: N ~ N (half-width / target)^2;
- an index outside [0, 1] by more than its CI, or a first-order index above the total index by
  more than both CIs: estimator noise, not a property of the model;
- a metric whose 2N rows of the matrices A and B all have one value while column-swap rows vary
  (a rare failure the A and B samples missed): the variance the indices divide by is 0, so
  "cannot estimate", with the N that puts about ``EVENTS_NEEDED`` such rows into A and B;
- a metric without a value in some run (a failed flight has none): "cannot estimate"; ``success``
  then says which parameters drive the failures.
"""

import math

import numpy as np

CONFIDENCE = 0.95
RESAMPLES = 1000  # bootstrap resamples of the confidence intervals
# an index known to +-0.1 tells a driver (total index 0.2 and up) from a bystander (below 0.05);
# wider intervals are flagged with the N that would narrow them to this
TARGET_HALF_WIDTH = 0.1
EVENTS_NEEDED = 10  # rows of A and B with a rare outcome before its variance is estimated at all
MAX_BASE_SAMPLES = 2**20


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


def power_of_two_at_least(n):
    return int(min(MAX_BASE_SAMPLES, 2 ** math.ceil(math.log2(max(2.0, n)))))


def base_samples_for(base, half_width, target=TARGET_HALF_WIDTH):
    """N (a power of 2) at which a CI of ``half_width`` at N base samples narrows to ``target``."""
    return power_of_two_at_least(base * (half_width / target) ** 2)


def index_flags(s):
    """What is wrong with one parameter's indices (``indices`` entry): a list of short texts."""
    flags = []
    for kind in ("first", "total"):
        value, conf = s[kind], s[f"{kind}_conf"]
        if not (math.isfinite(value) and math.isfinite(conf)):
            flags.append(f"{kind} not computable")
        elif value + conf < 0.0 or value - conf > 1.0:
            flags.append(f"{kind} outside [0, 1] beyond its CI")
        elif conf > TARGET_HALF_WIDTH:
            flags.append(f"{kind} CI wider than ±{TARGET_HALF_WIDTH:g}")
    if s["first"] - s["total"] > s["first_conf"] + s["total_conf"]:
        flags.append("first above total beyond their CIs")
    return flags


def design_rows(n_groups, base):
    """Row positions of the matrices A and B in SALib's order (per base sample: A, G swaps, B)."""
    start = np.arange(base) * (n_groups + 2)
    return np.concatenate([start, start + n_groups + 1])


def metric_entry(groups, values, base, seed=0):
    """The Sobol' entry of one metric (JSON-ready): its indices with flags, or why it cannot be
    estimated; either way ``base_samples_needed`` when the design is too small."""
    runs = len(values)
    finite = np.isfinite(values)
    if not finite.any():
        return {"cannot_estimate": "the mission produced no value of it in any run"}
    if not finite.all():
        missing = int(runs - finite.sum())
        return {
            "cannot_estimate": f"{missing} of {runs} runs have no value (failed flights or errored runs); "
            "'success' apportions what drives the failures"
        }
    if np.ptp(values) == 0.0:
        return {"cannot_estimate": f"the same value ({values[0]:.6g}) in every run: no variance to apportion"}
    ab = values[design_rows(len(groups), base)]
    if np.ptp(ab) == 0.0:
        differ = int(np.count_nonzero(values != ab[0]))
        needed = power_of_two_at_least(EVENTS_NEEDED * runs / (2.0 * differ))
        return {
            "cannot_estimate": f"the {len(ab)} runs of the matrices A and B all have the value {ab[0]:.6g} while "
            f"{differ} column-swap run{'s' if differ > 1 else ''} differ: the variance the indices divide by is 0 "
            f"(the A and B samples missed what the swaps hit); about N = {needed} base samples would put "
            f"~{EVENTS_NEEDED} such runs into A and B",
            "base_samples_needed": needed,
        }
    table = indices(groups, values, seed=seed)
    widest = 0.0
    for s in table.values():
        s["flags"] = index_flags(s)
        if s["flags"]:
            widest = max(widest, s["first_conf"], s["total_conf"])
    flagged = [name for name, s in table.items() if s["flags"]]
    entry = {"indices": table, "supported": not flagged}
    if flagged:
        needed = base_samples_for(base, widest) if math.isfinite(widest) and widest > 0 else None
        flags = [flag for s in table.values() for flag in s["flags"]]
        kinds = [
            (sum("wider" in f for f in flags), f"with a CI wider than ±{TARGET_HALF_WIDTH:g}, up to ±{widest:.2f}"),
            (sum("outside" in f for f in flags), "outside [0, 1] beyond its CI"),
            (sum("above total" in f for f in flags), "first-order above total beyond both CIs"),
            (sum("not computable" in f for f in flags), "not computable"),
        ]
        said = "; ".join(f"{count} {'index' if count == 1 else 'indices'} {what}" for count, what in kinds if count)
        entry["base_samples_needed"] = needed
        entry["flag"] = (
            f"N = {base} base samples cannot support the indices of {len(flagged)} of {len(table)} parameters "
            f"({said}: estimator noise, not the model)"
            + (f"; about N = {needed} would narrow the CIs to ±{TARGET_HALF_WIDTH:g}" if needed else "")
        )
    return entry


def default_metrics(plan, failed):
    """``success`` when some flight of the design failed, then the requirements' columns, or the
    mission's other outputs when no requirement judges a runs column."""
    columns = list(plan["requirement_columns"]) or list(plan["other_columns"])
    return (["success"] if failed else []) + columns


def campaign_indices(resolved, runs, plan, seed=0):
    """The Sobol' section of a saltelli campaign's report: per metric its indices (or why not).

    ``resolved``: the resolved campaign; ``runs``: its runs table (any order); ``plan``: the
    report's ``outputs.plan`` (the mission's requirement columns and other outputs)."""
    from refexmc.config.saltelli import layout, runs_needed

    groups = layout(resolved)
    runs = runs.sort_values("run_id")
    nominal = 1 if resolved.get("nominal_first", True) else 0
    design = runs[runs["run_id"] >= nominal]
    ok = (design["status"] == "ok").to_numpy() & design["success"].fillna(False).to_numpy(dtype=bool)
    base = len(design) // (len(groups) + 2)  # the design's N: N (G + 2) rows (refexmc.campaign.saltelli)
    chosen = (resolved.get("sobol") or {}).get("metrics")
    metrics = list(chosen) if chosen else default_metrics(plan, not ok.all())
    section = {
        "groups": [name for name, _ in groups],
        "runs": int(len(design)),
        "base_samples": base,
        "metrics_from": "the campaign's sobol: metrics"
        if chosen
        else "the requirements' columns"
        if plan["requirement_columns"]
        else "the mission's outputs",
        "target_half_width": TARGET_HALF_WIDTH,
        "metrics": {},
    }
    for metric in metrics:
        if metric == "success":
            values = ok.astype(float)
        elif metric == "pulses_total" and metric not in design:
            values = design[[c for c in design.columns if c.startswith("pulses_")]].to_numpy(float).sum(axis=1)
        else:
            values = design[metric].to_numpy(dtype=float)
        entry = metric_entry(groups, values, base, seed=seed)
        if entry.get("base_samples_needed"):
            entry["runs_needed"] = runs_needed(len(groups), entry["base_samples_needed"], bool(nominal))
        section["metrics"][metric] = entry
    return section


def ranking(metric_section):
    """Group names by total index, largest first."""
    table = metric_section["indices"]
    return sorted(table, key=lambda name: -table[name]["total"] if math.isfinite(table[name]["total"]) else 0.0)


def mark(s, kind):
    """``0.123 ± 0.045``, with ``?`` when the index is flagged (``index_flags``)."""
    value, conf = s[kind], s[f"{kind}_conf"]
    flagged = any(flag.startswith(kind) or flag.startswith("first above") for flag in s.get("flags", ()))
    return f"{value:.3f} ± {conf:.3f}" + (" ?" if flagged else "")


def needed_text(entry):
    if not entry.get("base_samples_needed"):
        return ""
    return f" (runs: {entry['runs_needed']})" if entry.get("runs_needed") else ""


def text(section, top=8):
    """Terminal lines: per metric the parameters with the largest total indices, flags said."""
    groups, base = len(section["groups"]), section["base_samples"]
    lines = [
        f"Sobol' indices (Saltelli design over {groups} parameters: N ({groups} + 2) = {section['runs']} runs "
        f"with N = {base} base samples; 95 % bootstrap CI; metrics: {section.get('metrics_from', '')})"
    ]
    flagged_any = False
    for metric, entry in section["metrics"].items():
        if "cannot_estimate" in entry:
            lines.append(f"  {metric}: cannot estimate: {entry['cannot_estimate']}{needed_text(entry)}")
            continue
        lines.append(f"  {metric}, largest total indices:")
        if entry.get("flag"):
            flagged_any = True
            lines.append(f"    ! {entry['flag']}{needed_text(entry)}")
        lines.append(f"    {'parameter':>42}  {'first ± 95 % CI':>17}  {'total ± 95 % CI':>17}")
        for name in ranking(entry)[:top]:
            s = entry["indices"][name]
            lines.append(f"    {name:>42}  {mark(s, 'first'):>17}  {mark(s, 'total'):>17}")
    if flagged_any:
        lines.append("  ?: not supported by this design (CI too wide, or outside [0, 1] beyond its CI)")
    return "\n".join(lines)


def figure(section, top=10, columns=3):
    """Bar chart of first and total indices with their CIs, one panel per estimated metric (a grid
    ``columns`` wide; flagged metrics say so in their title); PNG bytes or None."""
    import io

    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    analysed = [(m, e) for m, e in section["metrics"].items() if "indices" in e]
    if not analysed:
        return None
    width = min(columns, len(analysed))
    height = math.ceil(len(analysed) / width)
    fig = Figure(figsize=(4.3 * width, (0.35 * top + 1.5) * height), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(height, width, squeeze=False).ravel()
    for ax in axes[len(analysed) :]:
        ax.set_visible(False)
    for ax, (metric, entry) in zip(axes, analysed, strict=False):
        names = ranking(entry)[:top][::-1]
        s = [entry["indices"][n] for n in names]
        y = np.arange(len(names))
        ax.barh(
            y + 0.2, [v["total"] for v in s], 0.4, xerr=[v["total_conf"] for v in s], label="total", color="#4c72b0"
        )
        ax.barh(
            y - 0.2, [v["first"] for v in s], 0.4, xerr=[v["first_conf"] for v in s], label="first", color="#dd8452"
        )
        ax.set_yticks(y, names, fontsize="x-small")
        title = metric if entry.get("supported", True) else f"{metric}\nnot supported: N = {section['base_samples']}"
        ax.set_title(title, fontsize="small", color="black" if entry.get("supported", True) else "#b00000")
        low = min(0.0, *(v["first"] - v["first_conf"] for v in s))
        ax.set_xlim(max(low, -1.0), min(max(1.0, *(v["total"] for v in s)), 2.0))
        ax.axvline(0.0, color="black", lw=0.5)
        ax.axvline(1.0, color="grey", lw=0.5, ls=":")
    axes[0].legend(fontsize="small")
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=100)
    return buffer.getvalue()
