"""The report's figures as PNG bytes (matplotlib's Agg renderer; no pyplot, no global state).

- ``modes``: 000 Fig. 11 analogue, theta_t and |omega_m| per mode with runs aligned at mode start;
- ``propellant``: 000 Fig. 9/12 analogue, propellant remaining over time and at the end;
- ``failure_sets`` / ``failure_matrix``: success and propellant per failed-thruster set, and the
  thruster-pair matrix of a failure sweep (000 Table 4 analogue);
- ``sensitivity``: Spearman rank correlations of the dispersed parameters (tornado chart);
- ``convergence``: key statistics against the number of runs.
"""

import io
import math

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from refexmc.report.aggregate import plotted_modes
from refexmc.report.summary import PAPER_COMPENSABLE

DPI = 100
BAND_COLORS = ("#d9d9d9", "#a6a6a6")  # min-max, 1-99 %
MEDIAN_COLOR = "#595959"
NOMINAL_COLOR = "black"
TORNADO_BARS = 12
MAX_FAILURE_SETS = 60


def png(figure):
    """Render a Figure to PNG bytes."""
    FigureCanvasAgg(figure)
    buffer = io.BytesIO()
    figure.savefig(buffer, format="png", dpi=DPI)
    return buffer.getvalue()


def _envelope(ax, x, q, label_runs=True):
    """Draw percentile bands q[:, (0, 1, 50, 99, 100)] against x."""
    ok = np.isfinite(q[:, 2])
    x, q = x[ok], q[ok]
    if not len(x):
        return
    ax.fill_between(
        x, q[:, 0], q[:, 4], color=BAND_COLORS[0], lw=0, step="mid", label="min-max" if label_runs else None
    )
    ax.fill_between(x, q[:, 1], q[:, 3], color=BAND_COLORS[1], lw=0, step="mid", label="1-99 %" if label_runs else None)
    ax.plot(x, q[:, 2], color=MEDIAN_COLOR, lw=0.8, label="median" if label_runs else None)


def modes_figure(aggregate, nominal_label="nominal"):
    """000 Fig. 11 analogue: per controlled mode (``plotted_modes``), runs aligned at the mode's start.

    None when no mode has a sample.
    """
    modes = plotted_modes(aggregate)
    if not modes:
        return None
    names = aggregate["mode_names"]
    durations = np.asarray(aggregate["mode_durations"], dtype=float)
    widths = [max(durations[m], 0.08 * durations.max(), 1e-3) for m in modes]
    figure = Figure(figsize=(13, 6.5), layout="constrained")
    grid = figure.add_gridspec(2, len(modes), width_ratios=widths)
    nominal = aggregate["nominal"]
    rows = (("theta_t_deg", "total angle error θ_t [deg]"), ("omega_m_deg_s", "measured rate |ω_m| [deg/s]"))
    for r, (quantity, ylabel) in enumerate(rows):
        binned, q = aggregate["modes"][quantity]
        x = (np.arange(binned.time_bins) + 0.5) * binned.dt
        first = None
        for c, m in enumerate(modes):
            ax = figure.add_subplot(grid[r, c], sharey=first)
            first = first or ax
            _envelope(ax, x, q[m], label_runs=(c == 0))
            if nominal is not None:
                mine = nominal["mode"] == m
                ax.plot(
                    nominal["tau"][mine],
                    nominal[quantity][mine],
                    color=NOMINAL_COLOR,
                    lw=1.0,
                    label=nominal_label if c == 0 else None,
                )
            ax.set_yscale("log")
            ax.set_xlim(0, max(durations[m], binned.dt))
            ax.grid(True, which="major", lw=0.3)
            if r == 0:
                ax.set_title(names[m])
            if r == 1:
                ax.set_xlabel("s since mode start", fontsize=8)
            if c == 0:
                ax.set_ylabel(ylabel)
                if r == 0 and ax.get_legend_handles_labels()[0]:
                    ax.legend(fontsize=7, loc="lower left")
            else:
                ax.tick_params(labelleft=False)
            ax.tick_params(labelsize=7)
    return png(figure)


