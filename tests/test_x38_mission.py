"""The X-38 entry mission (configs/missions/x38-entry.yaml, issue 24): it flies what the direct
core.entry_flight call with the same values flies (tests/test_entry_flight.py's entry), its
metrics are named from the kernel's summary, and bad entry-mission input is exit 2 with file,
line and key path."""

import math
import re
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from test_entry_flight import prepare

from refexmc import simulate
from refexmc.cli import main
from refexmc.config import entry as config_entry
from refexmc.config.load import load_mission, load_vehicle
from refexmc.core import entry_flight as ef

ROOT = Path(__file__).resolve().parents[1]
MISSION = ROOT / "configs/missions/x38-entry.yaml"
TEXT = MISSION.read_text()


def _mission_flight(blocked=None):
    vehicle = load_vehicle(ROOT / "configs/vehicles/x38.yaml")
    return config_entry.entry_flight_from_mission(vehicle, load_mission(MISSION), blocked=blocked)


@pytest.mark.parametrize("blocked", [None, ("right", 14.0)])
def test_the_mission_file_flies_the_direct_entry_bit_for_bit(blocked):
    """The file holds the values tests/test_entry_flight.py passes the kernel by hand (an
    independent route to the same arrays): the flights must agree exactly."""
    flown, initial = _mission_flight(blocked)
    direct, direct_initial = prepare(blocked)
    np.testing.assert_array_equal(initial, direct_initial)
    result = simulate.fly_entry(flown, initial)
    summary = np.zeros(ef.SUMMARY_SIZE)
    history = np.zeros((3000, ef.HISTORY_COLUMNS))
    rows = ef.fly(direct, ef.work(), direct_initial, history, summary)
    np.testing.assert_array_equal(result.summary, summary)
    np.testing.assert_array_equal(result.history, history[:rows])
    values = result.runs_values()
    assert values["rcs_propellant_kg"] == summary[ef.SU_PROPELLANT]
    assert values["alpha_error_max_deg"] == math.degrees(summary[ef.SU_ALPHA_ERROR])
    assert values["cross_range_m"] == summary[ef.SU_CROSS_RANGE]
    assert result.success and result.failure_reason is None
    # the terminal condition: Mach 2 crossed within one control period (0.1 s at ~600 m/s, ~1e-2)
    assert 1.97 < values["terminal_mach"] < 2.0
    assert values["terminal_altitude_m"] > 15_000.0


def test_an_entry_that_hits_the_floor_is_a_failure_with_its_reason():
    vehicle = load_vehicle(ROOT / "configs/vehicles/x38.yaml")
    mission = load_mission(MISSION)
    mission["entry_flight"]["floor_altitude_m"] = 60_000.0  # above where Mach 2 is reached
    result = simulate.fly_entry(*config_entry.entry_flight_from_mission(vehicle, mission))
    assert not result.success and result.failure_reason == "floor altitude"
    assert result.runs_values()["terminal_altitude_m"] < 60_000.0
    assert result.runs_values()["terminal_mach"] > 2.0


def _line_of(text, needle):
    return text[: text.index(needle)].count("\n") + 1


def _cases():
    yield (
        "unsorted-alpha-schedule",
        TEXT.replace("{mach: 5.0, alpha_deg: 30.0}", "{mach: 1.0, alpha_deg: 30.0}"),
        ["entry_flight.alpha_schedule.1.mach", "strictly increasing, got 2.0 then 1.0"],
    )
    yield (
        "unsorted-bank-schedule",
        TEXT.replace("speed_m_s: 3000.0", "speed_m_s: 8000.0"),
        ["entry_flight.bank_schedule.2.speed_m_s", "strictly increasing, got 8000.0 then 7000.0"],
    )
    yield (
        "floor-above-entry",
        TEXT.replace("floor_altitude_m: 15000.0", "floor_altitude_m: 130000.0"),
        [
            "entry_flight.floor_altitude_m",
            "a floor below the entry altitude",
            f":{_line_of(TEXT, 'floor_altitude_m')}:",
        ],
    )
    yield (
        "unknown-key",
        TEXT.replace("  transient_s: 30.0", "  transient_s: 30.0\n  terminal_speed_m_s: 600.0"),
        ["entry_flight", "terminal_speed_m_s"],
    )
    yield (
        "missing-terminal",
        re.sub(r"\n  terminal_mach: .*", "", TEXT),
        ["entry_flight", "terminal_mach"],
    )
    yield (
        "speed-negative",
        TEXT.replace("speed_m_s: 7400.0", "speed_m_s: -7400.0"),
        ["entry_flight.state.speed_m_s"],
    )


CASES = list(_cases())


@pytest.mark.parametrize("case", CASES, ids=[c[0] for c in CASES])
def test_bad_entry_mission_is_exit_2_with_file_line_and_key_path(case, tmp_path):
    _, text, words = case
    path = tmp_path / "x38-bad.yaml"
    path.write_text(text)
    result = CliRunner().invoke(main, ["validate", str(path)])
    assert result.exit_code == 2, result.output
    assert "Traceback" not in result.output
    message = result.output.strip()
    assert re.search(rf"{re.escape(str(path))}:\d+: ", message), message
    for word in words:
        assert word in message, f"{word!r} not in {message!r}"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["x38-bad.yaml"]


def test_the_mission_file_validates():
    result = CliRunner().invoke(main, ["validate", str(MISSION)])
    assert result.exit_code == 0, result.output


@pytest.mark.parametrize(("known", "flag"), [(True, 1.0), (False, 0.0)])
def test_the_missions_blocked_flap_reaches_the_flight_known_or_not(known, flag):
    vehicle = load_vehicle(ROOT / "configs/vehicles/x38.yaml")
    mission = load_mission(ROOT / "configs/missions/x38-entry-right-flap-blocked.yaml")
    mission["entry_flight"]["blocked_flap"]["known_to_flight_software"] = known
    flown, _ = config_entry.entry_flight_from_mission(vehicle, mission)
    assert flown.surfaces[ef.SF_BLOCKED_FLAP] == 1.0  # right
    assert flown.surfaces[ef.SF_BLOCKED_DEFLECTION] == math.radians(14.0)
    assert flown.surfaces[ef.SF_BLOCKED_KNOWN] == flag


def test_a_blocked_deflection_outside_the_flap_limits_is_exit_2(tmp_path):
    text = (ROOT / "configs/missions/x38-entry-right-flap-blocked.yaml").read_text()
    (tmp_path / "mission.yaml").write_text(text.replace("deflection_deg: 14.0", "deflection_deg: 45.0"))
    campaign = (ROOT / "campaigns/x38-nominal.yaml").read_text()
    campaign = campaign.replace("../configs/missions/x38-entry.yaml", "mission.yaml")
    path = tmp_path / "c.yaml"
    path.write_text(campaign.replace("../configs/vehicles/", f"{ROOT}/configs/vehicles/"))
    result = CliRunner().invoke(main, ["validate", str(path)])
    assert result.exit_code == 2, result.output
    line = _line_of(text, "deflection_deg: 14.0")
    assert f"{tmp_path / 'mission.yaml'}:{line}: " in result.output, result.output
    assert "entry_flight.blocked_flap.deflection_deg" in result.output
    assert "within the flap limits [-10.0, 40.0]" in result.output
