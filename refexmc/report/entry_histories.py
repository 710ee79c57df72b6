"""Envelopes of an entry campaign's histories (issue 24, docs/x38.md): the signals a GNC engineer
reviews through a re-entry, over the time since the entry interface (and altitude over speed).

The signals are named by the OUT's history columns (``ENTRY_SIGNALS``); a signal whose columns
the OUT lacks is left out, never drawn empty. Each envelope is :class:`aggregate.BinnedQuantiles`
(1, 50, 99 %, exact to one value bin) with the exact minimum and maximum per time bin beside it,
so the min-max band contains every flown run, the nominal run 0 included. Read batch by batch:
memory is fixed by the bins, not by the number of runs.
"""

import math

import numpy as np

from refexmc.report import data
from refexmc.report.aggregate import ENVELOPE_PERCENTS, BinnedQuantiles, statistics_min_max
from refexmc.report.data import present_columns

MAX_X_BINS = 400
LINEAR_VALUE_BINS = 400  # 0.25 % of the column's range (Parquet statistics) per value bin
ERROR_DECADES = (1e-5, 1e3)  # |tracking error| [deg] on log-spaced signed bins
ERROR_BINS_PER_DECADE = 40  # 5.9 % of the value
ENTRY_MISSION_KEY = "entry_flight"


def _bank_error(columns):
    return (columns["bank_deg"] - columns["bank_command_deg"] + 180.0) % 360.0 - 180.0


# name -> (history columns it needs, how it is computed, unit, label, x axis, signed error)
ENTRY_SIGNALS = {
    "alpha_deg": (("alpha_deg",), None, "deg", "angle of attack α", "t", False),
    "bank_deg": (("bank_deg",), None, "deg", "bank μ", "t", False),
    "alpha_error_deg": (
        ("alpha_deg", "alpha_command_deg"),
        lambda c: c["alpha_deg"] - c["alpha_command_deg"],
        "deg",
        "α − α_cmd",
        "t",
        True,
    ),
    "beta_deg": (("beta_deg",), None, "deg", "sideslip β (command 0)", "t", True),
    "bank_error_deg": (("bank_deg", "bank_command_deg"), _bank_error, "deg", "μ − μ_cmd", "t", True),
    "qbar_pa": (("qbar_pa",), None, "Pa", "dynamic pressure q̄", "t", False),
    "load_factor_g": (("load_factor_g",), None, "g", "load factor", "t", False),
    "heat_flux_w_m2": (("heat_flux_w_m2",), None, "W/m²", "stagnation heat flux", "t", False),
    "altitude_over_speed_m": (("altitude_m", "speed_m_s"), None, "m", "altitude over speed", "speed", False),
    "flap_left_deg": (("flap_left_deg",), None, "deg", "left body flap", "t", False),
    "flap_right_deg": (("flap_right_deg",), None, "deg", "right body flap", "t", False),
    "rudder_deg": (("rudder_deg",), None, "deg", "rudders", "t", False),
    "rcs_propellant_kg": (("rcs_propellant_kg",), None, "kg", "RCS propellant used", "t", False),
}
NOMINAL_COLUMNS = ("alpha_command_deg", "bank_command_deg", "speed_m_s", "altitude_m")


def is_entry(campaign):
    """Does the campaign fly an entry mission (``core.entry_flight``)?"""
    return ENTRY_MISSION_KEY in (campaign.resolved.get("mission") or {})


def signed_log_edges(low=ERROR_DECADES[0], high=ERROR_DECADES[1], per_decade=ERROR_BINS_PER_DECADE):
    """Value edges symmetric about 0, log-spaced in |value| from ``low`` to ``high``."""
    positive = np.geomspace(low, high, int(round(math.log10(high / low) * per_decade)) + 1)
    return np.concatenate([-positive[::-1], positive])


def linear_edges(low, high, bins=LINEAR_VALUE_BINS):
    if high <= low:
        pad = abs(low) * 1e-3 or 0.5
        low, high = low - pad, high + pad
    return np.linspace(low, high, bins + 1)


