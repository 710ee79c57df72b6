"""Dispersions of a campaign: every input of the run function it may vary, by path.

The paths, their units, ranges, nominal values and where they land in the packed run inputs are
declared once, in ``config.parameters``; this module checks a campaign's ``dispersions`` against
them (one function per distribution, ``DISTRIBUTIONS``), gives each path's nominal value and
writes a drawn value into a run's inputs (``apply``). ``refexmc.campaign.sampling`` draws them through
the distributions' arithmetic of ``refexmc.distributions``.
"""

import difflib
import math
from collections.abc import Callable
from typing import NamedTuple

import numpy as np

from refexmc import distributions
from refexmc.config import derived, schema
from refexmc.config import feed as config_feed
from refexmc.config.errors import ConfigError
from refexmc.config.parameters import (  # noqa: F401 - the table, also read through this module
    AXES,
    ENTRY_SCALED_COEFFICIENTS,
    ENTRY_STATE_KEYS,
    INERTIA_COMPONENTS,
    MISSION_ROOTS,
    NOZZLE_CONSTANTS,
    PARAMETERS,
    Parameter,
    declared,
    file_of,
    parameter,
    put,
    put_rows,
    schema_default,
)
from refexmc.core import layout as L
from refexmc.distributions import (  # noqa: F401 - the distributions' arithmetic, also read through this module
    INERTIA_INDEX,
    UNIFORM_EPS,
    Z_MAX,
    inertia_matrix,
    inertia_tensors,
    truncnorm_support,
    uniforms_per_draw,
)

