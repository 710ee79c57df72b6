"""Dispersible parameters: every input of the run function a campaign may vary, by path.

A path names a quantity in the user's units, mostly the key path of the vehicle or mission
file (``separation.rates_deg_s``); a few paths exist only as dispersions (``rcs.thrust_scale``,
``atmosphere.density_scale``). Each is declared once here with its unit, its physical range,
how many components it has, its nominal value and where it goes in the packed run inputs.
Distributions are declared in ``DISTRIBUTIONS`` and checked against the path they are applied
to; ``refexmc.campaign.sampling`` draws them.
"""

import difflib
import math
import re
import statistics
from typing import NamedTuple

import numpy as np

from refexmc import crmath
from refexmc.config import derived, schema
from refexmc.config.errors import ConfigError
from refexmc.core import layout as L

AXES = ("x", "y", "z")
_MISSION_ROOTS = ("separation", "navigation", "local", "entry_flight")  # paths of the mission file (else the vehicle's)
INERTIA_COMPONENTS = ("xx", "yy", "zz", "xy", "xz", "yz")
INERTIA_INDEX = ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2))
INERTIA_ROWS, INERTIA_COLUMNS = (list(index) for index in zip(*INERTIA_INDEX, strict=True))


class Parameter(NamedTuple):
    path: str
    unit: str
    doc: str
    shape: str  # scalar | vector | thruster | wheel | derating | inertia | attitude
    lower: float = -math.inf  # physical range of every component (config keys: from the schema)
    upper: float = math.inf
    lower_inclusive: bool = True