class Envelope:
    """Percentile envelope of one signal over x bins centred on multiples of ``dx`` (a history
    sampled every dx lands one sample per run in each bin, whatever its rounding): histogram
    quantiles and the exact min/max."""

    def __init__(self, bins, dx, edges):
        self.bins, self.dx = bins, float(dx)
        self.binned = BinnedQuantiles(1, bins, dx, edges)
        self.low = np.full(bins, np.inf)
        self.high = np.full(bins, -np.inf)

    def add(self, x, values):
        keep = np.isfinite(values) & np.isfinite(x)
        x, values = x[keep] + 0.5 * self.dx, values[keep]
        xbin = np.clip((np.maximum(x, 0.0) / self.dx).astype(np.int64), 0, self.bins - 1)  # as BinnedQuantiles
        np.minimum.at(self.low, xbin, values)
        np.maximum.at(self.high, xbin, values)
        self.binned.add(np.zeros(len(x), dtype=np.int64), x, values)

    def quantiles(self):
        """[x bin, ENVELOPE_PERCENTS]: min, 1 %, median, 99 %, max; NaN where a bin has no sample.
        The histogram's percentiles are held within the exact min and max."""
        q = self.binned.quantiles(ENVELOPE_PERCENTS)[0]
        empty = ~np.isfinite(self.low)
        low, high = np.where(empty, np.nan, self.low), np.where(empty, np.nan, self.high)
        q[:, 1:4] = np.clip(q[:, 1:4], low[:, None], high[:, None])
        q[:, 0], q[:, 4] = low, high
        return q

    def x(self):
        return np.arange(self.bins) * self.dx

    def bin_of(self, x):
        """The bin of each value of ``x``."""
        return np.clip((np.maximum(np.asarray(x) + 0.5 * self.dx, 0.0) / self.dx).astype(np.int64), 0, self.bins - 1)

    def samples(self):
        return int(self.binned.sample_counts().sum())


def aggregate_entry_histories(campaign):
    """Envelopes of the entry signals the OUT has, over the flown runs (status ok): see
    :func:`aggregate_signals`."""
    return aggregate_signals(campaign, ENTRY_SIGNALS, NOMINAL_COLUMNS)


def aggregate_signals(campaign, specs, nominal_columns=()):
    """Envelopes of the signals ``specs`` names ({name: spec}, as ``ENTRY_SIGNALS``) that the OUT
    has, over the flown runs (status ok); ``nominal_columns``: further columns of the nominal run kept.

    Returns None without histories or flown runs; else a dict: ``signals`` {name: (Envelope,
    quantiles)} for the signals with samples, ``units``/``labels`` of them,
    ``missing`` {name: [absent history columns]}, ``nominal`` (the nominal run's samples by
    column and signal name, or None), ``mode_names``, ``rows`` (samples read).
    """
    ok = campaign.ok
    if not campaign.history_parts or ok.empty:
        return None
    present = present_columns(campaign)
    wanted = {name: spec for name, spec in specs.items() if set(spec[0]) <= present}
    missing = {name: sorted(set(spec[0]) - present) for name, spec in specs.items() if name not in wanted}
    if not wanted or not {"run_id", "t_s", "mode"} <= present:
        return None
    plain = sorted({spec[0][0] for spec in wanted.values() if spec[1] is None and not spec[5]})
    ranges = {
        column: (low, high)
        for column, (low, high) in statistics_min_max(campaign.history_parts, plain + ["speed_m_s"]).items()
        if math.isfinite(low) and math.isfinite(high)
    }
    t_end = float(np.nanmax(ok["t_end_s"].to_numpy(dtype=float))) if "t_end_s" in ok else 0.0
    t_end = max(t_end, 1.0 / campaign.history_rate_hz)
    dt = max(1.0 / campaign.history_rate_hz, t_end / MAX_X_BINS)
    t_bins = int(t_end / dt) + 2
    top_speed = ranges.get("speed_m_s", (0.0, 0.0))[1]
    speed_dx = max(top_speed, 1.0) / MAX_X_BINS
    envelopes = {}
    for name, (columns, _, _, _, axis, signed) in wanted.items():
        column = columns[0]
        edges = linear_edges(*ranges[column]) if not signed and column in ranges else signed_log_edges()
        if axis == "speed":
            envelopes[name] = Envelope(MAX_X_BINS + 1, speed_dx, edges)
        else:
            envelopes[name] = Envelope(t_bins, dt, edges)
    run_ids = ok["run_id"].to_numpy(dtype=np.int64)
    nominal_id = campaign.nominal_run_id
    read = sorted({"run_id", "t_s", "mode"} | {c for spec in wanted.values() for c in spec[0]})
    read += [c for c in nominal_columns if c in present and c not in read]
    nominal_parts, rows = [], 0
    for batch in data.history_batches(campaign, read):
        rows += batch.num_rows
        rid = batch.column("run_id").to_numpy(zero_copy_only=False)
        position = np.minimum(np.searchsorted(run_ids, rid), len(run_ids) - 1)
        flown = run_ids[position] == rid
        if not flown.all():  # rows of errored runs: not in the statistics
            batch, rid = batch.filter(flown), rid[flown]
        columns = {c: batch.column(c).to_numpy(zero_copy_only=False) for c in read if c != "mode"}
        columns = {c: (v.astype(np.float64) if c != "run_id" else v) for c, v in columns.items()}
        t = columns["t_s"]
        for name, (needed, compute, _, _, axis, _) in wanted.items():
            values = compute(columns) if compute is not None else columns[needed[0]]
            envelopes[name].add(columns["speed_m_s"] if axis == "speed" else t, values)
        if nominal_id is not None:
            mine = rid == nominal_id
            if mine.any():
                nominal_parts.append(
                    {
                        **{c: v[mine] for c, v in columns.items()},
                        "mode": data.mode_codes(batch.column("mode"), campaign.modes)[mine].astype(np.int64),
                        **{
                            name: (spec[1](columns) if spec[1] is not None else columns[spec[0][0]])[mine]
                            for name, spec in wanted.items()
                        },
                    }
                )
    nominal = None
    if nominal_parts:
        nominal = {key: np.concatenate([p[key] for p in nominal_parts]) for key in nominal_parts[0]}
        order = np.argsort(nominal["t_s"], kind="stable")
        nominal = {key: value[order] for key, value in nominal.items()}
    signals = {name: (e, e.quantiles()) for name, e in envelopes.items() if e.samples()}
    return {
        "signals": signals,
        "units": {name: specs[name][2] for name in signals},
        "labels": {name: specs[name][3] for name in signals},
        "missing": missing,
        "nominal": nominal,
        "mode_names": list(campaign.modes),
        "rows": rows,
    }


