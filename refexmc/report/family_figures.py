"""The figures of the quantities a vehicle family records over time besides the attitude (issue
34): a hop's distance to its target, speed and position (``trajectory: local``), a cold-gas
tank's pressure (``rcs.feed``), reaction wheels' momenta and motor torques. Each is drawn as the
entry figures are (``entry_figures.entry_figure``: min-max and 1-99 % bands of the flown runs,
median, the nominal run 0), with the requirement bounds on the runs column that judges it.

Signals are named by the OUT's history columns: a family records only its own columns
(docs/interface.md ``histories``), and a signal whose columns the OUT lacks is not drawn.
"""

import re

from refexmc.report import data, entry_figures, entry_histories

AXES = "xyz"
WHEEL_MOMENTUM = re.compile(r"^wheel_momentum_(\d+)_n_m_s$")
WHEELS_PER_ROW = 2

# name -> spec of entry_histories.ENTRY_SIGNALS: (columns, compute, unit, label, x axis, signed)
TRANSLATION_SIGNALS = {
    "position_error_m": (("position_error_m",), None, "m", "distance to the target", "t", False),
    "speed_m_s": (("speed_m_s",), None, "m/s", "speed", "t", False),
    **{f"position_{a}_m": ((f"position_{a}_m",), None, "m", f"position {a} (local frame)", "t", False) for a in AXES},
}
LOG_SIGNALS = ("position_error_m",)  # metres to centimetres: the bound readable on a log axis
TANK_SIGNALS = {"tank_pressure_pa": (("tank_pressure_pa",), None, "Pa", "tank pressure", "t", False)}
TRANSLATION_LAYOUT = (("position_error_m", "speed_m_s"), tuple(f"position_{a}_m" for a in AXES))
TANK_LAYOUT = (("tank_pressure_pa",),)

# requirement columns of the runs table -> the signal their bound is drawn on (the end value's
# bound drawn over the whole flight: where the run must be when it ends)
REQUIREMENT_SIGNALS = {
    "position_error_end_m": "position_error_m",
    "speed_end_m_s": "speed_m_s",
    "tank_pressure_end_pa": "tank_pressure_pa",
}
WHEEL_REQUIREMENTS = {  # symmetric: a bound on the largest |value| of any wheel, drawn at + and -
    "wheel_momentum_peak_n_m_s": "wheel_momentum",
    "wheel_momentum_end_n_m_s": "wheel_momentum",
    "wheel_torque_demand_peak_n_m": "wheel_torque",
}
BANDS_TEXT = (
    " Gray bands: min-max and 1-99 % of the {runs} flown runs still flying at each time, line: median{nominal}. "
    "Envelopes from {rows} history samples every {every:g} s (min and max exact per bin, percentiles to "
    "0.25 % of the signal's range)."
)


