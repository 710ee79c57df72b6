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
        "  initial_state.rates_deg_s: {dist: normal, sigma: [2.0, 2.0, 2.0]}\n"
        "  navigation.attitude_noise_deg: {dist: constant, value: 0.0}\n"
        "  navigation.rate_noise_deg_s: {dist: constant, value: 0.0}",
    ),
    ("runs: 1", "runs: 17"),
]


def test_the_draws_are_the_rows_of_the_design(tmp_path):
    campaign = load_campaign(campaign_copy("nominal.yaml", tmp_path, replace=SALTELLI))
    groups = tuple(saltelli.layout(campaign))
    assert groups == (("rcs.isp_s", 1), ("initial_state.rates_deg_s", 3))
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
    assert section["groups"] == ["rcs.isp_s", "initial_state.rates_deg_s"] and section["runs"] == 16
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


# --- what the design cannot support: flagged with the N that would ---------------------------------

GROUPS = (("x1", 1), ("x2", 1), ("x3", 1))


def ishigami_on_design(n_base, seed=7):
    u = saltelli._design(seed, GROUPS, n_base)
    x = -math.pi + 2.0 * math.pi * u
    return u, np.sin(x[:, 0]) + A * np.sin(x[:, 1]) ** 2 + B * x[:, 2] ** 4 * np.sin(x[:, 0])


def test_a_large_design_supports_its_indices_and_a_small_one_is_flagged_with_the_n_that_would():
    _, y = ishigami_on_design(4096)
    large = sobol.metric_entry(GROUPS, y, 4096, seed=1)
    assert large["supported"] and "flag" not in large
    _, y = ishigami_on_design(16)
    small = sobol.metric_entry(GROUPS, y, 16, seed=1)
    assert not small["supported"]
    needed = small["base_samples_needed"]
    assert needed > 16 and needed & (needed - 1) == 0  # a power of 2, as the design needs
    widest = max(max(s["first_conf"], s["total_conf"]) for s in small["indices"].values() if s["flags"])
    assert needed >= 16 * (widest / sobol.TARGET_HALF_WIDTH) ** 2  # CIs shrink as 1 / sqrt(N)
    assert "N = 16 base samples cannot support" in small["flag"] and f"about N = {needed}" in small["flag"]
    for s in small["indices"].values():  # an unflagged index is inside [0, 1] with a narrow CI
        if not s["flags"]:
            assert s["first_conf"] <= 0.1 and s["total_conf"] <= 0.1
            assert -s["first_conf"] <= s["first"] <= 1 + s["first_conf"]


def test_indices_outside_the_unit_interval_or_first_above_total_are_flagged():
    assert sobol.index_flags({"first": -0.3, "first_conf": 0.05, "total": 0.2, "total_conf": 0.05}) == [
        "first outside [0, 1] beyond its CI"
    ]
    assert "total outside [0, 1] beyond its CI" in sobol.index_flags(
        {"first": 0.5, "first_conf": 0.05, "total": 14.5, "total_conf": 3.0}
    )
    assert sobol.index_flags({"first": 0.6, "first_conf": 0.02, "total": 0.3, "total_conf": 0.02}) == [
        "first above total beyond their CIs"
    ]
    assert sobol.index_flags({"first": 0.3, "first_conf": 0.02, "total": 0.32, "total_conf": 0.02}) == []


def test_a_rare_failure_missed_by_a_and_b_cannot_be_estimated_never_a_confident_zero():
    """The issue's hop: success failed in 2 column-swap runs only, A and B all successful. The
    indices divide by the variance over A and B, 0: "cannot estimate", with the N that would."""
    n_base = 32
    u, _ = ishigami_on_design(n_base)
    both = np.minimum(u[:, 0], u[:, 1])  # a failure needs x1 and x2 both high: an interaction
    rows_ab = sobol.design_rows(len(GROUPS), n_base)
    swaps = np.setdiff1d(np.arange(len(u)), rows_ab)
    threshold = both[rows_ab].max()
    assert np.count_nonzero(both[swaps] > threshold) >= 1  # this design has such swap rows
    success = (both <= threshold).astype(float)
    entry = sobol.metric_entry(GROUPS, success, n_base)
    assert "indices" not in entry
    failed = int(np.count_nonzero(success == 0.0))
    assert (
        f"the 64 runs of the matrices A and B all have the value 1 while {failed} column-swap run"
        in (entry["cannot_estimate"])
    )
    rate = failed / len(u)
    assert entry["base_samples_needed"] >= sobol.EVENTS_NEEDED / (2 * rate)  # ~10 failures expected in A and B
    # failures in A and B too: an estimate, flagged at this N, never 0.000 +- 0.000 everywhere
    success = (both <= np.quantile(both, 0.9)).astype(float)
    entry = sobol.metric_entry(GROUPS, success, n_base, seed=1)
    assert "indices" in entry
    assert any(s["total"] > 0.0 and s["total_conf"] > 0.0 for s in entry["indices"].values())
    assert not entry["supported"] and entry["base_samples_needed"] > n_base


