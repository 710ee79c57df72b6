"""Fly a rare-event study (campaign key ``rare_event``, docs/rare-events.md): subset simulation
(:mod:`refexmc.campaign.subset`) whose limit state is a flight.

The study's inputs are the campaign's uniforms: every dispersed path that draws (as many uniforms
as one draw of it consumes) and, with random failures, one uniform for the failure count and one
per unit (the failed set: the ``count`` units of smallest uniform). Its standard-normal space is
``z = ndtri(u)``, and each flight's dispersed values are ``transform(ndtr(z))``
(``distributions.transform_rows``). Level 0 is the campaign's ordinary random draw of run ids 0..N-1
(keyed uniforms; a non-physical inertia redrawn as always, its z that of the attempt flown).
Later levels move in z: a proposal whose inertia is not physical lies outside the support and is
rejected without flying; every other proposal flies as a run of its own run id
(``subset.run_index``), so its in-flight noise (the run's seed) is drawn anew: an independence
proposal for the noise.

The runs table has every flight with ``level``, ``chain``, ``step`` and the event's ``margin``.
Levels follow one another; the steps of a level too (a chain's next proposal needs its state);
the chains of one step fly in parallel as chunks, each with its own part index. A round's
proposals come from keyed generators and the stored margins only, so ``-j``, chunking, the
backend and ``--resume`` give the same table; ``--resume`` replays the stored rounds and flies the
missing ones. ``rerun`` replays the study up to the run's round and flies it again.
"""

import math
import os
import shutil
from contextlib import closing, contextmanager
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq

from refexmc import distributions
from refexmc.campaign import lock, storage, subset
from refexmc.campaign.sampling import _TINY, Sampler
from refexmc.campaign.study_plan import LEVEL0_ROUND, ROUND_KEY, StudySampler, failure_block
from refexmc.config import dispersions
from refexmc.config.derived import unphysical_inertias
from refexmc.config.errors import ConfigError
from refexmc.config.failures import NO_FAILURES, THRUSTER_FAILURES, WHEEL_FAILURES
from refexmc.config.rare_event import event_of

MANIFEST_KEY = "rare_event"
STUDY_COLUMNS = ("level", "chain", "step", "margin")


def layout(campaign):
    """[(name, uniforms per draw, spec or None)]: the blocks of the study's z (dispersed paths that
    draw, then the random failures' blocks), in campaign order."""
    sampler = Sampler(campaign)
    blocks = []
    for path, spec in sampler.specs.items():
        count = distributions.uniforms_per_draw(spec, dispersions.size(path, sampler.vehicle))
        if count:
            blocks.append((path, count, spec))
    for kind, units in ((THRUSTER_FAILURES, sampler.n_thrusters), (WHEEL_FAILURES, sampler.n_wheels)):
        if campaign.get(kind.key, NO_FAILURES)["mode"] == "random":
            blocks.append((failure_block(kind), 1 + units, None))
    return blocks


def design_of(campaign):
    spec = campaign["rare_event"]
    return subset.Design(spec["per_level"], spec["p0"], spec["max_levels"], spec["proposal"])


def level0_normals(campaign, blocks, run_ids):
    """z of level 0's runs: ndtri of the uniforms each flew (an inertia redrawn: the attempt flown)."""
    from scipy import special

    sampler = StudySampler(campaign)
    columns = []
    for name, count, spec in blocks:
        u = sampler.uniforms_for_runs(name, list(run_ids), count)
        if spec is not None and spec["dist"] == "inertia":
            u = u.copy()
            tensors = distributions.inertia_tensors(distributions.transform_rows(spec, u, sampler.nominal[name]))
            unphysical = np.flatnonzero(unphysical_inertias(tensors))
            redrawn = sampler.inertia_redraws(name, spec, [int(run_ids[i]) for i in unphysical], count)
            for i in unphysical:  # the attempt flown (Sampler._draw); none: an error row, its margin -inf anyway
                if int(run_ids[i]) in redrawn:
                    u[i] = redrawn[int(run_ids[i])][0]
        columns.append(u)
    return special.ndtri(np.concatenate(columns, axis=1))


