"""Fly a chunk of runs: the unit of work every execution backend hands to a worker.

``fly_chunk(campaign, run_ids)`` depends only on the validated campaign and the run ids, never
on the worker, the chunking or the order: run i's inputs derive from (campaign seed, run id,
parameter path) alone (``refexmc.campaign.sampling``).
"""

import contextlib
import pickle

from refexmc import simulate
from refexmc.campaign import storage
from refexmc.campaign.sampling import Sampler
from refexmc.campaign.seeding import run_seed
from refexmc.config import dispersions, pointing, requirements
from refexmc.config.pack import mode_names, pack


class RunPlan:
    """Everything needed to fly any run of a campaign, built once per chunk."""

    def __init__(self, campaign):
        self.campaign = campaign
        self.sampler = Sampler(campaign)
        self.nominal_inputs = pack(campaign["vehicle"], campaign["mission"])
        self._wheel_failure_inputs = {(): self.nominal_inputs}
        self.n_thrusters = self.nominal_inputs.thrusters.shape[0]
        self.mode_names = mode_names(campaign["mission"])
        options = requirements.column_options(campaign["vehicle"], campaign["mission"])
        self.value_columns = requirements.run_value_columns(self.mode_names, **options)
        # pointing requirements, computed in the flight (config.pointing): one runs column each
        self.pointing = pointing.plan(pointing.of_campaign(campaign), campaign["mission"])
        self.value_columns += list(self.pointing.columns)
        self.wheels = options["wheels"]  # the runs table has a failed_wheels column
        self.family = simulate.flight_family(self.nominal_inputs)  # every run's: dispersions keep it
        self._warm_up()

    def _warm_up(self):
        """Draw one dispersed run once: scipy imports and LHS/Sobol designs happen here, not in a run.

        A worker builds its plan outside the wall-time watch, so that a run's time limit counts
        its own work only (under load, importing scipy.stats.qmc alone can take a second).
        """
        if self.sampler.n_dispersed > 0:
            with contextlib.suppress(Exception):  # that run raises again when flown: an error row
                self.sampler.values(self.sampler.offset)

    def load_kernels(self):
        """Load the flight kernel of the campaign's vehicle family (and only that) from numba's
        disk cache, compiling it if it is not there: a worker does it before it flies."""
        simulate.load_kernels([self.family])

    def inputs_with_failed_wheels(self, failed_wheels):
        """The undispersed inputs with ``failed_wheels`` (1-based ids) failed, and left out of the
        distribution when the campaign's wheel failures are detected; packed once per set."""
        if failed_wheels not in self._wheel_failure_inputs:
            detected = failed_wheels if self.sampler.wheel_failures_detected() else ()
            self._wheel_failure_inputs[failed_wheels] = pack(
                self.campaign["vehicle"],
                self.campaign["mission"],
                failed_wheels=failed_wheels,
                detected_wheels=detected,
            )
        return self._wheel_failure_inputs[failed_wheels]

    def prepare(self, run_id):
        """(nav seed, failures, p-columns, packed inputs) of run ``run_id``; failures: a
        ``storage.Failures`` (failed thruster and wheel ids)."""
        (prepared,) = self.prepare_runs([run_id])
        if isinstance(prepared, Exception):
            raise prepared
        return prepared

    def prepare_runs(self, run_ids):
        """:meth:`prepare` of each of ``run_ids``, their parameters drawn together and their inputs
        dispersed together, a group per set of failed wheels (the same numbers as alone); a run
        whose preparation raised gets the exception instead."""
        drawn = self.sampler.values_or_exceptions(run_ids)
        prepared = [self._failures(run_id, values) for run_id, values in zip(run_ids, drawn, strict=True)]
        groups = {}  # failed wheels -> the indices of the runs without an exception so far
        for k, entry in enumerate(prepared):
            if not isinstance(entry, Exception):
                groups.setdefault(entry.wheels, []).append(k)
        for failed_wheels, members in groups.items():
            thrusters = [prepared[k].thrusters for k in members]
            dispersed = self._inputs(failed_wheels, [drawn[k] for k in members], thrusters)
            columns = self.sampler.columns_for_runs([drawn[k] for k in members])
            for k, inputs, params in zip(members, dispersed, columns, strict=True):
                if isinstance(inputs, Exception):
                    prepared[k] = inputs
                else:
                    prepared[k] = (run_seed(self.campaign["seed"], run_ids[k]), prepared[k], params, inputs)
        return prepared

    def _failures(self, run_id, values):
        """The run's ``storage.Failures``, or the exception of its draw or of drawing them."""
        if isinstance(values, Exception):
            return values
        try:
            failed_wheels = self.sampler.failed_wheels(run_id)
            return storage.Failures(self.sampler.failed(run_id), failed_wheels)
        except Exception as exc:  # noqa: BLE001 - that run becomes an error row
            return exc

    def _inputs(self, failed_wheels, runs_values, runs_thrusters):
        """The dispersed inputs of runs with the same failed wheels and ``runs_thrusters`` failed
        (``Sampler.inputs_for_runs``); where that raises, each run's alone, a run that raises
        getting its exception."""
        try:
            nominal = self.inputs_with_failed_wheels(failed_wheels)
        except Exception as exc:  # noqa: BLE001 - those runs become error rows
            return [exc] * len(runs_values)
        try:
            return self.sampler.inputs_for_runs(nominal, runs_values, runs_thrusters)
        except Exception:  # noqa: BLE001 - let each run raise it alone
            return [
                self._inputs_or_exception(nominal, values, failed)
                for values, failed in zip(runs_values, runs_thrusters, strict=True)
            ]

    def _inputs_or_exception(self, nominal, values, failed):
        try:
            return self.sampler.inputs(nominal, values, failed)
        except Exception as exc:  # noqa: BLE001 - that run becomes an error row
            return exc

    @staticmethod
    def failure_reason(exc):
        """The error row's reason of a run whose preparation or flight raised ``exc``."""
        return f"{type(exc).__name__}: {exc}"

    def error_row(self, run_id, reason):
        """The runs row of a run without a result of its own (it raised, hung, or crashed its worker).

        Its seed, failed thrusters and wheels and ``p.<path>`` values are drawn again (cheap, deterministic),
        so that the row has every column of the table.
        """
        try:
            seed, failed, params, _ = self.prepare(run_id)
        except Exception:  # noqa: BLE001 - the row is still recorded, without its parameters
            seed, failed, params = run_seed(self.campaign["seed"], run_id), storage.Failures(), {}
        row = storage.runs_row(
            run_id, seed, failed, None, self.value_columns, self.n_thrusters, error=reason, wheels=self.wheels
        )
        row.update(params or dict.fromkeys(self.param_columns(), float("nan")))
        return row

    def fly(self, run_id, history_rate_hz, prepared=None):
        """(runs row, history table, FlightResult); an error gives an error row and no history/result.
        ``prepared``: the run's :meth:`prepare_runs` entry, when drawn with others."""
        row, result = self.fly_run(run_id, history_rate_hz, prepared)
        return row, None if result is None else storage.history_table(run_id, result), result

    def fly_run(self, run_id, history_rate_hz, prepared=None):
        """(runs row, FlightResult) of :meth:`fly`, without the history table (a chunk builds one
        for all its runs: ``storage.histories_table``); an error gives an error row and None."""
        try:
            if prepared is None:
                prepared = self.prepare(run_id)
            if isinstance(prepared, Exception):
                raise prepared
            seed, failed, params, inputs = prepared
            result = simulate.fly(inputs, seed, history_rate_hz, mode_names=self.mode_names, requirements=self.pointing)
        except Exception as exc:  # noqa: BLE001 - one bad run must not stop the campaign
            return self.error_row(run_id, self.failure_reason(exc)), None
        return self.result_row(run_id, prepared, result)

    def result_row(self, run_id, prepared, result):
        """(runs row, FlightResult) of a run flown from ``prepared`` (on any backend); an error row
        and None when its state is not finite."""
        try:
            seed, failed, params, _ = prepared
            reason = result.non_finite_reason()
        except Exception as exc:  # noqa: BLE001 - one bad run must not stop the campaign
            reason = f"{type(exc).__name__}: {exc}"
        if reason is not None:
            return self.error_row(run_id, reason), None
        row = storage.runs_row(run_id, seed, failed, result, self.value_columns, self.n_thrusters, wheels=self.wheels)
        row.update(params)
        return row, result

    def param_columns(self):
        return [c for path in self.sampler.specs for c in dispersions.columns(path, self.campaign["vehicle"])]


