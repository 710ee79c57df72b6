"""The table of parameters (config.parameters): each dispersible path declared once, and read by
validation, packing and dispersion alike (issue 26 part 6, docs/campaigns.md "Adding a
dispersible parameter")."""

import copy
import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from refexmc.config import dispersions, pack, parameters, schema
from refexmc.config.errors import ConfigError
from refexmc.config.load import load_mission, load_vehicle
from refexmc.config.parameters import PARAMETERS, TABLES
from tests import naive

ROOT = Path(__file__).resolve().parents[1]


def _pairs():
    """The (vehicle, mission) files of every shipped campaign, each pair once."""
    pairs = set()
    for path in sorted((ROOT / "campaigns").glob("*.yaml")):
        data = yaml.safe_load(path.read_text())
        pairs.add(((path.parent / data["vehicle"]).resolve(), (path.parent / data["mission"]).resolve()))
    return sorted(pairs)


PAIRS = _pairs()


@pytest.fixture(scope="module", params=PAIRS, ids=lambda pair: f"{pair[0].stem}+{pair[1].stem}")
def flown(request):
    """A shipped vehicle and mission with their packed nominal run inputs (no inputs for an entry mission)."""
    vehicle, mission = load_vehicle(request.param[0]), load_mission(request.param[1])
    inputs = None if "entry_flight" in mission else pack.pack(vehicle, mission)
    return vehicle, mission, inputs


def _bits(inputs):
    return {name: np.asarray(array, dtype=float).tobytes() for name, array in inputs._asdict().items()}


def _copy(inputs):
    return inputs._replace(**{name: array.copy() for name, array in inputs._asdict().items()})


def test_every_row_lands_in_a_layout_field_or_says_why():
    for path, param in PARAMETERS.items():
        if param.table is None:
            assert param.special, f"{path} lands nowhere and gives no reason"
            continue
        fields = TABLES[param.table]
        assert param.field in fields.slices, f"{path}: {param.table} has no field {param.field}"
        size = fields.slices[param.field][1]
        per_row = param.table in ("thrusters", "wheels")  # one value per thruster or wheel row
        expected = 1 if per_row or param.shape == "scalar" else 3
        assert size == expected, (path, size)
        assert param.scale > 0.0 and math.isfinite(param.scale), path


def test_a_row_for_a_key_the_schema_lacks_fails_at_import():
    with pytest.raises(KeyError, match="no such config key"):
        parameters.config_key("navigation.no_such_noise_deg", parameters.SCALAR, "nav", "rate_noise_rad_s")


def test_a_config_key_reads_unit_range_and_default_from_its_schema_node():
    param = PARAMETERS["navigation.gps_velocity_noise_m_s"]
    node = schema.MISSION["properties"]["navigation"]["properties"]["gps_velocity_noise_m_s"]
    assert f"[{param.unit}]" in node["description"] and param.unit == "m/s"
    assert (param.lower, param.lower_inclusive, param.upper) == (node["minimum"], True, math.inf)
    assert parameters.schema_default(param.key) == node["default"] == 0.0
    flow = PARAMETERS["rcs.derating"]  # (0, 1]: exclusive minimum and a maximum
    assert (flow.lower, flow.lower_inclusive, flow.upper) == (0.0, False, 1.0)


def test_every_distribution_has_one_check():
    assert list(dispersions._CHECKS) == list(dispersions.DISTRIBUTIONS)  # noqa: SLF001


def test_every_declared_path_validates_at_its_nominal(flown):
    """Every path a shipped vehicle and mission declare passes the campaign check at its nominal
    value (inside its schema range), resolved to that value: validation reads the same rows."""
    vehicle, mission, _ = flown
    checked = 0
    for path, param in PARAMETERS.items():
        if dispersions.undeclared(path, vehicle, mission) is not None:  # not flown here
            continue
        value = dispersions.nominal(path, vehicle, mission)
        if param.shape == "inertia":
            spec = {"dist": "inertia", "moments_sigma_fraction": 0.01}
        else:
            spec = {"dist": "constant", "value": value.tolist()}
        resolved = dispersions.check({path: spec}, vehicle, mission, None, {})[path]
        if param.shape != "inertia":
            np.testing.assert_array_equal(resolved["value"], value, err_msg=path)
        checked += 1
    assert checked


