"""`refexmc compare BASELINE_OUT OUT`: did a change make the campaign significantly worse?

The CI gate for changes to the flight software: a change that makes the vehicle use 10 % more
propellant must turn CI red. ``compare(baseline_out, current_out, tolerances)`` reads two campaign
outputs (``refexmc.report.data.load``; histories are not needed) and returns a ``Comparison``;
``format_table`` renders it. A metric is a **regression** when the change is statistically
significant (two-sided, 5 %) **and** worse than the baseline by more than its tolerance, so that
numerical noise (another numba or numpy version, a reordered sum) never fails CI while a real
degradation does. Errored runs are excluded from every statistic except ``error_rate``, and counted.

Metrics (current minus baseline): the success and error rates, then the mission's own metrics
(``mission_metrics``): the runs columns its requirements judge, then its other outputs
(``outputs.plan``), each worse in the direction of its tail in ``report/tails.py``:

- ``success_rate`` (over all runs, an errored run unsuccessful, as the report counts it) and
  ``error_rate`` (of all runs): difference of the two rates with the Newcombe hybrid score
  interval (Newcombe 1998, method 10: Wilson intervals of each rate combined; good coverage down
  to a few runs and at rates of 0 or 1, where the Wald interval degenerates). Significant when the
  95 % interval excludes 0. The p column shows Fisher's exact test for reference. Tolerance 0: any
  significant drop of the success rate (or rise of the error rate) is a regression.
- Run-table columns (``fuel_remaining``, ``theta_t_handover_deg``, ``pulses_total``, ``t_end_s``,
  and every other metric of the mission):
  - **paired**, when both campaigns flew the same dispersed inputs (``pairing``: same run ids,
    seeds, failed thrusters and values of every dispersed parameter both have): the median of the
    per-run differences with its distribution-free 95 % interval (sign-test order statistics,
    ``stats.percentile_bound``), and the Wilcoxon signed-rank test of the differences. Pairing
    removes the run-to-run spread of the dispersions (smoke, 20 runs: an Isp 2 % lower shifts
    propellant remaining by -0.009 in every run, Wilcoxon p = 2e-6; unpaired, with another seed,
    an Isp 10 % lower, -0.041, gives KS p = 0.012).
  - **unpaired** otherwise: the difference of the means with Welch's 95 % interval, and the
    two-sample Kolmogorov-Smirnov test (any change of the distribution, not only of its centre).
    The KS p-value is computed in the paired case too (``details["ks_p"]``).

Default tolerances (``METRICS``; ``--tolerance METRIC=VALUE`` overrides, ``inf`` reports without
gating), chosen against the smoke campaign, which uses 40-50 % of its propellant:

- ``fuel_remaining`` 0.01 (1 % of the tank, about 20 g of nitrogen or 20 high-thrust pulses per
  flight): 10 % more propellant used is 0.045-0.05, four to five times the tolerance. Noise stays
  far below it: scaling the vehicle mass by 1 + 1e-6 changes no run's propellant, by 1.01 single
  runs by up to 0.014 while the median per-run difference stays 0.
- ``theta_t_handover_deg`` 0.1 deg: a quarter of the 0.42 deg attitude deadband, inside which the
  limit cycle wanders anyway (smoke: 0.04-0.31 deg).
- ``pulses_total`` 50 valve openings per flight (about 6 % of the ~830 of a smoke flight): valve
  cycle life, and a sign of a chattering controller.
- ``t_end_s`` 1 s either way: the hand-over time is the initial condition of the aerodynamic phase
  (smoke: 229 s, 0.7 s across the dispersions); a shift either way is a change that phase's
  analysis has not seen, so both directions count as a regression.

A requirement column without a default tolerance regresses when it loses more than
``REQUIREMENT_MARGIN_SHARE`` (10 %) of the baseline's margin, median to the nearest bound; any other
output is shown with tolerance inf (never a regression) unless ``--tolerance`` names it. A
``--tolerance`` for another numeric column of the runs table (``pulses_3``, ...) adds that column
to the comparison (its tail says which direction is worse; ``either`` for columns without one).
"""

import difflib
import math
from dataclasses import dataclass, field

import numpy as np
from scipy import stats as sps

from refexmc.config.errors import ConfigError
from refexmc.config.requirements import parse_requirement
from refexmc.report import data, outputs, stats, tails
from refexmc.report.stats import ks_p, median_interval, newcombe_interval, welch_interval, wilcoxon_p
from refexmc.report.text import number

