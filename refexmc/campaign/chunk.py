"""Fly a chunk of runs: the unit of work every execution backend hands to a worker.

``fly_chunk(campaign, run_ids)`` depends only on the validated campaign and the run ids, never
on the worker, the chunking or the order: run i's inputs derive from (campaign seed, run id,
parameter path) alone.
"""

from refexmc.campaign import storage
from refexmc.campaign.execute import fly
from refexmc.campaign.seeding import run_seed
from refexmc.config.pack import pack


def failed_thrusters(campaign):
    failures = campaign["failures"]
    return tuple(sorted(failures.get("thrusters", ()))) if failures["mode"] == "fixed" else ()


def fly_chunk(campaign, run_ids):
    """Fly ``run_ids``; return (runs rows as dicts, history tables). A run that raises is an error row."""
    failed = failed_thrusters(campaign)
    inputs = pack(campaign["vehicle"], campaign["mission"], failed)
    rate = campaign["output"]["history_rate_hz"]
    n_thrusters = inputs.thrusters.shape[0]
    rows, histories = [], []
    for run_id in run_ids:
        seed = run_seed(campaign["seed"], run_id)
        try:
            result = fly(inputs, nav_seed=seed, history_rate_hz=rate)
        except Exception as exc:  # noqa: BLE001 - one bad run must not stop the campaign
            rows.append(storage.runs_row(run_id, seed, failed, None, n_thrusters, error=f"{type(exc).__name__}: {exc}"))
            continue
        rows.append(storage.runs_row(run_id, seed, failed, result, n_thrusters))
        histories.append(storage.history_table(run_id, result.history))
    return rows, histories
