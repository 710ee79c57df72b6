"""The campaign key ``rare_event`` (docs/rare-events.md): an event on one run and the subset-simulation
study that estimates its probability (refexmc.campaign.rare_event, refexmc.campaign.subset).

An event is written like a requirement on one run, ``'METRIC OP VALUE'``: METRIC a numeric column
of the runs table, OP one of ``<= < >= >``. Its **margin** is the signed distance to VALUE in the
metric's unit, ``<= 0`` where the event happens: ``metric - VALUE`` for ``<=``/``<``, ``VALUE -
metric`` for ``>=``/``>``. A flight that failed keeps the margin of its flown value; a run with no
value (an errored run) has margin ``-inf``: it counts as the event, and the report says so. A
requirement on a runs column has the margin of the event that fails it (:func:`requirement_event`).
"""

import math
import re
from dataclasses import dataclass

import numpy as np

from refexmc.config.errors import ConfigError

EVENT_OPERATORS = ("<=", "<", ">=", ">")
MIN_CHAINS = 10  # fewer chains give no usable chain correlation (gamma) for the interval
DEFAULTS = {"method": "subset", "per_level": 1000, "p0": 0.1, "max_levels": 10, "proposal": "pcn"}
_EVENT = re.compile(r"^\s*(?P<metric>[^\s<>=!]+)\s*(?P<op>[<>=!]+)\s*(?P<value>\S+)\s*$")


@dataclass(frozen=True)
class Event:
    text: str
    metric: str
    op: str
    value: float

    def margins(self, values):
        """The signed margin of each value (numpy array; NaN, no value, gives -inf: the event)."""
        values = np.asarray(values, dtype=float)
        margin = values - self.value if self.op in ("<=", "<") else self.value - values
        return np.where(np.isnan(margin), -np.inf, margin)

    def describe(self):
        """'fuel_remaining <= 0' in words for a report heading."""
        return f"{self.metric} {self.op} {self.value:g}"


def parse_event(text, columns, file=None, line=None, path=(), absent=None):
    """The :class:`Event` of ``'METRIC OP VALUE'`` over the runs ``columns``; ConfigError for bad input,
    an event on a column the campaign does not produce too (``absent``: {column: why},
    requirements.unproduced_columns)."""
    where = {"file": file, "line": line, "path": path}
    match = _EVENT.match(text) if isinstance(text, str) else None
    if not match:
        raise ConfigError(f"expected an event 'METRIC OP VALUE' (e.g. 'fuel_remaining <= 0.0'), got {text!r}", **where)
    metric, op, value_text = match.group("metric", "op", "value")
    if op not in EVENT_OPERATORS:
        raise ConfigError(f"expected one of {' '.join(EVENT_OPERATORS)} in the event, got '{op}'", **where)
    try:
        value = float(value_text)
    except ValueError:
        raise ConfigError(f"expected a number after '{op}', got '{value_text}'", **where) from None
    if not math.isfinite(value):
        raise ConfigError(f"expected a finite number after '{op}', got '{value_text}'", **where)
    numeric = [c for c in columns if c not in ("run_id", "seed")]
    if absent and metric in absent:
        from refexmc.config.requirements import not_produced

        raise not_produced(f"event '{text.strip()}'", metric, absent, numeric, **where)
    if metric not in numeric:
        import difflib

        guess = difflib.get_close_matches(metric, numeric, n=1, cutoff=0.6)
        hint = f"did you mean '{guess[0]}'?" if guess else "expected a numeric column of the runs table"
        stat = " (an event is on one run: a column, not a statistic)" if "." in metric and guess else ""
        raise ConfigError(f"unknown metric '{metric}' in the event; {hint}{stat}", **where)
    return Event(text.strip(), metric, op, value)


def design_problem(per_level, p0):
    """Why ``per_level`` samples cannot make a study with ``p0`` (a sentence), or None."""
    if not 0.0 < p0 <= 0.5:
        return f"expected 0 < p0 <= 0.5, got {p0}"
    chains = p0 * per_level
    if chains < MIN_CHAINS:
        return (
            f"per_level {per_level} with p0 {p0} gives {chains:g} chains; at least {MIN_CHAINS} are needed "
            f"(per_level >= {math.ceil(MIN_CHAINS / p0)})"
        )
    if abs(chains - round(chains)) > 1e-9 or per_level % round(chains):
        return (
            f"per_level {per_level} with p0 {p0} does not split into chains of equal length: per_level * p0 "
            f"must be a whole number that divides per_level (e.g. per_level {round(chains) * round(1 / p0)})"
        )
    return None


def check_rare_event(data, campaign, columns, file, lines, absent=None):
    """The resolved ``rare_event`` of campaign file ``data`` (defaults filled in); ConfigError (file,
    line, key path) for a study that cannot be flown. Sets ``campaign['runs']`` to ``per_level``.
    ``columns``: the runs columns the campaign produces; ``absent``: as :func:`parse_event`."""
    spec = {**DEFAULTS, **data["rare_event"]}

    def fail(message, *key):
        line = next((lines[key[:k]] for k in range(len(key), 0, -1) if key[:k] in lines), None)
        raise ConfigError(message, file=file, line=line, path=key)

    event_line = lines.get(("rare_event", "event"))
    parse_event(spec["event"], columns, file, event_line, ("rare_event", "event"), absent)
    problem = design_problem(spec["per_level"], spec["p0"])
    if problem:
        fail(problem, "rare_event", "per_level" if "p0 <=" not in problem else "p0")
    if "sweep" in data:
        fail("rare_event does not go with a sweep (each point would be a study of its own)", "rare_event")
    sampling = data.get("sampling", "random")
    if sampling != "random":
        fail(
            f"rare_event needs sampling: random (level 0 is a random draw, the levels move it), got {sampling}",
            "sampling" if "sampling" in data else "rare_event",
        )
    if data.get("nominal_first", True):
        fail(
            "rare_event: level 0 is a random draw of per_level runs; set nominal_first: false",
            "nominal_first" if "nominal_first" in data else "rare_event",
        )
    if data.get("runs", spec["per_level"]) != spec["per_level"]:  # a resolved campaign says runs: per_level
        fail("rare_event flies per_level runs a level, as many levels as it needs; remove 'runs'", "runs")
    for key in ("failures", "wheel_failures"):
        if (data.get(key) or {}).get("mode") == "enumerate":
            fail("rare_event cannot move enumerated failures; use mode random or fixed", key, "mode")
    campaign["runs"] = spec["per_level"]
    return spec


_VIOLATION = {">=": "<", ">": "<=", "<=": ">", "<": ">="}  # a requirement's OP -> its failing run's


def requirement_event(requirement):
    """The event a run fails requirement ``METRIC.STAT OP VALUE`` by (a ``config.requirements.Requirement``
    on a runs column), so that its per-run margin is the requirement's: ``fuel_remaining.min >= 0.2``
    gives ``fuel_remaining < 0.2``, margin ``fuel_remaining - 0.2``. None for a campaign metric
    (``success_rate``) or ``==``, which have no per-run margin."""
    from refexmc.config.requirements import split_metric

    column, stat = split_metric(requirement.metric)
    if stat is None or requirement.op not in _VIOLATION:
        return None
    op = _VIOLATION[requirement.op]
    return Event(f"{column} {op} {requirement.value:g}", column, op, requirement.value)


def event_of(campaign, columns):
    """The :class:`Event` of a validated campaign's ``rare_event``."""
    return parse_event(campaign["rare_event"]["event"], columns)
