"""A success-rate requirement's verdict says what the runs can show, both ways, and names the runs
that count as failing it (docs/report.md: `failing_count`, `failing_run_ids`)."""

import pytest
from test_report import synthetic_runs, write_out

from refexmc.binomial import clopper_pearson_upper
from refexmc.report import make_report


def verdict_of(tmp_path, failed, errored=(), requirement="success_rate >= 0.95", n=100):
    rows = synthetic_runs(n=n, errored=errored, failed=failed)
    out = write_out(tmp_path / "out", rows, requirements=[requirement], histories=False)
    return next(r for r in make_report(out, html=False)["requirements"] if r["requirement"] == requirement)


def test_a_fail_by_the_estimate_whose_upper_bound_reaches_the_bound_is_not_demonstrated_either_way(tmp_path):
    """The hop's case: 94 of 100 against 0.95; the one-sided 95 % upper bound 0.974 reaches 0.95."""
    failed = (13, 30, 37, 40, 64, 75)
    verdict = verdict_of(tmp_path, failed)
    assert not verdict["passed"] and verdict["actual"] == pytest.approx(0.94)
    upper = clopper_pearson_upper(94, 100)
    assert upper >= 0.95
    assert verdict["note"].startswith("failed by the estimate only")
    assert f"{upper:.3g}" in verdict["note"] and "not demonstrated either way" in verdict["note"]
    assert "success_rate_upper95 < 0.95" in verdict["note"]
    assert verdict["failing_count"] == 6 and verdict["failing_run_ids"] == list(failed)


def test_a_fail_the_upper_bound_confirms_gets_no_caveat(tmp_path):
    failed = tuple(range(1, 21))  # 80 of 100: the upper bound 0.87 is below 0.95
    verdict = verdict_of(tmp_path, failed)
    assert not verdict["passed"] and clopper_pearson_upper(80, 100) < 0.95
    assert verdict["note"] == ""
    assert verdict["failing_count"] == 20


def test_errored_runs_count_as_failing_the_success_rate(tmp_path):
    verdict = verdict_of(tmp_path, failed=(3, 11), errored=(7,), requirement="success_rate >= 0.5")
    assert verdict["passed"]
    assert verdict["failing_count"] == 3 and verdict["failing_run_ids"] == [3, 7, 11]
    error = verdict_of(tmp_path / "e", failed=(3, 11), errored=(7,), requirement="error_count <= 0")
    assert error["failing_run_ids"] == [7]