def _params():
    p = [
        Parameter("mass_kg", "kg", "vehicle mass (trajectory drag only)", "scalar"),
        Parameter(
            "inertia_kg_m2",
            "kg m^2",
            "inertia tensor about the actual CoM (dist: inertia only; the flight software keeps the nominal)",
            "inertia",
        ),
        Parameter("com_offset_m", "m", "actual minus nominal centre of mass, body axes", "vector"),
        Parameter("aerodynamics.mistrim_cm", "-", "aerodynamic moment coefficient per body axis", "vector"),
        Parameter("aerodynamics.drag_area_m2", "m^2", "C_D S of the trajectory", "scalar"),
        Parameter("rcs.thrust_n.low", "N", "low thrust level, all thrusters", "scalar"),
        Parameter("rcs.thrust_n.high", "N", "high thrust level, all thrusters", "scalar"),
        Parameter("rcs.thrust_scale", "-", "thrust factor per thruster (nominal 1)", "thruster", 0.0),
        Parameter("rcs.derating", "-", "thrust factor with 1, 2, ... valves open", "derating"),
        Parameter("rcs.isp_s", "s", "specific impulse", "scalar"),
        Parameter("rcs.propellant_kg", "kg", "propellant at separation", "scalar"),
        Parameter("main_engine.thrust_n", "N", "main-engine thrust (orbit trajectory)", "scalar"),
        Parameter(
            "main_engine.misalignment_deg",
            "deg",
            "main-engine force direction: rotation vector from the nominal (the flight software keeps the nominal)",
            "vector",
        ),
    ]
    for level in ("low", "high"):
        for name in L.TIME_CONSTANT_NAMES:
            p.append(
                Parameter(
                    f"rcs.valve_time_constants_ms.{level}.{name}",
                    "ms",
                    f"valve {name.replace('_', ' ')} at {level} thrust, per thruster, independent draws",
                    "thruster",
                )
            )
    p += [
        Parameter("separation.altitude_m", "m", "altitude at separation", "scalar"),
        Parameter("separation.speed_m_s", "m/s", "speed at separation", "scalar"),
        Parameter("separation.flight_path_angle_deg", "deg", "flight-path angle at separation", "scalar"),
        Parameter("separation.rates_deg_s", "deg/s", "body rates at separation", "vector"),
        Parameter(
            "separation.attitude_error_deg",
            "deg",
            "rotation vector from 'body x along velocity, wings level' (dist uniform_so3: any attitude)",
            "attitude",
        ),
        Parameter("navigation.attitude_bias_deg", "deg", "attitude measurement bias (rotation vector)", "vector"),
        Parameter("navigation.attitude_noise_deg", "deg", "attitude white noise, 1 sigma per axis", "scalar"),
        Parameter("navigation.rate_bias_deg_s", "deg/s", "rate measurement bias", "vector"),
        Parameter("navigation.rate_noise_deg_s", "deg/s", "rate white noise, 1 sigma per axis", "scalar"),
        Parameter(
            "navigation.ssm_calibration_time_s", "s", "attitude-bias decay time constant in calibrating modes", "scalar"
        ),
        Parameter("navigation.gps_position_bias_m", "m", "GPS position bias, ECI axes", "vector"),
        Parameter("navigation.gps_position_noise_m", "m", "GPS position white noise, 1 sigma per axis", "scalar"),
        Parameter("navigation.gps_velocity_bias_m_s", "m/s", "GPS velocity bias, ECI axes", "vector"),
        Parameter("navigation.gps_velocity_noise_m_s", "m/s", "GPS velocity white noise, 1 sigma per axis", "scalar"),
        Parameter(
            "navigation.local_position_noise_m",
            "m",
            "local trajectory: position white noise, 1 sigma per axis",
            "scalar",
        ),
        Parameter(
            "navigation.local_velocity_noise_m_s",
            "m/s",
            "local trajectory: velocity white noise, 1 sigma per axis",
            "scalar",
        ),
        Parameter(
            "navigation.tank_pressure_noise_pa", "Pa", "translation law's tank-pressure white noise, 1 sigma", "scalar"
        ),
        Parameter("atmosphere.density_scale", "-", "factor on every density of the atmosphere table", "scalar", 0.0),
        Parameter("wheels.friction.coulomb_n_m", "N m", "Coulomb friction tau_e, every wheel the same value", "scalar"),
        Parameter(
            "wheels.friction.viscous_n_m_s", "N m s/rad", "viscous friction tau_v, every wheel the same value", "scalar"
        ),
        Parameter(
            "wheels.initial_momentum_n_m_s",
            "N m s",
            "wheel momentum I_w Omega at t = 0, per wheel, independent draws (the flight software is not told)",
            "wheel",
        ),
        Parameter("rcs.feed.initial_pressure_pa", "Pa", "tank pressure at t = 0 (blow-down, regulated)", "scalar"),
        Parameter("rcs.feed.temperature_k", "K", "tank and gas temperature (blow-down, regulated)", "scalar"),
        Parameter("rcs.feed.throat_area_m2", "m^2", "nozzle throat area, every thruster (times its scale)", "scalar"),
        Parameter("local.position_m", "m", "position at t = 0 (trajectory local)", "vector"),
        Parameter("local.velocity_m_s", "m/s", "velocity at t = 0 (trajectory local)", "vector"),
    ]
    # an entry mission (issue 24, 003): its state, the blocked flap, the true air and coefficients
    # (the flight software keeps the nominal ones)
    for key, unit in ENTRY_STATE_KEYS.items():
        p.append(Parameter(f"entry_flight.state.{key}", unit, f"entry state at t = 0: {key}", "scalar"))
    p += [
        Parameter("entry_flight.blocked_flap.deflection_deg", "deg", "where the blocked flap is", "scalar"),
        Parameter("entry_flight.density_scale", "-", "factor on the true density (entry mission)", "scalar", 0.0),
    ]
    for key in ENTRY_SCALED_COEFFICIENTS:
        p.append(
            Parameter(
                f"entry_flight.coefficient_scale.{key}",
                "-",
                f"factor on the true {key} table (entry mission)",
                "scalar",
                0.0,
            )
        )
    p.append(Parameter("entry_flight.rcs_delay_ms", "ms", "delay of the thrusters' moment (entry mission)", "scalar"))
    return {param.path: _with_schema_range(param) for param in p}


ENTRY_STATE_KEYS = {
    "altitude_m": "m",
    "longitude_deg": "deg",
    "latitude_deg": "deg",
    "speed_m_s": "m/s",
    "flight_path_angle_deg": "deg",
    "heading_deg": "deg",
    "alpha_deg": "deg",
    "bank_deg": "deg",
}
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
_ENTRY_ONLY = ("entry_flight.density_scale", "entry_flight.coefficient_scale.")  # dispersion-only paths, nominal 1


def _schema_node(path):
    """The schema of a vehicle or mission key path (vector items for arrays), or None."""
    root = path.split(".")[0]
    node = schema.VEHICLE
    if root == "entry_flight":
        node = schema.ENTRY_MISSION
    elif root in _MISSION_ROOTS:
        node = schema.MISSION
    for key in path.split("."):
        properties, per_key = node.get("properties", {}), node.get("additionalProperties")
        node = properties.get(key, per_key if isinstance(per_key, dict) else None)  # per-level mappings
        if node is None:
            return None
    return node.get("items", node) if node.get("type") == "array" else node


