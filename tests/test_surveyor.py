"""The cold-gas surveyor (configs/vehicles/cold-gas-surveyor*.yaml, configs/missions/surveyor-hop.yaml):
the hop arrives, a stuck valve the hop needs fails it by a named reason, the deadband is what keeps
the law from spending the tank, and PD + PWM is slower and more frugal (docs/cold-gas.md)."""

import copy
import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from stored import campaign_copy, read_runs, store_campaign

from refexmc.cli import main
from refexmc.config.load import load_campaign, load_mission, load_vehicle
from refexmc.config.pack import mode_names, pack
from refexmc.simulate import fly

ROOT = Path(__file__).resolve().parents[1]
MISSION = load_mission(ROOT / "configs/missions/surveyor-hop.yaml")
RESERVE_PA = 1.0e6  # the mission's reserve_pressure_pa


def _hop(vehicle, failed=()):
    return fly(pack(vehicle, MISSION, failed_thrusters=failed), history_rate_hz=1.0, mode_names=mode_names(MISSION))


@pytest.fixture(scope="module")
def surveyor():
    return load_vehicle(ROOT / "configs/vehicles/cold-gas-surveyor.yaml")


def test_the_nominal_hop_arrives_with_the_reserve(surveyor):
    """Within the mission's 5 cm and 1 cm/s, the tank above the 10 bar reserve, x accelerating,
    coasting and braking (a few command changes), in well under the 120 s timeout."""
    result = _hop(surveyor)
    assert result.success, result.failure_reason
    row = result.runs_values()
    assert row["position_error_end_m"] <= 0.05 and row["speed_end_m_s"] <= 0.01
    assert row["tank_pressure_end_pa"] > RESERVE_PA
    assert row["switches_x"] <= 6
    assert row["t_end_s"] < 40.0


@pytest.mark.parametrize(("thruster", "needed"), [(1, True), (3, True), (5, False)])
def test_a_stuck_valve_the_hop_needs_fails_it_by_name(surveyor, thruster, needed):
    """XP (1) pushes the 3 m, YP (3) the 1 m: stuck closed, the hop cannot be made and the mode
    times out (failure reason hop_timeout); ZP (5) is not needed nominally and the hop arrives."""
    result = _hop(surveyor, failed=(thruster,))
    if needed:
        assert not result.success
        assert result.failure_reason == "hop_timeout"
    else:
        assert result.success


def test_without_a_deadband_the_law_chatters_and_spends_more_gas(surveyor):
    """The deadband is the flight software's stop: without it an axis that has arrived keeps
    switching about the origin (docs/cold-gas.md sec. 2)."""
    bare = copy.deepcopy(surveyor)
    del bare["flight_software"]["translation"]["deadband_position_m"]
    del bare["flight_software"]["translation"]["deadband_speed_m_s"]
    with_deadband, without = _hop(surveyor).runs_values(), _hop(bare).runs_values()
    assert without["switches_y"] > 3 * with_deadband["switches_y"]
    assert without["fuel_used_kg"] > with_deadband["fuel_used_kg"]


def test_pd_pwm_is_slower_and_uses_less_gas_than_the_law(surveyor):
    """The comparison campaign's vehicle: the same hop, more than twice the time, less than half the gas."""
    pd = _hop(load_vehicle(ROOT / "configs/vehicles/cold-gas-surveyor-pd-pwm.yaml"))
    law = _hop(surveyor)
    assert pd.success
    assert pd.runs_values()["t_end_s"] > 2.0 * law.runs_values()["t_end_s"]
    assert pd.runs_values()["fuel_used_kg"] < 0.5 * law.runs_values()["fuel_used_kg"]


@pytest.mark.parametrize(
    ("file", "old", "new", "words"),
    [
        (
            "vehicles/cold-gas-surveyor.yaml",
            "    model: blow_down                   # 002 sec. 3.2: nozzle and valve straight on the tank",
            "    model: constant",
            ["rcs.feed.tank_volume_m3", "feed is constant"],
        ),
        (
            "vehicles/cold-gas-surveyor.yaml",
            "    law: time_optimal                  # 002 eq. 44 per body axis",
            "    law: pd_pwm",
            ["flight_software.translation", "pd_pwm needs 'position_gain_s2'"],
        ),
        (
            "vehicles/cold-gas-surveyor.yaml",
            "trajectory: local",
            "trajectory: none",
            ["'local' needs a vehicle with the local trajectory"],
        ),
    ],
)
def test_bad_local_input_exits_2(tmp_path, file, old, new, words):
    """A constant feed with tank keys, a pd_pwm law without its gains, a local mission for a vehicle
    without the local trajectory: exit 2, one message with the file and key path, nothing flown."""
    from click.testing import CliRunner

    from refexmc.cli import main

    text = (ROOT / "configs" / file).read_text()
    assert old in text, old
    edited = tmp_path / Path(file).name
    edited.write_text(text.replace(old, new))
    campaign = (ROOT / "campaigns/surveyor-hop.yaml").read_text()
    campaign = campaign.replace(f"../configs/{file}", str(edited)).replace("../configs/", f"{ROOT}/configs/")
    path = tmp_path / "campaign.yaml"
    path.write_text(campaign)
    result = CliRunner().invoke(main, ["validate", str(path)])
    assert result.exit_code == 2, result.output
    assert "Traceback" not in result.output
    for word in words:
        assert word in result.output, result.output


