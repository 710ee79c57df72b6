"""Every dispersible parameter, declared once: its path, shape and where it lands in the core.

A path names a quantity in the user's units, mostly the key path of the vehicle or mission file
(``initial_state.rates_deg_s``); its unit, meaning, physical range and default are those its schema
node declares (``schema.py``: "[unit]" in each description). A few paths exist only as
dispersions (``rcs.thrust_scale``, ``atmosphere.density_scale``, the entry factors): they declare
their unit, meaning, range and nominal here.

Each row of ``PARAMETERS`` also says where the value lands in the packed run inputs: the table
of ``RunInputs`` (``vehicle``, ``mission``, ``nav``, ``thrusters``, ``wheels``), the field of its
``core.layout`` block and the factor from the user's unit to SI. The packers (``config.pack``)
write the nominal value there and ``config.dispersions.apply`` a drawn one, both through
:func:`put`, so adding a dispersible scalar is one schema key plus one row here (and the core's
layout field). Paths that do not land in one field declare why in ``special``; ``apply``, the
packers and ``nominal`` treat them by name (docs/campaigns.md, "Adding a dispersible parameter").
"""

import math
import re
from typing import NamedTuple

import numpy as np

from refexmc.config import schema
from refexmc.core import layout as L

AXES = ("x", "y", "z")
INERTIA_COMPONENTS = ("xx", "yy", "zz", "xy", "xz", "yz")
# paths of the mission file (else the vehicle's)
MISSION_ROOTS = ("initial_state", "navigation", "local", "entry_flight")
DEG = math.pi / 180.0  # degrees -> radians, the same bits as numpy's radians (x * (pi / 180))

# shapes: how many components a path has (dispersions.components)
SCALAR, VECTOR, ATTITUDE, INERTIA, THRUSTER, WHEEL, DERATING = (
    "scalar",
    "vector",
    "attitude",
    "inertia",
    "thruster",
    "wheel",
    "derating",
)
# the RunInputs tables a path may land in, with their layouts (a wheel or thruster table: every row)
TABLES = {"vehicle": L.VEHICLE, "mission": L.MISSION, "nav": L.NAV, "thrusters": L.THRUSTER, "wheels": L.WHEEL}


class Parameter(NamedTuple):
    path: str
    unit: str
    doc: str
    shape: str  # scalar | vector | thruster | wheel | derating | inertia | attitude
    lower: float = -math.inf  # physical range of every component (config keys: from the schema)
    upper: float = math.inf
    lower_inclusive: bool = True
    table: str | None = None  # RunInputs table it lands in (TABLES), None: special
    field: str | None = None  # the field of that table's layout
    scale: float = 1.0  # user unit -> SI
    key: str | None = None  # the config key path ("[]": every item of a list); None: dispersion only
    nominal: float | None = None  # a dispersion-only path's nominal value (every component)
    # why it is treated by name: by the packers (its nominal) and, without a table, by apply
    special: str = ""


def _schema_root(path):
    root = path.split(".")[0]
    if root == "entry_flight":
        return schema.ENTRY_MISSION
    return schema.MISSION if root in MISSION_ROOTS else schema.VEHICLE


def key_node(key):
    """The schema node of a config key path as declared (an array's node, not its items), or
    None; ``[]`` steps into the items of a list, a level name into a per-level mapping."""
    node = _schema_root(key)
    for part in key.split("."):
        if part.endswith("[]"):
            node = node.get("properties", {}).get(part[:-2])
            node = None if node is None else node.get("items")
        else:
            properties, per_key = node.get("properties", {}), node.get("additionalProperties")
            node = properties.get(part, per_key if isinstance(per_key, dict) else None)  # per-level mappings
        if node is None:
            return None
    return node


def schema_default(key):
    """The ``default`` a config key's schema declares (the value a file that omits it has), or None."""
    node = key_node(key)
    return None if node is None else node.get("default")


_UNIT = re.compile(r"^(?P<doc>.*?)\s*\[(?P<unit>[^\]]+)\](?P<rest>.*)$")


def config_key(path, shape, table=None, field=None, scale=1.0, *, key=None, note="", special=""):
    """A config key's row: unit and meaning from its schema description, range from its number node."""
    key = key or path
    node = key_node(key)
    if node is None:
        raise KeyError(f"{key}: no such config key (schema.py)")
    match = _UNIT.match(node["description"])
    if match is None:
        raise ValueError(f"{key}: its schema description names no [unit]")
    doc = match["doc"] + (f" ({note})" if note else "")
    number = node.get("items", node)
    if "exclusiveMinimum" in number:
        lower, inclusive = float(number["exclusiveMinimum"]), False
    else:
        lower, inclusive = float(number.get("minimum", -math.inf)), True
    upper = float(number.get("maximum", math.inf))
    unit = match["unit"]
    return Parameter(path, unit, doc, shape, lower, upper, inclusive, table, field, scale, key, None, special)


