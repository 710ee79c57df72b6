"""Any vehicle, any mission (issue 12): the mode program flies ReFEx unchanged, ReFEx without
SSM, and a 12-thruster spacecraft with plain PD and no trajectory; outputs are named from the files.
"""

import json
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from click.testing import CliRunner

from refexmc.campaign import storage
from refexmc.campaign.chunk import fly_chunk
from refexmc.cli import main
from refexmc.config import derived
from refexmc.config.load import load_campaign, load_mission, load_vehicle
from refexmc.config.pack import mode_names, pack
from refexmc.core import control
from refexmc.simulate import fly

ROOT = Path(__file__).resolve().parents[1]
GENERIC_VEHICLE = ROOT / "configs/vehicles/generic-12.yaml"
GENERIC_MISSION = ROOT / "configs/missions/generic-slew.yaml"


def _bits(column):
    """A column's values as comparable bits: floats by their IEEE pattern (NaN == NaN)."""
    column = column.combine_chunks() if isinstance(column, pa.ChunkedArray) else column
    if pa.types.is_floating(column.type):
        return column.to_numpy(zero_copy_only=False).view(np.uint64).tolist()
    return column.to_pylist()


def test_smoke_runs_table_is_bit_identical_to_the_baseline():
    """baselines/smoke was flown by the seven-mode loop before the mode program: same table, bit for
    bit (issue 37's elementary functions, core/elementary.py, left these 20 runs' bits unchanged; the
    IRASSI and hop baselines moved). It was written before issue 34's names: read through storage,
    its theta_t_handover_deg and p.separation.* columns are attitude_error_end_deg and
    p.initial_state.*, nothing else changed."""
    campaign = load_campaign(ROOT / "campaigns/smoke.yaml")
    rows, _ = fly_chunk(campaign, range(campaign["runs"]))
    flown = storage.runs_table(rows)
    raw = pq.read_table(ROOT / "baselines/smoke/runs")
    baseline = storage.read_runs_part(ROOT / "baselines/smoke/runs").sort_by("run_id")
    renamed = {old: new for old, new in zip(raw.column_names, baseline.column_names, strict=True) if old != new}
    assert renamed == {
        "p.separation.rates_deg_s.x": "p.initial_state.rates_deg_s.x",
        "p.separation.rates_deg_s.y": "p.initial_state.rates_deg_s.y",
        "p.separation.rates_deg_s.z": "p.initial_state.rates_deg_s.z",
        "p.separation.attitude_error_deg.x": "p.initial_state.attitude_rotvec_deg.x",
        "p.separation.attitude_error_deg.y": "p.initial_state.attitude_rotvec_deg.y",
        "p.separation.attitude_error_deg.z": "p.initial_state.attitude_rotvec_deg.z",
        "theta_t_handover_deg": "attitude_error_end_deg",
    }
    assert flown.column_names == baseline.column_names
    for name in baseline.column_names:
        assert _bits(flown[name]) == _bits(baseline[name]), name


def _run_and_report(tmp_path, name):
    out = tmp_path / name
    runner = CliRunner()
    result = runner.invoke(main, ["run", str(ROOT / "campaigns" / f"{name}.yaml"), "-o", str(out), "--no-progress"])
    assert result.exit_code == 0, result.output
    report = runner.invoke(main, ["report", str(out)])
    return out, report


@pytest.mark.parametrize(
    ("name", "modes"),
    [
        ("refex-no-ssm", ["NCM", "RDM1", "SAM", "RDM2", "EAM", "GEEM"]),
        ("generic-slew", ["detumble", "slew", "hold"]),
    ],
)
def test_new_missions_fly_pass_their_requirements_and_name_their_columns(tmp_path, name, modes):
    out, report = _run_and_report(tmp_path, name)
    assert report.exit_code == 0, report.output  # every requirement of the campaign file holds
    runs = pq.read_table(out / "runs").to_pandas()
    assert runs["success"].all()
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["modes"] == modes
    time_columns = [c for c in runs.columns if c.startswith("t_") and c != "t_end_s"]
    assert time_columns == [f"t_{m.lower()}_s" for m in modes]
    assert set(manifest["columns"]["runs"]) <= set(runs.columns)
    # every mode is flown and the times add up to the flight's end
    assert (runs[time_columns] > 0).all().all()
    assert np.allclose(runs[time_columns].sum(axis=1), runs["t_end_s"], atol=0.03)
    history = pq.read_table(out / "histories").column("mode").combine_chunks()
    assert set(history.dictionary.to_pylist()) == set(modes)


