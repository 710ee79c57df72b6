"""`refexmc run --until-decided`: fly a campaign batch by batch until its requirements are decided.

The campaign's ``runs`` (or ``--runs``) is the budget N. The runs are flown in batches; after each
batch the rule of :mod:`refexmc.campaign.sequential` looks at the runs table and the campaign
stops once its verdict is decided (a requirement FAILs, or every requirement PASSes), or at the
budget. Run i is the same run whatever the
number of runs (keyed seeds, ``sampling: random``), so OUT then holds exactly the first n runs of
the full campaign, and is the campaign ``--runs n`` with a stopping record: the resolved campaign
says ``runs: n``, ``manifest.json`` has ``until_decided`` (looks, verdicts, why it stopped).
Running it again with ``--resume`` (the same or a larger budget) replays the looks on the stored
runs and flies on only where the rule does.
"""

import math
import os
from pathlib import Path

from refexmc.campaign import sequential, storage
from refexmc.campaign.progress import Progress
from refexmc.campaign.run import CHUNK_SIZE_ENV, MAX_CHUNK_SIZE, resolve_campaign, run_campaign
from refexmc.config.errors import ConfigError
from refexmc.config.requirements import check_requirements

MANIFEST_KEY = "until_decided"


def default_batch(budget):
    """Runs between looks without ``--batch``: about DEFAULT_LOOKS looks, at least 10 runs."""
    return max(10, math.ceil(budget / sequential.DEFAULT_LOOKS))


def batch_chunk_size(batch):
    """Runs per chunk: ``$REFEXMC_CHUNK_SIZE`` or the largest divisor of ``batch`` up to MAX_CHUNK_SIZE,
    so that every look ends on a chunk boundary (an extended OUT keeps all its parts)."""
    text = os.environ.get(CHUNK_SIZE_ENV, "").strip()
    if text:
        return None  # run_campaign reads and checks it
    return max(d for d in range(1, min(batch, MAX_CHUNK_SIZE) + 1) if batch % d == 0)


def run_until_decided(
    campaign_file=None,
    out=None,
    runs=None,
    seed=None,
    batch=None,
    alpha=sequential.DEFAULT_ALPHA,
    resume=False,
    overwrite=False,
    notify=None,
    **options,
):
    """Fly ``campaign_file`` in batches until decided (module docstring); the last ``run_campaign``
    result with ``until_decided`` (the stopping record) added. ``options``: jobs, backend, scheduler,
    progress (as :func:`refexmc.campaign.run.run_campaign`). ConfigError for bad input."""
    campaign_file, campaign = resolve_campaign(campaign_file, runs, seed)
    sequential.check_sequential_campaign(campaign, file=campaign_file)
    if not 0.0 < alpha < 0.5:
        raise ConfigError(f"expected 0 < alpha < 0.5, got {alpha}", path=("--alpha",))
    budget = campaign["runs"]
    batch = default_batch(budget) if batch is None else batch
    if batch < 1:
        raise ConfigError(f"expected a batch of at least 1 run, got {batch}", path=("--batch",))
    batch = min(batch, budget)  # one look, at the budget
    columns = storage.output_names(campaign)["columns"]["runs"]
    parsed = check_requirements(campaign["requirements"], columns, file=campaign_file)
    decision = sequential.Decision(
        [sequential.rule_for(r, alpha) for r in parsed], sequential.look_sizes(budget, batch)
    )
    out = Path(out) if out is not None else Path("runs") / campaign["name"]
    stored = storage.read_manifest(out)["runs"] if resume and storage.is_output(out) else 0
    common = {"campaign_file": campaign_file, "out": out, "seed": seed, "chunk_size": batch_chunk_size(batch)}
    if isinstance(options.get("progress"), str):  # one meter over the budget, not one per look
        options = {**options, "progress": Progress(budget, min(stored, budget), options["progress"], start=False)}
    if notify is not None:
        common["notify"] = notify
    result = None
    for k, n in enumerate(decision.looks):
        first = k == 0
        if n > stored or result is None:
            size = max(n, stored)  # a resumed OUT: finish what it holds, then look at its prefixes
            result = run_campaign(
                runs=size,
                resume=resume or not first,
                overwrite=overwrite and first,
                extend=True,
                **common,
                **options,
            )
            stored = size
        table = result["runs"]
        if decision.look(k, table[table["run_id"] < n].reset_index(drop=True)):
            break
    if isinstance(options.get("progress"), Progress):
        options["progress"].close()
    record = decision.record(alpha, batch, int(len(result["runs"])))
    manifest = storage.read_manifest(out)
    storage.write_manifest(out, {**manifest, MANIFEST_KEY: record})
    return {**result, MANIFEST_KEY: record}


def format_stopping(record):
    """Lines for the terminal: how many runs were flown, why it stopped, each requirement's state."""
    looks = f"(looks every {record['batch_runs']} runs, alpha {record['alpha']:g})"
    states = [r["state"] for r in record["requirements"]]
    verdict = record.get("verdict") or (sequential.FAIL if sequential.FAIL in states else sequential.PASS)  # older
    if record["stopped"] == "decided" and verdict == sequential.FAIL:
        failed = sum(r["state"] == sequential.FAIL for r in record["requirements"])
        head = (
            f"stopped when decided after {record['runs_flown']} of {record['budget_runs']} runs {looks}: FAIL "
            f"({failed} requirement{'s' if failed > 1 else ''} failed, which no further run can undo)"
        )
    elif record["stopped"] == "decided":
        head = f"stopped when decided after {record['runs_flown']} of {record['budget_runs']} runs {looks}: PASS"
    else:
        head = f"flew the whole budget of {record['budget_runs']} runs {looks}: not every requirement was decided"
    lines = [head]
    for r in record["requirements"]:
        at = f" at {r['decided_at_runs']} runs" if r["decided_at_runs"] is not None else ""
        lines.append(f"  {r['state']:>4}{at}: {r['requirement']} [{r['test']}]")
    return "\n".join(lines)