def uniforms_of(z):
    from scipy import special

    return np.clip(special.ndtr(z), _TINY, 1.0 - _TINY)


def split(blocks, u_row):
    """{block name: its uniforms} of one row of the study's uniforms."""
    out, start = {}, 0
    for name, count, _ in blocks:
        out[name] = u_row[start : start + count].copy()
        start += count
    return out


def support_check(campaign, blocks):
    """``in_support(z)``: False where a proposal's inertia is not physical (rejected, not flown)."""
    sampler = Sampler(campaign)
    inertia = [
        (k, name, count, spec) for k, (name, count, spec) in enumerate(blocks) if spec and spec["dist"] == "inertia"
    ]
    starts = np.cumsum([0] + [count for _, count, _ in blocks])

    def in_support(z):
        inside = np.ones(len(z), dtype=bool)
        for k, name, count, spec in inertia:
            u = uniforms_of(z[:, starts[k] : starts[k] + count])
            tensors = distributions.inertia_tensors(distributions.transform_rows(spec, u, sampler.nominal[name]))
            inside &= ~np.asarray(unphysical_inertias(tensors), dtype=bool)
        return inside

    return in_support if inertia else None


def study_chunk_size(design):
    """Runs per chunk of a study without ``$REFEXMC_CHUNK_SIZE``: half a round (two part files and a
    task per worker of ``-j 2``, ~15 ms each), within [10, 100]."""
    return min(100, max(10, math.ceil(design.chains / 2)))


def round_chunk_size(chunk_size, chains):
    """Runs per chunk of a round of ``chains`` proposals: half the round at most, so that two workers
    share it (each chunk costs two part files and a task: ~15 ms)."""
    return max(1, min(chunk_size, math.ceil(chains / 2)))


def round_chunks(design, chunk_size, level, step, run_ids):
    """[(part index, run ids)] of round (level, step) whose flown runs are ``run_ids`` (level 0: all N).

    Part indices are fixed by the study's shape alone: level 0's chunks first, then each round's
    ``ceil(chains / round size)`` slots in order; a slot with no run to fly has no part.
    """
    if level == 0:
        return [
            (k, list(range(s, min(design.per_level, s + chunk_size))))
            for k, s in enumerate(range(0, design.per_level, chunk_size))
        ]
    level0 = math.ceil(design.per_level / chunk_size)
    size = round_chunk_size(chunk_size, design.chains)
    slots = math.ceil(design.chains / size)
    base = level0 + ((level - 1) * (design.steps - 1) + (step - 1)) * slots
    first = subset.run_index(design, level, step, 0)
    chunks = []
    for slot in range(slots):
        ids = [r for r in run_ids if first + slot * size <= r < first + (slot + 1) * size]
        if ids:
            chunks.append((base + slot, ids))
    return chunks


def round_campaign(campaign, blocks, level, step, z, run_ids, design):
    """The campaign a worker flies round (level, step) with: the proposals' uniforms by run id."""
    if level == 0:
        return {**campaign, ROUND_KEY: LEVEL0_ROUND}
    first = subset.run_index(design, level, step, 0)
    u = uniforms_of(z)
    return {
        **campaign,
        ROUND_KEY: {
            "level": level,
            "step": step,
            "chains": {int(r): int(r - first) for r in run_ids},
            "uniforms": {int(r): split(blocks, u[i]) for i, r in enumerate(run_ids)},
        },
    }


class _Replay(Exception):
    """Raised by a replay's evaluate when it reaches the round it was looking for."""

    def __init__(self, round_campaign):
        self.round_campaign = round_campaign


def stored_margins(out):
    """{run id: margin} of the runs stored in OUT (empty when none)."""
    runs = Path(out) / "runs"
    margins = {}
    for part in sorted(runs.glob("part-*.parquet")) if runs.is_dir() else ():
        table = pq.read_table(part, columns=["run_id", "margin"])
        margins.update(zip(table.column("run_id").to_pylist(), table.column("margin").to_pylist(), strict=True))
    return margins


