"""GPU campaigns (issue 37 "Measure"): refex-mc100 on one GPU at 10^4, 10^5, 10^6 runs against -j 16 CPUs.

Made to fit one 10-minute call on a 16-core H100/H200 machine (``--budget-s``, default 560 s):

0. The machine: GPU (``nvidia-smi -L``), CPU model and cores, numpy / numba / numba-cuda versions.
1. Warm-up: the CPU kernel cache (a 64-run ``refexmc run``), then the GPU kernel in this process
   (compiled or loaded from the disk cache: ``gpu_compile_s``), then a whole ``refexmc run --backend
   cuda`` of 256 runs in a fresh process (``gpu_command_s``: interpreter, imports, the kernel from
   the disk cache: the fixed cost a command adds to the in-process flight times below).
2. GPU campaigns of 10^4, 10^5 and 10^6 runs (``run_campaign(..., backend="cuda")`` in this process:
   the ``refexmc run`` command without its interpreter start, kernel warm), histories as the
   campaign declares; wall time, runs/s, the largest ``memory.used`` nvidia-smi reports meanwhile.
   A size whose projected time (from the last size's rate) no longer fits the budget is skipped
   and said so.
3. The CPUs: ``refexmc run ... --runs 100000 -j 16`` as a subprocess (warm cache): wall, runs/s,
   and the GPU/CPU throughput ratio (target >= 20x).
4. Bits: the GPU's and the CPU's 10^5-run tables row by row (same campaign and seed, same run
   ids, same draws): runs whose status, success or failure reason differ (the first 20 listed),
   and per float column the largest absolute difference on the runs whose outcome agrees and
   how many values are bit-identical; then ``refexmc compare CPU_OUT GPU_OUT`` (exit 0: no
   significant difference). A second GPU run of the first 10^4 runs in other chunks must be
   bit-identical to the first (GPU against itself).
5. ``refexmc report OUT --no-html`` of the largest GPU campaign: wall and peak RSS (target: 10^6
   runs in <= 60 s and <= 4 GB).

Results: a JSON file (``--json``, default ``$OUT/bench_gpu.json`` or ``bench_gpu.json`` here)
and a summary on stdout, for benchmarks/RESULTS.md.

Usage (numba-cuda 0.30.4 needs numpy < 2.5):
    pip install -e '.[cuda]'
    python benchmarks/bench_gpu.py [--budget-s 560] [--work DIR] [--json PATH]
"""

import argparse
import json
import os
import platform
import resource
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
CAMPAIGN = ROOT / "campaigns" / "refex-mc100.yaml"
REFEXMC = [sys.executable, "-m", "refexmc.cli"]


def sh(command, **kwargs):
    return subprocess.run(command, capture_output=True, text=True, **kwargs)


def machine():
    info = {"python": platform.python_version(), "cores": os.cpu_count()}
    gpu = sh(["nvidia-smi", "-L"]) if _which("nvidia-smi") else None
    info["gpu"] = gpu.stdout.strip() if gpu and gpu.returncode == 0 else "nvidia-smi not found"
    for line in Path("/proc/cpuinfo").read_text().splitlines() if Path("/proc/cpuinfo").exists() else []:
        if line.startswith("model name"):
            info["cpu"] = line.split(":", 1)[1].strip()
            break
    import numba

    info["numpy"], info["numba"] = np.__version__, numba.__version__
    try:
        import numba_cuda

        info["numba_cuda"] = getattr(numba_cuda, "__version__", "?")
    except ImportError:
        info["numba_cuda"] = None
    info["uptime"] = sh(["uptime"]).stdout.strip()
    return info


def _which(name):
    return any((Path(p) / name).exists() for p in os.environ.get("PATH", "").split(os.pathsep))


