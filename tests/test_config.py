"""Config schema and loader: every key declared and documented, bad input reported precisely."""

from pathlib import Path

import numpy as np
import pytest
import yaml

from refexmc.config import schema
from refexmc.config.errors import ConfigError
from refexmc.config.load import inertia_problem, load_any, load_campaign, load_mission, load_vehicle, read_yaml
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
    for branch in node.get("allOf", []):  # keys that depend on a type: {if: type == X, then: keys}
        if "then" in branch:
            yield from _walk(branch["then"], f"{path}<{branch['if']['properties']['type']['const']}>")


@pytest.mark.parametrize("name", ["VEHICLE", "MISSION", "CAMPAIGN"])
def test_every_key_is_documented_and_closed(name):
    for path, node in _walk(getattr(schema, name)):
        assert node.get("description"), f"{path} has no description"
        if node.get("type") == "object" and "properties" in node:
            closed = node.get("additionalProperties") is False or (
                node.get("allOf") and all(b["then"].get("additionalProperties") is False for b in node["allOf"])
            )
            assert closed, f"{path} accepts unknown keys"
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


def test_pack_marks_detected_thrusters_known_and_leaves_them_out_of_the_table():
    """pack(failed_thrusters, detected_thrusters): every failed thruster is failed, only the
    detected ones are known to the flight software (failure_known) and have a zero column in its
    allocation table; a detected id that has not failed is not a failure and changes nothing."""
    vehicle, mission = load_vehicle(VEHICLE), load_mission(MISSION)
    plain = pack(vehicle, mission, failed_thrusters=(1, 8))
    told = pack(vehicle, mission, failed_thrusters=(1, 8), detected_thrusters=(8, 3))
    assert told.thrusters[:, L.T_FAILED].tolist() == plain.thrusters[:, L.T_FAILED].tolist() == [1, 0, 0, 0, 0, 0, 0, 1]
    assert plain.thrusters[:, L.T_FAILURE_KNOWN].tolist() == [0] * 8
    assert told.thrusters[:, L.T_FAILURE_KNOWN].tolist() == [0, 0, 0, 0, 0, 0, 0, 1]
    assert plain.allocation[:, 7].any() and not told.allocation[:, 7].any()
    np.testing.assert_array_equal(np.delete(told.allocation, 7, axis=1), np.delete(plain.allocation, 7, axis=1))


def test_pack_uses_every_field_of_the_layout():
    """Each named field of each input array is written by the packer (no silent zeros)."""
    inputs = pack(load_vehicle(VEHICLE), load_mission(MISSION))
    assert inputs.vehicle.shape == (L.VEHICLE_SIZE,)
    assert inputs.thrusters.shape == (8, L.thruster_size(2))  # two thrust levels, low and high
    assert inputs.levels.shape == (2, L.LEVEL_SIZE)
    assert inputs.levels[:, L.LV_THRUST].tolist() == [2.157, 8.92]
    assert inputs.mission.shape == (L.MISSION_SIZE,)
    # physical constants and thresholds are all non-zero in the reference mission
    for name in ("earth_radius_m", "attitude_error_end_max_rad", "max_flight_time_s", "integrator_max_step_s"):
        assert inputs.mission[L.MISSION.slices[name][0]] > 0.0
    assert inputs.modes.shape == (7, L.MODE_SIZE)
    assert inputs.exits.shape == (11, L.EXIT_SIZE)  # one row per predicate of refex-exo.yaml
    assert np.allclose(np.linalg.norm(inputs.mission[L.M_SUN_DIRECTION : L.M_SUN_DIRECTION + 3]), 1.0)
    # time constants in seconds (000 Table 2, low thrust on-delay 19.1 ms)
    assert inputs.thrusters[0, L.time_constant_column(0, L.ON_DELAY)] == pytest.approx(0.0191)
    assert inputs.thrusters[0, L.time_constant_column(1, L.FALL)] == pytest.approx(0.045)
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
    names = [mode["name"] for mode in campaign["mission"]["modes"]]
    columns = runs_metric_columns(names, len(campaign["vehicle"]["rcs"]["thrusters"]), parameters)
    assert sorted(columns) == sorted(numeric)


