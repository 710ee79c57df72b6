"""Command line: a thin click layer over functions that tests call directly."""

import atexit
import errno
import functools
import gc
import json
import math
import sys
from pathlib import Path

import click

from refexmc.config.errors import ConfigError

STRICT = click.option("--strict", is_flag=True, help="Design warnings are errors (exit 2): docs/missions.md.")


def plural(count, word):
    return f"{count} {word}{'' if count == 1 else 's'}"


def residue_free(values, fmt):
    """``values`` (a vector quantity) with each component below the printed rounding of ``fmt``
    set to 0: below half the last decimal of an ``f`` format, or, for ``g``/``e``, below half the
    last significant digit of the largest component. A torque of 1.1e-16 N m beside 20.5 N m is a
    rounding residue, not a torque (issue 32), and a -0.0000 has no sign. None stays None."""
    kind = fmt[-1]
    if kind not in "fge":
        return list(values)
    precision = int(fmt.split(".")[1][:-1]) if "." in fmt else 6
    finite = [abs(v) for v in values if v is not None and math.isfinite(v)]
    if kind == "f":
        half_digit = 0.5 * 10.0**-precision
    elif finite and max(finite) > 0.0:
        half_digit = 0.5 * 10.0 ** (math.floor(math.log10(max(finite))) - max(precision - (kind == "g"), 0))
    else:
        half_digit = 0.0
    return [v if v is None or abs(v) >= half_digit and v != 0.0 else 0.0 for v in values]


def shown(values, fmt, separator=", "):
    """``values`` formatted with ``fmt`` and joined, rounding residues as 0 (:func:`residue_free`)."""
    return separator.join(format(v, fmt) for v in residue_free(values, fmt))


def _bad_input(message):
    click.echo(f"error: {message}", err=True)
    sys.exit(2)


def _os_error(exc, what, hint=""):
    """One line for an OSError (disk full, read-only, no permission): what failed, the path, the reason; exit 2."""
    reason = (exc.strerror or str(exc)).replace("\n", " ")
    name = errno.errorcode.get(exc.errno) if exc.errno else None
    where = f"{exc.filename}: " if exc.filename else ""
    _bad_input(f"{what}: {where}{reason}{f' ({name})' if name else ''}{hint}")


def _unreadable(exc, what, hint=""):
    """One line for a Parquet file pyarrow cannot read (a damaged part); exit 2."""
    _bad_input(f"{what}: {' '.join(str(exc).split())}{hint}")


RESUME_HINT = "; completed chunks are kept: fix this, then finish with --resume"
DAMAGED_HINT = "; a damaged part file is flown again by `refexmc run CAMPAIGN -o OUT --resume`"


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name="refexmc")
def main():
    """refexmc: Monte-Carlo campaigns for the ReFEx exoatmospheric attitude control system."""


