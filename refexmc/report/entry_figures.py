"""The figures of an entry campaign's report (issue 24, docs/x38.md), from
``entry_histories.aggregate_entry_histories``: rows of panels, each the min-max and 1-99 % bands
of the flown runs with their median and the nominal run 0, drawn with ``figures``' envelope.

- ``tracking``: α and bank μ against their commands, the tracking errors α − α_cmd, β and μ − μ_cmd;
- ``loads``: dynamic pressure, load factor, stagnation heat flux, altitude over speed;
- ``surfaces``: body flaps, rudders and the RCS propellant used.
"""

import numpy as np
from matplotlib.figure import Figure

from refexmc.report import entry_histories, figures
from refexmc.report.figures import NOMINAL_COLOR, _bounds_on_axis, _envelope

COMMAND_COLOR = "tab:blue"
MODE_COLOR = "tab:green"

TRACKING = (("alpha_deg", "bank_deg"), ("alpha_error_deg", "beta_deg", "bank_error_deg"))
LOADS = (("qbar_pa", "load_factor_g"), ("heat_flux_w_m2", "altitude_over_speed_m"))
SURFACES = (("flap_left_deg", "flap_right_deg"), ("rudder_deg", "rcs_propellant_kg"))
COMMANDS = {"alpha_deg": "alpha_command_deg", "bank_deg": "bank_command_deg"}
ALTITUDE_OVER_SPEED = "altitude_over_speed_m"


def rows_with_data(aggregate, layout):
    """``layout`` less the panels the aggregate has no samples of (and rows left empty)."""
    rows = [[name for name in row if name in aggregate["signals"]] for row in layout]
    return [row for row in rows if row]


def _mode_changes(nominal, mode_names):
    """[(time, name of the mode entered)] of the nominal run."""
    if nominal is None or len(nominal["mode"]) < 2:
        return []
    mode = nominal["mode"]
    at = np.flatnonzero(np.diff(mode) != 0) + 1
    return [(float(nominal["t_s"][k]), mode_names[mode[k]] if 0 <= mode[k] < len(mode_names) else "?") for k in at]


SYMLOG_SPREAD = 20.0  # largest |value| above this many times the typical 1-99 % |value|: symlog axis


def _symlog_threshold(q):
    """The linear range of a symlog axis for a signal whose largest |value| (transients) lies
    ``SYMLOG_SPREAD`` times above its typical 1-99 % band (the median over time of the band's
    larger |end|), rounded down to a decade; None when a linear axis shows it."""
    ok = np.isfinite(q[:, 2])
    if not ok.any():
        return None
    typical = float(np.median(np.maximum(np.abs(q[ok, 1]), np.abs(q[ok, 3]))))
    largest = float(np.max(np.abs(q[ok][:, [0, 4]])))
    if typical <= 0.0 or largest <= SYMLOG_SPREAD * typical:
        return None
    return 10.0 ** np.floor(np.log10(typical))


def _panel(ax, aggregate, name, bounds, changes, sequence):
    """One signal's bands, the nominal run (and its command), run 0's mode changes, the bounds."""
    envelope, q = aggregate["signals"][name]
    x = envelope.x()
    nominal = aggregate["nominal"]
    unit = aggregate["units"][name]
    if name == ALTITUDE_OVER_SPEED:
        x = x / 1000.0
        _envelope(ax, x, q / 1000.0, label_runs=True)
        if nominal is not None:
            ax.plot(
                nominal["speed_m_s"] / 1000.0,
                nominal[name] / 1000.0,
                color=NOMINAL_COLOR,
                lw=1.0,
                label="nominal (run 0)",
            )
        ax.set_xlabel("Earth-relative speed [km/s]", fontsize=8)
        ax.set_ylabel("altitude [km]", fontsize=8)
        ax.invert_xaxis()  # the entry flies from right to left, as time runs
    else:
        _envelope(ax, x, q)
        if nominal is not None:
            ax.plot(nominal["t_s"], nominal[name], color=NOMINAL_COLOR, lw=1.0, label="nominal (run 0)")
            command = COMMANDS.get(name)
            if command in nominal:
                ax.plot(nominal["t_s"], nominal[command], color=COMMAND_COLOR, lw=1.0, ls="--", label="command (run 0)")
        for k, (t, _) in enumerate(changes):
            ax.axvline(t, color=MODE_COLOR, lw=0.8, ls=":", label=f"run 0: {sequence}" if k == 0 else None)
        ok = np.isfinite(q[:, 2])
        ax.set_xlim(0.0, float(x[ok].max() + 0.5 * envelope.dx) if ok.any() else 1.0)
        ax.set_xlabel(aggregate.get("x_label", "time since the entry interface [s]"), fontsize=8)
        ax.set_ylabel(f"{aggregate['labels'][name]} [{unit}]", fontsize=8)
        threshold = _symlog_threshold(q)
        positive = bool(np.isfinite(q[:, 0]).any() and np.nanmin(q[:, 0]) > 0.0)
        if name in aggregate.get("log_signals", ()) and positive:  # a distance falling by decades (a hop)
            ax.set_yscale("log")
        elif threshold is not None:  # transients far above the steady errors: both readable
            ax.set_yscale("symlog", linthresh=threshold, linscale=1.0)
        if bounds:
            finite = q[np.isfinite(q[:, 0])]
            _bounds_on_axis(ax, float(finite[:, 0].min()), float(finite[:, 4].max()), bounds, vertical=False)
    ax.set_title(aggregate.get("titles", {}).get(name, aggregate["labels"][name]), fontsize=9)
    ax.tick_params(labelsize=7)
    ax.grid(True, lw=0.3)
    ax.legend(fontsize=6.5)


