"""Run a campaign: validate everything first, then fly chunks of runs into Parquet parts.

This version flies campaigns without dispersions (every run the nominal vehicle and mission,
with the campaign's fixed thruster failures and per-run navigation-noise seeds).
"""

import time
from pathlib import Path

import pyarrow as pa
import pyarrow.parquet as pq

from refexmc.campaign import storage
from refexmc.campaign.chunk import fly_chunk
from refexmc.config.errors import ConfigError
from refexmc.config.load import load_campaign

CHUNK_SIZE = 100


def default_output(campaign):
    return Path("runs") / campaign["name"]


def run_campaign(campaign_file, out=None, runs=None, seed=None, overwrite=False, resume=False, log=None):
    """Validate and run a campaign file; return a dict with the output path and run counts.

    Raises ConfigError for bad input (nothing written) and FileExistsError for an existing
    OUT without ``overwrite``/``resume``.
    """
    campaign = load_campaign(campaign_file)
    if campaign["dispersions"]:
        raise ConfigError("dispersions are not supported by this version", file=campaign_file, path=("dispersions",))
    if runs is not None:
        if runs < 1:
            raise ConfigError(f"expected runs >= 1, got {runs}", path=("--runs",))
        campaign["runs"] = runs
    if seed is not None:
        if seed < 0:
            raise ConfigError(f"expected seed >= 0, got {seed}", path=("--seed",))
        campaign["seed"] = seed
    out = Path(out) if out is not None else default_output(campaign)
    storage.prepare_output(out, overwrite=overwrite, resume=resume)
    started = storage.now()
    storage.write_resolved(out, campaign)
    storage.write_manifest(out, storage.manifest(campaign_file, campaign, CHUNK_SIZE, "running", started))

    n_chunks = (campaign["runs"] + CHUNK_SIZE - 1) // CHUNK_SIZE
    t0 = time.perf_counter()
    for chunk in range(n_chunks):
        name = storage.part_name(chunk)
        if resume and (out / "runs" / name).exists() and (out / "histories" / name).exists():
            continue
        run_ids = range(chunk * CHUNK_SIZE, min(campaign["runs"], (chunk + 1) * CHUNK_SIZE))
        rows, histories = fly_chunk(campaign, run_ids)
        if histories:
            storage.write_table_atomic(pa.concat_tables(histories), out / "histories" / name)
        storage.write_table_atomic(storage.runs_table(rows), out / "runs" / name)
        if log:
            log(f"{run_ids.stop}/{campaign['runs']} runs, {time.perf_counter() - t0:.1f} s")

    table = pq.read_table(out / "runs").to_pandas()
    counts = {
        "runs": int(len(table)),
        "ok": int((table["status"] == "ok").sum()),
        "error": int((table["status"] == "error").sum()),
        "success": int(table["success"].sum()),
    }
    storage.write_manifest(
        out, storage.manifest(campaign_file, campaign, CHUNK_SIZE, "complete", started, storage.now(), counts)
    )
    return {"out": out, "counts": counts, "runs": table, "campaign": campaign}