def _with_schema_range(param):
    """A config key's range is the one its schema declares (declared once, in schema.py)."""
    node = _schema_node(param.path)
    if node is None or node.get("type") != "number":
        return param
    if "exclusiveMinimum" in node:
        lower, inclusive = float(node["exclusiveMinimum"]), False
    else:
        lower, inclusive = float(node.get("minimum", -math.inf)), True
    return param._replace(lower=lower, upper=float(node.get("maximum", math.inf)), lower_inclusive=inclusive)


PARAMETERS = _params()
_PER_LEVEL = re.compile(r"^rcs\.(thrust_n|valve_time_constants_ms)\.([A-Za-z][A-Za-z0-9_]*)(\..+)?$")


def parameter(path):
    """The Parameter of a path, or None. Per-level paths exist for every level name: those of the
    registry name ReFEx's ``low`` and ``high``; ``rcs.thrust_n.<level>`` and
    ``rcs.valve_time_constants_ms.<level>.<name>`` of any other level take the same unit and range."""
    if path in PARAMETERS:
        return PARAMETERS[path]
    match = _PER_LEVEL.match(path)
    if match is None:
        return None
    template = PARAMETERS.get(f"rcs.{match.group(1)}.low{match.group(3) or ''}")
    if template is None:
        return None
    return template._replace(path=path, doc=template.doc.replace("low", match.group(2)))


# distribution -> (required parameters, optional parameters); parameters are numbers, or lists
# with one number per component of the path (a single number applies to every component)
DISTRIBUTIONS = {
    "constant": (("value",), ()),
    "normal": (("sigma",), ("mean",)),
    "truncnorm": (("sigma",), ("mean", "low", "high")),
    "uniform": (("low", "high"), ()),
    "lognormal": (("sigma",), ("median",)),
    "choice": (("values",), ("probabilities",)),
    "uniform_so3": ((), ()),
    "inertia": (("moments_sigma_fraction",), ("axes_sigma_deg",)),
}
DIST_DOC = {
    "constant": "value: the value",
    "normal": "mean (default: nominal), sigma >= 0",
    "truncnorm": "mean (default: nominal), sigma > 0, low and/or high bounds",
    "uniform": "low <= high, high - low finite",
    "lognormal": "median (default: nominal) > 0, sigma >= 0 of ln x",
    "choice": "values: numbers (each component independently) or vectors; probabilities (default equal)",
    "uniform_so3": "uniformly random rotation (Haar measure); separation.attitude_error_deg only",
    "inertia": "relative 1-sigma of the principal moments (< 0.5), principal-axis misalignment 1-sigma (<= 180 deg); "
    "draws that are not physical are redrawn",
}
# Uniforms are drawn inside [UNIFORM_EPS, 1 - UNIFORM_EPS], so a standard normal draw never
# exceeds Z_MAX (8.2) in size: the exact support of normal and lognormal draws, checked
# against each path's physical range.
UNIFORM_EPS = 2.0**-53
Z_MAX = -statistics.NormalDist().inv_cdf(UNIFORM_EPS) * (1.0 + 1e-12)  # 8.2095, rounded outward
MAX_AXES_SIGMA_DEG = 180.0  # inertia: a larger 1-sigma principal-axis misalignment means nothing
_SPECIAL = {"uniform_so3": "attitude", "inertia": "inertia"}


def components(path, vehicle):
    """Column suffixes of ``path``'s components (empty tuple: a scalar)."""
    shape = parameter(path).shape
    if shape in ("vector", "attitude"):
        return AXES
    if shape == "thruster":
        return tuple(str(i + 1) for i in range(len(vehicle["rcs"]["thrusters"])))
    if shape == "wheel":
        return tuple(str(i + 1) for i in range(len(vehicle["wheels"]["units"])))
    if shape == "derating":
        return tuple(str(i + 1) for i in range(len(vehicle["rcs"]["derating"])))
    if shape == "inertia":
        return INERTIA_COMPONENTS
    return ()


def size(path, vehicle):
    return max(1, len(components(path, vehicle)))


def uniforms_per_draw(spec, n_components):
    """Uniforms one draw of ``spec`` (a checked distribution) consumes (refexmc.campaign.sampling)."""
    dist = spec["dist"]
    if dist == "constant":
        return 0
    if dist == "choice":
        return n_components if spec["per_component"] else 1
    if dist == "uniform_so3":
        return 3
    if dist == "inertia":
        return 6
    return n_components


