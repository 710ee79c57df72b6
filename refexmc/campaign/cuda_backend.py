"""The GPU backend (``refexmc run --backend cuda``, docs/gpu.md): one run per CUDA thread.

The runs are drawn on the host exactly as for loky (``RunPlan.prepare_runs``: the same keyed
draws, the same ``p.`` columns). A launch flies a batch of chunks through refexmc.simulate_cuda
(thread k flies run k with the family's jitted CPU kernel source compiled by numba-cuda; this
layer never imports the core). The host then names each run's outputs as the CPU path does
(``simulate.flight_result``, ``RunPlan.result_row``), and yields each chunk's runs and histories
parts to the writer (refexmc.campaign.run), so progress, resume, signals and the lock are the
loky backend's.

The host's work is a chunk per task (:func:`prepare_into`, :func:`name_chunk`) for loky workers,
the launch's arrays in shared memory (refexmc.campaign.shared_arrays), or for threads of this
process (``-j 1``). A launch holds as many runs as half the free device memory takes
(``launch_runs``); while the GPU flies one launch, the workers pack the next, then name and
encode the flown one. A run whose preparation raised or whose state is not finite becomes an
error row, as on the CPU; a run that meets its mission's time limit is a failure, as on the CPU.
Unlike loky there is no wall-time watchdog per run (a thread cannot be stopped alone): the
flight's own time limit ends every run.
"""

import os
import threading
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import NamedTuple

import numpy as np

from refexmc import simulate_cuda
from refexmc.campaign import pool, shared_arrays, storage
from refexmc.config.errors import ConfigError
from refexmc.simulate_cuda import INPUT_TABLES, Batch, grid_kernel, input_shapes, launch_runs, output_shapes, run_sizes

# the entry flight (core.entry_flight) has no GPU kernel at all; other families that cannot fly
# on the GPU yet: simulate_cuda.REFUSED_FAMILIES
ENTRY_REFUSED = "the entry flight (core.entry_flight) is a kernel of its own, not built for the GPU yet"


def check(campaign=None):
    """ConfigError (one line, before anything is written) when ``campaign`` cannot fly on the GPU yet."""
    why = refusal(campaign) if campaign is not None else None
    if why is not None:
        raise ConfigError(f"cannot fly on a GPU: {why}", path=("--backend",))


def refusal(campaign):
    """Why ``campaign``'s vehicle family cannot fly on the GPU yet, or None."""
    if "entry_flight" in campaign["mission"]:
        return ENTRY_REFUSED
    for study in ("rare_event", "sweep"):
        if study in campaign:
            return f"a {study.replace('_', '-')} study flies with the loky or dask backend"
    return simulate_cuda.family_refusal(campaign["vehicle"], campaign["mission"])


def cuda_backend(campaign, chunks, jobs, guard, workers=None):
    """Fly ``chunks`` on this machine's GPU (of ``guard``, only its work directory is used: a GPU
    thread has no wall-time watchdog). ``jobs`` > 1: that many loky worker processes draw and pack
    the runs into the launch's arrays and name and encode its parts, a chunk a task, the arrays in
    shared memory (the host's work is what bounds a GPU campaign: benchmarks/bench_gpu_host.py);
    1: threads of this process do, on private arrays. ``workers``: how many loky workers
    ``backends.start_workers`` started for it (default: ``jobs``, at most one per chunk).

    Yields ``(chunk index, rows, runs Parquet bytes, history Parquet bytes)`` per chunk, in chunk
    order (with workers: its run ids for its rows, and its parts' files for their bytes:
    :func:`name_chunk`); the host prepares the next launch while the GPU flies one, and names and
    encodes a launch while the GPU flies the next.
    """
    from refexmc.campaign.chunk import plan_for

    if not chunks:
        return
    plan = plan_for(campaign)
    rate = campaign["output"]["history_rate_hz"]
    host_free = shared_arrays.available_bytes()
    shared = jobs > 1 and len(chunks) > 1 and shared_arrays.shareable()
    kernel = grid_kernel(plan.family)
    batches = _batches(chunks, launch_runs(plan, rate, host_free))
    workers = pool.executor(workers or min(jobs, len(chunks))) if shared else _threads()
    # a worker writes its chunk's parts into the work directory, the parent renames them into place
    # (through the pipe, a ReFEx chunk's ~1.6 MB of parts cost the parent 0.02 ms per run)
    work_dir = guard.state_dir if shared else None
    launches = []  # those whose arrays are allocated: at most two at a time (one named while the next flies)
    try:
        launch = Launch.submit(plan, campaign, batches[0], workers, shared)
        launches.append(launch)
        launch.allocate_outputs(plan)
        launch.start(kernel)
        for index in range(len(batches)):
            following = None
            if index + 1 < len(batches):  # its tasks queue before the naming of this one
                following = Launch.submit(plan, campaign, batches[index + 1], workers, shared)
                launches.append(following)
            launch.join()
            named = launch.submit_naming(campaign, workers, work_dir)
            if following is not None:
                following.allocate_outputs(plan)
                following.start(kernel)
            for part in named:
                yield part.result()
            launch.release()
            launches.remove(launch)
            launch = following
    finally:
        for launch in launches:  # a signal, a full disk, a failed launch: free the host's memory
            launch.release()
        if not shared:
            workers.shutdown(wait=False, cancel_futures=True)


