"""Read YAML files, validate them against the schema, and report bad input precisely."""

import difflib
import functools
import math
import re
import sys
from pathlib import Path
from typing import NamedTuple

import jsonschema
import numpy as np
import yaml

from refexmc import smallmatrix
from refexmc.config import (
    design_checks,
    entry,
    plausibility,
    pointing,
    published,
    renames,
    requirements,
    saltelli,
    schema,
)
from refexmc.config import feed as config_feed
from refexmc.config.derived import (
    allocation_table,
    inertia_problem,
    level_names,
    thruster_count,
    trajectory_model,
    translation_design,
    wheel_problem,
)
from refexmc.config.errors import ConfigError
from refexmc.config.failures import NO_FAILURES, THRUSTER_FAILURES, WHEEL_FAILURES, failure_sets


class _Loader(yaml.SafeLoader):
    """SafeLoader that also reads YAML 1.2 floats such as ``1e14`` (YAML 1.1 wants ``1.0e+14``)."""


_Loader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"^[-+]?(\d+\.?\d*|\.\d+)[eE][-+]?\d+$"),
    list("-+0123456789."),
)
_FLOAT_MAX = sys.float_info.max


_FLOAT_TAG = "tag:yaml.org,2002:float"
_INT_TAG = "tag:yaml.org,2002:int"
_MERGE_TAG = "tag:yaml.org,2002:merge"
_NON_FINITE_SPELLINGS = (".inf", "inf", ".nan", "nan")


def _scan(root, file):
    """Map every key path of a composed YAML document to its 1-based line, and refuse what the
    schema cannot see: a duplicate key (YAML keeps the last silently), a non-finite number
    (``.inf``, ``.nan`` in any spelling, ``1e999``), a recursive alias."""
    constructor = _Loader("")  # turns key and number nodes into values exactly as the load did
    lines = {}
    on_path = set()  # ids of the nodes being visited: an alias back to one of them is recursive

    def fail(message, node, path):
        raise ConfigError(message, file=file, line=node.start_mark.line + 1, path=path)

    def check_number(node, path):
        if node.tag not in (_FLOAT_TAG, _INT_TAG):
            return
        value = constructor.construct_object(node)
        if isinstance(value, int) and abs(value) <= _FLOAT_MAX:
            return
        if isinstance(value, float) and math.isfinite(value):
            return
        text = node.value if len(node.value) <= 24 else node.value[:20] + "..."
        if text.lstrip("+-").lower() not in _NON_FINITE_SPELLINGS:
            text += ", which overflows a float"
        fail(f"expected a finite number, got {text}", node, path)

    def visit(node, path):
        if id(node) in on_path:
            fail("a recursive YAML alias (a value that contains itself)", node, path)
        lines.setdefault(path, node.start_mark.line + 1)
        if isinstance(node, yaml.ScalarNode):
            check_number(node, path)
            return
        on_path.add(id(node))
        if isinstance(node, yaml.SequenceNode):
            for i, item in enumerate(node.value):
                visit(item, path + (i,))
        elif isinstance(node, yaml.MappingNode):
            merged = [value for key, value in node.value if key.tag == _MERGE_TAG]
            for value_node in merged:  # '<<: *anchor': the anchor's keys, which the keys here override
                for source in value_node.value if isinstance(value_node, yaml.SequenceNode) else [value_node]:
                    visit(source, path)
            first_line = {}
            for key_node, value_node in node.value:
                if key_node.tag == _MERGE_TAG:
                    continue
                if not isinstance(key_node, yaml.ScalarNode):
                    continue  # a list or mapping as a key: the construction refuses it (unhashable)
                check_number(key_node, path)
                key = constructor.construct_object(key_node, deep=True)
                line = key_node.start_mark.line + 1
                if key in first_line:
                    fail(
                        f"duplicate key '{key}' (first at line {first_line[key]}); a key may appear once",
                        key_node,
                        path + (key,),
                    )
                first_line[key] = line
                visit(value_node, path + (key,))
                lines[path + (key,)] = line
        on_path.discard(id(node))

    visit(root, ())
    return lines


def read_yaml(path):
    """Parse a YAML file into (data, line map); ConfigError on a missing file, bad syntax, a
    duplicate key or a non-finite number."""
    path = Path(path)
    try:
        text = path.read_text()
    except FileNotFoundError:
        raise ConfigError("file not found", file=path) from None
    except OSError as exc:
        raise ConfigError(f"cannot read file: {exc.strerror}", file=path) from None
    loader = _Loader(text)
    try:
        node = loader.get_single_node()
        lines = _scan(node, path) if node is not None else {}  # before construction, which flattens '<<'
        data = loader.construct_document(node) if node is not None else None
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        problem = getattr(exc, "problem", None) or str(exc)
        raise ConfigError(f"YAML syntax error: {problem}", file=path, line=mark.line + 1 if mark else None) from None
    finally:
        loader.dispose()
    return data, lines


def _describe(error):
    """One sentence for a jsonschema error, with did-you-mean for unknown keys."""
    if error.validator == "additionalProperties":
        allowed = list(error.schema.get("properties", {}))
        extra = [k for k in error.instance if k not in allowed]
        key = extra[0]
        guess = difflib.get_close_matches(str(key), allowed, n=1)
        hint = f"; did you mean '{guess[0]}'?" if guess else f"; expected one of: {', '.join(allowed)}"
        return (key,), f"unknown key '{key}'{hint}"
    if error.validator == "required":
        return (), error.message.replace("is a required property", "is required")
    if error.validator == "type":
        if (
            error.validator_value == "number"
            and isinstance(error.instance, int | float)
            and not isinstance(error.instance, bool)
        ):
            text = repr(error.instance)
            return (), f"expected a finite number, got {text if len(text) <= 24 else text[:20] + '...'}"
        return (), f"expected {error.validator_value}, got {error.instance!r}"
    if error.validator in ("minimum", "maximum", "exclusiveMinimum", "exclusiveMaximum"):
        words = {
            "minimum": ">=",
            "maximum": "<=",
            "exclusiveMinimum": ">",
            "exclusiveMaximum": "<",
        }[error.validator]
        return (), f"expected a value {words} {error.validator_value}, got {error.instance!r}"
    if error.validator == "enum":
        return (), f"expected one of {', '.join(map(str, error.validator_value))}, got {error.instance!r}"
    if error.validator in ("minItems", "maxItems"):
        return (
            (),
            f"expected {error.schema.get('minItems')}..{error.schema.get('maxItems')} items, got {len(error.instance)}",
        )
    return (), error.message


def _is_finite_number(checker, instance):
    """JSON Schema 'number', finite: every config number is a physical quantity (read_yaml refuses
    .inf and .nan with their line already; this keeps data that did not come from YAML honest)."""
    if not jsonschema.Draft202012Validator.TYPE_CHECKER.is_type(instance, "number"):
        return False
    return abs(instance) <= _FLOAT_MAX if isinstance(instance, int) else math.isfinite(instance)


_Validator = jsonschema.validators.extend(
    jsonschema.Draft202012Validator,
    type_checker=jsonschema.Draft202012Validator.TYPE_CHECKER.redefine("number", _is_finite_number),
)


