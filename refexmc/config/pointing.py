"""Pointing requirements of a campaign's ``requirements`` (ECSS-E-ST-60-10C; docs/pointing.md).

A record (``schema.POINTING_REQUIREMENT``) states an error index (APE, MPE, RPE, PDE, PRE; the
knowledge indices AKE, MKE, RKE, KDE, KRE where the mission models attitude knowledge error),
what |e| is (``error``), a bound with its unit, the probability P_C, the statistical
interpretation, the observation window, the verdict's confidence, the runs it judges and, for
the temporal interpretation, the fraction of runs that must meet it. Each becomes one row of the
core's ``layout.POINTING`` table, computed in the flight at the control rate (core.pointing), and
one runs-table column named ``<index>_<error>_<interpretation>[_<name>]_<unit>`` (``_fraction``
for the mixed interpretation). The verdict over runs is the report's (report.pointing).
"""

import math
from typing import NamedTuple

import numpy as np

from refexmc.config import schema
from refexmc.config.errors import ConfigError
from refexmc.core import layout as L

INDEX_IDS = {
    "APE": L.POINTING_INDEX_ABSOLUTE,
    "MPE": L.POINTING_INDEX_MEAN,
    "RPE": L.POINTING_INDEX_RELATIVE,
    "PDE": L.POINTING_INDEX_DRIFT,
    "PRE": L.POINTING_INDEX_REPRODUCIBILITY,
}
# the knowledge indices: the same statistic of e = estimated - true
INDEX_IDS.update(dict(zip(schema.KNOWLEDGE_INDICES, INDEX_IDS.values(), strict=True)))
INTERPRETATION_IDS = {
    "temporal": L.INTERPRETATION_TEMPORAL,
    "ensemble": L.INTERPRETATION_ENSEMBLE,
    "mixed": L.INTERPRETATION_MIXED,
}
UNITS = {"arcsec": math.pi / 180.0 / 3600.0, "deg": math.pi / 180.0}  # the bound's unit -> rad
BODY_AXES = {"x": (1.0, 0.0, 0.0), "y": (0.0, 1.0, 0.0), "z": (0.0, 0.0, 1.0)}
ALL_MODES = (1 << schema.MAX_MODES) - 1  # exact in a float64


class PointingRequirement(NamedTuple):
    """One pointing requirement as the campaign file states it (defaults filled)."""

    position: int  # its index in the campaign's requirements
    index: str
    error: str
    boresight: tuple | None  # error los: unit vector, body axes
    bound: float  # in ``unit``
    unit: str
    p_c: float
    interpretation: str
    window: dict  # modes (list or None), from_s, to_s
    delta_t_s: float  # inf: the observation period
    confidence: float
    runs: str  # all | failure_free
    runs_fraction: float
    column: str

    @property
    def knowledge(self):
        return self.index in schema.KNOWLEDGE_INDICES

    def text(self):
        """One line: ``APE(total) <= 0.4 arcsec, P_C 99.73 %, temporal, window science 14400-79200 s``."""
        window = describe_window(self.window)
        return (
            f"{self.index}({self.error}) <= {self.bound:g} {self.unit}, P_C {100 * self.p_c:g} %, "
            f"{self.interpretation}, window {window}, runs {self.runs}"
        )


class PointingPlan(NamedTuple):
    """What the flight computes: the core's table, the runs columns and each value's factor from
    the core's unit (rad; a fraction for mixed) to the column's."""

    table: np.ndarray
    columns: tuple
    scales: tuple


def describe_window(window):
    parts = []
    if window.get("modes"):
        parts.append("modes " + ", ".join(window["modes"]))
    start, end = window.get("from_s", 0.0), window.get("to_s", math.inf)
    if start > 0.0 or math.isfinite(end):
        parts.append(f"{start:g} s to {end:g} s" if math.isfinite(end) else f"from {start:g} s")
    return "; ".join(parts) or "the whole flight"


def is_pointing(item):
    """Whether a ``requirements`` entry is a pointing record (else a 'METRIC OP VALUE' string)."""
    return isinstance(item, dict)


def column_name(index, error, interpretation, unit, name=None):
    suffix = "fraction" if interpretation == "mixed" else unit
    return "_".join(filter(None, (index.lower(), error, interpretation, name, suffix)))


def navigation_modelled(mission, dispersions=()):
    """Whether the flight software's attitude differs from the truth: a bias, white or Gauss-Markov
    attitude error in the mission, or a dispersed ``navigation.attitude_*`` path."""
    nav = mission.get("navigation", {})
    declared = (
        any(v != 0.0 for v in nav.get("attitude_bias_deg", (0.0, 0.0, 0.0)))
        or nav.get("attitude_noise_deg", 0.0) > 0.0
        or nav.get("attitude_gm_sigma_deg", 0.0) > 0.0
    )
    return declared or any(str(key).startswith("navigation.attitude_") for key in dispersions)