@pytest.fixture(scope="module")
def generic():
    vehicle, mission = load_vehicle(GENERIC_VEHICLE), load_mission(GENERIC_MISSION)
    inputs = pack(vehicle, mission)
    return vehicle, mission, inputs, fly(inputs, history_rate_hz=40.0, mode_names=mode_names(mission))


def test_generic_flight_detumbles_slews_and_holds(generic):
    vehicle, mission, _, result = generic
    assert result.success, result.failure_reason
    assert result.value("modes_completed") == 3
    assert result.value("attitude_error_end_deg") < mission["attitude_error_end_max_deg"]
    # no trajectory: no altitude, no dynamic pressure
    assert np.all(result.column("altitude_m") == 0.0) and np.all(result.column("qbar_pa") == 0.0)
    # the hold ends 60 s after it began
    assert result.value("t_mode_s")[2] == pytest.approx(60.0, abs=0.026)


def test_first_mode_starts_its_guidance_at_separation(generic):
    """The detumble (first mode) profile lasts t1 = 1.5 max |omega_i| / (margin omega_dot_max,i) (000 eq. 19)."""
    vehicle, mission, _, result = generic
    rates = np.radians(mission["initial_state"]["rates_deg_s"])
    accel = vehicle["flight_software"]["guidance_accel_margin"] * derived.omega_dot_max(vehicle, "low")
    assert result.value("t1_mode_s")[0] == pytest.approx(np.max(1.5 * np.abs(rates) / accel), rel=1e-12)


def test_slew_reaches_the_inertial_target(generic):
    """At the hold's end the attitude is the target of the file (60 deg about z) within the hold criterion."""
    _, mission, inputs, result = generic
    from scipy.spatial.transform import Rotation

    target = mission["modes"][1]["target"]
    expected = Rotation.from_euler(target["sequence"], target["euler_deg"], degrees=True)
    assert inputs.modes[1, 9:13] == pytest.approx(expected.as_quat(), abs=1e-15)  # layout.MD_QUATERNION
    assert result.column("theta_t_deg")[-1] < mission["attitude_error_end_max_deg"]


def test_pd_controller_is_004_eq_1():
    """M_i = -Kp,i q_e,i - Kd,i omega_e,i; rates only when the attitude is not controlled."""
    rng = np.random.default_rng(1)
    for _ in range(20):
        q_error = np.append(rng.normal(size=3) * 0.1, 1.0)
        rate_error, kp, kd = rng.normal(size=3), rng.uniform(0, 10, 3), rng.uniform(0, 10, 3)
        out = np.zeros(3)
        control.torque_command(
            1, q_error, rate_error, np.zeros(3), np.zeros(3), kp, kd, np.zeros((3, 3)), np.eye(3), True, out
        )
        assert out == pytest.approx(-kp * q_error[:3] - kd * rate_error, rel=1e-15)
        control.torque_command(
            1, q_error, rate_error, np.zeros(3), np.zeros(3), kp, kd, np.zeros((3, 3)), np.eye(3), False, out
        )
        assert out == pytest.approx(-kd * rate_error, rel=1e-15)


def test_given_gains_are_flown_and_derived_ones_are_000_eq_38():
    """generic-12 flies its file's gains; refex derives them (000 eq. 38, 34)."""
    from refexmc.core import layout as L

    vehicle = load_vehicle(GENERIC_VEHICLE)
    levels = pack(vehicle, load_mission(GENERIC_MISSION)).levels
    gains = vehicle["flight_software"]["gains"]
    assert levels[0, L.LV_KP : L.LV_KP + 3].tolist() == gains["kp"]["low"]
    assert levels[1, L.LV_KD : L.LV_KD + 3].tolist() == gains["kd"]["high"]
    refex = load_vehicle(ROOT / "configs/vehicles/refex.yaml")
    kp, kd = derived.gains(refex, "low")
    packed = pack(refex, load_mission(ROOT / "configs/missions/refex-exo.yaml")).levels
    assert packed[0, L.LV_KP : L.LV_KP + 3].tolist() == kp.tolist()
    assert packed[0, L.LV_KD : L.LV_KD + 3].tolist() == kd.tolist()


