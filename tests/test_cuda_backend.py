"""The GPU backend (refexmc run --backend cuda, docs/gpu.md), tested without a GPU.

CI has none: the refusal without a GPU (exit 2, one line, nothing written) is tested as it is;
the backend itself under numba-cuda's simulator (a kernel runs as Python, one thread per run,
calling the CPU kernel on the thread's rows), whose runs table must be the CPU's bit for bit;
and every family's kernel is compiled to PTX for an H100 (sm_90) the way the backend compiles
it, so that a kernel numba-cuda cannot compile fails here. Tests that need numba-cuda skip
without it (``pip install 'refexmc[cuda]'``; ``make test`` installs it).
"""

import importlib.util
import json
import os
import re
import subprocess
import sys
import types
from pathlib import Path

import numba
import numpy as np
import pytest
from click.testing import CliRunner

from refexmc import _jit
from refexmc.cli import main
from refexmc.config.errors import ConfigError

ROOT = Path(__file__).resolve().parents[1]
HAS_NUMBA_CUDA = importlib.util.find_spec("numba_cuda") is not None
needs_numba_cuda = pytest.mark.skipif(not HAS_NUMBA_CUDA, reason="numba-cuda not installed (the cuda extra)")
needs_jit = pytest.mark.skipif(_jit.DISABLED, reason="REFEXMC_DISABLE_JIT=1: no kernels to compile")

# one campaign per family the GPU flies: ReFEx (table thrusters), SPORE (LP thrusters, orbit),
# IRASSI (reaction wheels), the surveyor hop (local trajectory, cold-gas tank, time-optimal law)
FAMILY_CAMPAIGNS = ["smoke", "spore-deorbit-iss", "irassi-fine-pointing", "surveyor-hop"]
# compiled to PTX: one campaign of every vehicle family the shipped campaigns fly, the entry's aside
PTX_CAMPAIGNS = [*FAMILY_CAMPAIGNS, "generic-slew", "refex-blow-down-mc100"]


def _refused(monkeypatch, tmp_path, unavailable):
    monkeypatch.setattr(_jit, "cuda_unavailable", lambda: unavailable)
    out = tmp_path / "out"
    result = CliRunner().invoke(main, ["run", str(ROOT / "campaigns/smoke.yaml"), "-o", str(out), "--backend", "cuda"])
    return result, out


def test_without_numba_cuda_the_cuda_backend_exits_2_with_one_line_and_writes_nothing(monkeypatch, tmp_path):
    result, out = _refused(monkeypatch, tmp_path, "numba-cuda is not installed (pip install 'refexmc[cuda]')")
    assert result.exit_code == 2
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and "numba-cuda is not installed" in lines[0] and "--backend" in lines[0]
    assert not out.exists()


class _NeedsItsKeyword(Exception):
    """An exception whose plain pickle cannot be loaded: ``__init__`` takes what ``args`` does not
    hold (where tblib's pickling is installed, as dask's distributed does, it can)."""

    def __init__(self, message, *, where):
        super().__init__(f"{message} at {where}")


def test_the_gpu_backends_host_workers_start_ahead_of_the_flight_only_above_j_1(monkeypatch):
    """With -j > 1 the GPU backend's host workers start as loky's do, before the campaign flies
    (they warm up meanwhile); with -j 1 its host work stays in this process: none start."""
    from refexmc.campaign import backends, pool

    started = []
    monkeypatch.setattr(pool, "start", started.append)
    monkeypatch.setattr(pool, "started_early", lambda: 0)
    assert backends.start_workers("cuda", 1) == {} and started == []
    assert backends.start_workers("cuda", 4) == {"workers": 4} and started == [4]


def _prepared_into_shared_memory(campaign, run_ids):
    """``cuda_backend.prepare_into`` of ``run_ids`` into a shared block, as a host worker does it:
    (the PreparedChunk back through a pickle, a copy of the block's arrays)."""
    import pickle

    from refexmc.campaign import cuda_backend, shared_arrays
    from refexmc.campaign.chunk import plan_for
    from refexmc.simulate_cuda import input_shapes

    block = shared_arrays.Arrays(input_shapes(plan_for(campaign).nominal_inputs, len(run_ids) + 1), shared=True)
    try:
        back = pickle.loads(pickle.dumps(cuda_backend.prepare_into(campaign, run_ids, block.handle(), 1)))
        return back, {name: array.copy() for name, array in block.arrays.items()}
    finally:
        block.release()


