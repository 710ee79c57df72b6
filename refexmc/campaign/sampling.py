"""Each run's dispersed inputs, failed thrusters and failed wheels, drawn from (campaign seed, run id, path).

Keyed seeding: the uniforms behind parameter ``path`` of run ``i`` come from a generator seeded
with ``SeedSequence([seed, i, key(path), 0])`` (random sampling), or from row ``i`` of a design
seeded with ``SeedSequence([seed, key(path), tag])`` (LHS, Sobol). So run i's inputs are the
same whatever ``-j``, chunking, backend, resume, or which other dispersions the campaign has.
With LHS or Sobol each parameter's components form one design over the dispersed runs; designs
of different parameters are independent (this is what makes them insensitive to the other
dispersions). An LHS design depends on the number of runs; a Sobol design does not (its rows
are a prefix of one scrambled sequence). Redraws (non-physical inertia) use attempts 1, 2, ...
"""

import functools
import hashlib
import itertools
import math

import numpy as np

from refexmc import distributions
from refexmc.campaign import saltelli
from refexmc.config import dispersions, renames
from refexmc.config.derived import level_names, thruster_count, unphysical_inertias, wheel_count
from refexmc.config.failures import NO_FAILURES, THRUSTER_FAILURES, WHEEL_FAILURES, failure_sets
from refexmc.distributions import transform_rows

_TINY = distributions.UNIFORM_EPS  # uniforms inside (0, 1): inverse CDFs stay finite
_DESIGN_TAG = {"lhs": 1, "sobol": 2}
FAILURES_KEY = THRUSTER_FAILURES.key  # the keyed stream of random failures: the campaign key
INERTIA_MAX_ATTEMPTS = 1000


@functools.lru_cache(maxsize=1024)
def path_key(name):
    """A stable 64-bit integer for a parameter path (independent of Python's hash seed); a renamed
    path keys by its first name (config.renames.seed_path): its draws stay the same."""
    return int.from_bytes(hashlib.sha256(renames.seed_path(name).encode()).digest()[:8], "little")


def keyed_rng(seed, run_id, name, attempt=0):
    """The generator of run ``run_id``'s draws for ``name``."""
    return np.random.default_rng(np.random.SeedSequence([int(seed), int(run_id), path_key(name), int(attempt)]))


def keyed_uniforms(seed, run_id, name, count, attempt=0):
    """``keyed_rng(seed, run_id, name, attempt).random(count)``, bit for bit, without building the
    generator (core.keyed_random: ~3 us instead of ~37 us per run and path)."""
    from refexmc.simulate import keyed_uniforms as draw  # numba: imported where drawn (workers), not by the parent

    return draw((seed, run_id, path_key(name), attempt), count)


def keyed_uniforms_for_runs(seed, run_ids, name, count, attempt=0):
    """Row i: ``keyed_uniforms(seed, run_ids[i], name, count, attempt)``, in one call for them all."""
    from refexmc.simulate import keyed_uniforms_for_runs as draw

    return draw((int(seed),), run_ids, path_key(name), attempt, count)


@functools.lru_cache(maxsize=256)
def _design(sampling, seed, name, n, dims):
    from scipy.stats import qmc  # scipy is imported where needed: it doubles `refexmc run` start-up

    rng = np.random.default_rng(np.random.SeedSequence([int(seed), path_key(name), _DESIGN_TAG[sampling]]))
    if sampling == "lhs":
        design = qmc.LatinHypercube(d=dims, rng=rng).random(n)
    else:
        design = qmc.Sobol(d=dims, scramble=True, rng=rng).random_base2(max(0, math.ceil(math.log2(n))))[:n]
    design.setflags(write=False)
    return design


dims = distributions.uniforms_per_draw  # uniforms one draw of a spec consumes


