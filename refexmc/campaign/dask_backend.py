"""The Dask distributed backend: fly chunks on the workers of a Dask cluster, results to the client.

``--scheduler`` names the cluster: ``local:N`` starts a ``LocalCluster`` of N worker processes
(one thread each) for the campaign and closes it at the end; ``local`` takes N from ``-j``;
anything else is the address of a running scheduler (``tcp://host:8786``) or the path of a
scheduler file (``dask scheduler --scheduler-file``), to which a client connects. Workers need
the same refexmc installed; they return each chunk's rows and history Parquet bytes to the
client, which writes the part files (the workers need no shared file system).

Each task runs :func:`refexmc.campaign.worker.fly_guarded` on a worker, one task at a time per
worker process, under the same wall-time watchdog as loky, but with no state file (it would be on
the worker's disk). Instead:

- A run that exceeds the wall-time limit: before the watchdog ends the worker process, it records
  the run id in the scheduler's metadata under the task's key (acknowledged, see
  :func:`refexmc.campaign.worker.set_over_limit_hook`). Dask runs the task again on another worker
  (a task whose worker died is retried up to ``distributed.scheduler.allowed-failures`` times,
  default 3), and that attempt records the hung run as an error instead of flying it. One hang
  costs one time limit and one worker restart, as with loky. The metadata goes when the task is
  forgotten.
- A worker that dies for any other reason (killed, lost, out of memory): Dask reschedules its
  tasks and the client gets each task's result exactly once, so no run is lost or duplicated. The
  client also checks that every result holds exactly its task's runs, none of them seen before.
- A run that crashes its worker (a segfault) crashes every attempt until Dask gives the task up
  (``KilledWorker``). As loky does after a crash, the client then flies the task's runs one at a
  time with nothing else in flight; a run whose task is given up again becomes an error row
  ("worker died during this run (crash or wall-time limit)"). That costs
  2 x (allowed-failures + 1) worker restarts; other runs are not affected.
"""

import itertools
import os
import threading
import time
import uuid
from collections import deque
from contextlib import contextmanager, suppress
from functools import partial
from pathlib import Path

from refexmc.campaign import worker as guarded
from refexmc.campaign.assembly import TASKS_PER_WORKER, ChunkAssembler, Task, error_row
from refexmc.config.errors import ConfigError

EXTRA_MISSING = "the dask backend needs the optional extra: pip install 'refexmc[dask]'"
DIED = "worker died during this run (crash or wall-time limit)"
HUNG = "hung"  # metadata under a task's key: {run id (str): True} for runs over the time limit
WINDOW_REFRESH_S = 2.0  # how often the client asks how many worker threads there are


def require_distributed():
    """The ``distributed`` module; ConfigError with the install hint when the extra is missing."""
    try:
        import distributed
    except ImportError:
        raise ConfigError(EXTRA_MISSING, path=("--backend",)) from None
    return distributed


def parse_scheduler(scheduler):
    """('local', N or None) for ``local[:N]``, else ('address', ADDRESS); ConfigError when malformed."""
    if scheduler is None or not str(scheduler).strip():
        raise ConfigError(
            "--backend dask needs --scheduler ADDRESS (a running Dask scheduler) or local:N "
            "(a LocalCluster of N worker processes)",
            path=("--scheduler",),
        )
    text = str(scheduler).strip()
    if text == "local":
        return "local", None
    if text.startswith("local:"):
        try:
            workers = int(text[len("local:") :])
        except ValueError:
            workers = 0
        if workers < 1:
            raise ConfigError(f"expected local:N with an integer N >= 1, got {text!r}", path=("--scheduler",))
        return "local", workers
    return "address", text


def check(scheduler=None):
    """ConfigError unless the backend can start: the extra is installed, the scheduler reachable."""
    distributed = require_distributed()
    kind, address = parse_scheduler(scheduler)
    if kind == "address":
        with _client(distributed, address):
            pass


@contextmanager
def _client(distributed, address):
    """A client of the scheduler at ``address`` (or of the scheduler file at that path)."""
    looks_like_a_file = "://" not in address and (address.endswith(".json") or "/" in address or os.sep in address)
    if looks_like_a_file and not Path(address).is_file():
        raise ConfigError(
            f"no scheduler file {address!r} (a running scheduler's file, or its address tcp://HOST:PORT)",
            path=("--scheduler",),
        )
    try:
        if Path(address).is_file():
            client = distributed.Client(scheduler_file=address)
        else:
            client = distributed.Client(address)
    except (OSError, TimeoutError, ValueError) as exc:
        raise ConfigError(f"cannot connect to the Dask scheduler {address!r}: {exc}", path=("--scheduler",)) from None
    try:
        yield client
    finally:
        client.close()


