"""Discrete causes in "what drives" (refexmc.report.factors): each failed unit, the failure set and
choice inputs ranked with the continuous inputs on one scale (eta^2 of the output's ranks), their
significance by Kruskal-Wallis, against scipy; the issue's IRASSI case on a synthetic runs table."""

import numpy as np
import pytest
from scipy import stats as sps
from test_report import synthetic_runs, write_out

from refexmc.report import data, factors, stats
from refexmc.report.summary import build

IRASSI_MODES = {"MANOEUVRE": 400.0, "SCIENCE": 64800.0}


def irassi_like_runs(n=400, seed=3):
    """IRASSI's finding, by construction: one wheel fails (undetected) in ~20 % of the runs; a failed
    wheel 1 or 2 pushes the largest pointing error above 0.6 arcsec, wheels 3 and 4 do not matter;
    an initial rate moves the error in every run, less strongly (its rho^2 beats each single
    wheel's indicator, not the failure set)."""
    rng = np.random.default_rng(seed)
    rows = synthetic_runs(n=n, errored=(), failed=(), seed=seed, modes=IRASSI_MODES)
    # as in 200 flown IRASSI runs (2026-11-27): 0.29 +- 0.07 arcsec without a failure, the noise level
    # rho 0.44 over all runs; wheel 3 or 4 failed +0.05-0.12; wheel 1 or 2 failed 2.2 arcsec
    penalty = {0: 0.0, 1: 1.9, 2: 1.9, 3: 0.12, 4: 0.05}
    for i, row in enumerate(rows):
        failed = int(rng.integers(1, 5)) if i and rng.uniform() < 0.2 else 0
        rate = float(rng.normal(0.0, 1.0))
        row.pop("attitude_error_end_deg")
        row.update(
            {
                "failed_wheels": str(failed) if failed else "",
                "pointing_max_arcsec": 0.29 + 0.045 * rate + 0.055 * rng.normal() + penalty[failed],
                "p.initial.rates_deg_s.0": rate,
            }
        )
    return rows


@pytest.fixture(scope="module")
def irassi(tmp_path_factory):
    rows = irassi_like_runs()
    out = write_out(
        tmp_path_factory.mktemp("irassi") / "out",
        rows,
        requirements=["pointing_max_arcsec.p99 <= 0.4"],
        histories=False,
        modes=IRASSI_MODES,
        vehicle="irassi",
    )
    return rows, data.load(out)


def test_the_undetected_wheel_1_or_2_failure_drives_the_pointing_error_first(irassi):
    rows, campaign = irassi
    from refexmc.report import make_report

    summary = make_report(campaign.out, html=False)["summary"]
    ranked = summary["sensitivity"]["pointing_max_arcsec"]
    assert all(not r["parameter"].startswith("p.") for r in ranked if r["kind"] != "input")
    assert ranked[0]["parameter"] == "failed wheel set (undetected)" and ranked[0]["kind"] == "failure set"
    assert ranked[0]["p_value"] < 1e-10
    assert {level["level"] for level in ranked[0]["levels_by_rank"][:2]} == {"1", "2"}  # which wheels
    above = [r for r in rows if r["pointing_max_arcsec"] > 0.6]
    assert above and all(r["failed_wheels"] in ("1", "2") for r in above)  # the observation
    names = [r["parameter"] for r in ranked]
    rate = names.index("p.initial.rates_deg_s.0")
    assert rate > 0  # the initial rate no longer ranks first ...
    assert ranked[rate]["eta2"] == pytest.approx(ranked[rate]["rho"] ** 2)  # ... on the same scale
    wheel = [f"wheel {k} failed (undetected)" for k in (1, 2, 3, 4)]
    for name in wheel[:2]:  # each a significant cause, raising the error
        entry = ranked[names.index(name)]
        assert entry["rho"] > 0 and entry["p_value"] < 1e-6
    for name in wheel[2:]:  # small penalties: below wheels 1 and 2
        assert names.index(name) > max(names.index(wheel[0]), names.index(wheel[1]))
    assert summary["sensitivity"]["factors"][:1] == ["wheel 1 failed (undetected)"]


def test_eta2_and_its_p_are_the_correlation_ratio_and_kruskal_wallis(irassi):
    _, campaign = irassi
    ok = campaign.ok
    y = ok["pointing_max_arcsec"].to_numpy(float)
    ranks = sps.rankdata(y)
    labels = ok["failed_wheels"].to_numpy()
    eta2, p, levels = stats.rank_eta2(ranks, labels)
    groups = [ranks[labels == level] for level in np.unique(labels)]
    between = sum(len(g) * (g.mean() - ranks.mean()) ** 2 for g in groups)
    assert levels == 5 and eta2 == pytest.approx(between / np.sum((ranks - ranks.mean()) ** 2), rel=1e-12)
    assert p == pytest.approx(sps.kruskal(*[y[labels == level] for level in np.unique(labels)]).pvalue, rel=1e-9)
    indicator = (labels == "1").astype(float)  # two levels: eta^2 is the indicator's Spearman rho^2
    rho = sps.spearmanr(indicator, y).statistic
    assert stats.rank_eta2(ranks, indicator)[0] == pytest.approx(rho**2, rel=1e-12)
    row = next(
        r
        for r in factors.factor_rows(factors.factors(campaign, ok), y, np.ones(len(y), bool))
        if r["parameter"] == "wheel 1 failed (undetected)"
    )
    assert row["rho"] == pytest.approx(rho, rel=1e-12) and row["runs_with"] == int(indicator.sum())


def test_choice_inputs_and_thruster_sets_are_factors_named_for_what_they_are(tmp_path):
    rng = np.random.default_rng(5)
    rows = synthetic_runs(n=60, errored=(), failed=(), seed=5)
    for row in rows:
        row["failed_thrusters"] = str(rng.choice(["", "1", "3", "1,3"]))
        row["p.rcs.isp_s"] = float(rng.choice([60.0, 70.0, 80.0]))
    out = write_out(tmp_path / "out", rows, requirements=["fuel_remaining.min >= 0.2"], histories=False)
    resolved = out / "campaign.resolved.yaml"
    resolved.write_text(
        resolved.read_text() + "dispersions:\n  rcs.isp_s: {dist: choice, values: [60.0, 70.0, 80.0]}\n"
    )
    campaign = data.load(out)
    names = [name for name, _, _ in factors.factors(campaign, campaign.ok)]
    thrusters = ["thruster 1 failed (undetected)", "thruster 3 failed (undetected)", "failed thruster set (undetected)"]
    assert names == [*thrusters, "rcs.isp_s (choice of 3 values)"]
    section = build(campaign, [])["sensitivity"]
    assert section is not None and section["factors"] == names