def test_sixty_three_thrusters_and_their_64_bit_masks_end_to_end():
    """Thruster 63 stands in for thruster 2 of generic-12: it fires, and its bit (62) reaches the
    history's valves_open exactly (beyond float64's 53-bit integers)."""
    import copy

    from refexmc.campaign.storage import history_table

    vehicle = copy.deepcopy(load_vehicle(GENERIC_VEHICLE))
    thrusters = vehicle["rcs"]["thrusters"]
    spare = {"position_m": [0.0, 0.0, -0.5], "direction": [1.0, 0.0, 0.0]}  # thruster 8's place: -y
    for k in range(len(thrusters) + 1, 63):
        thrusters.append({"id": k, **spare})
    thrusters.append({"id": 63, **{key: thrusters[1][key] for key in ("position_m", "direction")}})
    allocation = vehicle["flight_software"]["allocation"]
    for key, ids in allocation.items():
        allocation[key] = [63 if i == 2 else i for i in ids]
    mission = load_mission(GENERIC_MISSION)
    result = fly(pack(vehicle, mission), history_rate_hz=40.0, mode_names=mode_names(mission))
    assert result.success, result.failure_reason
    assert result.pulse_counts[1] == 0 and result.pulse_counts[62] > 0
    valves = history_table(0, result).column("valves_open").to_numpy()
    assert valves.dtype == np.int64
    assert np.any(valves & (1 << 62)) and not np.any(valves & (1 << 1))
    assert np.all(valves >= 0) and np.all(valves < 1 << 63)


def test_inspect_shows_the_gains_that_are_flown():
    """A vehicle with given gains: inspect reports those, not the 000 eq. 38 design it does not fly."""
    result = CliRunner().invoke(main, ["inspect", str(GENERIC_VEHICLE), "--json"])
    assert result.exit_code == 0, result.output
    info = json.loads(result.output)
    given = load_vehicle(GENERIC_VEHICLE)["flight_software"]["gains"]
    assert info["gains"]["low"] == {"kp": given["kp"]["low"], "kd": given["kd"]["low"]}
    assert info["gains_source"] == "given" and info["controller"] == "pd"


def _three_level_vehicle():
    """generic-12 with three thrust levels named its own way: fine 0.5 N, coarse 1 N, boost 4 N."""
    import copy

    vehicle = copy.deepcopy(load_vehicle(GENERIC_VEHICLE))
    rcs = vehicle["rcs"]
    rcs["thrust_n"] = {"fine": 0.5, "coarse": 1.0, "boost": 4.0}
    times = rcs["valve_time_constants_ms"]["low"]
    rcs["valve_time_constants_ms"] = {name: dict(times) for name in rcs["thrust_n"]}
    gains = vehicle["flight_software"]["gains"]
    for key in ("kp", "kd"):
        gains[key] = {name: list(gains[key]["low"]) for name in rcs["thrust_n"]}
    return vehicle


