"""Run a campaign: validate everything first, then fly chunks of runs in parallel into Parquet parts.

The parent process plans chunks of ``chunk_size`` runs, hands them to an execution backend
(:mod:`refexmc.campaign.backends`) and writes each chunk's ``runs`` and ``histories`` parts
atomically as it arrives, so that memory stays flat in the number of runs and a killed campaign
leaves only complete parts. ``resume`` flies exactly the chunks whose two parts are not both there
and sound (readable, holding the chunk's runs). SIGINT and SIGTERM stop the workers and keep what is done.
"""

import importlib
import math
import os
import shlex
import shutil
import signal
import sys
import threading
from contextlib import closing, contextmanager, suppress
from pathlib import Path

import yaml

import refexmc
from refexmc.campaign import lock, pool, storage
from refexmc.campaign.backends import BACKENDS, check_backend, start_workers, stop_workers
from refexmc.campaign.progress import Progress
from refexmc.campaign.worker import Guard
from refexmc.config import renames
from refexmc.config.design_checks import strict_error
from refexmc.config.errors import ConfigError
from refexmc.config.load import apply_overrides, load_campaign
from refexmc.config.schema import DEFAULT_RUN_TIME_LIMIT_S

MAX_CHUNK_SIZE = 100  # runs per chunk: ~0.5 s of flying, a 3 MB history part
MIN_CHUNK_SIZE = 10  # each chunk costs ~15 ms (two part files of ~150 columns), ~3 runs' flying
# the GPU backend's: its host workers pay per chunk (two loky tasks, the prepared chunk's metadata
# sent back, two parts of ~130 columns each) ~3 ms of the refexmc run process's CPU and ~10 ms of theirs;
# 1,000 runs is ~1 s of a worker's host work and a 15 MB ReFEx history part (benchmarks/RESULTS.md)
MAX_GPU_CHUNK_SIZE = 1000
TARGET_CHUNKS = 32  # enough chunks that the last one to finish leaves the other workers idle briefly
CHUNK_SIZE_ENV = "REFEXMC_CHUNK_SIZE"  # runs per chunk for a new OUT (tests use small chunks)
DEFAULT_CAMPAIGN = Path(refexmc.__file__).resolve().parents[1] / "campaigns" / "refex-mc100.yaml"
WORK_DIR = storage.WORK_DIR


def default_output(campaign):
    return Path("runs") / campaign["name"]


def default_jobs():
    """All cores this process may use."""
    return pool.usable_cores()


def resolve_campaign(campaign_file=None, runs=None, seed=None, warnings=None):
    """The validated campaign with the overrides applied (ConfigError on bad input); its design
    warnings (config.design_checks) are appended to the list ``warnings``."""
    if campaign_file is None:
        if not DEFAULT_CAMPAIGN.is_file():
            raise ConfigError(
                "the default campaign is missing (it ships with the source tree); give a CAMPAIGN file",
                file=DEFAULT_CAMPAIGN,
            )
        campaign_file = DEFAULT_CAMPAIGN
    campaign = apply_overrides(load_campaign(campaign_file, warnings), runs=runs, seed=seed)
    return campaign_file, campaign


def default_chunk_size(runs, backend="loky"):
    """Runs per chunk: about TARGET_CHUNKS chunks, within [MIN_CHUNK_SIZE, MAX_CHUNK_SIZE] (the
    ``cuda`` backend: MAX_GPU_CHUNK_SIZE).

    It depends on the number of runs and the backend only, not on the workers: the same campaign
    gives the same part files at any ``-j``. With 100-run chunks a 1,000-run campaign at ``-j 2``
    can end with one worker flying the last chunk alone for ~0.5 s; with 32-run chunks for ~0.2 s.
    Smaller chunks cost more than they save (1,000 runs, ``-j 2``: 20-run chunks ~10 % slower).
    On the GPU a chunk is host work only (drawing, naming, encoding), whose cost per chunk
    bounds a million-run campaign: larger chunks.
    """
    largest = MAX_GPU_CHUNK_SIZE if backend == "cuda" else MAX_CHUNK_SIZE
    return min(largest, max(MIN_CHUNK_SIZE, math.ceil(runs / TARGET_CHUNKS)))


def _chunk_size(chunk_size, runs, backend="loky"):
    if chunk_size is None:
        text = os.environ.get(CHUNK_SIZE_ENV, "").strip()
        if not text:
            return default_chunk_size(runs, backend)
        try:
            chunk_size = int(text)
        except ValueError:
            raise ConfigError(f"expected an integer >= 1, got {text!r}", path=(CHUNK_SIZE_ENV,)) from None
    if chunk_size < 1:
        raise ConfigError(f"expected an integer >= 1, got {chunk_size}", path=("chunk_size",))
    return chunk_size