class GpuMemory:
    """The largest ``memory.used`` (MiB) nvidia-smi reports while it runs (polled every 0.5 s)."""

    def __init__(self):
        self.peak_mib = None
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._poll, daemon=True)

    def _poll(self):
        while not self._stop.is_set():
            done = sh(["nvidia-smi", "--query-gpu=memory.used,memory.total", "--format=csv,noheader,nounits"])
            if done.returncode == 0 and done.stdout.strip():
                used = float(done.stdout.strip().splitlines()[0].split(",")[0])
                self.peak_mib = used if self.peak_mib is None else max(self.peak_mib, used)
            self._stop.wait(0.5)

    def __enter__(self):
        if _which("nvidia-smi"):
            self._thread.start()
        return self

    def __exit__(self, *exc):
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join()


def fly_gpu(runs, out, chunk_size=None):
    """A GPU campaign in this process: (wall s, counts, peak GPU memory MiB)."""
    from refexmc.campaign.run import run_campaign

    with GpuMemory() as memory:
        start = time.perf_counter()
        result = run_campaign(
            CAMPAIGN, out=out, runs=runs, backend="cuda", overwrite=True, chunk_size=chunk_size, notify=lambda m: None
        )
        wall = time.perf_counter() - start
    return wall, result["counts"], memory.peak_mib


def compare_tables(cpu_out, gpu_out):
    """Row-by-row bits of two runs tables of the same campaign and runs."""
    import pandas as pd

    cpu = pd.read_parquet(Path(cpu_out) / "runs").sort_values("run_id", ignore_index=True)
    gpu = pd.read_parquet(Path(gpu_out) / "runs").sort_values("run_id", ignore_index=True)
    common = np.intersect1d(cpu["run_id"], gpu["run_id"])
    cpu = cpu[cpu["run_id"].isin(common)].reset_index(drop=True)
    gpu = gpu[gpu["run_id"].isin(common)].reset_index(drop=True)
    outcome = ["status", "success", "failure_reason"]
    same = np.ones(len(cpu), dtype=bool)

    def text(column):  # a missing value (NaN in pandas' str columns) as ""
        return np.array(["" if pd.isna(v) else str(v) for v in column])

    for name in outcome:
        same &= text(cpu[name]) == text(gpu[name])
    differing = [
        {
            "run_id": int(cpu["run_id"][k]),
            "cpu": [str(cpu[n][k]) for n in outcome],
            "gpu": [str(gpu[n][k]) for n in outcome],
        }
        for k in np.flatnonzero(~same)[:20]
    ]
    columns = {}
    for name in cpu.columns:
        if cpu[name].dtype.kind != "f" or name.startswith("p."):
            continue
        a, b = cpu[name].to_numpy()[same], gpu[name].to_numpy()[same]
        identical = int(np.sum(a.view(np.uint64) == b.view(np.uint64)))
        finite = np.isfinite(a) & np.isfinite(b)
        largest = float(np.max(np.abs(a[finite] - b[finite]))) if finite.any() else 0.0
        columns[name] = {"max_abs_difference": largest, "bit_identical": identical, "of": int(same.sum())}
    parameters_equal = all(
        np.array_equal(cpu[c].to_numpy().view(np.uint64), gpu[c].to_numpy().view(np.uint64))
        for c in cpu.columns
        if c.startswith("p.") and cpu[c].dtype.kind == "f"
    )
    columns_identical = all(c["bit_identical"] == c["of"] for c in columns.values())
    every_value = (~same).sum() == 0 and parameters_equal and columns_identical
    return {
        "runs": len(common),
        "every_value_bit_identical": bool(every_value),
        "outcome_differs": int((~same).sum()),
        "differing_runs": differing,
        "parameters_bit_identical": bool(parameters_equal),
        "columns": columns,
    }