def replay(campaign, margins, stop_at=None):
    """The :class:`subset.Study` of stored ``margins`` ({run id: margin}); with ``stop_at`` (a run id),
    the round campaign that flies that run instead (ConfigError when the study never flew it)."""
    blocks = layout(campaign)
    design = design_of(campaign)

    def evaluate(level, step, z, index):
        if stop_at is not None and int(stop_at) in set(int(i) for i in index):
            raise _Replay(round_campaign(campaign, blocks, level, step, z, [int(i) for i in index], design))
        missing = [int(i) for i in index if int(i) not in margins]
        if missing:
            raise KeyError(missing[0])
        return np.array([margins[int(i)] for i in index], dtype=float)

    z0 = level0_normals(campaign, blocks, np.arange(design.per_level))
    try:
        return subset.subset_simulation(
            design, campaign["seed"], z0.shape[1], evaluate, z0=z0, in_support=support_check(campaign, blocks)
        )
    except _Replay as found:
        return found.round_campaign
    except KeyError as exc:
        if stop_at is not None:
            raise ConfigError(
                f"run {stop_at} was never flown: the study stopped before its round", path=("RUN_ID",)
            ) from None
        raise ValueError(f"run {exc.args[0]} of the study is missing from OUT") from None


def study_record(study, event, flown):
    """The manifest's and summary.json's ``rare_event``: P, interval, c.o.v., flights, levels."""
    levels = []
    for k, level in enumerate(study.levels):
        levels.append(
            {
                "level": k,
                "threshold": level.threshold,
                "conditional_probability": level.probability,
                "gamma": level.gamma,
                "cov": level.cov if math.isfinite(level.cov) else None,
                "flights": level.flights,
                "accepted": level.accepted if k else None,
                "proposals": level.proposals if k else None,
                "outside_support": level.outside_support if k else None,
            }
        )
    lo, hi = study.ci95
    reached = study.probability > 0.0
    below = 1.0
    for level in study.levels[:-1]:
        below *= level.probability
    return {
        "event": event.text,
        "method": "subset",
        "proposal": study.design.proposal,
        "per_level": study.design.per_level,
        "p0": study.design.p0,
        # no flight in the event: no estimate (never a confident 0), only the last threshold's probability above it
        "probability": study.probability if reached else None,
        "ci95": [lo, hi] if reached else None,
        "cov": study.cov if reached else None,
        "last_threshold": study.levels[-1].threshold,
        "last_threshold_probability": below,
        "interval": "Au & Beck (2001) c.o.v. with each level's chain correlation, levels taken as independent; "
        "lognormal 95 % interval P exp(+-1.96 sqrt(ln(1 + cov^2)))",
        "flights": int(flown),
        "levels": levels,
        "stopped": study.stopped,
    }


