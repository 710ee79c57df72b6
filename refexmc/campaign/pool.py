"""This process's pool of worker processes (joblib's loky executor): started early, warm before the first chunk,
killed when done.

A worker takes ~1 s to be ready for its first run on 2 cores: spawning and importing (~0.5 s),
numba's target and the kernels from the disk cache (~0.5 s). Each worker does that start-up in
its initializer (:func:`refexmc.campaign.worker.warm_up`), without waiting for a task, so that
starting the pool early hides it behind the parent's own start-up: ``refexmc run`` starts its
workers (one per job) before it imports the campaign machinery (pyarrow) and validates the
campaign, which is why this module imports nothing but joblib's executor.

The runs fan out through joblib, the design's choice for it: its reusable executor
(``joblib.externals.loky``, the one behind ``joblib.Parallel``'s default backend), used directly
rather than through ``Parallel``, because the backend needs what ``Parallel`` hides: workers
started before the first task with an initializer, a bounded window of futures handled in
completion order, and a crashed worker's exit codes (``TerminatedWorkerError``).

Every user asks for the executor through :func:`executor`, with the same initializer: loky
replaces an executor asked for with other arguments, killing its workers. A complete campaign
leaves its workers to the next one in this process (loky ends them after 10 s idle); :func:`stop`
kills them at once.
"""

import os
import threading

from joblib.externals.loky import get_reusable_executor

# loky's resource tracker, a process of its own that inherits this environment, warns when it exits
# about the semaphores of an executor killed while its workers were still starting (bad input found
# in the first second of `refexmc run`, under load). It unlinks them itself, and the
# FileNotFoundError it reports next shows they were gone already; its warnings would follow the
# command's one error message on stderr (seen in CI: tests/test_bad_input.py). Only its messages,
# which begin "resource_tracker", are ignored.
QUIET_RESOURCE_TRACKER = "ignore:resource_tracker:UserWarning"

_executor = None  # the executor this process asked for last: what stop() kills
_early = 0  # workers start_early() started for the command under way (0: none)


def usable_cores():
    """All cores this process may use: the default number of workers (``refexmc run -j``)."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1


def _start_worker():
    """Each worker's initializer: Ctrl-C is the parent's to handle; then warm up."""
    from refexmc.campaign import worker  # pyarrow and the kernels: the worker's business, not the parent's

    worker.ignore_interrupts()
    worker.warm_up()


def executor(workers):
    """joblib's reusable loky executor with ``workers`` worker processes (spawned with its first task)."""
    global _executor
    _quiet_resource_tracker()
    _executor = get_reusable_executor(max_workers=workers, initializer=_start_worker)
    return _executor


def _quiet_resource_tracker():
    """Add :data:`QUIET_RESOURCE_TRACKER` to ``PYTHONWARNINGS`` (after the user's own filters) before
    loky starts its resource tracker."""
    filters = os.environ.get("PYTHONWARNINGS", "")
    if QUIET_RESOURCE_TRACKER not in filters.split(","):
        os.environ["PYTHONWARNINGS"] = ",".join(f for f in (filters, QUIET_RESOURCE_TRACKER) if f)


def start(workers):
    """Have ``workers`` worker processes start now: they warm up before any task comes."""
    executor(workers).submit(int)  # loky spawns the workers it lacks when a task is submitted


def start_early(workers):
    """:func:`start` ``workers`` workers before the campaign is read (``refexmc run``): one per job,
    as the campaign's number of chunks is not known yet."""
    global _early
    start(workers)
    _early = workers


def started_early():
    """The workers :func:`start_early` started for the command under way (0: none). The campaign
    flies on all of them: shrinking a pool whose workers still warm up waits for them."""
    return _early if _executor is not None else 0


def stop():
    """Kill the workers of the executor this process asked for last, if any; return when they are gone."""
    global _executor, _early
    _early = 0
    if _executor is not None:
        kill(_executor)
        _executor = None


def kill(executor):
    """Shut ``executor`` down, killing its workers; return when they are gone.

    loky's manager thread can trip over the work queue it has just cleared (a KeyError in
    ``add_call_item_to_queue``, loky 3.6) when tasks are still queued: the workers are killed
    all the same, so that thread's traceback is not printed over the user's message.
    """
    previous = threading.excepthook

    def quiet(args):
        if args.thread is None or args.thread.name != "ExecutorManagerThread":
            previous(args)

    threading.excepthook = quiet
    try:
        executor.shutdown(wait=True, kill_workers=True)
    finally:
        threading.excepthook = previous