def entry_figure(aggregate, layout, bounds=None):
    """One figure of rows of panels (``layout``: rows of ``ENTRY_SIGNALS`` names); ``bounds``
    {name: [(value, label)]} drawn as dashed red lines. None when no panel has data."""
    rows = rows_with_data(aggregate, layout)
    if not rows:
        return None
    bounds = bounds or {}
    changes = _mode_changes(aggregate["nominal"], aggregate["mode_names"])
    sequence = ""
    if changes:
        first = aggregate["mode_names"][aggregate["nominal"]["mode"][0]]
        sequence = "mode changes " + " → ".join([first] + [m for _, m in changes])
    figure = Figure(figsize=(13, 3.3 * len(rows) + 0.3), layout="constrained")
    subfigures = np.atleast_1d(figure.subfigures(len(rows), 1))
    for subfigure, row in zip(subfigures, rows, strict=True):
        axes = np.atleast_1d(subfigure.subplots(1, len(row)))
        for ax, name in zip(axes, row, strict=True):
            _panel(ax, aggregate, name, bounds.get(name, ()), changes, sequence)
    return figures.png(figure)


# requirement columns of the runs table -> the signal their bound is drawn on; symmetric: a bound
# on a largest |error| drawn at + and -
REQUIREMENT_SIGNALS = {
    "alpha_error_max_deg": ("alpha_error_deg", True),
    "beta_max_deg": ("beta_deg", True),
    "bank_error_max_deg": ("bank_error_deg", True),
    "peak_qbar_pa": ("qbar_pa", False),
    "peak_load_g": ("load_factor_g", False),
    "peak_heat_flux_w_m2": ("heat_flux_w_m2", False),
    "rcs_propellant_kg": ("rcs_propellant_kg", False),
}
FIGURES = (
    (
        "Attitude tracking: α, β and bank μ against their commands",
        "Top: angle of attack and bank of every flown run (bands){command} (the α command follows the α(Mach) "
        "schedule{flap_alpha}, the bank the bank(speed) schedule). Bottom: the tracking errors α − α_cmd, "
        "β (commanded 0) and μ − μ_cmd, transients included; the requirements on the largest errors count "
        "only after the transients (transient_s after the start and after each mode change), their bounds "
        "drawn at ±.",
        TRACKING,
        "entry_tracking",
    ),
    (
        "Dynamic pressure, load factor, heat flux and the altitude-velocity corridor",
        "Dynamic pressure, aerodynamic load factor |L + D + Y| / (m g0) and stagnation-point heat flux "
        "(Sutton-Graves) over time, and altitude over Earth-relative speed (right to left as the entry flies). "
        "Dashed red: requirements on the peaks in their own unit.",
        LOADS,
        "entry_loads",
    ),
    (
        "Surface deflections and RCS propellant",
        "Actual deflections of the body flaps (positive trailing edge down) and rudders, and the RCS "
        "propellant used (003 eq. 5) over time.{flap_text} Dashed red: the propellant requirement.",
        SURFACES,
        "entry_surfaces",
    ),
)
BANDS_TEXT = (
    " Gray bands: min-max and 1-99 % of the {runs} flown runs still flying at each time (or speed), line: "
    "median{nominal}. Envelopes from {rows} history "
    "samples every {every:g} s ({bins} bins; min and max exact per bin, percentiles to 0.25 % of the "
    "signal's range, errors to 6 % of their value)."
)


def figures_of(campaign, summary, bounds_of):
    """[(title, caption, png bytes, file stem)] of an entry campaign's history figures; [] without
    histories. ``bounds_of(column, summary)``: [(value, label)] of the requirement bounds on a runs
    column. Sets ``summary["entry_panels"]``: the panels drawn and those left out."""
    aggregate = entry_histories.aggregate_entry_histories(campaign)
    if aggregate is None:
        return []
    flap = entry_histories.blocked_flap(campaign)
    if flap is not None:
        name = f"flap_{flap['flap']}_deg"
        if name in aggregate["signals"]:
            known = "known to" if flap["known_to_flight_software"] else "unknown to"
            aggregate["titles"] = {name: f"{aggregate['labels'][name]}: blocked, {known} the flight software"}
    bounds = {}
    for column, (signal, symmetric) in REQUIREMENT_SIGNALS.items():
        for value, label in bounds_of(column, summary):
            bounds.setdefault(signal, []).append((value, label))
            if symmetric:
                bounds[signal].append((-value, "_" + label))  # the - side, no second legend entry
    first = next(iter(aggregate["signals"].values()))[0]
    bands = BANDS_TEXT.format(
        runs=len(campaign.ok),
        rows=aggregate["rows"],
        every=1.0 / campaign.history_rate_hz,
        bins=first.bins,
        nominal="; black: the nominal run 0; dotted green: run 0's mode changes"
        if aggregate["nominal"] is not None
        else " (no nominal run 0 flown: no nominal line)",
    )
    result = []
    for title, caption, layout, stem in FIGURES:
        png_bytes = entry_figure(aggregate, layout, bounds)
        if png_bytes is None:
            continue
        text = caption.format(
            flap_alpha=", or with the flap blocked and known the α at which the flaps trim at it" if flap else "",
            command=" against the commands of the nominal run 0 (dashed blue)"
            if aggregate["nominal"] is not None
            else "",
            flap_text=f" The {entry_histories.blocked_flap_text(flap)}." if flap else "",
        )
        left_out = [n for row in layout for n in row if n not in aggregate["signals"]]
        if left_out:
            text += " Not drawn (the histories lack them): " + ", ".join(left_out) + "."
        result.append((title, text + bands, png_bytes, stem))
    summary["entry_panels"] = {
        "shown": [n for _, _, layout, _ in FIGURES for row in layout for n in row if n in aggregate["signals"]],
        "missing_columns": aggregate["missing"],
    }
    return result