def propellant_figure(campaign, aggregate, thresholds=()):
    """000 Fig. 9/12 analogue: propellant remaining over time (envelope, nominal) and at the end."""
    ok = campaign.ok
    figure = Figure(figsize=(12, 4.2), layout="constrained")
    axes = figure.subplots(1, 2, width_ratios=[2, 1]) if aggregate is not None else [None, figure.subplots()]
    nominal_id = campaign.nominal_run_id
    if aggregate is not None:
        ax = axes[0]
        binned, q = aggregate["propellant"]
        x = (np.arange(binned.time_bins) + 0.5) * binned.dt
        _envelope(ax, x, 100 * q[0])
        nominal = aggregate["nominal"]
        if nominal is not None:
            ax.plot(nominal["t_s"], 100 * nominal["fuel_remaining"], color=NOMINAL_COLOR, lw=1.0, label="nominal")
        for value, text in thresholds:
            ax.axhline(100 * value, color="tab:red", ls="--", lw=1, label=text)
        ax.set_xlabel("time since separation [s]")
        ax.set_ylabel("propellant remaining [%]")
        ax.set_ylim(0, 100)
        ax.grid(True, lw=0.3)
        ax.legend(fontsize=8, loc="lower left")
    ax = axes[1]
    fuel = 100 * ok["fuel_remaining"].to_numpy(dtype=float)
    fuel = fuel[np.isfinite(fuel)]
    if len(fuel):
        ax.hist(fuel, bins=min(60, max(10, int(math.sqrt(len(fuel))))), color=BAND_COLORS[1], edgecolor="white", lw=0.3)
    if nominal_id is not None:
        value = float(ok.loc[ok["run_id"] == nominal_id, "fuel_remaining"].iloc[0])
        ax.axvline(100 * value, color=NOMINAL_COLOR, lw=1.2, label=f"nominal {100 * value:.1f} %")
    for value, text in thresholds:
        ax.axvline(100 * value, color="tab:red", ls="--", lw=1, label=text)
    ax.set_xlabel("propellant remaining at the end [%]")
    ax.set_ylabel("runs")
    ax.grid(True, lw=0.3)
    if ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize=8)
    return png(figure)


def failure_sets_figure(sets):
    """Success rate (with 95 % interval) and propellant per failed-thruster set."""
    sets = sets[:MAX_FAILURE_SETS]
    labels = [f"[{s['failed_thrusters']}]" if s["failed_thrusters"] else "none" for s in sets]
    x = np.arange(len(sets))
    figure = Figure(figsize=(max(6, 0.3 * len(sets) + 2), 5.5), layout="constrained")
    top, bottom = figure.subplots(2, 1, sharex=True)
    rate = np.array([s["success_rate"] for s in sets])
    low = np.array([s["success_rate_ci95"][0] for s in sets])
    high = np.array([s["success_rate_ci95"][1] for s in sets])
    colors = ["tab:green" if r == 1 else ("tab:red" if r == 0 else "tab:orange") for r in rate]
    top.bar(x, 100 * rate, color=colors)
    if any(s["runs"] > 1 for s in sets):
        top.errorbar(x, 100 * rate, yerr=[100 * (rate - low), 100 * (high - rate)], fmt="none", ecolor="black", lw=0.8)
    top.set_ylabel("success [%]")
    top.set_ylim(0, 105)
    top.grid(True, axis="y", lw=0.3)
    bottom.plot(x, [100 * s["fuel_remaining_median"] for s in sets], "o", color="tab:blue", ms=4, label="median")
    bottom.plot(x, [100 * s["fuel_remaining_min"] for s in sets], "v", color="tab:red", ms=4, label="min")
    bottom.set_ylabel("propellant remaining [%]")
    bottom.set_xticks(x, labels, rotation=90, fontsize=7)
    bottom.set_xlabel("failed thrusters")
    bottom.grid(True, lw=0.3)
    bottom.legend(fontsize=8)
    return png(figure)


