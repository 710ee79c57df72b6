"""The report's figures as PNG bytes (matplotlib's Agg renderer; no pyplot, no global state).

- ``metric_distributions``: a histogram per requirement metric with its bounds;
- ``modes``: theta_t and |omega_m| per mode with runs aligned at mode start (000 Fig. 11 for ReFEx);
- ``propellant``: propellant remaining over time and at the end (000 Fig. 9/12 for ReFEx);
- ``failure_sets`` / ``failure_matrix``: success and propellant per failed-thruster set, and the
  thruster-pair matrix of a failure sweep (000 Table 4 analogue);
- ``sensitivity``: Spearman and partial rank correlations of the dispersed parameters (tornado chart),
  and ``scatter``: the top inputs against each failing or closest-to-failing requirement metric;
- ``convergence``: key statistics against the number of runs.
"""

import io
import math

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.ticker import NullLocator

from refexmc.report.summary import PAPER_COMPENSABLE

DPI = 100
BAND_COLORS = ("#d9d9d9", "#a6a6a6")  # min-max, 1-99 %
MEDIAN_COLOR = "#595959"
NOMINAL_COLOR = "black"
TORNADO_BARS = 12
RELATIVE_SPREAD_FOR_REFERENCE = 1e3  # |value| / spread above which a histogram is drawn about a reference
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


ROW_LABELS = {"theta_t_deg": "total angle error θ_t", "omega_m_deg_s": "measured rate |ω_m|"}


def modes_figure(aggregate, modes_by_quantity, nominal_label="nominal (run 0)", unit="deg", unit_scale=1.0, lines=()):
    """Angle and rate errors per mode, runs aligned at each mode's start: one row per quantity with a
    panel for each mode in ``modes_by_quantity[quantity]`` (modes with enough samples of it), log
    axes from the data. ``unit``/``unit_scale``: deg (1) or arcsec (3600); ``lines``: (value in
    ``unit``, label) drawn on the angle row (requirements in that unit). None when no panel has data."""
    rows = [q for q in ("theta_t_deg", "omega_m_deg_s") if modes_by_quantity.get(q)]
    if not rows:
        return None
    names = aggregate["mode_names"]
    durations = np.asarray(aggregate["mode_durations"], dtype=float)
    nominal = aggregate["nominal"]
    figure = Figure(figsize=(13, 3.4 * len(rows) + 0.4), layout="constrained")
    subfigures = np.atleast_1d(figure.subfigures(len(rows), 1))
    for subfigure, quantity in zip(subfigures, rows, strict=True):
        modes = modes_by_quantity[quantity]
        binned, q = aggregate["modes"][quantity]
        q = q * unit_scale
        x = (np.arange(binned.time_bins) + 0.5) * binned.dt
        widths = [max(durations[m], 0.12 * durations[modes].max(), 1e-3) for m in modes]
        grid = subfigure.add_gridspec(1, len(modes), width_ratios=widths)
        first = None
        floor = binned.edges[0] * unit_scale
        top = np.nanmax(q[modes][:, :, 4]) if np.isfinite(q[modes][:, :, 4]).any() else floor * 10
        for c, m in enumerate(modes):
            ax = subfigure.add_subplot(grid[0, c], sharey=first)
            first = first or ax
            _envelope(ax, x, q[m], label_runs=(c == 0))
            if nominal is not None:
                mine = (nominal["mode"] == m) & np.isfinite(nominal[quantity])
                ax.plot(
                    nominal["tau"][mine],
                    unit_scale * nominal[quantity][mine],
                    color=NOMINAL_COLOR,
                    lw=1.0,
                    marker="." if mine.sum() < 20 else None,
                    label=nominal_label if c == 0 else None,
                )
            if quantity == "theta_t_deg":
                for value, text in lines:
                    ax.axhline(value, color="tab:red", ls="--", lw=1, label=text if c == 0 else None)
            ax.set_yscale("log")
            ax.yaxis.set_minor_locator(NullLocator())  # minor log ticks on a dozen panels: most of the figure's time
            ax.set_ylim(
                floor, max(top, *(v for v, _ in lines), floor * 10) * 1.5 if quantity == "theta_t_deg" else top * 1.5
            )
            ax.set_xlim(0, max(durations[m], binned.dt))
            ax.grid(True, which="major", lw=0.3)
            ax.set_title(names[m], fontsize=9)
            if c == 0:
                rate = "/s" if quantity == "omega_m_deg_s" else ""
                ax.set_ylabel(f"{ROW_LABELS[quantity]} [{unit}{rate}]", fontsize=8)
                if ax.get_legend_handles_labels()[0]:
                    ax.legend(fontsize=7, loc="lower left")
            else:
                ax.tick_params(labelleft=False)
            ax.tick_params(labelsize=7)
        subfigure.supxlabel("time since the start of each mode [s]", fontsize=8)
    return png(figure)


