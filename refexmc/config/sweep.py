"""The campaign key ``sweep``: one or two vehicle or mission parameters varied over listed values
or a range, each point a full Monte-Carlo campaign (docs/studies.md).

```yaml
sweep:
  axes:
    - parameter: rcs.propellant_kg      # a scalar path of the dispersion table, set in the vehicle or mission
      values: [0.45, 0.5, 0.6]         # or range: {start: 0.45, stop: 0.8, count: 8}
    - parameter: rcs.thrust_scale       # or a parameter of a path's distribution (a second axis: a grid)
      dispersion: sigma
      values: [0.01, 0.02, 0.04]
  metrics: [fuel_remaining]             # runs columns whose percentiles the report draws against the point
```

A point's campaign is the campaign with the point's value written into the vehicle or mission
file (so run 0 is the nominal flight at that point) and a ``constant`` dispersion of the path at
that value (so every run records it in its ``p.<path>`` column); every other draw is the same at
every point (keyed seeds: common random numbers).
"""

import copy
import itertools
import math

import numpy as np

from refexmc.config import dispersions
from refexmc.config.errors import ConfigError, did_you_mean
from refexmc.config.parameters import MISSION_ROOTS  # paths under these are mission keys
from refexmc.config.requirements import not_produced, unproduced_columns
from refexmc.config.schema import SWEPT_DISTRIBUTION_PARAMETERS

DEFAULT_METRICS = ("fuel_remaining", "attitude_error_end_deg", "rcs_propellant_kg")  # those the runs table has


def _part(path):
    return "mission" if path.split(".")[0] in MISSION_ROOTS else "vehicle"


def file_value(campaign, path):
    """The value of ``path`` in the campaign's vehicle or mission file, its schema default where
    the file has the key's block but omits the key (KeyError when it has none)."""
    node = campaign[_part(path)]
    try:
        for key in path.split("."):
            node = node[key]
    except KeyError:
        node = dispersions.omitted_default(dispersions.parameter(path), campaign[_part(path)])
    if isinstance(node, bool) or not isinstance(node, (int, float)):
        raise KeyError(path)
    return float(node)


def axis_values(axis):
    """The values of one axis: ``values`` as given, or ``range`` as count evenly spaced values."""
    if "values" in axis:
        return [float(v) for v in axis["values"]]
    spec = axis["range"]
    return [float(v) for v in np.linspace(spec["start"], spec["stop"], spec["count"])]


def axis_name(axis):
    """``rcs.propellant_kg`` for a file value, ``rcs.isp_s:sigma`` for a dispersion's parameter."""
    return f"{axis['parameter']}:{axis['dispersion']}" if "dispersion" in axis else axis["parameter"]


def points(campaign):
    """[{axis name: value}] of every point, the last axis varying fastest."""
    axes = campaign["sweep"]["axes"]
    grid = itertools.product(*(axis_values(axis) for axis in axes))
    return [dict(zip((axis_name(axis) for axis in axes), values, strict=True)) for values in grid]


def point_campaign(campaign, index, values):
    """The plain campaign of point ``index`` (values: {axis name: value}); see the module docstring.

    An axis on a dispersion's parameter (``dispersion: sigma``) sets that parameter, for every
    component; an axis on a file value sets it in the vehicle or mission file and records it as a
    ``constant`` dispersion."""
    point = copy.deepcopy({key: value for key, value in campaign.items() if key != "sweep"})
    point["name"] = f"{campaign['name']}-point-{index:03d}"
    axes = {axis_name(axis): axis for axis in campaign["sweep"]["axes"]}
    for name, value in values.items():
        path = axes[name]["parameter"]
        if "dispersion" in axes[name]:
            point["dispersions"] = {
                **point["dispersions"],
                path: {**point["dispersions"][path], axes[name]["dispersion"]: value},
            }
            continue
        node = point[_part(path)]
        keys = path.split(".")
        for key in keys[:-1]:
            node = node[key]
        node[keys[-1]] = value
        point["dispersions"] = {**point["dispersions"], path: {"dist": "constant", "value": value}}
    return point


