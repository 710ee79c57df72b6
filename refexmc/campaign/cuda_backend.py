"""The GPU backend (``refexmc run --backend cuda``, docs/gpu.md): one run per CUDA thread.

The runs are drawn on the host exactly as for loky (``RunPlan.prepare_runs``: the same keyed
draws, the same ``p.`` columns). A launch flies a batch of chunks through refexmc.simulate_cuda
(thread k flies run k with the family's jitted CPU kernel source compiled by numba-cuda; this
layer never imports the core). The host then names each run's outputs as the CPU path does
(``simulate.flight_result``, ``RunPlan.result_row``), and yields each chunk's runs and histories
parts to the writer (refexmc.campaign.run), so progress, resume, signals and the lock are the
loky backend's.

A batch holds as many runs as half the free device memory takes (``launch_runs``); while the
GPU flies one batch, the host prepares the next. A run whose preparation raised or whose state is
not finite becomes an error row, as on the CPU; a run that meets its mission's time limit is a
failure, as on the CPU. Unlike loky there is no wall-time watchdog per run (a thread cannot be
stopped alone): the flight's own time limit ends every run.
"""

import os
import threading
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from refexmc import simulate_cuda
from refexmc.campaign import pool, storage
from refexmc.config.errors import ConfigError
from refexmc.simulate_cuda import Batch, grid_kernel, launch_runs

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


def cuda_backend(campaign, chunks, jobs, guard):
    """Fly ``chunks`` on this machine's GPU (``guard`` is the loky backend's and unused: a GPU
    thread has no wall-time watchdog). ``jobs`` > 1: that many loky worker processes draw and pack
    the runs, a chunk each (the host's serial bottleneck otherwise: benchmarks/bench_gpu_host.py);
    1: this process does.

    Yields ``(chunk index, rows, runs Parquet bytes, history Parquet bytes)`` per chunk, in chunk
    order; the host prepares the next batch while the GPU flies one, and names and encodes a batch
    while the GPU flies the next.
    """
    from refexmc.campaign.chunk import plan_for

    if not chunks:
        return
    plan = plan_for(campaign)
    rate = campaign["output"]["history_rate_hz"]
    kernel = grid_kernel(plan.family)
    batches = _batches(chunks, launch_runs(plan, rate))
    executor = pool.executor(min(jobs, len(chunks))) if jobs > 1 and len(chunks) > 1 else None

    def prepare(batch_chunks):
        return _prepare(plan, campaign, batch_chunks, rate, executor)

    batch = prepare(batches[0])
    flying = _start(batch, kernel)
    for index, batch_chunks in enumerate(batches):
        following = prepare(batches[index + 1]) if index + 1 < len(batches) else None  # while it flies
        batch.join(flying)
        if following is not None:
            flying_next = _start(following, kernel)
        yield from _chunk_parts(plan, batch, batch_chunks)  # while the following batch flies
        if following is not None:
            batch, flying = following, flying_next


def _start(batch, kernel):
    flying = threading.Thread(target=batch.launch, args=(kernel,), name="refexmc-cuda-launch", daemon=True)
    flying.start()
    return flying


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


def _prepare(plan, campaign, batch_chunks, rate, executor=None):
    """The launch of ``batch_chunks``: its runs drawn and packed here, or a chunk per loky worker."""
    run_ids = [run_id for _, ids in batch_chunks for run_id in ids]
    if executor is None:
        prepared = plan.prepare_runs(run_ids)
    else:
        from refexmc.campaign.chunk import prepare_chunk

        futures = [executor.submit(prepare_chunk, campaign, list(ids)) for _, ids in batch_chunks]
        prepared = [entry for future in futures for entry in future.result()]
    return Batch(plan, run_ids, prepared, rate)


def _chunk_parts(plan, batch, batch_chunks):
    """Each chunk's (chunk, rows, runs bytes, history bytes), in order, named and encoded by a
    thread per core (Arrow's encoding and the nogil reductions run in parallel)."""
    starts = np.cumsum([0] + [len(run_ids) for _, run_ids in batch_chunks])
    with ThreadPoolExecutor(max_workers=os.cpu_count() or 1, thread_name_prefix="refexmc-encode") as pool:
        parts = [
            pool.submit(_chunk_part, plan, batch, chunk, int(start), int(stop))
            for (chunk, _), start, stop in zip(batch_chunks, starts[:-1], starts[1:], strict=True)
        ]
        for part in parts:
            yield part.result()


def _chunk_part(plan, batch, chunk, start, stop):
    pieces = batch.rows(plan, start, stop)
    rows = [row for row, _ in pieces]
    flown = [(row["run_id"], result) for row, result in pieces if result is not None]
    runs = storage.encode_table(storage.runs_table(rows))
    if flown:
        history = storage.histories_table([r for r, _ in flown], [result for _, result in flown])
    else:
        history = storage.empty_history_table()
    return chunk, rows, runs, storage.encode_table(history)