def test_a_vehicle_with_three_named_thrust_levels_flies_each_mode_at_its_level(tmp_path):
    """Levels are rows named by the vehicle; a mode names its level; the thrust is the level's."""
    import yaml

    vehicle = _three_level_vehicle()
    mission = load_mission(GENERIC_MISSION)
    mission["modes"][0]["thrust"] = "coarse"  # detumble
    mission["modes"][1]["thrust"] = "coarse"  # slew
    mission["modes"][2]["thrust"] = "fine"  # hold
    inputs = pack(vehicle, mission)
    from refexmc.core import layout as L

    assert inputs.levels[:, L.LV_THRUST].tolist() == [0.5, 1.0, 4.0]
    assert inputs.modes[:, L.MD_LEVEL].tolist() == [1, 1, 0]
    result = fly(inputs, history_rate_hz=40.0, mode_names=mode_names(mission))
    assert result.success, result.failure_reason
    # the same mission at the vehicle file's 1 N gives the same detumble and slew (same thrust,
    # same time constants, same gains): only the hold, at half the thrust, differs
    reference = fly(pack(load_vehicle(GENERIC_VEHICLE), load_mission(GENERIC_MISSION)), history_rate_hz=40.0)
    assert result.value("t_mode_s")[:2].tolist() == reference.value("t_mode_s")[:2].tolist()
    assert result.value("fuel_used_kg") != reference.value("fuel_used_kg")
    # a campaign disperses a level by its name
    (tmp_path / "vehicle.yaml").write_text(yaml.safe_dump(vehicle))
    (tmp_path / "mission.yaml").write_text(yaml.safe_dump(mission))
    campaign = {
        "name": "three-levels",
        "vehicle": "vehicle.yaml",
        "mission": "mission.yaml",
        "runs": 3,
        "seed": 1,
        "dispersions": {"rcs.thrust_n.fine": {"dist": "normal", "sigma": 0.01}},
    }
    (tmp_path / "campaign.yaml").write_text(yaml.safe_dump(campaign))
    rows, _ = fly_chunk(load_campaign(tmp_path / "campaign.yaml"), range(3))
    assert [row["status"] for row in rows] == ["ok"] * 3
    assert rows[0]["p.rcs.thrust_n.fine"] == 0.5 and rows[1]["p.rcs.thrust_n.fine"] != 0.5


def test_a_mode_at_a_level_the_vehicle_lacks_is_refused(tmp_path):
    import yaml

    mission = (
        (ROOT / "configs/missions/generic-slew.yaml")
        .read_text()
        .replace("    kind: hold\n", "    kind: hold\n    thrust: turbo\n")
    )
    (tmp_path / "mission.yaml").write_text(mission)
    campaign = yaml.safe_load((ROOT / "campaigns/generic-slew.yaml").read_text())
    campaign["vehicle"] = str(GENERIC_VEHICLE)
    campaign["mission"] = "mission.yaml"
    (tmp_path / "campaign.yaml").write_text(yaml.safe_dump(campaign))
    result = CliRunner().invoke(main, ["validate", str(tmp_path / "campaign.yaml")])
    assert result.exit_code == 2
    line = next(n for n, s in enumerate(mission.splitlines(), 1) if "thrust: turbo" in s)
    assert f"mission.yaml:{line}: modes.2.thrust: thrust level 'turbo' is not one of the vehicle's: low, high" in (
        result.output
    ), result.output


def test_time_constants_must_name_the_thrust_levels(tmp_path):
    text = GENERIC_VEHICLE.read_text().replace("    high: {on_delay: 5.0", "    boost: {on_delay: 5.0")
    (tmp_path / "vehicle.yaml").write_text(text)
    result = CliRunner().invoke(main, ["validate", str(tmp_path / "vehicle.yaml")])
    assert result.exit_code == 2
    expected = "expected the thrust levels of rcs.thrust_n in its order (low, high), got low, boost"
    assert f"rcs.valve_time_constants_ms: {expected}" in result.output, result.output


def test_failures_name_thrusters_by_name_or_id(tmp_path):
    """failures.thrusters takes the vehicle's names (generic-12: XP1 ... ZN2) or ids; they fly as ids."""
    import yaml

    campaign = yaml.safe_load((ROOT / "campaigns/generic-slew.yaml").read_text())
    campaign.update(vehicle=str(GENERIC_VEHICLE), mission=str(GENERIC_MISSION), runs=2, dispersions={})
    campaign["failures"] = {"mode": "fixed", "thrusters": ["XP2", 9]}
    (tmp_path / "campaign.yaml").write_text(yaml.safe_dump(campaign))
    loaded = load_campaign(tmp_path / "campaign.yaml")
    assert loaded["failures"]["thrusters"] == [2, 9]
    rows, _ = fly_chunk(loaded, [1])
    assert rows[0]["failed_thrusters"] == "2,9"
    campaign["failures"]["thrusters"] = ["XP3"]
    (tmp_path / "campaign.yaml").write_text(yaml.safe_dump(campaign))
    result = CliRunner().invoke(main, ["validate", str(tmp_path / "campaign.yaml")])
    assert result.exit_code == 2
    assert "failures.thrusters.0: unknown thruster 'XP3'; did you mean" in result.output, result.output
