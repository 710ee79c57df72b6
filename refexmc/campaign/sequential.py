"""Stopping a campaign when its requirements are decided: a group-sequential test per requirement.

A campaign with a run budget N is looked at after every batch, at n_1 < n_2 < ... < n_K = N runs
(the looks are fixed before the first run). A requirement on a probability (``success_rate >=
0.99``; ``fuel_remaining.p1 >= 0.2``, i.e. P(a run keeps >= 20 %) >= 0.99) is a hypothesis on the
true rate p of a Bernoulli event per run. At look k it is decided

- PASS when the one-sided Clopper-Pearson bound at confidence 1 - alpha_k shows p on the
  requirement's side (``p >= p0``: the lower bound is >= p0),
- FAIL when the opposite bound shows p on the other side (the upper bound is < p0),

and stays decided. The alpha of the requirement is spent over the looks with the Lan-DeMets
spending function of Pocock type, alpha(t) = alpha ln(1 + (e - 1) t) at the information fraction
t = n / N (Lan and DeMets 1983, Biometrika 70(3) 659-663, eq. 3; Kim and DeMets 1987), alpha_k =
alpha(t_k) - alpha(t_(k-1)). A wrong verdict needs a bound at some look on the wrong side of the
true p, an event of probability at most alpha_k at look k, so by the union bound the rate of
wrong verdicts is at most sum alpha_k = alpha(1) = alpha, whatever p is (conservative: the looks'
correlation is not used). Pocock-type spending spends more of alpha early than O'Brien-Fleming
type, which is what stopping a clearly good or clearly bad design early needs.

Requirements that are not on a probability are settled only where the sample makes the verdict
final: ``<column>.min >= v`` (and ``max <= v``) fails for good once one run fails it, a moment
statistic (mean, std, ...) once a failed or errored run is stored (the report ranks it at the
failing end, docs/report.md); otherwise they stay open until the budget.

Everything here is plain Python on a runs table; the bounds are ``refexmc.binomial``'s, the report's.
"""

import math
from dataclasses import dataclass

import numpy as np

from refexmc.binomial import clopper_pearson_lower, clopper_pearson_upper
from refexmc.config.errors import ConfigError
from refexmc.config.requirements import MOMENT_STATS, parse_percentile_stat, split_metric

DEFAULT_ALPHA = 0.05  # wrong-verdict rate of a requirement that states no confidence of its own
STATED_ALPHA = 0.05  # the requirements named ``..._lower95``/``..._upper95`` state 95 % confidence
DEFAULT_LOOKS = 10  # looks over the budget when no batch size is given

PASS, FAIL, OPEN = "PASS", "FAIL", "open"


def spending(t, alpha):
    """Alpha spent by information fraction t in [0, 1]: Pocock type, alpha ln(1 + (e - 1) t) (Lan-DeMets 1983)."""
    return alpha * math.log1p((math.e - 1.0) * min(max(t, 0.0), 1.0))


def look_sizes(budget, batch):
    """Runs at each look: batch, 2 batch, ..., and the budget last."""
    if budget < 1 or batch < 1:
        raise ValueError(f"budget and batch must be >= 1, got {budget}, {batch}")
    return [*range(batch, budget, batch), budget]


def alpha_increments(looks, alpha):
    """alpha_k spent at each look (they sum to alpha)."""
    fractions = [n / looks[-1] for n in looks]
    spent = [spending(t, alpha) for t in fractions]
    return [b - a for a, b in zip([0.0, *spent[:-1]], spent, strict=True)]


def _smallest(n, holds):
    """Smallest s in 0..n with ``holds(s)`` (monotone: false, then true); n + 1 if none."""
    low, high = 0, n + 1
    while low < high:
        middle = (low + high) // 2
        if holds(middle):
            high = middle
        else:
            low = middle + 1
    return low


def boundaries(p0, op, looks, alpha):
    """Per look, (PASS when successes >= pass_at, FAIL when successes <= fail_at) for the hypothesis
    ``p OP p0`` on the rate p of a Bernoulli event, ``op`` one of ``>= > <= <``.

    pass_at is n + 1 where no count passes, fail_at is -1 where none fails.
    """
    if op not in (">=", ">", "<=", "<"):
        raise ValueError(f"no sequential test for operator {op!r}")
    pass_at, fail_at = [], []
    for n, alpha_k in zip(looks, alpha_increments(looks, alpha), strict=True):
        passing, failing = _look_boundary(n, 1.0 - alpha_k, p0, op)
        pass_at.append(passing)
        fail_at.append(failing)
    return pass_at, fail_at