def validate(data, schema_def, file, lines, prefix=()):
    """Raise ConfigError for the first (shallowest) schema violation."""
    if data is None:
        raise ConfigError("empty file", file=file)
    validator = _Validator(schema_def)
    # shallowest first; at equal depth an unknown key (with its did-you-mean) before a missing one
    errors = sorted(
        validator.iter_errors(data),
        key=lambda e: (len(e.absolute_path), e.validator != "additionalProperties", str(e.absolute_path)),
    )
    if errors:
        error = errors[0]
        extra, message = _describe(error)
        path = tuple(error.absolute_path) + extra
        line = lines.get(path) or lines.get(tuple(error.absolute_path)) or lines.get(())
        raise ConfigError(message, file=file, line=line, path=prefix + path)


def check_vehicle(vehicle, file, lines, prefix=(), warnings=None):
    """Checks the schema cannot express: an actuator for the actuation, the keys each actuator and
    controller take, thruster and wheel numbering, allocation ids, wheel axes, physical inertia;
    then the design checks (config.design_checks), whose warnings go to the list ``warnings``, after
    the plausibility checks' (config.plausibility)."""

    fail = _failing_at(file, lines, prefix)
    plausible = plausibility.check_vehicle(vehicle, fail)
    fsw = vehicle["flight_software"]
    if "rcs" not in vehicle and "wheels" not in vehicle:
        fail("expected an actuator: 'rcs', 'wheels' or both")
    hardware = schema.ACTUATION_HARDWARE[fsw["actuation"]]
    if hardware not in vehicle:
        fail(f"actuation {fsw['actuation']} needs the vehicle's '{hardware}'", "flight_software", "actuation")
    if "rcs" in vehicle:
        for key in schema.RCS_DESIGN_KEYS:
            if key not in fsw:
                fail(f"'{key}' is required with an rcs (the thruster design, 000)", "flight_software")
        _check_rcs(vehicle, fail)
        _check_feed(vehicle, fail, plausible)
    else:
        for key in (*schema.RCS_DESIGN_KEYS, "allocation"):
            if key in fsw:
                fail(f"'{key}' is a thruster design key; the vehicle has no rcs", "flight_software", key)
    if "wheels" in vehicle:
        _check_wheels(vehicle, fail)
    controller = fsw["controller"]
    if controller == "smc":
        if "smc" not in fsw:
            fail("controller smc needs its gains (flight_software.smc)", "flight_software", "controller")
        if "gains" in fsw:
            fail("controller smc takes no 'gains' (its gains are flight_software.smc)", "flight_software", "gains")
    elif "smc" in fsw:
        fail(f"'smc' is used by controller smc only; the controller is {controller}", "flight_software", "smc")
    elif fsw["actuation"] == "wheels" and "gains" not in fsw:
        fail(
            f"controller {controller} with actuation wheels needs given gains for the level "
            f"'{schema.WHEELS_LEVEL}' (flight_software.gains)",
            "flight_software",
            "controller",
        )
    levels = level_names(vehicle)
    named = [("rcs", "valve_time_constants_ms")] if "rcs" in vehicle else []
    if "gains" in fsw:
        named += [("flight_software", "gains", "kp"), ("flight_software", "gains", "kd")]
    for path in named:
        node = vehicle
        for key in path:
            node = node[key]
        expected = list(vehicle["rcs"]["thrust_n"]) if path[0] == "rcs" else levels
        if list(node) != expected:
            what = (
                f"the level of actuation wheels ({schema.WHEELS_LEVEL})"
                if expected == [schema.WHEELS_LEVEL]
                else f"the thrust levels of rcs.thrust_n in its order ({', '.join(expected)})"
            )
            fail(f"expected {what}, got {', '.join(node)}", *path)
    message = inertia_problem(vehicle["inertia_kg_m2"])
    if message:
        fail(message, "inertia_kg_m2")
    entry.check(vehicle, fail)  # issue 24: entry aerodynamics and surfaces
    with plausibility.blamed(plausible, "position_m"):  # a position in mm turns the allocation: name it
        found = design_checks.check_vehicle(vehicle, fail)
    if warnings is not None:
        warnings.extend(plausible + found)


def _check_numbering(units, what, path, fail):
    """Ids 1..N in order and unique names of the ``what`` (thruster, wheel) list at ``path``."""
    names = {}
    for i, unit in enumerate(units):
        if "name" in unit:
            if unit["name"] in names:
                also = names[unit["name"]]
                fail(f"{what} name '{unit['name']}' is used twice (also {what} {also})", *path, i, "name")
            names[unit["name"]] = i + 1
        if unit["id"] != i + 1:
            fail(f"expected {what} ids 1..{len(units)} in order, got {unit['id']}", *path, i, "id")


def _check_rcs(vehicle, fail):
    """Thruster numbering and names, the actuation's switching limits, the allocation table."""
    thrusters = vehicle["rcs"]["thrusters"]
    _check_numbering(thrusters, "thruster", ("rcs", "thrusters"), fail)
    for i, thruster in enumerate(thrusters):
        if smallmatrix.norm(thruster["direction"]) == 0.0:
            fail("expected a non-zero force direction", "rcs", "thrusters", i, "direction")
    if vehicle["flight_software"]["actuation"] == "lp_pwm" and vehicle["rcs"]["switching_limits_ms"]["min_off"] != 0.0:
        fail(
            "actuation lp_pwm pulses inside each control period and applies no minimum rest; "
            "expected switching_limits_ms.min_off: 0 (min_on is honoured by rounding the pulse)",
            "rcs",
            "switching_limits_ms",
            "min_off",
        )
    if vehicle["flight_software"]["actuation"] == "pwpf_table" and "allocation" not in vehicle["flight_software"]:
        fail("actuation pwpf_table needs an allocation table (flight_software.allocation)", "flight_software")
    for key, ids in vehicle["flight_software"].get("allocation", {}).items():
        for k, tid in enumerate(ids):
            if tid > len(thrusters):
                fail(f"expected a thruster id 1..{len(thrusters)}, got {tid}", "flight_software", "allocation", key, k)
    try:
        allocation_table(vehicle)
    except KeyError as missing:
        fail(f"expected an entry for the axis command '{missing.args[0]}'", "flight_software", "allocation")


def _check_feed(vehicle, fail, plausible=()):
    """rcs.feed: the keys its model takes; isp_s and propellant_kg given with the constant feed
    only (a tank's are derived from it); no tank behind thrusters a wheel vehicle never fires; a
    regulated level below the full tank's thrust, refused at an implausible feed value behind it
    (``plausible``: the vehicle's plausibility warnings)."""
    rcs = vehicle["rcs"]
    feed = rcs.get("feed", {})
    model = feed.get("model", "constant")
    if model == "constant":
        for key in feed:
            if key != "model":
                fail(f"'{key}' is a key of a blow_down or regulated feed; the feed is constant", "rcs", "feed", key)
        for key in ("isp_s", "propellant_kg"):
            if key not in rcs:
                fail(f"'{key}' is required with the constant feed (rcs.feed.model)", "rcs")
        return
    if vehicle["flight_software"]["actuation"] == "wheels":
        fail("a wheel vehicle's thrusters never fire: expected no rcs.feed with actuation wheels", "rcs", "feed")
    for key in ("isp_s", "propellant_kg"):
        if key in rcs:
            fail(f"'{key}' is derived from the tank with feed {model} (002 eq. 1, 15); expected none", "rcs", key)
    for key in schema.FEED_TANK_KEYS:
        if key not in feed:
            fail(f"'{key}' is required with feed {model}", "rcs", "feed")
    if model == "regulated":
        full = config_feed.design(feed)["initial_thrust_n"]
        for level, thrust in rcs["thrust_n"].items():
            if thrust < full:
                continue
            with plausibility.blamed(plausible, "feed"):  # a tank pressure in bar fails here: name it
                fail(
                    f"a regulated level needs less thrust than the full tank gives (C_F A_t P0 = {full:.6g} N), "
                    f"got {thrust:g}",
                    "rcs",
                    "thrust_n",
                    level,
                )