def check_resumable(out, campaign, extend=False):
    """The manifest of ``out`` if it holds this very campaign; ConfigError (nothing changed) otherwise.

    ``extend``: a campaign that differs only in having at least as many runs is accepted too (its
    first runs are those stored: ``refexmc run --until-decided``, refexmc.campaign.decided).
    """
    out = Path(out)
    resolved = out / "campaign.resolved.yaml"
    if not (out / "manifest.json").is_file() or not resolved.is_file():
        raise ConfigError(
            "cannot resume: not a refexmc output directory (no manifest.json or campaign.resolved.yaml); "
            "use --overwrite or another -o",
            file=out,
        )
    try:
        stored = yaml.safe_load(resolved.read_text())
        manifest = storage.read_manifest(out)
    except (yaml.YAMLError, ValueError) as exc:  # damaged: what was flown cannot be known
        reason = " ".join(str(exc).split())
        raise ConfigError(
            f"cannot resume: unreadable manifest or resolved campaign ({reason}); remove OUT or use another -o",
            file=out,
        ) from None
    if not isinstance(stored, dict):
        raise ConfigError(
            "cannot resume: campaign.resolved.yaml holds no campaign; remove OUT or use another -o", file=out
        )
    renames.migrate_campaign(stored)  # an output written before a rename (issue 34) holds its campaign
    current = storage.normalized_campaign(campaign)
    if extend and isinstance(stored.get("runs"), int) and stored["runs"] <= current["runs"]:
        stored = {**stored, "runs": current["runs"]}
    if stored != current:
        keys = sorted(key for key in {*stored, *current} if stored.get(key) != current.get(key))
        raise ConfigError(
            f"cannot resume: it holds a different campaign (differs in {', '.join(keys)}); "
            "use --overwrite or another -o",
            file=out,
        )
    if manifest.get("flight_code") != storage.flight_code():
        flown_by = manifest.get("flight_code") or "code of before issue 37, which recorded none"
        raise ConfigError(
            f"cannot resume: its runs were flown by other flight code ({flown_by}; now {storage.flight_code()}: "
            "refexmc/core or numba changed), whose bits the runs flown now would not match; "
            "use --overwrite or another -o",
            file=out,
        )
    return manifest


def plan_chunks(runs, chunk_size):
    """[(chunk index, run ids)] covering run ids 0..runs-1."""
    return [(k, range(start, min(runs, start + chunk_size))) for k, start in enumerate(range(0, runs, chunk_size))]


def chunk_done(out, chunk):
    name = storage.part_name(chunk)
    return (Path(out) / "runs" / name).is_file() and (Path(out) / "histories" / name).is_file()


def chunks_to_fly(out, chunks, notify):
    """The chunks of ``chunks`` without two sound parts in OUT; a damaged part is reported to ``notify``."""
    todo = []
    for chunk, run_ids in chunks:
        problem = storage.part_problem(out, chunk, run_ids) if chunk_done(out, chunk) else "missing"
        if problem is None:
            continue
        if problem != "missing":
            notify(f"{out}: chunk {chunk} (runs {run_ids[0]}..{run_ids[-1]}) is damaged, flying it again: {problem}")
        todo.append((chunk, run_ids))
    return todo


class CampaignInterrupted(Exception):
    """SIGINT or SIGTERM stopped a campaign; every chunk completed before it is kept in ``out``."""

    def __init__(self, signum, out=None, done=0, total=0):
        self.signum = signum
        self.out = out
        self.done = done
        self.total = total
        super().__init__(f"interrupted by {signal.Signals(signum).name}")

    @property
    def exit_code(self):
        """The shell's code for a process ended by the signal: 130 (SIGINT), 143 (SIGTERM)."""
        return 128 + self.signum


STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)