def _look_boundary(n, confidence, p0, op):
    """(pass_at, fail_at) of :func:`boundaries` at one look of n runs with bounds at ``confidence``."""
    above = op in (">", "<=")  # these compare a bound with p0 strictly: '>' to PASS, '<=' to FAIL

    def lower_reaches(s):  # the lower bound shows p above p0 (at or above for ``p >= p0``'s PASS)
        bound = clopper_pearson_lower(s, n, confidence)
        return bound > p0 if above else bound >= p0

    def upper_reaches(s):  # the upper bound no longer shows p below p0
        bound = clopper_pearson_upper(s, n, confidence)
        return bound > p0 if above else bound >= p0

    # both bounds increase with s, so each condition holds from some count on
    if op in (">=", ">"):
        # PASS: lower >= p0 (> for '>'); FAIL: upper < p0 (<= for '>')
        return _smallest(n, lower_reaches), _smallest(n, upper_reaches) - 1
    # ``p <= p0``: PASS while upper <= p0 (< for '<'), FAIL once lower > p0 (>= for '<'); both
    # returned as counts of the complement, n - s, so that PASS is again "at least" and FAIL "at most"
    pass_at_most = _smallest(n, upper_reaches) - 1
    fail_from = _smallest(n, lower_reaches)
    return n - pass_at_most, n - fail_from


@dataclass(frozen=True)
class Rule:
    """How one requirement is settled: ``kind`` "probability" (a Bernoulli event per run, the
    hypothesis ``p op p0`` at ``alpha``), "final_fail" (a sample verdict that, once failed, stays
    failed) or "open" (decided only at the budget); ``why``: one line for the report."""

    requirement: object
    kind: str
    why: str
    column: str = None  # the runs column the event compares (None: the flight's success)
    event_op: str = None  # a run meets the requirement when ``value event_op threshold``
    op: str = None
    p0: float = None
    alpha: float = None

    @property
    def counts_complement(self):
        """``p <= p0`` hypotheses count the runs that do not meet the event (see :func:`boundaries`)."""
        return self.op in ("<=", "<")


def _probability(requirement, why, p0, op, alpha, column=None, event_op=None):
    return Rule(requirement, "probability", why, column=column, event_op=event_op, op=op, p0=p0, alpha=alpha)


def rule_for(requirement, alpha=DEFAULT_ALPHA):
    """The :class:`Rule` that settles ``requirement`` (a ``refexmc.config.requirements.Requirement``)."""
    metric, op, value = requirement.metric, requirement.op, requirement.value
    if metric == "success_rate" and op != "==":
        return _probability(requirement, f"P(success) {op} {value:g} at alpha {alpha:g}", value, op, alpha)
    if metric == "success_rate_lower95" and op in (">=", ">"):
        return _probability(requirement, f"P(success) {op} {value:g} at 95 % confidence", value, op, STATED_ALPHA)
    if metric == "success_rate_upper95" and op in ("<=", "<"):
        return _probability(requirement, f"P(success) {op} {value:g} at 95 % confidence", value, op, STATED_ALPHA)
    if metric == "failure_rate_upper95" and op in ("<=", "<"):
        success_op = ">=" if op == "<=" else ">"
        why = f"P(success) {success_op} {1 - value:g} at 95 % confidence"
        return _probability(requirement, why, 1.0 - value, success_op, STATED_ALPHA)
    column, stat = split_metric(metric)
    if stat is None or column.startswith("p."):
        return Rule(requirement, "open", "not a probability of a flight outcome: decided at the budget")
    if stat.startswith("p") and op != "==":
        try:
            percent, bound = parse_percentile_stat(stat)
        except ValueError:
            percent, bound = None, None
        stated = {None: alpha, "lower": STATED_ALPHA if op in (">=", ">") else None}
        stated["upper"] = STATED_ALPHA if op in ("<=", "<") else None
        if percent is not None and stated[bound] is not None:
            # q-th percentile >= v <=> P(value >= v) >= 1 - q/100; <= v <=> P(value <= v) >= q/100
            p0 = 1.0 - percent / 100.0 if op in (">=", ">") else percent / 100.0
            level = f"alpha {alpha:g}" if bound is None else "95 % confidence"
            why = f"P({column} {op} {value:g}) >= {p0:g} at {level}"
            return _probability(requirement, why, p0, ">=", stated[bound], column=column, event_op=op)
    if (stat == "min" and op in (">=", ">")) or (stat == "max" and op in ("<=", "<")):
        return Rule(requirement, "final_fail", f"fails for good at the first run with {column} not {op} {value:g}")
    if stat in MOMENT_STATS and op != "==":
        return Rule(requirement, "final_fail", "fails for good at the first failed or errored run")
    return Rule(requirement, "open", "decided at the budget")


COMPARE = {">=": np.greater_equal, ">": np.greater, "<=": np.less_equal, "<": np.less}


def meets(rule, runs):
    """Boolean array: each run of the runs table meets the rule's event (errored and failed runs never do)."""
    flown = (runs["status"] == "ok").to_numpy() & runs["success"].fillna(False).to_numpy(dtype=bool)
    if rule.column is None:
        return flown
    values = column_values(runs, rule.column)
    with np.errstate(invalid="ignore"):
        return flown & COMPARE[rule.event_op](values, rule.requirement.value)


def column_values(runs, column):
    if column == "pulses_total":
        return runs[[c for c in runs.columns if c.startswith("pulses_")]].to_numpy(dtype=float).sum(axis=1)
    return runs[column].to_numpy(dtype=float)