def test_the_nominal_applied_through_apply_is_the_packed_nominal_bit_for_bit(flown):
    """For every path a shipped vehicle and mission declare: writing its nominal value with
    ``dispersions.apply`` into the packed inputs (its field first spoiled with NaN, so the write
    is seen) gives the packer's inputs bit for bit: packer and apply read the same row."""
    vehicle, mission, inputs = flown
    if inputs is None:
        pytest.skip("an entry mission: campaign.entry_plan builds its vehicle (tests/test_x38_campaign.py)")
    levels = pack.level_names(vehicle)
    packed = _bits(inputs)
    checked = []
    for path, param in PARAMETERS.items():
        if dispersions.undeclared(path, vehicle, mission) is not None:  # not flown here
            continue
        run = _copy(inputs)
        if param.table is not None:
            offset, count = TABLES[param.table].slices[param.field]
            table = getattr(run, param.table)
            if table.ndim == 2:
                table[:, offset] = np.nan
            else:
                table[offset : offset + count] = np.nan
        dispersions.apply(run, path, dispersions.nominal(path, vehicle, mission), inputs.atmosphere, levels)
        differ = [name for name, bits in _bits(run).items() if bits != packed[name]]
        assert not differ, f"{path}: the nominal through apply differs from the packed nominal in {differ}"
        checked.append(path)
    assert checked


def _flown_paths(vehicle, mission):
    """Every dispersible path the vehicle and mission fly, the per-level ones for each of its levels."""
    levels = pack.level_names(vehicle)
    paths = []
    for path in PARAMETERS:
        for level in levels if path.startswith(("rcs.thrust_n.low", "rcs.valve_time_constants_ms.low.")) else [None]:
            paths.append(path if level is None else path.replace(".low", f".{level}", 1))
    return [path for path in dict.fromkeys(paths) if dispersions.undeclared(path, vehicle, mission) is None]


def test_a_chunks_dispersions_written_at_once_are_each_runs_alone_bit_for_bit(flown):
    """``dispersions.apply_rows`` writes a chunk's values path by path into tables stacked one per
    run; tests/naive.py's twin writes them run by run, element by element. Every path the vehicle
    and mission fly (the special ones too: nozzle constants, thrust levels and their regulators,
    misalignment, inertia, derating, valve time constants, density), 5 runs of values spread
    around the nominal, in one order: the same bits, table by table."""
    vehicle, mission, inputs = flown
    if inputs is None:
        pytest.skip("an entry mission: campaign.entry_plan builds its vehicle (tests/test_x38_campaign.py)")
    levels = pack.level_names(vehicle)
    paths = _flown_paths(vehicle, mission)
    rng = np.random.default_rng(11)
    runs = []
    for _ in range(5):
        values = {}
        for path in paths:
            nominal = np.asarray(dispersions.nominal(path, vehicle, mission), dtype=float)
            values[path] = nominal + 0.01 * (np.abs(nominal) + 1.0) * rng.standard_normal(nominal.shape)
        runs.append(values)
    stack = dispersions.stacked(inputs, 5)  # as Sampler.inputs_for_runs: a copy per run of what is written
    for path in paths:
        dispersions.apply_rows(stack, path, np.array([values[path] for values in runs]), inputs.atmosphere, levels)
    for k, values in enumerate(runs):
        alone = _copy(inputs)
        for path in paths:
            naive.apply_dispersion(alone, path, values[path], inputs.atmosphere, levels)
        run = inputs._replace(**{name: array[k] for name, array in stack._asdict().items()})
        differ = [name for name, bits in _bits(run).items() if bits != _bits(alone)[name]]
        assert not differ, f"run {k}: {differ} differ"
    assert _bits(run) != _bits(inputs)  # the values were written


def test_omitted_optional_keys_pack_their_schema_default(monkeypatch):
    """The packer's default of an optional key is the schema's, declared once: change it there
    and the packed field follows."""
    mission = copy.deepcopy(load_mission(ROOT / "configs/missions/refex-exo.yaml"))
    mission["navigation"].pop("gps_velocity_noise_m_s", None)
    node = schema.MISSION["properties"]["navigation"]["properties"]["gps_velocity_noise_m_s"]
    offset = parameters.L.NAV.slices["gps_velocity_noise_m_s"][0]
    assert pack.pack_navigation(mission)[offset] == 0.0
    monkeypatch.setitem(node, "default", 0.25)
    assert pack.pack_navigation(mission)[offset] == 0.25