@main.command()
@click.argument("campaign", required=False, type=click.Path(dir_okay=False, path_type=Path))
@click.option("-o", "--out", type=click.Path(file_okay=False, path_type=Path), help="Output directory.")
@click.option("-j", "--jobs", type=int, help="Worker processes [default: all usable cores].")
@click.option("--runs", type=int, help="Override the number of runs.")
@click.option("--seed", type=int, help="Override the campaign seed.")
@click.option("--resume", is_flag=True, help="Finish what is missing in an existing OUT of the same campaign.")
@click.option(
    "--overwrite", is_flag=True, help="Replace an existing OUT (only a refexmc output with nothing else in it)."
)
@click.option(
    "--backend",
    type=click.Choice(["loky", "dask", "cuda"]),
    default="loky",
    show_default=True,
    help="Execution backend: loky (-j processes on this machine), dask (a Dask cluster, see --scheduler) "
    "or cuda (this machine's GPU, one run per thread; the cuda extra, docs/gpu.md).",
)
@click.option(
    "--scheduler",
    metavar="ADDRESS|local:N",
    help="Dask cluster for --backend dask: a scheduler address (tcp://host:8786), a scheduler file, "
    "or local:N to start N worker processes here (docs/cluster.md).",
)
@click.option("--no-progress", is_flag=True, help="No progress bar or lines on stderr.")
@click.option(
    "--until-decided",
    is_flag=True,
    help="Fly in batches until the verdict is decided (a requirement FAILs: exit 1; or all PASS); "
    "the runs are the budget (docs/studies.md).",
)
@click.option("--batch", type=int, help="With --until-decided: runs between looks [default: budget / 10, >= 10].")
@click.option("--alpha", type=float, help="With --until-decided: wrong-verdict rate [default: 0.05].")
@STRICT
def run(
    campaign,
    out,
    jobs,
    runs,
    seed,
    resume,
    overwrite,
    backend,
    scheduler,
    no_progress,
    until_decided,
    batch,
    alpha,
    strict,
):
    """Run CAMPAIGN (default: campaigns/refex-mc100.yaml) and write OUT (default runs/<name>).

    Chunks of runs are flown in parallel worker processes; a run that raises, crashes its
    worker or exceeds the campaign's run_time_limit_s (default 60 s) is recorded as an error.

    One run at a time writes OUT (lock file OUT/.refexmc.lock). Ctrl-C or SIGTERM stops the
    workers, keeps the completed chunks and prints the --resume command (exit 130 / 143).

    Example: refexmc run campaigns/nominal.yaml -o runs/nominal -j 2 --overwrite

    On a Dask cluster (pip install 'refexmc[dask]'; docs/cluster.md):

    \b
      refexmc run campaigns/refex-mc100.yaml --backend dask --scheduler tcp://head:8786
      refexmc run campaigns/refex-mc100.yaml --backend dask --scheduler local:4

    Stopping when decided (docs/studies.md): refexmc run CAMPAIGN --runs 2000 --until-decided
    """
    if resume and overwrite:
        _bad_input("--resume and --overwrite exclude each other")
    from refexmc.campaign import pool  # joblib's executor alone: before the campaign machinery is imported

    if (backend == "loky" and (jobs is None or jobs >= 1)) or (backend == "cuda" and (jobs is None or jobs > 1)):
        pool.start_early(jobs or pool.usable_cores())  # they warm up while this process validates (~1 s)
    dask_local = _local_workers(scheduler, jobs) if backend == "dask" else None
    if dask_local:
        from refexmc.campaign import dask_backend

        dask_backend.start_local_early(dask_local)  # its start overlaps the validation as well
    if not until_decided and (batch is not None or alpha is not None):
        _bad_input("--batch and --alpha go with --until-decided")
    until = {"batch": batch, "alpha": 0.05 if alpha is None else alpha} if until_decided else None
    try:
        result = _run_campaign(
            campaign, out, jobs, runs, seed, resume, overwrite, backend, scheduler, no_progress, until, strict
        )
    finally:
        pool.stop()  # idle now, and this process ends: its exit would wait ~0.4 s for them to leave
        if dask_local:
            dask_backend.stop_early()  # a cluster that no campaign took (bad input)
    click.echo(format_run_summary(result))
    if "rare_event" in result:  # a rare-event study (docs/rare-events.md): its estimate and levels
        from refexmc.campaign.rare_event import format_study

        click.echo(format_study(result["rare_event"]))
    if until_decided:
        from refexmc.campaign.decided import format_stopping

        click.echo(format_stopping(result["until_decided"]))
    errored = result["runs"].loc[result["runs"]["status"] == "error", "run_id"].tolist()
    if errored:
        click.echo(f"runs with errors: {', '.join(map(str, errored))}", err=True)
    failed = until_decided and result["until_decided"].get("verdict") == "FAIL"  # a FAIL decides the campaign
    if errored or failed:
        sys.exit(1)


def _local_workers(scheduler, jobs):
    """The workers of the LocalCluster ``--scheduler local[:N]`` asks for (None: another scheduler,
    or a malformed one, which the campaign's checks report)."""
    from refexmc.campaign.dask_backend import parse_scheduler

    try:
        kind, workers = parse_scheduler(scheduler)
    except ConfigError:
        return None
    if kind != "local" or (jobs is not None and jobs < 1):
        return None
    from refexmc.campaign import pool

    return workers or jobs or pool.usable_cores()


def _run_campaign(
    campaign, out, jobs, runs, seed, resume, overwrite, backend, scheduler, no_progress, until=None, strict=False
):
    """The result of ``run_campaign`` (``until``: of ``run_until_decided`` with these options); bad
    input, a failure or an interrupt exits with its message and code."""
    from refexmc.campaign import storage
    from refexmc.campaign.progress import progress_mode
    from refexmc.campaign.run import CampaignInterrupted, resume_command
    from refexmc.campaign.sweep import run_campaign_or_sweep as run_campaign

    if until is not None:
        from refexmc.campaign.decided import run_until_decided

        run_campaign = functools.partial(run_until_decided, **until)
    try:
        return run_campaign(
            campaign,
            out=out,
            runs=runs,
            seed=seed,
            jobs=jobs,
            backend=backend,
            scheduler=scheduler,
            overwrite=overwrite,
            resume=resume,
            progress=None if no_progress else progress_mode(),
            strict=strict,
        )
    except ConfigError as exc:
        _bad_input(str(exc))
    except OSError as exc:
        started = out is not None and storage.is_output(out)  # a manifest: there is something to resume
        _os_error(exc, "run stopped", RESUME_HINT if started else "")
    except CampaignInterrupted as exc:
        command = resume_command(campaign, out or exc.out, runs, seed, backend, scheduler)
        if until is not None:  # the looks replay on the stored runs
            command += " --until-decided" + "".join(f" --{k} {v}" for k, v in until.items() if v is not None)
        click.echo(
            f"{exc}: {exc.done} of {exc.total} runs done and kept in {exc.out}; finish with: {command}", err=True
        )
        sys.exit(exc.exit_code)
    except KeyboardInterrupt:  # before the campaign started
        click.echo("interrupted by SIGINT: nothing was flown", err=True)
        sys.exit(130)


