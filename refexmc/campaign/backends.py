"""Execution backends: fly chunks of runs in worker processes, yield each chunk when it is complete.

A backend is a generator function ``backend(campaign, chunks, jobs, guard, **options)``: ``chunks``
is a list of ``(chunk index, run ids)``, ``guard`` a :class:`refexmc.campaign.worker.Guard`,
``options`` what :func:`check_backend` and :func:`start_workers` returned for it (e.g. ``scheduler``
for dask, ``workers`` for loky); it yields ``(chunk index, rows, runs Parquet bytes, history Parquet
bytes)`` in completion order (cuda: in chunk order, each part's bytes possibly in a file of the work
directory, ``storage.place_part``, and then its run ids in place of its rows: the writing process
only counts them, and sending a chunk's rows costs it ~18 us a run), rows sorted by run id, and
keeps only a bounded number of chunks in flight so that memory does not grow with the campaign.
``check_backend(name, **options)`` runs before anything is written: ConfigError for an unknown
backend, an option it does not take, or one it cannot start with (dask: the extra missing, a
malformed or unreachable scheduler). ``loky`` (below: joblib's loky executor) runs on this machine;
``dask`` (:mod:`refexmc.campaign.dask_backend`, imported only when used) on a Dask cluster; ``cuda``
(:mod:`refexmc.campaign.cuda_backend`, imported only when used) on this machine's GPU.
``start_workers(name, workers)`` starts a backend's workers before the campaign is prepared, so that
they warm up meanwhile (loky: :mod:`refexmc.campaign.pool`).

Workers return both parts already encoded (:class:`refexmc.campaign.worker.Flown`); only a
chunk that came back in pieces (after a crash) is assembled and encoded again
(:class:`refexmc.campaign.assembly.ChunkAssembler`, shared with the dask backend).

A run that exceeds the wall-time limit, or that kills its worker process (a segfault), becomes
an error row; the other runs of its chunk are flown again. After a crash it is not known which
of the runs in flight caused it, so each of them is flown again alone, with nothing else in
flight: the one that crashes again is the culprit.
"""

import re
from collections import deque
from concurrent.futures import FIRST_COMPLETED, wait

from joblib.externals.loky.process_executor import TerminatedWorkerError

from refexmc.campaign import pool
from refexmc.campaign.assembly import TASKS_PER_WORKER, ChunkAssembler, Task, error_row
from refexmc.campaign.worker import FLYING, OVER_LIMIT, collect_states, fly_guarded
from refexmc.config.errors import ConfigError

MAX_BLIND_RETRIES = 3  # a chunk whose worker died with no run in flight is retried this often


def _exit_codes(exc):
    """The workers' exit codes as loky reports them, e.g. 'SIGSEGV(-11)'."""
    found = re.search(r"exit codes of the workers are \{([^}]*)\}", str(exc))
    return found.group(1) if found else "unknown"


def _submit(executor, inflight, task, campaign, guard, source):
    try:
        future = executor.submit(fly_guarded, campaign, task.run_ids, guard)
    except TerminatedWorkerError:
        source.appendleft(task)  # not started: the pool broke since the last look
        raise
    inflight[future] = task


def loky_backend(campaign, chunks, jobs, guard, workers=None):
    """Fly ``chunks`` on ``jobs`` loky worker processes (a worker process even for jobs=1).

    ``workers``: the pool :func:`start_workers` started (default: ``jobs``, at most one per chunk),
    flown on as it is: shrinking it would wait for its workers to finish warming up.
    """
    if not chunks:
        return
    jobs = workers or max(1, min(jobs, len(chunks)))
    window = TASKS_PER_WORKER * jobs
    assembler = ChunkAssembler(chunks)
    queue = deque(Task(chunk, run_ids) for chunk, run_ids in chunks)
    isolate = deque()  # suspects of a crash, flown one at a time with nothing else in flight
    blind_retries = {}
    inflight = {}
    executor = pool.executor(jobs)
    finished = False
    try:
        while queue or isolate or inflight:
            crash = None
            try:
                if isolate:
                    if not inflight:
                        _submit(executor, inflight, isolate.popleft(), campaign, guard, isolate)
                else:
                    while queue and len(inflight) < window:
                        _submit(executor, inflight, queue.popleft(), campaign, guard, queue)
            except TerminatedWorkerError as exc:
                crash = exc
            done = list(inflight) if crash else wait(list(inflight), return_when=FIRST_COMPLETED)[0]
            broken = []
            while done:
                for future in done:
                    task = inflight.pop(future)
                    try:
                        flown = future.result()
                    except TerminatedWorkerError as exc:
                        broken.append(task)
                        crash = exc
                        continue
                    finished_chunk = assembler.add(task.chunk, flown)
                    if finished_chunk:
                        yield finished_chunk
                # a broken pool fails every task still in flight (or has just finished it): collect them all
                done = list(inflight) if crash else []
            if crash:
                executor.shutdown(wait=True, kill_workers=True)
                yield from _recover(campaign, broken, crash, guard, assembler, queue, isolate, blind_retries)
                executor = pool.executor(jobs)
        finished = True
    finally:
        if not finished:  # interrupted or failed: leave no worker running
            pool.kill(executor)


