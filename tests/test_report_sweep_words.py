"""A failure sweep (one run per failure set, nothing dispersed): a factor without runs within its
levels is flagged, not ranked (its eta^2 is 1 by chance), and the runs beside the nominal one are
failure-set runs, not "dispersed" ones (docs/report.md)."""

import numpy as np
import pytest
from test_report import synthetic_runs, write_out

from refexmc.report import make_report
from refexmc.report.factors import replication_flag


@pytest.fixture(scope="module")
def sweep(tmp_path_factory):
    """The nominal run and one run per single and double failure of 6 thrusters (22 runs); thruster
    5 failed costs propellant."""
    sets = [""] + [str(k) for k in range(1, 7)] + [f"{a},{b}" for a in range(1, 7) for b in range(a + 1, 7)]
    rows = synthetic_runs(n=len(sets), errored=(), failed=(), sets=sets, seed=4)
    rng = np.random.default_rng(4)
    for row, failed in zip(rows, sets, strict=True):
        row["fuel_remaining"] = 0.8 - (0.3 if "5" in failed.split(",") else 0.0) - 0.02 * rng.uniform()
        row["fuel_used_kg"] = 1.96 * (1.0 - row["fuel_remaining"])
        # undispersed; as in a flown failure-sweep.yaml, the nominal run 0 alone has another input
        # value (its propellant load), so one input varies and the scatter figure has a panel
        row["p.rcs.isp_s"] = 70.0 if row["run_id"] else 68.0
        row["p.navigation.rate_noise_deg_s"] = 0.0
    return write_out(tmp_path_factory.mktemp("sweep") / "out", rows, requirements=["fuel_remaining.min >= 0.2"])


def enumerate_failures(out):
    """Mark the stored campaign as an enumeration of failures (as failure-sweep.yaml is)."""
    import yaml

    path = out / "campaign.resolved.yaml"
    campaign = yaml.safe_load(path.read_text())
    campaign["failures"] = {"mode": "enumerate", "sizes": [1, 2]}
    path.write_text(yaml.safe_dump(campaign))


def test_a_factor_with_one_run_per_level_is_flagged_not_ranked(sweep):
    enumerate_failures(sweep)
    report = make_report(sweep, html=True)
    rows = report["summary"]["sensitivity"]["fuel_remaining"]
    by_name = {r["parameter"]: r for r in rows}
    set_row = by_name["failed thruster set (undetected)"]
    assert set_row["supported"] is False and set_row["eta2"] is None and set_row["p_value"] is None
    assert "no within-level replication" in set_row["flag"] and set_row["runs_needed"] == 2 * 22
    assert rows[0]["parameter"] == "thruster 5 failed (undetected)"  # ranked first, the set last
    assert rows[-1] is set_row
    line = next(line for line in report["text"].splitlines() if line.startswith("what drives fuel_remaining"))
    assert line.startswith("what drives fuel_remaining: thruster 5 failed (undetected) (η²")
    assert "failed thruster set (undetected) not supported: 22 runs over 22 levels" in line
    page = (sweep / "report" / "index.html").read_text()
    assert "no within-level replication" in page


def test_an_undispersed_enumeration_counts_failure_set_runs_against_the_nominal(sweep):
    enumerate_failures(sweep)
    report = make_report(sweep, html=True)
    against = report["summary"]["nominal"]["propellant_used_vs_dispersed"]
    assert against["others"] == "failure-set runs" and against["of"] == 21
    assert "dispersed" not in against["covers"]
    assert "failure-set runs using more propellant than the nominal run" in report["text"]
    assert "dispersed runs using more" not in report["text"].lower()
    page = (sweep / "report" / "index.html").read_text()
    assert "Failure-set runs using more propellant than the nominal run" in page


def test_replication_needs_two_runs_per_level_on_average():
    assert replication_flag(40, 2) == "" and replication_flag(74, 37) == ""
    assert "no within-level replication" in replication_flag(37, 37)
    assert "3 runs beyond one per level" in replication_flag(40, 37)
