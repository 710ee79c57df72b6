"""Fly a chunk of an entry campaign (issue 24, docs/x38.md): ``core.entry_flight`` through
``simulate.fly_entry``, one run per row of the runs table.

The plan has :class:`chunk.RunPlan`'s interface (``prepare_runs``, ``fly_run``, ``fly``,
``error_row``, ``load_kernels``, ``param_columns``), so the backends fly it alike. Run i's inputs
derive from (campaign seed, run id, parameter path) alone, drawn by ``campaign.sampling.Sampler``.
The flight software keeps the vehicle file's density, coefficient tables and inertia; the
dispersions set the truth (``config.entry.entry_vehicle``: ``density_factor``,
``coefficient_factors``, ``inertia``).
"""

import copy

import numpy as np

from refexmc import distributions, simulate
from refexmc.campaign.sampling import Sampler
from refexmc.campaign.seeding import run_seed
from refexmc.config import dispersions, entry
from refexmc.config.requirements import ENTRY_COLUMNS

_SCALE = "entry_flight.coefficient_scale."


class EntryRun:
    """A flown entry with the history columns the campaign stores."""

    def __init__(self, result, history_every):
        self.result = result
        self.mode_names = list(entry.MODE_NAMES)
        self.every = history_every

    def history_columns(self):
        """History signals by column name (``simulate.EntryResult.history_columns``)."""
        return self.result.history_columns(self.every)


class EntryRunPlan:
    """Everything needed to fly any run of an entry campaign, built once per chunk."""

    def __init__(self, campaign):
        self.campaign = campaign
        self.sampler = Sampler(campaign)
        self.vehicle, self.mission = campaign["vehicle"], campaign["mission"]
        rate = campaign["output"]["history_rate_hz"]
        self.history_every = max(1, int(round(1.0 / rate)))  # the kernel records one row per second
        self.mode_names = list(entry.MODE_NAMES)

    def load_kernels(self):
        """Compile (or load from numba's disk cache) the entry kernel by flying nothing: the first
        run pays it otherwise."""
        simulate.load_entry_kernel(*entry.entry_flight_from_mission(self.vehicle, self.mission))

    def param_columns(self):
        return [c for path in self.sampler.specs for c in dispersions.columns(path, self.vehicle)]

    def prepare_runs(self, run_ids):
        """(seed, p-columns, (flown vehicle, initial state)) of each run, or its exception."""
        drawn = self.sampler.values_or_exceptions(run_ids)
        return [self._prepared(run_id, values) for run_id, values in zip(run_ids, drawn, strict=True)]

    def _prepared(self, run_id, values):
        if isinstance(values, Exception):
            return values
        try:
            flight = self.flight(values)
        except Exception as exc:  # noqa: BLE001 - that run becomes an error row
            return exc
        return run_seed(self.campaign["seed"], run_id), self.sampler.columns(values), flight

    def flight(self, values):
        """(``core.entry_flight.EntryVehicle``, initial state) with the drawn ``values`` ({path: values})."""
        vehicle, mission = self.vehicle, self.mission
        density, factors, inertia = 1.0, {}, None
        if any(path in ("mass_kg",) or path.startswith("entry_flight.state.") for path in values) or (
            "entry_flight.blocked_flap.deflection_deg" in values or "entry_flight.rcs_delay_ms" in values
        ):
            vehicle, mission = copy.deepcopy(vehicle), copy.deepcopy(mission)
        for path, value in values.items():
            if path == "inertia_kg_m2":  # the truth's; the flight software keeps the vehicle file's
                inertia = distributions.inertia_matrix(np.atleast_1d(value))
                continue
            number = float(np.atleast_1d(value)[0])
            if path == "mass_kg":
                vehicle["mass_kg"] = number
            elif path == "entry_flight.density_scale":
                density = number
            elif path.startswith(_SCALE):
                factors[path[len(_SCALE) :]] = number
            else:  # entry_flight.state.<key>, entry_flight.blocked_flap.deflection_deg, entry_flight.rcs_delay_ms
                node = mission
                keys = path.split(".")
                for key in keys[:-1]:
                    node = node[key]
                node[keys[-1]] = number
        return entry.entry_flight_from_mission(
            vehicle, mission, density_factor=density, coefficient_factors=factors, inertia=inertia
        )

    def _row(self, run_id, seed, params, result=None, error=None):
        row = {
            "run_id": run_id,
            "seed": seed,
            "status": "error" if error else "ok",
            "success": False if result is None else result.success,
            "failure_reason": error if result is None else result.failure_reason,
        }
        values = result.runs_values() if result is not None else dict.fromkeys(ENTRY_COLUMNS, float("nan"))
        row.update(values)
        row.update(params)
        return row

    def error_row(self, run_id, reason):
        """The runs row of a run without a result (it raised, hung, or crashed its worker)."""
        (prepared,) = self.prepare_runs([run_id])
        params = dict.fromkeys(self.param_columns(), float("nan"))
        if not isinstance(prepared, Exception):
            params = prepared[1]
        return self._row(run_id, run_seed(self.campaign["seed"], run_id), params, error=reason)

    def fly_run(self, run_id, history_rate_hz, prepared=None):
        """(runs row, EntryRun); an error gives an error row and None."""
        try:
            if prepared is None:
                (prepared,) = self.prepare_runs([run_id])
            if isinstance(prepared, Exception):
                raise prepared
            seed, params, (flown, initial) = prepared
            result = simulate.fly_entry(flown, initial)
            values = result.runs_values()
            reason = next((f"non-finite {k} in the summary" for k, v in values.items() if not np.isfinite(v)), None)
        except Exception as exc:  # noqa: BLE001 - one bad run must not stop the campaign
            reason = f"{type(exc).__name__}: {exc}"
        if reason is not None:
            return self.error_row(run_id, reason), None
        return self._row(run_id, seed, params, result), EntryRun(result, self.history_every)

    def fly(self, run_id, history_rate_hz, prepared=None):
        from refexmc.campaign import storage

        row, run = self.fly_run(run_id, history_rate_hz, prepared)
        return row, None if run is None else storage.histories_table([run_id], [run]), run
