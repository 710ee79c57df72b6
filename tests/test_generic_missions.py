"""Any vehicle, any mission (issue 12): the mode program flies ReFEx unchanged, ReFEx without
SSM, and a 12-thruster spacecraft with plain PD and no trajectory; outputs are named from the files.
"""

import json
import math
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
    """baselines/smoke was flown by the seven-mode loop before the mode program: same table, bit for bit."""
    campaign = load_campaign(ROOT / "campaigns/smoke.yaml")
    rows, _ = fly_chunk(campaign, range(campaign["runs"]))
    flown = storage.runs_table(rows)
    baseline = pq.read_table(ROOT / "baselines/smoke/runs").sort_by("run_id")
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
    assert result.value("theta_t_handover_deg") < mission["handover_max_angle_deg"]
    # no trajectory: no altitude, no dynamic pressure
    assert np.all(result.column("altitude_m") == 0.0) and np.all(result.column("qbar_pa") == 0.0)
    # the hold ends 60 s after it began
    assert result.value("t_mode_s")[2] == pytest.approx(60.0, abs=0.026)


def test_first_mode_starts_its_guidance_at_separation(generic):
    """The detumble (first mode) profile lasts t1 = 1.5 max |omega_i| / (margin omega_dot_max,i) (000 eq. 19)."""
    vehicle, mission, _, result = generic
    rates = np.radians(mission["separation"]["rates_deg_s"])
    accel = vehicle["flight_software"]["guidance_accel_margin"] * derived.omega_dot_max(vehicle, "low")
    assert result.value("t1_mode_s")[0] == pytest.approx(np.max(1.5 * np.abs(rates) / accel), rel=1e-12)


def test_slew_reaches_the_inertial_target(generic):
    """At the hold's end the attitude is the target of the file (60 deg about z) within the hold criterion."""
    _, mission, inputs, result = generic
    from scipy.spatial.transform import Rotation

    target = mission["modes"][1]["target"]
    expected = Rotation.from_euler(target["sequence"], target["euler_deg"], degrees=True)
    assert inputs.modes[1, 9:13] == pytest.approx(expected.as_quat(), abs=1e-15)  # layout.MD_QUATERNION
    assert result.column("theta_t_deg")[-1] < mission["handover_max_angle_deg"]


def test_pd_controller_is_004_eq_1():
    """M_i = -Kp,i q_e,i - Kd,i omega_e,i; rates only when the attitude is not controlled."""
    rng = np.random.default_rng(1)
    for _ in range(20):
        q_error = np.append(rng.normal(size=3) * 0.1, 1.0)
        rate_error, kp, kd = rng.normal(size=3), rng.uniform(0, 10, 3), rng.uniform(0, 10, 3)
        out = np.zeros(3)
        control.torque_command(1, q_error, rate_error, np.zeros(3), np.zeros(3), kp, kd, np.eye(3), True, out)
        assert out == pytest.approx(-kp * q_error[:3] - kd * rate_error, rel=1e-15)
        control.torque_command(1, q_error, rate_error, np.zeros(3), np.zeros(3), kp, kd, np.eye(3), False, out)
        assert out == pytest.approx(-kd * rate_error, rel=1e-15)


def test_given_gains_are_flown_and_derived_ones_are_000_eq_38():
    """generic-12 flies its file's gains; refex derives them (000 eq. 38, 34)."""
    from refexmc.core import layout as L

    vehicle = load_vehicle(GENERIC_VEHICLE)
    fsw = pack(vehicle, load_mission(GENERIC_MISSION)).fsw
    gains = vehicle["flight_software"]["gains"]
    assert fsw[L.F_KP : L.F_KP + 3].tolist() == gains["kp"]["low"]
    assert fsw[L.F_KD + 3 : L.F_KD + 6].tolist() == gains["kd"]["high"]
    refex = load_vehicle(ROOT / "configs/vehicles/refex.yaml")
    kp, kd = derived.gains(refex, "low")
    packed = pack(refex, load_mission(ROOT / "configs/missions/refex-exo.yaml")).fsw
    assert packed[L.F_KP : L.F_KP + 3] == pytest.approx(kp, rel=0) and packed[L.F_KD : L.F_KD + 3] == pytest.approx(
        kd, rel=0
    )
    assert math.isfinite(kp.sum())


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