def _check_wheels(vehicle, fail):
    """Wheel numbering and names, non-zero axes that span the body axes, initial momenta within the limit."""
    wheels = vehicle["wheels"]
    units = wheels["units"]
    _check_numbering(units, "wheel", ("wheels", "units"), fail)
    for i, unit in enumerate(units):
        if smallmatrix.norm(unit["axis"]) == 0.0:
            fail("expected a non-zero spin axis", "wheels", "units", i, "axis")
        momentum = unit.get("initial_momentum_n_m_s", 0.0)
        if abs(momentum) > wheels["momentum_max_n_m_s"]:
            fail(
                f"expected |initial momentum| <= momentum_max_n_m_s ({wheels['momentum_max_n_m_s']:g} N m s), "
                f"got {momentum:g}",
                "wheels",
                "units",
                i,
                "initial_momentum_n_m_s",
            )
    message = wheel_problem(vehicle)
    if message:
        fail(message, "wheels", "units")
    managed = wheels.get("null_space_management")
    if managed is not None:
        bias = managed.get("bias_n_m_s")
        if (managed["target"] == "bias") != (bias is not None):
            fail("expected bias_n_m_s with target bias, and only then", "wheels", "null_space_management")
        if bias is not None and len(bias) != len(units):
            fail(
                f"expected one bias per wheel ({len(units)}), got {len(bias)}",
                "wheels",
                "null_space_management",
                "bias_n_m_s",
            )
        if bias is not None and max(abs(b) for b in bias) >= wheels["momentum_max_n_m_s"]:
            fail(
                f"expected every |bias| below momentum_max_n_m_s ({wheels['momentum_max_n_m_s']:g} N m s)",
                "wheels",
                "null_space_management",
                "bias_n_m_s",
            )


def check_modes(modes, fail):
    """The mode program: unique names, the keys and targets each kind takes, the predicates it can
    answer (schema.MODE_KINDS, schema.EXIT_PREDICATES)."""
    kind_keys = {key for spec in schema.MODE_KINDS.values() for keys in spec["keys"] for key in keys}
    seen = {}
    for m, mode in enumerate(modes):
        name, kind = mode["name"], mode["kind"]
        spec = schema.MODE_KINDS[kind]
        key = name.lower()
        if key == "end":
            fail("'end' is not a mode name (its time column would be t_end_s, the flight's end)", "modes", m, "name")
        if key in seen:
            fail(f"mode name '{name}' is used twice (also mode {seen[key] + 1})", "modes", m, "name")
        seen[key] = m
        required, optional = spec["keys"]
        for k in required:
            if k not in mode:
                fail(f"kind {kind} needs '{k}'", "modes", m)
        for k in sorted(kind_keys & set(mode) - set(required) - set(optional)):
            fail(f"kind {kind} takes no '{k}'", "modes", m, k)
        allowed, target = spec["targets"], mode.get("target")
        if allowed is None and target is not None:
            fail(f"kind {kind} takes no target", "modes", m, "target")
        if allowed is not None and target is None:
            fail(f"kind {kind} needs a target ({', '.join(allowed)})", "modes", m)
        if target is not None and target["type"] not in allowed:
            message = f"kind {kind} cannot use target {target['type']}; expected one of {', '.join(allowed)}"
            fail(message, "modes", m, "target", "type")
        if target is not None and target["type"] == "inertial":
            has_q, has_euler = "quaternion" in target, "euler_deg" in target or "sequence" in target
            if has_q == has_euler or (has_euler and not ("euler_deg" in target and "sequence" in target)):
                fail("expected either 'quaternion' or both 'euler_deg' and 'sequence'", "modes", m, "target")
            if has_q and smallmatrix.norm(target["quaternion"]) == 0.0:
                fail("expected a non-zero quaternion", "modes", m, "target", "quaternion")
        for g, group in enumerate(mode["exit"]):
            for predicate in group:
                needs = schema.EXIT_PREDICATES[predicate][2]
                if needs in (None, "trajectory") or needs in spec["provides"]:
                    continue
                kinds = [k for k, s in schema.MODE_KINDS.items() if needs in s["provides"]]
                what = needs.replace("_", " ")
                message = f"predicate {predicate} needs a {what} ({', '.join(kinds)}); kind {kind} has none"
                fail(message, "modes", m, "exit", g, predicate)


def check_mission(mission, file, lines, prefix=(), warnings=None):
    """Checks the schema cannot express: the mode program, ascending atmosphere, non-zero sun and
    gravity-gradient directions, one initial attitude, a pointing window inside the flight; the
    plausibility warnings (config.plausibility) go to the list ``warnings``."""

    fail = _failing_at(file, lines, prefix)
    check_modes(mission["modes"], fail)
    initial = mission["initial_state"]
    if ("attitude_rotvec_deg" in initial) == ("attitude_euler_deg" in initial):
        fail("expected either 'attitude_rotvec_deg' or 'attitude_euler_deg' (with 'euler_sequence')", "initial_state")
    if ("euler_sequence" in initial) != ("attitude_euler_deg" in initial):
        if "euler_sequence" in initial:
            fail("'euler_sequence' goes with 'attitude_euler_deg'", "initial_state", "euler_sequence")
        fail("'attitude_euler_deg' needs 'euler_sequence' (e.g. ZYX)", "initial_state", "attitude_euler_deg")
    gravity = mission.get("disturbances", {}).get("gravity_gradient")
    if gravity is not None and smallmatrix.norm(gravity["direction"]) == 0.0:
        fail("expected a non-zero vector", "disturbances", "gravity_gradient", "direction")
    start = mission.get("pointing_statistics_from_s")
    if start is not None and start >= mission["max_flight_time_s"]:
        fail(
            f"expected a time before max_flight_time_s ({mission['max_flight_time_s']:g} s), got {start:g}",
            "pointing_statistics_from_s",
        )
    bases = [row["base_altitude_km"] for row in mission.get("atmosphere", [])]
    if any(b2 <= b1 for b1, b2 in zip(bases, bases[1:], strict=False)):
        raise ConfigError(
            "expected strictly ascending base altitudes",
            file=file,
            line=lines.get(("atmosphere",)),
            path=prefix + ("atmosphere",),
        )
    if "sun_direction" in mission and smallmatrix.norm(mission["sun_direction"]) == 0.0:
        raise ConfigError(
            "expected a non-zero vector",
            file=file,
            line=lines.get(("sun_direction",)),
            path=prefix + ("sun_direction",),
        )
    if warnings is not None:
        warnings.extend(plausibility.check_mission(mission, fail))