def test_a_host_worker_packs_each_run_into_its_rows_and_keeps_a_failed_runs_reason(monkeypatch):
    """The GPU backend's host workers draw and pack a chunk each into the launch's rows in shared
    memory (``cuda_backend.prepare_into``): each run's tables, seed and ``p.`` values are those of
    ``RunPlan.prepare_runs``; a run whose preparation raised keeps the reason the CPU's error row
    gives it (``Type: message``, also for an exception that does not pickle) and flies the nominal
    inputs, unread."""
    pytest.importorskip("numba_cuda")
    from refexmc.campaign import chunk
    from refexmc.campaign.run import resolve_campaign
    from refexmc.simulate_cuda import INPUT_TABLES

    _, campaign = resolve_campaign(ROOT / "campaigns/smoke.yaml", runs=3)
    plan = chunk.plan_for(campaign)
    drawn = plan.prepare_runs([0, 1, 2])
    prepare_runs = chunk.RunPlan.prepare_runs
    monkeypatch.setattr(
        chunk.RunPlan,
        "prepare_runs",
        lambda self, ids: [_NeedsItsKeyword("no draw", where="run 1") if k == 1 else p
                           for k, p in zip(ids, prepare_runs(self, ids), strict=True)],
    )  # fmt: skip
    back, arrays = _prepared_into_shared_memory(campaign, [0, 1, 2])
    assert back.reasons == [None, "_NeedsItsKeyword: no draw at run 1", None]
    assert plan.error_row(1, back.reasons[1])["failure_reason"] == "_NeedsItsKeyword: no draw at run 1"
    columns = plan.param_columns()
    for k in (0, 2):
        seed, failed, params, inputs = drawn[k]
        assert back.seeds[k] == seed == arrays["seeds"][1 + k] and back.failures[k] == failed
        assert dict(zip(columns, back.params[k].tolist(), strict=True)) == params
        assert all(np.array_equal(arrays[name][1 + k], getattr(inputs, name)) for name in INPUT_TABLES)
    assert all(np.array_equal(arrays[name][2], getattr(plan.nominal_inputs, name)) for name in INPUT_TABLES)
    assert not arrays["mission"][0].any()  # row 0 is not the chunk's: untouched


_USER_WITHOUT_GPU = """
import sys
from refexmc import _jit
if _jit.cuda_unavailable() is None:
    print("a GPU is there")
    sys.exit(0)
from refexmc.cli import console
sys.argv = ["refexmc", "run", "campaigns/smoke.yaml", "-o", sys.argv[1], "--backend", "cuda"]
console()
"""


@needs_numba_cuda
def test_without_a_gpu_and_without_the_simulator_the_cuda_backend_exits_2(tmp_path):
    """As a user meets it: no simulator, no GPU on this machine (skipped where there is one)."""
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_ENABLE_CUDASIM"}
    out = tmp_path / "out"
    done = subprocess.run(
        [sys.executable, "-c", _USER_WITHOUT_GPU, str(out)], cwd=ROOT, env=env, capture_output=True, text=True
    )
    if done.stdout.strip() == "a GPU is there":
        pytest.skip("a GPU is there")
    assert done.returncode == 2
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "no CUDA GPU" in lines[0], done.stderr
    assert done.stdout == "" and not out.exists()


@pytest.mark.parametrize("campaign", ["refex-propellant-sweep", "refex-rare-exhaustion", "x38-blocked-flap-sweep"])
@pytest.mark.parametrize("gpu", ["none", "simulated"])
def test_a_study_on_the_gpu_backend_exits_2_before_anything_is_written(monkeypatch, tmp_path, campaign, gpu):
    """A sweep or a rare-event study is refused as a whole (without a GPU: for that; with one: by
    name), before its OUT is created: before, a sweep flew every point on the GPU (its points are
    campaigns of their own), a refused sweep left a manifest "running" behind that blocked the next
    run, and a rare-event study flew its level 0 and then failed with a traceback."""
    if gpu == "simulated" and not HAS_NUMBA_CUDA:
        pytest.skip("numba-cuda not installed (the cuda extra)")
    monkeypatch.setattr(_jit, "cuda_unavailable", lambda: None if gpu == "simulated" else "no CUDA GPU here")
    out = tmp_path / "out"
    args = ["run", str(ROOT / f"campaigns/{campaign}.yaml"), "-o", str(out), "--backend", "cuda", "--no-progress"]
    result = CliRunner().invoke(main, args)
    assert result.exit_code == 2, result.output
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and "cannot fly on a GPU" in lines[0], result.output
    if gpu == "simulated":  # the reason by name: the entry's family first, else the study
        why = "entry flight" if campaign.startswith("x38") else "sweep" if "sweep" in campaign else "rare-event"
        assert why in lines[0], lines[0]
    assert not out.exists()


