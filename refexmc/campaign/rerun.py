"""Re-fly one run of a finished campaign from its output directory, with a full-rate history.

Everything needed is in ``OUT/campaign.resolved.yaml`` (vehicle and mission inlined, seed and
run count as flown): run i's inputs derive from (seed, run id, parameter path) alone, so the
re-flown summary row equals the stored one bit for bit.
"""

import math
from pathlib import Path

from refexmc.campaign import storage
from refexmc.campaign.chunk import RunPlan
from refexmc.config.errors import ConfigError
from refexmc.config.load import load_campaign
from refexmc.simulate import control_period


def _same(a, b):
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return True
    return a == b


def stored_row(out, run_id):
    """The run's row of ``OUT/runs`` as a dict, or None when that run was not stored."""
    runs_dir = Path(out) / "runs"
    if not runs_dir.is_dir() or not any(runs_dir.glob("part-*.parquet")):
        return None
    table = storage.read_runs_parts(sorted(runs_dir.glob("part-*.parquet")), filters=[("run_id", "==", int(run_id))])
    return table.to_pylist()[0] if table.num_rows else None


def rerun(out, run_id, history_rate_hz=None, dest=None):
    """Re-fly run ``run_id`` of OUT; write its history to ``dest`` (default OUT/reruns/run-<id>.parquet).

    ``history_rate_hz`` defaults to the control rate (every control step). Returns a dict with
    the new ``row``, the ``stored`` row (or None), the columns that ``differ`` and the ``path``.
    ConfigError for a directory that is not a campaign output or a run id it does not have.
    """
    out = Path(out)
    resolved = out / "campaign.resolved.yaml"
    if not resolved.is_file():
        raise ConfigError("not a refexmc output directory (no campaign.resolved.yaml)", file=out)
    campaign = load_campaign(resolved)
    if "sweep" in campaign:  # its runs are the points' (refexmc.campaign.sweep)
        raise ConfigError("a sweep's output: re-fly a run of one point, OUT/points/NNN", file=out)
    if "rare_event" in campaign:  # a study's run: its round replayed from OUT (refexmc.campaign.rare_event)
        from refexmc.campaign.rare_event import rerun_plan

        if run_id < 0:
            raise ConfigError(f"expected a run id >= 0, got {run_id}", file=out, path=("RUN_ID",))
        plan = rerun_plan(out, campaign, run_id)
    elif not 0 <= run_id < campaign["runs"]:
        raise ConfigError(f"expected a run id 0..{campaign['runs'] - 1}, got {run_id}", file=out, path=("RUN_ID",))
    elif "entry_flight" in campaign["mission"]:  # an entry campaign (issue 24): its history is one row per second
        from refexmc.campaign.entry_plan import EntryRunPlan

        plan = EntryRunPlan(campaign)
        history_rate_hz = 1.0 if history_rate_hz is None else history_rate_hz
    else:
        plan = RunPlan(campaign)
    if history_rate_hz is None:
        history_rate_hz = 1.0 / control_period(plan.nominal_inputs)
    if not history_rate_hz > 0:
        raise ConfigError(f"expected a history rate > 0, got {history_rate_hz}", path=("--history-rate",))
    row, history, _ = plan.fly(run_id, history_rate_hz)
    path = Path(dest) if dest is not None else out / "reruns" / f"run-{run_id}.parquet"
    if history is None:
        history = storage.empty_history_table()
    storage.write_table_atomic(history, path)
    stored = stored_row(out, run_id)
    differ = []
    if stored is not None:  # a column either row lacks differs too (a stored column the new row lost)
        keys = list(row) + [key for key in stored if key not in row]
        differ = [key for key in keys if key not in row or key not in stored or not _same(row[key], stored[key])]
    return {"row": row, "stored": stored, "differ": differ, "path": path, "campaign": campaign}
