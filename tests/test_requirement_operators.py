"""Every requirement operator evaluated (not only parsed) on campaigns with failed and errored runs.

A failed flight or errored run stands at the failing end of the distribution: -inf for >= and >,
+inf for <= and <, and == cannot be met (report/requirements.py, docs/report.md). Each case is
checked on the same runs without the failures too, so a verdict that ignored them would show.
"""

import pytest
from test_report import synthetic_runs, write_out

from refexmc.report import make_report
from refexmc.report.requirements import failing_description, listed_ids, overall_verdict, plural, requirement_label

FAILED, ERRORED = (3, 11), (7,)


def verdicts(tmp_path, name, requirements, failed=(), errored=()):
    rows = synthetic_runs(n=30, failed=failed, errored=errored)
    out = write_out(tmp_path / name, rows, requirements=requirements, histories=False)
    report = make_report(out, html=False)
    return {v["requirement"]: v for v in report["requirements"]}, report, rows


def successful_extremes(rows):
    fuel = [r["fuel_remaining"] for r in rows if r["status"] == "ok" and r["success"]]
    return min(fuel), max(fuel)


def requirement_set(low, high):
    """Requirements every successful flight meets, strict and not, on both sides; the bounds are
    the successful flights' own extremes; p1 and p99 of 30 runs fall within the failing ones."""
    below, above = low - 0.01, high + 0.01
    return {
        f"fuel_remaining.min >= {below}": "low",
        f"fuel_remaining.min > {below}": "low",
        f"fuel_remaining.p1 > {below}": "low",
        f"fuel_remaining.mean > {below}": "low",
        f"fuel_remaining.max <= {above}": "high",
        f"fuel_remaining.max < {above}": "high",
        f"fuel_remaining.p99 < {above}": "high",
        f"fuel_remaining.mean_plus_3sd < {above + 1.0}": "high",
        "modes_completed.min == 7": None,
    }


@pytest.mark.parametrize(("failed", "errored"), [(FAILED, ()), ((), ERRORED), (FAILED, ERRORED)])
def test_failing_runs_fail_every_operator_that_the_successful_flights_meet(tmp_path, failed, errored):
    clean_rows = synthetic_runs(n=30, failed=(), errored=())
    texts = list(requirement_set(*successful_extremes(clean_rows)))
    clean, clean_report, _ = verdicts(tmp_path, "clean", texts)
    assert clean_report["verdict"] == "PASS", [v for v in clean.values() if not v["passed"]]
    assert clean_report["passed"] is True
    # the same runs, some of them failed or errored: every requirement fails, with the ids named
    judged, report, _ = verdicts(tmp_path, "failing", texts, failed=failed, errored=errored)
    assert report["verdict"] == ("ERRORED" if errored else "FAIL") and report["passed"] is False
    for text in texts:
        verdict = judged[text]
        assert verdict["passed"] is False, (text, verdict)
        assert verdict["failing_run_ids"] == sorted((*failed, *errored)), text


def test_strict_operators_put_the_failing_runs_on_their_failing_side(tmp_path):
    """min > x and max < x: the failing runs rank at -inf and +inf respectively (not the other way
    round, which would leave min and max to the successful flights and read PASS)."""
    low, high = successful_extremes(synthetic_runs(n=30, failed=FAILED, errored=()))
    texts = [f"fuel_remaining.min > {low - 0.2}", f"fuel_remaining.max < {high + 0.2}"]
    judged, _, _ = verdicts(tmp_path, "strict", texts, failed=FAILED)
    assert judged[texts[0]]["actual"] is None and judged[texts[0]]["passed"] is False  # -inf: not computable
    assert judged[texts[1]]["actual"] is None and judged[texts[1]]["passed"] is False
    assert "fails because of the failed flights 3, 11" in judged[texts[0]]["note"]
    # a percentile whose tail holds the two failing runs still passes, from the successful flights
    tolerant = [f"fuel_remaining.p50 > {low - 0.2}", f"fuel_remaining.p50 < {high + 0.2}"]
    judged, _, _ = verdicts(tmp_path, "tolerant", tolerant, failed=FAILED)
    assert all(judged[t]["passed"] for t in tolerant), judged


def test_strict_operators_are_strict_at_the_boundary(tmp_path):
    """With no failing run, a bound equal to the statistic passes >= and <= and fails > and <."""
    low, high = successful_extremes(synthetic_runs(n=30, failed=(), errored=()))
    texts = [
        f"fuel_remaining.min >= {low!r}",
        f"fuel_remaining.min > {low!r}",
        f"fuel_remaining.max <= {high!r}",
        f"fuel_remaining.max < {high!r}",
    ]
    judged, _, _ = verdicts(tmp_path, "boundary", texts)
    assert [judged[t]["passed"] for t in texts] == [True, False, True, False]
    assert judged[texts[1]]["actual"] == low


@pytest.mark.parametrize(
    ("text", "passes"),
    [
        ("success_rate >= 0.9", True),  # 27 of 30: 0.9
        ("success_rate > 0.9", False),
        ("success_rate <= 0.9", True),
        ("success_rate < 0.9", False),
        ("success_rate < 0.91", True),
        ("success_rate == 0.9", True),
    ],
)
def test_campaign_metrics_count_errored_runs_as_unsuccessful(tmp_path, text, passes):
    """Two failed flights and one errored run of 30: success_rate = 27 / 30 = 0.9 exactly as computed."""
    judged, _, _ = verdicts(tmp_path, "rate", [text], failed=FAILED, errored=ERRORED)
    assert judged[text]["actual"] == 27 / 30
    assert judged[text]["passed"] is passes
    assert judged[text]["covers"] == "all 30 runs (1 errored run count as unsuccessful)"


