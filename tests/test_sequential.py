"""The stopping rule of `refexmc run --until-decided` (refexmc.campaign.sequential).

Its promise: the rate of wrong verdicts is at most alpha at any true success rate. Checked two
independent ways: by simulating many Bernoulli campaigns in plain numpy, and exactly, by
propagating the distribution of the success count from look to look (a binomial convolution per
batch) over the campaigns not yet decided.
"""

import math

import numpy as np
import pandas as pd
import pytest
from scipy import stats as sps

from refexmc.campaign import sequential
from refexmc.config.requirements import Requirement


def requirement(text):
    metric, op, value = text.split()
    return Requirement(text=text, metric=metric, op=op, value=float(value), source="campaign")


def exact_outcome(p, looks, pass_at, fail_at):
    """(P(PASS), P(FAIL), expected runs flown) of the rule on Bernoulli(p) runs, exactly.

    ``alive[s]``: probability of s successes so far with no verdict yet.
    """
    alive = np.array([1.0])
    previous, passed, failed, flown = 0, 0.0, 0.0, 0.0
    for k, n in enumerate(looks):
        batch = sps.binom.pmf(np.arange(n - previous + 1), n - previous, p)
        alive = np.convolve(alive, batch)  # index: successes after n runs
        counts = np.arange(n + 1)
        passing, failing = counts >= pass_at[k], counts <= fail_at[k]
        passed += alive[passing].sum()
        failed += alive[failing].sum()
        flown += n * alive[passing | failing].sum()
        alive = np.where(passing | failing, 0.0, alive)
        previous = n
    flown += looks[-1] * alive.sum()
    return passed, failed, flown


def simulated_outcome(p, looks, pass_at, fail_at, campaigns, rng):
    """The same by simulation: ``campaigns`` Bernoulli campaigns in numpy, each stopped at its first verdict."""
    successes = (rng.random((campaigns, looks[-1])) < p).cumsum(axis=1)[:, np.array(looks) - 1]
    passing = successes >= np.array(pass_at)
    failing = successes <= np.array(fail_at)
    decided = passing | failing
    first = np.where(decided.any(axis=1), decided.argmax(axis=1), -1)
    rows = np.arange(campaigns)
    verdict_pass = (first >= 0) & passing[rows, first]
    verdict_fail = (first >= 0) & failing[rows, first]
    flown = np.where(first >= 0, np.array(looks)[first], looks[-1])
    return verdict_pass.mean(), verdict_fail.mean(), flown.mean()


# the settings of docs/studies.md: P(success) >= 0.9 and >= 0.99, looks every 50 or 100 runs
CASES = [(0.9, 1000, 50), (0.99, 2000, 100), (0.5, 300, 10)]


@pytest.mark.parametrize("p0, budget, batch", CASES)
def test_wrong_verdicts_at_most_alpha_on_above_and_below_the_requirement(p0, budget, batch):
    alpha = 0.05
    looks = sequential.look_sizes(budget, batch)
    pass_at, fail_at = sequential.boundaries(p0, ">=", looks, alpha)
    for p in (p0 - 0.02, p0 - 0.005, p0, min(1.0, p0 + 0.005), min(1.0, p0 + 0.02)):
        passed, failed, _ = exact_outcome(p, looks, pass_at, fail_at)
        wrong = passed if p < p0 else failed  # 'p >= p0': PASS is right at p0 itself
        assert wrong <= alpha, f"p = {p}: wrong verdicts {wrong:.4f} > alpha {alpha}"


@pytest.mark.parametrize("p0, budget, batch", CASES)
def test_simulated_bernoulli_campaigns_agree_with_the_exact_rates(p0, budget, batch):
    alpha, campaigns = 0.05, 20000
    rng = np.random.default_rng(27)
    looks = sequential.look_sizes(budget, batch)
    pass_at, fail_at = sequential.boundaries(p0, ">=", looks, alpha)
    for p in (p0 - 0.01, p0, min(1.0, p0 + 0.005)):
        exact = exact_outcome(p, looks, pass_at, fail_at)
        simulated = simulated_outcome(p, looks, pass_at, fail_at, campaigns, rng)
        wrong = simulated[0] if p < p0 else simulated[1]
        # 4 binomial standard errors of a rate alpha over 20000 campaigns: 0.006; a failure here
        # by chance has probability ~6e-5 per comparison
        margin = 4 * math.sqrt(alpha * (1 - alpha) / campaigns)
        assert wrong <= alpha + margin
        for got, want in zip(simulated[:2], exact[:2], strict=True):
            assert abs(got - want) <= 4 * math.sqrt(max(want * (1 - want), 1e-4) / campaigns)
        assert abs(simulated[2] - exact[2]) <= 0.02 * budget


