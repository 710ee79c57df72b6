"""A pointing record (docs/pointing.md) is a requirement on its runs column everywhere the report
uses requirement columns: statistics order and tail, sensitivity, convergence and the per-failed-
wheel-set verdicts (the walkthrough's IRASSI finding, on a synthetic runs table)."""

import numpy as np
import pytest
from test_factors import IRASSI_MODES, irassi_like_runs
from test_report import write_out

from refexmc.report import make_report

APE = "ape_total_temporal_arcsec"
APE_RECORD = {  # campaigns/irassi-fine-pointing.yaml's, over the whole flight and every run
    "index": "APE",
    "error": "total",
    "bound_arcsec": 0.4,
    "p_c": 0.9973,
    "interpretation": "temporal",
    "window": {"from_s": 0.0},
    "confidence": 0.95,
    "runs": "all",  # the failed-wheel runs count: the record fails
    "runs_fraction": 0.99,
}


@pytest.fixture(scope="module")
def irassi(tmp_path_factory):
    """400 runs; a failed wheel 1 or 2 puts the APE's time quantile far above 0.4 arcsec (0.8 x the
    largest error); the wheel requirements pass everywhere, the pointing record fails."""
    rows = irassi_like_runs()
    rng = np.random.default_rng(11)
    for row in rows:
        row[APE] = 0.8 * row["pointing_max_arcsec"]
        row["pointing_rms_x_arcsec"] = 0.3 * row["pointing_max_arcsec"]
        row["wheel_momentum_peak_n_m_s"] = float(rng.uniform(30.0, 50.0))
        row["wheel_saturated_s"] = float(rng.uniform(200.0, 400.0))
    out = write_out(
        tmp_path_factory.mktemp("irassi-ape") / "out",
        rows,
        requirements=["success_rate >= 1.0", APE_RECORD, "wheel_momentum_peak_n_m_s.max < 68"],
        histories=False,
        modes=IRASSI_MODES,
        vehicle="irassi",
    )
    return rows, make_report(out, html=True)


def test_the_pointing_record_column_is_a_requirement_column_with_its_upper_tail(irassi):
    _, report = irassi
    summary = report["summary"]
    plan = summary["outputs"]
    # in the campaign file's order: the record before the wheel requirement
    assert plan["requirement_columns"] == [APE, "wheel_momentum_peak_n_m_s"]
    assert plan["tails"][APE] == "upper"  # an upper bound: the upper tail is worse
    assert summary["columns"][APE]["tail"] == "upper"
    assert "required: APE(total) <= 0.4 arcsec" in plan["labels"][APE]
    assert APE not in plan["other_columns"]
    lines = report["text"].splitlines()
    upper = lines.index(next(line for line in lines if line.startswith("larger is worse")))
    assert lines[upper + 2].startswith(APE)  # first row of the upper-tail table, not last of the two-sided one


def test_what_drives_and_convergence_follow_the_failing_pointing_record(irassi):
    _, report = irassi
    summary = report["summary"]
    record = next(r for r in summary["requirements"] if r.get("kind") == "pointing")
    assert not record["passed"]
    sensitivity = summary["sensitivity"]
    assert sensitivity["targets"][0] == APE  # the only failing requirement, first
    assert sensitivity["figure_targets"][0] == APE
    assert sensitivity[APE][0]["parameter"] == "failed wheel set (undetected)"
    assert summary["convergence"]["column"] == APE and summary["convergence"]["tail"] == "upper"
    assert f"what drives {APE}: failed wheel set (undetected)" in report["text"]
    assert "wheel_failure_sets" in summary


def test_each_failed_wheel_set_is_judged_by_the_pointing_record(irassi):
    rows, report = irassi
    wheel_sets = report["summary"]["wheel_failure_sets"]
    name = f"{APE}.within"
    # the requirements only: no statistic without a requirement beside them
    assert wheel_sets["statistics"] == [name, "wheel_momentum_peak_n_m_s.max"]
    by_set = {s["failed_wheels"]: s for s in wheel_sets["sets"]}
    for key, s in by_set.items():
        group = [r for r in rows if r["status"] == "ok" and r["failed_wheels"] == key]
        within = sum(r["success"] and r[APE] <= 0.4 for r in group) / len(group)
        assert s[name] == pytest.approx(within)
        assert s["verdicts"][name] == (within >= 0.99)
        assert s["passed"] == (all(s["verdicts"].values()) and s["successes"] == s["runs"])
    assert by_set["1"][name] == 0.0 and not by_set["1"]["passed"]
    assert by_set["2"][name] == 0.0 and not by_set["2"]["passed"]
    assert "share of the set's runs within 0.4 arcsec" in wheel_sets["meanings"][name]
