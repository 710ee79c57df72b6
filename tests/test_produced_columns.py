"""Metrics on runs columns the campaign never fills are bad input (docs/campaigns.md).

The runs table of every attitude mission has ``attitude_error_end_deg`` and ``fuel_remaining``,
but a hop (translate modes only: no attitude reference) leaves the first NaN in every run, and a
vehicle with reaction wheels only the second (config.requirements.unproduced_columns). A
requirement, a published value, a sweep metric, a rare event or a Sobol' metric on such a column
could never be judged; the report used to call it "not computable (no runs, or too few runs)".
`validate` and `run` refuse it: exit 2, one line with file, line and key path, the column, why the
campaign has none, and the columns it does produce.
"""

import pytest
from click.testing import CliRunner
from stored import ROOT, campaign_copy

from refexmc.cli import main
from refexmc.config import requirements
from refexmc.config import sweep as sweep_config
from refexmc.config.load import load_campaign

HOP_ANGLE = "attitude_error_end_deg"
HOP_WHY = "the mission's last mode 'hop' is a translate mode, which has no attitude reference"
HOP_PRODUCES = "the columns it produces: fuel_remaining, fuel_used_kg, t_end_s, t_hop_s, position_error_end_m"


def _line(path, fragment):
    return next(n for n, line in enumerate(path.read_text().splitlines(), 1) if fragment in line)


def _refused(path, key, fragment, column, why, *words):
    """`validate` and `run` of ``path``: exit 2, one line at ``fragment``'s line and ``key``, naming
    ``column``, ``why`` and ``words``; `run` writes nothing."""
    out = path.parent / "out"
    for args in (["validate", str(path)], ["run", str(path), "-o", str(out), "--no-progress", "-j", "1"]):
        result = CliRunner().invoke(main, args)
        assert result.exit_code == 2, result.output
        lines = result.output.strip().splitlines()
        assert len(lines) == 1 and "Traceback" not in result.output, result.output
        assert lines[0].startswith(f"error: {path}:{_line(path, fragment)}: {key}: "), lines[0]
        for word in (f"does not produce the runs column '{column}'", why, *words):
            assert word in lines[0], (word, lines[0])
        assert not out.exists()


def test_a_requirement_on_the_end_attitude_of_a_hop_is_refused(tmp_path):
    """The walkthrough's case: surveyor-hop with `attitude_error_end_deg.max <= 1` (it validated,
    flew, and the report said FAIL "not computable")."""
    path = campaign_copy("surveyor-hop.yaml", tmp_path)
    path.write_text(path.read_text() + "  - attitude_error_end_deg.max <= 1\n")
    _refused(path, "requirements.4", "attitude_error_end_deg.max", HOP_ANGLE, HOP_WHY, HOP_PRODUCES)


def test_the_columns_a_hop_produces_are_listed_without_the_end_attitude(tmp_path):
    path = campaign_copy("surveyor-hop.yaml", tmp_path)
    path.write_text(path.read_text() + "  - attitude_error_end_deg.p95 <= 1\n")
    result = CliRunner().invoke(main, ["validate", str(path)])
    produced = result.output.split("the columns it produces: ")[1]
    assert HOP_ANGLE not in produced and "pulses_1 .. pulses_6" in produced and "p.<dispersed path>" in produced


def test_a_sobol_metric_the_hop_does_not_produce_is_refused_and_not_offered(tmp_path):
    path = campaign_copy(
        "surveyor-hop-sobol.yaml", tmp_path, replace=[("metrics: [t_hop_s,", "metrics: [attitude_error_end_deg,")]
    )
    _refused(path, "sobol.metrics.0", "metrics: [attitude_error_end_deg", HOP_ANGLE, HOP_WHY, "success, fuel_remaining")
    # a misspelt metric: the list of the hop's metrics no longer offers the end attitude
    path = campaign_copy("surveyor-hop-sobol.yaml", tmp_path, replace=[("metrics: [t_hop_s,", "metrics: [t_hopp,")])
    result = CliRunner().invoke(main, ["validate", str(path)])
    assert result.exit_code == 2 and "did you mean 't_hop_s'" in result.output, result.output
    assert HOP_ANGLE not in result.output


