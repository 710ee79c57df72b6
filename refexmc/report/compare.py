"""`refexmc compare BASELINE_OUT OUT`: did a change make the campaign significantly worse?

The CI gate for changes to the flight software. ``compare(baseline_out, current_out, tolerances)``
reads two campaign outputs (``refexmc.report.data.load``; histories are not needed) and returns a
``Comparison``; ``format_table`` renders it. A metric is a **regression** when the change is
statistically significant (two-sided, 5 %) **and** worse than the baseline by more than its
tolerance, so that numerical noise never fails CI while a real degradation does. Errored runs are
excluded from every statistic except ``error_rate``, and counted (docs/compare.md).

**No PASS about runs that did not all fly.** Either campaign incomplete by the report's own check
(``data.completeness``: interrupted, planned runs or part files missing) makes the verdict
INCOMPLETE (exit 1), whatever the rows, which are then of the stored runs only
(``Comparison.incomplete``, ``Comparison.verdict``).

**Which metrics, judged how** (each by the mission's own terms, no default of one mission):

- ``success_rate`` (over all runs, an errored run unsuccessful, as the report counts it) and
  ``error_rate``: gated with tolerance 0 (any significant drop of the success rate or rise of the
  error rate is a regression).
- the runs columns the campaigns' **requirements** judge, in requirement order: worse is the
  requirement's failing side (``<=``/``<``: higher is worse; ``>=``/``>``: lower is worse; both
  kinds on one column: a change either way); tolerance ``REQUIREMENT_MARGIN_SHARE`` (10 %) of the
  baseline's margin, median to the nearest bound.
- the mission's **other outputs** (``outputs.plan``): shown with their statistics and never gated,
  unless ``--tolerance METRIC=VALUE`` gives them a tolerance (then worse is the column's tail in
  ``report/tails.py``, "either way" for a column without one). ``--tolerance`` also overrides a
  requirement column's tolerance and adds any other numeric runs column.

**The tests.** The verdict and the printed 95 % interval come from one construction each, so that a
significant row never prints an interval holding 0:

- a column, **paired** (both campaigns flew the same dispersed inputs, ``pairing``): the median of
  the per-run differences with its distribution-free interval (order statistics), and the exact
  sign test that this interval inverts (``stats.sign_test_p``). Chosen over the Wilcoxon
  signed-rank test because the sign test needs no symmetry of the differences and its interval is
  exact; it loses little here, where a change moves most runs the same way (smoke: an Isp 10 %
  lower raises the propellant used in every one of 10 runs, p = 2/2^10).
- a column, **unpaired**: the difference of the means with Welch's interval and Welch's t-test
  (``stats.welch_p``), exact inversions of each other; the means are what a shifted design moves,
  and at campaign sizes (tens of runs and up) their distribution is near normal. The two-sample
  Kolmogorov-Smirnov p-value is kept in ``details["ks_p"]`` and a note names a column whose
  distribution changed shape without a significant change of its mean.
- a rate, **paired**: McNemar's exact test on the discordant runs (``stats.mcnemar_exact``): the
  difference of the rates over the common runs, with the Clopper-Pearson interval of the share of
  discordant runs that improved mapped onto it.
- a rate, **unpaired**: the difference of the rates with Newcombe's hybrid score interval
  (Newcombe 1998, method 10) and the p-value of inverting it (``stats.newcombe_p``).
"""

import difflib
import math
from dataclasses import dataclass, field

import numpy as np

from refexmc.config.errors import ConfigError
from refexmc.config.requirements import parse_requirement
from refexmc.report import data, outputs, pointing, stats, tails
from refexmc.report.stats import (
    ks_p,
    mcnemar_exact,
    median_interval,
    newcombe_interval,
    newcombe_p,
    sign_test_p,
    welch_interval,
    welch_p,
)
from refexmc.report.text import number

ALPHA = 1.0 - stats.CONFIDENCE  # two-sided level of every test and interval: 5 %
PARAMETER_RTOL = 1e-9  # dispersed inputs that agree this closely are the same input (scipy ppf round-off)