def test_looking_often_without_the_correction_exceeds_alpha():
    """The reason for the spending: 95 % Clopper-Pearson bounds at every one of 20 looks wrongly
    fail a design exactly on its requirement far more often than 5 %."""
    p0, looks = 0.9, sequential.look_sizes(1000, 50)
    uncorrected_fail_at = [
        sequential._smallest(n, lambda s, n=n: sps.beta.ppf(0.95, s + 1, n - s) >= p0 if s < n else True) - 1
        for n in looks
    ]
    _, failed, _ = exact_outcome(p0, looks, [n + 1 for n in looks], uncorrected_fail_at)
    assert failed > 0.1
    _, fail_at = sequential.boundaries(p0, ">=", looks, 0.05)
    _, failed, _ = exact_outcome(p0, looks, [n + 1 for n in looks], fail_at)
    assert failed <= 0.05


def test_boundaries_are_the_clopper_pearson_bounds_at_the_spent_alpha():
    """Recomputed from scipy's beta quantiles, not from refexmc.report.stats."""
    looks = sequential.look_sizes(500, 100)
    spent = [0.05 * math.log(1 + (math.e - 1) * n / 500) for n in looks]
    increments = np.diff([0.0, *spent])
    pass_at, fail_at = sequential.boundaries(0.9, ">=", looks, 0.05)
    for n, a, passing, failing in zip(looks, increments, pass_at, fail_at, strict=True):
        lower = [sps.beta.ppf(a, s, n - s + 1) if s > 0 else 0.0 for s in range(n + 1)]
        upper = [sps.beta.ppf(1 - a, s + 1, n - s) if s < n else 1.0 for s in range(n + 1)]
        assert lower[passing] >= 0.9 > lower[passing - 1]
        assert upper[failing] < 0.9 <= upper[failing + 1]
    assert sum(increments) == pytest.approx(0.05, rel=1e-12)


def test_at_most_requirements_mirror_at_least_ones():
    looks = sequential.look_sizes(400, 40)
    # P(success) <= 0.2, counted on the failures, is P(failure) >= 0.8
    assert sequential.boundaries(0.2, "<=", looks, 0.05) == sequential.boundaries(0.8, ">=", looks, 0.05)


def test_a_clearly_good_or_bad_design_stops_early():
    """P(success) >= 0.9 with a budget of 2000: at 0.97 or 0.8 far fewer runs are flown on average."""
    looks = sequential.look_sizes(2000, 50)
    pass_at, fail_at = sequential.boundaries(0.9, ">=", looks, 0.05)
    for p in (0.97, 0.8):
        passed, failed, flown = exact_outcome(p, looks, pass_at, fail_at)
        assert passed + failed > 0.999
        assert flown < 0.2 * 2000, f"p = {p}: {flown:.0f} runs on average"


def test_rules_of_the_requirement_grammar():
    rule = sequential.rule_for(requirement("success_rate >= 0.99"), alpha=0.01)
    assert (rule.kind, rule.p0, rule.op, rule.alpha, rule.column) == ("probability", 0.99, ">=", 0.01, None)
    rule = sequential.rule_for(requirement("failure_rate_upper95 <= 0.05"))
    assert (rule.p0, rule.op, rule.alpha) == (0.95, ">=", 0.05)
    rule = sequential.rule_for(requirement("fuel_remaining.p1 >= 0.2"), alpha=0.1)
    assert (rule.column, rule.event_op, rule.p0, rule.op, rule.alpha) == ("fuel_remaining", ">=", 0.99, ">=", 0.1)
    rule = sequential.rule_for(requirement("attitude_error_end_deg.p99.865_upper95 <= 5"), alpha=0.1)
    assert (rule.event_op, rule.alpha) == ("<=", 0.05) and rule.p0 == pytest.approx(0.99865, rel=1e-15)
    assert sequential.rule_for(requirement("fuel_remaining.min >= 0.2")).kind == "final_fail"
    assert sequential.rule_for(requirement("t_end_s.mean <= 300")).kind == "final_fail"
    assert sequential.rule_for(requirement("fuel_remaining.median >= 0.2")).kind == "open"
    assert sequential.rule_for(requirement("p.rcs.isp_s.mean >= 60")).kind == "open"