def _threads():
    return ThreadPoolExecutor(max_workers=os.cpu_count() or 1, thread_name_prefix="refexmc-host")


def _batches(chunks, runs_per_launch):
    """Consecutive chunks grouped into launches of at most ``runs_per_launch`` runs (a chunk is never split)."""
    batches, current, size = [], [], 0
    for chunk, run_ids in chunks:
        if current and size + len(run_ids) > runs_per_launch:
            batches.append(current)
            current, size = [], 0
        current.append((chunk, run_ids))
        size += len(run_ids)
    if current:
        batches.append(current)
    return batches


class Launch:
    """One launch of a campaign: its chunks, their runs' arrays (shared or private memory), the
    prepared chunks' metadata and the flight's thread."""

    def __init__(self, plan, batch_chunks, shared):
        self.chunks = batch_chunks
        self.first = [int(v) for v in np.cumsum([0] + [len(ids) for _, ids in batch_chunks])]
        self.n = self.first[-1]
        self.inputs = shared_arrays.Arrays(input_shapes(plan.nominal_inputs, self.n), shared)
        self.outputs = None
        self.shared = shared
        self.pending = []  # the chunks' preparation futures
        self.prepared = None  # their PreparedChunk, in order
        self.batch = None
        self.flying = None
        self.naming = []

    @classmethod
    def submit(cls, plan, campaign, batch_chunks, workers, shared):
        """A launch whose chunks' preparation is submitted to ``workers``."""
        launch = cls(plan, batch_chunks, shared)
        target = launch.inputs.handle() if shared else launch.inputs
        launch.pending = [
            workers.submit(prepare_into, campaign, list(ids), target, first)
            for (_, ids), first in zip(batch_chunks, launch.first, strict=False)
        ]
        return launch

    def allocate_outputs(self, plan):
        """Wait for the chunks' preparation; allocate the outputs their runs need."""
        self.prepared = [future.result() for future in self.pending]
        self.pending = []
        rows = max(chunk.history_rows for chunk in self.prepared)
        capacity = max(chunk.capacity for chunk in self.prepared)
        self.outputs = shared_arrays.Arrays(
            output_shapes(plan.nominal_inputs, self.n, rows, plan.pointing, capacity), self.shared
        )
        self.batch = Batch({**self.inputs.arrays, **self.outputs.arrays}, plan.family, plan.pointing)

    def start(self, kernel):
        self.flying = threading.Thread(
            target=self.batch.launch, args=(kernel,), name="refexmc-cuda-launch", daemon=True
        )
        self.flying.start()

    def join(self):
        self.batch.join(self.flying)
        self.flying = None

    def submit_naming(self, campaign, workers, work_dir=None):
        """Each chunk's naming and encoding submitted to ``workers``: futures of its part, in order
        (``work_dir``: its parts written there, :func:`name_chunk`)."""
        handles = (self.inputs.handle(), self.outputs.handle()) if self.shared else (self.inputs, self.outputs)
        self.naming = [
            workers.submit(name_chunk, campaign, chunk, prepared, handles, first, work_dir)
            for (chunk, _), prepared, first in zip(self.chunks, self.prepared, self.first, strict=False)
        ]
        return self.naming

    def release(self):
        """Cancel the launch's tasks not started, wait for its flight to land, and free its arrays
        (a worker still reading them keeps its mapping until it is done).

        A kernel cannot be stopped, and the flight's thread writes the launch's outputs without the
        GIL: freed under it (a signal's exit unmaps shared memory), it would crash the process."""
        for future in (*self.pending, *self.naming):
            future.cancel()
        if self.flying is not None:
            self.flying.join()
            self.flying = None
        self.batch = None
        for arrays in (self.inputs, self.outputs):
            if arrays is not None:
                arrays.release()