def test_the_entry_flight_and_studies_are_refused_on_the_gpu_by_name(monkeypatch):
    monkeypatch.setattr(_jit, "cuda_unavailable", lambda: None)
    if not HAS_NUMBA_CUDA:
        pytest.skip("numba-cuda not installed (the cuda extra)")
    from refexmc.campaign import cuda_backend
    from refexmc.campaign.run import resolve_campaign

    _, entry = resolve_campaign(ROOT / "campaigns/x38-nominal.yaml")
    with pytest.raises(ConfigError, match="entry flight"):
        cuda_backend.check(entry)
    _, smoke = resolve_campaign(ROOT / "campaigns/smoke.yaml")
    cuda_backend.check(smoke)  # the ReFEx family flies
    assert cuda_backend.refusal({**smoke, "sweep": {}}) is not None


def test_launches_group_whole_chunks_in_order():
    pytest.importorskip("numba_cuda")
    from refexmc.campaign.cuda_backend import _batches

    chunks = [(0, [0, 1, 2]), (1, [3, 4, 5]), (2, [6, 7]), (3, [8])]
    batches = _batches(chunks, 6)
    assert batches == [[(0, [0, 1, 2]), (1, [3, 4, 5])], [(2, [6, 7]), (3, [8])]]
    assert _batches(chunks, 2) == [[c] for c in chunks]  # a chunk larger than a launch is never split


_SIMULATED = r"""
import json, sys
import numpy as np
from refexmc.campaign import storage
from refexmc.campaign.chunk import fly_chunk
from refexmc.campaign.run import resolve_campaign, run_campaign

def bits(table):
    out = {}
    for name in table.columns:
        column = table[name]
        if column.dtype.kind == "f":
            out[name] = column.to_numpy(dtype=np.float64).view(np.uint64).tolist()
        else:
            out[name] = [repr(v) for v in column.tolist()]
    return out

report = {}
for name in sys.argv[2:]:
    path = f"campaigns/{name}.yaml"
    gpu = {}
    for chunk_size in (2, 3):
        # chunks of 2: drawn and packed by two loky workers; of 3: in this process (one chunk)
        result = run_campaign(path, out=f"{sys.argv[1]}/{name}-{chunk_size}", runs=3, backend="cuda",
                              chunk_size=chunk_size, jobs=2, notify=lambda message: None)
        gpu[chunk_size] = bits(result["runs"])
    _, campaign = resolve_campaign(path, runs=3)
    rows, _ = fly_chunk(campaign, [0, 1, 2])
    cpu = bits(storage.runs_table(rows).to_pandas())
    report[name] = {
        "chunkings_equal": gpu[2] == gpu[3],
        "columns_equal": list(gpu[2]) == list(cpu),
        "different": sorted(c for c in cpu if gpu[2].get(c) != cpu[c]),
        "statuses": gpu[2]["status"],
    }
print(json.dumps(report))
"""


