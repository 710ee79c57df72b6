"""Campaign throughput, parallel speed-up, memory and storage (issue 3 targets).

Runs ``refexmc run campaigns/refex-mc100.yaml --runs N -j J`` as a subprocess, as a user does,
and measures its wall time and the peak resident memory of its process tree (the CLI process
and its worker processes, sampled from /proc every 50 ms). Benchmarks:

0. The machine's own ceiling: the campaign's per-run work flown in one process, then in two
   processes at once (no pool, no IPC, no writing): what -j 2 could give at best here.
1. 1,000 runs at -j 1 and at -j 2, alternating, ``--repeats`` times: runs/s and the speed-up
   (target >= 1.8x), both for the whole command and while flying (from the part files' write
   times, :func:`flying_rate`), and a 20-run campaign for the fixed cost.
2. Peak RSS at 1,000 and at 10,000 runs, -j 2 (target: within 15 % of each other).
3. Parquet bytes per run (runs and histories parts) of the 10,000-run campaign.
4. Wall time of the 10,000-run campaign at -j 2 (target <= 180 s).

Usage: .venv/bin/python benchmarks/bench_campaign.py [--repeats 3] [--big-runs 10000] [--json PATH]
"""

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import pyarrow.parquet as pq

ROOT = Path(__file__).resolve().parents[1]
CAMPAIGN = ROOT / "campaigns" / "refex-mc100.yaml"
REFEXMC = [sys.executable, "-m", "refexmc.cli"]


def _children(pid):
    """All descendants of ``pid`` (from /proc/*/stat parent ids)."""
    parents = {}
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                fields = (entry / "stat").read_text().rsplit(")", 1)[1].split()
            except OSError:
                continue
            parents.setdefault(int(fields[1]), []).append(int(entry.name))
    out, todo = [], [pid]
    while todo:
        kids = parents.get(todo.pop(), [])
        out += kids
        todo += kids
    return out


def _rss_kib(pid):
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1])
    except OSError:
        pass
    return 0