ALPHA = 1.0 - stats.CONFIDENCE  # two-sided level of every test and interval: 5 %
PARAMETER_RTOL = 1e-9  # dispersed inputs that agree this closely are the same input (scipy ppf round-off)

OK, BETTER, REGRESSION, NOT_COMPUTABLE = "ok", "better", "REGRESSION", "n/a"


@dataclass(frozen=True)
class MetricSpec:
    name: str
    kind: str  # "proportion" or "distribution"
    better: str  # "higher", "lower" or "either" (a significant change either way is a regression)
    tolerance: float  # in the metric's unit; a change within it is never a regression
    digits: int = 4  # decimals in the table


METRICS = {
    spec.name: spec
    for spec in (
        MetricSpec("success_rate", "proportion", "higher", 0.0, digits=3),
        MetricSpec("error_rate", "proportion", "lower", 0.0, digits=3),
        MetricSpec("fuel_remaining", "distribution", "higher", 0.01, 4),  # fraction of the propellant
        MetricSpec("theta_t_handover_deg", "distribution", "lower", 0.1, 3),  # deg
        MetricSpec("pulses_total", "distribution", "lower", 50.0, 1),  # valve openings per flight
        MetricSpec("t_end_s", "distribution", "either", 1.0, 2),  # s
    )
}
COLUMN_BETTER = {"fuel_used_kg": "lower", "modes_completed": "higher"}  # extra columns; default "either"
BETTER_BY_TAIL = {"upper": "lower", "lower": "higher", "both": "either"}  # report/tails.py's worse tail
# a requirement metric without a default tolerance regresses when it loses more than this share of
# the baseline's margin to the requirement (median to bound): small against the margin the
# requirement leaves, large against run-to-run noise, which moves the median by far less
REQUIREMENT_MARGIN_SHARE = 0.1


def _column_better(column):
    if column.startswith("pulses_"):
        return "lower"
    tail = tails.worse_tail(column)
    return COLUMN_BETTER.get(column, BETTER_BY_TAIL[tail] if tail else "either")


def _requirements(campaign):
    """The campaign's requirements as the dicts ``outputs`` reads (metric, op, value, requirement);
    a malformed one is left out here (``refexmc report`` says what is wrong with it)."""
    columns = list(campaign.runs.columns)
    result = []
    for text in campaign.resolved.get("requirements") or []:
        try:
            r = parse_requirement(text, columns, "campaign")
        except ConfigError:
            continue
        result.append({"metric": r.metric, "op": r.op, "value": r.value, "requirement": r.text})
    return result


def requirement_tolerance(column, requirements, baseline):
    """``REQUIREMENT_MARGIN_SHARE`` of the smallest margin between the baseline's median of
    ``column`` (successful flights) and a bound of its requirements; inf when not computable."""
    values = baseline.successful[column].to_numpy(dtype=float)
    values = values[np.isfinite(values)]
    if not len(values):
        return math.inf
    median = float(np.median(values))
    margins = [abs(r["value"] - median) for r in outputs.requirements_of(column, requirements) if r["op"] != "=="]
    margins = [m for m in margins if m > 0.0]
    return REQUIREMENT_MARGIN_SHARE * min(margins) if margins else math.inf


def mission_metrics(baseline, current):
    """MetricSpecs of the mission's own metrics both runs tables have: the requirements' columns
    (both campaigns'), then the other outputs (``outputs.plan``) that vary in either campaign.
    Defaults: ``METRICS`` where it names the column; a requirement column
    ``requirement_tolerance``; any other output inf (shown, never a regression by default)."""
    requirements = _requirements(current) + [r for r in _requirements(baseline) if r not in _requirements(current)]
    plans = [outputs.plan(campaign, requirements) for campaign in (baseline, current)]
    both = set(baseline.runs.columns) & set(current.runs.columns)
    judged = [c for c in outputs.requirement_columns(requirements) if c in both]
    others = []
    for plan in plans:
        others += [c for c in plan["other_columns"] if c in both and c not in judged and c not in others]
    specs = {}
    for column in [*judged, *others]:
        if column in METRICS:
            specs[column] = METRICS[column]
            continue
        tail = plans[1]["tails"].get(column) or plans[0]["tails"].get(column) or "both"
        better = BETTER_BY_TAIL[tail]
        tolerance = requirement_tolerance(column, requirements, baseline) if column in judged else math.inf
        specs[column] = MetricSpec(column, "distribution", better, tolerance, 4)
    return specs


