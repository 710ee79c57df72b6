"""Where a campaign's time per run goes (issue 15): kernel, sampling, history, encoding, transfer.

Flies ``--runs`` runs of ``campaigns/refex-mc100.yaml`` in this process, one at a time, through
the same functions a worker calls (``RunPlan.prepare_runs`` per chunk, ``simulate.fly``,
``storage.runs_row``, ``storage.histories_table`` per chunk, ``worker.Flown.encode``), timing
each stage, then the hand-over of a chunk's result to the parent (pickle dumps + loads of the
``Flown``, what loky does) and the parent's atomic write of the two parts. Chunks are of
``--chunk`` runs, as ``refexmc run`` makes them.

It also times the whole command, ``refexmc run ... -j 1``, at ``--runs`` and at ``--runs / 10``
runs, and reports its marginal cost per run (the difference over the difference in runs, so that
start-up cancels) against the mean kernel time of the same runs: the issue's target is
marginal <= 1.3 x kernel.

Usage: .venv/bin/python benchmarks/bench_run_cost.py [--runs 1000] [--chunk 32] [--repeats 3] [--json PATH]
"""

import argparse
import json
import os
import pickle
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from refexmc.campaign import storage  # noqa: E402
from refexmc.campaign.chunk import RunPlan  # noqa: E402
from refexmc.campaign.worker import Flown  # noqa: E402
from refexmc.config.load import apply_overrides, load_campaign  # noqa: E402
from refexmc.simulate import fly  # noqa: E402

CAMPAIGN = ROOT / "campaigns" / "refex-mc100.yaml"
STAGES = ("sampling", "kernel", "runs_row", "history_table", "encode", "transfer", "parent_write")


def stage_times(runs, chunk):
    """Seconds spent per stage over ``runs`` runs (chunk stages spread over their runs)."""
    campaign = apply_overrides(load_campaign(CAMPAIGN), runs=runs)
    plan = RunPlan(campaign)
    rate = campaign["output"]["history_rate_hz"]
    fly(plan.prepare(1)[3], nav_seed=1, history_rate_hz=rate)  # compiled or loaded from the cache
    spent = dict.fromkeys(STAGES, 0.0)
    clock = time.perf_counter
    with tempfile.TemporaryDirectory() as tmp:
        for start in range(0, runs, chunk):
            rows, results = [], []
            run_ids = list(range(start, min(runs, start + chunk)))
            t0 = clock()
            prepared = plan.prepare_runs(run_ids)  # a worker draws its chunk's parameters together
            spent["sampling"] += clock() - t0
            for run_id, (seed, failed, params, inputs) in zip(run_ids, prepared, strict=True):
                t1 = clock()
                result = fly(inputs, nav_seed=seed, history_rate_hz=rate, mode_names=plan.mode_names)
                t2 = clock()
                row = storage.runs_row(run_id, seed, failed, result, plan.value_columns, plan.n_thrusters)
                row.update(params)
                t3 = clock()
                results.append(result)
                rows.append(row)
                spent["kernel"] += t2 - t1
                spent["runs_row"] += t3 - t2
            t0 = clock()
            history = storage.histories_table(run_ids, results)  # once per chunk, as a worker does
            t1 = clock()
            spent["history_table"] += t1 - t0
            t0 = clock()
            flown = Flown.encode(rows, [history])
            t1 = clock()
            received = pickle.loads(pickle.dumps(flown, protocol=pickle.HIGHEST_PROTOCOL))
            t2 = clock()
            name = storage.part_name(start // chunk)
            storage.write_bytes_atomic(received.history, Path(tmp) / "histories" / name)
            storage.write_bytes_atomic(received.runs, Path(tmp) / "runs" / name)
            t3 = clock()
            spent["encode"] += t1 - t0
            spent["transfer"] += t2 - t1
            spent["parent_write"] += t3 - t2
    return spent


def command_seconds(runs, out):
    command = [sys.executable, "-m", "refexmc.cli", "run", str(CAMPAIGN), "--runs", str(runs), "-j", "1"]
    command += ["-o", str(out), "--overwrite", "--no-progress"]
    t0 = time.perf_counter()
    subprocess.run(command, cwd=ROOT, check=True, stdout=subprocess.DEVNULL)
    return time.perf_counter() - t0


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=1000)
    parser.add_argument("--chunk", type=int, default=32)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--json", type=Path)
    args = parser.parse_args()

    breakdowns = [stage_times(args.runs, args.chunk) for _ in range(args.repeats)]
    per_run_ms = {s: statistics.median(b[s] for b in breakdowns) / args.runs * 1e3 for s in STAGES}
    total = sum(per_run_ms.values())
    small = max(1, args.runs // 10)
    with tempfile.TemporaryDirectory() as tmp:
        command_seconds(small, Path(tmp) / "warm")  # kernels in the cache, files in the page cache
        pairs = [
            (command_seconds(small, Path(tmp) / "small"), command_seconds(args.runs, Path(tmp) / "big"))
            for _ in range(args.repeats)
        ]
    marginal_ms = statistics.median((big - small_s) / (args.runs - small) for small_s, big in pairs) * 1e3
    fixed_s = statistics.median(small_s - small * marginal_ms / 1e3 for small_s, _ in pairs)
    result = {
        "command": " ".join(sys.argv),
        "machine": f"{platform.node()} {platform.machine()} {os.cpu_count()} cpus, Python {platform.python_version()}",
        "runs": args.runs,
        "chunk": args.chunk,
        "per_run_ms": per_run_ms,
        "in_process_total_ms": total,
        "command_marginal_ms": marginal_ms,
        "command_fixed_s": fixed_s,
        "marginal_over_kernel": marginal_ms / per_run_ms["kernel"],
        "command_seconds": pairs,
    }
    width = max(map(len, STAGES))
    print(f"per run, median of {args.repeats} x {args.runs} runs in chunks of {args.chunk}:")
    for stage in STAGES:
        print(f"  {stage:<{width}}  {per_run_ms[stage]:7.3f} ms  {100 * per_run_ms[stage] / total:5.1f} %")
    print(f"  {'total':<{width}}  {total:7.3f} ms")
    print(f"refexmc run -j 1: marginal {marginal_ms:.3f} ms per run = {result['marginal_over_kernel']:.2f} x kernel;")
    print(f"  fixed {fixed_s:.2f} s (from {small} and {args.runs} runs)")
    if args.json:
        args.json.write_text(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