# --- numbers YAML accepts but no physical quantity has, and keys YAML would silently drop --------

# Every spelling PyYAML reads as a non-finite float (YAML 1.1 '.inf'/'.nan' in any case, with a
# sign; YAML 1.2 exponents that overflow; an explicit !!float tag), and an integer too large for a
# float (it would overflow when packed).
NON_FINITE = [".inf", "-.Inf", "+.INF", ".Inf", ".nan", ".NaN", ".NAN", "1e999", "-1e999", "1.0e+999"]
NON_FINITE += ["!!float inf", "!!float -inf", "!!float nan", "1" + "0" * 400]


def _line_of(path, needle):
    return next(i for i, s in enumerate(Path(path).read_text().splitlines(), 1) if needle in s)


@pytest.mark.parametrize("spelling", NON_FINITE)
def test_non_finite_number_in_a_vehicle_file_is_bad_input(tmp_path, spelling):
    path = _write(tmp_path, _vehicle_text("  isp_s: 70.0", f"  isp_s: {spelling}"))
    with pytest.raises(ConfigError) as err:
        load_vehicle(path)
    assert err.value.file == path
    assert err.value.line == _line_of(path, "isp_s:")
    assert err.value.path == ("rcs", "isp_s")
    assert "expected a finite number, got" in err.value.message
    assert spelling.split()[-1][:20] in err.value.message  # as written


NOMINAL_CAMPAIGN = ROOT / "campaigns/nominal.yaml"


def _config_text(kind):
    source = {"vehicle": VEHICLE, "mission": MISSION, "campaign": NOMINAL_CAMPAIGN}[kind]
    return source.read_text().replace("../configs", str(ROOT / "configs"))


# (file kind, text replaced, replacement, key path of the error, text on the error's line)
NON_FINITE_PLACES = [
    ("mission", "9.661e-8", ".nan", ("atmosphere", 7, "density_kg_m3"), "base_altitude_km: 110,"),
    ("mission", "rates_deg_s: [", "rates_deg_s: [-.inf, ", ("initial_state", "rates_deg_s", 0), "-.inf"),
    ("campaign", "runs: 1\n", "runs: 1e999\n", ("runs",), "1e999"),
    ("campaign", "history_rate_hz: 2", "history_rate_hz: .NaN", ("output", "history_rate_hz"), ".NaN"),
    ("campaign", "dispersions: {}", "dispersions: {rcs.isp_s: {dist: normal, sigma: .inf}}", None, ".inf"),
    ("campaign", "dispersions: {}", "dispersions: {.inf: 1}", ("dispersions",), ".inf"),
]


@pytest.mark.parametrize(("kind", "old", "new", "key_path", "on_line"), NON_FINITE_PLACES)
def test_non_finite_numbers_anywhere_are_bad_input(tmp_path, kind, old, new, key_path, on_line):
    text = _config_text(kind)
    assert old in text
    path = _write(tmp_path, text.replace(old, new, 1))
    with pytest.raises(ConfigError, match="expected a finite number") as err:
        load_any(path)
    assert err.value.line == _line_of(path, on_line)
    assert err.value.path == (key_path or ("dispersions", "rcs.isp_s", "sigma"))


def test_tiny_numbers_that_underflow_to_zero_are_still_numbers(tmp_path):
    text = MISSION.read_text().replace("rate_noise_deg_s: ", "rate_noise_deg_s: 1e-999 #", 1)
    assert load_mission(_write(tmp_path, text))["navigation"]["rate_noise_deg_s"] == 0.0