@dataclass
class Pairing:
    """Whether run i of both campaigns flew the same dispersed inputs, and on which runs."""

    paired: bool
    run_ids: np.ndarray  # run ids ok in both (the pairs), empty when not paired
    note: str
    only_baseline: list = field(default_factory=list)  # p. columns dispersed in one campaign only
    only_current: list = field(default_factory=list)


@dataclass
class MetricResult:
    metric: str
    kind: str
    better: str
    tolerance: float
    baseline: float  # rate, or mean of the ok runs
    current: float
    n_baseline: int  # runs in the population (all runs for error_rate, ok runs otherwise)
    n_current: int
    difference: float  # current - baseline: rates, median per-run difference (paired) or means
    ci: tuple  # 95 % interval of ``difference``
    estimate: str  # what ``difference`` is
    test: str
    p_value: float
    significant: bool
    verdict: str  # OK, BETTER, REGRESSION or NOT_COMPUTABLE
    digits: int = 4
    details: dict = field(default_factory=dict)


@dataclass
class Comparison:
    baseline: dict  # name, out, runs, ok, errored
    current: dict
    pairing: Pairing
    metrics: list
    notes: list

    @property
    def regressions(self):
        return [m for m in self.metrics if m.verdict == REGRESSION]

    @property
    def passed(self):
        return not self.regressions


# --- verdict -----------------------------------------------------------------------------------


def verdict(better, difference, significant, tolerance):
    """REGRESSION when significant and worse by more than ``tolerance``; BETTER when significant and
    better by more; OK otherwise; NOT_COMPUTABLE when the difference is not a number."""
    if not math.isfinite(difference):
        return NOT_COMPUTABLE
    if not significant:
        return OK
    if better == "either":
        return REGRESSION if abs(difference) > tolerance else OK
    gain = difference if better == "higher" else -difference
    if gain < -tolerance:
        return REGRESSION
    return BETTER if gain > tolerance else OK


# --- pairing -----------------------------------------------------------------------------------


def _same(a, b):
    """Equal run by run: integers (seeds) exactly, floats to PARAMETER_RTOL, anything else as text."""
    a = np.asarray(a)
    b = np.asarray(b)
    if a.dtype.kind in "iub" and b.dtype.kind in "iub":
        return bool(np.array_equal(a, b))
    if a.dtype.kind in "fiub" and b.dtype.kind in "fiub":
        return bool(np.allclose(a.astype(float), b.astype(float), rtol=PARAMETER_RTOL, atol=0.0, equal_nan=True))
    return bool(np.array_equal(a.astype(str), b.astype(str)))


def pairing(baseline, current):
    """Pair run i with run i when both campaigns flew the same dispersed inputs.

    Same inputs: on the run ids ok in both, equal ``seed`` (the in-flight noise), equal
    ``failed_thrusters`` and equal values of every ``p.`` column both campaigns have. A ``p.``
    column in one campaign only (a parameter dispersed, or set by a ``constant``, on one side only)
    does not prevent pairing: it is the deliberate change, and the differences measure its effect.
    A changed seed, run count with LHS/Sobol, or distribution of a common parameter changes the
    draws, and run-by-run differences would mix the change with different flights: no pairing.
    """
    b = baseline.ok.set_index("run_id")
    c = current.ok.set_index("run_id")
    ids = np.intersect1d(b.index.to_numpy(), c.index.to_numpy())
    only_baseline = sorted(set(baseline.parameter_columns) - set(current.parameter_columns))
    only_current = sorted(set(current.parameter_columns) - set(baseline.parameter_columns))
    if len(ids) == 0:
        return Pairing(False, np.zeros(0, dtype=np.int64), "not paired: no run id is ok in both campaigns")
    differ = [
        column
        for column in ("seed", "failed_thrusters")
        if column in b and column in c and not _same(b.loc[ids, column], c.loc[ids, column])
    ]
    common = sorted(set(baseline.parameter_columns) & set(current.parameter_columns))
    differ += [column for column in common if not _same(b.loc[ids, column], c.loc[ids, column])]
    if differ:
        shown = ", ".join(differ[:4]) + (f" (+{len(differ) - 4} more)" if len(differ) > 4 else "")
        note = f"not paired: the runs' inputs differ ({shown}); unpaired tests only"
        return Pairing(False, np.zeros(0, dtype=np.int64), note, only_baseline, only_current)
    note = f"paired run by run on {len(ids)} runs (same seeds, failed thrusters and dispersed parameters)"
    for side, columns in (("baseline", only_baseline), ("current", only_current)):
        if columns:
            note += f"; dispersed in the {side} only: {', '.join(columns[:4])}" + (" ..." if len(columns) > 4 else "")
    return Pairing(True, ids, note, only_baseline, only_current)