def _recover(campaign, broken, crash, guard, assembler, queue, isolate, blind_retries):
    """Sort the runs of broken tasks into error rows, runs to fly alone, and tasks to fly again."""
    states = collect_states(guard.state_dir).values()
    over_limit = {run_id for run_id, state in states if state == OVER_LIMIT}
    flying = {run_id for run_id, state in states if state == FLYING}
    limit = f"wall-time limit exceeded ({guard.time_limit_s:g} s)"
    died = f"worker process died during this run (exit code {_exit_codes(crash)})"
    for task in broken:
        errors, again, alone = [], [], []
        for run_id in task.run_ids:
            if run_id in over_limit:
                errors.append(error_row(campaign, run_id, limit))
            elif task.isolated and not over_limit:
                errors.append(error_row(campaign, run_id, died))
            elif run_id in flying and not over_limit:
                alone.append(run_id)
            else:
                again.append(run_id)
        if not over_limit and not flying:  # died between runs: no run to blame, fly the task again
            blind_retries[task.chunk] = blind_retries.get(task.chunk, 0) + 1
            if blind_retries[task.chunk] > MAX_BLIND_RETRIES:
                raise RuntimeError(f"worker processes keep dying while flying chunk {task.chunk}: {crash}") from crash
        if errors:
            finished_chunk = assembler.add_errors(task.chunk, errors)
            if finished_chunk:
                yield finished_chunk
        isolate.extend(Task(task.chunk, [run_id], isolated=True) for run_id in alone)
        if again:
            queue.appendleft(Task(task.chunk, again))


def dask_backend(campaign, chunks, jobs, guard, scheduler=None):
    """Fly ``chunks`` on a Dask cluster (:mod:`refexmc.campaign.dask_backend`; needs the dask extra)."""
    from refexmc.campaign import dask_backend as dask  # importing refexmc never imports dask

    return dask.dask_backend(campaign, chunks, jobs, guard, scheduler=scheduler)


def cuda_backend(campaign, chunks, jobs, guard, workers=None):
    """Fly ``chunks`` on this machine's GPU (:mod:`refexmc.campaign.cuda_backend`; needs the cuda
    extra); ``workers``: the host workers :func:`start_workers` started."""
    from refexmc.campaign import cuda_backend as cuda  # importing refexmc never imports numba-cuda

    return cuda.cuda_backend(campaign, chunks, jobs, guard, workers=workers)


def _loky_options(scheduler=None):
    if scheduler is not None:
        raise ConfigError(
            "--scheduler is for --backend dask (loky flies on this machine, in -j processes)", path=("--scheduler",)
        )
    return {}


def _dask_options(scheduler=None):
    from refexmc.campaign import dask_backend as dask

    dask.check(scheduler)
    return {"scheduler": scheduler}


def _cuda_options(scheduler=None, campaign=None):
    from refexmc import _jit

    if scheduler is not None:
        raise ConfigError("--scheduler is for --backend dask (cuda flies on this machine's GPU)", path=("--scheduler",))
    why = _jit.cuda_unavailable()
    if why is not None:
        raise ConfigError(f"cannot fly on a GPU: {why}", path=("--backend",))
    from refexmc.campaign import cuda_backend as cuda  # numba-cuda is there: import it

    cuda.check(campaign)
    return {}


BACKENDS = {"loky": loky_backend, "dask": dask_backend, "cuda": cuda_backend}
_OPTIONS = {"loky": _loky_options, "dask": _dask_options, "cuda": _cuda_options}


def _start_loky(workers):
    workers = max(workers, pool.started_early())
    pool.start(workers)
    return {"workers": workers}


def _start_cuda_host(workers):
    """The GPU backend's host workers (``-j`` > 1: they pack and name the runs), started as loky's."""
    return _start_loky(workers) if workers > 1 else {}


_STARTERS = {"loky": _start_loky, "cuda": _start_cuda_host}  # dask: its cluster starts when the campaign flies


def start_workers(name, workers):
    """Start ``workers`` workers of backend ``name`` ahead of the flight; the options that fly on them."""
    starter = _STARTERS.get(name)
    return starter(workers) if starter else {}


def stop_workers():
    """Kill the workers :func:`start_workers` started, if they still run (loky: :func:`pool.stop`)."""
    pool.stop()


def check_backend(name, campaign=None, **options):
    """The keyword options to pass to backend ``name``; ConfigError if it cannot run with ``options``
    (or, for cuda, ``campaign``'s vehicle family cannot fly on the GPU)."""
    if name not in BACKENDS:
        raise ConfigError(f"expected one of {', '.join(BACKENDS)}, got {name!r}", path=("--backend",))
    if name == "cuda":  # which families it flies
        options = {**options, "campaign": campaign}
    return _OPTIONS[name](**options)