def _final_fail(rule, runs):
    """The sample verdict of a "final_fail" rule has failed (it cannot pass again with more runs)."""
    failing = ~((runs["status"] == "ok").to_numpy() & runs["success"].fillna(False).to_numpy(dtype=bool))
    if failing.any():
        return True
    column, stat = split_metric(rule.requirement.metric)
    if stat not in ("min", "max"):
        return False
    values = column_values(runs, column)
    values = values[np.isfinite(values)]
    return bool(len(values)) and not bool(COMPARE[rule.requirement.op](values, rule.requirement.value).all())


class Decision:
    """The state of each requirement over the looks of a campaign of budget ``looks[-1]``."""

    def __init__(self, rules, looks):
        self.rules = list(rules)
        self.looks = list(looks)
        self.bounds = [
            boundaries(r.p0, r.op, self.looks, r.alpha) if r.kind == "probability" else None for r in self.rules
        ]
        self.states = [OPEN] * len(self.rules)
        self.decided_at = [None] * len(self.rules)
        self.history = []  # per look: {"runs", "states", "meeting"}

    def look(self, k, runs):
        """Update the states with the runs table at look k (it holds run ids 0 .. looks[k] - 1)."""
        n = self.looks[k]
        if len(runs) != n:
            raise ValueError(f"look {k} expects {n} runs, got {len(runs)}")
        meeting = []
        for i, rule in enumerate(self.rules):
            count = None
            if rule.kind == "probability":
                count = int(meets(rule, runs).sum())
                if self.states[i] == OPEN:
                    pass_at, fail_at = self.bounds[i]
                    tested = n - count if rule.counts_complement else count
                    if tested >= pass_at[k]:
                        self.states[i], self.decided_at[i] = PASS, n
                    elif tested <= fail_at[k]:
                        self.states[i], self.decided_at[i] = FAIL, n
            elif rule.kind == "final_fail" and self.states[i] == OPEN and _final_fail(rule, runs):
                self.states[i], self.decided_at[i] = FAIL, n
            meeting.append(count)
        self.history.append({"runs": n, "states": list(self.states), "meeting": meeting})
        return self.decided

    @property
    def verdict(self):
        """The campaign's verdict so far: FAIL once any requirement FAILs (the campaign fails
        whatever the others do), PASS once every one PASSes, else open."""
        if FAIL in self.states:
            return FAIL
        return PASS if all(state == PASS for state in self.states) else OPEN

    @property
    def decided(self):
        """The campaign's verdict is decided (a FAIL decides it): flying on cannot change it."""
        return self.verdict != OPEN

    def record(self, alpha, batch, flown):
        """The JSON-ready stopping record (``manifest.json`` ``until_decided``); ``flown``: runs in OUT."""
        return {
            "budget_runs": self.looks[-1],
            "batch_runs": batch,
            "alpha": alpha,
            "spending": "Lan-DeMets, Pocock type: alpha ln(1 + (e - 1) n / budget); one-sided Clopper-Pearson bounds",
            "looks": [h["runs"] for h in self.history],
            "decided_at_runs": self.history[-1]["runs"] if self.history else 0,
            "runs_flown": flown,
            "stopped": "decided" if self.decided else "budget",
            "verdict": self.verdict,
            "requirements": [
                {
                    "requirement": rule.requirement.text,
                    "rule": rule.kind,
                    "test": rule.why,
                    "state": state,
                    "decided_at_runs": at,
                }
                for rule, state, at in zip(self.rules, self.states, self.decided_at, strict=True)
            ],
        }


def check_sequential_campaign(campaign, file=None):
    """ConfigError unless the runs of ``campaign`` are the same whatever its number of runs (so a
    campaign stopped early holds the first runs of a longer one) and it has requirements."""
    if "sweep" in campaign:
        raise ConfigError(
            "--until-decided does not stop a sweep (fly its points' campaigns)", file=file, path=("sweep",)
        )
    if "rare_event" in campaign:
        raise ConfigError(
            "--until-decided cannot be used with a rare_event study: it flies level by level, "
            "each level's runs decided by the last (docs/rare-events.md)",
            file=file,
            path=("rare_event",),
        )
    sampling = campaign.get("sampling", "random")
    if sampling in ("lhs", "saltelli"):
        raise ConfigError(
            f"--until-decided needs 'sampling: random' or 'sobol': a {sampling} design depends on the "
            "number of runs, so a campaign stopped early would not hold the first runs of a longer one",
            file=file,
            path=("sampling",),
        )
    for key in ("failures", "wheel_failures"):
        if (campaign.get(key) or {}).get("mode") == "enumerate":
            raise ConfigError(
                "--until-decided cannot stop an enumeration: its runs are the listed failure sets",
                file=file,
                path=(key, "mode"),
            )
    if not campaign.get("requirements"):
        raise ConfigError(
            "--until-decided needs requirements to decide (campaign key 'requirements')",
            file=file,
            path=("requirements",),
        )