# --- metrics -----------------------------------------------------------------------------------


def compare_proportion(spec, x_baseline, n_baseline, x_current, n_current, tolerance):
    """A rate (successes x of n) of both campaigns: difference, Newcombe interval, Fisher p."""
    rate_b = x_baseline / n_baseline if n_baseline else math.nan
    rate_c = x_current / n_current if n_current else math.nan
    difference = rate_c - rate_b
    low, high = newcombe_interval(x_current, n_current, x_baseline, n_baseline)
    p = math.nan
    if n_baseline and n_current:
        table = [[x_current, n_current - x_current], [x_baseline, n_baseline - x_baseline]]
        p = float(sps.fisher_exact(table).pvalue)
    significant = math.isfinite(low) and (low > 0.0 or high < 0.0)
    return MetricResult(
        metric=spec.name,
        kind=spec.kind,
        better=spec.better,
        tolerance=tolerance,
        baseline=rate_b,
        current=rate_c,
        n_baseline=n_baseline,
        n_current=n_current,
        difference=difference,
        ci=(low, high),
        estimate="difference of rates (Newcombe hybrid score interval)",
        test="Fisher exact",
        p_value=p,
        significant=significant,
        verdict=verdict(spec.better, difference, significant, tolerance),
        digits=spec.digits,
        details={"x_baseline": x_baseline, "x_current": x_current},
    )


def _finite(values):
    values = np.asarray(values, dtype=float)
    return values[np.isfinite(values)]


def compare_distribution(spec, baseline, current, pairs, tolerance):
    """One runs column: paired (``pairs`` a Pairing that is paired) or unpaired comparison."""
    b = _finite(baseline.ok[spec.name])
    c = _finite(current.ok[spec.name])
    mean_difference, welch = welch_interval(b, c)
    details = {"ks_p": ks_p(b, c), "mean_difference": mean_difference, "welch_ci": welch}
    if pairs.paired:
        base_by_id = baseline.ok.set_index("run_id")[spec.name]
        cur_by_id = current.ok.set_index("run_id")[spec.name]
        diffs = _finite(cur_by_id.loc[pairs.run_ids].to_numpy(float) - base_by_id.loc[pairs.run_ids].to_numpy(float))
        difference, ci = median_interval(diffs)
        p = wilcoxon_p(diffs)
        details.update(pairs=len(diffs), worse_runs=_worse_runs(spec.better, diffs, tolerance))
        estimate, test = "median of the per-run differences (sign-test interval)", "Wilcoxon signed-rank"
    else:
        difference, ci, p = mean_difference, welch, details["ks_p"]
        estimate, test = "difference of the means (Welch interval)", "two-sample KS"
    significant = math.isfinite(p) and p < ALPHA
    return MetricResult(
        metric=spec.name,
        kind=spec.kind,
        better=spec.better,
        tolerance=tolerance,
        baseline=float(b.mean()) if len(b) else math.nan,
        current=float(c.mean()) if len(c) else math.nan,
        n_baseline=len(b),
        n_current=len(c),
        difference=float(difference),
        ci=tuple(float(v) for v in ci),
        estimate=estimate,
        test=test,
        p_value=p,
        significant=significant,
        verdict=verdict(spec.better, float(difference), significant, tolerance),
        digits=spec.digits,
        details=details,
    )


def _worse_runs(better, diffs, tolerance):
    """How many paired runs got worse by more than the tolerance (for the reader, not the verdict)."""
    if better == "higher":
        return int(np.count_nonzero(diffs < -tolerance))
    if better == "lower":
        return int(np.count_nonzero(diffs > tolerance))
    return int(np.count_nonzero(np.abs(diffs) > tolerance))