def check_flight(vehicle, mission, fail_mission, fail_vehicle, plausible=()):
    """What a vehicle and a mission need of each other: a trajectory model and its inputs, given
    gains for the pd controller. ``fail_*(message, *key_path)`` raise in the file concerned; a
    derived check (the tank's reserve, the deorbit burn) that fails is refused at a plausibility
    warning of ``plausible`` behind it (config.plausibility.blamed)."""
    levels = level_names(vehicle)
    for m, mode in enumerate(mission["modes"]):
        if "thrust" in mode and vehicle["flight_software"]["actuation"] == "wheels":
            fail_mission(
                f"vehicle {vehicle['name']} flies reaction wheels (actuation wheels); a mode takes no 'thrust'",
                "modes",
                m,
                "thrust",
            )
        if mode.get("thrust", levels[0]) not in levels:
            fail_mission(
                f"thrust level '{mode['thrust']}' is not one of the vehicle's: {', '.join(levels)}",
                "modes",
                m,
                "thrust",
            )
    if vehicle["flight_software"]["controller"] == "pd" and "gains" not in vehicle["flight_software"]:
        fail_vehicle("controller pd needs given gains (flight_software.gains)", "flight_software", "controller")
    trajectory = trajectory_model(vehicle)
    if trajectory == "local":
        _check_local(vehicle, mission, fail_mission, fail_vehicle, plausible)
    else:
        if "local" in mission:
            fail_mission(
                f"'local' needs a vehicle with the local trajectory; {vehicle['name']} has {trajectory}", "local"
            )
        for m, mode in enumerate(mission["modes"]):
            if mode["kind"] in schema.LOCAL_KINDS:
                fail_mission(f"kind {mode['kind']} needs the local trajectory", "modes", m, "kind")
        if "translation" in vehicle["flight_software"]:
            fail_vehicle("'translation' needs the local trajectory", "flight_software", "translation")
        for key in schema.LOCAL_NAVIGATION_KEYS:
            if key in mission["navigation"]:
                fail_mission(f"navigation.{key} needs a vehicle with the local trajectory", "navigation", key)
    if trajectory != "orbit":
        if "orbit" in mission:
            fail_mission(
                f"'orbit' needs a vehicle with the orbit trajectory; {vehicle['name']} has {trajectory}", "orbit"
            )
        for m, mode in enumerate(mission["modes"]):
            if mode["kind"] in schema.ORBIT_KINDS:
                fail_mission(f"kind {mode['kind']} needs the orbit trajectory", "modes", m, "kind")
            if mode.get("target", {}).get("type") in schema.ORBIT_TARGETS:
                fail_mission("target burn_start needs the orbit trajectory", "modes", m, "target", "type")
    else:
        _check_orbit(vehicle, mission, fail_mission, fail_vehicle, plausible)
        return
    if trajectory == "planar_drag":
        if "aerodynamics" not in vehicle:
            fail_vehicle("the planar_drag trajectory needs 'aerodynamics' (drag area, reference area and length)")
        for key in ("earth", "atmosphere"):
            if key not in mission:
                fail_mission(f"the vehicle's planar_drag trajectory needs '{key}'")
        for key in ("altitude_m", "speed_m_s", "flight_path_angle_deg"):
            if key not in mission["initial_state"]:
                fail_mission(f"the vehicle's planar_drag trajectory needs initial_state '{key}'", "initial_state")
        return
    for m, mode in enumerate(mission["modes"]):
        target = mode.get("target", {}).get("type")
        if target in schema.TRAJECTORY_TARGETS:
            fail_mission(f"target {target} needs a trajectory; the vehicle has none", "modes", m, "target", "type")
        for g, group in enumerate(mode["exit"]):
            for predicate in group:
                if schema.EXIT_PREDICATES[predicate][2] == "trajectory":
                    fail_mission(
                        f"predicate {predicate} needs a trajectory; the vehicle has none",
                        "modes",
                        m,
                        "exit",
                        g,
                        predicate,
                    )


def _check_local(vehicle, mission, fail_mission, fail_vehicle, plausible=()):
    """A local vehicle and mission: a tank (rcs.feed), the pwpf_table actuation and a translation
    law; the mission's local block; a fuel reserve the origin can be reached with (002 eq. 45-46)."""
    fsw = vehicle["flight_software"]
    if "rcs" not in vehicle or vehicle["rcs"].get("feed", {}).get("model", "constant") == "constant":
        fail_vehicle("the local trajectory flies the thrust a tank gives: expected rcs.feed blow_down or regulated")
    if fsw["actuation"] != "pwpf_table":
        fail_vehicle("the local trajectory needs actuation pwpf_table", "flight_software", "actuation")
    if "translation" not in fsw:
        fail_vehicle("the local trajectory needs a translation law (flight_software.translation)", "flight_software")
    law = fsw["translation"]
    pd_keys = ("position_gain_s2", "velocity_gain_s", "pwm_period_s")
    for key in pd_keys:
        if law["law"] == "pd_pwm" and key not in law:
            fail_vehicle(f"translation law pd_pwm needs '{key}'", "flight_software", "translation")
        if law["law"] != "pd_pwm" and key in law:
            fail_vehicle(f"'{key}' is a key of law pd_pwm", "flight_software", "translation", key)
    if len(vehicle["rcs"]["thrusters"]) > 52:
        fail_vehicle("the translation law's thruster masks hold at most 52 thrusters", "rcs", "thrusters")
    if "local" not in mission:
        fail_mission(f"vehicle {vehicle['name']} has the local trajectory: expected a 'local' block")
    local = mission["local"]
    p0 = vehicle["rcs"]["feed"]["initial_pressure_pa"]
    reserve = local.get("reserve_pressure_pa", 0.0)
    _, force, tau = translation_design(vehicle)
    accel = [f / vehicle["mass_kg"] for f in force]
    # the tank's keys live in the vehicle file: name them there too (issue 34)
    tank = f"P0 = {p0:g} Pa at {fail_vehicle.where('rcs', 'feed', 'initial_pressure_pa')}"
    with plausibility.blamed(plausible, "feed", "mass_kg", "reserve_pressure_pa"):  # 002 eq. 45-46
        for axis in range(3):
            if accel[axis] == 0.0:
                continue
            # 002 eq. 45-46 on the scaled state: x3_0 - |x2_0| = k tau^2 (P0 - |v0| / (k tau))
            reachable = p0 - abs(local["velocity_m_s"][axis]) / (accel[axis] * tau[axis])
            if reachable <= 0.0:
                fail_mission(
                    f"the initial speed along body {'xyz'[axis]} cannot be stopped by the tank (002 eq. 46: "
                    f"P0 - |v0|/(k tau) = {reachable:.6g} Pa; {tank})",
                    "local",
                    "velocity_m_s",
                )
            if reserve >= reachable:
                fail_mission(
                    f"expected a fuel reserve inside 002 eq. 45, 0 <= reserve < P0 - |v0|/(k tau) = {reachable:.6g} Pa "
                    f"(body {'xyz'[axis]}; {tank}), got {reserve:g}",
                    "local",
                    "reserve_pressure_pa",
                )