def _local_cluster(distributed, workers):
    """A LocalCluster of ``workers`` one-thread worker processes, each warmed up as it starts
    (:mod:`refexmc.campaign.dask_preload`); its dashboard on any free port, so that campaigns
    side by side do not collide."""
    return distributed.LocalCluster(
        n_workers=workers,
        threads_per_worker=1,
        processes=True,
        dashboard_address=":0",
        preload=["refexmc.campaign.dask_preload"],
    )


_early = None  # (workers, thread, {"cluster": ...}) of the LocalCluster start_local_early started


def start_local_early(workers):
    """Start a LocalCluster of ``workers`` workers in a thread, now: ``refexmc run --scheduler
    local[:N]`` does so before it reads the campaign, so that importing distributed (~0.7 s), the
    cluster's start (~0.7 s) and its workers' warm-up overlap the validation. The campaign takes
    it (:func:`connect`); :func:`stop_early` closes one that no campaign took."""
    global _early
    box = {}

    def start():
        with suppress(Exception):  # the campaign's own checks and start report it
            box["cluster"] = _local_cluster(require_distributed(), workers)

    thread = threading.Thread(target=start, name="refexmc-dask-start", daemon=True)
    thread.start()
    _early = (workers, thread, box)


def _take_early(workers):
    """The cluster :func:`start_local_early` started, if it has ``workers`` workers (else None)."""
    global _early
    if _early is None or _early[0] != workers:
        return None
    _, thread, box = _early
    thread.join()
    _early = None
    return box.get("cluster")


def stop_early():
    """Close the cluster :func:`start_local_early` started if no campaign took it (bad input)."""
    global _early
    if _early is not None:
        _, thread, box = _early
        _early = None
        thread.join()
        if "cluster" in box:
            box["cluster"].close()


@contextmanager
def connect(scheduler, jobs):
    """A client of the cluster ``scheduler`` names; a LocalCluster started here (or ahead, by
    :func:`start_local_early`) is closed on exit."""
    distributed = require_distributed()
    kind, value = parse_scheduler(scheduler)
    if kind == "address":
        with _client(distributed, value) as client:
            yield client
        return
    workers = value or jobs
    cluster = _take_early(workers) or _local_cluster(distributed, workers)
    try:
        with distributed.Client(cluster) as client:
            yield client
    finally:
        cluster.close()


def _limit_reason(guard):
    return f"wall-time limit exceeded ({guard.time_limit_s:g} s)"


def dask_backend(campaign, chunks, jobs, guard, scheduler=None):
    """Fly ``chunks`` on the Dask cluster ``scheduler`` names (``jobs``: the workers of bare ``local``)."""
    if not chunks:
        return
    distributed = require_distributed()
    guard = guard._replace(state_dir=None)  # the parent's work directory is not on the workers' disks
    with connect(scheduler, jobs) as client:
        yield from _fly_chunks(distributed, client, campaign, chunks, guard)


def _fly_chunks(distributed, client, campaign, chunks, guard):
    assembler = ChunkAssembler(chunks)
    received = {}  # chunk -> run ids whose rows arrived (a result must not count twice)
    queue = deque(Task(chunk, run_ids) for chunk, run_ids in chunks)
    isolate = deque()  # runs of a task Dask gave up: flown one at a time with nothing else in flight
    inflight = {}
    prefix = f"refexmc-{uuid.uuid4().hex[:12]}"
    serial = itertools.count()
    window = _Window(client)

    def submit(task):
        key = f"{prefix}-{task.chunk:05d}-{next(serial)}"
        inflight[client.submit(_fly_task, campaign, task.run_ids, guard, key=key)] = task

    def collect(task, rows, flown=None):
        """Rows of ``task``: a worker's :class:`Flown` (``flown``), or error rows the client made."""
        ids = [row["run_id"] for row in rows]
        seen = received.setdefault(task.chunk, set())
        if sorted(ids) != sorted(set(ids)) or seen.intersection(ids) or not set(ids) <= set(task.run_ids):
            raise RuntimeError(f"chunk {task.chunk}: a result repeats runs or holds runs of another task: {ids}")
        seen.update(ids)
        finished = assembler.add(task.chunk, flown) if flown else assembler.add_errors(task.chunk, rows)
        if finished:
            del received[task.chunk]
        return finished

    try:
        while queue or isolate or inflight:
            if isolate:
                if not inflight:
                    submit(isolate.popleft())
            else:
                limit = window()
                while queue and len(inflight) < limit:
                    submit(queue.popleft())
            for future in distributed.wait(list(inflight), return_when="FIRST_COMPLETED").done:
                if future.status not in ("finished", "error", "cancelled"):
                    continue  # its result was lost with a worker before it came here: Dask computes it again
                task = inflight.pop(future)
                if future.status == "cancelled":
                    raise RuntimeError(
                        f"chunk {task.chunk}: the Dask task was cancelled (scheduler restarted or connection "
                        "lost); finish the campaign with --resume"
                    )
                try:
                    flown = future.result()  # any other exception of the task ends the campaign
                except distributed.KilledWorker:
                    hung = client.get_metadata([future.key, HUNG], default={})
                    finished = collect(task, _given_up(campaign, task, hung, guard, queue, isolate))
                else:
                    if sorted(row["run_id"] for row in flown.rows) != task.run_ids:
                        raise RuntimeError(f"chunk {task.chunk}: a task returned other runs than it was given")
                    finished = collect(task, flown.rows, flown)
                if finished:
                    yield finished
    finally:
        if inflight:  # interrupted or failed: stop what this campaign still has queued
            with suppress(Exception):  # the connection may be what failed
                client.cancel(list(inflight))