def failure_matrix_figure(sets, thrusters, show_paper=False):
    """Thruster-pair matrix of single (diagonal) and double failures: success and min propellant."""
    rate = np.full((thrusters, thrusters), np.nan)
    text = [["" for _ in range(thrusters)] for _ in range(thrusters)]
    for s in sets:
        ids = [int(t) for t in s["failed_thrusters"].split(",") if t]
        if not 1 <= len(ids) <= 2 or max(ids) > thrusters:
            continue
        i, j = ids[0] - 1, ids[-1] - 1
        fuel = s["fuel_remaining_min"]
        label = (f"{s['successes']}/{s['runs']}" if s["runs"] > 1 else ("ok" if s["successes"] else "fail")) + (
            f"\n{100 * fuel:.0f} %" if math.isfinite(fuel) else ""
        )
        for a, b in ((i, j), (j, i)):
            rate[a, b] = s["success_rate"]
            text[a][b] = label
    figure = Figure(figsize=(7.2, 6.4), layout="constrained")
    ax = figure.subplots()
    image = ax.imshow(np.ma.masked_invalid(rate), cmap="RdYlGn", vmin=0, vmax=1)
    for a in range(thrusters):
        for b in range(thrusters):
            if text[a][b]:
                ax.text(b, a, text[a][b], ha="center", va="center", fontsize=7)
            if show_paper and tuple(sorted({a + 1, b + 1})) in PAPER_COMPENSABLE:
                ax.add_patch(_square(a, b))
    ticks = np.arange(thrusters)
    ax.set_xticks(ticks, [str(t + 1) for t in ticks])
    ax.set_yticks(ticks, [str(t + 1) for t in ticks])
    ax.set_xlabel("failed thruster")
    ax.set_ylabel("failed thruster")
    title = "diagonal: single failure; off-diagonal: pair. Cell: success, min propellant"
    if show_paper:
        title += "\nblack frame: compensable per 000 Table 4"
    ax.set_title(title, fontsize=9)
    figure.colorbar(image, ax=ax, label="success rate", shrink=0.8)
    return png(figure)


def _square(row, column):
    from matplotlib.patches import Rectangle

    return Rectangle((column - 0.5, row - 0.5), 1, 1, fill=False, edgecolor="black", lw=2)


def sensitivity_figure(section, labels):
    """Tornado charts: the parameters with the largest |Spearman rho| for each output."""
    outputs = [o for o in labels if section.get(o)]
    figure = Figure(figsize=(6.5 * len(outputs), 0.32 * TORNADO_BARS + 1.6), layout="constrained")
    axes = np.atleast_1d(figure.subplots(1, len(outputs)))
    critical = section.get("critical_abs_rho_95")
    for ax, output in zip(axes, outputs, strict=True):
        rows = section[output][:TORNADO_BARS][::-1]
        rho = np.array([r["rho"] for r in rows])
        y = np.arange(len(rows))
        ax.barh(y, rho, color=["tab:red" if v > 0 else "tab:blue" for v in rho])
        ax.set_yticks(y, [r["parameter"][2:] for r in rows], fontsize=7)
        if critical is not None and math.isfinite(critical):
            ax.axvspan(
                -critical, critical, color="#eeeeee", zorder=0, label=f"|ρ| < {critical:.2f}: not significant (5 %)"
            )
            ax.legend(fontsize=7, loc="lower right")
        ax.axvline(0, color="black", lw=0.6)
        ax.set_xlim(-1, 1)
        ax.set_xlabel(f"Spearman ρ with {labels[output]}", fontsize=8)
        ax.grid(True, axis="x", lw=0.3)
    return png(figure)


def convergence_figure(section):
    """Success rate with its 95 % interval, and propellant statistics, against the number of runs."""
    n = np.asarray(section["n"])
    figure = Figure(figsize=(12, 4), layout="constrained")
    left, right = figure.subplots(1, 2)
    left.fill_between(
        n,
        100 * np.asarray(section["success_ci95_low"]),
        100 * np.asarray(section["success_ci95_high"]),
        color=BAND_COLORS[0],
        label="95 % Clopper-Pearson",
    )
    left.plot(n, 100 * np.asarray(section["success_rate"]), color="black", label="success rate")
    left.set_ylabel("success [%]")
    names = {
        "fuel_remaining.mean": "mean",
        "fuel_remaining.p1": "1st percentile",
        "fuel_remaining.mean_minus_3sd": "mean - 3 sd",
        "fuel_remaining.tol_lower": "tolerance bound (99.865 %/95 %)",
        "fuel_remaining.min": "min",
    }
    for key, label in names.items():
        values = np.asarray(section[key], dtype=float)
        right.plot(n, 100 * values, label=label)
    right.set_ylabel("propellant remaining [%]")
    for ax in (left, right):
        ax.set_xscale("log")
        ax.set_xlabel("runs")
        ax.grid(True, which="both", lw=0.3)
        ax.legend(fontsize=8)
    return png(figure)