def _check_orbit(vehicle, mission, fail_mission, fail_vehicle, plausible=()):
    """An orbit vehicle and mission: main engine, burn guidance, Earth and orbit; no planar-trajectory
    targets or dynamic pressure; ignition on a control step."""
    if "main_engine" not in vehicle:
        fail_vehicle("the orbit trajectory needs 'main_engine'")
    if "burn_guidance" not in vehicle["flight_software"]:
        fail_vehicle("the orbit trajectory needs flight_software 'burn_guidance'", "flight_software")
    for key in ("earth", "orbit"):
        if key not in mission:
            fail_mission(f"the vehicle's orbit trajectory needs '{key}'")
    from refexmc.config.pack import deorbit_plan  # the bisection: a target it cannot reach is bad input

    try:
        deorbit_plan(vehicle, mission)
    except ConfigError as error:
        with plausibility.blamed(plausible, "main_engine", "mass_kg"):  # an engine in other units
            fail_mission(error.message, "orbit", "deorbit")
    period = 1.0 / vehicle["flight_software"]["control_rate_hz"]
    start = mission["orbit"]["deorbit"]["burn_start_s"]
    if abs(start / period - round(start / period)) > 1e-6:
        fail_mission(
            f"burn_start_s must be a whole number of control periods ({period:g} s)", "orbit", "deorbit", "burn_start_s"
        )
    for m, mode in enumerate(mission["modes"]):
        target = mode.get("target", {}).get("type")
        if target in schema.TRAJECTORY_TARGETS:
            fail_mission(f"target {target} needs the planar_drag trajectory", "modes", m, "target", "type")
        for g, group in enumerate(mode["exit"]):
            if "dynamic_pressure_above_pa" in group:
                fail_mission(
                    "the orbit trajectory has no atmosphere (dynamic pressure 0)",
                    "modes",
                    m,
                    "exit",
                    g,
                    "dynamic_pressure_above_pa",
                )


def load_vehicle(path, warnings=None):
    """The validated vehicle file; its design warnings are appended to the list ``warnings``."""
    data, lines = read_yaml(path)
    validate(data, schema.VEHICLE, path, lines)
    check_vehicle(data, path, lines, warnings=warnings)
    return data


def _renamed(found, file, lines):
    """The warnings of the old names ``found`` by config.renames (each an error under --strict)."""
    return renames.warnings_of(found, file, lines, design_checks.DesignWarning)


def load_mission(path, warnings=None):
    """The validated mission file; a warning per old key name (config.renames) and its plausibility
    warnings go to the list ``warnings``."""
    data, lines = read_yaml(path)
    found = _renamed(renames.migrate_mission(data, lines), path, lines)
    if warnings is not None:
        warnings.extend(found)
    if isinstance(data, dict) and "entry_flight" in data:  # an entry mission (issue 24, docs/x38.md)
        validate(data, schema.ENTRY_MISSION, path, lines)
        check_entry_mission(data, path, lines, warnings=warnings)
        return data
    validate(data, schema.MISSION, path, lines)
    check_mission(data, path, lines, warnings=warnings)
    return data


def check_entry_mission(mission, file, lines, prefix=(), warnings=None):
    """Checks of an entry mission the schema cannot express: the guidance schedules' axes
    (Mach, speed) strictly increasing; plausibility warnings go to the list ``warnings``."""
    fail = _failing_at(file, lines, prefix)
    flight = mission["entry_flight"]
    for key, axis in (("alpha_schedule", "mach"), ("bank_schedule", "speed_m_s")):
        nodes = flight[key]
        for k in range(1, len(nodes)):
            if nodes[k][axis] <= nodes[k - 1][axis]:
                fail(
                    f"expected {axis} strictly increasing, got {nodes[k - 1][axis]!r} then {nodes[k][axis]!r}",
                    "entry_flight",
                    key,
                    k,
                    axis,
                )
    if flight["floor_altitude_m"] >= flight["state"]["altitude_m"]:
        fail(
            f"expected a floor below the entry altitude ({flight['state']['altitude_m']:g} m), "
            f"got {flight['floor_altitude_m']:g}",
            "entry_flight",
            "floor_altitude_m",
        )
    if warnings is not None:
        warnings.extend(plausibility.check_mission(mission, fail))


def _resolve_part(campaign, key, campaign_file, lines, part_schema, checker, renamed=None):
    """(validated data, a function raising ConfigError at a key path of it). ``renamed``: a list
    that gets a warning per old name of a mission file (config.renames); None: no migration."""
    ref = campaign[key]
    if isinstance(ref, dict):
        part_lines = {k[1:]: v for k, v in lines.items() if k[:1] == (key,)}
        validate(ref, part_schema, campaign_file, part_lines, (key,))
        checker(ref, campaign_file, part_lines, (key,))
        return ref, _failing_at(campaign_file, part_lines, (key,))
    path = (Path(campaign_file).parent / ref).resolve()
    try:
        data, part_lines = read_yaml(path)
    except ConfigError as error:
        if error.file != path or error.line is not None:
            raise
        # the file cannot be read at all: name the campaign line that refers to it (issue 34)
        # the path once, as written; a relative one is read from the campaign file's folder
        relative = "" if Path(ref).is_absolute() or path.exists() else " (relative to the campaign file's folder)"
        raise ConfigError(
            f"{key} file '{ref}'{relative}: {error.message}", file=campaign_file, line=lines.get((key,)), path=(key,)
        ) from None
    if renamed is not None:
        renamed += _renamed(renames.migrate_mission(data, part_lines), path, part_lines)
    validate(data, part_schema, path, part_lines)
    checker(data, path, part_lines)
    return data, _failing_at(path, part_lines, ())


def _failing_at(file, lines, prefix):
    """fail(message, *key_path): raise ConfigError at the key path (the line of its nearest given
    parent); ``fail.where(*key_path)`` is the place as text, for a message about another file."""

    def fail(message, *path):
        raise ConfigError(message, file=file, line=_line_of(lines, path), path=prefix + path)

    def where(*path):
        return str(ConfigError("", file=file, line=_line_of(lines, path), path=prefix + path)).rstrip(": ")

    fail.where = where
    return fail


def _line_of(lines, path):
    return next((lines[path[:k]] for k in range(len(path), -1, -1) if path[:k] in lines), None)


FAILURE_KEYS = {"none": (), "fixed": ("units",), "random": ("count_probabilities",), "enumerate": ("sizes",)}