def format_run_summary(result):
    """A few lines a reviewer reads first: success, propellant, final angle error, mode times."""
    from refexmc.config.mission_words import end_name

    table = result["runs"]
    counts = result["counts"]
    lines = [
        f"campaign {result['campaign']['name']}: {counts['runs']} runs, {counts['success']} succeeded, "
        f"{counts['error']} errored -> {result['out']}",
    ]
    ok = table[table["status"] == "ok"]
    if "entry_flight" in result["campaign"]["mission"]:  # an entry campaign (issue 24, docs/x38.md)
        if len(ok):
            lines.append(
                f"  RCS propellant [kg]: min {ok['rcs_propellant_kg'].min():.2f}, "
                f"median {ok['rcs_propellant_kg'].median():.2f}, max {ok['rcs_propellant_kg'].max():.2f}"
            )
        return "\n".join(lines)
    if len(ok) == 1:
        row = ok.iloc[0]
        verdict = "success" if row["success"] else f"FAILED ({row['failure_reason']})"
        end = end_name(result["campaign"]["mission"]) if row["success"] else "flight stopped"
        lines.append(f"  flight: {verdict}, {end} at t = {row['t_end_s']:.1f} s")
        lines.append(f"  propellant remaining: {100 * row['fuel_remaining']:.1f} % ({row['fuel_used_kg']:.3f} kg used)")
        theta = row["attitude_error_end_deg"]
        at = f"at the {end}" if row["success"] else "when it stopped"
        lines.append(f"  total angle error {at}: {theta:.2f} deg" if not math.isnan(theta) else "")
        names = [mode["name"] for mode in result["campaign"]["mission"]["modes"]]
        times = ", ".join(f"{m} {row[f't_{m.lower()}_s']:.1f}" for m in names)
        lines.append(f"  time in mode [s]: {times}")
    elif len(ok) > 1 and ok["fuel_remaining"].notna().any():  # wheels only: no propellant
        lines.append(
            f"  propellant remaining: min {100 * ok['fuel_remaining'].min():.1f} %, "
            f"median {100 * ok['fuel_remaining'].median():.1f} %"
        )
    return "\n".join(line for line in lines if line)


@main.command()
@click.argument("out", type=click.Path(file_okay=False, path_type=Path))
@click.option("--no-html", is_flag=True, help="Write summary.json only, no index.html and figures.")
@click.option("--require", "require", multiple=True, metavar="'METRIC OP VALUE'", help="An extra requirement.")
def report(out, no_html, require):
    """Summarise campaign OUT: statistics, requirement verdicts, figures (OUT/report/).

    Exit 1 when a requirement fails, or the campaign is incomplete or has errored runs (the CI gate).
    Example: refexmc report runs/refex-mc100 --require 'fuel_remaining.min >= 0.2'
    """
    from pyarrow import ArrowException

    from refexmc.report import make_report

    try:
        from refexmc.config import renames  # a name of before issue 34 means its new one

        result = make_report(out, require=[renames.new_text(text) for text in require], html=not no_html)
    except ConfigError as exc:
        _bad_input(str(exc))
    except OSError as exc:
        _os_error(exc, "report failed")
    except ArrowException as exc:
        _unreadable(exc, f"report failed: cannot read {out}", DAMAGED_HINT)
    click.echo(result["text"])
    sys.exit(0 if result["passed"] else 1)


