"""The requirement grammar of campaign files and ``--require``: ``'METRIC OP VALUE'``.

Example: ``fuel_remaining.min >= 0.20``.

METRIC is either a campaign-level metric (``CAMPAIGN_METRICS``) or ``<column>.<stat>``:

- ``<column>``: a numeric column of the ``runs`` table (``fuel_remaining``, ``fuel_used_kg``,
  ``t_end_s``, ``t_<mode>_s``, ``attitude_error_end_deg``, ``modes_completed``, ``pulses_<k>``,
  ``p.<path>``; with the orbit trajectory ``ORBIT_COLUMNS``, with a mission's pointing window
  ``POINTING_COLUMNS``, with reaction wheels ``WHEEL_COLUMNS``), or the derived ``pulses_total``
  (sum of the thrusters' pulse counts);
- ``<stat>``, judged by the report over every stored run: a failed flight or an errored run
  counts as failing the requirement (docs/report.md says how for each statistic):
  ``count min max mean median std`` (std with ddof 1); ``mean_minus_3sd mean_plus_3sd``;
  ``three_sigma`` 3 std, the half-width of the 3-sigma dispersion (a source's "3-sigma uncertainty");
  ``p<q>`` the q-th percentile, 0 <= q <= 100 (``p0.135 p1 p50 p99 p99.865``; numpy's linear
  interpolation); ``tol_lower tol_upper`` the one-sided normal tolerance bounds, 99.865 % coverage
  at 95 % confidence (the confidence bound of the 3-sigma value, assuming normality);
  ``p<q>_lower95 p<q>_upper95`` distribution-free 95 % confidence bounds on the q-th percentile
  (order statistics; NaN when the campaign has too few runs for one).

OP is one of ``>= <= > < ==``; VALUE a number. A metric that is not computable (NaN: no runs,
too few runs for a bound) fails its requirement. Unknown metrics are bad input (ConfigError):
``load_campaign`` checks a campaign file's ``requirements`` against the columns its runs table
will have (:func:`runs_metric_columns`), so that a misspelt metric is refused before any run is
flown, and so is a metric on a column the table has but the vehicle and mission never fill
(:func:`unproduced_columns`: ``attitude_error_end_deg`` of a hop); ``refexmc report`` checks them
again against the stored table, with ``--require``.
Evaluating them is the report's job (``refexmc.report.requirements.evaluate``).
"""

import difflib
import math
import operator
import re
from dataclasses import dataclass

from refexmc.config.errors import ConfigError
from refexmc.config.schema import DEFAULT_TRAJECTORY, MODE_KINDS

CAMPAIGN_METRICS = {
    "runs": "runs in the runs table (ok and errored)",
    "ok_count": "runs with status ok (flown)",
    "error_count": "runs with status error (they count as failing every other requirement)",
    "error_rate": "error_count / runs",
    "success_count": "flown runs that succeeded",
    "failure_count": "flown runs that did not succeed",
    "success_rate": "success_count / runs (an errored run counts as unsuccessful)",
    "success_rate_lower95": "one-sided 95 % Clopper-Pearson lower bound of the success probability",
    "success_rate_upper95": "one-sided 95 % Clopper-Pearson upper bound of the success probability",
    "failure_rate_upper95": "1 - success_rate_lower95: the failure probability bound",
}

BASIC_STATS = ("count", "min", "max", "mean", "median", "std", "three_sigma", "mean_minus_3sd", "mean_plus_3sd")
BOUND_STATS = ("tol_lower", "tol_upper")
# statistics of the moments (and tolerance bounds on them): a failed or errored run stored with the
# runs sends them to the failing end (docs/report.md), so one such run decides them
MOMENT_STATS = ("mean", "std", "three_sigma", "mean_minus_3sd", "mean_plus_3sd", "tol_lower", "tol_upper")
PERCENTILE_STATS = ("p0.135", "p1", "p5", "p50", "p95", "p99", "p99.865")
NAMED_STATS = BASIC_STATS + BOUND_STATS
SUGGESTED_STATS = NAMED_STATS + PERCENTILE_STATS + ("p0.135_lower95", "p99.865_upper95")
DERIVED_COLUMNS = ("pulses_total",)
NOT_METRIC_COLUMNS = ("run_id", "seed")

OPERATORS = {">=": operator.ge, "<=": operator.le, ">": operator.gt, "<": operator.lt, "==": operator.eq}

