"""The worker side of execution: fly a chunk's runs one at a time under a wall-time watchdog.

Every backend hands :func:`fly_guarded` to its worker processes. It draws the parameters of
the runs it was given together, then flies one run after another, so the worker always knows
which run it is flying. A watchdog thread (the flight kernel is numba ``nogil``, so the thread
runs while a flight does) ends the worker process with ``os._exit`` when one run exceeds
``Guard.time_limit_s``. Time spent compiling or loading the numba kernels is not counted (up to
``COMPILE_GRACE_S``, so that a run that hangs before the first flight of its worker is caught too).

Each worker keeps a 16-byte state file ``<state_dir>/worker-<pid>.state``, memory-mapped so that
an update costs nothing and outlives the process: the run id being flown and whether it is
flying or over its time limit. After a worker died, the parent reads these files
(:func:`collect_states`) to learn which run hung (over the limit) or which runs were in flight
when a worker crashed. A backend whose workers share no file system with the parent (Dask)
passes ``state_dir=None`` (the state lives in anonymous memory) and learns of a hung run from
an over-limit hook (:func:`set_over_limit_hook`) that the watchdog calls before it ends the worker.

Test hooks (for tests of this machinery only; never active unless set): the parent reads
``REFEXMC_TEST_HANG_RUN=<run_id>`` (that run is flown, then sleeps forever) and
``REFEXMC_TEST_CRASH_RUN=<run_id>`` (that run kills its worker with SIGSEGV) when it builds
the :class:`Guard` (:meth:`Guard.create`), and passes them to the workers as arguments.
"""

import gc
import importlib
import mmap
import os
import signal
import struct
import threading
import time
from pathlib import Path
from typing import NamedTuple

import pyarrow as pa

from refexmc.campaign import storage

TEST_HANG_ENV = "REFEXMC_TEST_HANG_RUN"
TEST_CRASH_ENV = "REFEXMC_TEST_CRASH_RUN"

IDLE, FLYING, OVER_LIMIT = 0, 1, 2
EXIT_OVER_LIMIT = 70  # exit status of a worker ended by its watchdog
_STATE = struct.Struct("<qq")  # run id (-1 when idle), IDLE | FLYING | OVER_LIMIT
_POLL_S = 0.1
COMPILE_GRACE_S = 300.0  # the most time a worker's first run may spend compiling kernels, uncounted
HOOK_TIMEOUT_S = 10.0  # the most time the over-limit hook may take before the watchdog ends the worker


class Guard(NamedTuple):
    """What a worker needs besides the campaign: where its state file goes, the time limit, test hooks."""

    state_dir: str | None  # absolute: workers do not follow the parent's working directory; None: no file
    time_limit_s: float
    test_hang_run: int | None = None
    test_crash_run: int | None = None

    @classmethod
    def create(cls, state_dir, time_limit_s):
        """A guard for ``state_dir``, with the test hooks taken from the environment (normally unset)."""

        def hook(name):
            value = os.environ.get(name, "").strip()
            return int(value) if value else None

        return cls(str(Path(state_dir).resolve()), float(time_limit_s), hook(TEST_HANG_ENV), hook(TEST_CRASH_ENV))


class _Flight:
    """The run a worker is flying, as its watchdog sees it."""

    def __init__(self, run_id, time_limit_s, state):
        self.run_id = run_id
        self.time_limit_s = time_limit_s
        self.state = state
        self.start = time.monotonic()
        self.grace_until = self.start + COMPILE_GRACE_S


_lock = threading.Lock()
_current = None  # _Flight or None; set and cleared by fly_guarded, read by the watchdog
_watchdog = None
_over_limit_hook = None  # called with the run id of a hung run before the watchdog ends the worker


def set_over_limit_hook(hook):
    """Have the watchdog call ``hook(run_id)`` when a run exceeds its limit, before it ends the worker.

    The hook runs in a thread of its own, for at most HOOK_TIMEOUT_S; ``None`` removes it.
    """
    global _over_limit_hook
    _over_limit_hook = hook


def _call_over_limit_hook(run_id):
    hook = _over_limit_hook
    if hook is not None:
        reporter = threading.Thread(target=hook, args=(run_id,), name="refexmc-over-limit", daemon=True)
        reporter.start()
        reporter.join(HOOK_TIMEOUT_S)


def _kernels_compiled():
    """True while every flight kernel this worker asked for is compiled or loaded from the cache
    (or JIT is disabled): a campaign of another vehicle family compiles a kernel of its own."""
    from refexmc.simulate import kernels_loaded

    return kernels_loaded()


def _watch():
    while True:
        time.sleep(_POLL_S)
        with _lock:
            flight = _current
            if flight is None:
                continue
            now = time.monotonic()
            if not _kernels_compiled() and now < flight.grace_until:
                flight.start = now  # compiling is not the run's time
                continue
            if now - flight.start > flight.time_limit_s:
                _STATE.pack_into(flight.state, 0, flight.run_id, OVER_LIMIT)
                _call_over_limit_hook(flight.run_id)
                os._exit(EXIT_OVER_LIMIT)