def set_failed(inputs, failed, detected=False):
    """Mark thrusters ``failed`` (1-based ids) failed and every other one working. ``detected``:
    the flight software knows them (failures.detected): they are marked known, which takes them
    out of the LP (``core.allocation.nominal_arms``), and their column of the allocation table is
    zero, so the table no longer commands them (``inputs.allocation`` must be the run's own copy)."""
    failed_column = L.THRUSTER.slices["failed"][0]
    known_column = L.THRUSTER.slices["failure_known"][0]
    inputs.thrusters[:, failed_column] = 0.0
    inputs.thrusters[:, known_column] = 0.0
    for tid in failed:
        inputs.thrusters[tid - 1, failed_column] = 1.0
        if detected:
            inputs.thrusters[tid - 1, known_column] = 1.0
            inputs.allocation[:, tid - 1] = 0


def columns(path, vehicle):
    """``p.<path>`` column names of the runs table."""
    comps = components(path, vehicle)
    return [f"p.{path}.{c}" for c in comps] if comps else [f"p.{path}"]


def nominal(path, vehicle, mission):
    """Nominal value of ``path`` in its user units, one entry per component (KeyError: the vehicle
    or mission does not have it). The separation attitude of a mission that gives it as Euler
    angles is their rotation vector."""
    if path == "inertia_kg_m2":
        j = np.asarray(vehicle["inertia_kg_m2"], dtype=float)
        return np.array([j[a, b] for a, b in INERTIA_INDEX])
    if path == "rcs.thrust_scale":
        return np.ones(len(vehicle["rcs"]["thrusters"]))
    if path == "atmosphere.density_scale":
        return np.ones(1)
    if path.startswith(_ENTRY_ONLY):
        if "entry_flight" not in mission:
            raise KeyError(path)
        return np.ones(1)
    if path.startswith("rcs.valve_time_constants_ms."):
        _, _, level, name = path.split(".")
        rcs = vehicle["rcs"]
        return np.full(len(rcs["thrusters"]), float(rcs["valve_time_constants_ms"][level][name]))
    if path == "wheels.initial_momentum_n_m_s":
        return np.array([float(unit.get("initial_momentum_n_m_s", 0.0)) for unit in vehicle["wheels"]["units"]])
    if path == "separation.attitude_error_deg" and "attitude_euler_deg" in mission["separation"]:
        return np.degrees(derived.separation_rotation_vector(mission["separation"]))
    root = mission if path.split(".")[0] in _MISSION_ROOTS else vehicle
    value = root
    for key in path.split("."):
        value = value[key]
    return np.atleast_1d(np.asarray(value, dtype=float)).copy()


def _declared_instead(path, root):
    """``"; rcs.thrust_n declares: nominal"``: the keys of the deepest node of ``path`` that the
    file has (a thrust level by another name), or '' when the first key is already missing."""
    node, keys = root, path.split(".")
    for depth, key in enumerate(keys):
        if not isinstance(node, dict) or key not in node:
            if depth == 0 or not isinstance(node, dict):
                return ""
            return f"; {'.'.join(keys[:depth])} declares: {', '.join(map(str, node))}"
        node = node[key]
    return ""


def _undeclared(path, vehicle, mission):
    """Why ``path`` cannot be dispersed for this vehicle and mission (a quantity they do not
    have: no trajectory, no aerodynamics, no atmosphere), or None."""
    trajectory = vehicle.get("trajectory", "planar_drag")
    if path.startswith("atmosphere.") and "atmosphere" not in mission:
        return f"'{path}' needs an atmosphere; the mission has none"
    entry = "entry_flight" in mission  # an entry mission flies the mass through 003 eq. 3
    if path.startswith("entry_flight.coefficient_scale."):
        key = path.rsplit(".", 1)[1]
        if key not in vehicle.get("entry_aerodynamics", {}).get("coefficients", {}):
            return f"'{path}': vehicle {vehicle['name']} has no '{key}' table (entry_aerodynamics.coefficients)"
    if entry and path not in ("mass_kg", "inertia_kg_m2") and not path.startswith("entry_flight."):
        return f"'{path}' is not flown by an entry mission; its paths: mass_kg, inertia_kg_m2, entry_flight.*"
    if (
        path in ("mass_kg", "aerodynamics.drag_area_m2", "aerodynamics.mistrim_cm")
        and trajectory == "none"
        and not entry
    ):
        return f"'{path}' acts through the trajectory; vehicle {vehicle['name']} has none (trajectory: none)"
    feed_model = vehicle.get("rcs", {}).get("feed", {}).get("model", "constant")
    if path.startswith("rcs.thrust_n.") and feed_model == "blow_down":
        return f"'{path}': vehicle {vehicle['name']} has a blow-down tank: its pressure gives the thrust"
    if path.startswith("rcs.") and "rcs" in vehicle and derived.flies_wheels(vehicle):
        return f"'{path}': vehicle {vehicle['name']} flies reaction wheels (actuation wheels); its thrusters never fire"
    try:
        nominal(path, vehicle, mission)
    except KeyError:
        part = "mission" if path.split(".")[0] in _MISSION_ROOTS else "vehicle"
        return f"'{path}': the {part} file does not declare it" + _declared_instead(
            path, mission if part == "mission" else vehicle
        )
    return None