_REQUIREMENT = re.compile(r"^\s*(?P<metric>[^\s<>=!]+)\s*(?P<op>[<>=!]+)\s*(?P<value>\S+)\s*$")
_PERCENTILE_TAIL = re.compile(r"\.(p\d+(?:\.\d+)?(?:_lower95|_upper95)?)$")
_NAMED_TAIL = re.compile(r"\.([a-z_0-9]+)$")


@dataclass(frozen=True)
class Requirement:
    text: str
    metric: str
    op: str
    value: float
    source: str  # "campaign" (OUT/campaign.resolved.yaml) or "--require"


def split_metric(metric):
    """``'fuel_remaining.p0.135'`` -> ``('fuel_remaining', 'p0.135')``; a campaign metric -> (metric, None)."""
    if metric in CAMPAIGN_METRICS:
        return metric, None
    match = _PERCENTILE_TAIL.search(metric) or _NAMED_TAIL.search(metric)
    if not match:
        return None, None
    return metric[: match.start()], match.group(1)


def valid_stat(stat):
    if stat in NAMED_STATS:
        return True
    try:
        parse_percentile_stat(stat)
    except ValueError:
        return False
    return True


def derived_columns(columns):
    """The :data:`DERIVED_COLUMNS` a runs table of ``columns`` has: ``pulses_total`` where thrusters
    count pulses (``pulses_<i>``: not a wheel vehicle's, nor an entry's)."""
    return ["pulses_total"] if any(c.startswith("pulses_") and c[7:].isdigit() for c in columns) else []


def check_metric(metric, columns, file=None, line=None, path=(), absent=None):
    """ConfigError (with did-you-mean) unless ``metric`` names a metric of a campaign with ``columns``;
    ``absent``: {column: why} of the columns the campaign does not produce (:func:`unproduced_columns`)."""
    columns = [c for c in columns if c not in NOT_METRIC_COLUMNS]
    columns += derived_columns(columns)
    column, stat = split_metric(metric)
    if absent and column in absent:
        raise not_produced(f"metric '{metric}'", column, absent, columns, file=file, line=line, path=path)
    if column is not None and (stat is None or (column in columns and valid_stat(stat))):
        return
    if column in columns:
        guess = difflib.get_close_matches(stat, SUGGESTED_STATS, n=1, cutoff=0.5)
        hint = f"did you mean '{column}.{guess[0]}'?" if guess else f"statistics: {', '.join(SUGGESTED_STATS)}, p<q>"
        raise ConfigError(f"unknown statistic '{stat}' in metric '{metric}'; {hint}", file=file, line=line, path=path)
    if stat is not None and valid_stat(stat):  # a misspelt column: match the column alone, not its '.max'
        guess = [f"{g}.{stat}" for g in difflib.get_close_matches(column, columns, n=1, cutoff=0.6)]
    else:
        candidates = list(CAMPAIGN_METRICS) + [f"{c}.{s}" for c in columns for s in ("min", "max", "mean", "median")]
        guess = difflib.get_close_matches(metric, candidates, n=1, cutoff=0.6)
    hint = f"did you mean '{guess[0]}'?" if guess else "expected a campaign metric or '<runs column>.<statistic>'"
    raise ConfigError(
        f"unknown metric '{metric}'; {hint} (campaign metrics: {', '.join(CAMPAIGN_METRICS)})",
        file=file,
        line=line,
        path=path,
    )


def parse_requirement(text, columns, source="--require", file=None, line=None, path=(), absent=None):
    """Parse ``'METRIC OP VALUE'`` against the runs ``columns`` (``absent``: as :func:`check_metric`);
    ConfigError for bad input."""
    where = {"file": file, "line": line, "path": path}
    if not isinstance(text, str):
        raise ConfigError(f"expected a string 'METRIC OP VALUE', got {text!r}", **where)
    match = _REQUIREMENT.match(text)
    if not match:
        raise ConfigError(f"expected 'METRIC OP VALUE' (e.g. 'fuel_remaining.min >= 0.2'), got '{text}'", **where)
    metric, op, value_text = match.group("metric", "op", "value")
    if op not in OPERATORS:
        raise ConfigError(f"unknown operator '{op}' in '{text}'; expected one of {', '.join(OPERATORS)}", **where)
    try:
        value = float(value_text)
    except ValueError:
        raise ConfigError(f"expected a number after '{op}', got '{value_text}' in '{text}'", **where) from None
    if not math.isfinite(value):
        raise ConfigError(f"expected a finite number after '{op}', got '{value_text}' in '{text}'", **where)
    check_metric(metric, columns, **where, absent=absent)
    return Requirement(text=text.strip(), metric=metric, op=op, value=value, source=source)