def _start_watchdog():
    global _watchdog
    if _watchdog is None or not _watchdog.is_alive():
        _watchdog = threading.Thread(target=_watch, name="refexmc-watchdog", daemon=True)
        _watchdog.start()


def _open_state(state_dir):
    if state_dir is None:  # nobody reads it after the worker is gone
        state = mmap.mmap(-1, _STATE.size)
        _STATE.pack_into(state, 0, -1, IDLE)
        return state
    path = Path(state_dir) / f"worker-{os.getpid()}.state"
    fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
    try:
        os.ftruncate(fd, _STATE.size)
        state = mmap.mmap(fd, _STATE.size)
    finally:
        os.close(fd)
    _STATE.pack_into(state, 0, -1, IDLE)
    return state


def _set_current(flight):
    global _current
    with _lock:
        _current = flight


def _test_hooks(guard, run_id):
    """Called after the run has flown (so the kernels are compiled): hang or crash on request."""
    if run_id == guard.test_hang_run:
        while True:  # a hung run, for the tests of the watchdog
            time.sleep(1.0)
    if run_id == guard.test_crash_run:
        os.kill(os.getpid(), signal.SIGSEGV)  # a crashing run, for the tests of crash recovery


class Flown(NamedTuple):
    """What a worker returns for the runs it was given.

    ``rows`` (dicts) serve the bookkeeping of the process that writes the parts; ``runs`` and
    ``history`` are those parts as Parquet file bytes (runs in the order given; ``history`` None
    when no run has one). Encoding here keeps the writing process from being the bottleneck:
    a 20-run runs part costs ~25 ms to build and compress, about the time of flying 4 runs.
    """

    rows: list
    runs: bytes | None
    history: bytes | None

    @classmethod
    def encode(cls, rows, histories=()):
        runs = storage.encode_table(storage.runs_table(rows)) if rows else None
        return cls(rows, runs, storage.encode_table(pa.concat_tables(histories)) if histories else None)


def ignore_interrupts():
    """Worker initializer: Ctrl-C (SIGINT to the terminal's process group) is for the parent to handle.

    The parent stops the campaign and its workers; a worker that raised KeyboardInterrupt in the
    middle of a run would only add tracebacks to the terminal.
    """
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def warm_up():
    """Worker start-up that no run should pay for: imports, numba's target, the keyed-uniform
    kernels from the disk cache (~1 s on 2 cores). Each loky worker does it as it starts
    (:mod:`refexmc.campaign.pool`), while the parent still prepares the campaign, which it does
    not know yet: the flight kernel of the campaign's vehicle family is loaded with the
    campaign's plan, before the first run is watched (:func:`fly_guarded`).

    What it loaded lives as long as the worker: frozen, the garbage collector skips it (loky
    collects after a worker's first task, ~0.1 s with all this loaded).
    """
    try:
        importlib.import_module("refexmc.campaign.chunk")
        importlib.import_module("scipy.special")  # every dispersed draw's inverse CDFs
        importlib.import_module("refexmc.simulate").load_kernels()
    except Exception:  # noqa: BLE001 - the runs meet it again, and become error rows
        pass
    gc.freeze()


def fly_guarded(campaign, run_ids, guard):
    """Fly ``run_ids`` one by one under the watchdog; return a :class:`Flown`.

    The runs' parameters are drawn together first (``RunPlan.prepare_runs``: one vectorised draw
    per parameter path), then each run is flown with its own time limit, and the history table
    of the runs that flew is built once (``storage.histories_table``).
    """
    from refexmc.campaign.chunk import plan_for  # here: the parent imports this module, never flies

    plan = plan_for(campaign)  # imports and sampling designs: not a run's time
    plan.load_kernels()  # the campaign's flight kernel, from the disk cache: not a run's time either
    rate = campaign["output"]["history_rate_hz"]
    prepared = plan.prepare_runs(run_ids)
    _start_watchdog()
    state = _open_state(guard.state_dir)
    rows, flown = [], {}
    try:
        for run_id, run_prepared in zip(run_ids, prepared, strict=True):
            _STATE.pack_into(state, 0, run_id, FLYING)
            _set_current(_Flight(run_id, guard.time_limit_s, state))
            row, result = plan.fly_run(run_id, rate, run_prepared)
            _test_hooks(guard, run_id)
            _set_current(None)
            _STATE.pack_into(state, 0, -1, IDLE)
            rows.append(row)
            if result is not None:
                flown[run_id] = result
    finally:
        _set_current(None)
        state.close()
    history = storage.histories_table(list(flown), list(flown.values())) if flown else None
    return Flown.encode(rows, [history] if history is not None else [])


def collect_states(state_dir):
    """Read and delete the state files of workers that are gone: {pid: (run id, state)}.

    Call only when no worker of ``state_dir`` can still be running (after their pool broke).
    """
    states = {}
    for path in Path(state_dir).glob("worker-*.state"):
        data = path.read_bytes()
        if len(data) == _STATE.size:
            states[int(path.name[len("worker-") : -len(".state")])] = _STATE.unpack(data)
        path.unlink()
    return states