def dispersion_only(path, unit, doc, shape, table=None, field=None, *, lower=-math.inf, nominal=None, special=""):
    """A path that is no config key: it declares its unit, meaning, range and nominal here."""
    return Parameter(path, unit, doc, shape, lower, math.inf, True, table, field, 1.0, None, nominal, special)


FLIGHT_SOFTWARE_KEEPS = "the flight software keeps the nominal"
TRANSLATION_KEEPS = "the truth; the translation law keeps the file's value (docs/cold-gas.md)"
ENTRY = "the true entry vehicle (campaign.entry_plan builds it)"
NOZZLE_CONSTANTS = "the nozzle's C_F and Gamma follow it (config.feed.nozzle_constants)"


def _table():
    p = [
        config_key(
            "mass_kg",
            SCALAR,
            "vehicle",
            "mass_kg",
            note="trajectory drag; trajectory local: the thrust's acceleration, the translation law keeps the file's",
        ),
        config_key(
            "inertia_kg_m2",
            INERTIA,
            note=f"dist: inertia only; {FLIGHT_SOFTWARE_KEEPS}",
            special="six components of a symmetric tensor (a dispersion that keeps it physical)",
        ),
        config_key("com_offset_m", VECTOR, "vehicle", "com_offset_m"),
        config_key("aerodynamics.mistrim_cm", VECTOR, "vehicle", "aero_mistrim_cm"),
        config_key("aerodynamics.drag_area_m2", SCALAR, "vehicle", "drag_area_m2"),
    ]
    for level in schema.REFEX_LEVEL_NAMES:  # every other level name takes their unit and range (parameter())
        p.append(
            config_key(
                f"rcs.thrust_n.{level}",
                SCALAR,
                note=f"{level} level, all thrusters",
                special="a row of the levels table; a regulated feed's set pressure follows the thrust",
            )
        )
    p += [
        dispersion_only(
            "rcs.thrust_scale",
            "-",
            "thrust factor per thruster (nominal 1)",
            THRUSTER,
            "thrusters",
            "thrust_scale",
            lower=0.0,
            nominal=1.0,
        ),
        config_key("rcs.derating", DERATING, special="padded to layout.DERATING_MAX_VALVES with its last entry"),
        config_key(
            "rcs.isp_s", SCALAR, "vehicle", "isp_s", special="a blow-down or regulated feed packs its own (002 eq. 1)"
        ),
        config_key(
            "rcs.propellant_kg",
            SCALAR,
            "vehicle",
            "propellant_kg",
            special="a blow-down or regulated feed packs its gas (002 eq. 15)",
        ),
        config_key("main_engine.thrust_n", SCALAR, "vehicle", "engine_thrust_n", note="orbit trajectory"),
        config_key(
            "main_engine.misalignment_deg",
            VECTOR,
            note=FLIGHT_SOFTWARE_KEEPS,
            special="rotates the nominal engine axis into the true force direction",
        ),
    ]
    for level in schema.REFEX_LEVEL_NAMES:
        for name in L.TIME_CONSTANT_NAMES:
            p.append(
                config_key(
                    f"rcs.valve_time_constants_ms.{level}.{name}",
                    THRUSTER,
                    note=f"at {level} thrust, per thruster, independent draws",
                    special="a column of the thruster table per level (layout.time_constant_column)",
                )
            )
    p += [
        config_key("initial_state.altitude_m", SCALAR, "mission", "initial_altitude_m"),
        config_key("initial_state.speed_m_s", SCALAR, "mission", "initial_speed_m_s"),
        config_key("initial_state.flight_path_angle_deg", SCALAR, "mission", "initial_flight_path_angle_rad", DEG),
        config_key("initial_state.rates_deg_s", VECTOR, "mission", "initial_rates_rad_s", DEG),
        config_key(
            "initial_state.attitude_rotvec_deg",
            ATTITUDE,
            "mission",
            "initial_attitude_rotvec_rad",
            DEG,
            note="dist uniform_so3: any attitude",
            special="a mission may give it as Euler angles: their rotation vector is the nominal",
        ),
        config_key("navigation.attitude_bias_deg", VECTOR, "nav", "attitude_bias_rad", DEG),
        config_key("navigation.attitude_noise_deg", SCALAR, "nav", "attitude_noise_rad", DEG),
        config_key("navigation.rate_bias_deg_s", VECTOR, "nav", "rate_bias_rad_s", DEG),
        config_key("navigation.rate_noise_deg_s", SCALAR, "nav", "rate_noise_rad_s", DEG),
        config_key("navigation.ssm_calibration_time_s", SCALAR, "nav", "ssm_calibration_time_s"),
        config_key("navigation.gps_position_bias_m", VECTOR, "nav", "gps_position_bias_m"),
        config_key("navigation.gps_position_noise_m", SCALAR, "nav", "gps_position_noise_m"),
        config_key("navigation.gps_velocity_bias_m_s", VECTOR, "nav", "gps_velocity_bias_m_s"),
        config_key("navigation.gps_velocity_noise_m_s", SCALAR, "nav", "gps_velocity_noise_m_s"),
        config_key("navigation.local_position_noise_m", SCALAR, "nav", "local_position_noise_m"),
        config_key("navigation.local_velocity_noise_m_s", SCALAR, "nav", "local_velocity_noise_m_s"),
        config_key("navigation.tank_pressure_noise_pa", SCALAR, "nav", "tank_pressure_noise_pa"),
        config_key("navigation.attitude_gm_sigma_deg", SCALAR, "nav", "attitude_gm_sigma_rad", DEG),
        config_key("navigation.attitude_gm_tau_s", SCALAR, "nav", "attitude_gm_tau_s"),
        config_key("navigation.rate_gm_sigma_deg_s", SCALAR, "nav", "rate_gm_sigma_rad_s", DEG),
        config_key("navigation.rate_gm_tau_s", SCALAR, "nav", "rate_gm_tau_s"),
        dispersion_only(
            "atmosphere.density_scale",
            "-",
            "factor on every density of the atmosphere table",
            SCALAR,
            lower=0.0,
            nominal=1.0,
            special="scales the density column of the nominal atmosphere table",
        ),
        config_key(
            "wheels.friction.coulomb_n_m", SCALAR, "wheels", "coulomb_friction_n_m", note="every wheel the same"
        ),
        config_key(
            "wheels.friction.viscous_n_m_s", SCALAR, "wheels", "viscous_friction_n_m_s", note="every wheel the same"
        ),
        config_key(
            "wheels.initial_momentum_n_m_s",
            WHEEL,
            "wheels",
            "initial_momentum_n_m_s",
            key="wheels.units[].initial_momentum_n_m_s",
            note="per wheel, independent draws; the flight software is not told",
        ),
        # every number of a blow-down or regulated feed (rcs.feed, core.feed: the tank's gas and
        # tau follow from them at t = 0); the model itself is a choice of kernel, not a number
        config_key("rcs.feed.tank_volume_m3", SCALAR, "vehicle", "feed_tank_volume_m3", note=TRANSLATION_KEEPS),
        config_key(
            "rcs.feed.gas_constant_j_kg_k", SCALAR, "vehicle", "feed_gas_constant_j_kg_k", note=TRANSLATION_KEEPS
        ),
        config_key(
            "rcs.feed.heat_capacity_ratio",
            SCALAR,
            "vehicle",
            "feed_heat_capacity_ratio",
            note=TRANSLATION_KEEPS,
            special=NOZZLE_CONSTANTS,
        ),
        config_key(
            "rcs.feed.initial_pressure_pa", SCALAR, "vehicle", "feed_initial_pressure_pa", note=TRANSLATION_KEEPS
        ),
        config_key("rcs.feed.temperature_k", SCALAR, "vehicle", "feed_temperature_k", note=TRANSLATION_KEEPS),
        config_key("rcs.feed.throat_area_m2", SCALAR, "vehicle", "feed_throat_area_m2", note=TRANSLATION_KEEPS),
        config_key(
            "rcs.feed.expansion_ratio",
            SCALAR,
            "vehicle",
            "feed_expansion_ratio",
            note=TRANSLATION_KEEPS,
            special=NOZZLE_CONSTANTS,
        ),
        config_key(
            "rcs.feed.ambient_pressure_pa", SCALAR, "vehicle", "feed_ambient_pressure_pa", note=TRANSLATION_KEEPS
        ),
        config_key("local.position_m", VECTOR, "mission", "local_position_m", note="trajectory local"),
        config_key("local.velocity_m_s", VECTOR, "mission", "local_velocity_m_s", note="trajectory local"),
    ]
    # an entry mission (issue 24, 003): its state, the blocked flap, the true air and coefficients
    # (the flight software keeps the nominal ones)
    for name in ENTRY_STATE_KEYS:
        p.append(config_key(f"entry_flight.state.{name}", SCALAR, note="entry state at t = 0", special=ENTRY))
    p += [
        config_key(
            "entry_flight.blocked_flap.deflection_deg", SCALAR, note="deflection of the blocked flap", special=ENTRY
        ),
        dispersion_only(
            "entry_flight.density_scale",
            "-",
            "factor on the true density (entry mission)",
            SCALAR,
            lower=0.0,
            nominal=1.0,
            special=ENTRY,
        ),
    ]
    for name in ENTRY_SCALED_COEFFICIENTS:
        p.append(
            dispersion_only(
                f"entry_flight.coefficient_scale.{name}",
                "-",
                f"factor on the true {name} table (entry mission)",
                SCALAR,
                lower=0.0,
                nominal=1.0,
                special=ENTRY,
            )
        )
    p.append(config_key("entry_flight.rcs_delay_ms", SCALAR, special=ENTRY))
    return {param.path: param for param in p}