OK, BETTER, REGRESSION, NOT_COMPUTABLE = "ok", "better", "REGRESSION", "n/a"
PASS, FAIL, INCOMPLETE = "PASS", "FAIL", "INCOMPLETE"  # the comparison's verdict (docs/compare.md)


@dataclass(frozen=True)
class MetricSpec:
    name: str
    kind: str  # "proportion" or "distribution"
    better: str  # "higher", "lower" or "either" (a significant change either way is a regression)
    tolerance: float  # in the metric's unit; a change within it is never a regression; inf: not gated
    digits: int = 4  # decimals in the table
    requirement: str = ""  # the requirements that judge the column (its direction), "" for none
    source: str = ""  # where the tolerance comes from: "rate", "margin", "--tolerance" or "" (not gated)


RATES = {
    spec.name: spec
    for spec in (
        MetricSpec("success_rate", "proportion", "higher", 0.0, 3, source="rate"),
        MetricSpec("error_rate", "proportion", "lower", 0.0, 3, source="rate"),
    )
}
BETTER_BY_TAIL = {"upper": "lower", "lower": "higher", "both": "either"}  # report/tails.py's worse tail
BETTER_BY_OPERATOR = {"<=": "lower", "<": "lower", ">=": "higher", ">": "higher"}  # a requirement's good side
# a requirement metric regresses when it loses more than this share of the baseline's margin to
# the requirement (median to bound): small against the margin the requirement leaves, large
# against run-to-run noise, which moves the median by far less
REQUIREMENT_MARGIN_SHARE = 0.1


def _column_better(column):
    """Worse direction of a column without a requirement: its tail (report/tails.py), else either way."""
    tail = tails.worse_tail(column)
    return BETTER_BY_TAIL[tail] if tail else "either"