def parse_percentile_stat(stat):
    """``p<q>`` -> (q, None); ``p<q>_lower95`` / ``p<q>_upper95`` -> (q, "lower" / "upper"). ValueError else."""
    if not stat.startswith("p"):
        raise ValueError(stat)
    body, bound = stat[1:], None
    for side in ("lower", "upper"):
        suffix = f"_{side}95"
        if body.endswith(suffix):
            body, bound = body[: -len(suffix)], side
    if not body or not all(c.isdigit() or c == "." for c in body):
        raise ValueError(stat)
    percent = float(body)
    if not 0.0 <= percent <= 100.0:
        raise ValueError(stat)
    return percent, bound


def mode_time_columns(mode_names):
    """Runs-table columns of the time spent in each mode of the mission: ``t_<name>_s``."""
    return [f"t_{name.lower()}_s" for name in mode_names]


# runs of a vehicle with the orbit trajectory (004): the entry state at the entry interface
# (Earth-relative, geocentric), the engine's pointing error while it fires, its propellant
ORBIT_COLUMNS = (
    "entry_longitude_deg",
    "entry_latitude_deg",
    "entry_speed_m_s",
    "entry_flight_path_angle_deg",
    "entry_heading_deg",
    "entry_time_s",
    "burn_pointing_rms_deg",
    "burn_pointing_max_deg",
    "engine_propellant_used_kg",
)


# runs of a mission with a pointing window (``pointing_statistics_from_s``, 001 sec. 11): the true
# attitude against the reference, per body axis at the end, per axis RMS and the largest total
# angle over the window (arcsec)
POINTING_COLUMNS = (
    "pointing_end_x_arcsec",
    "pointing_end_y_arcsec",
    "pointing_end_z_arcsec",
    "pointing_rms_x_arcsec",
    "pointing_rms_y_arcsec",
    "pointing_rms_z_arcsec",
    "pointing_max_arcsec",
)
# runs of a vehicle with reaction wheels (001): the largest |I_w Omega| of any wheel over the flight
# and at its end, the largest motor torque asked for (before limits), the time some wheel was held
# at a limit, and the relative angular momentum residual (a check of the integration)
WHEEL_COLUMNS = (
    "wheel_momentum_peak_n_m_s",
    "wheel_momentum_end_n_m_s",
    "wheel_torque_demand_peak_n_m",
    "wheel_saturated_s",
    "angular_momentum_residual",
)


# runs of a vehicle with the local trajectory (002): where it ended against the target, the tank
# pressure left and the translation law's command changes per body axis (the first opening counts)
LOCAL_COLUMNS = (
    "position_error_end_m",
    "speed_end_m_s",
    "tank_pressure_end_pa",
    "switches_x",
    "switches_y",
    "switches_z",
)


# runs of an entry mission (issue 24, 003; simulate.EntryResult): RCS propellant, the largest
# alpha, sideslip and bank errors after the transients, peaks of q, load factor and Sutton-Graves
# heat flux, down- and cross-range, Mach and altitude at the end, the flight time and the time in
# each mode of the mode program (config.entry.MODE_NAMES: the report's t_<mode>_s)
ENTRY_COLUMNS = (
    "rcs_propellant_kg",
    "alpha_error_max_deg",
    "beta_max_deg",
    "bank_error_max_deg",
    "peak_qbar_pa",
    "peak_load_g",
    "peak_heat_flux_w_m2",
    "down_range_m",
    "cross_range_m",
    "terminal_mach",
    "terminal_altitude_m",
    "t_end_s",
    "t_rcs_s",
    "t_flaps_s",
    "t_flaps_rudders_s",
)


def column_options(vehicle, mission):
    """What decides a campaign's optional runs columns: ``trajectory`` (``orbit``: ORBIT_COLUMNS),
    ``pointing`` (the mission has a pointing window: POINTING_COLUMNS), ``wheels`` (the vehicle
    has reaction wheels: WHEEL_COLUMNS); keyword arguments of :func:`run_value_columns`."""
    return {
        "trajectory": vehicle.get("trajectory", DEFAULT_TRAJECTORY),
        "pointing": "pointing_statistics_from_s" in mission,
        "wheels": "wheels" in vehicle,
    }


def run_value_columns(mode_names, trajectory=DEFAULT_TRAJECTORY, pointing=False, wheels=False):
    """The float columns of a runs row, in table order (NaN in an errored run's row);
    ``trajectory``: the vehicle's trajectory model (``orbit`` adds ``ORBIT_COLUMNS``); ``pointing``,
    ``wheels``: add ``POINTING_COLUMNS``, ``WHEEL_COLUMNS`` (:func:`column_options`)."""
    columns = ["fuel_remaining", "fuel_used_kg", "t_end_s", *mode_time_columns(mode_names), "attitude_error_end_deg"]
    if trajectory == "orbit":
        columns += ORBIT_COLUMNS
    if trajectory == "local":
        columns += LOCAL_COLUMNS
    if pointing:
        columns += POINTING_COLUMNS
    if wheels:
        columns += WHEEL_COLUMNS
    return columns