def wheel_signals(present):
    """The wheels' signals ({name: spec}) and layout (momenta rows, then torques rows, ``WHEELS_PER_ROW``
    panels a row: room for each panel's legend) of the columns ``present``."""
    wheels = sorted(int(m.group(1)) for m in map(WHEEL_MOMENTUM.match, present) if m)
    specs = {}
    for i in wheels:
        momentum, torque = f"wheel_momentum_{i}_n_m_s", f"wheel_torque_{i}_n_m"
        specs[momentum] = ((momentum,), None, "N m s", f"wheel {i} momentum I_w Ω", "t", False)
        specs[torque] = ((torque,), None, "N m", f"wheel {i} motor torque", "t", False)
    names = [f"wheel_momentum_{i}_n_m_s" for i in wheels] + [f"wheel_torque_{i}_n_m" for i in wheels]
    momenta_rows = -(-len(wheels) // WHEELS_PER_ROW)
    rows = [names[: len(wheels)][k * WHEELS_PER_ROW : (k + 1) * WHEELS_PER_ROW] for k in range(momenta_rows)]
    rows += [names[len(wheels) :][k * WHEELS_PER_ROW : (k + 1) * WHEELS_PER_ROW] for k in range(momenta_rows)]
    return specs, tuple(tuple(row) for row in rows)


def _figures(present):
    """[(title, caption, signals, layout, stem)] of the family figures the OUT's columns allow."""
    wheel_specs, wheel_layout = wheel_signals(present)
    figures = []
    if {"position_error_m", "speed_m_s"} <= present:
        figures.append(
            (
                "Distance to the target, speed and position",
                "Distance from the position to the target of the mode flown and speed (truth, local frame), "
                "and the position per axis of the local frame.{target} Dashed red: the requirements on the end "
                "values (where a run must be when it ends), drawn over the whole flight.",
                TRANSLATION_SIGNALS,
                TRANSLATION_LAYOUT,
                "translation",
            )
        )
    if "tank_pressure_pa" in present:
        figures.append(
            (
                "Tank pressure",
                "Pressure of the cold-gas tank over time (blow-down: it falls as gas leaves, and the thrust "
                "with it). Dashed red: the requirements on the pressure left at the end, where the campaign has one.",
                TANK_SIGNALS,
                TANK_LAYOUT,
                "tank",
            )
        )
    if wheel_specs:
        figures.append(
            (
                "Reaction wheel momenta and motor torques",
                "Each wheel's momentum relative to the body (I_w Ω, what its speed limit bounds) and its motor "
                "torque, held over each control period. Dashed red: requirements on the largest of any wheel, "
                "drawn at ±.",
                wheel_specs,
                wheel_layout,
                "wheels",
            )
        )
    return figures


def _bounds(summary, bounds_of, signals):
    bounds = {}
    for column, signal in REQUIREMENT_SIGNALS.items():
        for value, label in bounds_of(column, summary):
            bounds.setdefault(signal, []).append((value, label))
    for column, prefix in WHEEL_REQUIREMENTS.items():
        for value, label in bounds_of(column, summary):
            for name in (n for n in signals if n.startswith(prefix + "_")):  # each panel its own legend
                bounds.setdefault(name, []).append((value, label))
                bounds[name].append((-value, "_" + label))  # the - side: no second legend entry
    return bounds


def _target_text(campaign):
    local = (campaign.resolved.get("mission") or {}).get("local") or {}
    target = local.get("target_position_m")
    if not target:
        return ""
    return " The target of the mission: (" + ", ".join(f"{v:g}" for v in target) + ") m."


def figures_of(campaign, summary, bounds_of):
    """[(title, caption, png bytes, file stem)] of the family's history figures; [] without
    histories or without a family signal. ``bounds_of(column, summary)``: [(value, label)] of the
    requirement bounds on a runs column. Sets ``summary["family_panels"]``: the panels drawn."""
    if not campaign.history_parts or campaign.ok.empty:
        return []
    present = data.present_columns(campaign)
    result, shown = [], []
    for title, caption, specs, layout, stem in _figures(present):
        aggregate = entry_histories.aggregate_signals(campaign, specs)
        if aggregate is None or not aggregate["signals"]:
            continue
        aggregate["x_label"] = "time since the start of the flight [s]"
        aggregate["log_signals"] = LOG_SIGNALS
        png_bytes = entry_figures.entry_figure(aggregate, layout, _bounds(summary, bounds_of, aggregate["signals"]))
        if png_bytes is None:
            continue
        bands = BANDS_TEXT.format(
            runs=len(campaign.ok),
            rows=aggregate["rows"],
            every=1.0 / campaign.history_rate_hz,
            nominal="; black: the nominal run 0; dotted green: run 0's mode changes"
            if aggregate["nominal"] is not None
            else " (no nominal run 0 flown: no nominal line)",
        )
        result.append((title, caption.format(target=_target_text(campaign)) + bands, png_bytes, stem))
        shown += [n for row in layout for n in row if n in aggregate["signals"]]
    summary["family_panels"] = {"shown": shown}
    return result
