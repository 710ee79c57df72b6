"""Fly a sweep (campaign key ``sweep``, refexmc.config.sweep): every point a plain campaign in
``OUT/points/NNN/``, written by :func:`refexmc.campaign.run.run_campaign` from the point's
resolved campaign file ``OUT/points/NNN.yaml``.

OUT holds the sweep's ``manifest.json`` (``sweep``: the axes and each point's values and folder)
and ``campaign.resolved.yaml``; each point folder is an ordinary campaign output (``report``,
``rerun`` and ``compare`` work on it as on any). Every point flies the same run ids with the same
seeds (common random numbers). ``resume`` flies only what is missing: the points not started and
the chunks a killed point lacks; ``-j`` and the Dask backend fly each point as they fly a campaign.
"""

import shutil
from pathlib import Path

from refexmc.campaign import lock, storage
from refexmc.campaign.backends import check_backend
from refexmc.campaign.run import (
    CampaignInterrupted,
    check_resumable,
    default_output,
    notify_stderr,
    resolve_campaign,
    run_campaign,
)
from refexmc.config import sweep as sweep_config
from refexmc.config.errors import ConfigError
from refexmc.config.load import load_campaign

POINTS_DIR = "points"
MANIFEST_KEY = "sweep"


def point_folder(index):
    return f"{POINTS_DIR}/{index:03d}"


def is_sweep(out):
    """Whether OUT is a sweep's output (its manifest says so)."""
    path = Path(out) / "manifest.json"
    return path.is_file() and MANIFEST_KEY in storage.read_manifest(out)


def sweep_record(campaign):
    """The manifest's ``sweep``: axes, metrics and each point's values and folder."""
    columns = storage.output_names(campaign)["columns"]["runs"]
    return {
        "axes": [sweep_config.axis_name(axis) for axis in campaign["sweep"]["axes"]],
        "metrics": sweep_config.metrics(campaign, columns),
        "points": [
            {"point": k, "values": values, "folder": point_folder(k)}
            for k, values in enumerate(sweep_config.points(campaign))
        ],
    }


def run_campaign_or_sweep(campaign_file=None, out=None, runs=None, seed=None, **options):
    """:func:`run_sweep` for a campaign with a ``sweep``, else :func:`refexmc.campaign.run.run_campaign`
    (the same arguments)."""
    resolved_file, campaign = resolve_campaign(campaign_file, runs, seed)
    if "rare_event" in campaign:  # levels of subset simulation (refexmc.campaign.rare_event)
        from refexmc.campaign.rare_event import run_rare_event

        return run_rare_event(campaign_file, out=out, runs=runs, seed=seed, **options)
    if "sweep" not in campaign:
        return run_campaign(campaign_file, out=out, runs=runs, seed=seed, **options)
    return run_sweep(resolved_file, campaign, out if out is not None else default_output(campaign), **options)


def run_sweep(campaign_file, campaign, out, overwrite=False, resume=False, notify=notify_stderr, **options):
    """Fly every point of the validated sweep ``campaign`` into OUT; the combined result (runs
    table with a ``point`` column first). ``options``: those of :func:`refexmc.campaign.run.run_campaign`
    (jobs, backend, ...). ConfigError on bad input, with nothing written."""
    out = Path(out)
    record = sweep_record(campaign)
    # the backend as a whole study (cuda refuses a sweep; a Dask scheduler must answer), before any write
    check_backend(options.get("backend", "loky"), campaign=campaign, scheduler=options.get("scheduler"))
    lock.check_free(out)
    storage.check_output(out, overwrite=overwrite, resume=resume, protect=[campaign_file])
    previous = check_resumable(out, campaign) if resume and not storage.is_empty(out) else None
    with lock.locked(out, notify):
        if overwrite:
            for path in out.iterdir():
                if path.name == storage.LOCK_NAME:
                    continue
                shutil.rmtree(path) if path.is_dir() and not path.is_symlink() else path.unlink()
        (out / POINTS_DIR).mkdir(exist_ok=True)
        files = []
        for point in record["points"]:  # every point validated before anything flies
            file = out / f"{point['folder']}.yaml"
            plain = sweep_config.point_campaign(campaign, point["point"], point["values"])
            if not file.is_file() or storage.normalized_campaign(plain) != storage.normalized_campaign(
                load_campaign(file)
            ):
                storage.write_text_atomic(storage.resolved_yaml(plain), file)
            load_campaign(file)
            files.append(file)
        started = previous["started"] if previous else storage.now()
        if not previous:
            storage.write_resolved(out, campaign)

        def write_manifest(status, counts=None):
            info = storage.manifest(campaign_file, campaign, None, status, started, storage.now(), counts)
            storage.write_manifest(out, {**info, MANIFEST_KEY: record})

        write_manifest("running")
        tables = []
        for point, file in zip(record["points"], files, strict=True):
            folder = out / point["folder"]
            try:
                result = run_campaign(file, out=folder, resume=not storage.is_empty(folder), notify=notify, **options)
            except CampaignInterrupted as exc:  # the message counts the runs of every point
                write_manifest("interrupted")
                earlier = sum(len(table) for table in tables)
                exc.out, exc.done = out, earlier + exc.done
                exc.total = campaign["runs"] * len(record["points"])
                raise
            tables.append(result["runs"].assign(point=point["point"]))
        import pandas as pd  # as run.py: not at start-up

        table = pd.concat(tables, ignore_index=True)
        table = table[["point", *[c for c in table.columns if c != "point"]]]
        counts = {
            "points": len(record["points"]),
            "runs": int(len(table)),
            "ok": int((table["status"] == "ok").sum()),
            "error": int((table["status"] == "error").sum()),
            "success": int(table["success"].sum()),
        }
        write_manifest("complete", counts)
    return {"out": out, "counts": counts, "runs": table, "campaign": campaign, MANIFEST_KEY: record}


def check_not_sweep(campaign, what):
    if "sweep" in campaign:
        raise ConfigError(f"{what} does not take a sweep campaign", path=("sweep",))
