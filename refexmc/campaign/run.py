"""Run a campaign: validate everything first, then fly chunks of runs in parallel into Parquet parts.

The parent process plans chunks of ``chunk_size`` runs, hands them to an execution backend
(:mod:`refexmc.campaign.backends`) and writes each chunk's ``runs`` and ``histories`` parts
atomically as it arrives, so that memory stays flat in the number of runs and a killed campaign
leaves only complete parts. ``resume`` flies exactly the chunks whose two parts are not both there.
"""

import math
import os
import shutil
from pathlib import Path

import pyarrow.parquet as pq
import yaml

import refexmc
from refexmc.campaign import storage
from refexmc.campaign.backends import BACKENDS, check_backend
from refexmc.campaign.progress import Progress
from refexmc.campaign.worker import Guard
from refexmc.config.errors import ConfigError
from refexmc.config.load import apply_overrides, load_campaign

MAX_CHUNK_SIZE = 100  # runs per chunk: ~0.5 s of flying, a 3 MB history part
MIN_CHUNK_SIZE = 10  # each chunk costs ~15 ms (two part files of ~150 columns), ~3 runs' flying
TARGET_CHUNKS = 32  # enough chunks that the last one to finish leaves the other workers idle briefly
CHUNK_SIZE_ENV = "REFEXMC_CHUNK_SIZE"  # runs per chunk for a new OUT (tests use small chunks)
DEFAULT_RUN_TIME_LIMIT_S = 60.0  # per-run wall-time limit when the campaign has no run_time_limit_s
DEFAULT_CAMPAIGN = Path(refexmc.__file__).resolve().parents[1] / "campaigns" / "refex-mc100.yaml"
WORK_DIR = ".refexmc-work"  # private to a running campaign: worker state files


def default_output(campaign):
    return Path("runs") / campaign["name"]