def _check_dispersion_axis(campaign, i, axis, fail, file):
    """A sweep of a dispersion's parameter: the path is dispersed with a distribution that has it,
    and every point's distribution passes the dispersion checks (its support, sec. 3)."""
    path, name = axis["parameter"], axis["dispersion"]
    spec = campaign["dispersions"].get(path)
    if spec is None:
        fail(f"'{path}' is not dispersed: 'dispersion: {name}' sweeps a parameter of its distribution", "axes", i)
    required, optional = dispersions.DISTRIBUTIONS.get(spec.get("dist"), ((), ()))
    if name not in SWEPT_DISTRIBUTION_PARAMETERS or name not in (*required, *optional):
        allowed = [p for p in (*required, *optional) if p in SWEPT_DISTRIBUTION_PARAMETERS]
        fail(
            f"'{spec.get('dist')}' has no parameter '{name}' to sweep; expected one of: {', '.join(allowed)}",
            "axes",
            i,
            "dispersion",
        )
    for value in axis_values(axis):
        trial = {**campaign["dispersions"], path: {**spec, name: value}}
        try:
            dispersions.check(trial, campaign["vehicle"], campaign["mission"], file, {})
        except ConfigError as exc:
            fail(f"at {name} = {value:g}: {exc.message}", "axes", i)


def check_sweep(campaign, file=None, lines=None, columns=(), absent=None):
    """ConfigError (file, line, key path) unless the campaign's ``sweep`` can be flown; ``columns``:
    the runs columns it produces, ``absent``: {column: why} of those its table has but never fills
    (requirements.unproduced_columns)."""
    lines = lines or {}
    absent = absent or {}
    sweep = campaign["sweep"]

    def fail(message, *path):
        key_path = ("sweep", *path)
        line = next((lines[key_path[:n]] for n in range(len(key_path), 0, -1) if key_path[:n] in lines), None)
        raise ConfigError(message, file=file, line=line, path=key_path)

    seen = set()
    for i, axis in enumerate(sweep["axes"]):
        path = axis["parameter"]
        if axis_name(axis) in seen:
            fail(f"'{axis_name(axis)}' is swept twice", "axes", i, "parameter")
        seen.add(axis_name(axis))
        if ("values" in axis) == ("range" in axis):
            fail("expected exactly one of 'values' and 'range'", "axes", i)
        if "range" in axis and not all(math.isfinite(axis["range"][k]) for k in ("start", "stop")):
            fail("expected finite start and stop", "axes", i, "range")
        if "dispersion" in axis:
            _check_dispersion_axis(campaign, i, axis, fail, file)
            continue
        param = dispersions.parameter(path)
        if param is None or param.shape != "scalar":
            scalar = [p for p, q in dispersions.PARAMETERS.items() if q.shape == "scalar"]
            hint = did_you_mean(path, scalar, cutoff=0.5) if param is None else ""  # as for dispersion paths
            if hint:
                fail(f"unknown parameter path '{path}'; {hint}", "axes", i, "parameter")
            fail(f"expected a scalar parameter path ({', '.join(scalar)}), got '{path}'", "axes", i, "parameter")
        try:
            file_value(campaign, path)
        except (KeyError, TypeError):
            why = dispersions.undeclared(path, campaign["vehicle"], campaign["mission"])  # e.g. a constant feed
            fail(why or f"the {_part(path)} file has no value at '{path}' to sweep", "axes", i, "parameter")
        if path in campaign["dispersions"]:
            fail(f"'{path}' is swept and dispersed; remove it from dispersions", "axes", i, "parameter")
        for value in axis_values(axis):
            if not dispersions.in_range(param, value):
                key = "values" if "values" in axis else "range"
                fail(
                    f"{value:g} is outside the physical range of '{path}' ({dispersions.range_text(param)})",
                    "axes",
                    i,
                    key,
                )
    for j, metric in enumerate(sweep.get("metrics", [])):
        if metric in absent:
            fail(not_produced(f"sweep metric '{metric}'", metric, absent, columns).message, "metrics", j)
        if metric not in columns:
            fail(f"expected a runs column, got '{metric}'{_column_hint(metric, columns)}", "metrics", j)


def _column_hint(metric, columns):
    """'; did you mean ...?' or the campaign's own columns (a mode's columns carry its name)."""
    own = [c for c in columns if not c.startswith("p.")]
    hint = did_you_mean(metric, own)
    if hint:
        return f"; {hint}"
    return f"; this campaign's columns (and its p. inputs): {', '.join(own)}"


def metrics(campaign, columns):
    """The runs columns the report draws against the swept value: the listed ones, else those of
    ``DEFAULT_METRICS`` the campaign produces (``columns``, less requirements.unproduced_columns)."""
    listed = campaign["sweep"].get("metrics")
    if listed is not None:
        return list(listed)
    mission = campaign["mission"]
    absent = {} if "entry_flight" in mission else unproduced_columns(campaign["vehicle"], mission)
    return [c for c in DEFAULT_METRICS if c in columns and c not in absent]