def run_rare_event(
    campaign_file=None,
    out=None,
    seed=None,
    jobs=None,
    backend="loky",
    scheduler=None,
    overwrite=False,
    resume=False,
    progress=None,
    chunk_size=None,
    notify=None,
    strict=False,
    runs=None,
):
    """Fly (or finish, ``resume``) the rare-event study of ``campaign_file`` into OUT; the result of
    ``run.run_campaign`` (``runs``: level 0's table, the campaign's ordinary statistics) with
    ``rare_event`` (:func:`study_record`) and ``study_runs`` (every flight). The options are
    :func:`refexmc.campaign.run.run_campaign`'s (``progress``: the levels are reported to ``notify``
    instead; ``runs``: refused, a study's are ``per_level`` a level)."""
    from refexmc.campaign import run as run_module
    from refexmc.campaign.backends import check_backend, start_workers, stop_workers
    from refexmc.config.design_checks import strict_error

    notify = notify or run_module.notify_stderr
    design_warnings = []
    campaign_file, campaign = run_module.resolve_campaign(campaign_file, runs, seed, design_warnings)
    if strict and design_warnings:
        raise strict_error(design_warnings)
    for warning in design_warnings:
        notify(f"warning: {warning}")
    jobs = run_module.default_jobs() if jobs is None else jobs
    if jobs < 1:
        raise ConfigError(f"expected jobs >= 1, got {jobs}", path=("--jobs",))
    options = check_backend(backend, campaign=campaign, scheduler=scheduler)  # cuda: refused, before any write
    out = Path(out) if out is not None else run_module.default_output(campaign)
    design = design_of(campaign)
    execution = {
        "design_warnings": [str(w) for w in design_warnings],
        "jobs": jobs,
        "backend": backend,
        "scheduler": scheduler,
        "run_time_limit_s": float(campaign.get("run_time_limit_s", 60.0)),
    }

    def check():
        storage.check_output(out, overwrite=overwrite, resume=resume, protect=[campaign_file])
        return run_module.check_resumable(out, campaign) if resume and not storage.is_empty(out) else None

    lock.check_free(out)
    check()
    with run_module.stop_on_signals(), lock.locked(out, notify):
        try:
            previous = check()
            with run_module._workers_stopped_on_error():
                options = {**options, **start_workers(backend, max(1, min(jobs, design.chains)))}
                storage.prepare_output(out, overwrite=overwrite, resume=resume, protect=[campaign_file])
                return _fly_study(
                    campaign_file, campaign, out, design, execution, options, previous, chunk_size, notify
                )
        except run_module.CampaignInterrupted as exc:
            most = design.per_level + (design.max_levels - 1) * (design.per_level - design.chains)
            exc.out, exc.total = out, f"at most {most}"  # the levels still to fly are not known
            exc.done = len(stored_margins(out)) if storage.is_output(out) else 0
            raise
        finally:
            if backend != "loky":
                stop_workers()


def _fly_study(campaign_file, campaign, out, design, execution, options, previous, chunk_size, notify):
    from refexmc.campaign import run as run_module
    from refexmc.campaign.worker import Guard

    if previous:
        chunk_size, started = previous["chunk_size"], previous["started"]
        resumed = [*previous.get("resumed", []), storage.now()]
    else:
        if chunk_size is None and not os.environ.get(run_module.CHUNK_SIZE_ENV, "").strip():
            chunk_size = study_chunk_size(design)
        chunk_size, started, resumed = run_module._chunk_size(chunk_size, design.per_level), storage.now(), []
        storage.write_resolved(out, campaign)

    def write_manifest(status, finished=None, counts=None, record=None):
        info = storage.manifest(
            campaign_file, campaign, chunk_size, status, started, finished, counts, **execution, resumed=resumed
        )
        if record is not None:
            info[MANIFEST_KEY] = record
        storage.write_manifest(out, info)

    if not previous or previous.get("status") != "complete":
        storage.remove_report(out)  # it would describe other contents
    write_manifest("running")
    margins = stored_margins(out) if previous else {}
    blocks = layout(campaign)
    event = event_of(campaign, storage.output_names(campaign)["columns"]["runs"])
    work = out / storage.WORK_DIR
    shutil.rmtree(work, ignore_errors=True)
    work.mkdir()
    guard = Guard.create(work, execution["run_time_limit_s"])

    def evaluate(level, step, z, index):
        ids = [int(i) for i in index]
        chunks = round_chunks(design, chunk_size, level, step, ids)
        todo = run_module.chunks_to_fly(out, chunks, notify) if previous else chunks
        if todo:
            flown_campaign = round_campaign(campaign, blocks, level, step, z, ids, design)
            with closing(fly_round(flown_campaign, todo)) as flown:
                for chunk, rows, runs, history in flown:
                    name = storage.part_name(chunk)
                    storage.write_bytes_atomic(history, out / "histories" / name)
                    storage.write_bytes_atomic(runs, out / "runs" / name)
                    margins.update((row["run_id"], row["margin"]) for row in rows)
            for chunk, run_ids in chunks:  # a resumed round: the parts found sound
                if any(r not in margins for r in run_ids):
                    table = pq.read_table(out / "runs" / storage.part_name(chunk), columns=["run_id", "margin"])
                    margins.update(
                        zip(table.column("run_id").to_pylist(), table.column("margin").to_pylist(), strict=True)
                    )
        if step in (0, design.steps - 1):
            in_event = sum(margin <= 0.0 for margin in margins.values())
            notify(f"rare event: level {level} flown, {len(margins)} flights so far, {in_event} of them in the event")
        return np.array([margins[i] for i in ids], dtype=float)

    try:
        with round_flyer(execution, options, guard) as fly_round:
            z0 = level0_normals(campaign, blocks, np.arange(design.per_level))
            study = subset.subset_simulation(
                design, campaign["seed"], z0.shape[1], evaluate, z0=z0, in_support=support_check(campaign, blocks)
            )
    except run_module.CampaignInterrupted:
        write_manifest("interrupted")
        raise
    finally:
        shutil.rmtree(work, ignore_errors=True)
    table = read_study_runs(out)
    record = study_record(study, event, len(table))
    level0 = table[table["level"] == 0].reset_index(drop=True)
    counts = {
        "runs": int(len(level0)),
        "ok": int((level0["status"] == "ok").sum()),
        "error": int((level0["status"] == "error").sum()),
        "success": int(level0["success"].sum()),
        "study_flights": int(len(table)),
        "study_errors": int((table["status"] == "error").sum()),
    }
    write_manifest("complete", storage.now(), counts, record)
    return {
        "out": out,
        "counts": counts,
        "runs": level0,
        "study_runs": table,
        "campaign": campaign,
        MANIFEST_KEY: record,
    }