def run_cli(runs, jobs, out, campaign=CAMPAIGN, options=()):
    """(wall s, peak tree RSS MiB, peak single-process RSS MiB) of one `refexmc run` (``options``:
    more of its options, e.g. ``("--backend", "dask", "--scheduler", "local:2")``)."""
    command = [*REFEXMC, "run", str(campaign), "--runs", str(runs), "-j", str(jobs), "-o", str(out)]
    command += ["--overwrite", "--no-progress", *options]
    peak = {"tree": 0, "process": 0}
    t0 = time.perf_counter()
    proc = subprocess.Popen(command, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    done = threading.Event()

    def sample():
        while not done.is_set():
            rss = [_rss_kib(p) for p in [proc.pid, *_children(proc.pid)]]
            peak["tree"] = max(peak["tree"], sum(rss))
            peak["process"] = max(peak["process"], max(rss))
            time.sleep(0.05)

    thread = threading.Thread(target=sample, daemon=True)
    thread.start()
    _, stderr = proc.communicate()
    wall = time.perf_counter() - t0
    done.set()
    thread.join()
    if proc.returncode not in (0, 1):
        raise RuntimeError(f"refexmc run failed ({proc.returncode}): {stderr.decode()[-2000:]}")
    return wall, peak["tree"] / 1024.0, peak["process"] / 1024.0


_PROBE = """
import sys, time
from refexmc.campaign.chunk import fly_chunk
from refexmc.campaign.run import resolve_campaign
_, campaign = resolve_campaign(sys.argv[1], runs=int(sys.argv[2]) + 1)
fly_chunk(campaign, [0])  # kernels loaded, imports done: only flying is timed
t0 = time.perf_counter()
fly_chunk(campaign, range(1, int(sys.argv[2]) + 1))
print(time.perf_counter() - t0)
"""


def machine_ceiling(runs, repeats):
    """The speed-up this machine gives the campaign's own work: ``runs`` runs flown in-process by
    one process alone, then by two processes at once (each ``runs``); no pool, no IPC, no writing.

    Returns (one-process s, two-process s (the slower), ceiling = 2 * t1 / t2), medians.
    """
    command = [sys.executable, "-c", _PROBE, str(CAMPAIGN), str(runs)]
    alone, together = [], []
    for _ in range(repeats):
        alone.append(float(subprocess.run(command, cwd=ROOT, capture_output=True, check=True, text=True).stdout))
        procs = [subprocess.Popen(command, cwd=ROOT, stdout=subprocess.PIPE, text=True) for _ in range(2)]
        together.append(max(float(proc.communicate()[0]) for proc in procs))
    t1, t2 = statistics.median(alone), statistics.median(together)
    return t1, t2, 2 * t1 / t2


def flying_rate(out):
    """Runs per second while the workers fly, read off the campaign itself: the runs parts' write
    times (ns) from the first chunk written to the last, over the runs of all chunks but the first.
    Start-up (imports, worker spawn, kernel load) and the final read are outside this window."""
    parts = sorted((p.stat().st_mtime_ns, pq.ParquetFile(p).metadata.num_rows) for p in (out / "runs").glob("part-*"))
    runs_after_first = sum(rows for _, rows in parts[1:])
    return runs_after_first / ((parts[-1][0] - parts[0][0]) * 1e-9)


def parquet_bytes(out):
    sizes = {kind: sum(p.stat().st_size for p in (out / kind).glob("part-*.parquet")) for kind in ("runs", "histories")}
    return sizes


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--runs", type=int, default=1000)
    parser.add_argument("--big-runs", type=int, default=10000)
    parser.add_argument("--json", type=Path)
    args = parser.parse_args()
    results = {
        "machine": {
            "nproc": os.cpu_count(),
            "affinity": len(os.sched_getaffinity(0)),
            "python": platform.python_version(),
            "platform": platform.platform(),
        }
    }
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        run_cli(20, 2, tmp / "warm")  # fills or refreshes the numba cache; untimed
        t1, t2, ceiling = machine_ceiling(args.runs, args.repeats)
        results["bench0"] = {"runs": args.runs, "one_process_s": t1, "two_processes_s": t2, "ceiling": ceiling}
        print(f"machine ceiling: {args.runs} runs in one process {t1:.2f} s, two at once {t2:.2f} s: {ceiling:.2f}x")
        times = {1: [], 2: []}
        rates = {1: [], 2: []}  # runs/s while flying (flying_rate)
        fixed = {1: [], 2: []}  # a 20-run campaign: start-up, worker spawn, final read
        rss_small = []
        for _ in range(args.repeats):
            for jobs in (1, 2):
                fixed[jobs].append(run_cli(20, jobs, tmp / f"f{jobs}")[0])
                wall, tree, _ = run_cli(args.runs, jobs, tmp / f"j{jobs}")
                times[jobs].append(wall)
                rates[jobs].append(flying_rate(tmp / f"j{jobs}"))
                if jobs == 2:
                    rss_small.append(tree)
                rate = args.runs / wall
                print(
                    f"{args.runs} runs -j {jobs}: {wall:.2f} s, {rate:.0f} runs/s whole command, "
                    f"{rates[jobs][-1]:.0f} runs/s flying, peak RSS {tree:.0f} MiB"
                )
        speedups = [a / b for a, b in zip(times[1], times[2], strict=True)]
        results["bench1"] = {
            "runs": args.runs,
            "j1_s": times[1],
            "j2_s": times[2],
            "j1_median_s": statistics.median(times[1]),
            "j2_median_s": statistics.median(times[2]),
            "j1_runs_per_s": args.runs / statistics.median(times[1]),
            "j2_runs_per_s": args.runs / statistics.median(times[2]),
            "speedup_pairwise": speedups,
            "speedup_median": statistics.median(speedups),
        }
        steady = {j: (args.runs - 20) / (statistics.median(times[j]) - statistics.median(fixed[j])) for j in (1, 2)}
        results["bench1"]["fixed_20_runs_s"] = fixed
        results["bench1"]["steady_runs_per_s"] = steady
        results["bench1"]["steady_speedup"] = steady[2] / steady[1]
        flying = [b / a for a, b in zip(rates[1], rates[2], strict=True)]
        results["bench1"]["flying_runs_per_s"] = rates
        results["bench1"]["flying_speedup_pairwise"] = flying
        results["bench1"]["flying_speedup_median"] = statistics.median(flying)
        print(
            f"flying rate -j1 {statistics.median(rates[1]):.0f}, -j2 {statistics.median(rates[2]):.0f} runs/s: "
            f"speed-up median {statistics.median(flying):.2f}x (pairwise {[round(x, 2) for x in flying]})"
        )
        print(f"speed-up -j2 / -j1: median {statistics.median(speedups):.2f}x (pairwise {speedups})")
        print(
            f"20-run campaign (fixed cost): -j1 {statistics.median(fixed[1]):.2f} s, "
            f"-j2 {statistics.median(fixed[2]):.2f} s; "
            f"steady state {steady[1]:.0f} vs {steady[2]:.0f} runs/s = {steady[2] / steady[1]:.2f}x"
        )
        wall, tree, process = run_cli(args.big_runs, 2, tmp / "big")
        sizes = parquet_bytes(tmp / "big")
        results["bench2"] = {
            "rss_small_mib": statistics.median(rss_small),
            "rss_big_mib": tree,
            "rss_big_max_process_mib": process,
            "ratio": tree / statistics.median(rss_small),
        }
        results["bench3"] = {k: v / args.big_runs for k, v in sizes.items()}
        results["bench4"] = {"runs": args.big_runs, "wall_s": wall, "runs_per_s": args.big_runs / wall}
        print(
            f"{args.big_runs} runs -j 2: {wall:.1f} s ({args.big_runs / wall:.0f} runs/s); peak RSS {tree:.0f} MiB "
            f"vs {statistics.median(rss_small):.0f} MiB at {args.runs} "
            f"({100 * (results['bench2']['ratio'] - 1):+.1f} %)"
        )
        print(
            f"Parquet bytes per run: runs {sizes['runs'] / args.big_runs:.0f}, "
            f"histories {sizes['histories'] / args.big_runs:.0f}"
        )
    if args.json:
        args.json.write_text(json.dumps(results, indent=2) + "\n")


if __name__ == "__main__":
    main()