def compare_histories(cpu_out, gpu_out, runs=2000):
    """The histories of the first ``runs`` runs of two OUTs, every column by its bits: the names of
    the columns that differ (none where the GPU flies the CPU's bits)."""
    import pyarrow.dataset as ds

    def table(out):
        data = ds.dataset(Path(out) / "histories", format="parquet")
        frame = data.to_table(filter=ds.field("run_id") < runs).to_pandas()
        return frame.sort_values(["run_id", "t_s"], ignore_index=True)

    cpu, gpu = table(cpu_out), table(gpu_out)
    if cpu.shape != gpu.shape or list(cpu.columns) != list(gpu.columns):
        return {"runs": runs, "same_shape": False, "cpu": list(cpu.shape), "gpu": list(gpu.shape)}
    differ = []
    for name in cpu.columns:
        a, b = cpu[name].to_numpy(), gpu[name].to_numpy()
        if a.dtype.kind == "f":
            a, b = a.view(f"u{a.itemsize}"), b.view(f"u{b.itemsize}")
        if not np.array_equal(a, b):
            differ.append(name)
    return {"runs": runs, "same_shape": True, "samples": len(cpu), "columns_differing": differ}


def report_time(out):
    """``refexmc report OUT --no-html``: (wall s, peak RSS MB of the report process, exit code)."""
    start = time.perf_counter()
    done = sh([*REFEXMC, "report", str(out), "--no-html"], cwd=ROOT)
    wall = time.perf_counter() - start
    rss_mb = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024  # the largest child so far
    return wall, rss_mb, done.returncode


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--budget-s", type=float, default=560.0, help="stop starting new work after this")
    parser.add_argument("--work", default=os.environ.get("OUT", "/tmp/bench_gpu"), help="campaign outputs")
    parser.add_argument("--json", help="results file (default WORK/bench_gpu.json)")
    parser.add_argument("--sizes", type=int, nargs="*", default=[10_000, 100_000, 1_000_000])
    parser.add_argument("--cpu-runs", type=int, default=100_000)
    parser.add_argument("--jobs", type=int, default=16)
    parser.add_argument("--warm-runs", type=int, default=64, help="runs of the CPU warm-up (the GPU's: 4x)")
    args = parser.parse_args()
    began = time.perf_counter()
    work = Path(args.work)
    work.mkdir(parents=True, exist_ok=True)
    results = {"machine": machine(), "campaign": str(CAMPAIGN.relative_to(ROOT)), "gpu": {}, "skipped": []}
    print(json.dumps(results["machine"], indent=1), flush=True)

    def left():
        return args.budget_s - (time.perf_counter() - began)

    # 1. warm-up: the CPU kernel (disk cache), then the GPU kernel in this process
    start = time.perf_counter()
    done = sh([*REFEXMC, "run", str(CAMPAIGN), "--runs", str(args.warm_runs), "-j", "2", "-o", str(work / "warm-cpu"),
               "--overwrite", "--no-progress"], cwd=ROOT)  # fmt: skip
    results["cpu_warm_s"] = time.perf_counter() - start
    if done.returncode not in (0, 1):
        print(done.stderr[-2000:], flush=True)
    start = time.perf_counter()
    fly_gpu(4 * args.warm_runs, work / "warm-gpu")
    results["gpu_compile_s"] = time.perf_counter() - start
    gpu_warm = f"gpu compile + {4 * args.warm_runs} runs {results['gpu_compile_s']:.1f} s"
    print(f"warm: cpu {results['cpu_warm_s']:.1f} s, {gpu_warm}", flush=True)
    # the whole command in a fresh process: the GPU kernel from the disk cache (compiled above), if
    # numba-cuda's cache works here; else this includes the compile again
    start = time.perf_counter()
    done = sh([*REFEXMC, "run", str(CAMPAIGN), "--runs", str(4 * args.warm_runs), "--backend", "cuda", "-o",
               str(work / "warm-gpu-command"), "--overwrite", "--no-progress"], cwd=ROOT)  # fmt: skip
    results["gpu_command_s"] = {"runs": 4 * args.warm_runs, "wall_s": time.perf_counter() - start,
                                "exit": done.returncode, "stderr": done.stderr[-1500:]}  # fmt: skip
    print(f"a fresh `refexmc run --backend cuda` of {4 * args.warm_runs} runs: {results['gpu_command_s']}", flush=True)

    # 2. GPU campaigns
    rate = None
    for runs in args.sizes:
        projected = runs / rate if rate else 0.0
        if projected > left() - 120:  # keep ~2 min for the CPU campaign and the comparison
            results["skipped"].append(f"gpu {runs} runs: projected {projected:.0f} s, {left():.0f} s left")
            continue
        wall, counts, memory = fly_gpu(runs, work / f"gpu-{runs}")
        rate = runs / wall
        results["gpu"][runs] = {"wall_s": wall, "runs_per_s": rate, "counts": counts, "gpu_memory_peak_mib": memory}
        print(f"gpu {runs}: {wall:.1f} s, {rate:.0f} runs/s, peak {memory} MiB, {counts}", flush=True)

    # 3. the CPUs on the same campaign
    cpu_out = work / f"cpu-{args.cpu_runs}"
    cpu_projected = args.cpu_runs / 1900.0  # issue 37: ~1,900 runs/s at -j 16
    if cpu_projected < left():
        start = time.perf_counter()
        done = sh([*REFEXMC, "run", str(CAMPAIGN), "--runs", str(args.cpu_runs), "-j", str(args.jobs), "-o",
                   str(cpu_out), "--overwrite", "--no-progress"], cwd=ROOT)  # fmt: skip
        wall = time.perf_counter() - start
        results["cpu"] = {"runs": args.cpu_runs, "jobs": args.jobs, "wall_s": wall, "runs_per_s": args.cpu_runs / wall,
                          "exit": done.returncode}  # fmt: skip
        print(f"cpu {args.cpu_runs} -j {args.jobs}: {wall:.1f} s", flush=True)
        if args.cpu_runs in results["gpu"]:
            ratio = results["gpu"][args.cpu_runs]["runs_per_s"] / results["cpu"]["runs_per_s"]
            results["gpu_over_cpu_throughput"] = ratio
            print(f"GPU / {args.jobs} cores: {ratio:.1f}x", flush=True)
    else:
        results["skipped"].append(f"cpu {args.cpu_runs} runs: projected {cpu_projected:.0f} s, {left():.0f} s left")

    # 4. bits: GPU against CPU, GPU against itself in other chunks
    gpu_out = work / f"gpu-{args.cpu_runs}"
    if cpu_out.exists() and gpu_out.exists():
        results["bits"] = compare_tables(cpu_out, gpu_out)
        results["history_bits"] = compare_histories(cpu_out, gpu_out)
        done = sh([*REFEXMC, "compare", str(cpu_out), str(gpu_out)], cwd=ROOT)
        results["compare"] = {"exit": done.returncode, "output": done.stdout[-4000:]}
        print(json.dumps({k: v for k, v in results["bits"].items() if k != "columns"}, indent=1), flush=True)
        print(json.dumps(results["history_bits"]), flush=True)
    if left() > 60 and args.sizes:
        first = args.sizes[0]
        _, _, _ = fly_gpu(first, work / f"gpu-{first}-rechunked", chunk_size=37)
        again = compare_tables(work / f"gpu-{first}", work / f"gpu-{first}-rechunked")
        results["gpu_rechunked_identical"] = again["outcome_differs"] == 0 and all(
            c["bit_identical"] == c["of"] for c in again["columns"].values()
        )

    # 5. the report of the largest GPU campaign
    if results["gpu"] and left() > 30:
        largest = max(results["gpu"])
        wall, rss, code = report_time(work / f"gpu-{largest}")
        results["report"] = {"runs": largest, "wall_s": wall, "peak_rss_mb": rss, "exit": code}
        print(f"report {largest}: {wall:.1f} s, {rss:.0f} MB", flush=True)

    results["total_s"] = time.perf_counter() - began
    path = Path(args.json) if args.json else work / "bench_gpu.json"
    path.write_text(json.dumps(results, indent=1, default=str))
    print(f"results: {path}", flush=True)


if __name__ == "__main__":
    main()