def _check_failures(failures, units, path, lines, kind=THRUSTER_FAILURES):
    """Failure settings against the vehicle's ``units`` (thrusters or wheels, with id and an
    optional name); names in the fixed list become ids."""
    n_units = len(units)
    word = kind.word

    def fail(message, *sub):
        key = (kind.key, *sub)
        raise ConfigError(message, file=path, line=lines.get(key) or lines.get((kind.key,)), path=key)

    mode = failures["mode"]
    if mode != "none" and n_units == 0:
        fail(f"{kind.key} mode {mode} fails {word}s; the vehicle has none", "mode")
    used = {kind.units_key if key == "units" else key for key in FAILURE_KEYS[mode]}
    for key in (kind.units_key, "count_probabilities", "sizes"):
        if key in failures and key not in used:
            fail(f"'{key}' is not used with mode {mode}", key)
    for key in used:
        if key not in failures:
            fail(f"mode {mode} needs '{key}'")
    if mode == "none" and "detected" in failures:
        fail(f"'detected' is not used with mode none (no {word} fails)", "detected")
    if mode == "fixed":
        ids = {u.get("name", u["id"]): u["id"] for u in units}
        ids.update({u["id"]: u["id"] for u in units})
        resolved = []
        for k, uid in enumerate(failures[kind.units_key]):
            if isinstance(uid, str) and uid not in ids:
                names = [u["name"] for u in units if "name" in u]
                guess = difflib.get_close_matches(uid, names, n=1)
                hint = (
                    f"; did you mean '{guess[0]}'?" if guess else f"; the vehicle names: {', '.join(names) or 'none'}"
                )
                fail(f"unknown {word} '{uid}'{hint}", kind.units_key, k)
            if isinstance(uid, int) and uid > n_units:
                fail(f"expected a {word} id 1..{n_units}, got {uid}", kind.units_key, k)
            if ids[uid] in resolved:
                fail(f"{word} {ids[uid]} is listed twice (by id and by name)", kind.units_key, k)
            resolved.append(ids[uid])
        failures[kind.units_key] = resolved  # ids from here on: runs table, sampling, resolved campaign
    elif mode == "random":
        probabilities = failures["count_probabilities"]
        if len(probabilities) > n_units + 1:
            fail(f"expected at most {n_units + 1} probabilities (0..{n_units} failed)", "count_probabilities")
        if abs(sum(probabilities) - 1.0) > 1e-9:
            fail(f"expected probabilities summing to 1, got {sum(probabilities):g}", "count_probabilities")
    elif mode == "enumerate":
        for k, size in enumerate(failures["sizes"]):
            if size > n_units:
                fail(f"expected a set size 1..{n_units}, got {size}", "sizes", k)


def enumerated_failures(campaign):
    """The FailureKind whose mode is enumerate (the run count derives from its sets), or None."""
    for kind in (THRUSTER_FAILURES, WHEEL_FAILURES):
        if campaign.get(kind.key, NO_FAILURES)["mode"] == "enumerate":
            return kind
    return None


def load_campaign(path, warnings=None):
    """Validated campaign with vehicle and mission inlined; ConfigError on any bad input. The
    design warnings of its vehicle and mission (config.design_checks) are appended to ``warnings``."""
    from refexmc.config import dispersions  # imports this module

    path = Path(path)
    data, lines = read_yaml(path)
    found = _renamed(renames.migrate_campaign(data, lines), path, lines)  # old names: warnings (issue 34)
    validate(data, schema.CAMPAIGN, path, lines)
    checker = functools.partial(check_vehicle, warnings=found)
    vehicle, fail_vehicle = _resolve_part(data, "vehicle", path, lines, schema.VEHICLE, checker)
    if _is_entry_mission(data["mission"], path):
        return _load_entry_campaign(path, data, lines, vehicle, fail_vehicle, warnings, found)
    mission_checker = functools.partial(check_mission, warnings=found)
    mission, fail_mission = _resolve_part(data, "mission", path, lines, schema.MISSION, mission_checker, found)
    check_flight(vehicle, mission, fail_mission, fail_vehicle, plausible=found)
    found += design_checks.check_flight(vehicle, mission, fail_mission)
    campaign = {
        "name": data["name"],
        "runs": data.get("runs"),
        "seed": data["seed"],
        "nominal_first": data.get("nominal_first", True),
        "sampling": data.get("sampling", "random"),
        "dispersions": data.get("dispersions", {}),
        "failures": data.get("failures", {"mode": "none"}),
        "run_time_limit_s": data.get("run_time_limit_s", schema.DEFAULT_RUN_TIME_LIMIT_S),
        "output": data.get("output", {"history_rate_hz": 2.0}),
        "requirements": data.get("requirements", []),
        # only when given: the resolved campaign (its digest, --resume) of a file without it is unchanged
        **({"published": data["published"]} if "published" in data else {}),
        "vehicle": vehicle,
        "mission": mission,
    }
    if (
        "wheel_failures" in data
    ):  # only when given: the resolved campaign (its digest) of a file without it is unchanged
        campaign["wheel_failures"] = data["wheel_failures"]
    n_thrusters = thruster_count(vehicle)
    _check_failures(campaign["failures"], vehicle.get("rcs", {}).get("thrusters", []), path, lines)
    wheel_units = vehicle.get("wheels", {}).get("units", [])
    _check_failures(campaign.get("wheel_failures", NO_FAILURES), wheel_units, path, lines, WHEEL_FAILURES)
    if (
        campaign["failures"]["mode"] == "enumerate"
        and campaign.get("wheel_failures", NO_FAILURES)["mode"] == "enumerate"
    ):
        raise ConfigError(
            "failures and wheel_failures cannot both enumerate (one run per set of one kind)",
            file=path,
            line=lines.get(("wheel_failures", "mode")),
            path=("wheel_failures", "mode"),
        )
    specs = dispersions.check(campaign["dispersions"], vehicle, mission, path, lines)
    found += plausibility.check_dispersions(specs, lambda key: dispersions.nominal(key, vehicle, mission), path, lines)
    parameter_columns = [c for key in campaign["dispersions"] for c in dispersions.columns(key, vehicle)]
    mode_names = [mode["name"] for mode in mission["modes"]]
    options = requirements.column_options(vehicle, mission)
    columns = requirements.runs_metric_columns(mode_names, n_thrusters, parameter_columns, **options)
    for i, item in enumerate(campaign["requirements"]):  # a pointing record: its schema, then its sense
        if pointing.is_pointing(item):
            prefix = ("requirements", i)
            if not set(item) & set(schema.POINTING_REQUIREMENT["properties"]):  # not meant as a pointing record
                raise ConfigError(
                    "expected a requirement 'COLUMN.STAT OP VALUE' (e.g. 'position_error_end_m.max <= 0.05',"
                    " docs/campaigns.md) or a pointing record (docs/pointing.md)",
                    file=path,
                    line=lines.get(prefix),
                    path=prefix,
                )
            within = {key[2:]: line for key, line in lines.items() if key[:2] == prefix}
            validate(item, schema.POINTING_REQUIREMENT, path, within, prefix=prefix)
    pointed = pointing.parse(campaign["requirements"], mission, campaign["dispersions"], path, lines)
    columns += [req.column for req in pointed]  # their runs columns (docs/pointing.md)
    # the columns the table has but this vehicle and mission never fill (NaN in every run): a
    # requirement, published value, sweep metric, event or Sobol' metric on one is bad input
    absent = requirements.unproduced_columns(vehicle, mission)
    columns = [c for c in columns if c not in absent]
    requirements.check_requirements(campaign["requirements"], columns, path, lines, absent)
    published.check_published(campaign.get("published", []), columns, path, lines, absent=absent)
    if "sweep" in data:  # only when given: the resolved campaign (its digest) of a file without it is unchanged
        from refexmc.config import sweep

        campaign["sweep"] = data["sweep"]
        sweep.check_sweep(campaign, path, lines, columns, absent)
        found += plausibility.check_sweep(campaign["sweep"]["axes"], path, lines)
    if "rare_event" in data:  # only when given: the resolved campaign (its digest) of a file without it is unchanged
        from refexmc.config.rare_event import check_rare_event

        campaign["rare_event"] = check_rare_event(data, campaign, columns, path, lines, absent)
    enumerated = enumerated_failures(campaign)
    if enumerated is not None:
        n_units = n_thrusters if enumerated is THRUSTER_FAILURES else len(wheel_units)
        derived = len(failure_sets(campaign[enumerated.key]["sizes"], n_units)) + int(campaign["nominal_first"])
        if campaign["runs"] is not None and campaign["runs"] != derived:
            raise ConfigError(
                f"{enumerated.key} mode enumerate gives {derived} runs; remove 'runs' or set it to {derived}",
                file=path,
                line=lines.get(("runs",)),
                path=("runs",),
            )
        campaign["runs"] = derived
    elif campaign["runs"] is None:
        raise ConfigError("'runs' is required", file=path, line=1, path=("runs",))
    if warnings is not None:
        warnings.extend(found)
    if campaign["sampling"] == "saltelli":  # the design's run count and what it cannot hold
        saltelli.check(campaign, path, lines)
    if "sobol" in data:  # only when given: the resolved campaign (its digest) of a file without it is unchanged
        campaign["sobol"] = data["sobol"]
        check_sobol_metrics(campaign, [c for c in columns if not c.startswith("p.")], path, lines, absent)
    return campaign


