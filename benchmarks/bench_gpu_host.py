"""The host's share of a GPU campaign (issue 37), measured without a GPU.

``refexmc run --backend cuda`` (refexmc.campaign.cuda_backend) does on the host, per run, what a
loky worker does besides flying: draw and pack the run into its launch's rows
(``cuda_backend.prepare_into``), then name its outputs as the CPU path does and build and encode
its chunk's runs and history parts (``cuda_backend.name_chunk``). The GPU's flight time can only
hide behind this work, so it bounds the throughput of a GPU campaign whatever the GPU. This
benchmark runs one launch of ``--runs`` runs of ``campaigns/refex-mc100.yaml`` (histories as the
campaign declares) through the backend's host phases (``cuda_backend.Launch``), its outputs those
the CPU kernel (the function each GPU thread runs) wrote once, in two ways: ``in_process``, a
chunk after the other in one thread of this process (what the host work costs in all), and
``pool``, a chunk per loky worker on every core with the launch's arrays in shared memory (the
backend with ``-j`` > 1), where ``parent_cpu`` is what the ``refexmc run`` process itself spends
(submitting, receiving the rows, putting the parts in place): the serial share.

The projection to 10^6 runs: the host work in one process; the ``refexmc run`` process's CPU with
the pool; and the host work spread over 16 workers without overhead (a 16-core machine).

Usage: .venv/bin/python benchmarks/bench_gpu_host.py [--runs 2000] [--chunk 1000] [--json PATH]
"""

import argparse
import json
import os
import platform
import statistics
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402

from refexmc import simulate, simulate_cuda  # noqa: E402
from refexmc.campaign import cuda_backend, pool, storage  # noqa: E402
from refexmc.campaign.chunk import plan_for  # noqa: E402
from refexmc.campaign.run import MAX_GPU_CHUNK_SIZE, plan_chunks  # noqa: E402
from refexmc.config.load import apply_overrides, load_campaign  # noqa: E402
from refexmc.core import flight, pointing  # noqa: E402
from refexmc.core import layout as L  # noqa: E402

CAMPAIGN = ROOT / "campaigns" / "refex-mc100.yaml"
RUNS_AT_SCALE = 1_000_000


def _fill_on_cpu(batch):
    """The batch's outputs as its launch would leave them: each run by the family's CPU kernel."""
    run_flight = flight.kernel(*batch.family)
    for j in range(len(batch)):
        record = pointing.Record(batch.p_table, batch.p_samples[j], batch.p_counts[j], batch.p_work[j])
        run_flight(
            batch.run_inputs(j), np.int64(batch.seeds[j]), np.int64(batch.every[j]), batch.summaries[j],
            batch.pulses[j], batch.histories[j], record,
        )  # fmt: skip


def _size(part):
    return part.stat().st_size if isinstance(part, Path) else len(part)


def _host_phases(plan, campaign, chunks, workers, shared, flown):
    """One launch of ``chunks`` through the backend's host phases (``cuda_backend.Launch``), its
    outputs copied from ``flown`` (a launch of the same runs filled by the CPU kernel once: a
    worker idle for 10 s, as during a CPU fill, would end): {phase: (wall s, this process's CPU s)},
    the launch and its parts."""
    clock, cpu = time.perf_counter, time.process_time
    t0, c0 = clock(), cpu()
    launch = cuda_backend.Launch.submit(plan, campaign, chunks, workers, shared)
    launch.allocate_outputs(plan)
    t1, c1 = clock(), cpu()
    if flown is None:
        _fill_on_cpu(launch.batch)
    else:
        for name in simulate_cuda.OUTPUTS:
            launch.outputs[name][...] = flown.outputs[name]
    t2, c2 = clock(), cpu()
    parts = []
    with tempfile.TemporaryDirectory() as out:  # the parts put in place as `refexmc run` does
        work_dir = Path(out) / "work" if shared else None
        if shared:
            work_dir.mkdir()
        for future in launch.submit_naming(campaign, workers, work_dir):
            chunk, rows, runs, history = future.result()
            parts.append((chunk, len(rows), _size(runs), _size(history)))
            storage.place_part(history, Path(out) / "histories" / storage.part_name(chunk))
            storage.place_part(runs, Path(out) / "runs" / storage.part_name(chunk))
        t3, c3 = clock(), cpu()
    return {"prepare": (t1 - t0, c1 - c0), "name_and_encode": (t3 - t2, c3 - c2)}, launch, parts


