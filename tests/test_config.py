"""Config schema and loader: every key declared and documented, bad input reported precisely."""

from pathlib import Path

import numpy as np
import pytest
import yaml

from refexmc.config import schema
from refexmc.config.errors import ConfigError
from refexmc.config.load import inertia_problem, load_any, load_campaign, load_mission, load_vehicle
from refexmc.config.pack import pack
from refexmc.core import layout as L

ROOT = Path(__file__).resolve().parents[1]
VEHICLE = ROOT / "configs/vehicles/refex.yaml"
MISSION = ROOT / "configs/missions/refex-exo.yaml"


def _walk(node, path="root"):
    yield path, node
    for key, sub in node.get("properties", {}).items():
        yield from _walk(sub, f"{path}.{key}")
    if isinstance(node.get("items"), dict):
        yield from _walk(node["items"], f"{path}[]")
    if isinstance(node.get("additionalProperties"), dict):
        yield from _walk(node["additionalProperties"], f"{path}.*")


@pytest.mark.parametrize("name", ["VEHICLE", "MISSION", "CAMPAIGN"])
def test_every_key_is_documented_and_closed(name):
    for path, node in _walk(getattr(schema, name)):
        assert node.get("description"), f"{path} has no description"
        if node.get("type") == "object" and "properties" in node:
            assert node.get("additionalProperties") is False, f"{path} accepts unknown keys"
        if node.get("type") == "number" and not path.endswith("[]"):  # vector items: unit on the vector
            assert "[" in node["description"], f"{path}: description names no unit"


def test_reference_configs_are_valid():
    assert load_vehicle(VEHICLE)["name"] == "refex"
    assert load_mission(MISSION)["name"] == "refex-exo"
    assert load_any(ROOT / "campaigns/nominal.yaml")[0] == "campaign"


def _write(tmp_path, text, name="bad.yaml"):
    path = tmp_path / name
    path.write_text(text)
    return path


def _vehicle_text(replace_from, replace_to):
    text = VEHICLE.read_text()
    assert replace_from in text
    return text.replace(replace_from, replace_to, 1)


def test_unknown_key_names_line_path_and_suggestion(tmp_path):
    path = _write(tmp_path, _vehicle_text("  isp_s: 70.0", "  isp_sec: 70.0"))
    with pytest.raises(ConfigError) as err:
        load_vehicle(path)
    line = next(i for i, s in enumerate(path.read_text().splitlines(), 1) if "isp_sec" in s)
    assert err.value.line == line
    assert err.value.path == ("rcs", "isp_sec")
    assert "did you mean 'isp_s'" in str(err.value)
    assert str(path) in str(err.value)


def test_wrong_type_and_out_of_range(tmp_path):
    path = _write(tmp_path, _vehicle_text("  isp_s: 70.0", "  isp_s: seventy"))
    with pytest.raises(ConfigError, match=r"rcs\.isp_s: expected number"):
        load_vehicle(path)
    path = _write(tmp_path, _vehicle_text("  isp_s: 70.0", "  isp_s: -70.0"))
    with pytest.raises(ConfigError, match=r"expected a value > 0"):
        load_vehicle(path)


def test_yaml_syntax_error_reports_line(tmp_path):
    path = _write(tmp_path, "name: x\nruns: [1, 2\nseed: 3\n")
    with pytest.raises(ConfigError) as err:
        load_campaign(path)
    assert "YAML syntax error" in str(err.value)
    assert err.value.line is not None


def test_missing_file(tmp_path):
    with pytest.raises(ConfigError, match="file not found"):
        load_campaign(tmp_path / "nope.yaml")


def test_yaml_12_floats_are_numbers(tmp_path):
    text = MISSION.read_text().replace("mu_m3_s2: 3.986004e14", "mu_m3_s2: 3986004e8")
    assert load_mission(_write(tmp_path, text))["earth"]["mu_m3_s2"] == pytest.approx(3.986004e14)