def test_a_translate_mode_flies_to_its_own_target(surveyor):
    """surveyor-hop-sequential: hop_x goes to the mode's target_position_m [3, 0, 0] and stops
    (the exit predicates measured against it), then hop_y to the mission's [3, 1, 0]; slower than
    both axes at once on the shared tank (docs/cold-gas.md sec. 4)."""
    mission = load_mission(ROOT / "configs/missions/surveyor-hop-sequential.yaml")
    sequential = fly(pack(surveyor, mission), history_rate_hz=1.0, mode_names=mode_names(mission))
    assert sequential.success, sequential.failure_reason
    row = sequential.runs_values()
    assert row["t_hop_x_s"] > 0.0 and row["t_hop_y_s"] > 0.0
    assert row["position_error_end_m"] <= 0.05  # against [3, 1, 0], the last mode's target
    assert row["t_end_s"] > _hop(surveyor).runs_values()["t_end_s"]
    # hop_x alone: stopping at [3, 0, 0] means y has not moved yet
    first = copy.deepcopy(mission)
    first["modes"] = first["modes"][:1]
    alone = fly(pack(surveyor, first), history_rate_hz=1.0, mode_names=mode_names(first))
    assert alone.success and alone.runs_values()["switches_y"] <= 2


REPORT_ONLY = [f"--tolerance={metric}=inf" for metric in ("t_hop_s", "position_error_end_m")]  # as docs/cold-gas.md


def test_compare_puts_the_law_and_pd_pwm_side_by_side(tmp_path):
    """`refexmc compare` of the two campaigns (12 runs each, the same draws): paired run by run,
    the time to arrive and the gas as the median of each runs table's flown runs (the statistic
    the paired difference is of; computed here from the stored tables), PD + PWM over twice as
    slow and under half the gas, and with the time metrics set to report only (docs/cold-gas.md)
    the comparison passes: exit 0."""
    outs = {}
    for name in ("surveyor-hop", "surveyor-hop-pd-pwm"):
        path = campaign_copy(f"{name}.yaml", tmp_path, replace=[("runs: 1000", "runs: 12")])
        outs[name] = tmp_path / f"out-{name}"
        store_campaign(load_campaign(path), outs[name])
    law, pd = outs["surveyor-hop"], outs["surveyor-hop-pd-pwm"]
    result = CliRunner().invoke(main, ["compare", str(law), str(pd), *REPORT_ONLY])
    assert result.exit_code == 0, result.output
    assert "paired run by run on 12 runs" in result.output
    rows = {line.split()[0]: line.split() for line in result.output.splitlines() if line.strip()}
    for metric in ("t_hop_s", "fuel_used_kg"):
        law_median, pd_median = (
            np.nanmedian(runs.loc[runs["status"] == "ok", metric]) for runs in map(read_runs, (law, pd))
        )
        for printed, median in ((rows[metric][1], law_median), (rows[metric][2], pd_median)):
            half_digit = 0.5 * 10.0 ** -len(printed.split(".")[1])  # rounded to the printed decimals
            assert abs(float(printed) - median) <= half_digit, (metric, printed, median)
    assert float(rows["t_hop_s"][2]) > 2.0 * float(rows["t_hop_s"][1])
    assert float(rows["fuel_used_kg"][2]) < 0.5 * float(rows["fuel_used_kg"][1])


@pytest.mark.parametrize("vehicle", ["cold-gas-surveyor.yaml", "cold-gas-surveyor-pd-pwm.yaml"])
def test_inspect_prints_the_translation_law_and_no_attitude_gains(vehicle):
    """Issue 34: `inspect` on a hop's vehicle says what its flight uses (the translation law, its
    deadband, the thrusters per axis, n C_F A_t, tau and the initial acceleration), not 40 lines
    of zero attitude gains, deadbands, PWPF and an empty allocation table."""
    path = str(ROOT / "configs/vehicles" / vehicle)
    text = CliRunner().invoke(main, ["inspect", path]).output
    info = json.loads(CliRunner().invoke(main, ["inspect", path, "--json"]).output)
    law = info["translation"]["law"]
    assert f"translation law {law}" in text and "attitude: not controlled" in text
    for attitude_word in ("Kp", "Kd", "PWPF", "allocation", "deadband [deg", "lever arms"):
        assert attitude_word not in text, attitude_word
    assert len(text.splitlines()) < 20
    assert [t["+"] for t in info["translation"]["thrusters"]] == [[1], [3], [5]]  # XP, YP, ZP
    assert [t["-"] for t in info["translation"]["thrusters"]] == [[2], [4], [6]]
    # one thruster per direction: tau is the feed's, the acceleration its initial thrust over the mass
    mass = load_vehicle(path)["mass_kg"]
    for axis in range(3):
        assert info["translation"]["time_constant_s"][axis] == pytest.approx(info["feed"]["blow_down_time_constant_s"])
        assert info["translation"]["initial_accel_m_s2"][axis] == pytest.approx(info["feed"]["initial_thrust_n"] / mass)
    if law == "pd_pwm":
        assert "position_gain_s2" in info["translation"] and "position_gain_s2" in text