def _bounds_on_axis(ax, lows, highs, bounds, vertical=True, reach=3.0):
    """Draw each (value, label) bound as a dashed red line when it lies within ``reach`` data spans
    of the data; one further off the scale gets a legend entry with its value and direction
    instead of squeezing the data into a corner."""
    span = max(highs - lows, abs(highs) * 1e-9, 1e-300)
    for value, text in bounds:
        if lows - reach * span <= value <= highs + reach * span:
            if vertical:
                ax.axvline(value, color="tab:red", ls="--", lw=1.2, label=text)
            else:
                ax.axhline(value, color="tab:red", ls="--", lw=1.2, label=text)
        else:
            if vertical:
                arrow = "right" if value > highs else "left"
            else:
                arrow = "above" if value > highs else "below"
            ax.plot([], [], color="tab:red", ls=":", lw=1.2, label=f"{text} (off scale, {arrow})")


def _data_limits(values):
    low, high = float(np.min(values)), float(np.max(values))
    if high == low:
        pad = abs(low) * 1e-3 or 0.5
        return low - pad, high + pad
    return low, high


def metric_distributions_figure(panels):
    """Histogram per requirement metric over the successful flights, its bounds in the metric's own
    unit and the nominal run. ``panels``: dicts with column, unit, values, nominal (or None), bounds
    [(value, label)]. Ranges from the data; a bound far from the data is marked at the edge."""
    columns = min(3, len(panels))
    rows = -(-len(panels) // columns)
    figure = Figure(figsize=(4.3 * columns + 0.4, 3.1 * rows + 0.3), layout="constrained")
    axes = np.atleast_1d(figure.subplots(rows, columns)).ravel()
    for ax, panel in zip(axes, panels, strict=False):
        values = np.asarray(panel["values"], dtype=float)
        low, high = _data_limits(values)
        # values far from 0 against their spread (an entry angle of -5.0000026 +- 1e-6 deg) are drawn
        # as the difference to a round reference, which the axis label names
        reference = 0.0
        if high > low and abs(high) / (high - low) > RELATIVE_SPREAD_FOR_REFERENCE:
            reference = float(f"{np.median(values):.{int(math.ceil(math.log10(abs(high) / (high - low))))}g}")
        values, low, high = values - reference, low - reference, high - reference
        ax.hist(
            values,
            bins=min(60, max(8, int(math.sqrt(len(values))))),
            range=(low, high),
            color=BAND_COLORS[1],
            edgecolor="white",
            lw=0.3,
            label=f"{len(values)} successful flights",
        )
        if panel.get("nominal") is not None and math.isfinite(panel["nominal"]):
            ax.axvline(panel["nominal"] - reference, color=NOMINAL_COLOR, lw=1.2, label="nominal (run 0)")
        _bounds_on_axis(ax, low, high, [(value - reference, text) for value, text in panel["bounds"]])
        unit = f" [{panel['unit']}]" if panel["unit"] else ""
        name = panel["column"] if reference == 0.0 else f"{panel['column']} − ({reference:g})"
        ax.ticklabel_format(axis="x", useOffset=False)
        ax.set_xlabel(f"{name}{unit}", fontsize=8)
        ax.set_ylabel("runs", fontsize=8)
        ax.tick_params(labelsize=7)
        ax.grid(True, lw=0.3)
        ax.legend(fontsize=6.5)
    for ax in axes[len(panels) :]:
        figure.delaxes(ax)
    return png(figure)


def propellant_figure(campaign, aggregate, thresholds=(), time_label="time since the start of the flight [s]"):
    """Propellant remaining over time (envelope of the runs still flying, nominal) and at the end;
    ranges from the data, a requirement off the data's scale marked at the edge."""
    ok = campaign.ok
    fuel = 100 * ok["fuel_remaining"].to_numpy(dtype=float)
    fuel = fuel[np.isfinite(fuel)]
    with_history = aggregate is not None and np.isfinite(aggregate["propellant"][1][0][:, 2]).any()
    figure = Figure(figsize=(12, 4.2), layout="constrained")
    axes = figure.subplots(1, 2, width_ratios=[2, 1]) if with_history else [None, figure.subplots()]
    nominal_id = campaign.nominal_run_id
    bounds = [(100 * value, text) for value, text in thresholds]
    if with_history:
        ax = axes[0]
        binned, q = aggregate["propellant"]
        x = (np.arange(binned.time_bins) + 0.5) * binned.dt
        _envelope(ax, x, 100 * q[0])
        nominal = aggregate["nominal"]
        if nominal is not None:
            ax.plot(
                nominal["t_s"], 100 * nominal["fuel_remaining"], color=NOMINAL_COLOR, lw=1.0, label="nominal (run 0)"
            )
        low = float(np.nanmin(100 * q[0][:, 0]))
        _bounds_on_axis(ax, low, 100.0, bounds, vertical=False)
        ax.set_xlabel(time_label)
        ax.set_ylabel("propellant remaining [%]")
        ax.set_ylim(max(0.0, low - 0.05 * (100 - low)), 100.5)
        ax.grid(True, lw=0.3)
        ax.legend(fontsize=8, loc="lower left")
    ax = axes[1]
    low, high = _data_limits(fuel)
    ax.hist(
        fuel,
        bins=min(60, max(10, int(math.sqrt(len(fuel))))),
        range=(low, high),
        color=BAND_COLORS[1],
        edgecolor="white",
        lw=0.3,
        label=f"{len(fuel)} flown runs",
    )
    if nominal_id is not None:
        value = float(ok.loc[ok["run_id"] == nominal_id, "fuel_remaining"].iloc[0])
        if math.isfinite(value):
            ax.axvline(100 * value, color=NOMINAL_COLOR, lw=1.2, label=f"nominal {100 * value:.1f} %")
    _bounds_on_axis(ax, low, high, bounds)
    ax.set_xlabel("propellant remaining at the end [%]")
    ax.set_ylabel("runs")
    ax.grid(True, lw=0.3)
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


def sensitivity_figure(section, targets, labels=None):
    """Tornado charts per target output: Spearman ρ (bars) and PRCC (diamonds) of the inputs and
    discrete causes that explain most of its rank variance (a failed unit: the ρ of its indicator,
    hatched; a factor of more levels: √η², hatched, unsigned); the band of |ρ| not significant at 5 %."""
    from matplotlib.patches import Patch

    labels = labels or {}
    figure = Figure(figsize=(6.2 * len(targets), 0.32 * TORNADO_BARS + 1.8), layout="constrained")
    axes = np.atleast_1d(figure.subplots(1, len(targets)))
    critical = section.get("critical_abs_rho_95")
    for ax, output in zip(axes, targets, strict=True):
        rows = [r for r in section[output] if r.get("eta2") is not None][:TORNADO_BARS][::-1]  # ranked ones only
        rho = np.array([math.sqrt(r["eta2"]) if r.get("rho") is None else r["rho"] for r in rows])
        y = np.arange(len(rows))
        factor = [r.get("kind", "input") != "input" for r in rows]
        for k, (value, hatched) in enumerate(zip(rho, factor, strict=True)):
            colour = "tab:red" if value > 0 else "tab:blue"
            ax.barh(k, value, color="white" if hatched else colour, edgecolor=colour, hatch="///" if hatched else None)
        handles = [Patch(facecolor="tab:gray", label="Spearman ρ (input)")]
        if any(factor):
            hatched = {"facecolor": "white", "edgecolor": "tab:gray", "hatch": "///"}
            handles.append(Patch(**hatched, label="failure or choice (ρ or √η²)"))
        prcc = np.array([np.nan if r.get("prcc") is None else r["prcc"] for r in rows])
        if np.isfinite(prcc).any():
            ax.plot(prcc, y, "D", color="black", ms=4, label="PRCC")
        names = [r["parameter"][2:] if r["parameter"].startswith("p.") else r["parameter"] for r in rows]
        ax.set_yticks(y, names, fontsize=7)
        if critical is not None and math.isfinite(critical):
            ax.axvspan(
                -critical, critical, color="#eeeeee", zorder=0, label=f"|ρ| < {critical:.2f}: not significant (5 %)"
            )
        ax.axvline(0, color="black", lw=0.6)
        ax.set_xlim(-1, 1)
        ax.set_xlabel(f"rank correlation with {output}", fontsize=8)
        ax.set_title(labels.get(output, output), fontsize=8, wrap=True)
        ax.grid(True, axis="x", lw=0.3)
        ax.legend(handles=[*ax.get_legend_handles_labels()[0], *handles], fontsize=7, loc="lower right")
    return png(figure)


def scatter_figure(panels):
    """Inputs against a metric: ``panels`` dicts with x (input values), y (metric), x_label, y_label,
    bounds [(value, label)] on the metric, rho. One row per metric, up to three inputs each."""
    rows = sorted({p["row"] for p in panels})
    columns = max(sum(p["row"] == r for p in panels) for r in rows)
    figure = Figure(figsize=(4.3 * columns + 0.4, 3.0 * len(rows) + 0.3), layout="constrained")
    axes = np.atleast_2d(figure.subplots(len(rows), columns, squeeze=False))
    used = set()
    for r, row in enumerate(rows):
        for c, panel in enumerate(p for p in panels if p["row"] == row):
            ax = axes[r, c]
            used.add((r, c))
            ax.plot(panel["x"], panel["y"], ".", color="tab:blue", ms=3, label=f"ok runs, ρ = {panel['rho']:+.2f}")
            y = np.asarray(panel["y"], dtype=float)
            y = y[np.isfinite(y)]
            _bounds_on_axis(ax, float(y.min()), float(y.max()), panel["bounds"], vertical=False)
            ax.set_xlabel(panel["x_label"], fontsize=7)
            ax.set_ylabel(panel["y_label"], fontsize=7)
            ax.tick_params(labelsize=7)
            ax.grid(True, lw=0.3)
            ax.legend(fontsize=6.5)
    for r in range(len(rows)):
        for c in range(columns):
            if (r, c) not in used:
                figure.delaxes(axes[r, c])
    return png(figure)


def convergence_figure(section, unit_scale=1.0, unit=""):
    """Success rate with its 95 % interval, and the statistics of one metric, against the number of runs."""
    n = np.asarray(section["n"])
    statistics = section.get("statistics") or {}
    figure = Figure(figsize=(12 if statistics else 6.5, 4), layout="constrained")
    axes = np.atleast_1d(figure.subplots(1, 2 if statistics else 1))
    left = axes[0]
    left.fill_between(
        n,
        100 * np.asarray(section["success_ci95_low"]),
        100 * np.asarray(section["success_ci95_high"]),
        color=BAND_COLORS[0],
        label="95 % Clopper-Pearson",
    )
    left.plot(n, 100 * np.asarray(section["success_rate"]), color="black", label="success rate")
    left.set_ylabel("success [%]")
    if statistics:
        right = axes[1]
        for entry in statistics.values():
            values = unit_scale * np.asarray(entry["values"], dtype=float)
            right.plot(n, values, label=entry["label"])
        right.set_ylabel(f"{section['column']}" + (f" [{unit}]" if unit else ""))
    for ax in axes:
        ax.set_xscale("log")
        ax.xaxis.set_minor_locator(NullLocator())
        ax.set_xlabel("runs")
        ax.grid(True, which="major", lw=0.3)
        ax.legend(fontsize=8)
    return png(figure)