class PreparedChunk(NamedTuple):
    """What the host keeps of a chunk's runs once they are packed into their launch's rows."""

    run_ids: list
    seeds: np.ndarray  # int64: each run's nav seed
    failures: list  # each run's storage.Failures (None: its preparation raised)
    params: np.ndarray  # (runs, plan.param_columns()): the p. columns
    reasons: list  # None, or the error row's reason of a run whose preparation raised
    history_rows: int  # the most history rows a run of the chunk writes
    capacity: int  # the most pointing samples a run of the chunk keeps


def prepare_into(campaign, run_ids, target, first):
    """Draw and pack ``run_ids`` (``RunPlan.prepare_runs``) into rows ``first``... of the launch
    arrays ``target`` (a shared block's handle, or the arrays): a :class:`PreparedChunk`. A run whose
    preparation raised, or whose tables have other shapes than its campaign's, gets the nominal
    inputs in its rows (its thread flies them; the run is an error row and its outputs are not read)."""
    from refexmc.campaign.chunk import plan_for

    plan = plan_for(campaign)
    rate = campaign["output"]["history_rate_hz"]
    shapes = tuple(table.shape for table in plan.nominal_inputs)
    columns = plan.param_columns()
    n = len(run_ids)
    seeds, params = np.zeros(n, dtype=np.int64), np.full((n, len(columns)), np.nan)
    failures, reasons = [None] * n, [None] * n
    history_rows = capacity = 1
    with shared_arrays.attached(target) as arrays:
        for k, prepared in enumerate(plan.prepare_runs(run_ids)):
            if not isinstance(prepared, Exception) and tuple(t.shape for t in prepared[3]) != shapes:
                prepared = ValueError("input tables of other shapes than its campaign's (a GPU launch stacks them)")
            if isinstance(prepared, Exception):
                reasons[k] = plan.failure_reason(prepared)
                inputs = plan.nominal_inputs
            else:
                seeds[k], failures[k], values, inputs = prepared
                params[k] = [values[column] for column in columns]
            every, rows, samples = run_sizes(inputs, rate, plan.pointing)
            history_rows, capacity = max(history_rows, rows), max(capacity, samples)
            for name in INPUT_TABLES:
                arrays[name][first + k] = getattr(inputs, name)
            arrays["seeds"][first + k], arrays["every"][first + k] = seeds[k], every
    return PreparedChunk(list(run_ids), seeds, failures, params, reasons, history_rows, capacity)


def name_chunk(campaign, chunk, prepared, targets, first, work_dir=None):
    """The chunk's ``(chunk, rows, runs bytes, history bytes)`` from its runs' rows ``first``... of
    the flown launch's arrays ``targets`` (inputs, outputs): each run named as the CPU path names it
    (``simulate.flight_result``, ``RunPlan.result_row``). With ``work_dir`` (a loky worker), each
    part's bytes are written to a file there and its Path returned instead (``storage.place_part``
    renames it), and the chunk's run ids instead of its rows (only counted: ``backends``)."""
    from refexmc.campaign.chunk import plan_for

    plan = plan_for(campaign)
    inputs, outputs = targets
    with shared_arrays.attached(inputs) as input_arrays, shared_arrays.attached(outputs) as output_arrays:
        batch = Batch({**input_arrays, **output_arrays}, plan.family, plan.pointing)
        rows, runs, history = _named(plan, batch, prepared, first)
        del batch  # its views of the arrays, before they are detached
    if work_dir is None:
        return chunk, rows, runs, history
    files = []
    for part, data in (("runs", runs), ("histories", history)):
        path = Path(work_dir) / f"gpu-{part}-{storage.part_name(chunk)}"
        storage.write_bytes_atomic(data, path)
        files.append(path)
    return chunk, list(prepared.run_ids), *files


def _named(plan, batch, prepared, first):
    columns = plan.param_columns()
    rows, flown = [], []
    for k, run_id in enumerate(prepared.run_ids):
        if prepared.reasons[k] is not None:
            rows.append(plan.error_row(run_id, prepared.reasons[k]))
            continue
        params = dict(zip(columns, prepared.params[k].tolist(), strict=True))
        result = batch.result(first + k, plan.mode_names, plan.pointing)
        row, result = plan.result_row(run_id, (int(prepared.seeds[k]), prepared.failures[k], params, None), result)
        rows.append(row)
        if result is not None:
            flown.append((run_id, result))
    runs = storage.encode_table(storage.runs_table(rows))
    if flown:
        history = storage.histories_table([r for r, _ in flown], [result for _, result in flown])
    else:
        history = storage.empty_history_table()
    return rows, runs, storage.encode_table(history)