@pytest.mark.parametrize(
    ("inertia", "problem"),
    [
        ([[20, 0, 0], [0, 240, 0], [0, 0, -1]], "positive definite"),
        ([[1, 0, 0], [0, 1, 0], [0, 0, 3]], "triangle inequality"),
        ([[20, 1, 0], [0, 240, 0], [0, 0, 250]], "symmetric"),
    ],
)
def test_non_physical_inertia(inertia, problem, tmp_path):
    assert problem in inertia_problem(inertia)
    rows = "\n".join(f"  - {row}" for row in inertia)
    text = VEHICLE.read_text()
    start = text.index("inertia_kg_m2:")
    end = text.index("com_offset_m:")
    path = _write(tmp_path, text[:start] + "inertia_kg_m2:\n" + rows + "\n" + text[end:])
    with pytest.raises(ConfigError, match=problem):
        load_vehicle(path)


def test_thruster_ids_in_allocation_and_failures_are_checked(tmp_path):
    path = _write(tmp_path, _vehicle_text('"-z": [5]', '"-z": [9]'))
    with pytest.raises(ConfigError, match=r"thruster id 1\.\.8, got 9"):
        load_vehicle(path)
    campaign = (ROOT / "campaigns/nominal.yaml").read_text()
    campaign = campaign.replace("../configs", str(ROOT / "configs")).replace(
        "  mode: none", "  mode: fixed\n  thrusters: [1, 9]"
    )
    with pytest.raises(ConfigError, match=r"failures\.thrusters\.1"):
        load_campaign(_write(tmp_path, campaign, "c.yaml"))


def test_inline_vehicle_errors_carry_the_campaign_path(tmp_path):
    vehicle = yaml.safe_load(VEHICLE.read_text())
    vehicle["rcs"]["thrust_n"]["low"] = "x"
    campaign = {
        "name": "inline",
        "vehicle": vehicle,
        "mission": str(MISSION),
        "runs": 1,
        "seed": 1,
    }
    path = _write(tmp_path, yaml.safe_dump(campaign, sort_keys=False), "c.yaml")
    with pytest.raises(ConfigError) as err:
        load_campaign(path)
    assert err.value.path == ("vehicle", "rcs", "thrust_n", "low")
    assert err.value.line is not None


def test_pack_uses_every_field_of_the_layout():
    """Each named field of each input array is written by the packer (no silent zeros)."""
    inputs = pack(load_vehicle(VEHICLE), load_mission(MISSION))
    assert inputs.vehicle.shape == (L.VEHICLE_SIZE,)
    assert inputs.thrusters.shape == (8, L.THRUSTER_SIZE)
    assert inputs.mission.shape == (L.MISSION_SIZE,)
    # physical constants and thresholds are all non-zero in the reference mission
    for name in ("earth_radius_m", "ssm_exit_altitude_m", "geem_handover_qbar_pa", "integrator_max_step_s"):
        assert inputs.mission[L.MISSION.slices[name][0]] > 0.0
    assert np.allclose(np.linalg.norm(inputs.mission[L.M_SUN_DIRECTION : L.M_SUN_DIRECTION + 3]), 1.0)
    # time constants in seconds (000 Table 2, low thrust on-delay 19.1 ms)
    assert inputs.thrusters[0, L.T_ON_DELAY_LOW] == pytest.approx(0.0191)
    assert inputs.fsw[L.F_CONTROL_PERIOD] == pytest.approx(0.025)


def test_requirement_columns_are_the_numeric_columns_of_a_runs_row():
    """The columns a campaign file's requirements may name are those a runs row really has."""
    from refexmc.campaign.chunk import RunPlan
    from refexmc.config import dispersions
    from refexmc.config.requirements import NOT_METRIC_COLUMNS, runs_metric_columns

    campaign = load_campaign(ROOT / "campaigns" / "smoke.yaml")
    plan = RunPlan(campaign)
    row, _, _ = plan.fly(3, campaign["output"]["history_rate_hz"])
    numeric = [k for k, v in row.items() if k not in NOT_METRIC_COLUMNS and isinstance(v, int | float)]
    numeric = [k for k in numeric if not isinstance(row[k], bool)]  # success is a flag, not a metric column
    parameters = [c for key in campaign["dispersions"] for c in dispersions.columns(key, campaign["vehicle"])]
    assert sorted(runs_metric_columns(len(campaign["vehicle"]["rcs"]["thrusters"]), parameters)) == sorted(numeric)