ENTRY_STATE_KEYS = (
    "altitude_m",
    "longitude_deg",
    "latitude_deg",
    "speed_m_s",
    "flight_path_angle_deg",
    "heading_deg",
    "alpha_deg",
    "bank_deg",
)
ENTRY_SCALED_COEFFICIENTS = (  # vehicle-file coefficient names (config.entry.coefficient_slots)
    "lift",
    "drag",
    "pitch",
    "pitch_per_elevon_rad",
    "roll_per_aileron_rad",
    "yaw_per_aileron_rad",
    "roll_per_rudder_rad",
    "yaw_per_rudder_rad",
)

PARAMETERS = _table()
_PER_LEVEL = re.compile(r"^rcs\.(thrust_n|valve_time_constants_ms)\.([A-Za-z][A-Za-z0-9_]*)(\..+)?$")


def parameter(path):
    """The Parameter of a path, or None. Per-level paths exist for every level name: those of the
    table name ReFEx's ``low`` and ``high``; ``rcs.thrust_n.<level>`` and
    ``rcs.valve_time_constants_ms.<level>.<name>`` of any other level take the same unit and range."""
    if path in PARAMETERS:
        return PARAMETERS[path]
    match = _PER_LEVEL.match(path)
    if match is None:
        return None
    template_level = schema.REFEX_LEVEL_NAMES[0]
    template = PARAMETERS.get(f"rcs.{match.group(1)}.{template_level}{match.group(3) or ''}")
    if template is None:
        return None
    level = match.group(2)
    return template._replace(path=path, key=path, doc=template.doc.replace(f"{template_level} ", f"{level} "))