class Sampler:
    """Draws of one campaign. Cheap to build; a worker builds one per chunk."""

    def __init__(self, campaign):
        self.campaign = campaign
        self.vehicle = campaign["vehicle"]
        self.mission = campaign["mission"]
        self.seed = campaign["seed"]
        self.sampling = campaign["sampling"]
        self.offset = 1 if campaign["nominal_first"] else 0
        self.n_dispersed = campaign["runs"] - self.offset
        self.n_thrusters = thruster_count(self.vehicle)
        self.levels = level_names(self.vehicle)
        self.specs = dispersions.check(campaign["dispersions"], self.vehicle, self.mission, None, {})
        self.nominal = {path: dispersions.nominal(path, self.vehicle, self.mission) for path in self.specs}
        self.column_names = {path: dispersions.columns(path, self.vehicle) for path in self.specs}
        self._joined_names = {}  # (paths of a run's values, in order): their columns' names
        self.n_wheels = wheel_count(self.vehicle)
        self.wheel_failures = campaign.get(WHEEL_FAILURES.key, NO_FAILURES)
        self.failure_sets = self._enumerated(campaign["failures"], self.n_thrusters)
        self.wheel_failure_sets = self._enumerated(self.wheel_failures, self.n_wheels)

    @staticmethod
    def _enumerated(failures, n_units):
        return failure_sets(failures["sizes"], n_units) if failures["mode"] == "enumerate" else []

    def is_nominal(self, run_id):
        return self.offset == 1 and run_id == 0

    def uniforms(self, path, run_id, count, attempt=0):
        if count == 0:
            return np.empty(0)
        if self.sampling == "random" or attempt > 0:
            u = keyed_uniforms(self.seed, run_id, path, count, attempt)
        elif self.sampling == "saltelli":  # one joint design over every path (refexmc.campaign.saltelli)
            u = saltelli.uniforms(self, path, [run_id - self.offset])[0]
        else:
            u = _design(self.sampling, self.seed, path, self.n_dispersed, count)[run_id - self.offset]
        return np.clip(u, _TINY, 1.0 - _TINY)

    def uniforms_for_runs(self, path, run_ids, count):
        """(len(run_ids), count) uniforms: row i is ``uniforms(path, run_ids[i], count)``."""
        if count == 0:
            return np.empty((len(run_ids), 0))
        if self.sampling == "random":
            u = keyed_uniforms_for_runs(self.seed, run_ids, path, count)
        elif self.sampling == "saltelli":
            u = saltelli.uniforms(self, path, np.asarray(run_ids, dtype=np.int64) - self.offset)
        else:
            rows = np.asarray(run_ids, dtype=np.int64) - self.offset
            u = _design(self.sampling, self.seed, path, self.n_dispersed, count)[rows]
        return np.clip(u, _TINY, 1.0 - _TINY)

    def values(self, run_id):
        """{path: values in user units} of run ``run_id`` (the nominal values for the nominal run)."""
        (values,) = self.values_for_runs([run_id])
        if isinstance(values, Exception):
            raise values
        return values

    def values_for_runs(self, run_ids):
        """:meth:`values` of each of ``run_ids``, drawn path by path for them all at once (the same
        numbers). A run without a physical draw gets its exception (a ValueError) instead."""
        dispersed = [run_id for run_id in run_ids if not self.is_nominal(run_id)]
        drawn = {path: self._draw(path, spec, dispersed) for path, spec in self.specs.items()}
        out = []
        for run_id in run_ids:
            if self.is_nominal(run_id):
                out.append({path: value.copy() for path, value in self.nominal.items()})
                continue
            values = {path: draws[run_id] for path, draws in drawn.items()}
            problem = next((v for v in values.values() if isinstance(v, Exception)), None)
            out.append(problem if problem is not None else values)
        return out

    def values_or_exceptions(self, run_ids):
        """:meth:`values_for_runs`; where drawing the chunk at once raises (not a single run's
        problem), each run drawn alone, a run that raises getting its exception (an error row)."""
        try:
            return self.values_for_runs(run_ids)
        except Exception:  # noqa: BLE001 - let each run raise it alone
            return [self._values_or_exception(run_id) for run_id in run_ids]

    def _values_or_exception(self, run_id):
        try:
            return self.values(run_id)
        except Exception as exc:  # noqa: BLE001 - that run becomes an error row
            return exc

    def _draw(self, path, spec, run_ids):
        """{run id: values of ``path``} of ``run_ids``; inertia that is not physical is redrawn
        with attempts 1, 2, ... (an exception as the value when every attempt failed)."""
        n = dims(spec, dispersions.size(path, self.vehicle))
        rows = transform_rows(spec, self.uniforms_for_runs(path, run_ids, n), self.nominal[path])
        drawn = dict(zip(run_ids, rows, strict=True))
        if spec["dist"] == "inertia":
            unphysical = unphysical_inertias(distributions.inertia_tensors(rows))
            redrawn = self.inertia_redraws(path, spec, list(itertools.compress(run_ids, unphysical)), n)
            none = ValueError(f"{path}: no physical inertia in {INERTIA_MAX_ATTEMPTS} draws; reduce the sigmas")
            for run_id in itertools.compress(run_ids, unphysical):
                drawn[run_id] = redrawn[run_id][1] if run_id in redrawn else none
        return drawn

    def inertia_redraws(self, path, spec, run_ids, n):
        """{run id: (uniforms, values)} of the first physical inertia of attempts 1, 2, ... of each
        of ``run_ids`` (their first draw was not); a run without one in INERTIA_MAX_ATTEMPTS is left
        out. Each attempt draws the runs still without one at once (the same numbers as alone)."""
        found, pending = {}, list(run_ids)
        for attempt in range(1, INERTIA_MAX_ATTEMPTS + 1):
            if not pending:
                break
            u = np.clip(keyed_uniforms_for_runs(self.seed, pending, path, n, attempt), _TINY, 1.0 - _TINY)
            rows = transform_rows(spec, u, self.nominal[path])
            physical = ~np.asarray(unphysical_inertias(distributions.inertia_tensors(rows)), dtype=bool)
            found.update((pending[i], (u[i], rows[i])) for i in np.flatnonzero(physical))
            pending = [run_id for run_id, ok in zip(pending, physical, strict=True) if not ok]
        return found

    def _failed_units(self, failures, kind, n_units, sets, run_id):
        """Failed unit ids (1-based, ascending) of run ``run_id`` under ``failures`` (thrusters or
        wheels alike): random counts and sets come from the stream keyed by the campaign key."""
        mode = failures["mode"]
        if mode == "fixed":
            return tuple(sorted(failures[kind.units_key]))
        if mode == "none" or self.is_nominal(run_id):
            return ()
        if mode == "enumerate":
            return sets[run_id - self.offset]
        rng = keyed_rng(self.seed, run_id, kind.key)
        cumulative = np.cumsum(failures["count_probabilities"])
        count = min(int(np.searchsorted(cumulative, rng.random(), side="right")), len(cumulative) - 1)
        return tuple(sorted(int(t) + 1 for t in rng.choice(n_units, size=count, replace=False)))

    def failed(self, run_id):
        """Failed thruster ids (1-based, ascending) of run ``run_id``."""
        return self._failed_units(
            self.campaign["failures"], THRUSTER_FAILURES, self.n_thrusters, self.failure_sets, run_id
        )

    def failed_wheels(self, run_id):
        """Failed wheel ids (1-based, ascending) of run ``run_id``."""
        return self._failed_units(self.wheel_failures, WHEEL_FAILURES, self.n_wheels, self.wheel_failure_sets, run_id)

    def failures_detected(self):
        """Whether the flight software knows the failed thrusters (``failures.detected``)."""
        return bool(self.campaign["failures"].get("detected", False))

    def wheel_failures_detected(self):
        """Whether the flight software knows the failed wheels (``wheel_failures.detected``)."""
        return bool(self.wheel_failures.get("detected", False))

    def inputs(self, nominal_inputs, values, failed):
        """The run's own copy of the packed inputs with ``values`` and ``failed`` applied:
        :meth:`inputs_for_runs` of one run."""
        return self.inputs_for_runs(nominal_inputs, [values], [failed])[0]

    def inputs_for_runs(self, nominal_inputs, runs_values, runs_failed):
        """Each run's own copy of the packed inputs with its values (``runs_values[k]``: {path:
        values}, the same paths for every run) and failed thrusters (``runs_failed[k]``) applied.
        The runs' copies are rows of one stack per table, each path applied to them all at once
        (``dispersions.apply_rows``: the same bits as run by run). Failed wheels are packed
        (``nominal_inputs`` is the pack of the runs' wheel failures, which also sets the levels and
        the distribution matrix of detected ones); only the wheel table is dispersed, so that is
        the one wheel table copied. Failed thrusters are set here, known to the flight software with
        ``failures.detected`` (each run's own allocation table then)."""
        detected = self.failures_detected()
        copied = (*dispersions.DISPERSED_TABLES, *(("allocation",) if detected else ()))
        n = len(runs_values)
        stack = dispersions.stacked(nominal_inputs, n, copied)
        for path in runs_values[0] if n else ():
            rows = np.array([values[path] for values in runs_values], dtype=float)
            dispersions.apply_rows(stack, path, rows, nominal_inputs.atmosphere, self.levels)
        runs = [nominal_inputs._replace(**{name: getattr(stack, name)[k] for name in copied}) for k in range(n)]
        for inputs, failed in zip(runs, runs_failed, strict=True):
            dispersions.set_failed(inputs, failed, detected)
        return runs

    def columns(self, values):
        """The ``p.<path>`` columns of one run: :meth:`columns_for_runs` of one."""
        return self.columns_for_runs([values])[0]

    def columns_for_runs(self, runs_values):
        """The ``p.<path>`` columns of each run's values (the same paths for every run), joined
        path by path for them all at once and named (a dispersed ReFEx run has 26 paths)."""
        if not runs_values or not runs_values[0]:
            return [{} for _ in runs_values]
        paths = tuple(runs_values[0])
        if paths not in self._joined_names:
            self._joined_names[paths] = [name for path in paths for name in self.column_names[path]]
        names, n = self._joined_names[paths], len(runs_values)
        table = np.concatenate(
            [np.array([values[path] for values in runs_values], dtype=float).reshape(n, -1) for path in paths], axis=1
        )
        return [dict(zip(names, row, strict=True)) for row in table.tolist()]
