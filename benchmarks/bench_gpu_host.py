"""The host's share of a GPU campaign (issue 37), measured without a GPU.

``refexmc run --backend cuda`` (refexmc.campaign.cuda_backend) does on the host, per run, what a
loky worker does besides flying: draw and pack the run (``RunPlan.prepare_runs``), stack the runs'
inputs into a launch's arrays (``simulate_cuda.Batch``), then name each run's outputs
(``Batch.rows``: ``simulate.flight_result``, ``RunPlan.result_row``), build the chunk's runs and
history tables and encode both parts. The GPU's flight time can only hide behind this work, so it
bounds the throughput of a GPU campaign whatever the GPU: this benchmark times each stage on
``--runs`` runs of ``campaigns/refex-mc100.yaml`` (histories as the campaign declares), with the
batch's outputs filled by the CPU kernel (the function each GPU thread runs), and the backend's
chunk naming and encoding (``cuda_backend._chunk_parts``) on 1 thread and on every core.

The projection to 10^6 runs: with ``-j 1`` the ``refexmc run`` process prepares and stacks every
launch itself, one run after the other (``parent_serial_in_process``); with ``-j`` > 1 loky workers
draw and pack a chunk each and the parent only unpickles and stacks (``parent_cpu_with_pool``: its
CPU time, all its threads); a thread per core names and encodes
(``chunk_parts``: Arrow's table building and encoding release the GIL, naming holds it); and the
floor if all this host work were spread over 16 processes without overhead.

Usage: .venv/bin/python benchmarks/bench_gpu_host.py [--runs 2000] [--chunk 100] [--json PATH]
"""

import argparse
import json
import os
import platform
import statistics
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402

from refexmc import simulate  # noqa: E402
from refexmc.campaign import cuda_backend, pool, storage  # noqa: E402
from refexmc.campaign.chunk import RunPlan  # noqa: E402
from refexmc.campaign.run import plan_chunks  # noqa: E402
from refexmc.config.load import apply_overrides, load_campaign  # noqa: E402
from refexmc.core import flight, pointing  # noqa: E402
from refexmc.core import layout as L  # noqa: E402
from refexmc.simulate_cuda import Batch  # noqa: E402

CAMPAIGN = ROOT / "campaigns" / "refex-mc100.yaml"
RUNS_AT_SCALE = 1_000_000


def _fill_on_cpu(batch):
    """The batch's outputs as its launch would leave them: each flown run by the family's CPU kernel."""
    run_flight = flight.kernel(*batch.family)
    for j, k in enumerate(batch.flown):
        inputs = batch.prepared[k][3]
        record = pointing.Record(batch.p_table, batch.p_samples[j], batch.p_counts[j], batch.p_work[j])
        run_flight(
            inputs, np.int64(batch.seeds[j]), np.int64(batch.every[j]), batch.summaries[j], batch.pulses[j],
            batch.histories[j], record,
        )  # fmt: skip