@main.command()
@click.argument("baseline_out", type=click.Path(file_okay=False, path_type=Path))
@click.argument("out", type=click.Path(file_okay=False, path_type=Path))
@click.option(
    "--tolerance",
    "tolerances",
    multiple=True,
    metavar="METRIC=VALUE",
    help="Gate a metric: a change worse than VALUE (in its unit) is a regression when significant "
    "(inf: report only). Outputs without a requirement are gated only this way; any numeric runs "
    "column can be named.",
)
def compare(baseline_out, out, tolerances):
    """Compare campaign OUT against BASELINE_OUT by the mission's own metrics.

    Success and error rates, then each runs column a requirement judges (worse: its failing side;
    tolerance: 10 % of the baseline's margin), then the other outputs (shown; gated only with
    --tolerance). Paired run by run when both flew the same dispersed inputs (median difference,
    sign test; rates by McNemar), else Welch (rates: Newcombe); the p and the interval come from
    one test. Exit 1 when a metric is significantly worse by more than its tolerance (the CI
    gate, docs/compare.md).
    Example: refexmc compare baselines/smoke runs/smoke --tolerance pulses_total=50
    """
    from pyarrow import ArrowException

    from refexmc.report.compare import compare as compare_campaigns
    from refexmc.report.compare import format_table

    try:
        from refexmc.config import renames  # a name of before issue 34 means its new one

        result = compare_campaigns(baseline_out, out, [renames.new_text(text) for text in tolerances])
    except ConfigError as exc:
        _bad_input(str(exc))
    except OSError as exc:
        _os_error(exc, "compare failed")
    except ArrowException as exc:
        _unreadable(exc, f"compare failed: cannot read {baseline_out} or {out}", DAMAGED_HINT)
    click.echo(format_table(result))
    sys.exit(0 if result.passed else 1)


@main.command()
@click.argument("out", type=click.Path(file_okay=False, path_type=Path))
@click.argument("run_id", type=int)
@click.option("--history-rate", type=float, help="History sample rate [Hz] (default: every control step).")
@click.option("-o", "--output", "dest", type=click.Path(dir_okay=False, path_type=Path), help="History file.")
def rerun(out, run_id, history_rate, dest):
    """Re-fly run RUN_ID of campaign OUT bit for bit, with a full-rate history.

    Prints the run's summary row and whether it equals the stored one (exit 1 if not).
    Example: refexmc rerun runs/refex-mc100 42 -o worst.parquet
    """
    from pyarrow import ArrowException

    from refexmc.campaign.rerun import rerun as rerun_run

    try:
        result = rerun_run(out, run_id, history_rate_hz=history_rate, dest=dest)
    except ConfigError as exc:
        _bad_input(str(exc))
    except OSError as exc:
        _os_error(exc, "rerun failed")
    except ArrowException as exc:
        _unreadable(exc, f"rerun failed: cannot read {out}", DAMAGED_HINT)
    from refexmc.campaign.rerun import summary_lines

    for line in summary_lines(result):  # in the mission's words (a wheel vehicle: no propellant)
        click.echo(line)
    click.echo(f"  history: {result['path']}")
    if result["stored"] is None:
        click.echo("  (this run is not in OUT/runs: nothing to compare with)")
    elif result["differ"]:
        click.echo(f"  DIFFERS from the stored row in: {', '.join(result['differ'])}", err=True)
        sys.exit(1)
    else:
        click.echo("  summary row identical to the stored one")


@main.command()
@click.argument("files", nargs=-1, required=True, type=click.Path(dir_okay=False, path_type=Path))
@STRICT
@click.option(
    "--convergence",
    is_flag=True,
    help="Also fly each campaign's nominal run at its integration step and at a quarter of it, and "
    "compare every requirement's metric (docs/interface.md).",
)
def validate(files, strict, convergence):
    """Check campaign, vehicle or mission FILES without running anything.

    Design warnings (a design that validates but may not fly as meant: docs/missions.md) are
    printed on stderr; --strict makes them errors (exit 2). With --convergence each campaign's
    nominal run is flown at the mission's integrator steps and at a quarter of them; a
    requirement whose metric moves by more than 10 % of its margin is a warning.
    Example: refexmc validate campaigns/nominal.yaml configs/vehicles/refex.yaml --strict;
    refexmc validate campaigns/irassi-fine-pointing.yaml --convergence
    """
    from refexmc.config.load import load_any

    bad = 0
    for path in files:
        warnings = []
        try:
            kind, data = load_any(path, warnings)
        except ConfigError as exc:
            click.echo(f"error: {exc}", err=True)
            bad += 1
            continue
        if convergence and kind == "campaign":
            warnings += _convergence(path, data)
        elif convergence:
            click.echo(f"{path}: --convergence checks campaigns (requirements), not a {kind}: skipped")
        for warning in warnings:
            click.echo(f"{'error' if strict else 'warning'}: {warning}", err=True)
        if strict and warnings:
            bad += 1
            continue
        click.echo(f"{path}: valid {kind}" + (f", {plural(len(warnings), 'design warning')}" if warnings else ""))
    if bad:
        sys.exit(2)


