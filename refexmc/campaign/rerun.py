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


ARCSEC_PER_DEG = 3600.0
SMALL_ANGLE_DEG = 0.1  # below it the end angle prints in arcsec (IRASSI's 4e-5 deg is 0.15 arcsec, not 0.000 deg)


def wheels_only(vehicle):
    """A vehicle whose flight software commands reaction wheels alone (IRASSI): no thrusters, no propellant."""
    return (vehicle.get("flight_software") or {}).get("actuation") == "wheels"


def angle_text(theta_deg):
    """The end angle with digits that show it: deg from 0.1 deg, arcsec below."""
    if abs(theta_deg) >= SMALL_ANGLE_DEG:
        return f"{theta_deg:.3f} deg"
    return f"{theta_deg * ARCSEC_PER_DEG:.4g} arcsec"


def summary_lines(result):
    """What `refexmc rerun` prints of a re-flown run (``rerun``'s result), in the mission's words:
    propellant only where the run has a value (a wheel vehicle has none), the end angle in arcsec
    when below 0.1 deg, failed thrusters only for a vehicle with thrusters, failed wheels where the
    runs table has them."""
    from refexmc.config.mission_words import end_condition, end_name

    row = result["row"]
    campaign = result["campaign"]
    mission = campaign["mission"]
    verdict = "success" if row["success"] else f"FAILED ({row['failure_reason']})"
    lines = [f"run {row['run_id']} of {campaign['name']}: {verdict}, status {row['status']}"]
    if "entry_flight" in mission:  # an entry campaign (issue 24, docs/x38.md)
        lines.append(
            f"  the entry ended at Mach {row['terminal_mach']:.3f}, {row['terminal_altitude_m'] / 1000:.1f} km, "
            f"t = {row['t_end_s']:.1f} s; RCS propellant {row['rcs_propellant_kg']:.3f} kg"
        )
        return lines
    lines.append(f"  the mission: {end_condition(mission)}")
    stopped = end_name(mission) if row["success"] else "flight stopped"
    parts = []
    fuel = row.get("fuel_remaining")
    if fuel is not None and math.isfinite(fuel):
        parts.append(f"propellant remaining {100 * fuel:.1f} %")
    parts.append(f"{stopped} at t = {row['t_end_s']:.2f} s")
    theta = row.get("attitude_error_end_deg")
    if theta is not None and math.isfinite(theta):
        parts.append(f"total angle error {angle_text(theta)}")
    if "failed_thrusters" in row and not wheels_only(campaign.get("vehicle") or {}):
        parts.append(f"failed thrusters [{row['failed_thrusters']}]")
    if "failed_wheels" in row:
        parts.append(f"failed wheels [{row['failed_wheels']}]")
    lines.append("  " + ", ".join(parts))
    return lines
