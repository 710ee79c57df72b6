"""The timeline of one warm ``refexmc run`` (issue 15: the fixed cost of a campaign).

Runs ``refexmc run CAMPAIGN --runs N -j J -o OUT --overwrite --no-progress`` as a new process
``--repeats`` times (after one untimed run, so that the kernels are in numba's disk cache and
the files in the page cache) and reads the milestones from what the command leaves in OUT,
measured from the moment the process is started:

- ``validated``: ``campaign.resolved.yaml`` written (campaign resolved, OUT checked, locked, prepared);
- ``first part``: the first ``runs`` part written (the workers started and flew a chunk);
- ``last part``: the last ``runs`` part written;
- ``done``: ``manifest.json`` written as complete (``run_campaign`` is about to return);
- ``exit``: the process has exited.

Prints the median of each milestone over the repeats. File times have the file system's
granularity (a few milliseconds).

Usage: .venv/bin/python benchmarks/bench_startup.py [--runs 2] [-j 1] [--repeats 5] [--campaign PATH]
       [--scheduler local:N]
"""

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CAMPAIGN = ROOT / "campaigns" / "refex-mc100.yaml"
MILESTONES = ("validated", "first part", "last part", "done", "exit")


def _mtime(path):
    return path.stat().st_mtime_ns / 1e9


def timeline(campaign, runs, jobs, out, scheduler=None):
    """{milestone: seconds after the process was started} of one ``refexmc run`` (on the Dask
    cluster ``scheduler`` if given, e.g. ``local:2``)."""
    command = [sys.executable, "-m", "refexmc.cli", "run", str(campaign), "--runs", str(runs), "-j", str(jobs)]
    command += ["-o", str(out), "--overwrite", "--no-progress"]
    command += ["--backend", "dask", "--scheduler", scheduler] if scheduler else []
    start = time.time()
    subprocess.run(command, cwd=ROOT, check=True, stdout=subprocess.DEVNULL)
    end = time.time()
    parts = sorted(_mtime(path) for path in (out / "runs").glob("*.parquet"))
    times = {
        "validated": _mtime(out / "campaign.resolved.yaml"),
        "first part": parts[0],
        "last part": parts[-1],
        "done": _mtime(out / "manifest.json"),
    }
    return {**{name: t - start for name, t in times.items()}, "exit": end - start}


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=2)
    parser.add_argument("-j", "--jobs", type=int, default=1)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--campaign", type=Path, default=CAMPAIGN)
    parser.add_argument("--scheduler", help="fly on this Dask cluster (--backend dask), e.g. local:2")
    args = parser.parse_args()

    env_note = os.environ.get("REFEXMC_CHUNK_SIZE")
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "out"
        timeline(args.campaign, args.runs, args.jobs, out, args.scheduler)  # kernels cached, files in the page cache
        samples = [timeline(args.campaign, args.runs, args.jobs, out, args.scheduler) for _ in range(args.repeats)]
    where = f"--scheduler {args.scheduler}" if args.scheduler else f"-j {args.jobs}"
    print(f"refexmc run --runs {args.runs} {where}, median of {args.repeats} warm runs [s after start]:")
    if env_note:
        print(f"  (REFEXMC_CHUNK_SIZE={env_note})")
    for name in MILESTONES:
        values = [sample[name] for sample in samples]
        spread = f"{min(values):.2f}..{max(values):.2f}"
        print(f"  {name:<10}  {statistics.median(values):6.2f}  ({spread})")


if __name__ == "__main__":
    main()