def test_a_metric_without_a_value_in_some_runs_says_why():
    _, y = ishigami_on_design(8)
    y[3] = math.nan
    assert "1 of 40 runs have no value" in sobol.metric_entry(GROUPS, y, 8)["cannot_estimate"]
    assert "no value of it in any run" in sobol.metric_entry(GROUPS, np.full(40, math.nan), 8)["cannot_estimate"]


# the hop: a Saltelli campaign over the hop's own dispersions, N = 8 base samples (81 runs)
HOP_SALTELLI = [
    ("runs: 1000", "runs: 81"),
    ("sampling: random", "sampling: saltelli"),
    ("  navigation.attitude_noise_deg: {dist: uniform, low: 0.0, high: 0.1}", ""),
    ("  navigation.local_position_noise_m: {dist: uniform, low: 0.0, high: 0.005}", ""),
    ("  navigation.local_velocity_noise_m_s: {dist: uniform, low: 0.0, high: 0.001}", ""),
    ("  navigation.tank_pressure_noise_pa: {dist: uniform, low: 0.0, high: 2.5e4}", ""),
    ("  mode: random\n  count_probabilities: [0.95, 0.05]", "  mode: none"),
]


def test_the_hop_sobol_analyses_its_own_metrics_and_flags_what_n_8_cannot_support(tmp_path):
    path = campaign_copy("surveyor-hop.yaml", tmp_path, replace=HOP_SALTELLI)
    out = tmp_path / "out"
    run_campaign(path, out, jobs=1)
    result = make_report(out, html=False)
    section = result["summary"]["sobol"]
    assert list(section["metrics"]) == ["t_hop_s", "position_error_end_m", "tank_pressure_end_pa"]
    assert "attitude_error_end_deg" not in result["text"].split("Sobol' indices")[1]
    for metric, entry in section["metrics"].items():
        assert "indices" in entry or "cannot_estimate" in entry
        if "indices" in entry:  # 8 base samples over 8 groups: flagged, with the N that would do
            assert not entry["supported"] and entry["base_samples_needed"] >= 64, metric
            assert entry["runs_needed"] == entry["base_samples_needed"] * 10 + 1
    assert "not analysed" not in result["text"] and " ?" in result["text"]
    narrowed = campaign_copy(
        "surveyor-hop.yaml", tmp_path, "narrowed.yaml", HOP_SALTELLI, sobol="{metrics: [success, speed_end_m_s]}"
    )
    assert load_campaign(narrowed)["sobol"]["metrics"] == ["success", "speed_end_m_s"]


def test_a_sobol_metric_the_mission_lacks_is_bad_input_at_validate(tmp_path):
    from click.testing import CliRunner

    from refexmc.cli import main

    path = campaign_copy(
        "surveyor-hop.yaml", tmp_path, replace=HOP_SALTELLI, sobol="\n  metrics: [t_hop_s, pointing_max_arcsec]"
    )
    result = CliRunner().invoke(main, ["validate", str(path)])
    assert result.exit_code == 2 and "Traceback" not in result.output
    line = path.read_text().splitlines().index("  metrics: [t_hop_s, pointing_max_arcsec]") + 1
    assert f"{path}:{line}: sobol.metrics.1: unknown metric 'pointing_max_arcsec'" in result.output
    random = campaign_copy("surveyor-hop.yaml", tmp_path, "random.yaml", sobol="{metrics: [t_hop_s]}")
    with pytest.raises(ConfigError, match="'sobol' goes with 'sampling: saltelli'"):
        load_campaign(random)
