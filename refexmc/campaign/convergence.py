"""Step convergence of a campaign (``refexmc validate --convergence``, issue 33).

The campaign's nominal run (run 0 with ``nominal_first``: the design values, no failures) is
flown twice: with the mission's integration steps (``integrator.max_step_s``, and
``integrator.trajectory_step_s`` where a trajectory is integrated) and with a quarter of them.
For every requirement of the campaign the nominal run's value of its metric is compared: the
difference as a fraction of the requirement's margin (threshold minus the value at the
campaign's step). Past :data:`FRACTION_LIMIT` the step is too coarse for that requirement: the
verdict could depend on the integrator rather than on the design. A statistic of one run is the
run's value (``p99`` of one value is that value); the campaign metrics read the run's success or
error (1 or 0).

An entry campaign (``entry_flight``) integrates one RK4 step per control period, a step that is
part of the flight software's design, not an integration setting: it is not refined, and the
check says so.
"""

import copy
import math
from dataclasses import dataclass

from refexmc.config import pointing, requirements

FRACTION_LIMIT = 0.10  # a difference beyond 10 % of the margin warns (an error under --strict)
REFINEMENT = 4  # the refined run's steps are the campaign's / 4
STEP_KEYS = ("max_step_s", "trajectory_step_s")

_SUCCESS_METRICS = ("success_count", "success_rate", "success_rate_lower95", "success_rate_upper95")
_FAILURE_METRICS = ("failure_count", "failure_rate_upper95")
_ERROR_METRICS = ("error_count", "error_rate")


@dataclass(frozen=True)
class Comparison:
    """One requirement's metric on the nominal run at the campaign's step and at the refined one."""

    requirement: str
    coarse: float
    fine: float
    fraction: float  # |fine - coarse| / |threshold - coarse|; 0 when equal, inf on a zero margin

    @property
    def converged(self):
        return self.fraction <= FRACTION_LIMIT


def run_value(row, metric):
    """The nominal run's value of a requirement's ``metric`` from its runs ``row`` (a dict)."""
    column, _ = requirements.split_metric(metric)
    if column in _SUCCESS_METRICS:
        return float(bool(row["success"]))
    if column in _FAILURE_METRICS:
        return float(not row["success"])
    if column in _ERROR_METRICS:
        return float(row["status"] == "error")
    if column in ("runs", "ok_count"):
        return float(column == "runs" or row["status"] == "ok")
    if column == "pulses_total":
        return float(sum(value for name, value in row.items() if name.startswith("pulses_")))
    return float(row[column])


def fraction_of_margin(coarse, fine, threshold):
    """|fine - coarse| over |threshold - coarse| (0 when the two agree, NaNs included)."""
    if coarse == fine or (math.isnan(coarse) and math.isnan(fine)):
        return 0.0
    difference = abs(fine - coarse)
    margin = abs(threshold - coarse)
    if math.isnan(difference):
        return math.inf
    return difference / margin if margin > 0.0 else math.inf


def refined(campaign, factor=REFINEMENT):
    """A copy of ``campaign`` whose nominal run is run 0 and whose integration steps are divided by
    ``factor``; None for an entry campaign (its step is the control period)."""
    if "entry_flight" in campaign["mission"]:
        return None
    finer = copy.deepcopy(campaign)
    finer["nominal_first"] = True
    integrator = finer["mission"]["integrator"]
    for key in STEP_KEYS:
        if key in integrator:
            integrator[key] = integrator[key] / factor
    return finer


def _nominal_row(campaign):
    from refexmc.campaign.chunk import plan_for

    plan = plan_for(campaign)
    plan.load_kernels()
    row, _ = plan.fly_run(0, campaign["output"]["history_rate_hz"])
    return row


def step_convergence(campaign):
    """The :class:`Comparison` of each of the campaign's requirements, and the two runs rows
    (campaign's step, refined); None when the campaign has no integration step to refine."""
    fine_campaign = refined(campaign)
    if fine_campaign is None:
        return None
    coarse_campaign = refined(campaign, 1)
    coarse_row = _nominal_row(coarse_campaign)
    fine_row = _nominal_row(fine_campaign)
    comparisons = []
    records = {req.position: req for req in pointing.of_campaign(campaign)}
    for position, text in enumerate(campaign["requirements"]):
        if position in records:  # a pointing record: its own runs column against its bound
            req = records[position]
            coarse, fine = float(coarse_row[req.column]), float(fine_row[req.column])
            threshold = 1.0 - req.p_c if req.interpretation == "mixed" else req.bound  # mixed: time above
            comparisons.append(Comparison(req.text(), coarse, fine, fraction_of_margin(coarse, fine, threshold)))
            continue
        parsed = requirements.parse_requirement(text, list(coarse_row) + list(requirements.CAMPAIGN_METRICS))
        coarse = run_value(coarse_row, parsed.metric)
        fine = run_value(fine_row, parsed.metric)
        comparisons.append(Comparison(parsed.text, coarse, fine, fraction_of_margin(coarse, fine, parsed.value)))
    return comparisons, coarse_row, fine_row


def steps_text(campaign):
    """The integration steps compared, in words ('integrator.max_step_s 0.01 s against 0.0025 s')."""
    integrator = campaign["mission"]["integrator"]
    parts = [
        f"integrator.{key} {integrator[key]:g} s against {integrator[key] / REFINEMENT:g} s"
        for key in STEP_KEYS
        if key in integrator
    ]
    return ", ".join(parts)