def _put(array, fields, name, values):
    offset, count = fields.slices[name]
    values = np.asarray(values, dtype=float).ravel()
    assert values.size == count, (name, values.size, count)
    array[offset : offset + count] = values


def inertia_matrix(values):
    """3x3 tensor from the (xx, yy, zz, xy, xz, yz) components."""
    j = np.empty((3, 3))
    for v, (a, b) in zip(values, INERTIA_INDEX, strict=True):
        j[a, b] = j[b, a] = v
    return j


def inertia_tensors(rows):
    """n x 3 x 3 tensors from the rows (xx, yy, zz, xy, xz, yz) of an n x 6 array (:func:`inertia_matrix` of each)."""
    j = np.empty((len(rows), 3, 3))
    j[:, INERTIA_ROWS, INERTIA_COLUMNS] = rows
    j[:, INERTIA_COLUMNS, INERTIA_ROWS] = rows
    return j


_VEHICLE_SCALARS = {
    "mass_kg": ("mass_kg", 1.0),
    "aerodynamics.drag_area_m2": ("drag_area_m2", 1.0),
    "rcs.isp_s": ("isp_s", 1.0),
    "rcs.propellant_kg": ("propellant_kg", 1.0),
    "com_offset_m": ("com_offset_m", 1.0),
    "aerodynamics.mistrim_cm": ("aero_mistrim_cm", 1.0),
    "main_engine.thrust_n": ("engine_thrust_n", 1.0),
    "rcs.feed.initial_pressure_pa": ("feed_initial_pressure_pa", 1.0),
    "rcs.feed.temperature_k": ("feed_temperature_k", 1.0),
    "rcs.feed.throat_area_m2": ("feed_throat_area_m2", 1.0),
}
_MISSION_FIELDS = {
    "separation.altitude_m": ("separation_altitude_m", 1.0),
    "separation.speed_m_s": ("separation_speed_m_s", 1.0),
    "separation.flight_path_angle_deg": ("separation_flight_path_angle_rad", math.pi / 180.0),
    "separation.rates_deg_s": ("separation_rates_rad_s", math.pi / 180.0),
    "separation.attitude_error_deg": ("separation_attitude_rotvec_rad", math.pi / 180.0),
    "local.position_m": ("local_position_m", 1.0),
    "local.velocity_m_s": ("local_velocity_m_s", 1.0),
}
_NAV_FIELDS = {
    "navigation.attitude_bias_deg": ("attitude_bias_rad", math.pi / 180.0),
    "navigation.attitude_noise_deg": ("attitude_noise_rad", math.pi / 180.0),
    "navigation.rate_bias_deg_s": ("rate_bias_rad_s", math.pi / 180.0),
    "navigation.rate_noise_deg_s": ("rate_noise_rad_s", math.pi / 180.0),
    "navigation.ssm_calibration_time_s": ("ssm_calibration_time_s", 1.0),
    "navigation.gps_position_bias_m": ("gps_position_bias_m", 1.0),
    "navigation.gps_position_noise_m": ("gps_position_noise_m", 1.0),
    "navigation.gps_velocity_bias_m_s": ("gps_velocity_bias_m_s", 1.0),
    "navigation.gps_velocity_noise_m_s": ("gps_velocity_noise_m_s", 1.0),
    "navigation.local_position_noise_m": ("local_position_noise_m", 1.0),
    "navigation.local_velocity_noise_m_s": ("local_velocity_noise_m_s", 1.0),
    "navigation.tank_pressure_noise_pa": ("tank_pressure_noise_pa", 1.0),
}

_WHEEL_COLUMNS = {  # every wheel the same value (scalar paths) or one value per wheel
    "wheels.friction.coulomb_n_m": "coulomb_friction_n_m",
    "wheels.friction.viscous_n_m_s": "viscous_friction_n_m_s",
    "wheels.initial_momentum_n_m_s": "initial_momentum_n_m_s",
}