def unproduced_columns(vehicle, mission):
    """{column: why} of the runs columns (:func:`run_value_columns`) that this vehicle and mission never
    fill: NaN in every run, so that no requirement, event, sweep metric or Sobol' index of them can be
    computed (the report leaves such columns out as outputs the mission does not produce).

    - ``attitude_error_end_deg``: the angle to the last mode's reference attitude as the program ends
      (core.flight); a last mode whose kind has no attitude reference (``schema.MODE_KINDS``:
      ``translate``, ``locked``, ``rate_damping``) gives none;
    - ``fuel_remaining``: the fraction of the RCS propellant left; a vehicle without an RCS has none;
    - ``fuel_used_kg``: 0 in every run of a vehicle without an RCS (its table keeps the column), a
      requirement on it always met.
    """
    absent = {}
    modes = mission.get("modes") or []
    if modes:
        last = modes[-1]
        if "attitude_reference" not in MODE_KINDS.get(last.get("kind"), {}).get("provides", ("attitude_reference",)):
            absent["attitude_error_end_deg"] = (
                f"the mission's last mode '{last['name']}' is a {last['kind']} mode, which has no attitude "
                "reference to measure the end attitude error against"
            )
    if "rcs" not in vehicle:
        absent["fuel_remaining"] = "the vehicle has no RCS, so no RCS propellant to take a fraction of"
        absent["fuel_used_kg"] = "the vehicle has no RCS, so it uses no propellant (0 kg in every run)"
    return absent


def columns_text(columns):
    """The runs columns for a message: outputs by name, the thrusters' pulse counts and the dispersed
    inputs folded (``pulses_1 .. pulses_8``, ``p.<path>``)."""
    pulses = [c for c in columns if c.startswith("pulses_") and c[7:].isdigit()]
    shown = [c for c in columns if c not in pulses and not c.startswith("p.") and c not in NOT_METRIC_COLUMNS]
    if pulses:
        shown.append(f"{pulses[0]} .. {pulses[-1]}" if len(pulses) > 1 else pulses[0])
    if any(c.startswith("p.") for c in columns):
        shown.append("p.<dispersed path>")
    return ", ".join(shown)


def not_produced(what, column, absent, columns, file=None, line=None, path=()):
    """The ConfigError for ``what`` (e.g. "metric 'attitude_error_end_deg.max'") on a runs column the
    campaign does not produce (``absent``: :func:`unproduced_columns`); ``columns``: those it produces."""
    produced = [c for c in columns if c not in absent]
    return ConfigError(
        f"{what}: this campaign does not produce the runs column '{column}' ({absent[column]}), so it has no "
        f"value in any run; the columns it produces: {columns_text(produced)}",
        file=file,
        line=line,
        path=path,
    )


def entry_metric_columns(parameter_columns=()):
    """The numeric columns of an entry campaign's runs table (campaign.entry_plan)."""
    return [*ENTRY_COLUMNS, *parameter_columns]


def runs_metric_columns(
    mode_names, n_thrusters, parameter_columns=(), trajectory=DEFAULT_TRAJECTORY, pointing=False, wheels=False
):
    """The numeric columns of a campaign's runs table (``refexmc.campaign.storage.runs_row``)."""
    pulses = [f"pulses_{k + 1}" for k in range(n_thrusters)]
    values = run_value_columns(mode_names, trajectory, pointing, wheels)
    return [*values, "modes_completed", *pulses, *parameter_columns]


def check_requirements(requirements, columns, file=None, lines=None, absent=None):
    """Parse a campaign file's ``'METRIC OP VALUE'`` requirements (ConfigError with file, line and
    key path); its pointing records (mappings) are ``config.pointing``'s. ``absent``: {column: why}
    of the columns the campaign does not produce (:func:`unproduced_columns`): refused too."""
    lines = lines or {}
    parsed = []
    for i, text in enumerate(requirements):
        if isinstance(text, dict):  # a pointing requirement (config.pointing checks it)
            continue
        line = lines.get(("requirements", i))
        where = {"file": file, "line": line, "path": ("requirements", i)}
        parsed.append(parse_requirement(text, columns, "campaign", **where, absent=absent))
    return parsed
