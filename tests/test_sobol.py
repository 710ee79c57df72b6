"""Sobol' indices (sampling saltelli, refexmc.campaign.saltelli and refexmc.report.sobol): the
estimation code against the Ishigami function's analytic indices, the campaign's draws against
SALib's design, and the campaigns the design cannot support."""

import math

import numpy as np
import pytest
from stored import campaign_copy, invoke_run

from refexmc.campaign import saltelli
from refexmc.campaign.run import run_campaign
from refexmc.campaign.sampling import Sampler
from refexmc.config.errors import ConfigError
from refexmc.config.load import load_campaign
from refexmc.report import make_report, sobol

A, B = 7.0, 0.1  # the Ishigami function's usual constants (Ishigami and Homma 1990)


def ishigami_analytic():
    """(first, total) indices of x1, x2, x3 (Sobol' and Levitan 1999; Saltelli et al. 2008, 4.7)."""
    v1 = 0.5 * (1.0 + B * math.pi**4 / 5.0) ** 2
    v2 = A**2 / 8.0
    v13 = 8.0 * B**2 * math.pi**8 / 225.0
    v = v1 + v2 + v13
    return [v1 / v, v2 / v, 0.0], [(v1 + v13) / v, v2 / v, v13 / v]


def test_ishigami_indices_within_their_confidence_intervals():
    groups = (("x1", 1), ("x2", 1), ("x3", 1))
    n_base = 4096
    u = saltelli._design(20231121, groups, n_base)  # the design a campaign's draws come from
    x = -math.pi + 2.0 * math.pi * u
    y = np.sin(x[:, 0]) + A * np.sin(x[:, 1]) ** 2 + B * x[:, 2] ** 4 * np.sin(x[:, 0])
    estimated = sobol.indices(groups, y, seed=1)
    first, total = ishigami_analytic()
    for k, name in enumerate(("x1", "x2", "x3")):
        s = estimated[name]
        # the intervals are 95 % ones: 2 half-widths (3.9 standard errors) leave a chance of ~1e-4
        # per index that a correct estimator misses; the half-widths themselves must be small
        assert abs(s["first"] - first[k]) <= 2 * s["first_conf"], (name, s, first[k])
        assert abs(s["total"] - total[k]) <= 2 * s["total_conf"], (name, s, total[k])
        assert s["first_conf"] < 0.05 and s["total_conf"] < 0.05
    assert estimated["x3"]["first"] < 0.05 < estimated["x3"]["total"]  # x3 acts only with x1


# two dispersed parameters on ReFEx, noise off: G = 2 groups, N = 4 base samples: 16 + 1 runs
SALTELLI = [
    ("sampling: random", "sampling: saltelli"),
    (
        "dispersions: {}",
        "dispersions:\n  rcs.isp_s: {dist: uniform, low: 60.0, high: 80.0}\n"
        "  separation.rates_deg_s: {dist: normal, sigma: [2.0, 2.0, 2.0]}\n"
        "  navigation.attitude_noise_deg: {dist: constant, value: 0.0}\n"
        "  navigation.rate_noise_deg_s: {dist: constant, value: 0.0}",
    ),
    ("runs: 1", "runs: 17"),
]


def test_the_draws_are_the_rows_of_the_design(tmp_path):
    campaign = load_campaign(campaign_copy("nominal.yaml", tmp_path, replace=SALTELLI))
    groups = tuple(saltelli.layout(campaign))
    assert groups == (("rcs.isp_s", 1), ("separation.rates_deg_s", 3))
    design = saltelli._design(campaign["seed"], groups, 4)
    assert design.shape == (4 * (2 + 2), 4)
    sampler = Sampler(campaign)
    drawn = sampler.values_for_runs(range(1, 17))
    isp = np.array([values["rcs.isp_s"][0] for values in drawn])
    np.testing.assert_allclose(isp, 60.0 + 20.0 * np.clip(design[:, 0], 2.0**-53, 1 - 2.0**-53), rtol=1e-15)
    # SALib's order: per base sample A, A with the isp group from B, A with the rates from B, B
    a, ab_isp, ab_rates, b = (design[k::4] for k in range(4))
    np.testing.assert_array_equal(ab_isp[:, 0], b[:, 0])
    np.testing.assert_array_equal(ab_isp[:, 1:], a[:, 1:])
    np.testing.assert_array_equal(ab_rates[:, 1:], b[:, 1:])


def test_a_saltelli_campaign_reports_its_indices(tmp_path):
    out = tmp_path / "out"
    run_campaign(campaign_copy("nominal.yaml", tmp_path, replace=SALTELLI), out, jobs=1)
    result = make_report(out)
    section = result["summary"]["sobol"]
    assert section["groups"] == ["rcs.isp_s", "separation.rates_deg_s"] and section["runs"] == 16
    assert "indices" in section["metrics"]["fuel_used_kg"]
    assert "Saltelli design over 2 parameters: N (2 + 2) = 16 runs with N = 4 base samples" in result["text"]
    assert "id='sobol'" in (out / "report/index.html").read_text()


@pytest.mark.parametrize(
    "replace, expected",
    [
        ([("runs: 17", "runs: 18")], "needs N \\(2 \\+ 2\\) dispersed runs"),
        (
            [
                (
                    "  navigation.rate_noise_deg_s: {dist: constant, value: 0.0}",
                    "  navigation.rate_noise_deg_s: {dist: uniform, low: 0.0, high: 0.02}",
                )
            ],
            "rate_noise_deg_s is not 0",
        ),
        ([("failures:\n  mode: none", "failures:\n  mode: random\n  count_probabilities: [0.9, 0.1]")], "random"),
        (
            [
                (
                    "  rcs.isp_s: {dist: uniform, low: 60.0, high: 80.0}",
                    "  inertia_kg_m2: {dist: inertia, moments_sigma_fraction: 0.01}",
                )
            ],
            "redraws",
        ),
    ],
)
def test_refuses_what_the_design_cannot_support(tmp_path, replace, expected):
    path = campaign_copy("nominal.yaml", tmp_path, replace=[*SALTELLI, *replace])
    with pytest.raises(ConfigError, match=expected):
        load_campaign(path)
    result = invoke_run(path, "-o", tmp_path / "out")
    assert result.exit_code == 2 and "Traceback" not in result.output
    assert not (tmp_path / "out").exists()


def test_runs_override_is_checked_too(tmp_path):
    path = campaign_copy("nominal.yaml", tmp_path, replace=SALTELLI)
    result = invoke_run(path, "-o", tmp_path / "out", "--runs", "20")
    assert result.exit_code == 2 and "--runs: sampling saltelli" in result.output and "e.g. runs: 257" in result.output