def apply(inputs, path, values, nominal_atmosphere, levels=("low", "high")):
    """Write ``values`` (user units) of ``path`` into the run's own copies of the input arrays;
    ``levels``: the vehicle's thrust-level names, in order (``derived.level_names``)."""
    values = np.asarray(values, dtype=float)
    if path.startswith("rcs.thrust_n."):
        row = inputs.levels[list(levels).index(path.split(".")[2])]
        # a regulated feed delivers the level's thrust through its set pressure (config.feed.set_pressure)
        row[L.LV_REGULATOR_PRESSURE] *= values[0] / row[L.LV_THRUST]
        row[L.LV_THRUST] = values[0]
    elif path in _VEHICLE_SCALARS:
        field, scale = _VEHICLE_SCALARS[path]
        _put(inputs.vehicle, L.VEHICLE, field, values * scale)
    elif path in _MISSION_FIELDS:
        field, scale = _MISSION_FIELDS[path]
        _put(inputs.mission, L.MISSION, field, values * scale)
    elif path in _NAV_FIELDS:
        field, scale = _NAV_FIELDS[path]
        _put(inputs.nav, L.NAV, field, values * scale)
    elif path == "main_engine.misalignment_deg":
        nominal_axis = inputs.fsw[L.F_ENGINE_AXIS : L.F_ENGINE_AXIS + 3]
        _put(inputs.vehicle, L.VEHICLE, "engine_direction", derived.rotate_by_rotation_vector(nominal_axis, values))
    elif path == "inertia_kg_m2":
        _put(inputs.vehicle, L.VEHICLE, "inertia_kg_m2", inertia_matrix(values))
    elif path == "rcs.derating":
        padded = list(values) + [values[-1]] * (L.DERATING_MAX_VALVES - len(values))
        _put(inputs.vehicle, L.VEHICLE, "derating", padded)
    elif path == "rcs.thrust_scale":
        inputs.thrusters[:, L.THRUSTER.slices["thrust_scale"][0]] = values
    elif path.startswith("rcs.valve_time_constants_ms."):
        _, _, level, name = path.split(".")
        column = L.time_constant_column(list(levels).index(level), L.TIME_CONSTANT_NAMES.index(name))
        inputs.thrusters[:, column] = values / 1e3
    elif path == "atmosphere.density_scale":
        inputs.atmosphere[:, 1] = nominal_atmosphere[:, 1] * values[0]
    elif path in _WHEEL_COLUMNS:
        inputs.wheels[:, L.WHEEL.slices[_WHEEL_COLUMNS[path]][0]] = values
    else:  # pragma: no cover - PARAMETERS and apply() are kept in step by tests
        raise KeyError(path)


# --- validation of a campaign's ``dispersions`` mapping ----------------------------------------


def in_range(param, value):
    """Whether ``value`` lies in the physical range of ``param``: finite, and within its bounds."""
    if not math.isfinite(value) or value > param.upper:
        return False
    return value >= param.lower if param.lower_inclusive else value > param.lower


def range_text(param):
    """The physical range of ``param`` in words, e.g. 'finite and > 0'."""
    low = "" if param.lower == -math.inf else f"{'>=' if param.lower_inclusive else '>'} {param.lower:g}"
    if param.upper != math.inf:
        return f"{low} and <= {param.upper:g}" if low else f"<= {param.upper:g}"
    return f"{low} and finite" if low else "any finite value"


def _normal_cdf(z):
    return 0.5 * math.erfc(-z / math.sqrt(2.0))


def _lowest_draw_below(bound_z):
    """Lowest standard draw of a normal truncated to (-inf, bound_z] that uniforms >= UNIFORM_EPS
    reach: the inverse CDF at UNIFORM_EPS * Phi(bound_z), rounded outward; -inf where the
    sampler's arithmetic underflows (a bound some 38 sigma on the far side of the mean)."""
    p = UNIFORM_EPS * _normal_cdf(bound_z)
    if p < 1e-300:
        return -math.inf
    return statistics.NormalDist().inv_cdf(p) * (1.0 + 1e-12)


def truncnorm_support(mean, sigma, low, high):
    """(lowest, highest) truncnorm draw per component: a given bound, or for a missing one
    (+-inf) the exact extreme of the draws (Z_MAX-like, beyond 8.2 sigma when the other bound
    cuts the distribution short)."""
    lowest = [
        lo if math.isfinite(lo) else m + s * _lowest_draw_below((hi - m) / s)
        for m, s, lo, hi in zip(mean, sigma, low, high, strict=True)
    ]
    highest = [
        hi if math.isfinite(hi) else m - s * _lowest_draw_below((m - lo) / s)
        for m, s, lo, hi in zip(mean, sigma, low, high, strict=True)
    ]
    return np.array(lowest), np.array(highest)


