"""A flight's end in the mission's own words: hand-over only where the mission hands over (issue 26)."""

from pathlib import Path

from click.testing import CliRunner
from stored import campaign_copy, invoke_run

from refexmc.cli import main
from refexmc.config.load import load_mission
from refexmc.config.mission_words import end_condition, end_name, exit_condition_text

ROOT = Path(__file__).resolve().parents[1]
NOT_GENERIC = ("hand-over", "handover", "separation")


def test_only_a_mission_ending_on_dynamic_pressure_hands_over():
    refex = load_mission(ROOT / "configs/missions/refex-exo.yaml")
    slew = load_mission(ROOT / "configs/missions/generic-slew.yaml")
    irassi = load_mission(ROOT / "configs/missions/irassi-small-angle.yaml")
    assert end_name(refex) == "hand-over"
    assert end_condition(refex).startswith("hand-over when GEEM exits on dynamic_pressure_above_pa 1000, or ")
    assert end_condition(slew) == "end when hold exits on time_in_mode_s 60"
    assert end_name(irassi) == "end" and "science exits on mission_time_s 79200" in end_condition(irassi)


def test_exit_conditions_read_all_of_within_and_any_of_across():
    text = exit_condition_text([{"guidance_finished": True, "rates_below_deg_s": 0.15}, {"time_in_mode_s": 8.0}])
    assert text == "guidance_finished and rates_below_deg_s 0.15, or time_in_mode_s 8"


def test_rerun_of_a_failed_generic_flight_speaks_of_its_end_not_a_hand_over(tmp_path):
    """generic-slew with a slew timeout it cannot meet: every flight fails in the slew."""
    mission = tmp_path / "mission.yaml"
    mission.write_text(
        (ROOT / "configs/missions/generic-slew.yaml").read_text().replace("timeout_s: 300.0", "timeout_s: 2.0")
    )
    campaign = campaign_copy(
        "generic-slew.yaml", tmp_path, replace=[(str(ROOT / "configs/missions/generic-slew.yaml"), str(mission))]
    )
    out = tmp_path / "out"
    flown = invoke_run(campaign, "-o", out, "--runs", "2", "-j", "1", "--no-progress")
    assert flown.exit_code == 0, flown.output
    result = CliRunner().invoke(main, ["rerun", str(out), "0", "-o", str(tmp_path / "run0.parquet")])
    assert result.exit_code == 0, result.output
    assert "FAILED (slew_timeout)" in result.output
    assert "the mission: end when hold exits on time_in_mode_s 60" in result.output
    assert "flight stopped at t = " in result.output
    for word in NOT_GENERIC:
        assert word not in result.output.lower(), (word, result.output)