def default_jobs():
    """All cores this process may use."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1


def resolve_campaign(campaign_file=None, runs=None, seed=None):
    """The validated campaign with the overrides applied (ConfigError on bad input)."""
    if campaign_file is None:
        if not DEFAULT_CAMPAIGN.is_file():
            raise ConfigError(
                "the default campaign is missing (it ships with the source tree); give a CAMPAIGN file",
                file=DEFAULT_CAMPAIGN,
            )
        campaign_file = DEFAULT_CAMPAIGN
    campaign = apply_overrides(load_campaign(campaign_file), runs=runs, seed=seed)
    return campaign_file, campaign


def default_chunk_size(runs):
    """Runs per chunk: about TARGET_CHUNKS chunks, within [MIN_CHUNK_SIZE, MAX_CHUNK_SIZE].

    It depends on the number of runs only, not on the workers: the same campaign gives the same
    part files at any ``-j``. With 100-run chunks a 1,000-run campaign at ``-j 2`` can end with
    one worker flying the last chunk alone for ~0.5 s; with 32-run chunks for ~0.2 s. Smaller
    chunks cost more than they save (1,000 runs, ``-j 2``: 20-run chunks ~10 % slower than 32).
    """
    return min(MAX_CHUNK_SIZE, max(MIN_CHUNK_SIZE, math.ceil(runs / TARGET_CHUNKS)))


def _chunk_size(chunk_size, runs):
    if chunk_size is None:
        text = os.environ.get(CHUNK_SIZE_ENV, "").strip()
        if not text:
            return default_chunk_size(runs)
        try:
            chunk_size = int(text)
        except ValueError:
            raise ConfigError(f"expected an integer >= 1, got {text!r}", path=(CHUNK_SIZE_ENV,)) from None
    if chunk_size < 1:
        raise ConfigError(f"expected an integer >= 1, got {chunk_size}", path=("chunk_size",))
    return chunk_size


def check_resumable(out, campaign):
    """The manifest of ``out`` if it holds this very campaign; ConfigError (nothing changed) otherwise."""
    out = Path(out)
    resolved = out / "campaign.resolved.yaml"
    if not (out / "manifest.json").is_file() or not resolved.is_file():
        raise ConfigError(
            "cannot resume: not a refexmc output directory (no manifest.json or campaign.resolved.yaml); "
            "use --overwrite or another -o",
            file=out,
        )
    stored = yaml.safe_load(resolved.read_text())
    current = storage.normalized_campaign(campaign)
    if stored != current:
        keys = sorted(key for key in {*stored, *current} if stored.get(key) != current.get(key))
        raise ConfigError(
            f"cannot resume: it holds a different campaign (differs in {', '.join(keys)}); "
            "use --overwrite or another -o",
            file=out,
        )
    return storage.read_manifest(out)


def plan_chunks(runs, chunk_size):
    """[(chunk index, run ids)] covering run ids 0..runs-1."""
    return [(k, range(start, min(runs, start + chunk_size))) for k, start in enumerate(range(0, runs, chunk_size))]


def chunk_done(out, chunk):
    name = storage.part_name(chunk)
    return (Path(out) / "runs" / name).is_file() and (Path(out) / "histories" / name).is_file()


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
):
    """Validate and run a campaign file (default: DEFAULT_CAMPAIGN); return output path, counts, runs table.

    ``jobs``: worker processes (default all usable cores). ``progress``: 'bar', 'lines' or None.
    ``chunk_size``: runs per chunk of a new OUT (default ``$REFEXMC_CHUNK_SIZE`` or :func:`default_chunk_size`);
    a resumed OUT keeps the chunk size in its manifest. ``scheduler``: the Dask cluster of
    ``backend='dask'`` (an address, a scheduler file, or ``local:N``). Raises ConfigError for bad input and
    FileExistsError for an existing OUT without ``overwrite``/``resume``; in both cases nothing
    is written.
    """
    campaign_file, campaign = resolve_campaign(campaign_file, runs, seed)
    jobs = default_jobs() if jobs is None else jobs
    if jobs < 1:
        raise ConfigError(f"expected jobs >= 1, got {jobs}", path=("--jobs",))
    options = check_backend(backend, scheduler=scheduler)
    chunk_size = _chunk_size(chunk_size, campaign["runs"])
    out = Path(out) if out is not None else default_output(campaign)
    time_limit_s = float(campaign.get("run_time_limit_s", DEFAULT_RUN_TIME_LIMIT_S))

    previous = check_resumable(out, campaign) if resume and out.exists() else None
    storage.prepare_output(out, overwrite=overwrite, resume=resume)
    if previous:
        chunk_size = previous["chunk_size"]
        started = previous["started"]
        resumed = [*previous.get("resumed", []), storage.now()]
    else:
        started, resumed = storage.now(), []
        storage.write_resolved(out, campaign)
    execution = {
        "jobs": jobs,
        "backend": backend,
        "scheduler": scheduler,
        "run_time_limit_s": time_limit_s,
        "resumed": resumed,
    }
    storage.write_manifest(out, storage.manifest(campaign_file, campaign, chunk_size, "running", started, **execution))

    work = out / WORK_DIR
    shutil.rmtree(work, ignore_errors=True)  # a killed campaign's worker state
    work.mkdir()
    chunks = plan_chunks(campaign["runs"], chunk_size)
    todo = [(chunk, run_ids) for chunk, run_ids in chunks if not chunk_done(out, chunk)]
    meter = Progress(campaign["runs"], campaign["runs"] - sum(len(r) for _, r in todo), progress)
    try:
        guard = Guard.create(work, time_limit_s)
        for chunk, rows, runs, history in BACKENDS[backend](campaign, todo, jobs, guard, **options):
            name = storage.part_name(chunk)
            storage.write_bytes_atomic(history, out / "histories" / name)
            storage.write_bytes_atomic(runs, out / "runs" / name)
            meter.update(len(rows))
    finally:
        meter.close()
    shutil.rmtree(work, ignore_errors=True)

    table = pq.read_table(out / "runs").to_pandas().sort_values("run_id", ignore_index=True)
    counts = {
        "runs": int(len(table)),
        "ok": int((table["status"] == "ok").sum()),
        "error": int((table["status"] == "error").sum()),
        "success": int(table["success"].sum()),
    }
    info = storage.manifest(
        campaign_file, campaign, chunk_size, "complete", started, storage.now(), counts, **execution
    )
    storage.write_manifest(out, info)
    return {"out": out, "counts": counts, "runs": table, "campaign": campaign}