@np.errstate(over="ignore")  # an overflowing support is inf, which the range check refuses
def check(dispersions, vehicle, mission, file, lines):
    """Validate every dispersion; return {path: spec with parameters broadcast to arrays}."""
    out = {}
    for path, spec in dispersions.items():
        where = ("dispersions", path)

        def fail(message, *sub, _where=where):
            key = _where + sub
            line = lines.get(key) or lines.get(_where) or lines.get(("dispersions",))
            raise ConfigError(message, file=file, line=line, path=key)

        if parameter(path) is None:
            guess = difflib.get_close_matches(str(path), list(PARAMETERS), n=1, cutoff=0.5)
            hint = f"; did you mean '{guess[0]}'?" if guess else "; see docs/campaigns.md for the dispersible paths"
            fail(f"unknown parameter path '{path}'{hint}")
        param = parameter(path)
        missing = _undeclared(path, vehicle, mission)
        if missing:
            fail(missing)
        if not isinstance(spec, dict):
            fail(f"expected a mapping with 'dist' and its parameters, got {spec!r}")
        if "dist" not in spec:
            fail("'dist' is required (one of: " + ", ".join(DISTRIBUTIONS) + ")")
        dist = spec["dist"]
        if dist not in DISTRIBUTIONS:
            guess = difflib.get_close_matches(str(dist), list(DISTRIBUTIONS), n=1)
            hint = f"; did you mean '{guess[0]}'?" if guess else ""
            fail(f"unknown distribution {dist!r}{hint}; expected one of: {', '.join(DISTRIBUTIONS)}", "dist")
        required, optional = DISTRIBUTIONS[dist]
        allowed = ("dist", *required, *optional)
        for key in spec:
            if key not in allowed:
                guess = difflib.get_close_matches(str(key), allowed, n=1)
                hint = f"; did you mean '{guess[0]}'?" if guess else f"; {dist} takes: {', '.join(allowed[1:])}"
                fail(f"unknown key '{key}' for dist {dist}{hint}", key)
        for key in required:
            if key not in spec:
                fail(f"dist {dist} needs '{key}' ({DIST_DOC[dist]})")
        if _SPECIAL.get(dist, param.shape) != param.shape or (param.shape == "inertia" and dist != "inertia"):
            if param.shape == "inertia":
                fail("inertia_kg_m2 takes only dist: inertia (a dispersion that keeps the tensor physical)", "dist")
            fail(f"dist {dist} does not apply to {path}", "dist")
        n = size(path, vehicle)
        n_params = 3 if dist == "inertia" else n
        unit = f" [{param.unit}]"

        def vector(key, _n=n_params, _fail=fail, _spec=spec):
            value = _spec[key]
            if isinstance(value, bool) or not isinstance(value, (int, float, list)):
                _fail(f"expected a number or a list of {_n} numbers, got {value!r}", key)
            if isinstance(value, list):
                if len(value) != _n or any(isinstance(v, bool) or not isinstance(v, (int, float)) for v in value):
                    _fail(f"expected a number or a list of {_n} numbers (one per component), got {value!r}", key)
                array = np.asarray(value, dtype=float)
            else:
                array = np.full(_n, float(value))
            if not np.isfinite(array).all():
                _fail(f"expected finite numbers, got {value!r}", key)
            return array

        resolved = {"dist": dist}
        nominal_value = nominal(path, vehicle, mission)
        if dist == "constant":
            resolved["value"] = vector("value")
            support = (resolved["value"], resolved["value"])
        elif dist in ("normal", "truncnorm"):
            resolved["mean"] = vector("mean") if "mean" in spec else nominal_value.copy()
            resolved["sigma"] = sigma = vector("sigma")
            if (sigma < 0).any() or (dist == "truncnorm" and (sigma <= 0).any()):
                fail(f"expected sigma {'>' if dist == 'truncnorm' else '>='} 0{unit}, got {spec['sigma']!r}", "sigma")
            if dist == "normal":
                support = (resolved["mean"] - Z_MAX * sigma, resolved["mean"] + Z_MAX * sigma)
            else:
                if "low" not in spec and "high" not in spec:
                    fail("truncnorm needs 'low' and/or 'high' (else use normal)")
                resolved["low"] = low = vector("low") if "low" in spec else np.full(n, -np.inf)
                resolved["high"] = high = vector("high") if "high" in spec else np.full(n, np.inf)
                if (low >= high).any():
                    fail("expected low < high", "low")
                support = truncnorm_support(resolved["mean"], sigma, low, high)
        elif dist == "uniform":
            resolved["low"], resolved["high"] = vector("low"), vector("high")
            if (resolved["low"] > resolved["high"]).any():
                fail("expected low <= high", "low")
            if not np.isfinite(resolved["high"] - resolved["low"]).all():
                fail("expected high - low to be a finite number (draws are low + (high - low) u)", "high")
            # the sampler's own arithmetic at the extreme uniforms (it is monotone in u)
            width = resolved["high"] - resolved["low"]
            support = (resolved["low"] + width * UNIFORM_EPS, resolved["low"] + width * (1.0 - UNIFORM_EPS))
        elif dist == "lognormal":
            resolved["median"] = vector("median") if "median" in spec else nominal_value.copy()
            resolved["sigma"] = vector("sigma")
            if (resolved["median"] <= 0).any():
                fail("expected a median > 0 (lognormal draws are positive)", "median" if "median" in spec else "dist")
            if (resolved["sigma"] < 0).any():
                fail(f"expected sigma >= 0 (of ln x), got {spec['sigma']!r}", "sigma")
            spread = crmath.exp(Z_MAX * resolved["sigma"])  # the sampler's exp: the same bits on every CPU
            support = (resolved["median"] / spread, resolved["median"] * spread)
        elif dist == "choice":
            values = spec["values"]
            if not isinstance(values, list) or not values:
                fail("expected a non-empty list of values", "values")
            items = []
            for k, item in enumerate(values):
                if isinstance(item, list):
                    if len(item) != n or any(isinstance(v, bool) or not isinstance(v, (int, float)) for v in item):
                        fail(f"expected a number or a list of {n} numbers, got {item!r}", "values", k)
                    items.append(np.asarray(item, dtype=float))
                elif isinstance(item, (int, float)) and not isinstance(item, bool):
                    items.append(np.full(n, float(item)))
                else:
                    fail(f"expected a number or a list of {n} numbers, got {item!r}", "values", k)
                if not np.isfinite(items[-1]).all():
                    fail(f"expected finite numbers, got {item!r}", "values", k)
            resolved["values"] = np.array(items)
            resolved["per_component"] = not any(isinstance(item, list) for item in values)
            probabilities = spec.get("probabilities")
            if probabilities is None:
                resolved["probabilities"] = np.full(len(items), 1.0 / len(items))
            else:
                if (
                    not isinstance(probabilities, list)
                    or len(probabilities) != len(items)
                    or any(
                        isinstance(p, bool) or not isinstance(p, (int, float)) or not 0 <= p <= 1 for p in probabilities
                    )
                ):
                    fail(f"expected {len(items)} probabilities in [0, 1], one per value", "probabilities")
                if abs(sum(probabilities) - 1.0) > 1e-9:
                    fail(f"expected probabilities summing to 1, got {sum(probabilities):g}", "probabilities")
                resolved["probabilities"] = np.asarray(probabilities, dtype=float)
            support = (resolved["values"].min(axis=0), resolved["values"].max(axis=0))
        elif dist == "uniform_so3":
            support = None
        else:  # inertia
            resolved["moments_sigma_fraction"] = vector("moments_sigma_fraction")
            resolved["axes_sigma_deg"] = vector("axes_sigma_deg") if "axes_sigma_deg" in spec else np.zeros(3)
            if (resolved["moments_sigma_fraction"] < 0).any() or (resolved["moments_sigma_fraction"] >= 0.5).any():
                fail("expected 0 <= moments_sigma_fraction < 0.5", "moments_sigma_fraction")
            if (resolved["axes_sigma_deg"] < 0).any() or (resolved["axes_sigma_deg"] > MAX_AXES_SIGMA_DEG).any():
                fail(f"expected 0 <= axes_sigma_deg <= {MAX_AXES_SIGMA_DEG:g} [deg]", "axes_sigma_deg")
            support = None
        if support is not None:
            low, high = support
            for k in range(n):
                for bound in (low[k], high[k]):
                    if not in_range(param, bound):
                        comp = components(path, vehicle)
                        which = f" (component {comp[k]})" if comp else ""
                        hint = ""
                        if dist in ("normal", "lognormal"):
                            hint = f" (the {Z_MAX:.1f}-sigma extreme); use truncnorm with bounds or a smaller sigma"
                        elif dist == "truncnorm" and not math.isfinite(bound):
                            hint = "; give both bounds, or a bound nearer the mean"
                        unit_text = "" if param.unit == "-" else f" {param.unit}"
                        fail(
                            f"{dist} draws{which} reach {bound:g}{unit_text}, outside the physical range "
                            f"{range_text(param)}{hint}",
                            "dist",
                        )
        out[path] = resolved
    return out