def runs_table(success, fuel):
    n = len(success)
    return pd.DataFrame(
        {
            "run_id": np.arange(n),
            "status": ["ok"] * n,
            "success": success,
            "fuel_remaining": fuel,
        }
    )


def test_decision_follows_the_runs_table():
    rules = [
        sequential.rule_for(requirement("success_rate >= 0.5")),
        sequential.rule_for(requirement("fuel_remaining.min >= 0.2")),
        sequential.rule_for(requirement("fuel_remaining.p20 >= 0.3")),  # P(fuel >= 0.3) >= 0.8
    ]
    decision = sequential.Decision(rules, sequential.look_sizes(60, 20))
    success = np.ones(60, dtype=bool)
    fuel = np.full(60, 0.5)
    fuel[5] = 0.25  # below 0.3: 19 of 20 meet the percentile's event at the first look, 20 needed
    fuel[25] = 0.1  # run 25 breaks the minimum: known at the second look (38 of 40 meet, 38 needed)
    table = runs_table(success, fuel)
    assert not decision.look(0, table.iloc[:20])
    assert decision.states == ["PASS", "open", "open"]  # 20 of 20 successes: P >= 0.5 shown
    assert decision.look(1, table.iloc[:40])  # every requirement decided: stop
    assert decision.states == ["PASS", "FAIL", "PASS"]
    assert decision.decided_at == [20, 40, 40]
    record = decision.record(0.05, 20, 40)
    assert record["stopped"] == "decided" and record["looks"] == [20, 40] and record["budget_runs"] == 60
    with pytest.raises(ValueError):
        decision.look(2, table.iloc[:59])


def test_failed_and_errored_runs_never_meet_an_event():
    table = runs_table(np.array([True, False, True]), np.array([0.5, 0.5, np.nan]))
    table.loc[2, "status"] = "error"
    rule = sequential.rule_for(requirement("fuel_remaining.p50 >= 0.2"))
    assert sequential.meets(rule, table).tolist() == [True, False, False]


def test_a_moment_requirement_fails_for_good_at_the_first_failed_run():
    rules = [sequential.rule_for(requirement("fuel_remaining.mean >= 0.2"))]
    decision = sequential.Decision(rules, sequential.look_sizes(30, 10))
    success = np.ones(30, dtype=bool)
    success[14] = False  # a failed flight: the report ranks it at -inf, the mean cannot recover
    table = runs_table(success, np.full(30, 0.5))
    assert not decision.look(0, table.iloc[:10]) and decision.states == ["open"]
    assert decision.look(1, table.iloc[:20]) and decision.states == ["FAIL"] and decision.decided_at == [20]


def test_a_fail_decides_the_campaign_while_other_requirements_are_open():
    """One FAIL decides the campaign's verdict: the looks stop though another requirement is open."""
    rules = [
        sequential.rule_for(requirement("success_rate >= 1.0")),  # never PASSes in a finite campaign
        sequential.rule_for(requirement("fuel_remaining.min >= 0.2")),
    ]
    decision = sequential.Decision(rules, sequential.look_sizes(100, 10))
    fuel = np.full(100, 0.5)
    fuel[13] = 0.1  # breaks the minimum at the second look
    table = runs_table(np.ones(100, dtype=bool), fuel)
    assert not decision.look(0, table.iloc[:10]) and decision.verdict == "open"
    assert decision.look(1, table.iloc[:20])
    assert decision.states == ["open", "FAIL"] and decision.verdict == "FAIL"
    record = decision.record(0.05, 10, 20)
    assert record["stopped"] == "decided" and record["verdict"] == "FAIL" and record["looks"] == [10, 20]