_ENTRY_ONLY = ("entry_flight.density_scale", "entry_flight.coefficient_scale.")  # dispersion-only paths, nominal 1


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
    "uniform_so3": "uniformly random rotation (Haar measure); initial_state.attitude_rotvec_deg only",
    "inertia": "relative 1-sigma of the principal moments (< 0.5), principal-axis misalignment 1-sigma (<= 180 deg); "
    "draws that are not physical are redrawn",
}
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
    or mission does not have it). The initial attitude of a mission that gives it as Euler
    angles is their rotation vector."""
    if path == "inertia_kg_m2":
        j = np.asarray(vehicle["inertia_kg_m2"], dtype=float)
        return np.array([j[a, b] for a, b in INERTIA_INDEX])
    if path.startswith(_ENTRY_ONLY) and "entry_flight" not in mission:
        raise KeyError(path)
    param = parameter(path)
    if param.key is None:  # dispersion only: its declared nominal, every component
        return np.full(size(path, vehicle), float(param.nominal))
    if path.startswith("rcs.valve_time_constants_ms."):  # one value in the file, one per thruster drawn
        _, _, level, name = path.split(".")
        rcs = vehicle["rcs"]
        return np.full(len(rcs["thrusters"]), float(rcs["valve_time_constants_ms"][level][name]))
    if path == "initial_state.attitude_rotvec_deg" and "attitude_euler_deg" in mission["initial_state"]:
        return np.degrees(derived.initial_rotation_vector(mission["initial_state"]))
    root = file_of(param, vehicle, mission)
    try:
        value = declared(param, root)
    except KeyError:
        value = omitted_default(param, root)
    return np.atleast_1d(np.asarray(value, dtype=float)).copy()


def omitted_default(param, root):
    """The schema default of ``param``'s key where the file has its block but omits the key (what
    the packer packs, ``parameters.configured``); KeyError where the file lacks the block or the
    key declares no default."""
    if param is None or param.key is None:  # no path, or a dispersion-only one: no file key
        raise KeyError(param)
    parent, _, _ = param.key.rpartition(".")
    default = schema_default(param.key)
    if not parent or "[]" in param.key or default is None:
        raise KeyError(param.key)
    node = root
    for key in parent.split("."):
        node = node[key]  # KeyError: no such block in the file
    return default


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


def undeclared(path, vehicle, mission):
    """Why ``path`` cannot be dispersed for this vehicle and mission (a quantity they do not
    have: no trajectory, no aerodynamics, no atmosphere), or None."""
    trajectory = derived.trajectory_model(vehicle)
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
    if path.startswith("rcs.feed.") and feed_model == "constant" and "rcs" in vehicle:
        return (
            f"'{path}': vehicle {vehicle['name']} has the constant feed (rcs.feed.model): no tank or nozzle "
            "to disperse (its thrust_n at isp_s)"
        )
    if path.startswith("rcs.thrust_n.") and feed_model == "blow_down":
        return f"'{path}': vehicle {vehicle['name']} has a blow-down tank: its pressure gives the thrust"
    if path.startswith("rcs.") and "rcs" in vehicle and derived.flies_wheels(vehicle):
        return f"'{path}': vehicle {vehicle['name']} flies reaction wheels (actuation wheels); its thrusters never fire"
    try:
        nominal(path, vehicle, mission)
    except KeyError:
        part = "mission" if path.split(".")[0] in MISSION_ROOTS else "vehicle"
        return f"'{path}': the {part} file does not declare it" + _declared_instead(
            path, mission if part == "mission" else vehicle
        )
    return None


def _put_rows(stack, fields, name, rows):
    offset, count = fields.slices[name]
    rows = np.asarray(rows, dtype=float).reshape(len(stack), -1)
    assert rows.shape[1] == count, (name, rows.shape[1], count)
    stack[:, offset : offset + count] = rows


# the RunInputs tables a dispersion writes (and set_failed: "allocation" too, with detected failures)
DISPERSED_TABLES = ("vehicle", "thrusters", "levels", "mission", "nav", "atmosphere", "wheels")


def stacked(inputs, runs, copied=DISPERSED_TABLES):
    """``inputs``' tables stacked for ``runs`` runs (what :func:`apply_rows` writes into): those
    named in ``copied`` a copy per run, the others read-only views of the one table."""
    return inputs._replace(
        **{
            name: np.repeat(table[np.newaxis], runs, axis=0)
            if name in copied
            else np.broadcast_to(table, (runs, *table.shape))
            for name, table in inputs._asdict().items()
        }
    )


def apply(inputs, path, values, nominal_atmosphere, levels=schema.REFEX_LEVEL_NAMES):
    """Write ``values`` (user units) of ``path`` into the run's own copies of the input arrays:
    :func:`apply_rows` of one run."""
    stack = inputs._replace(**{name: table[np.newaxis] for name, table in inputs._asdict().items()})
    apply_rows(stack, path, np.asarray(values, dtype=float)[np.newaxis], nominal_atmosphere, levels)


def apply_rows(stack, path, rows, nominal_atmosphere, levels=schema.REFEX_LEVEL_NAMES):
    """Write each run's values ``rows[k]`` (user units) of ``path`` into ``stack``'s tables' row k
    (a RunInputs of tables stacked one per run, the runs' own copies): the operations of each run
    alone, elementwise, so the same bits (tests/naive.py twins it run by run). ``levels``: the
    vehicle's thrust-level names, in order (``derived.level_names``). A path that lands in one
    field (``parameters``) goes there as the packer puts its nominal; the special ones, by name,
    with the reason ``parameters.PARAMETERS`` gives."""
    rows = np.asarray(rows, dtype=float).reshape(len(stack.vehicle), -1)
    param = parameter(path)
    if param.table is not None:
        put_rows(getattr(stack, param.table), param, rows)
        if param.special == NOZZLE_CONSTANTS:  # the packed C_F and Gamma of the drawn gamma and epsilon
            for vehicle in stack.vehicle:
                vehicle[L.V_FEED_THRUST_COEFFICIENT], vehicle[L.V_FEED_FLOW_FACTOR] = config_feed.nozzle_constants(
                    float(vehicle[L.V_FEED_HEAT_CAPACITY_RATIO]), float(vehicle[L.V_FEED_EXPANSION_RATIO])
                )
    elif path.startswith("rcs.thrust_n."):
        level = stack.levels[:, list(levels).index(path.split(".")[2])]
        # a regulated feed delivers the level's thrust through its set pressure (config.feed.set_pressure)
        level[:, L.LV_REGULATOR_PRESSURE] *= rows[:, 0] / level[:, L.LV_THRUST]
        level[:, L.LV_THRUST] = rows[:, 0]
    elif path == "main_engine.misalignment_deg":
        nominal_axes = stack.fsw[:, L.F_ENGINE_AXIS : L.F_ENGINE_AXIS + 3]
        directions = [
            derived.rotate_by_rotation_vector(axis, row) for axis, row in zip(nominal_axes, rows, strict=True)
        ]
        _put_rows(stack.vehicle, L.VEHICLE, "engine_direction", directions)
    elif path == "inertia_kg_m2":
        _put_rows(stack.vehicle, L.VEHICLE, "inertia_kg_m2", inertia_tensors(rows))
    elif path == "rcs.derating":
        padding = np.repeat(rows[:, -1:], L.DERATING_MAX_VALVES - rows.shape[1], axis=1)
        _put_rows(stack.vehicle, L.VEHICLE, "derating", np.concatenate([rows, padding], axis=1))
    elif path.startswith("rcs.valve_time_constants_ms."):
        _, _, level, name = path.split(".")
        column = L.time_constant_column(list(levels).index(level), L.TIME_CONSTANT_NAMES.index(name))
        stack.thrusters[:, :, column] = rows / 1e3
    elif path == "atmosphere.density_scale":
        stack.atmosphere[:, :, 1] = nominal_atmosphere[np.newaxis, :, 1] * rows[:, :1]
    else:  # pragma: no cover - the entry paths: campaign.entry_plan builds the entry vehicle from them
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


class _Dispersion(NamedTuple):
    """One dispersion being checked: its spec, its path's nominal value and unit, and the checks'
    helpers (``fail(message, *key)`` raises the ConfigError; ``vector(key)`` reads a parameter)."""

    spec: dict
    n: int  # components of the path
    nominal: np.ndarray
    unit: str  # " [unit]", for messages
    fail: Callable
    vector: Callable


def _check_constant(d):
    return {"value": d.vector("value")}


def _mean_and_sigma(d, dist):
    mean = d.vector("mean") if "mean" in d.spec else d.nominal.copy()
    sigma = d.vector("sigma")
    if (sigma < 0).any() or (dist == "truncnorm" and (sigma <= 0).any()):
        d.fail(f"expected sigma {'>' if dist == 'truncnorm' else '>='} 0{d.unit}, got {d.spec['sigma']!r}", "sigma")
    return mean, sigma


def _check_normal(d):
    mean, sigma = _mean_and_sigma(d, "normal")
    return {"mean": mean, "sigma": sigma}


def _check_truncnorm(d):
    mean, sigma = _mean_and_sigma(d, "truncnorm")
    if "low" not in d.spec and "high" not in d.spec:
        d.fail("truncnorm needs 'low' and/or 'high' (else use normal)")
    low = d.vector("low") if "low" in d.spec else np.full(d.n, -np.inf)
    high = d.vector("high") if "high" in d.spec else np.full(d.n, np.inf)
    if (low >= high).any():
        d.fail("expected low < high", "low")
    return {"mean": mean, "sigma": sigma, "low": low, "high": high}


def _check_uniform(d):
    low, high = d.vector("low"), d.vector("high")
    if (low > high).any():
        d.fail("expected low <= high", "low")
    if not np.isfinite(high - low).all():
        d.fail("expected high - low to be a finite number (draws are low + (high - low) u)", "high")
    return {"low": low, "high": high}


def _check_lognormal(d):
    median = d.vector("median") if "median" in d.spec else d.nominal.copy()
    sigma = d.vector("sigma")
    if (median <= 0).any():
        d.fail("expected a median > 0 (lognormal draws are positive)", "median" if "median" in d.spec else "dist")
    if (sigma < 0).any():
        d.fail(f"expected sigma >= 0 (of ln x), got {d.spec['sigma']!r}", "sigma")
    return {"median": median, "sigma": sigma}


def _check_choice(d):
    values, n = d.spec["values"], d.n
    if not isinstance(values, list) or not values:
        d.fail("expected a non-empty list of values", "values")
    items = []
    for k, item in enumerate(values):
        if isinstance(item, list):
            if len(item) != n or any(isinstance(v, bool) or not isinstance(v, (int, float)) for v in item):
                d.fail(f"expected a number or a list of {n} numbers, got {item!r}", "values", k)
            items.append(np.asarray(item, dtype=float))
        elif isinstance(item, (int, float)) and not isinstance(item, bool):
            items.append(np.full(n, float(item)))
        else:
            d.fail(f"expected a number or a list of {n} numbers, got {item!r}", "values", k)
        if not np.isfinite(items[-1]).all():
            d.fail(f"expected finite numbers, got {item!r}", "values", k)
    resolved = {"values": np.array(items), "per_component": not any(isinstance(item, list) for item in values)}
    probabilities = d.spec.get("probabilities")
    if probabilities is None:
        resolved["probabilities"] = np.full(len(items), 1.0 / len(items))
    else:
        if (
            not isinstance(probabilities, list)
            or len(probabilities) != len(items)
            or any(isinstance(p, bool) or not isinstance(p, (int, float)) or not 0 <= p <= 1 for p in probabilities)
        ):
            d.fail(f"expected {len(items)} probabilities in [0, 1], one per value", "probabilities")
        if abs(sum(probabilities) - 1.0) > 1e-9:
            d.fail(f"expected probabilities summing to 1, got {sum(probabilities):g}", "probabilities")
        resolved["probabilities"] = np.asarray(probabilities, dtype=float)
    return resolved


def _check_uniform_so3(d):
    return {}


def _check_inertia(d):
    moments = d.vector("moments_sigma_fraction")
    axes = d.vector("axes_sigma_deg") if "axes_sigma_deg" in d.spec else np.zeros(3)
    if (moments < 0).any() or (moments >= 0.5).any():
        d.fail("expected 0 <= moments_sigma_fraction < 0.5", "moments_sigma_fraction")
    if (axes < 0).any() or (axes > MAX_AXES_SIGMA_DEG).any():
        d.fail(f"expected 0 <= axes_sigma_deg <= {MAX_AXES_SIGMA_DEG:g} [deg]", "axes_sigma_deg")
    return {"moments_sigma_fraction": moments, "axes_sigma_deg": axes}


# distribution -> its check: the resolved parameters (their support: distributions.support)
_CHECKS = {
    "constant": _check_constant,
    "normal": _check_normal,
    "truncnorm": _check_truncnorm,
    "uniform": _check_uniform,
    "lognormal": _check_lognormal,
    "choice": _check_choice,
    "uniform_so3": _check_uniform_so3,
    "inertia": _check_inertia,
}


def _check_support(param, path, vehicle, dist, support, fail):
    """Fail unless every draw of every component lies in the physical range of ``param``."""
    low, high = support
    for k in range(len(low)):
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


def _parameter_vector(spec, key, n, fail):
    """Distribution parameter ``key`` of ``spec``: a number (every component) or a list of ``n``."""
    value = spec[key]
    if isinstance(value, bool) or not isinstance(value, (int, float, list)):
        fail(f"expected a number or a list of {n} numbers, got {value!r}", key)
    if isinstance(value, list):
        if len(value) != n or any(isinstance(v, bool) or not isinstance(v, (int, float)) for v in value):
            fail(f"expected a number or a list of {n} numbers (one per component), got {value!r}", key)
        array = np.asarray(value, dtype=float)
    else:
        array = np.full(n, float(value))
    if not np.isfinite(array).all():
        fail(f"expected finite numbers, got {value!r}", key)
    return array


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
        missing = undeclared(path, vehicle, mission)
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
        n_params = 3 if dist == "inertia" else n  # inertia: one parameter per principal axis

        def vector(key, _n=n_params, _fail=fail, _spec=spec):
            return _parameter_vector(_spec, key, _n, _fail)

        dispersion = _Dispersion(spec, n, nominal(path, vehicle, mission), f" [{param.unit}]", fail, vector)
        resolved = _CHECKS[dist](dispersion)
        support = distributions.support({"dist": dist, **resolved})
        if support is not None:
            _check_support(param, path, vehicle, dist, support, fail)
        out[path] = {"dist": dist, **resolved}
    return out