def measure(runs, chunk, repeats):
    campaign = apply_overrides(load_campaign(CAMPAIGN), runs=runs)
    plan = plan_for(campaign)
    simulate.load_kernels([plan.family])
    chunks = plan_chunks(runs, chunk)
    cores = os.cpu_count() or 1
    serial = ThreadPoolExecutor(max_workers=1)  # the host's work run by run: what it costs in all
    _, flown, parts = _host_phases(plan, campaign, chunks, serial, False, None)
    t0 = time.perf_counter()
    _fill_on_cpu(flown.batch)
    cpu_flight_ms = (time.perf_counter() - t0) / runs * 1e3
    pooled = pool.executor(cores)  # -j cores: a chunk per loky worker, the arrays in shared memory
    _host_phases(plan, campaign, chunks[: 2 * cores], pooled, True, None)[1].release()  # workers warm up
    times = {}
    for _ in range(repeats):
        for name, workers, shared in (("in_process", serial, False), ("pool", pooled, True)):
            phases, launch, parts = _host_phases(plan, campaign, chunks, workers, shared, flown)
            launch.release()
            for phase, (wall, cpu) in phases.items():
                times.setdefault(f"{name}_{phase}_wall", []).append(wall)
                times.setdefault(f"{name}_{phase}_parent_cpu", []).append(cpu)
    pool.stop()
    per_run_ms = {name: statistics.median(values) / runs * 1e3 for name, values in times.items()}
    batch = flown.batch
    sizes = {
        "history_raw_bytes_per_run": int(batch.histories.nbytes / max(len(batch), 1)),
        "history_rows_written_per_run": float(np.mean(batch.summaries[:, L.S_HISTORY_ROWS])),
        "launch_input_bytes_per_run": int(sum(a.nbytes for a in batch.inputs) / max(len(batch), 1)),
        "parquet_bytes_per_run": {
            "runs": sum(part[2] for part in parts) / runs,
            "histories": sum(part[3] for part in parts) / runs,
        },
    }
    return per_run_ms, sizes, cpu_flight_ms


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--runs", type=int, default=2000)
    parser.add_argument(
        "--chunk", type=int, default=MAX_GPU_CHUNK_SIZE, help="runs per chunk (a 10^6-run GPU campaign's: 1000)"
    )
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--json", type=Path)
    args = parser.parse_args()
    per_run_ms, sizes, cpu_flight_ms = measure(args.runs, args.chunk, args.repeats)
    cores = os.cpu_count() or 1
    host = per_run_ms["in_process_prepare_wall"] + per_run_ms["in_process_name_and_encode_wall"]
    parent = per_run_ms["pool_prepare_parent_cpu"] + per_run_ms["pool_name_and_encode_parent_cpu"]
    result = {
        "machine": f"{platform.processor() or platform.machine()}, {cores} cores, load {os.getloadavg()[0]:.1f}",
        "campaign": CAMPAIGN.name,
        "runs": args.runs,
        "chunk": args.chunk,
        "per_run_ms": per_run_ms,
        "sizes": sizes,
        "cpu_flight_ms_per_run": cpu_flight_ms,
        "host_ms_per_run_in_process": host,
        "parent_cpu_ms_per_run_with_pool": parent,
        "at_1e6_runs_s": {
            "host_work_in_one_process": RUNS_AT_SCALE * host / 1e3,
            "refexmc_run_process_cpu_with_pool": RUNS_AT_SCALE * parent / 1e3,
            "host_work_over_16_workers": RUNS_AT_SCALE * host / 16 / 1e3,
        },
    }
    print(json.dumps(result, indent=2))
    if args.json:
        args.json.write_text(json.dumps(result, indent=2) + "\n")


if __name__ == "__main__":
    main()