def parse(requirements, mission, dispersions=(), file=None, lines=None):
    """The pointing records of a campaign's ``requirements``, checked (ConfigError with file, line
    and key path; ``load_campaign`` has validated each against ``schema.POINTING_REQUIREMENT``):
    one bound, a boresight for los only, window modes of the mission, window from < to,
    knowledge indices only where navigation is modelled, distinct columns."""
    lines = lines or {}
    mode_names = [mode["name"] for mode in mission["modes"]]
    parsed, columns = [], {}
    for position, item in enumerate(requirements):
        if not is_pointing(item):
            continue
        prefix = ("requirements", position)

        def fail(message, *path, prefix=prefix):
            full = prefix + path
            line = next((lines[full[:k]] for k in range(len(full), 0, -1) if full[:k] in lines), None)
            raise ConfigError(message, file=file, line=line, path=full)

        bounds = [key for key in ("bound_arcsec", "bound_deg") if key in item]
        if len(bounds) != 1:
            fail("expected one bound: bound_arcsec or bound_deg", *(bounds[1:2] or []))
        unit = bounds[0].removeprefix("bound_")
        error = item["error"]
        boresight = None
        if error == "los":
            if "boresight" not in item:
                fail("error los needs a boresight (body axes)", "error")
            b = np.asarray(item["boresight"], dtype=float)
            norm = math.sqrt(float(b[0] * b[0] + b[1] * b[1] + b[2] * b[2]))
            if norm == 0.0:
                fail("expected a non-zero boresight", "boresight")
            boresight = tuple(float(v / norm) for v in b)
        elif "boresight" in item:
            fail(f"a boresight is for error los; error is {error}", "boresight")
        window = dict(item["window"])
        for j, name in enumerate(window.get("modes", [])):
            if name not in mode_names:
                fail(f"no mode '{name}' in the mission (modes: {', '.join(mode_names)})", "window", "modes", j)
        start, end = window.get("from_s", 0.0), window.get("to_s", math.inf)
        if not start < end:
            fail(f"expected from_s < to_s, got {start:g} and {end:g}", "window", "to_s")
        window.setdefault("from_s", 0.0)
        window.setdefault("to_s", math.inf)
        window.setdefault("modes", None)
        index = item["index"]
        if index in schema.KNOWLEDGE_INDICES and not navigation_modelled(mission, dispersions):
            fail(
                f"{index} is a knowledge index: the mission models no attitude knowledge error "
                "(navigation.attitude_bias_deg, attitude_noise_deg, attitude_gm_sigma_deg, or a dispersed "
                "navigation.attitude_* path)",
                "index",
            )
        if "delta_t_s" in item and INDEX_IDS[index] in (L.POINTING_INDEX_ABSOLUTE, L.POINTING_INDEX_REPRODUCIBILITY):
            fail(f"delta_t_s is the averaging interval of MPE, RPE, PDE (MKE, RKE, KDE), not of {index}", "delta_t_s")
        interpretation = item["interpretation"]
        column = column_name(index, error, interpretation, unit, item.get("name"))
        if column in columns:
            fail(f"requirements {columns[column]} and {position} make the same column '{column}'; give one a 'name'")
        columns[column] = position
        parsed.append(
            PointingRequirement(
                position=position,
                index=index,
                error=error,
                boresight=boresight,
                bound=float(item[bounds[0]]),
                unit=unit,
                p_c=float(item["p_c"]),
                interpretation=interpretation,
                window=window,
                delta_t_s=float(item.get("delta_t_s", math.inf)),
                confidence=float(item.get("confidence", 0.95)),
                runs=item.get("runs", "all"),
                runs_fraction=float(item.get("runs_fraction", 0.99)),
                column=column,
            )
        )
    return parsed


def of_campaign(campaign):
    """The pointing requirements of a validated campaign (``load_campaign``'s)."""
    return parse(campaign.get("requirements", []), campaign["mission"], campaign.get("dispersions", {}))


def plan(requirements, mission):
    """The core's table (``layout.POINTING`` rows), the runs columns and their scales."""
    mode_names = [mode["name"] for mode in mission["modes"]]
    table = np.zeros((len(requirements), L.POINTING_SIZE))
    scales = []
    for r, req in enumerate(requirements):
        row = table[r]
        row[L.P_INDEX] = INDEX_IDS[req.index]
        row[L.P_KNOWLEDGE] = 1.0 if req.knowledge else 0.0
        if req.error == "total":
            row[L.P_ERROR] = L.ERROR_TOTAL
        elif req.error == "los":
            row[L.P_ERROR] = L.ERROR_LOS
            row[L.P_AXIS : L.P_AXIS + 3] = req.boresight
        else:
            row[L.P_ERROR] = L.ERROR_AXIS
            row[L.P_AXIS : L.P_AXIS + 3] = BODY_AXES[req.error]
        row[L.P_WINDOW_FROM] = req.window["from_s"]
        row[L.P_WINDOW_TO] = req.window["to_s"]
        modes = req.window["modes"]
        row[L.P_MODE_MASK] = ALL_MODES if not modes else sum(1 << mode_names.index(m) for m in modes)
        row[L.P_DELTA_T] = req.delta_t_s
        row[L.P_INTERPRETATION] = INTERPRETATION_IDS[req.interpretation]
        row[L.P_PROBABILITY] = req.p_c
        row[L.P_BOUND] = req.bound * UNITS[req.unit]
        scales.append(1.0 if req.interpretation == "mixed" else 1.0 / UNITS[req.unit])
    return PointingPlan(table, tuple(req.column for req in requirements), tuple(scales))