def _given_up(campaign, task, hung, guard, queue, isolate):
    """Error rows for the runs of a task Dask gave up (KilledWorker); queue its other runs again.

    A run recorded as hung is an error; the worker died of it, so the task's other runs go back to
    the queue. Otherwise each run of a chunk task is flown alone, and a task of one run flown
    alone that still kills its workers is that run's error.
    """
    errors = [error_row(campaign, run_id, _limit_reason(guard)) for run_id in task.run_ids if str(run_id) in hung]
    rest = [run_id for run_id in task.run_ids if str(run_id) not in hung]
    if task.isolated:
        errors += [error_row(campaign, run_id, DIED) for run_id in rest]
    elif errors:
        if rest:
            queue.appendleft(Task(task.chunk, rest))
    else:
        isolate.extend(Task(task.chunk, [run_id], isolated=True) for run_id in rest)
    return errors


class _Window:
    """Chunks to keep in flight: TASKS_PER_WORKER per worker thread of the cluster, asked now and then."""

    def __init__(self, client):
        self.client = client
        self.size = TASKS_PER_WORKER
        self.asked = None

    def __call__(self):
        now = time.monotonic()
        if self.asked is None or now - self.asked > WINDOW_REFRESH_S:
            threads = sum(self.client.nthreads().values())
            self.size = TASKS_PER_WORKER * max(1, threads)  # no worker yet: tasks wait at the scheduler
            self.asked = now
        return self.size


# --- the worker side ---------------------------------------------------------------------------

_fly_lock = threading.Lock()  # one task at a time per worker process: the watchdog guards one flight
_warm = False


def warm_up_once():
    """Warm this worker process up once, as a loky worker's initializer does (``worker.warm_up``):
    at its start on the LocalClusters refexmc starts (:mod:`refexmc.campaign.dask_preload`), in its
    first task elsewhere. Its imports and kernels are then frozen out of the garbage collector's
    reach, so that collections in the tasks and the process's exit do not walk them."""
    global _warm
    if not _warm:
        guarded.warm_up()
        _warm = True


def _report_hung(client, key, run_id):
    """The over-limit hook: record a hung run under its task's key before the worker ends itself."""
    with suppress(Exception):  # the worker is about to end; without the record the client gets KilledWorker
        client.set_metadata([key, HUNG, str(run_id)], True)


def _fly_task(campaign, run_ids, guard):
    """Run on a worker: fly ``run_ids`` under the watchdog, except runs an earlier attempt hung on."""
    import distributed

    key = distributed.get_worker().get_current_task()
    client = distributed.get_client()
    with _fly_lock:
        warm_up_once()
        hung = client.get_metadata([key, HUNG], default={})
        flown = [run_id for run_id in run_ids if str(run_id) not in hung]
        guarded.set_over_limit_hook(partial(_report_hung, client, key))
        try:
            result = guarded.fly_guarded(campaign, flown, guard)
        finally:
            guarded.set_over_limit_hook(None)
    if len(flown) == len(run_ids):
        return result
    reason = _limit_reason(guard)
    rows = result.rows + [error_row(campaign, run_id, reason) for run_id in run_ids if str(run_id) in hung]
    return guarded.Flown(sorted(rows, key=lambda row: row["run_id"]), None, result.history)