def landing_in(table):
    """The parameters that land in one field of ``table`` (a RunInputs table name) by the generic rule."""
    return [param for param in PARAMETERS.values() if param.table == table]


def put(array, param, values):
    """Write ``values`` (user units, one per component) of ``param`` into its field of ``array``
    (the table it lands in; a thruster or wheel table: every row, per-row values by column)."""
    put_rows(array[np.newaxis], param, np.asarray(values, dtype=float)[np.newaxis])


def put_rows(stack, param, rows):
    """:func:`put` of each run: ``rows[k]`` (user units) into the table ``stack[k]`` (a stack of
    the table ``param`` lands in, one per run; the same operations on each as alone)."""
    fields = TABLES[param.table]
    offset, count = fields.slices[param.field]
    values = (np.asarray(rows, dtype=float) * param.scale).reshape(len(stack), -1)
    if stack.ndim == 3:  # one row per thruster or wheel: a single field, one value per row (or all the same)
        assert count == 1, (param.field, count)
        stack[:, :, offset] = values
        return
    assert values.shape[1] == count, (param.field, values.shape[1], count)
    stack[:, offset : offset + count] = values


def file_of(param, vehicle, mission):
    """The file ``param``'s key belongs to: the mission's or the vehicle's."""
    return mission if param.path.split(".")[0] in MISSION_ROOTS else vehicle


def declared(param, root):
    """The value the file ``root`` gives ``param``'s key (KeyError: it does not); a ``[]`` key:
    a list of one value per item, an item without the key its schema default."""
    node = root
    parts = param.key.split(".")
    for depth, part in enumerate(parts):
        if part.endswith("[]"):
            default = schema_default(param.key)
            return [_item(item, parts[depth + 1 :], default) for item in node[part[:-2]]]
        node = node[part]
    return node


def _item(node, parts, default):
    for part in parts:
        if part not in node:
            return default
        node = node[part]
    return node


def configured(param, root):
    """The value packed for ``param`` from the file ``root``: the file's value, its key's schema
    default where the file omits it, a dispersion-only path's nominal; None where there is none
    (a part the vehicle or mission does not have: no aerodynamics, no main engine, no local
    trajectory, no initial altitude without a trajectory)."""
    if param.key is None:
        return param.nominal
    try:
        return declared(param, root)
    except KeyError:
        return schema_default(param.key)


def pack_nominal(array, table, root):
    """Write every parameter that lands in ``table`` by the generic rule, from the file ``root``
    (the vehicle or mission dict), into ``array``; a parameter the file does not have leaves
    its field as it is (zero in a fresh table). Special ones are the packer's own."""
    for param in landing_in(table):
        if param.special:
            continue
        value = configured(param, root)
        if value is not None:
            put(array, param, value)