def _convergence(path, campaign):
    """Print the step-convergence table of ``campaign`` (refexmc.campaign.convergence); return its warnings."""
    from refexmc.campaign import convergence

    checked = convergence.step_convergence(campaign)
    if checked is None:
        click.echo(f"{path}: step convergence not checked: an entry flight's RK4 step is its control period")
        return []
    comparisons, coarse_row, fine_row = checked
    click.echo(f"{path}: step convergence of the nominal run, {convergence.steps_text(campaign)}")
    if not comparisons:
        click.echo("  (the campaign has no requirements)")
    width = max([len(c.requirement) for c in comparisons] + [11])
    click.echo(f"  {'requirement':{width}s}  {'at the step':>14s}  {'at a quarter':>14s}  difference / margin")
    warnings = []
    for c in comparisons:
        click.echo(f"  {c.requirement:{width}s}  {c.coarse:14.7g}  {c.fine:14.7g}  {100.0 * c.fraction:.3g} %")
        if not c.converged:
            warnings.append(
                f"{path}: step convergence: '{c.requirement}' moves from {c.coarse:.7g} to {c.fine:.7g} with a "
                f"quarter of the step, {100.0 * c.fraction:.3g} % of its margin (more than "
                f"{100.0 * convergence.FRACTION_LIMIT:g} %): the integrator step is too coarse for it"
            )
    for name, row in (("the step", coarse_row), ("a quarter", fine_row)):
        if row["status"] == "error":
            warnings.append(f"{path}: step convergence: the nominal run at {name} errored: {row['failure_reason']}")
    return warnings