# (file kind, text replaced, replacement, key path, text on the first occurrence's line, on the second's)
DUPLICATES = [
    ("vehicle", "mass_kg: 400.0", "mass_kg: 400.0\nmass_kg: 4.0", ("mass_kg",), "mass_kg: 400.0", "mass_kg: 4.0"),
    ("vehicle", "    high: 8.92", "    high: 8.92\n    low: 1.0", ("rcs", "thrust_n", "low"), "low: 2.157", "low: 1.0"),
    (
        "vehicle",
        "low: {on_delay: 19.1,",
        "low: {on_delay: 19.1, on_delay: 0.0,",
        ("rcs", "valve_time_constants_ms", "low", "on_delay"),
        "on_delay: 0.0",
        "on_delay: 0.0",
    ),
    (
        "mission",
        "  altitude_m: 85000.0",
        "  altitude_m: 85000.0\n  altitude_m: 1.0",
        ("initial_state", "altitude_m"),
        "altitude_m: 85000.0",
        "altitude_m: 1.0",
    ),
    ("campaign", "seed: 20231121", "seed: 20231121\nseed: 1", ("seed",), "seed: 20231121", "seed: 1\n"),
    (
        "campaign",
        "  history_rate_hz: 2",
        "  history_rate_hz: 2\n  history_rate_hz: 40",
        ("output", "history_rate_hz"),
        "history_rate_hz: 2\n",
        "history_rate_hz: 40",
    ),
    (
        "campaign",
        "dispersions: {}",
        "dispersions:\n  rcs.isp_s: {dist: normal, sigma: 1.0}\n  rcs.isp_s: {dist: normal, sigma: 9.0}",
        ("dispersions", "rcs.isp_s"),
        "sigma: 1.0",
        "sigma: 9.0",
    ),
]


@pytest.mark.parametrize(("kind", "old", "new", "key_path", "first", "second"), DUPLICATES)
def test_duplicate_keys_are_bad_input(tmp_path, kind, old, new, key_path, first, second):
    text = _config_text(kind)
    assert old in text
    path = _write(tmp_path, text.replace(old, new, 1))
    with pytest.raises(ConfigError, match="duplicate key") as err:
        load_any(path)
    lines = path.read_text().splitlines(keepends=True)
    first_line = next(i for i, s in enumerate(lines, 1) if first in s)
    second_line = max(i for i, s in enumerate(lines, 1) if second in s)
    assert (err.value.file, err.value.line, err.value.path) == (path, second_line, key_path)
    assert f"duplicate key '{key_path[-1]}' (first at line {first_line})" in err.value.message


def test_duplicate_key_in_an_inline_vehicle_names_the_campaign_file(tmp_path):
    body = VEHICLE.read_text().replace("  isp_s: 70.0", "  isp_s: 70.0\n  isp_s: 7000.0")
    inline = "\n".join("  " + line for line in body.splitlines())
    campaign = f"name: inline\nvehicle:\n{inline}\nmission: {MISSION}\nruns: 1\nseed: 1\n"
    path = _write(tmp_path, campaign, "c.yaml")
    with pytest.raises(ConfigError, match="duplicate key 'isp_s'") as err:
        load_campaign(path)
    assert err.value.file == path
    assert err.value.path == ("vehicle", "rcs", "isp_s")
    assert err.value.line == _line_of(path, "isp_s: 7000.0")


def test_yaml_merge_keys_override_without_being_duplicates(tmp_path):
    text = "name: m\nbase: &b {x: 1, y: 2}\nc:\n  <<: *b\n  x: 5\n"
    data, lines = read_yaml(_write(tmp_path, text))
    assert data["c"] == {"x": 5, "y": 2}
    assert lines[("c", "x")] == 5


def test_recursive_alias_is_bad_input_not_a_crash(tmp_path):
    with pytest.raises(ConfigError, match="recursive YAML alias"):
        read_yaml(_write(tmp_path, "a: &x [1, *x]\n"))