@contextmanager
def stop_on_signals():
    """In the body, SIGINT and SIGTERM raise :class:`CampaignInterrupted` (main thread only).

    After the first, both are ignored until the body is left, so that a second Ctrl-C does not cut
    short the cleanup (workers stopped, lock released); the previous handlers come back afterwards.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def interrupt(signum, frame):
        for number in STOP_SIGNALS:
            signal.signal(number, signal.SIG_IGN)
        raise CampaignInterrupted(signum)

    previous = {number: signal.signal(number, interrupt) for number in STOP_SIGNALS}
    try:
        yield
    finally:
        for number, handler in previous.items():
            signal.signal(number, handler if handler is not None else signal.SIG_DFL)


def resume_command(campaign_file=None, out=None, runs=None, seed=None, backend="loky", scheduler=None):
    """The `refexmc run ... --resume` command line that finishes this campaign (shell-quoted)."""
    words = ["refexmc", "run"]
    if campaign_file is not None:
        words.append(str(campaign_file))
    if out is not None:
        words += ["-o", str(out)]
    words.append("--resume")
    for option, value in (("--runs", runs), ("--seed", seed)):
        if value is not None:
            words += [option, str(value)]
    if backend != "loky":
        words += ["--backend", backend]
    if scheduler is not None:
        words += ["--scheduler", str(scheduler)]
    return shlex.join(words)


def notify_stderr(message):
    print(f"refexmc: {message}", file=sys.stderr, flush=True)


def run_campaign(
    campaign_file=None,
    out=None,
    runs=None,
    seed=None,
    jobs=None,
    backend="loky",
    overwrite=False,
    resume=False,
    progress=None,
    chunk_size=None,
    scheduler=None,
    notify=notify_stderr,
    strict=False,
    extend=False,
):
    """Validate and run a campaign file (default: DEFAULT_CAMPAIGN); return output path, counts, runs table.

    ``jobs``: worker processes (default all usable cores). ``progress``: 'bar', 'lines' or None, or a
    caller's :class:`Progress` over more runs than this call flies (left open for its next call).
    ``chunk_size``: runs per chunk of a new OUT (default ``$REFEXMC_CHUNK_SIZE`` or :func:`default_chunk_size`);
    a resumed OUT keeps the chunk size in its manifest. ``scheduler``: the Dask cluster of
    ``backend='dask'`` (an address, a scheduler file, or ``local:N``). ``notify(message)``: what
    the user should know on the way (a damaged part flown again, a stale lock taken over), and
    each design warning of the campaign (config.design_checks; also in ``manifest.json``'s
    ``design_warnings``); ``strict``: a design warning is bad input instead.
    ``extend`` (with ``resume``): OUT may hold the same campaign with fewer runs; the missing runs
    are added (refexmc.campaign.decided).

    OUT is locked for the whole campaign (:mod:`refexmc.campaign.lock`). Raises ConfigError for
    bad input, an OUT this run may not write (:func:`storage.check_output`) or one another run
    holds, with nothing written; :class:`CampaignInterrupted` on SIGINT/SIGTERM (workers stopped,
    completed chunks kept); OSError when OUT cannot be written.

    The workers start as soon as OUT is locked, and warm up while OUT is prepared; whatever ends
    the campaign early kills them. After a complete campaign they are left to the next one in this
    process (:func:`refexmc.campaign.backends.stop_workers` ends them).
    """
    design_warnings = []
    campaign_file, campaign = resolve_campaign(campaign_file, runs, seed, design_warnings)
    if strict and design_warnings:
        raise strict_error(design_warnings)
    for warning in design_warnings:
        notify(f"warning: {warning}")
    jobs = default_jobs() if jobs is None else jobs
    if jobs < 1:
        raise ConfigError(f"expected jobs >= 1, got {jobs}", path=("--jobs",))
    if "rare_event" in campaign:  # its levels follow one another (refexmc.campaign.rare_event)
        raise ConfigError(
            "a rare-event study flies level by level with `refexmc run` (not --until-decided)", file=campaign_file
        )
    if "sweep" in campaign:  # every point a campaign of its own
        raise ConfigError(
            "a sweep flies with refexmc.campaign.sweep.run_campaign_or_sweep (`refexmc run`)", file=campaign_file
        )
    options = check_backend(backend, campaign=campaign, scheduler=scheduler)
    out = Path(out) if out is not None else default_output(campaign)
    flight = {
        "campaign_file": campaign_file,
        "campaign": campaign,
        "out": out,
        "chunk_size": _chunk_size(chunk_size, campaign["runs"], backend),
        "execution": {
            "jobs": jobs,
            "backend": backend,
            "scheduler": scheduler,
            "run_time_limit_s": float(campaign.get("run_time_limit_s", DEFAULT_RUN_TIME_LIMIT_S)),
        },
        "design_warnings": [str(w) for w in design_warnings],
    }

    def check():
        """The manifest of the OUT to resume (None for a new one); ConfigError when OUT is not to be written."""
        storage.check_output(out, overwrite=overwrite, resume=resume, protect=[campaign_file])
        return check_resumable(out, campaign, extend) if resume and not storage.is_empty(out) else None

    lock.check_free(out)
    check()  # before OUT is created or locked: a refusal leaves no trace
    with stop_on_signals(), lock.locked(out, notify):
        try:
            previous = check()  # again, now that no other run can change OUT
            with _workers_stopped_on_error():
                options = {**options, **_start_workers(flight, previous)}
                storage.prepare_output(out, overwrite=overwrite, resume=resume, protect=[campaign_file])
                return _run_locked(flight, previous, options, progress, notify)
        except CampaignInterrupted as exc:
            exc.out, exc.total = out, campaign["runs"]
            exc.done = _runs_done(out, campaign["runs"])
            raise


def _start_workers(flight, previous):
    """Start the backend's workers, one per chunk up to ``jobs``; the backend options that fly on them.

    A resumed OUT may need fewer: its chunks still to fly are known only once its parts are read.
    """
    chunk_size = previous["chunk_size"] if previous else flight["chunk_size"]
    chunks = len(plan_chunks(flight["campaign"]["runs"], chunk_size))
    execution = flight["execution"]
    return start_workers(execution["backend"], max(1, min(execution["jobs"], chunks)))


@contextmanager
def _workers_stopped_on_error():
    """Kill the workers when the body raises: a campaign that ends early leaves none running."""
    try:
        yield
    except BaseException:
        stop_workers()
        raise


def _runs_done(out, runs):
    """How many runs of OUT have both parts (0 when OUT has no manifest yet)."""
    if not storage.is_output(out):
        return 0
    chunks = plan_chunks(runs, storage.read_manifest(out)["chunk_size"])
    return sum(len(run_ids) for chunk, run_ids in chunks if chunk_done(out, chunk))


def _run_locked(flight, previous, options, progress, notify):
    """Fly what OUT (prepared and locked) still needs and write the manifest; the result of :func:`run_campaign`."""
    campaign_file, campaign, out = flight["campaign_file"], flight["campaign"], flight["out"]
    if previous:
        chunk_size, started = previous["chunk_size"], previous["started"]
        resumed = [*previous.get("resumed", []), storage.now()]
        if previous["runs"] != campaign["runs"]:  # extended (check_resumable): now it holds more runs
            storage.write_resolved(out, campaign)
    else:
        chunk_size, started, resumed = flight["chunk_size"], storage.now(), []
        storage.write_resolved(out, campaign)
    execution = {**flight["execution"], "resumed": resumed, "design_warnings": flight["design_warnings"]}

    def write_manifest(status, finished=None, counts=None):
        info = storage.manifest(campaign_file, campaign, chunk_size, status, started, finished, counts, **execution)
        storage.write_manifest(out, info)

    chunks = plan_chunks(campaign["runs"], chunk_size)
    todo = chunks_to_fly(out, chunks, notify) if previous else chunks
    if todo:
        storage.remove_report(out)  # it would describe other contents
    write_manifest("running")
    if isinstance(progress, Progress):  # the caller's meter over all its runs (run --until-decided's budget)
        meter, closes = progress, False
        meter.start()
    else:
        meter, closes = Progress(campaign["runs"], campaign["runs"] - sum(len(r) for _, r in todo), progress), True
    pandas = _import_meanwhile("pandas")
    try:
        _fly(campaign, todo, out, execution, options, meter)
    except BaseException as exc:
        meter.close()  # a caller's too: nothing more flies
        if isinstance(exc, CampaignInterrupted):
            with suppress(OSError):
                write_manifest("interrupted")
        raise
    finally:
        pandas.join()
    if closes:
        meter.close()

    table = read_runs(out, chunks)
    counts = {
        "runs": int(len(table)),
        "ok": int((table["status"] == "ok").sum()),
        "error": int((table["status"] == "error").sum()),
        "success": int(table["success"].sum()),
    }
    write_manifest("complete", storage.now(), counts)
    return {"out": out, "counts": counts, "runs": table, "campaign": campaign}


def _import_meanwhile(module):
    """Import ``module`` in a thread of its own (started, to be joined): the parent waits for the
    workers most of a campaign, and importing pandas when the runs are in costs ~0.4 s."""
    importer = threading.Thread(target=importlib.import_module, args=(module,), name=f"refexmc-import-{module}")
    importer.start()
    return importer


def read_runs(out, chunks):
    """The runs table of ``chunks`` in OUT (a DataFrame sorted by run id).

    Part by part: reading the folder would import pyarrow.dataset (~0.4 s) for a few small files.
    """
    parts = [out / "runs" / storage.part_name(chunk) for chunk, _ in chunks]
    return storage.read_runs_parts(parts).to_pandas().sort_values("run_id", ignore_index=True)


def _fly(campaign, todo, out, execution, options, meter):
    """Fly the chunks ``todo`` on ``backend``, writing each chunk's parts into OUT as it completes."""
    work = out / WORK_DIR
    shutil.rmtree(work, ignore_errors=True)  # a killed campaign's worker state
    work.mkdir()
    try:
        guard = Guard.create(work, execution["run_time_limit_s"])
        backend = BACKENDS[execution["backend"]](campaign, todo, execution["jobs"], guard, **options)
        with closing(backend) as flown:  # an exception here (a signal, a full disk) stops the workers at once
            for chunk, rows, runs, history in flown:
                name = storage.part_name(chunk)
                storage.place_part(history, out / "histories" / name)
                storage.place_part(runs, out / "runs" / name)
                meter.update(len(rows))
    finally:
        shutil.rmtree(work, ignore_errors=True)