def test_a_sweep_metric_the_hop_does_not_produce_is_refused(tmp_path):
    sweep = "sweep:\n  axes:\n    - parameter: rcs.feed.tank_volume_m3\n      values: [0.001, 0.0015]\n"
    path = campaign_copy("surveyor-hop.yaml", tmp_path)
    path.write_text(path.read_text() + sweep + "  metrics: [tank_pressure_end_pa, attitude_error_end_deg]\n")
    _refused(path, "sweep.metrics.1", "metrics: [tank_pressure_end_pa", HOP_ANGLE, HOP_WHY, HOP_PRODUCES)
    # without metrics: the defaults the hop produces (fuel_remaining), not its NaN end attitude
    path.write_text(path.read_text().replace("  metrics: [tank_pressure_end_pa, attitude_error_end_deg]\n", ""))
    campaign = load_campaign(path)
    columns = requirements.run_value_columns(["hop"], trajectory="local")  # the table has the column
    assert HOP_ANGLE in columns
    assert sweep_config.metrics(campaign, columns) == ["fuel_remaining"]


def test_a_rare_event_the_hop_does_not_produce_is_refused(tmp_path):
    path = campaign_copy(
        "surveyor-hop-rare.yaml",
        tmp_path,
        replace=[("event: position_error_end_m > 0.06", "event: attitude_error_end_deg > 1")],
    )
    _refused(path, "rare_event.event", "event: attitude_error_end_deg", HOP_ANGLE, HOP_WHY, "event '")


def test_a_published_value_the_hop_does_not_produce_is_refused(tmp_path):
    path = campaign_copy("surveyor-hop.yaml", tmp_path)
    published = "published:\n  - source: a paper\n    statistic: max\n    values: {attitude_error_end_deg: 2.0}\n"
    path.write_text(path.read_text() + published)
    _refused(path, f"published.0.values.{HOP_ANGLE}", "values: {attitude_error_end_deg", HOP_ANGLE, HOP_WHY)


def test_the_propellant_fraction_of_a_vehicle_with_wheels_only_is_refused(tmp_path):
    path = campaign_copy(
        "irassi-fine-pointing.yaml",
        tmp_path,
        replace=[("  - success_rate >= 1.0\n", "  - success_rate >= 1.0\n  - fuel_remaining.min >= 0.2\n")],
    )
    _refused(path, "requirements.1", "fuel_remaining.min", "fuel_remaining", "the vehicle has no RCS")


def test_the_propellant_used_by_a_vehicle_with_wheels_only_is_refused(tmp_path):
    # 0 kg in every run: 'fuel_used_kg.max <= 1' was always met, a PASS about nothing
    path = campaign_copy(
        "irassi-fine-pointing.yaml",
        tmp_path,
        replace=[("  - success_rate >= 1.0\n", "  - success_rate >= 1.0\n  - fuel_used_kg.max <= 1\n")],
    )
    _refused(path, "requirements.1", "fuel_used_kg.max", "fuel_used_kg", "uses no propellant")


@pytest.mark.parametrize(
    ("vehicle", "mission", "absent"),
    [
        ("refex.yaml", "refex-exo.yaml", []),  # ends tracking the entry attitude; an RCS
        ("cold-gas-surveyor.yaml", "surveyor-hop.yaml", [HOP_ANGLE]),
        ("irassi.yaml", "irassi-small-angle.yaml", ["fuel_remaining", "fuel_used_kg"]),
    ],
)
def test_unproduced_columns_follow_the_last_mode_and_the_actuators(vehicle, mission, absent):
    from refexmc.config.load import load_mission, load_vehicle

    found = requirements.unproduced_columns(
        load_vehicle(ROOT / "configs/vehicles" / vehicle), load_mission(ROOT / "configs/missions" / mission)
    )
    assert sorted(found) == absent


def test_a_requirement_on_a_column_the_hop_produces_still_validates(tmp_path):
    path = campaign_copy("surveyor-hop.yaml", tmp_path)
    path.write_text(path.read_text() + "  - speed_end_m_s.max <= 0.02\n")
    result = CliRunner().invoke(main, ["validate", "--strict", str(path)])
    assert result.exit_code == 0, result.output


PULSES = "requirements:\n  - pulses_total.max <= 500\n"


@pytest.mark.parametrize("name", ["irassi-fine-pointing.yaml", "x38-nominal.yaml"])
def test_pulses_total_is_a_metric_only_where_thrusters_count_pulses(tmp_path, name):
    """A wheel vehicle's runs table has no ``pulses_<i>`` (an entry's neither): ``pulses_total``
    is unknown there (before: it validated, flew, and the report failed with KeyError)."""
    path = campaign_copy(name, tmp_path)
    path.write_text(path.read_text() + "  - pulses_total.max <= 5\n")
    result = CliRunner().invoke(main, ["validate", str(path)])
    assert result.exit_code == 2, result.output
    assert "unknown metric 'pulses_total.max'" in result.output and "Traceback" not in result.output
    smoke = campaign_copy("smoke.yaml", tmp_path, "smoke-pulses.yaml", [("requirements:\n", PULSES)])  # thrusters
    assert CliRunner().invoke(main, ["validate", str(smoke)]).exit_code == 0
