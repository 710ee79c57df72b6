"""The plan a worker flies a round of a rare-event study with (refexmc.campaign.rare_event): the
campaign's :class:`refexmc.campaign.chunk.RunPlan` whose sampler takes the round's uniforms and
whose rows carry ``level``, ``chain``, ``step`` and the event's ``margin``.

``chunk.plan_for`` builds it for a campaign with ``rare_event`` (:func:`study_plan_for`, given the
RunPlan class: this module imports no flying machinery, so that none imports it back).
"""

import functools
import math
import pickle

import numpy as np

from refexmc.campaign import storage
from refexmc.campaign.sampling import _TINY, Sampler, keyed_uniforms_for_runs
from refexmc.config.rare_event import event_of

ROUND_KEY = "_rare_event_round"  # the round a chunk belongs to, in the campaign a worker gets (never stored)


def failure_block(kind):
    """The name of the uniforms behind a campaign's random ``kind`` failures (count, then one per unit)."""
    return f"{kind.key}.uniforms"


def failed_from_uniforms(u, count_probabilities):
    """Failed unit ids (1-based, ascending): the count from u[0], the set the units of smallest u[1:]."""
    cumulative = np.cumsum(count_probabilities)
    count = min(int(np.searchsorted(cumulative, u[0], side="right")), len(cumulative) - 1)
    return tuple(sorted(int(k) + 1 for k in np.argsort(u[1:], kind="stable")[:count]))


class StudySampler(Sampler):
    """The campaign's sampler, with the uniforms of a round's proposals given (``uniforms``: {run id:
    {block: uniforms}}) and random failures drawn from uniforms as well."""

    def __init__(self, campaign, uniforms=None):
        super().__init__(campaign)
        self.given = uniforms or {}

    def uniforms_for_runs(self, path, run_ids, count):
        if count == 0 or not any(run_id in self.given for run_id in run_ids):  # a constant draws none
            if path.endswith(".uniforms"):  # a failure block: keyed like a dispersion
                return np.clip(keyed_uniforms_for_runs(self.seed, run_ids, path, count), _TINY, 1.0 - _TINY)
            return super().uniforms_for_runs(path, run_ids, count)
        return np.array([self.given[run_id][path] for run_id in run_ids]).reshape(len(run_ids), count)

    def _failed_units(self, failures, kind, n_units, sets, run_id):
        if failures["mode"] != "random":
            return super()._failed_units(failures, kind, n_units, sets, run_id)
        u = self.uniforms_for_runs(failure_block(kind), [run_id], 1 + n_units)[0]
        return failed_from_uniforms(u, failures["count_probabilities"])


LEVEL0_ROUND = {"level": 0, "step": 0, "chains": {}, "uniforms": {}}


class StudyPlanMixin:
    """Mixed into :class:`refexmc.campaign.chunk.RunPlan` (:func:`study_plan_class`): a round's plan."""

    def __init__(self, campaign):
        study_round = campaign.get(ROUND_KEY) or LEVEL0_ROUND
        campaign = {key: value for key, value in campaign.items() if key != ROUND_KEY}
        super().__init__(campaign)
        self.event = event_of(campaign, storage.output_names(campaign)["columns"]["runs"])
        self.set_round(study_round)

    def set_round(self, study_round):
        """Fly round ``study_round`` (level, step, chains and uniforms by run id) from now on."""
        self.round = study_round
        self.sampler = StudySampler(self.campaign, study_round["uniforms"])

    def _study_columns(self, run_id, row):
        level = self.round["level"]
        chain = run_id if level == 0 else self.round["chains"][run_id]
        margin = float(self.event.margins([row.get(self.event.metric, math.nan)])[0])
        if row["status"] == "error":
            margin = -math.inf  # no value of its own: it counts as the event (the report says so)
        row.update({"level": level, "chain": chain, "step": self.round["step"], "margin": margin})
        return row

    def fly_run(self, run_id, history_rate_hz, prepared=None):
        row, result = super().fly_run(run_id, history_rate_hz, prepared)
        return self._study_columns(run_id, row), result

    def error_row(self, run_id, reason):
        return self._study_columns(run_id, super().error_row(run_id, reason))


_last_study_plan = (None, None)  # (the campaign's pickle without its round, its StudyRunPlan)


@functools.cache
def study_plan_class(run_plan):
    """``StudyRunPlan``: :class:`StudyPlanMixin` over ``run_plan`` (chunk.RunPlan)."""
    return type("StudyRunPlan", (StudyPlanMixin, run_plan), {})


def study_plan_for(campaign, run_plan):
    """The :class:`StudyRunPlan` of a round's campaign: built once per study in a worker (3-6 ms and
    a pack), then given each round's uniforms (``chunk.plan_for`` for a rare-event campaign)."""
    global _last_study_plan
    base = {key: value for key, value in campaign.items() if key != ROUND_KEY}
    key = pickle.dumps(base, protocol=pickle.HIGHEST_PROTOCOL)
    if _last_study_plan[0] != key:
        _last_study_plan = (key, study_plan_class(run_plan)(base))
    plan = _last_study_plan[1]
    plan.set_round(campaign.get(ROUND_KEY) or LEVEL0_ROUND)
    return plan