def completeness(complete=True, errored=0, missing=(), planned=30):
    return {
        "complete": complete,
        "runs_planned": planned,
        "runs_stored": planned - len(missing),
        "problems": [] if complete else ["manifest status running"],
        "missing_run_count": len(missing),
        "missing_run_ids": list(missing),
        "errored_count": errored,
        "errored_run_ids": list(range(errored)),
    }


MET, UNMET = {"passed": True}, {"passed": False}


@pytest.mark.parametrize(
    ("state", "verdicts", "expected"),
    [
        (completeness(), [MET, MET], ("PASS", True)),
        (completeness(), [MET, UNMET], ("FAIL", False)),
        (completeness(), [], ("NO REQUIREMENTS", True)),
        (completeness(errored=1), [MET], ("ERRORED", False)),  # every requirement met, still not accepted
        (completeness(errored=1), [], ("ERRORED", False)),
        (completeness(complete=False, missing=(4, 5)), [MET], ("INCOMPLETE", False)),
        (completeness(complete=False, missing=(4,), errored=1), [], ("INCOMPLETE", False)),
    ],
)
def test_only_pass_and_no_requirements_exit_zero(state, verdicts, expected):
    """The overall verdict and whether `report` exits 0 (docs/report.md): incompleteness first,
    then errored runs, whatever the requirements say."""
    verdict, passed, banner = overall_verdict(state, verdicts)
    assert (verdict, passed) == expected
    assert (banner != "") == (verdict in ("INCOMPLETE", "ERRORED"))  # a banner: no verdict can be given
    if verdict == "INCOMPLETE":
        assert f"missing run ids {list(state['missing_run_ids'])}" in banner and "--resume" in banner
        assert f"requirements: {sum(v['passed'] for v in verdicts)} of {len(verdicts)} met" in banner
    if verdict == "ERRORED":
        assert "1 of 30 runs raised errors (run ids 0)" in banner


@pytest.mark.parametrize(("op", "passes"), [("<=", True), ("<", False), (">=", True), (">", False)])
def test_an_input_column_is_judged_over_every_run_failed_and_errored_included(tmp_path, op, passes):
    """p.<path> is an input: every run has its value, a failed or errored run's too, and none is
    ranked at a failing end. The bound is the largest (<=, <) or smallest (>=, >) drawn value."""
    rows = synthetic_runs(n=30, failed=FAILED, errored=ERRORED)
    drawn = [r["p.rcs.isp_s"] for r in rows]
    bound = max(drawn) if op.startswith("<") else min(drawn)
    stat = "max" if op.startswith("<") else "min"
    text = f"p.rcs.isp_s.{stat} {op} {bound!r}"
    judged, _, _ = verdicts(tmp_path, "input", [text], failed=FAILED, errored=ERRORED)
    assert judged[text]["actual"] == bound and judged[text]["passed"] is passes
    assert judged[text]["failing_count"] == 0 and judged[text]["covers"].startswith("all 30 runs (an input")


@pytest.mark.parametrize(
    ("passed", "overall", "label"),
    [
        (True, "PASS", "PASS"),
        (True, "FAIL", "PASS"),
        (False, "FAIL", "FAIL"),
        (True, "ERRORED", "met"),  # no PASS anywhere while the campaign cannot be accepted
        (True, "INCOMPLETE", "met"),
        (False, "INCOMPLETE", "FAIL"),
    ],
)
def test_a_met_requirement_reads_pass_only_when_the_campaign_can_pass(passed, overall, label):
    assert requirement_label({"passed": passed}, overall) == label


def test_the_words_around_a_verdict_count_and_list_runs():
    """What `report` prints beside a verdict: singular and plural, ids truncated after ten."""
    assert [plural(n, "run") for n in (0, 1, 2)] == ["0 runs", "1 run", "2 runs"]
    assert listed_ids(range(10)) == "0, 1, 2, 3, 4, 5, 6, 7, 8, 9"
    assert listed_ids(range(11)) == "0, 1, 2, 3, 4, 5, 6, 7, 8, 9, ... (11 in all)"
    assert failing_description([3], []) == "failed flight 3"
    assert failing_description([3, 11], [7]) == "failed flights 3, 11 and errored run 7"
    assert failing_description([], [7, 8]) == "errored runs 7, 8"


def test_a_success_rate_met_by_its_estimate_only_says_so(tmp_path):
    """30 runs without a failure meet 'success_rate >= 0.95' by the estimate (1.0) but not with 95 %
    confidence (one-sided Clopper-Pearson lower bound 0.05^(1/30) = 0.905): the verdict stands (the
    requirement is written on the estimate) and its note says how to require it with confidence
    and that 59 runs without a failure would (0.95^59 = 0.0485 <= 0.05 < 0.95^58)."""
    judged, _, _ = verdicts(tmp_path, "estimate", ["success_rate >= 0.95", "success_rate >= 0.9"])
    note = judged["success_rate >= 0.95"]["note"]
    assert judged["success_rate >= 0.95"]["passed"] is True
    assert f"lower bound is {0.05 ** (1 / 30):.3g} over 30 runs" in note
    assert "'success_rate_lower95 >= 0.95'" in note and "at least 59 runs" in note
    assert judged["success_rate >= 0.9"]["note"] == ""  # 0.905 >= 0.9: met with confidence too