def measure(runs, chunk, repeats):
    campaign = apply_overrides(load_campaign(CAMPAIGN), runs=runs)
    plan = RunPlan(campaign)
    rate = campaign["output"]["history_rate_hz"]
    simulate.load_kernels([plan.family])
    chunks = plan_chunks(runs, chunk)
    run_ids = list(range(runs))
    clock = time.perf_counter
    times = {name: [] for name in ("prepare", "stack", "rows", "tables", "encode")}
    for _ in range(repeats):
        t0 = clock()
        prepared = plan.prepare_runs(run_ids)
        t1 = clock()
        batch = Batch(plan, run_ids, prepared, rate)
        t2 = clock()
        times["prepare"].append(t1 - t0)
        times["stack"].append(t2 - t1)
    # the backend with -j > 1: a chunk per loky worker, the parent unpickles and stacks
    executor = pool.executor(os.cpu_count() or 1)
    cuda_backend._prepare(plan, campaign, chunks[:2], rate, executor)  # the workers start and warm up
    pooled, parent_cpu = [], []
    for _ in range(repeats):
        t0, c0 = clock(), time.process_time()
        cuda_backend._prepare(plan, campaign, chunks, rate, executor)
        pooled.append(clock() - t0)
        parent_cpu.append(time.process_time() - c0)
    pool.stop()
    times["pooled_prepare_and_stack_wall"] = pooled
    times["pooled_parent_cpu"] = parent_cpu
    t0 = clock()
    _fill_on_cpu(batch)
    cpu_flight_s = clock() - t0
    for _ in range(repeats):
        spent = dict.fromkeys(("rows", "tables", "encode"), 0.0)
        for _, ids in chunks:  # cuda_backend._chunk_part, stage by stage
            t0 = clock()
            pieces = batch.rows(plan, ids.start, ids.stop)
            t1 = clock()
            rows = [row for row, _ in pieces]
            flown = [(row["run_id"], result) for row, result in pieces if result is not None]
            runs_table = storage.runs_table(rows)
            history = storage.histories_table([r for r, _ in flown], [result for _, result in flown])
            t2 = clock()
            storage.encode_table(runs_table)
            storage.encode_table(history)
            t3 = clock()
            spent["rows"] += t1 - t0
            spent["tables"] += t2 - t1
            spent["encode"] += t3 - t2
        for name, value in spent.items():
            times[name].append(value)
    threads = {}
    for workers in sorted({1, os.cpu_count() or 1}):
        walls = []
        for _ in range(repeats):
            t0 = clock()
            with ThreadPoolExecutor(max_workers=workers) as encoders:
                list(encoders.map(lambda c: cuda_backend._chunk_part(plan, batch, c[0], c[1].start, c[1].stop), chunks))
            walls.append(clock() - t0)
        threads[workers] = statistics.median(walls) / runs * 1e3
    per_run_ms = {name: statistics.median(values) / runs * 1e3 for name, values in times.items()}
    sizes = {
        "history_raw_bytes_per_run": int(batch.histories.nbytes / max(len(batch.flown), 1)),
        "history_rows_written_per_run": float(
            np.mean([batch.summaries[j][L.S_HISTORY_ROWS] for j in range(len(batch.flown))])
        ),
        "launch_input_bytes_per_run": int(sum(a.nbytes for a in batch.inputs) / max(len(batch.flown), 1)),
    }
    return per_run_ms, threads, cpu_flight_s / runs * 1e3, sizes


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--runs", type=int, default=2000)
    parser.add_argument("--chunk", type=int, default=100, help="runs per chunk (a 10^6-run campaign's: 100)")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--json", type=Path)
    args = parser.parse_args()
    per_run_ms, threads, flight_ms, sizes = measure(args.runs, args.chunk, args.repeats)
    serial = per_run_ms["prepare"] + per_run_ms["stack"]
    total = serial + per_run_ms["rows"] + per_run_ms["tables"] + per_run_ms["encode"]
    cores = os.cpu_count() or 1
    result = {
        "machine": f"{platform.processor() or platform.machine()}, {cores} cores, load {os.getloadavg()[0]:.1f}",
        "campaign": CAMPAIGN.name,
        "runs": args.runs,
        "chunk": args.chunk,
        "per_run_ms": per_run_ms,
        "chunk_parts_ms_per_run_by_threads": threads,
        "cpu_flight_ms_per_run": flight_ms,
        "sizes": sizes,
        "host_ms_per_run": total,
        "at_1e6_runs_s": {
            "parent_serial_in_process": RUNS_AT_SCALE * serial / 1e3,
            "parent_cpu_with_pool": RUNS_AT_SCALE * per_run_ms["pooled_parent_cpu"] / 1e3,
            f"chunk_parts_on_{max(threads)}_threads": RUNS_AT_SCALE * threads[max(threads)] / 1e3,
            "floor_16_processes": RUNS_AT_SCALE * total / 16 / 1e3,
        },
    }
    print(json.dumps(result, indent=2))
    if args.json:
        args.json.write_text(json.dumps(result, indent=2) + "\n")


if __name__ == "__main__":
    main()