@contextmanager
def round_flyer(execution, options, guard):
    """``fly_round(campaign, chunks)``: the backend's generator of flown chunks for one round. On Dask,
    one client for the whole study (a ``local:N`` cluster started once, not once per round)."""
    from refexmc.campaign.backends import BACKENDS

    if execution["backend"] != "dask":
        yield lambda campaign, chunks: BACKENDS[execution["backend"]](
            campaign, chunks, execution["jobs"], guard, **options
        )
        return
    from refexmc.campaign import dask_backend

    distributed = dask_backend.require_distributed()
    remote = guard._replace(state_dir=None)  # the parent's work directory is not on the workers' disks
    with dask_backend.connect(options["scheduler"], execution["jobs"]) as client:
        yield lambda campaign, chunks: dask_backend._fly_chunks(distributed, client, campaign, chunks, remote)


def read_study_runs(out):
    """Every flight of the study in OUT (a DataFrame sorted by run id)."""
    parts = sorted((Path(out) / "runs").glob("part-*.parquet"))
    return storage.read_runs_parts(parts).to_pandas().sort_values("run_id", ignore_index=True)


def rerun_plan(out, campaign, run_id):
    """The plan that flies run ``run_id`` of the study in OUT again (its round replayed from OUT)."""
    from refexmc.campaign.chunk import plan_for  # the flying machinery: only to fly

    if run_id < design_of(campaign).per_level:
        return plan_for(campaign)
    margins = stored_margins(out)
    if run_id not in margins:
        raise ConfigError(
            f"run {run_id} is not in OUT: the study did not fly it (a proposal outside the "
            "inputs' support, or after the study ended)",
            file=out,
            path=("RUN_ID",),
        )
    return plan_for(replay(campaign, margins, stop_at=run_id))


def format_study(record):
    """Lines for the terminal after a study: P, interval and the levels."""
    p = record["probability"]
    head = f"rare event {record['event']}: "
    if p is None:
        bound = f"P(margin <= {record['last_threshold']:.4g}) ~ {record['last_threshold_probability']:.2g}"
        head += f"no flight reached it; P <= {bound}"
    else:
        lo, hi = record["ci95"]
        head += f"P = {p:.3g}, 95 % interval [{lo:.3g}, {hi:.3g}], c.o.v. {record['cov']:.2f}"
    lines = [f"{head} from {record['flights']} flights in {len(record['levels'])} levels ({record['stopped']})"]
    for level in record["levels"]:
        threshold = "-" if level["threshold"] is None else f"{level['threshold']:.4g}"
        lines.append(
            f"  level {level['level']}: margin threshold {threshold}, "
            f"conditional probability {level['conditional_probability']:.3g}"
        )
    return "\n".join(lines)