def test_a_new_parameter_is_one_row(monkeypatch):
    """The recipe of docs/campaigns.md: one row for an existing config key and layout field
    makes it dispersible: checked against its schema range, given its nominal and applied."""
    path = "aerodynamics.reference_area_m2"
    vehicle = load_vehicle(ROOT / "configs/vehicles/refex.yaml")
    mission = load_mission(ROOT / "configs/missions/refex-exo.yaml")
    with pytest.raises(ConfigError, match="unknown parameter path"):
        dispersions.check({path: {"dist": "constant", "value": 2.0}}, vehicle, mission, None, {})

    row = parameters.config_key(path, parameters.SCALAR, "vehicle", "aero_area_m2")
    monkeypatch.setitem(PARAMETERS, path, row)
    specs = dispersions.check({path: {"dist": "constant", "value": 2.0}}, vehicle, mission, None, {})
    assert dispersions.columns(path, vehicle) == [f"p.{path}"]
    np.testing.assert_array_equal(dispersions.nominal(path, vehicle, mission), [vehicle["aerodynamics"][path[13:]]])
    inputs = pack.pack(vehicle, mission)
    dispersions.apply(inputs, path, specs[path]["value"], inputs.atmosphere)
    assert inputs.vehicle[parameters.L.V_AERO_AREA] == 2.0
    with pytest.raises(ConfigError, match=r"outside the physical range > 0"):  # the schema's exclusiveMinimum
        dispersions.check({path: {"dist": "constant", "value": -1.0}}, vehicle, mission, None, {})


def test_the_unit_factor_matches_the_units_the_names_carry():
    """Independent of the rows: a path in degrees lands in a field in radians with the factor
    pi/180, and any other path in a field of the same unit suffix with the factor 1."""
    suffixes = {"_deg": "_rad", "_deg_s": "_rad_s"}
    for path, param in PARAMETERS.items():
        if param.table is None:
            continue
        suffix = next((s for s in ("_deg_s", "_deg") if path.endswith(s)), None)
        if suffix is not None:
            assert param.field.endswith(suffixes[suffix]) and param.scale == math.pi / 180.0, path
        else:
            assert param.scale == 1.0, path
            unit = "_" + path.rsplit("_", 1)[-1]
            assert param.field.endswith(unit) or param.unit == "-", (path, param.field)


def _file_value(vehicle, mission, path):
    """The value a file gives ``path``, read by hand (the per-wheel key from each unit), or None."""
    if path == "wheels.initial_momentum_n_m_s":
        units = vehicle.get("wheels", {}).get("units")
        return None if units is None else [unit.get("initial_momentum_n_m_s", 0.0) for unit in units]
    node = mission if path.split(".")[0] in ("initial_state", "navigation", "local") else vehicle
    for part in path.split("."):
        if not isinstance(node, dict) or part not in node:
            return None
        node = node[part]
    return node


def test_packed_fields_hold_the_file_values_in_si_units(flown):
    """An independent reading of the packer: each field a shipped file's parameter lands in holds
    the file's value, through numpy's radians where the path is in degrees, bit for bit."""
    vehicle, mission, inputs = flown
    if inputs is None:
        pytest.skip("an entry mission packs no core tables")
    checked = 0
    for path, param in PARAMETERS.items():
        if param.table is None or param.special or param.key is None:
            continue
        value = _file_value(vehicle, mission, path)
        if value is None:
            continue
        expected = np.radians(value) if path.endswith(("_deg", "_deg_s")) else np.asarray(value, dtype=float)
        offset, count = TABLES[param.table].slices[param.field]
        table = getattr(inputs, param.table)
        packed = table[:, offset] if table.ndim == 2 else table[offset : offset + count]
        expected = np.broadcast_to(expected, packed.shape)
        assert packed.tobytes() == np.ascontiguousarray(expected).tobytes(), path
        checked += 1
    assert checked


def _defaults(node, path=()):
    """(key path, required?) of every schema key that declares a ``default``."""
    for key, child in node.get("properties", {}).items():
        if "default" in child:
            yield ".".join((*path, key)), key in node.get("required", ())
        yield from _defaults(child, (*path, key))
    for child in (node.get("items"), node.get("additionalProperties")):
        if isinstance(child, dict):
            yield from _defaults(child, (*path, "*"))


def test_a_schema_default_is_declared_only_on_optional_keys():
    """A default is the value a file that omits the key has: a required key cannot have one, and the
    defaults the packers read are found (the walk sees them)."""
    found = {}
    for root in (schema.VEHICLE, schema.MISSION, schema.ENTRY_MISSION):
        found.update(dict(_defaults(root)))
    assert "rcs.feed.ambient_pressure_pa" in found and "flight_software.burn_guidance.law" in found
    assert "navigation.gps_velocity_noise_m_s" in found
    required = sorted(key for key, is_required in found.items() if is_required)
    assert required == [], f"required keys with a default: {required}"