@needs_numba_cuda
@needs_jit
@pytest.mark.slow
@pytest.mark.cuda
def test_under_the_simulator_every_family_flies_the_cpu_runs_table_bit_for_bit(tmp_path):
    """A GPU campaign under the simulator: the same rows as the CPU's ``fly_chunk`` (draws, p.
    columns, every flown value: the simulator's threads call the CPU kernel), whatever the chunking."""
    env = {**os.environ, "NUMBA_ENABLE_CUDASIM": "1"}
    done = subprocess.run(
        [sys.executable, "-c", _SIMULATED, str(tmp_path), *FAMILY_CAMPAIGNS],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    report = json.loads(done.stdout.strip().splitlines()[-1])
    for name in FAMILY_CAMPAIGNS:
        assert report[name]["statuses"] == ["'ok'"] * 3, (name, report[name])
        assert report[name]["chunkings_equal"], name
        assert report[name]["columns_equal"], name
        assert report[name]["different"] == [], (name, report[name]["different"])


def _compile_ptx(campaign_name):
    """The PTX (sm_90) of a campaign's GPU kernel, compiled as the backend compiles it.

    numba-cuda compiles a @jit function that a kernel calls with ``compile_device``, which asks the
    current device for its compute capability even when ``compile_ptx`` is given one (numba-cuda
    0.30.4): without a driver it fails. The only thing asked of the driver is that number, so the
    device is stood in for by one of compute capability 9.0 while compiling.
    """
    import numba.cuda.dispatcher as cuda_dispatcher
    from numba import cuda
    from numba.cuda import types as types_
    from numba.cuda.compiler import compile_cuda

    from refexmc import simulate_cuda
    from refexmc.campaign.chunk import RunPlan
    from refexmc.campaign.run import resolve_campaign
    from refexmc.core import flight

    _, campaign = resolve_campaign(ROOT / f"campaigns/{campaign_name}.yaml", runs=2)
    plan = RunPlan(campaign)
    inputs = [prepared[3] for prepared in plan.prepare_runs([0, 1])]
    batch = simulate_cuda.batch_of_runs(plan, inputs, [0, 1], campaign["output"]["history_rate_hz"])
    signature = tuple(numba.typeof(argument) for argument in batch.typing_arguments())
    kernel = simulate_cuda._fly_runs(flight.kernel_parts(*plan.family).fly_run)
    stand_in = types.SimpleNamespace(compute_capability=(9, 0))
    real = cuda_dispatcher.get_current_device
    cuda_dispatcher.get_current_device = lambda: stand_in
    try:
        with _jit.cuda_without_contraction():
            ptx, _ = cuda.compile_ptx(kernel, signature, cc=(9, 0))
            # the NVVM IR numba-cuda hands to NVVM before libdevice is linked in: what it calls
            ir = compile_cuda(kernel, types_.void, signature, cc=(9, 0)).library.get_llvm_str()
    finally:
        cuda_dispatcher.get_current_device = real
    return ptx, ir


# libdevice functions whose result has one right answer (exact, or correctly rounded: sqrt is
# sqrt.rn.f64), which the CPU computes too, and LLVM intrinsics of the same kind. Not fmin/fmax:
# they answer otherwise than the CPU's min/max for a NaN first argument and for -0 against +0
# (the core's float min/max are core.elementary.smaller/larger)
EXACT_DEVICE_FUNCTIONS = {
    "__nv_sqrt", "__nv_frexp", "__nv_ldexp", "__nv_fabs", "__nv_floor", "__nv_ceil", "__nv_trunc",
    "__nv_copysign", "__nv_isnand", "__nv_isinfd", "__nv_isfinited",
    "llvm.sqrt.f64", "llvm.fabs.f64", "llvm.floor.f64", "llvm.ceil.f64", "llvm.trunc.f64", "llvm.copysign.f64",
}  # fmt: skip


def _math_called(ir):
    """The libdevice functions and floating-point LLVM intrinsics the NVVM IR ``ir`` calls."""
    return set(re.findall(r'@"?(__nv_\w+|llvm\.[a-z0-9_.]+\.f64)\b', ir))


@needs_numba_cuda
@needs_jit
@pytest.mark.slow
@pytest.mark.cuda
@pytest.mark.parametrize("campaign_name", PTX_CAMPAIGNS)
def test_every_gpu_familys_kernel_compiles_to_ptx_without_a_device(campaign_name):
    ptx, ir = _compile_ptx(campaign_name)
    assert ".entry" in ptx and ".target sm_90" in ptx
    # the CPU's operations, each rounded as the CPU rounds it (docs/gpu.md): no contraction into
    # fused multiply-adds (NVVM -fma=0) and no transcendental function of CUDA's libdevice (the
    # core's own, refexmc/core/elementary.py, on both targets)
    assert "fma.rn" not in ptx
    assert _math_called(ir) <= EXACT_DEVICE_FUNCTIONS, _math_called(ir) - EXACT_DEVICE_FUNCTIONS
    assert np.char.count(ptx, "NRT_").sum() == 0  # no allocation, no reference counting on the device


@needs_numba_cuda
@needs_jit
def test_without_contraction_nvvm_rounds_a_product_and_a_sum_separately():
    """What :func:`refexmc._jit.cuda_without_contraction` is for, on a kernel with no device
    function (compiles without a driver, in a second): numba-cuda's default NVVM options fuse
    ``a * b + c`` into one ``fma.rn.f64``; under the context it stays ``mul.rn`` then ``add.rn``,
    the CPU's two roundings. If numba-cuda ever stops contracting by default, the first half
    fails: the context is then no longer needed (docs/gpu.md)."""
    from numba import cuda

    def axpy(out, a, b, c):
        i = cuda.grid(1)
        if i < out.shape[0]:
            out[i] = a[i] * b[i] + c[i]

    signature = (numba.float64[::1],) * 4
    contracted, _ = cuda.compile_ptx(axpy, signature, cc=(9, 0))
    with _jit.cuda_without_contraction():
        separate, _ = cuda.compile_ptx(axpy, signature, cc=(9, 0))
    assert "fma.rn.f64" in contracted
    assert "fma.rn" not in separate and "mul.rn.f64" in separate and "add.rn.f64" in separate
    from numba.cuda.cudadrv import nvvm

    assert nvvm.compile_ir.__name__ == "compile_ir"  # the context put numba-cuda's function back


def test_the_ptx_test_covers_every_family_of_the_shipped_campaigns():
    from refexmc.campaign.run import resolve_campaign
    from refexmc.config.pack import pack
    from refexmc.core import flight

    def family(name):
        _, campaign = resolve_campaign(ROOT / "campaigns" / f"{name}.yaml")
        if "entry_flight" in campaign["mission"]:
            return "entry"
        return flight.family(pack(campaign["vehicle"], campaign["mission"]))

    shipped = {family(path.stem) for path in (ROOT / "campaigns").glob("*.yaml")} - {"entry"}
    compiled = [family(name) for name in PTX_CAMPAIGNS]
    assert set(compiled) == shipped and len(compiled) == len(shipped)  # each family once


def test_a_run_whose_tables_have_other_shapes_becomes_an_error_not_a_failed_launch(monkeypatch):
    """A launch stacks its runs' tables: a run whose tables have other shapes than its campaign's
    (none does today: dispersions keep them) is an error row, the others fly."""
    pytest.importorskip("numba_cuda")
    from refexmc.campaign import chunk
    from refexmc.campaign.run import resolve_campaign

    _, campaign = resolve_campaign(ROOT / "campaigns/smoke.yaml", runs=2)
    prepare_runs = chunk.RunPlan.prepare_runs

    def one_thruster_less(self, ids):
        runs = prepare_runs(self, ids)
        seed, failed, params, inputs = runs[1]
        runs[1] = (seed, failed, params, inputs._replace(thrusters=inputs.thrusters[:-1]))
        return runs

    monkeypatch.setattr(chunk.RunPlan, "prepare_runs", one_thruster_less)
    back, _ = _prepared_into_shared_memory(campaign, [0, 1])
    assert back.reasons[0] is None
    assert back.reasons[1].startswith("ValueError: input tables of other shapes")


def test_importing_refexmc_does_not_import_numba_cuda():
    code = (
        "import sys, refexmc.cli, refexmc.campaign.run, refexmc.campaign.backends, refexmc.simulate; "
        "print(sorted(m for m in sys.modules if m.split('.')[0] == 'numba_cuda' or m.startswith('numba.cuda')))"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=ROOT)
    assert result.stdout.strip() == "[]"


CACHE_KEYS = """
import json
from pathlib import Path

from numba.cuda.dispatcher import CUDACache

from refexmc import _jit, simulate_cuda
from refexmc.campaign.chunk import RunPlan
from refexmc.campaign.run import resolve_campaign
from refexmc.core import flight


class Codegen:  # what numba-cuda's codegen tells its cache: the CUDA runtime's version, the device's cc
    def magic_tuple(self):
        return ((12, 9), (9, 0))


out = {}
for name in ["smoke", "irassi-fine-pointing"]:
    family = RunPlan(resolve_campaign(Path("campaigns") / f"{name}.yaml", runs=2)[1]).family
    kernel = simulate_cuda._fly_runs(flight.kernel_parts(*family).fly_run)
    keyed = _jit._keyed_cuda_cache(kernel, ("fly_runs", tuple(int(v) for v in family)))
    out[name] = {
        "keyed": repr(keyed._index_key(("signature",), Codegen())),
        "numba_cuda": repr(CUDACache(kernel)._index_key(("signature",), Codegen())),
        "in_cache_dir": str(keyed._cache_path).startswith(str(_jit.cache_dir())),
    }
print(json.dumps(out))
"""


@needs_numba_cuda
@needs_jit
def test_a_gpu_kernel_is_cached_under_its_family_the_same_in_every_process():
    """numba-cuda keys a kernel closure by its pickled cells; the grid kernel's cell is the family's
    jitted ``fly_run``, which pickles with a per-process uuid, so numba-cuda's key differs in every
    process (the kernel would never be found again). refexmc's key is the family's: the same in
    two processes, different for two families, and the entries live in refexmc's cache directory
    (whose name hashes the core's source)."""
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_ENABLE_CUDASIM"}

    def keys():
        done = subprocess.run([sys.executable, "-c", CACHE_KEYS], cwd=ROOT, env=env, capture_output=True, text=True)
        assert done.returncode == 0, done.stderr[-3000:]
        return json.loads(done.stdout.strip().splitlines()[-1])

    first, second = keys(), keys()
    assert first["smoke"]["keyed"] == second["smoke"]["keyed"]
    assert first["irassi-fine-pointing"]["keyed"] == second["irassi-fine-pointing"]["keyed"]
    assert first["smoke"]["keyed"] != first["irassi-fine-pointing"]["keyed"]
    assert first["smoke"]["numba_cuda"] != second["smoke"]["numba_cuda"]  # why refexmc keys it itself
    assert all(first[name]["in_cache_dir"] for name in first)


def _cli(campaign, out, *args, env):
    command = [sys.executable, "-m", "refexmc.cli", "run", campaign, "-o", out, "--no-progress", *args]
    return subprocess.Popen(
        list(map(str, command)), env={**os.environ, **env}, start_new_session=True, stderr=subprocess.PIPE, text=True
    )


@needs_numba_cuda
@needs_jit
@pytest.mark.slow
@pytest.mark.cuda
def test_a_signal_stops_a_gpu_campaign_and_resume_completes(tmp_path):
    """SIGINT in the middle of a GPU campaign whose host workers share the launch's arrays (-j 2,
    under the simulator): exit 130 without a traceback (the flight's thread, which writes the
    shared arrays, joined before they are freed), the parts written so far kept, and --resume
    completes it with the CPU's runs table. (The arrays are memory files of the process: nothing
    of them outlives it, shared_arrays.)"""
    import signal
    import time

    from stored import campaign_copy, read_runs

    from refexmc.campaign import run as run_module
    from refexmc.campaign import shared_arrays

    if not shared_arrays.shareable():
        pytest.skip("no memory files to share (not Linux)")
    campaign, out, runs = campaign_copy("smoke.yaml", tmp_path), tmp_path / "out", 96
    env = {"NUMBA_ENABLE_CUDASIM": "1", run_module.CHUNK_SIZE_ENV: "2"}
    process = _cli(campaign, out, "--runs", runs, "--backend", "cuda", "-j", 2, env=env)
    deadline = time.monotonic() + 300  # a cold kernel cache compiles first
    while not ((out / "runs").is_dir() and any((out / "runs").glob("part-*.parquet"))):
        assert process.poll() is None, process.stderr.read()
        assert time.monotonic() < deadline, "no part file"
        time.sleep(0.01)
    process.send_signal(signal.SIGINT)
    stderr = process.communicate(timeout=120)[1]
    assert process.returncode == 128 + signal.SIGINT, stderr
    assert "interrupted by SIGINT" in stderr and "Traceback" not in stderr, stderr
    kept = sorted((out / "runs").glob("part-*.parquet"))
    assert 0 < len(kept) < runs // 2, "the signal came after the end"
    resumed = _cli(campaign, out, "--resume", "--runs", runs, "--backend", "cuda", "-j", 2, env=env)
    assert resumed.wait(timeout=600) == 0, resumed.stderr.read()
    cpu = _cli(campaign, tmp_path / "cpu", "--runs", runs, "-j", 2, env={run_module.CHUNK_SIZE_ENV: "2"})
    assert cpu.wait(timeout=600) == 0, cpu.stderr.read()
    assert read_runs(out).equals(read_runs(tmp_path / "cpu"))