def check_sobol_metrics(campaign, columns, path=None, lines=None, absent=None):
    """ConfigError (file, line, key path) unless the ``sobol`` key goes with ``sampling: saltelli``
    and names only ``success`` and runs columns the mission produces (``columns``; ``absent``:
    {column: why} of those its table has but never fills, requirements.unproduced_columns)."""
    lines = lines or {}
    absent = absent or {}
    if campaign["sampling"] != "saltelli":
        raise ConfigError(
            "'sobol' goes with 'sampling: saltelli' (the design its indices need), "
            f"got sampling {campaign['sampling']}",
            file=path,
            line=lines.get(("sobol",)),
            path=("sobol",),
        )
    known = ["success", *(c for c in columns if c not in absent), *requirements.derived_columns(columns)]
    for i, metric in enumerate(campaign["sobol"]["metrics"]):
        if metric in known:
            continue
        where = {
            "file": path,
            "line": lines.get(("sobol", "metrics", i)) or lines.get(("sobol", "metrics")),
            "path": ("sobol", "metrics", i),
        }
        if metric in absent:
            raise requirements.not_produced(f"Sobol' metric '{metric}'", metric, absent, known, **where)
        guess = difflib.get_close_matches(metric, known, n=1, cutoff=0.6)
        hint = f"did you mean '{guess[0]}'? " if guess else ""
        shown = ", ".join(c for c in known if not c.startswith("pulses_"))
        raise ConfigError(
            f"unknown metric '{metric}': this mission produces no such runs column; {hint}(metrics: {shown})", **where
        )


def _is_entry_mission(ref, campaign_file):
    """Whether a campaign's mission (inline or a file) is an entry mission (``entry_flight``)."""
    if isinstance(ref, dict):
        return "entry_flight" in ref
    try:
        data, _ = read_yaml((Path(campaign_file).parent / ref).resolve())
    except ConfigError:
        return False  # the ordinary route reports the file's problem
    return isinstance(data, dict) and "entry_flight" in data


# campaign keys an entry campaign (issue 24) does not take: thruster and wheel failures (a blocked
# flap is the mission's entry_flight.blocked_flap) and published values (not built for it); nor
# Saltelli designs (below)
_ENTRY_CAMPAIGN_REFUSED = ("failures", "wheel_failures", "published")


def _load_entry_campaign(path, data, lines, vehicle, fail_vehicle, warnings, found):
    """The validated campaign of an entry mission (docs/x38.md): the flight is
    core.entry_flight (campaign.entry_plan), its runs columns requirements.ENTRY_COLUMNS."""
    from refexmc.config import dispersions  # imports this module

    mission_checker = functools.partial(check_entry_mission, warnings=found)
    mission, fail_mission = _resolve_part(data, "mission", path, lines, schema.ENTRY_MISSION, mission_checker)
    for key in _ENTRY_CAMPAIGN_REFUSED:
        if key in data and data[key] != {"mode": "none"}:  # a resolved campaign says failures: none
            raise ConfigError(
                f"'{key}' is not available with an entry mission (a blocked flap is the mission's "
                "entry_flight.blocked_flap)",
                file=path,
                line=lines.get((key,)),
                path=(key,),
            )
    if "rare_event" in data:
        raise ConfigError(
            "rare_event is not available with an entry mission yet (docs/rare-events.md)",
            file=path,
            line=lines.get(("rare_event",)),
            path=("rare_event",),
        )
    for key in ("sampling", "sobol"):
        if key in data and (key == "sobol" or data[key] == "saltelli"):
            raise ConfigError(
                f"{'sampling saltelli' if key == 'sampling' else key} is not available with an entry mission",
                file=path,
                line=lines.get((key,)),
                path=(key,),
            )
    if "surfaces" not in vehicle:
        fail_vehicle("an entry mission needs a vehicle with aerodynamic surfaces ('surfaces')")
    flaps = vehicle["surfaces"]["body_flaps"]
    blocked = mission["entry_flight"].get("blocked_flap")
    if blocked is not None and not flaps["min_deg"] <= blocked["deflection_deg"] <= flaps["max_deg"]:
        fail_mission(
            f"expected a blocked deflection within the flap limits [{flaps['min_deg']}, {flaps['max_deg']}] deg "
            f"of vehicle {vehicle['name']}, got {blocked['deflection_deg']}",
            "entry_flight",
            "blocked_flap",
            "deflection_deg",
        )
    campaign = {
        "name": data["name"],
        "runs": data.get("runs"),
        "seed": data["seed"],
        "nominal_first": data.get("nominal_first", True),
        "sampling": data.get("sampling", "random"),
        "dispersions": data.get("dispersions", {}),
        "failures": {"mode": "none"},
        "run_time_limit_s": data.get("run_time_limit_s", schema.DEFAULT_RUN_TIME_LIMIT_S),
        "output": data.get("output", {"history_rate_hz": 1.0}),
        "requirements": data.get("requirements", []),
        "vehicle": vehicle,
        "mission": mission,
    }
    if campaign["runs"] is None:
        raise ConfigError("'runs' is required", file=path, line=1, path=("runs",))
    rate = campaign["output"]["history_rate_hz"]
    if rate > 1.0:
        raise ConfigError(
            f"expected at most 1 Hz with an entry mission (core.entry_flight records one row per second), got {rate:g}",
            file=path,
            line=lines.get(("output", "history_rate_hz")),
            path=("output", "history_rate_hz"),
        )
    limits = _entry_limits(vehicle)
    delay, delay_limit = mission["entry_flight"].get("rcs_delay_ms", 0.0), limits["entry_flight.rcs_delay_ms"]
    if not delay_limit.holds(delay):
        fail_mission(
            f"expected an RCS delay below the control period of vehicle {vehicle['name']} "
            f"({delay_limit.high:g} ms), got {delay:g}",
            "entry_flight",
            "rcs_delay_ms",
        )
    specs = dispersions.check(campaign["dispersions"], vehicle, mission, path, lines)
    found += plausibility.check_dispersions(specs, lambda key: dispersions.nominal(key, vehicle, mission), path, lines)
    for key, limit in limits.items():
        _check_entry_draws(specs.get(key), key, limit, vehicle, mission, path, lines.get(("dispersions", key)))
    parameter_columns = [c for key in campaign["dispersions"] for c in dispersions.columns(key, vehicle)]
    columns = requirements.entry_metric_columns(parameter_columns)
    for i, item in enumerate(campaign["requirements"]):
        if pointing.is_pointing(item):
            raise ConfigError(
                "an entry campaign takes no pointing requirement (its flight has no attitude reference to point)",
                file=path,
                line=lines.get(("requirements", i)),
                path=("requirements", i),
            )
    requirements.check_requirements(campaign["requirements"], columns, path, lines)
    if "sweep" in data:  # only when given: the resolved campaign (its digest) of a file without it is unchanged
        from refexmc.config import sweep

        campaign["sweep"] = data["sweep"]
        sweep.check_sweep(campaign, path, lines, columns)
        _check_entry_sweep(campaign, path, lines)
    if warnings is not None:
        warnings.extend(found)
    return campaign