_last_plan = (None, None)  # (the campaign's pickle, its RunPlan): reused by a worker's later chunks


def plan_for(campaign):
    """The RunPlan of ``campaign``, reused while the same campaign comes back.

    Every task brings the worker its own unpickled copy of the campaign, so the plan is kept by
    the campaign's content (its pickle, ~0.1 ms), not by the object: building a plan costs
    3-6 ms, a fifth of a millisecond per run of a 32-run chunk.
    """
    global _last_plan
    if "rare_event" in campaign:  # a rare-event study's round (issue 36): rows with level, chain, step, margin
        from refexmc.campaign.study_plan import study_plan_for

        return study_plan_for(campaign, RunPlan)
    key = pickle.dumps(campaign, protocol=pickle.HIGHEST_PROTOCOL)
    if _last_plan[0] != key:
        if "entry_flight" in campaign["mission"]:  # an entry campaign (issue 24): core.entry_flight
            from refexmc.campaign.entry_plan import EntryRunPlan

            _last_plan = (key, EntryRunPlan(campaign))
        else:
            _last_plan = (key, RunPlan(campaign))
    return _last_plan[1]


def fly_chunk(campaign, run_ids):
    """Fly ``run_ids``; return (runs rows as dicts, the history table of the runs that flew, or None
    when none did). A run that raises is an error row."""
    plan = plan_for(campaign)
    plan.load_kernels()
    rate = campaign["output"]["history_rate_hz"]
    rows, flown = [], {}
    for run_id, prepared in zip(run_ids, plan.prepare_runs(run_ids), strict=True):
        row, result = plan.fly_run(run_id, rate, prepared)
        rows.append(row)
        if result is not None:
            flown[run_id] = result
    return rows, storage.histories_table(list(flown), list(flown.values())) if flown else None