@main.command()
@click.argument("file", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object.")
@click.option("--torque", help="TX,TY,TZ: show what fires for this body torque (N m).")
@click.option("--level", help="thrust level for --torque (default: the vehicle's first).")
@STRICT
def inspect(file, as_json, torque, level, strict):
    """Print the design quantities derived from a vehicle (or a campaign's vehicle).

    omega_dot_max (000 eq. 1), gains (eq. 38, 34), f_min (eq. 44), switching times, allocation table;
    with --torque, the allocation of that torque: per-thruster command and the torque it realises.
    Example: refexmc inspect configs/vehicles/refex.yaml --json
    """
    from refexmc.config.derived import design
    from refexmc.config.design_checks import strict_error
    from refexmc.config.load import load_any

    warnings = []
    try:
        kind, data = load_any(file, warnings)
    except ConfigError as exc:
        _bad_input(str(exc))
    if strict and warnings:
        _bad_input(str(strict_error(warnings)))
    for warning in warnings:
        click.echo(f"warning: {warning}", err=True)
    if kind == "mission":
        _bad_input(f"{file}: a mission has no design quantities; give a vehicle or campaign file")
    vehicle = data["vehicle"] if kind == "campaign" else data
    if torque is not None:
        _inspect_torque(vehicle, torque, level, as_json)
        return
    info = design(vehicle)
    if "entry_control" in vehicle:  # an entry vehicle (docs/x38.md): what its entry flight uses
        from refexmc.config import entry

        info["entry"] = entry.design(vehicle)
    if as_json:
        click.echo(json.dumps(info, indent=2))
        return
    click.echo(format_design(vehicle.get("name", str(file)), info))


def _inspect_torque(vehicle, text, level, as_json):
    from refexmc.config.derived import allocate_torque, level_names

    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        values = []
    if len(values) != 3 or not all(math.isfinite(v) for v in values):
        _bad_input(f"--torque: expected three finite numbers TX,TY,TZ in N m, got {text!r}")
    levels = level_names(vehicle)
    if level is not None and level not in levels:
        _bad_input(f"--level: expected one of the vehicle's thrust levels {', '.join(levels)}, got {level!r}")
    result = allocate_torque(vehicle, values, level)
    if as_json:
        click.echo(json.dumps(result, indent=2))
        return
    alloc = result["allocation"]
    if "wheels" in result:
        lines = [f"distribution ({alloc['method']}) of torque {values} N m: motor torque commands -D torque"]
        commands = residue_free(alloc["commands"], ".6g")
        for i, (u, limited) in enumerate(zip(commands, alloc["limited_commands"], strict=True)):
            note = f", limited to {limited:.6g}" if limited != alloc["commands"][i] else ""
            lines.append(f"  wheel {i + 1:2d}  {u:12.6g} N m{note}")
        lines.append(f"  realised body torque [N m]: {shown(alloc['realised_torque_n_m'], '.6g')}")
        click.echo("\n".join(lines))
        return
    lines = [f"allocation ({alloc['method']}, {alloc['level']} thrust) of torque {values} N m"]
    if alloc["method"] == "table":
        opened = sum(u > 0.0 for u in alloc["commands"])
        lines[0] += f": {opened} valves open, thrust derated x{alloc['derating']:g}"
    for i, u in enumerate(alloc["commands"]):
        if u > 0.0:
            lines.append(f"  thruster {i + 1:2d}  {u:10.6f} N")
    realised = shown(alloc["realised_torque_n_m"], ".6g")
    lines.append(f"  realised torque [N m]: {realised}; total thrust {sum(alloc['commands']):.6f} N")
    if alloc["attained_share"] is not None and alloc["attained_share"] < 1.0:
        lines.append(f"  not attainable: {100 * alloc['attained_share']:.2f} % of it along its direction")
    click.echo("\n".join(lines))


def format_design(name, info):
    """``refexmc inspect``'s text: the attitude design, then an entry vehicle's entry part."""
    text = _format_attitude_design(name, info)
    if "entry" not in info:
        return text
    return text + "\n" + "\n".join(_format_entry(info["entry"]))


def _format_entry(entry):
    def vec(values, fmt):
        return shown(values, fmt, "  ")

    control, flaps = entry["control"], entry["flaps"]
    lines = [
        "  entry flight (missions with entry_flight; docs/x38.md): entry_control and surfaces fly it; the",
        "  controller, gains and PWPF above are those of attitude missions",
        f"    RCS pure moment [N m]       {vec(entry['rcs_capacity_n_m'], '10.1f')}   x y z, every thruster at "
        "full thrust",
        f"    propellant [g/s per kN m]   {vec([w * 1e6 for w in entry['propellant_kg_s_per_n_m']], '10.3f')}   "
        "b_th K per axis, what the blending minimises (003 eq. 5)",
        f"    body flaps [deg]            {flaps['min_deg']:g} .. {flaps['max_deg']:g}, "
        f"rate {flaps['rate_max_deg_s']:g} deg/s, lag {entry['time_constant_s']:g} s",
    ]
    if "flap_hinge_reach_deg" in entry:
        reach = entry["flap_hinge_reach_deg"]
        pairs = ", ".join(
            f"{q / 1e3:g} kPa: {d:.1f}" for q, d in zip(reach["qbar_pa"], reach["deflection_deg"], strict=True)
        )
        lines.append(
            f"      hinge moment limits the flap above q {reach['binds_above_qbar_pa'] / 1e3:.1f} kPa at alpha "
            f"{reach['alpha_deg']:g} deg; reach [deg]: {pairs}"
        )
    if "blocked" in flaps:
        blocked = flaps["blocked"]
        lines.append(f"      {blocked['flap']} flap blocked at {blocked['deflection_deg']:g} deg (vehicle file)")
    if "rudders" in entry:
        rudders = entry["rudders"]
        lines.append(
            f"    rudders [deg]               {rudders['min_deg']:g} .. {rudders['max_deg']:g}, rate "
            f"{rudders['rate_max_deg_s']:g} deg/s, usable below Mach {rudders['usable_below_mach']:g}"
        )
    lines.append(
        f"    control at {entry['control_rate_hz']:g} Hz: angle gains {vec(control['angle_gain_1_s'], 'g')} 1/s "
        f"(alpha, beta, bank), rate gain {control['rate_gain_1_s']:g} 1/s, integral "
        f"{control['integral_gain_1_s']:g} 1/s, alignment {control['align_gain_1_s']:g} 1/s "
        f"within {control['align_limit_deg']:g} deg"
    )
    return lines


def _format_attitude_design(name, info):
    from refexmc.config.derived import CORRECTION_WARNING_MS

    def vec(values, fmt):
        width = int(fmt.split(".")[0].rstrip("dfg") or 0)
        return "  ".join(format(v, fmt) if v is not None else "-".rjust(width) for v in residue_free(values, fmt))

    lines = [f"vehicle {name}"]
    if "lever_arms_m" in info and info.get("attitude_controlled", True):
        lines.append(f"  lever arms l [m]              {vec(info['lever_arms_m'], '8.3f')}")
        lines.append(f"  thrusters per axis n_t        {vec(info['thrusters_per_axis'], '8d')}")
    if "feed" in info:
        lines += _format_feed(info["feed"])
    if "translation" in info:
        lines += _format_translation(info["translation"], vec)
    if not info.get("attitude_controlled", True):  # a hop: no attitude gains, PWPF or allocation to show
        lines.append(
            f"  attitude: not controlled (flight_software gains all zero); actuation {info['actuation']} opens the "
            "valves the translation law asks for"
        )
        return "\n".join(lines)
    lines.append(f"  controller {info['controller']}, gains {info['gains_source']}, actuation {info['actuation']}")
    if "smc" in info:
        smc = info["smc"]
        lines.append(f"    slope Lambda [1/s]          {vec(smc['slope_s'], '8.4g')}")
        lines.append(f"    gain G [rad/s^2]            {vec(smc['gain_rad_s2'], '8.4g')}")
        lines.append(f"    boundary layer [rad/s]      {vec(smc['boundary_layer_rad_s'], '8.4g')}")
    for level in info["levels"]:
        thrust = level in info.get("rcs_levels", ())
        lines.append(f"  {level} thrust" if thrust else f"  {level} (reaction wheels)")
        accel, torque = ("8.4f", "8.3f") if thrust else ("10.4g", "10.4g")  # wheels: ~1e-4 rad/s^2
        lines.append(f"    omega_dot_max [rad/s^2]     {vec(info['omega_dot_max_rad_s2'][level], accel)}")
        lines.append(f"    tau_max [N m]               {vec(info['torque_max_n_m'][level], torque)}")
        if info["controller"] != "smc":
            lines.append(f"    Kp                          {vec(info['gains'][level]['kp'], '8.3f')}")
            lines.append(f"    Kd                          {vec(info['gains'][level]['kd'], '8.3f')}")
        if level in info.get("deadbands", {}):
            band, bit = info["deadbands"][level], info["minimum_impulse_bit"][level]
            j = "" if info["controller"] == "pd" else "J "
            lines.append(f"    rate deadband [deg/s]       {vec(band['rate_deg_s'], '8.4f')}   tau_min / ({j}Kd)")
            lines.append(
                f"    angle deadband [deg]        {vec(band['angle_deg'], '8.4f')}   2 asin(tau_min / ({j}Kp))"
            )
            lines.append(f"    min impulse bit [N m s]     {vec(bit['n_m_s'], '8.4f')}   shortest pulse, '+' entry")
            lines.append(f"      its rate change [deg/s]   {vec(bit['rate_deg_s'], '8.4f')}")
        if level in info.get("pulse_equivalent_ms", {}):
            lines.append(
                f"    valves: a {info['hardware_min_on_ms']:g} ms pulse gives {info['pulse_equivalent_ms'][level]:.2f} "
                f"ms of full thrust; impulse-matching correction {info['pulse_correction_matching_ms'][level]:.2f} ms"
            )
    if "wheels" in info:
        lines += _format_wheels(info["wheels"], vec)
    if "pwpf_t_on_ms" not in info:
        return "\n".join(lines)
    lines.append(
        f"  PWPF: t_on {info['pwpf_t_on_ms']:g} ms, t_off {info['pwpf_t_off_ms']:g} ms, "
        f"correction {info['pwpf_correction_ms']:g} ms, tau_min {100 * info['tau_min_fraction']:.1f} %, "
        f"f_min {100 * info['f_min_fraction']:.1f} % of tau_max"
    )
    lines.append(
        f"  hardware switching limits: min pulse {info['hardware_min_on_ms']:g} ms, "
        f"min rest {info['hardware_min_off_ms']:g} ms"
    )
    for level, matching in info["pulse_correction_matching_ms"].items():
        if abs(info["pwpf_correction_ms"] - matching) > CORRECTION_WARNING_MS:
            lines.append(
                f"  WARNING: the PWPF correction {info['pwpf_correction_ms']:g} ms differs from the {level}-thrust "
                f"impulse-matching correction {matching:.2f} ms by more than {CORRECTION_WARNING_MS:g} ms "
                "(000 sec. 5: the pulses then deliver a different impulse than the modulator assumes)"
            )
    if "allocation" not in info:
        if info["actuation"] == "lp_pwm":
            lines.append(f"  actuation {info['actuation']}: LP allocation (004 eq. 2-5); see --torque")
        return "\n".join(lines)
    levels = list(info["allocation_torque_n_m"])
    lines.append("  allocation: axis command -> thrusters; the torque they realise [N m, x y z], derated, per level")
    lines.append(f"    {'':8s} {'':14s}" + "".join(f"{level:>30s}" for level in levels))
    for key, ids in info["allocation"].items():
        torques = "".join(f"  {vec(info['allocation_torque_n_m'][level][key], '8.3f')}" for level in levels)
        lines.append(f"    {key:8s} {', '.join(map(str, ids)):14s}{torques}")
    return "\n".join(lines)


def _format_feed(feed):
    """The cold-gas tank and nozzle of a blow-down or regulated feed (002 eq. 1-20; config.feed)."""
    return [
        f"  feed {feed['model']} (002 sec. 3): {feed['gas_kg']:.4g} kg of gas, blow-down time constant "
        f"{feed['blow_down_time_constant_s']:.4g} s per open thruster",
        f"    thrust coefficient C_F      {feed['thrust_coefficient']:.5f} (vacuum, exit Mach {feed['exit_mach']:.3f})",
        f"    exhaust velocity [m/s]      {feed['exhaust_velocity_m_s']:.2f} (Isp {feed['specific_impulse_s']:.2f} s)",
        f"    thrust [N]: initial         {feed['initial_thrust_n']:.5g}, "
        f"at half tank {feed['thrust_at_half_tank_n']:.5g}",
        f"    total impulse [N s]         {feed['total_impulse_n_s']:.5g} (all the gas, vacuum)",
    ] + [
        f"    regulated {level}: chamber held at {pressure / 1e5:.4g} bar while the tank is above it"
        for level, pressure in feed.get("set_pressure_pa", {}).items()
    ]


def _format_translation(translation, vec):
    """The translation law of translate modes (trajectory local; 002 sec. 4; config.derived)."""
    law = translation["law"]
    what = {
        "time_optimal": "002 eq. 44 per body axis, coasts on sigma0, keeps the reserve on sigma1, brakes on sigma2",
        "bang_bang": "-sign(sigma2) per body axis (002 Fig. 8's comparison)",
        "pd_pwm": "a = -kp e - kd v per body axis, pulse-width modulated over whole control periods",
    }[law]
    lines = [
        f"  translation law {law} of translate modes: {what}",
        f"    deadband                    {translation['deadband_position_m']:g} m and "
        f"{translation['deadband_speed_m_s']:g} m/s per axis: within both the axis coasts",
        "    axis  thrusters +     thrusters -     n C_F A_t [N/Pa]  tau [s]   accel at P0 [m/s^2]",
    ]
    for axis, name in enumerate("xyz"):
        plus, minus = translation["thrusters"][axis]["+"], translation["thrusters"][axis]["-"]
        lines.append(
            f"    {name:4s}  {', '.join(map(str, plus)) or '-':14s}  {', '.join(map(str, minus)) or '-':14s}  "
            f"{translation['force_per_pa_n_pa'][axis]:16.4g}  {translation['time_constant_s'][axis]:7.4g}   "
            f"{translation['initial_accel_m_s2'][axis]:.4g}"
        )
    if law == "pd_pwm":
        gains = ", ".join(
            f"{key} {translation[key]:g}"
            for key in ("position_gain_s2", "velocity_gain_s", "pwm_period_s")
            if key in translation
        )
        lines.append(f"    {gains}")
    return lines


def _format_wheels(wheels, vec):
    lines = [
        f"  reaction wheels: {len(wheels['axes'])}, {wheels['wheel_torque_max_n_m']:g} N m and "
        f"{wheels['wheel_momentum_max_n_m_s']:g} N m s each ({wheels['speed_max_rpm']:.0f} rpm); "
        f"distribution {wheels['distribution']} (001 sec. 9.1)"
    ]
    lines.append("    wheel  axis (body)                    distribution row D")
    for i, (axis, row) in enumerate(zip(wheels["axes"], wheels["distribution_matrix"], strict=True)):
        lines.append(f"    {i + 1:5d}  {vec(axis, '8.4f')}   {vec(row, '8.4f')}")
    for k, null in enumerate(zip(*wheels["null_space"], strict=True)):
        lines.append(f"    null space {k + 1}: {vec(null, '8.4f')} (wheel torques that turn no body axis)")
    managed = wheels["null_space_management"]
    if managed is None:
        lines.append("    null-space momentum management: off")
    else:
        target = "zero" if managed["target"] == "zero" else f"bias {managed['bias_n_m_s']} N m s"
        cap = managed.get("torque_max_n_m", wheels["wheel_torque_max_n_m"])
        lines.append(
            f"    null-space momentum management: target {target}, time constant {managed['time_constant_s']:g} s, "
            f"deadband {managed.get('deadband_n_m_s', 0.0):g} N m s, at most {cap:g} N m per wheel"
            + (
                f", gives up {managed['give_up_beyond_n_m_s']:g} N m s beyond the deadband"
                if "give_up_beyond_n_m_s" in managed
                else ""
            )
        )
    lines.append(f"    largest body torque [N m]   {vec(wheels['torque_max_n_m'], '8.4g')}")
    return lines


def console():
    """The ``refexmc`` command: :func:`main` in a process of its own.

    The process ends with the command, so its last garbage collection, a walk over every object
    pandas, pyarrow and numba left (~0.2 s), is skipped: at exit the objects are frozen out of
    the collector's reach, and the operating system takes the memory back. Files are closed by
    then; tests call :func:`main` in their own process, which this does not touch.
    """
    atexit.register(gc.freeze)  # atexit runs before the interpreter's last collection
    main()


if __name__ == "__main__":
    console()