class _Limit(NamedTuple):
    """Where an entry path's values must lie: [low, high], or [low, high) with ``open_high``."""

    low: float
    high: float
    what: str
    unit: str
    open_high: bool = False

    def holds(self, value):
        return self.low <= value and (value < self.high if self.open_high else value <= self.high)

    def text(self):
        return f"{self.what} [{self.low}, {self.high}{')' if self.open_high else ']'} {self.unit}"


def _entry_limits(vehicle):
    """The entry paths whose values the vehicle bounds beyond their schema range."""
    flaps = vehicle["surfaces"]["body_flaps"]
    period_ms = 1000.0 / vehicle["flight_software"]["control_rate_hz"]
    return {
        "entry_flight.blocked_flap.deflection_deg": _Limit(
            flaps["min_deg"], flaps["max_deg"], "the flap limits", "deg"
        ),
        "entry_flight.rcs_delay_ms": _Limit(0.0, period_ms, "the control period", "ms", open_high=True),
    }


def _check_entry_draws(spec, key, limit, vehicle, mission, path, line):
    """ConfigError at dispersions.<key> when the distribution ``spec`` (None: not dispersed)
    reaches outside ``limit``."""
    from refexmc.config import dispersions
    from refexmc.distributions import transform  # the sampler's own arithmetic, monotone in u

    if spec is None:
        return
    nominal = dispersions.nominal(key, vehicle, mission)
    eps = dispersions.UNIFORM_EPS
    low, high = (float(transform(spec, np.array([u]), nominal)[0]) for u in (eps, 1.0 - eps))
    if not (limit.holds(low) and limit.holds(high)):
        raise ConfigError(
            f"expected draws within {limit.text()}, the distribution reaches [{low:g}, {high:g}]",
            file=path,
            line=line,
            path=("dispersions", key),
        )


def _check_entry_sweep(campaign, path, lines):
    """An entry campaign's sweep: each value of a file value a dispersion the entry flies (the
    point's ``constant`` dispersion, config.sweep.point_campaign) within the vehicle's limits
    (:func:`_entry_limits`); each point of a dispersion's parameter with its draws within them."""
    from refexmc.config import dispersions, sweep

    vehicle, mission = campaign["vehicle"], campaign["mission"]
    limits = _entry_limits(vehicle)
    for i, axis in enumerate(campaign["sweep"]["axes"]):
        key_path = ("sweep", "axes", i, "values" if "values" in axis else "range")
        where = {"file": path, "line": lines.get(key_path) or lines.get(("sweep", "axes", i)), "path": key_path}
        name, limit = axis["parameter"], limits.get(axis["parameter"])
        for value in sweep.axis_values(axis):
            if "dispersion" in axis:  # the dispersion's own checks ran (config.sweep)
                if limit is None:
                    break
                spec = {**campaign["dispersions"][name], axis["dispersion"]: value}
                try:
                    _check_entry_draws(spec, name, limit, vehicle, mission, path, None)
                except ConfigError as exc:
                    raise ConfigError(f"at {axis['dispersion']} = {value:g}: {exc.message}", **where) from None
                continue
            try:
                trial = {**campaign["dispersions"], name: {"dist": "constant", "value": value}}
                dispersions.check(trial, vehicle, mission, path, {})
            except ConfigError as exc:
                raise ConfigError(f"at {value:g}: {exc.message}", **where) from None
            if limit is not None and not limit.holds(value):
                raise ConfigError(f"expected values within {limit.text()}, got {value:g}", **where)


def apply_overrides(campaign, runs=None, seed=None):
    """Command-line ``--runs``/``--seed`` over the file's values; ConfigError when not allowed."""
    if runs is not None and "rare_event" in campaign:
        raise ConfigError("--runs cannot be used with rare_event (set rare_event.per_level)", path=("--runs",))
    if runs is not None:
        enumerated = enumerated_failures(campaign)
        if enumerated is not None:
            raise ConfigError(f"--runs cannot be used with {enumerated.key} mode enumerate (the run count is derived)")
        if runs < 1:
            raise ConfigError(f"expected runs >= 1, got {runs}", path=("--runs",))
        campaign["runs"] = runs
        if campaign["sampling"] == "saltelli":  # the design's run count (the rest was checked at load)
            try:
                saltelli.check(campaign)
            except ConfigError as exc:
                raise ConfigError(exc.message, path=("--runs",)) from None
    if seed is not None:
        if not 0 <= seed < 2**63:
            raise ConfigError(f"expected 0 <= seed < 2**63, got {seed}", path=("--seed",))
        campaign["seed"] = seed
    return campaign


def detect_kind(data):
    """'campaign', 'vehicle' or 'mission' from a file's top-level keys."""
    if not isinstance(data, dict):
        return None
    if "runs" in data or "dispersions" in data:
        return "campaign"
    if "rcs" in data or "inertia_kg_m2" in data:
        return "vehicle"
    if "modes" in data or "initial_state" in data or renames.OLD_BLOCK in data or "entry_flight" in data:
        return "mission"
    return None


def load_any(path, warnings=None):
    """Validate a campaign, vehicle or mission file; return (kind, validated data). Design
    warnings (a campaign's or a vehicle's) are appended to the list ``warnings``."""
    data, _ = read_yaml(path)
    kind = detect_kind(data)
    if kind == "campaign":
        return kind, load_campaign(path, warnings)
    if kind == "vehicle":
        return kind, load_vehicle(path, warnings)
    if kind == "mission":
        return kind, load_mission(path, warnings)
    raise ConfigError("not a campaign, vehicle or mission file (no 'runs', 'rcs' or 'modes' key)", file=path, line=1)