def requirement_better(column, requirements):
    """Better direction of a requirement column from its operators: ``<=`` lower, ``>=`` higher;
    both kinds (a band), ``==`` or none: "either"."""
    sides = {BETTER_BY_OPERATOR.get(r["op"], "either") for r in outputs.requirements_of(column, requirements)}
    return sides.pop() if len(sides) == 1 else "either"


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
    for req in pointing.requirements_of(campaign):  # a pointing record: its runs column, lower is better
        limit = 1.0 - req.p_c if req.interpretation == "mixed" else req.bound
        # as 'COLUMN.max <= limit': every run within the limit (its column and direction are what compare reads)
        result.append({"metric": f"{req.column}.max", "op": "<=", "value": limit, "requirement": req.text()})
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
    (both campaigns'), judged by their requirements (``requirement_better``,
    ``requirement_tolerance``), then the other outputs (``outputs.plan``) that vary in either
    campaign, shown with tolerance inf (never a regression unless ``--tolerance`` names them)."""
    requirements = _requirements(current) + [r for r in _requirements(baseline) if r not in _requirements(current)]
    plans = [outputs.plan(campaign, requirements) for campaign in (baseline, current)]
    both = set(baseline.runs.columns) & set(current.runs.columns)
    judged = [c for c in outputs.requirement_columns(requirements) if c in both]
    others = []
    for plan in plans:
        others += [c for c in plan["other_columns"] if c in both and c not in judged and c not in others]
    specs = {}
    for column in judged:
        texts = ", ".join(r["requirement"] for r in outputs.requirements_of(column, requirements))
        tolerance = requirement_tolerance(column, requirements, baseline)
        better = requirement_better(column, requirements)
        source = "margin" if math.isfinite(tolerance) else ""
        specs[column] = MetricSpec(column, "distribution", better, tolerance, 4, texts, source)
    for column in others:
        specs[column] = MetricSpec(column, "distribution", _column_better(column), math.inf, 4)
    return specs


def check_requirement_columns(baseline, current):
    """ConfigError when a runs column that either campaign's requirements judge is missing from the
    other campaign's runs table: such a metric cannot be compared, and leaving it out would let a
    comparison pass without it (an IRASSI baseline against an X-38 campaign: the wheels' momentum)."""
    problems = []
    sides = (("baseline", baseline, "current", current), ("current", current, "baseline", baseline))
    for judging, campaign, lacking, other in sides:
        requirements = _requirements(campaign)
        missing = [c for c in outputs.requirement_columns(requirements) if c not in other.runs.columns]
        if missing:
            texts = [r["requirement"] for c in missing for r in outputs.requirements_of(c, requirements)]
            problems.append(
                f"the {lacking} campaign's runs table ({other.out / 'runs'}) lacks {', '.join(missing)}, "
                f"judged by the {judging}'s requirements ({'; '.join(dict.fromkeys(texts))})"
            )
    if problems:
        raise ConfigError(
            "; ".join(problems) + ": compare needs every requirement's column in both campaigns "
            "(a campaign of another mission or vehicle is no baseline for this one)"
        )


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
    baseline: float  # rate, or the ok runs' median (paired) or mean (unpaired)
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
    requirement: str = ""  # the requirements that judge it ("" for none)
    source: str = ""  # where its tolerance comes from (MetricSpec.source)


@dataclass
class Comparison:
    baseline: dict  # name, out, runs, ok, errored
    current: dict
    pairing: Pairing
    metrics: list
    notes: list
    # side ("baseline", "current") -> report.data.completeness of a campaign not every planned run of
    # which is stored (interrupted, a part file missing): no PASS about runs that did not all fly
    incomplete: dict = field(default_factory=dict)

    @property
    def regressions(self):
        return [m for m in self.metrics if m.verdict == REGRESSION]

    @property
    def verdict(self):
        """INCOMPLETE (either campaign; wins over FAIL, as in the report), FAIL (a regression) or PASS."""
        if self.incomplete:
            return INCOMPLETE
        return FAIL if self.regressions else PASS

    @property
    def passed(self):
        return self.verdict == PASS


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


def _proportion_result(spec, tolerance, rates, ns, difference, ci, estimate, test, p, details):
    low, high = ci
    significant = math.isfinite(low) and (low > 0.0 or high < 0.0)  # the printed interval decides
    return MetricResult(
        metric=spec.name,
        kind=spec.kind,
        better=spec.better,
        tolerance=tolerance,
        baseline=rates[0],
        current=rates[1],
        n_baseline=ns[0],
        n_current=ns[1],
        difference=difference,
        ci=(low, high),
        estimate=estimate,
        test=test,
        p_value=p,
        significant=significant,
        verdict=verdict(spec.better, difference, significant, tolerance),
        digits=spec.digits,
        details=details,
    )


def compare_proportion(spec, x_baseline, n_baseline, x_current, n_current, tolerance):
    """A rate (x of n) of two unpaired campaigns: difference, Newcombe interval and its inversion's p."""
    rate_b = x_baseline / n_baseline if n_baseline else math.nan
    rate_c = x_current / n_current if n_current else math.nan
    return _proportion_result(
        spec,
        tolerance,
        (rate_b, rate_c),
        (n_baseline, n_current),
        rate_c - rate_b,
        newcombe_interval(x_current, n_current, x_baseline, n_baseline),
        "difference of rates (Newcombe hybrid score interval)",
        "Newcombe score",
        newcombe_p(x_current, n_current, x_baseline, n_baseline),
        {"x_baseline": x_baseline, "x_current": x_current},
    )


def compare_paired_proportion(spec, baseline_outcome, current_outcome, tolerance):
    """A binary outcome of the same runs in both campaigns (boolean arrays, run by run): McNemar's
    exact test on the discordant runs; the difference of the rates, (won - lost) / n, with the
    Clopper-Pearson interval of won / (won + lost) mapped onto it: (won + lost) (2 pi - 1) / n."""
    b = np.asarray(baseline_outcome, dtype=bool)
    c = np.asarray(current_outcome, dtype=bool)
    n = len(b)
    lost, won = int(np.count_nonzero(b & ~c)), int(np.count_nonzero(~b & c))
    p, (low, high) = mcnemar_exact(lost, won)
    m = lost + won
    ci = (m * (2.0 * low - 1.0) / n, m * (2.0 * high - 1.0) / n) if n else (math.nan, math.nan)
    if m == 0:
        ci = (0.0, 0.0)  # no run changed its outcome
    x_b, x_c = int(b.sum()), int(c.sum())
    return _proportion_result(
        spec,
        tolerance,
        (x_b / n if n else math.nan, x_c / n if n else math.nan),
        (n, n),
        (won - lost) / n if n else math.nan,
        ci,
        "difference of rates over the paired runs (McNemar: Clopper-Pearson interval of the discordant runs)",
        "McNemar exact",
        p,
        {"x_baseline": x_b, "x_current": x_c, "discordant_lost": lost, "discordant_won": won},
    )


def _finite(values):
    values = np.asarray(values, dtype=float)
    return values[np.isfinite(values)]


def compare_distribution(spec, baseline, current, pairs, tolerance):
    """One runs column: paired (``pairs`` a Pairing that is paired) or unpaired comparison.

    Paired, every statistic of the row (the medians shown, the per-run differences, the KS and Welch
    details) is over the paired runs, so that the baseline's column and the current's are of the
    same runs; unpaired, over each campaign's ok runs."""
    if pairs.paired:
        base_paired = baseline.ok.set_index("run_id")[spec.name].loc[pairs.run_ids].to_numpy(float)
        cur_paired = current.ok.set_index("run_id")[spec.name].loc[pairs.run_ids].to_numpy(float)
        b, c = _finite(base_paired), _finite(cur_paired)
    else:
        b, c = _finite(baseline.ok[spec.name]), _finite(current.ok[spec.name])
    mean_difference, welch = welch_interval(b, c)
    details = {"ks_p": ks_p(b, c), "mean_difference": mean_difference, "welch_ci": welch}
    if pairs.paired:
        diffs = _finite(cur_paired - base_paired)
        difference, ci = median_interval(diffs)
        p = sign_test_p(diffs)
        details.update(pairs=len(diffs), worse_runs=_worse_runs(spec.better, diffs, tolerance))
        estimate, test = "median of the per-run differences (sign-test interval)", "sign test"
    else:
        difference, ci, p = mean_difference, welch, welch_p(b, c)
        estimate, test = "difference of the means (Welch interval)", "Welch t"
    low, high = (float(v) for v in ci)
    significant = math.isfinite(low) and (low > 0.0 or high < 0.0)  # the printed interval decides
    centre = np.median if pairs.paired else np.mean  # the statistic the difference is of
    return MetricResult(
        metric=spec.name,
        kind=spec.kind,
        better=spec.better,
        tolerance=tolerance,
        baseline=float(centre(b)) if len(b) else math.nan,
        current=float(centre(c)) if len(c) else math.nan,
        n_baseline=len(b),
        n_current=len(c),
        difference=float(difference),
        ci=(low, high),
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

    METRIC is a rate (``RATES``), one of the mission's metrics (``mission_metrics``: its direction
    kept) or a numeric column both runs tables have (then added to the comparison, worse by its
    tail). VALUE is a number >= 0 in the metric's unit, or ``inf`` (report, never gate). Unknown
    metrics get a did-you-mean over exactly these names.
    """
    columns = [c for c in _numeric_columns(baseline) if c in set(_numeric_columns(current))]
    mission = mission_metrics(baseline, current) if texts else {}
    known = list(RATES) + list(mission) + [c for c in columns if c not in mission]
    specs = {}
    for text in texts:
        where = {"path": ("--tolerance",)}
        metric, sep, value_text = str(text).partition("=")
        metric, value_text = metric.strip(), value_text.strip()
        if not sep or not metric or not value_text:
            raise ConfigError(f"expected METRIC=VALUE (e.g. success_rate=0.05), got '{text}'", **where)
        try:
            value = float(value_text)
        except ValueError:
            raise ConfigError(f"expected a number after '=', got '{value_text}' in '{text}'", **where) from None
        if math.isnan(value) or value < 0.0:
            raise ConfigError(f"expected a tolerance >= 0 (or inf), got '{value_text}' in '{text}'", **where)
        if metric in RATES:
            base = RATES[metric]
        elif metric in mission:
            base = mission[metric]
        elif metric in columns:
            base = MetricSpec(metric, "distribution", _column_better(metric), value)
        else:
            guess = difflib.get_close_matches(metric, known, n=1, cutoff=0.6)
            hint = f"did you mean '{guess[0]}'? " if guess else ""
            shown = ", ".join(known[:12]) + (", ..." if len(known) > 12 else "")
            raise ConfigError(f"unknown metric '{metric}'; {hint}(metrics: {shown})", **where)
        source = "--tolerance" if math.isfinite(value) else ""
        specs[metric] = MetricSpec(base.name, base.kind, base.better, value, base.digits, base.requirement, source)
    return specs


# --- the comparison ----------------------------------------------------------------------------


def _describe(campaign):
    successful = len(campaign.successful)
    return {
        "name": campaign.name,
        "out": str(campaign.out),
        "runs": len(campaign.runs),
        "ok": len(campaign.ok),
        "errored": len(campaign.errored),
        "success": successful,
        "failed": len(campaign.ok) - successful,
    }


def _outcomes(campaign, run_ids):
    """(success, errored) per run id of ``run_ids`` (boolean arrays; an errored run is unsuccessful)."""
    runs = campaign.runs.drop_duplicates("run_id").set_index("run_id").loc[run_ids]
    flown = (runs["status"] == "ok").to_numpy()
    return flown & runs["success"].fillna(False).to_numpy(dtype=bool), ~flown


def compare(baseline_out, current_out, tolerances=()):
    """Compare campaign output ``current_out`` against ``baseline_out``; see the module docstring.

    ``tolerances``: ``'METRIC=VALUE'`` strings (``parse_tolerances``). Bad input (an OUT that is not
    a campaign output, a damaged manifest.json, a bad tolerance, a requirement's column one runs
    table lacks: ``check_requirement_columns``) raises ConfigError.
    """
    baseline = data.load(baseline_out)
    current = data.load(current_out)
    check_requirement_columns(baseline, current)
    overrides = parse_tolerances(tolerances, baseline, current)
    # the report's completeness check (docs/report.md, INCOMPLETE): not every planned run stored
    checked = {"baseline": data.completeness(baseline), "current": data.completeness(current)}
    incomplete = {side: info for side, info in checked.items() if not info["complete"]}
    specs = {**RATES, **mission_metrics(baseline, current), **overrides}
    pairs = pairing(baseline, current)
    b, c = _describe(baseline), _describe(current)
    common = np.intersect1d(baseline.runs["run_id"].to_numpy(), current.runs["run_id"].to_numpy())
    outcomes = {"baseline": _outcomes(baseline, common), "current": _outcomes(current, common)}
    results = []
    for spec in specs.values():
        if spec.name in RATES:
            which = 0 if spec.name == "success_rate" else 1
            if pairs.paired:  # the same runs: McNemar on the runs whose outcome changed
                result = compare_paired_proportion(
                    spec, outcomes["baseline"][which], outcomes["current"][which], spec.tolerance
                )
            else:  # over all runs, an errored run unsuccessful: as the report counts it
                key = "success" if which == 0 else "errored"
                result = compare_proportion(spec, b[key], b["runs"], c[key], c["runs"], spec.tolerance)
        elif spec.name in baseline.runs and spec.name in current.runs:
            result = compare_distribution(spec, baseline, current, pairs, spec.tolerance)
        else:
            continue
        result.requirement, result.source = spec.requirement, spec.source
        results.append(result)
    notes = [pairs.note]
    if pairs.paired and len(common) < max(b["runs"], c["runs"]):
        notes.append(
            f"rates over the {len(common)} run ids both campaigns hold, columns over the "
            f"{len(pairs.run_ids)} of them flown (status ok) in both"
        )
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
    shape = [
        m.metric
        for m in results
        if m.kind == "distribution" and not m.significant and m.details.get("ks_p", math.nan) < ALPHA
    ]
    if shape:
        notes.append(
            f"distribution changed shape (two-sample KS p < 0.05) without a significant shift: {', '.join(shape)}"
        )
    if pairs.paired:
        notes += _changed_runs(baseline, current, pairs)
    return Comparison(baseline=b, current=c, pairing=pairs, metrics=results, notes=notes, incomplete=incomplete)


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
    source = {"margin": f"; {100 * REQUIREMENT_MARGIN_SHARE:g} % of the margin", "--tolerance": "; --tolerance"}
    return f"{number(m.tolerance)} ({worse}{source.get(m.source, '')})"


def _counts(info):
    return (
        f"{info['runs']} runs: {info['success']} successful, {info['failed']} failed "
        f"flight{'' if info['failed'] == 1 else 's'}, {info['errored']} errored"
    )


def _missing(info):
    """What is missing from an incomplete campaign (``report.data.completeness``), as the report says it."""
    planned = info["runs_planned"]
    parts = [f"{info['runs_stored']} of {planned} planned runs stored"] if planned is not None else []
    parts += info["problems"]
    if info["missing_run_count"]:
        parts.append(f"missing run ids {info['missing_run_ids']}")
    return "; ".join(parts)


def _resume(info):
    return f"finish it with `{info.get('resume_command') or 'refexmc run CAMPAIGN -o OUT --resume'}`"


def format_table(comparison):
    """The terminal table: metric, baseline, current, difference [95 % interval], test, p, tolerance, verdict."""
    b, c = comparison.baseline, comparison.current
    lines = [
        f"baseline {b['name']}: {_counts(b)} ({b['out']})",
        f"current  {c['name']}: {_counts(c)} ({c['out']})",
    ]
    lines += [
        f"INCOMPLETE {side}: {_missing(info)}. No verdict until every planned run of both campaigns has flown "
        f"({_resume(info)}); the rows below are of the stored runs only."
        for side, info in comparison.incomplete.items()
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
    paired = comparison.pairing.paired
    lines.append(
        "difference: current - baseline; rates: "
        + (
            "over the run ids both campaigns hold, McNemar exact on the runs whose outcome changed"
            if paired
            else "over each campaign's stored runs, Newcombe hybrid score interval"
        )
        + "; columns: "
        + (
            f"median of the per-run differences, sign-test interval, baseline/current are medians over the "
            f"{len(comparison.pairing.run_ids)} paired runs (ok in both)"
            if paired
            else "difference of the means, Welch interval and t-test, baseline/current are means over each "
            "campaign's ok runs"
        )
        + "; each p is the test its interval inverts"
    )
    judged = [m for m in comparison.metrics if m.requirement]
    if judged:
        lines.append("worse by the requirement: " + "; ".join(f"{m.metric}: {m.requirement}" for m in judged))
    lines.append(
        "REGRESSION: significant at 5 % and worse than the baseline by more than the tolerance; "
        "outputs without a requirement are gated only with --tolerance METRIC=VALUE"
    )
    regressions = comparison.regressions
    names = ", ".join(m.metric for m in regressions)
    found = f"{len(regressions)} regression{'s' if len(regressions) > 1 else ''}"
    if comparison.incomplete:
        missing = "; ".join(
            f"{side}: {_missing(info)}; {_resume(info)}" for side, info in comparison.incomplete.items()
        )
        stored = f"{found} ({names})" if regressions else "no significant regression"
        lines.append(
            f"verdict: INCOMPLETE ({missing}): no verdict until every planned run of both campaigns has flown; "
            f"on the stored runs: {stored}"
        )
    elif regressions:
        lines.append(f"verdict: FAIL ({found}: {names})")
    else:
        lines.append("verdict: PASS (no significant regression)")
    return "\n".join(lines)