def blocked_flap(campaign):
    """The blocked body flap as the OUT declares it (the mission's ``entry_flight.blocked_flap``,
    else the vehicle file's ``surfaces.body_flaps.blocked``), or None: a dict with ``flap``,
    ``deflection_deg`` (nominal), ``known_to_flight_software``, ``dispersed`` (the campaign's
    dispersion of the deflection, or None) and ``drawn`` (min, max over the runs table), ``source``."""
    mission = (campaign.resolved.get("mission") or {}).get(ENTRY_MISSION_KEY) or {}
    spec, source = mission.get("blocked_flap"), "mission entry_flight.blocked_flap"
    if not spec:
        surfaces = (campaign.resolved.get("vehicle") or {}).get("surfaces") or {}
        spec, source = (surfaces.get("body_flaps") or {}).get("blocked"), "vehicle surfaces.body_flaps.blocked"
    if not spec:
        return None
    path = "entry_flight.blocked_flap.deflection_deg"
    dispersion = (campaign.resolved.get("dispersions") or {}).get(path)
    column = f"p.{path}"
    drawn = None
    if column in campaign.runs:
        values = campaign.runs[column].to_numpy(dtype=float)
        values = values[np.isfinite(values)]
        if len(values):
            drawn = (float(values.min()), float(values.max()))
    return {
        "flap": str(spec.get("flap")),
        "deflection_deg": float(spec.get("deflection_deg")),
        "known_to_flight_software": bool(spec.get("known_to_flight_software", True)),
        "dispersed": dispersion,
        "drawn": drawn,
        "source": source,
    }


def blocked_flap_text(flap):
    """The blocked flap in words: which, where (fixed or dispersed, the range drawn), known or not."""
    if flap is None:
        return ""
    dispersion = flap["dispersed"]
    if dispersion:
        where = f"dispersed ({dispersion.get('dist')}"
        parameters = ", ".join(
            f"{k} {v:g}" for k, v in dispersion.items() if k != "dist" and isinstance(v, (int, float))
        )
        where += f" {parameters}" if parameters else ""
        where += ")"
        if flap["drawn"] is not None:
            where += f", drawn {flap['drawn'][0]:.4g}-{flap['drawn'][1]:.4g}°"
        where += f", nominal {flap['deflection_deg']:g}°"
    else:
        where = f"fixed at {flap['deflection_deg']:g}°"
    known = "known to the flight software" if flap["known_to_flight_software"] else "unknown to the flight software"
    return f"{flap['flap']} body flap blocked, {where}, {known}"