# --- tolerances --------------------------------------------------------------------------------


def _numeric_columns(campaign):
    return [
        c
        for c in campaign.runs.columns
        if c not in ("run_id", "seed") and not c.startswith("p.") and campaign.runs[c].dtype.kind in "fiu"
    ]


def parse_tolerances(texts, baseline, current):
    """``['METRIC=VALUE', ...]`` -> {metric: MetricSpec with that tolerance}; ConfigError on bad input.

    METRIC is one of ``METRICS`` or a numeric column both runs tables have (then added to the
    comparison). VALUE is a number >= 0 in the metric's unit, or ``inf`` (report, never gate).
    Unknown metrics get a did-you-mean over exactly these names (not the ``<column>.<stat>``
    grammar of ``requirements.check_metric``, whose hints would name statistics compare has not).
    """
    columns = [c for c in _numeric_columns(baseline) if c in set(_numeric_columns(current))]
    known = list(METRICS) + [c for c in columns if c not in METRICS]
    mission = mission_metrics(baseline, current) if texts else {}
    specs = {}
    for text in texts:
        where = {"path": ("--tolerance",)}
        metric, sep, value_text = str(text).partition("=")
        metric, value_text = metric.strip(), value_text.strip()
        if not sep or not metric or not value_text:
            raise ConfigError(f"expected METRIC=VALUE (e.g. fuel_remaining=0.02), got '{text}'", **where)
        try:
            value = float(value_text)
        except ValueError:
            raise ConfigError(f"expected a number after '=', got '{value_text}' in '{text}'", **where) from None
        if math.isnan(value) or value < 0.0:
            raise ConfigError(f"expected a tolerance >= 0 (or inf), got '{value_text}' in '{text}'", **where)
        if metric in METRICS:
            base = METRICS[metric]
        elif metric in mission:
            base = mission[metric]
        elif metric in columns:
            base = MetricSpec(metric, "distribution", _column_better(metric), value)
        else:
            guess = difflib.get_close_matches(metric, known, n=1, cutoff=0.6)
            hint = f"did you mean '{guess[0]}'? " if guess else ""
            raise ConfigError(
                f"unknown metric '{metric}'; {hint}(metrics: {', '.join(METRICS)}, or a numeric runs column)", **where
            )
        specs[metric] = MetricSpec(base.name, base.kind, base.better, value, base.digits)
    return specs


# --- the comparison ----------------------------------------------------------------------------


def _describe(campaign):
    return {
        "name": campaign.name,
        "out": str(campaign.out),
        "runs": len(campaign.runs),
        "ok": len(campaign.ok),
        "errored": len(campaign.errored),
        "success": int(campaign.ok["success"].astype(bool).sum()),
    }


def compare(baseline_out, current_out, tolerances=()):
    """Compare campaign output ``current_out`` against ``baseline_out``; see the module docstring.

    ``tolerances``: ``'METRIC=VALUE'`` strings (``parse_tolerances``). Bad input (an OUT that is not
    a campaign output, a bad tolerance) raises ConfigError.
    """
    baseline = data.load(baseline_out)
    current = data.load(current_out)
    overrides = parse_tolerances(tolerances, baseline, current)
    rates = {name: METRICS[name] for name in ("success_rate", "error_rate")}
    specs = {**rates, **mission_metrics(baseline, current), **overrides}
    pairs = pairing(baseline, current)
    b, c = _describe(baseline), _describe(current)
    results = []
    for spec in specs.values():
        if spec.name == "success_rate":  # over all runs, an errored run unsuccessful: as the report
            results.append(compare_proportion(spec, b["success"], b["runs"], c["success"], c["runs"], spec.tolerance))
        elif spec.name == "error_rate":
            results.append(compare_proportion(spec, b["errored"], b["runs"], c["errored"], c["runs"], spec.tolerance))
        elif spec.name in baseline.runs and spec.name in current.runs:
            results.append(compare_distribution(spec, baseline, current, pairs, spec.tolerance))
    notes = [pairs.note]
    differ = sorted(
        key
        for key in {*baseline.resolved, *current.resolved}
        if baseline.resolved.get(key) != current.resolved.get(key)
    )
    if differ:
        notes.append(f"the resolved campaigns differ in: {', '.join(differ)}")
    for side, info in (("baseline", b), ("current", c)):
        if info["errored"]:
            notes.append(
                f"{side}: {info['errored']} of {info['runs']} runs errored "
                "(in error_rate only, excluded from the other metrics)"
            )
    if pairs.paired:
        notes += _changed_runs(baseline, current, pairs)
    return Comparison(baseline=b, current=c, pairing=pairs, metrics=results, notes=notes)


def _changed_runs(baseline, current, pairs):
    """Paired runs whose outcome flipped: worth a `refexmc rerun` each."""
    notes = []
    b = baseline.ok.set_index("run_id").loc[pairs.run_ids, "success"].astype(bool)
    c = current.ok.set_index("run_id").loc[pairs.run_ids, "success"].astype(bool)
    lost = [int(i) for i in pairs.run_ids[(b & ~c).to_numpy()]]
    won = [int(i) for i in pairs.run_ids[(~b & c).to_numpy()]]
    errored_now = sorted(set(baseline.ok["run_id"]) & set(current.errored["run_id"]))
    if lost:
        notes.append(
            f"runs that succeeded in the baseline and fail now: {_ids(lost)} (refexmc rerun {current.out} {lost[0]})"
        )
    if won:
        notes.append(f"runs that failed in the baseline and succeed now: {_ids(won)}")
    if errored_now:
        notes.append(f"runs ok in the baseline that raise errors now: {_ids(errored_now)}")
    return notes


def _ids(ids, most=10):
    return ", ".join(map(str, ids[:most])) + (f" (+{len(ids) - most} more)" if len(ids) > most else "")


# --- the table ---------------------------------------------------------------------------------


def _value(value, digits, signed=False):
    if value is None or not math.isfinite(value):
        return "-"
    return f"{value:+.{digits}f}" if signed else f"{value:.{digits}f}"


def _p(value):
    return "-" if not math.isfinite(value) else f"{value:.2g}"


def _tolerance(m):
    if math.isinf(m.tolerance):
        return "inf (not gated)"
    worse = {"higher": "drop", "lower": "rise", "either": "either way"}[m.better]
    return f"{number(m.tolerance)} ({worse})"


def format_table(comparison):
    """The terminal table: metric, baseline, current, difference [95 % interval], test, p, tolerance, verdict."""
    b, c = comparison.baseline, comparison.current
    lines = [
        f"baseline {b['name']}: {b['runs']} runs, {b['ok']} ok, {b['errored']} errored ({b['out']})",
        f"current  {c['name']}: {c['runs']} runs, {c['ok']} ok, {c['errored']} errored ({c['out']})",
    ]
    lines += [f"note: {note}" for note in comparison.notes]
    header = ("metric", "baseline", "current", "difference [95 % CI]", "test", "p", "tolerance", "verdict")
    rows = []
    for m in comparison.metrics:
        if m.kind == "proportion":
            base = f"{_value(m.baseline, m.digits)} ({m.details['x_baseline']}/{m.n_baseline})"
            cur = f"{_value(m.current, m.digits)} ({m.details['x_current']}/{m.n_current})"
        else:
            base, cur = _value(m.baseline, m.digits), _value(m.current, m.digits)
        low, high = m.ci
        interval = f"[{_value(low, m.digits, True)}, {_value(high, m.digits, True)}]"
        rows.append(
            (m.metric, base, cur, f"{_value(m.difference, m.digits, True)} {interval}", m.test, _p(m.p_value))
            + (_tolerance(m), m.verdict)
        )
    widths = [max(len(str(r[k])) for r in [header, *rows]) for k in range(len(header))]
    lines.append("")
    for row in [header, *rows]:
        lines.append("  ".join(str(v).ljust(w) for v, w in zip(row, widths, strict=True)).rstrip())
    lines.append("")
    lines.append(
        "difference: current - baseline; rates: Newcombe hybrid score interval; columns: "
        + (
            "median of the per-run differences (sign-test interval), baseline/current are means"
            if comparison.pairing.paired
            else "difference of the means (Welch interval)"
        )
    )
    lines.append("REGRESSION: significant at 5 % and worse than the baseline by more than the tolerance")
    regressions = comparison.regressions
    if regressions:
        names = ", ".join(m.metric for m in regressions)
        lines.append(f"verdict: FAIL ({len(regressions)} regression{'s' if len(regressions) > 1 else ''}: {names})")
    else:
        lines.append("verdict: PASS (no significant regression)")
    return "\n".join(lines)
