"""The same bits on any CPU (issues 22 and 32): drawn parameters, packed inputs and runs tables do
not depend on the machine's SIMD features, its BLAS kernels or numba's compile target.

A subprocess stands in for another CPU: numpy limited to SSE4.2 (``NPY_ENABLE_CPU_FEATURES``;
``NPY_DISABLE_CPU_FEATURES`` does not turn AVX-512 off), numpy's OpenBLAS on another kernel set
(``OPENBLAS_CORETYPE``: Nehalem's SSE kernels without FMA, Haswell's and Zen's with it, SkylakeX's
AVX-512 ones where the CPU has AVX-512), glibc's libm without its FMA/AVX2 variants
(``GLIBC_TUNABLES``), numba compiling for ``NUMBA_CPU_NAME=generic``
(x86-64 baseline: SSE2, no FMA), in a cold kernel cache of its own. On the old sampler (numpy's
``np.exp``, LAPACK's eigh and BLAS products for the inertia, libm's sin/cos/atan2 for rotations)
each of these changed some draws by an ulp on an AVX-512 machine with FMA; on the old packing
(LAPACK's pinv for the wheels' distribution) OpenBLAS's Nehalem kernels changed IRASSI's runs.
Emulation only finds what differs on the CPU at hand, so a second check does not depend on it:
everything that feeds a run is packed with BLAS and LAPACK poisoned (``tests/blas_poison.py``).

The flights of every family on the emulated CPUs (marker ``emulated_cpu``: the generic CPU's cold
compile of every kernel is ~200 s of one core) run in ``make test-cpus``, not in ``make test``;
CI runs both. The draws, the poisoned packing and the machine-code scan run in ``make test``.
"""

import itertools
import json
import os
import platform
import re
import shutil
import struct
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from refexmc import _jit
from refexmc.core import layout as L

ROOT = Path(__file__).resolve().parents[1]
SSE42 = "SSE SSE2 SSE3 SSSE3 SSE41 POPCNT SSE42"
OLD_CPU = {
    "NPY_ENABLE_CPU_FEATURES": SSE42,
    "OPENBLAS_CORETYPE": "Nehalem",
}
# numpy refuses x86 feature names on other machines
X86_64 = platform.machine() in ("x86_64", "AMD64")
x86_64_only = pytest.mark.skipif(not X86_64, reason="x86-64 SIMD features")
# glibc >= 2.33 names; older glibc ignores unknown tunables (then the check is weaker, not wrong)
NO_FMA_LIBM = {"GLIBC_TUNABLES": "glibc.cpu.hwcaps=-AVX512F,-AVX512DQ,-AVX2,-FMA,-AVX"}

# every distribution kind, on a path it applies to; sizes large enough to have caught the old
# np.exp (with AVX-512, ~5 % of lognormal draws one ulp off) and libm's FMA variants (~1 in 1,500)
DRAWS = """
import sys
import numpy as np
from scipy import special
from refexmc import distributions
from refexmc.campaign import sampling
from refexmc.config import dispersions
from refexmc.config.load import load_campaign

nominal = load_campaign("campaigns/nominal.yaml")
campaign = dict(nominal, dispersions={
    "atmosphere.density_scale": {"dist": "lognormal", "median": 1.0, "sigma": 0.3},
    "initial_state.rates_deg_s": {"dist": "normal", "mean": [1.0, 0.0, -2.0], "sigma": [0.5, 2.0, 1.0]},
    "rcs.thrust_scale": {"dist": "truncnorm", "mean": 1.0, "sigma": 0.05, "low": 0.9, "high": 1.2},
    "rcs.valve_time_constants_ms.high.fall": {"dist": "truncnorm", "sigma": 2.25, "low": 0.0},
    "navigation.rate_noise_deg_s": {"dist": "uniform", "low": 0.0, "high": 0.02},
    "rcs.isp_s": {"dist": "choice", "values": [60.0, 65.0, 70.0], "probabilities": [0.2, 0.5, 0.3]},
    "com_offset_m": {"dist": "constant", "value": [0.001, 0.0, 0.0]},
    "initial_state.attitude_rotvec_deg": {"dist": "uniform_so3"},
    "inertia_kg_m2": {"dist": "inertia", "moments_sigma_fraction": 0.05, "axes_sigma_deg": 5.0},
})
sampler = sampling.Sampler(campaign)
rows = {"atmosphere.density_scale": 200_000, "initial_state.attitude_rotvec_deg": 40_000, "inertia_kg_m2": 40_000}
out = {}
for k, (path, spec) in enumerate(sampler.specs.items()):
    n = sampling.dims(spec, dispersions.size(path, campaign["vehicle"]))
    u = np.random.default_rng(k).random((rows.get(path, 20_000), n))
    u = np.clip(u, dispersions.UNIFORM_EPS, 1.0 - dispersions.UNIFORM_EPS)
    out[path] = distributions.transform_rows(spec, u, sampler.nominal[path])
    out[f"{path}/ndtri"] = special.ndtri(u)
np.savez(sys.argv[1], **out)
"""


def _python(script, args, env_extra, cwd=ROOT, timeout=600):
    env = {**os.environ, **env_extra}
    result = subprocess.run(
        [sys.executable, "-c", script, *map(str, args)],
        cwd=cwd,
        env=env,
        capture_output=True,
        text=True,
        timeout=timeout,
    )
    assert result.returncode == 0, result.stderr[-3000:]


def _differing(a, b):
    """{key: number of elements whose bits differ} of two dicts of float arrays."""
    assert sorted(a) == sorted(b)
    return {k: int((a[k].view(np.uint64) != b[k].view(np.uint64)).sum()) for k in a if a[k].shape == b[k].shape} | {
        k: -1 for k in a if a[k].shape != b[k].shape
    }


@pytest.fixture(scope="module")
def host_draws(tmp_path_factory):
    path = tmp_path_factory.mktemp("draws") / "host.npz"
    _python(DRAWS, [path], {})
    with np.load(path) as data:
        return {k: data[k] for k in data.files}


def _older_draws(tmp_path, env):
    path = tmp_path / "older.npz"
    _python(DRAWS, [path], env)
    with np.load(path) as data:
        return {k: data[k] for k in data.files}


@x86_64_only
def test_every_distribution_draws_the_same_bits_with_sse42_numpy_and_openblas(host_draws, tmp_path):
    older = _older_draws(tmp_path, OLD_CPU)
    assert len(host_draws["atmosphere.density_scale"]) == 200_000
    differing = {k: n for k, n in _differing(host_draws, older).items() if n}
    assert not differing, f"elements with other bits under {OLD_CPU}: {differing}"


def test_without_glibcs_fma_variants_only_scipys_ndtri_moves_a_draw(host_draws, tmp_path):
    """glibc's exp, log, sin, cos and atan2 have FMA/AVX2 variants that round differently from the
    plain ones in ~1 result in 1,500. The sampler's own exp, sin, cos and atan2 are correctly
    rounded (refexmc.crmath); scipy's ndtri (cephes) calls glibc's log in its tails and so differs
    for ~2 uniforms in a million (docs/campaigns.md): every draw that differs is one of those."""
    older = _older_draws(tmp_path, NO_FMA_LIBM)
    unexplained = {}
    for path in [k for k in host_draws if not k.endswith("/ndtri")]:
        moved = (host_draws[path].view(np.uint64) != older[path].view(np.uint64)).reshape(len(host_draws[path]), -1)
        ndtri = f"{path}/ndtri"
        ndtri_moved = (host_draws[ndtri].view(np.uint64) != older[ndtri].view(np.uint64)).any(axis=1)
        if (moved.any(axis=1) & ~ndtri_moved).any():
            unexplained[path] = int((moved.any(axis=1) & ~ndtri_moved).sum())
    assert not unexplained, f"draws that moved without glibc's log moving scipy's ndtri: {unexplained}"


FLY = """
import json, sys
import numpy as np
import pyarrow as pa
from refexmc.campaign import storage
from refexmc.campaign.chunk import fly_chunk, plan_for
from refexmc.config.load import load_campaign
from refexmc.core import allocation, environment, feed, local_flight, lp_allocation, orbit_flight, rcs, switching
from refexmc.core import wheels

STEPS = {  # each family's own step functions: compiled only by a kernel of that family
    "thrusters": [rcs.update, rcs.next_breakpoint, rcs.segment_thrust, rcs.open_mask, rcs.torque_arms],
    "pwpf_table": [switching.enforce, allocation.table_masks],
    "lp_pwm": [lp_allocation.pulse_width, lp_allocation.allocate, allocation.nominal_arms],
    "wheels": [wheels.drive, wheels.start, wheels.step, wheels.rk4_step],
    "planar_drag": [environment.advance_nodes, environment.interpolate],
    "orbit": [orbit_flight.start, orbit_flight.steer, orbit_flight.engine_period, orbit_flight.translate],
    "feed": [feed.start, feed.segment, feed.gas],
    "local": [
        local_flight.start, local_flight.desired, local_flight.advance, local_flight.navigate, local_flight.measure,
        local_flight.segment_force, feed.pressure_within,
    ],
}
out, compiled = {}, []
for label, name, runs, changes in json.loads(sys.argv[2]):
    campaign = load_campaign(f"campaigns/{name}.yaml")
    campaign.update(changes, runs=runs)
    rows, _ = fly_chunk(campaign, range(runs))
    # the step functions' signatures compiled so far in this process (in a cold cache: by the
    # kernels of this campaign's family and the ones before)
    steps = {group: [len(function.signatures) for function in functions] for group, functions in STEPS.items()}
    family = getattr(plan_for(campaign), "family", None)  # the entry has a kernel of its own
    compiled.append({"label": label, "family": family and list(family), "compiled": steps})
    table = storage.runs_table(rows)
    for column in table.column_names:
        values = table[column].combine_chunks()
        if pa.types.is_floating(values.type):
            out[f"{label}/{column}"] = values.to_numpy(zero_copy_only=False).view(np.uint64).tolist()
        else:
            out[f"{label}/{column}"] = values.to_pylist()
json.dump({"columns": out, "compiled": compiled}, open(sys.argv[1], "w"))
"""
# every vehicle family (docs/families.md), a few runs each: (label, campaign, runs, campaign keys changed)
DETECTED_WHEEL = {"wheel_failures": {"mode": "fixed", "wheels": [2], "detected": True}}
# (the IRASSI and ReFEx kernels first: test_a_family_compiles_none_of_the_other_families_steps)
CAMPAIGNS = [
    ("irassi", "irassi-fine-pointing", 3, {}),  # reaction wheels (001)
    ("smoke", "smoke", 4, {}),  # thrusters, PWPF and the allocation table, planar drag (000)
    ("refex-regulated", "refex-blow-down-mc100", 2, {}),  # the regulated feed
    ("irassi-rw2-detected", "irassi-fine-pointing", 2, DETECTED_WHEEL),  # D of three wheels
    ("cold-gas-fig8", "cold-gas-fig8", 2, {}),  # blow-down feed, time-optimal translation (002)
    ("surveyor-hop", "surveyor-hop", 2, {}),  # local trajectory
    ("spore", "spore-deorbit-iss", 2, {}),  # LP allocation, orbit and deorbit burn (004)
    ("generic-slew", "generic-slew", 2, {}),  # attitude only
    ("x38", "x38-nominal", 2, {}),  # entry (003)
]
CPU_FLAGS = set(Path("/proc/cpuinfo").read_text().split()) if Path("/proc/cpuinfo").exists() else set()
# OpenBLAS's kernels (OPENBLAS_CORETYPE) and what they execute: forcing one the CPU lacks crashes
CORETYPES = {
    "Nehalem": {"sse4_2"},
    "Haswell": {"avx2", "fma"},
    "Zen": {"avx2", "fma"},
    "SkylakeX": {"avx512f", "avx512dq", "avx512bw", "avx512vl"},
}


def _cpu_variants(tmp_path):
    """{name: environment} of the CPUs emulated here: every OpenBLAS kernel set the CPU can run
    (numba's kernels from the shared cache: OpenBLAS does not change them), and an old CPU:
    numba compiling for a generic CPU of the architecture (x86-64: SSE2, no FMA) into a cold cache
    of its own, the one cold compile, with numpy at SSE4.2 and OpenBLAS's Nehalem kernels on x86-64."""
    variants = {
        f"openblas-{name.lower()}": {"OPENBLAS_CORETYPE": name}
        for name, flags in CORETYPES.items()
        if flags <= CPU_FLAGS
    }
    variants["glibc-without-fma-variants"] = NO_FMA_LIBM  # the flights call no libm (core/elementary.py)
    variants[GENERIC] = {
        **(OLD_CPU if X86_64 else {}),
        "NUMBA_CPU_NAME": "generic",
        "NUMBA_CACHE_DIR": str(tmp_path / "numba-generic"),
    }
    return variants


GENERIC = "sse42-nehalem-generic"  # the cold-compiling variant


def _fly_concurrently(tmp_path, variants, timeout=1200):
    """{variant name: FLY's output}, every variant's subprocess started at once (a cold compile
    takes one core for minutes; the others load kernels and fly in seconds)."""
    processes = {}
    for name, env in variants.items():
        processes[name] = subprocess.Popen(
            [sys.executable, "-c", FLY, str(tmp_path / f"{name}.json"), json.dumps(CAMPAIGNS)],
            cwd=ROOT,
            env={**os.environ, **env},
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
    try:
        for name, process in processes.items():
            _, stderr = process.communicate(timeout=timeout)
            assert process.returncode == 0, f"{name}: {stderr[-3000:]}"
    finally:  # a failure or a timeout leaves no compile running on through the tests after it
        for process in processes.values():
            if process.poll() is None:
                process.kill()
                process.communicate()
    return {name: json.loads((tmp_path / f"{name}.json").read_text()) for name in variants}


@pytest.fixture(scope="module")
def emulated_flights(tmp_path_factory):
    """{variant: {"columns": runs-table values, "compiled": step signatures after each campaign}}
    of "host" (this CPU, the shared kernel cache) and every :func:`_cpu_variants`. ~3 min on 2
    cores with a warm kernel cache here: the generic CPU's kernels compile cold."""
    if _jit.DISABLED:
        pytest.skip("REFEXMC_DISABLE_JIT=1: nothing is compiled")
    tmp_path = tmp_path_factory.mktemp("emulated")
    variants = _cpu_variants(tmp_path)
    cold = {name: env for name, env in variants.items() if "NUMBA_CACHE_DIR" in env}
    # the host's flights fill (or load) the shared kernel cache while the generic CPU compiles its
    # own; then the OpenBLAS variants load the host's kernels
    flights = _fly_concurrently(tmp_path, {"host": {}, **cold})
    flights.update(_fly_concurrently(tmp_path, {name: env for name, env in variants.items() if name not in cold}))
    return flights


@pytest.mark.slow
@pytest.mark.emulated_cpu
@x86_64_only
def test_every_familys_runs_table_is_the_same_bits_on_every_emulated_cpu(emulated_flights):
    """A few runs of every vehicle family (thrusters, feeds, wheels with and without a detected
    failure, local, orbit with LP, attitude only, entry), flown here and in subprocesses under
    each of :func:`_cpu_variants`: every runs-table value the same bits, glibc's libm without its
    FMA/AVX2 variants too. Before issue 37 the flight kernels called glibc's exp, sin, atan2, ...
    (numba's math.exp, ...): without those variants 20 of 521 columns differed (IRASSI's pointing
    and wheel momentum, X-38's entry columns); they now call refexmc.core.elementary.
    Before issue 32 the wheels' distribution matrix came from LAPACK's SVD and OpenBLAS's
    products: the IRASSI columns with a detected failure differed between OpenBLAS's Nehalem and
    Haswell kernels (and, without a failure, between two AVX-512 machines)."""
    tables = {name: flights["columns"] for name, flights in emulated_flights.items()}
    host = tables.pop("host")
    assert {key.split("/")[0] for key in host} == {label for label, *_ in CAMPAIGNS}
    assert host["irassi-rw2-detected/failed_wheels"] == ["2", "2"]
    assert len(tables) >= 2  # the generic CPU and OpenBLAS's Nehalem kernels at least
    differing = {}
    for name, table in tables.items():
        assert sorted(table) == sorted(host)
        differing[name] = sorted(key for key in host if host[key] != table[key])
    assert not any(differing.values()), f"columns with other bits: {differing}"


# --- one compiled kernel per vehicle family (docs/families.md) ---------------------------------


@pytest.mark.slow
@pytest.mark.emulated_cpu
def test_a_family_compiles_none_of_the_other_families_steps(emulated_flights):
    """Compile what is flown (style.md 11): in the generic CPU's process, whose numba cache starts
    empty, the IRASSI kernel (actuation wheels, no trajectory) flown first compiles no thruster,
    table, LP, planar, orbit, feed or local step, and the ReFEx kernel next (pwpf_table,
    planar_drag) none of the LP, wheel, orbit, feed or local steps. A branch left unpruned would
    type its steps (or fail to compile on a None). Shares the cold compile of
    :func:`emulated_flights` (before: a process of its own, two minutes of a cold suite)."""
    irassi, refex, *_ = emulated_flights[GENERIC]["compiled"]
    assert irassi["label"] == "irassi" and refex["label"] == "smoke"
    assert irassi["family"] == [L.ACTUATION_WHEELS, L.TRAJECTORY_NONE, 1, L.FEED_CONSTANT]
    assert refex["family"] == [L.ACTUATION_PWPF_TABLE, L.TRAJECTORY_PLANAR_DRAG, 0, L.FEED_CONSTANT]
    first = irassi["compiled"]
    for family in ("thrusters", "pwpf_table", "lp_pwm", "planar_drag", "orbit", "feed", "local"):
        assert first[family] == [0] * len(first[family]), f"the IRASSI kernel compiled {family} steps: {first}"
    assert all(n >= 1 for n in first["wheels"]), first
    second = refex["compiled"]  # after both kernels: the wheel steps are the IRASSI kernel's
    for family in ("lp_pwm", "orbit", "feed", "local"):
        assert second[family] == [0] * len(second[family]), f"the ReFEx kernel compiled {family} steps: {second}"
    assert second["wheels"] == first["wheels"], "the ReFEx kernel compiled wheel steps"
    assert all(n >= 1 for n in second["thrusters"] + second["pwpf_table"] + second["planar_drag"]), second


# --- no BLAS or LAPACK in what feeds a run (issue 32) ----------------------------------------

POISON = ROOT / "tests" / "blas_poison.py"
poisonable = pytest.mark.skipif(
    platform.machine() not in ("x86_64", "AMD64", "aarch64") or not Path("/proc/self/maps").exists(),
    reason="the trap instruction and /proc/self/maps of Linux on x86-64 or aarch64",
)


def _poisoned(*args):
    env = {**os.environ, "PYTHONFAULTHANDLER": "1"}
    return subprocess.run(
        [sys.executable, str(POISON), *args], cwd=ROOT, env=env, capture_output=True, text=True, timeout=600
    )


@poisonable
def test_everything_that_feeds_a_run_packs_with_blas_and_lapack_poisoned():
    """Every shipped campaign (each sweep point): the nominal inputs, the draws and inputs of its
    first 40 runs (failure sets too), IRASSI's tables with every set of one or two wheels failed
    and detected, and the shipped files no campaign flies, packed while numpy.linalg,
    scipy.linalg, np.dot, np.matmul, ... raise and every BLAS/LAPACK function of the loaded
    OpenBLAS libraries starts with an illegal instruction (``tests/blas_poison.py``: what it
    covers and what not). So BLAS creeping into what feeds a run fails on any machine, not only
    on one whose kernels round differently (before issue 32: the wheels' pinv, products, norms)."""
    result = _poisoned("pack")
    assert result.returncode == 0, result.stderr[-4000:]
    poisoned, packed = result.stdout.strip().split("} {", 1)
    assert "openblas" in poisoned  # numpy's own OpenBLAS (and scipy's) had their functions trapped
    for name in ("irassi-fine-pointing", "x38-nominal", "spore-failure-sweep-detected", "surveyor-hop", "smoke"):
        assert f"'{name}'" in packed


@poisonable
@pytest.mark.parametrize(
    ("code", "caught_by"),
    [
        ("np.ones((3, 4)) @ np.ones(4)", "Illegal instruction"),  # the operator: the trap in cblas_dgemv
        ("np.ones(3).dot(np.ones(3))", "Illegal instruction"),  # a method: cblas_ddot
        ("from numpy.linalg._linalg import svd; svd(np.eye(3))", "Illegal instruction"),  # LAPACK dgesdd
        ("np.linalg.pinv(np.ones((3, 4)))", "BlasCalled: np.linalg.pinv"),
        ("np.dot(np.ones(3), np.ones(3))", "BlasCalled: np.dot"),
    ],
)
def test_the_poison_catches_blas_and_lapack_however_called(code, caught_by):
    """The control: each of these does get caught, the trap naming the Python line."""
    result = _poisoned("control", code)
    assert "CONTROL GOT THROUGH" not in result.stdout
    assert result.returncode != 0 and caught_by in result.stderr, result.stderr[-3000:]
    if caught_by == "Illegal instruction":
        assert 'File "<string>", line 1' in result.stderr  # faulthandler: where it was called


@poisonable
def test_the_poison_lets_numpys_own_loops_through():
    """Elementwise arithmetic, reductions, np.cross and integer products are not BLAS."""
    code = "np.cross([1.0, 0, 0], [0, 1.0, 0]) + np.ones((3, 3)).sum(axis=0) * 2.0; np.dot(np.ones(3, int), [1, 2, 3])"
    result = _poisoned("control", code)
    assert result.returncode == 0 and "CONTROL GOT THROUGH" in result.stdout, result.stderr[-3000:]


# --- the pieces, against independent references ----------------------------------------------


def test_crmath_exp_is_correctly_rounded():
    """Against Python's decimal module (50 digits, then the correctly rounded conversion to float)."""
    from decimal import Decimal, localcontext

    from refexmc import crmath

    x = np.random.default_rng(1).normal(size=20_000) * 3.0
    with localcontext() as context:
        context.prec = 50
        expected = np.array([float(Decimal(v).exp()) for v in x.tolist()])
    np.testing.assert_array_equal(crmath.exp(x), expected)
    assert crmath.exp(np.array([-800.0, 0.0, 800.0])).tolist() == [0.0, 1.0, np.inf]


def test_crmath_sin_cos_atan2_are_libm_within_an_ulp():
    """glibc's sin, cos and atan2 are within an ulp of the correctly rounded value (and equal to it
    almost always); the shapes broadcast like numpy's."""
    import math

    from refexmc import crmath

    x = np.random.default_rng(2).uniform(-7.0, 7.0, size=20_000)
    for mine, libm in [
        (crmath.sin(x), np.array([math.sin(v) for v in x])),
        (crmath.cos(x), np.array([math.cos(v) for v in x])),
    ]:
        assert np.all(np.abs(mine - libm) <= np.spacing(np.abs(libm)))
        assert np.mean(mine == libm) > 0.99
    y = crmath.atan2(x[:, np.newaxis], np.array([1.0, -2.0]))
    assert y.shape == (20_000, 2)
    libm = np.array([[math.atan2(v, 1.0), math.atan2(v, -2.0)] for v in x])
    assert np.all(np.abs(y - libm) <= np.spacing(np.abs(libm)))


def test_symmetric_eigen_agrees_with_lapack():
    from refexmc.smallmatrix import symmetric_eigen

    rng = np.random.default_rng(3)
    matrices = [np.diag([6.92, 6.92, 3.72]), np.array([[20.04, 0.0, -1.5], [0.0, 243.85, 0.0], [-1.5, 0.0, 247.6]])]
    matrices += [(m + m.T) * 50.0 for m in rng.normal(size=(200, 3, 3))]
    for matrix in matrices:
        values, vectors = symmetric_eigen(matrix)
        scale = np.abs(matrix).max()
        np.testing.assert_allclose(values, np.linalg.eigvalsh(matrix), rtol=0, atol=1e-13 * scale)
        np.testing.assert_allclose(vectors.T @ vectors, np.eye(3), rtol=0, atol=1e-14)
        np.testing.assert_allclose(vectors @ np.diag(values) @ vectors.T, matrix, rtol=0, atol=1e-13 * scale)
    # a diagonal matrix keeps its axes, equal moments in LAPACK's order (the later axis first)
    values, vectors = symmetric_eigen(np.diag([6.92, 6.92, 3.72]))
    assert values.tolist() == [3.72, 6.92, 6.92]
    assert vectors.tolist() == [[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]]


def test_rotations_agree_with_scipy():
    from scipy.spatial.transform import Rotation

    from refexmc.distributions import rotation_matrices, so3_rotation_vectors_deg

    rng = np.random.default_rng(4)
    rotvec = np.vstack([rng.normal(size=(2000, 3)), np.zeros((1, 3)), [[1e-300, 0.0, 0.0]], [[3.0, 0.0, 0.0]]])
    np.testing.assert_allclose(rotation_matrices(rotvec), Rotation.from_rotvec(rotvec).as_matrix(), rtol=0, atol=1e-15)
    u = rng.random((2000, 3))
    mine = so3_rotation_vectors_deg(u)
    r1, r2, a, b = np.sqrt(1.0 - u[:, 0]), np.sqrt(u[:, 0]), 2 * np.pi * u[:, 1], 2 * np.pi * u[:, 2]
    quat = np.stack([r1 * np.sin(a), r1 * np.cos(a), r2 * np.sin(b), r2 * np.cos(b)], axis=1)  # Shoemake, scalar last
    expected = Rotation.from_quat(quat)
    np.testing.assert_allclose(Rotation.from_rotvec(mine, degrees=True).as_matrix(), expected.as_matrix(), atol=1e-14)
    assert np.linalg.norm(mine, axis=1).max() <= 180.0


# --- the flight kernels: no fast-math, no SVML, no FMA ----------------------------------------

FMA = re.compile(r"\bv?fn?m(?:add|sub)\w*")


def _kernel_objects(cache, into):
    """Write the machine code (ELF objects) of numba's on-disk cache ``cache`` into ``into``; return
    the files. A ``.nbc`` file pickles each kernel's object code as one bytes object (opcode ``B``,
    4-byte length, the bytes)."""
    files = []
    for data in sorted(Path(cache).rglob("*.nbc")):
        raw = data.read_bytes()
        start = 0
        while (i := raw.find(b"\x7fELF", start)) >= 5:
            start = i + 4
            if raw[i - 5] != ord("B"):
                continue
            (length,) = struct.unpack("<I", raw[i - 4 : i])
            files.append(into / f"{len(files)}-{data.stem}.o")
            files[-1].write_bytes(raw[i : i + length])
    return files


def _fma_in(objects):
    """{object file name: FMA mnemonics in its disassembly}, for those that have any."""
    found = {}
    for batch in itertools.batched(objects, 200) if hasattr(itertools, "batched") else [objects]:
        listing = subprocess.run(["objdump", "-d", *map(str, batch)], capture_output=True, text=True, check=True).stdout
        for part in re.split(r"\n(?=\S+\.o:\s+file format)", listing):
            name = part.split(":", 1)[0].strip()
            if FMA.search(part):
                found[Path(name).name] = sorted(set(FMA.findall(part)))
    return found


# libm's rounded functions; the exact ones are allowed: frexp, ldexp (numba_frexp, numba_ldexp) and
# fmod (a float ``%``: its result is representable, every variant returns it exactly)
LIBM = re.compile(
    r"^(?:__)?(?:sin|cos|tan|sincos|exp|exp2|expm1|log|log2|log10|log1p|pow|atan2|atan|asin|acos|sinh|cosh|tanh"
    r"|asinh|acosh|atanh|hypot|cbrt|erf|erfc|lgamma|tgamma)f?(?:_finite)?$"
)
# keyed_random (the draws' SeedSequence/PCG64 in integers, no float function) links numba's log10 in
# code numba adds itself (no line of keyed_random.py computes a logarithm); no value passes through it
LIBM_EXEMPT = {"keyed_random.uniforms_for_runs": {"log10"}}


def _libm_calls_in(objects):
    """{object file name: libm functions it calls}: the undefined symbols ``nm -u`` lists."""
    found = {}
    for batch in itertools.batched(objects, 200) if hasattr(itertools, "batched") else [objects]:
        listing = subprocess.run(["nm", "-u", *map(str, batch)], capture_output=True, text=True, check=True).stdout
        for part in re.split(r"\n(?=\S+\.o:\s*$)", listing, flags=re.MULTILINE):
            name = part.split(":", 1)[0].strip()
            exempt = next((allowed for kernel, allowed in LIBM_EXEMPT.items() if f"-{kernel}-" in name), set())
            symbols = {line.split()[-1] for line in part.splitlines()[1:] if line.strip()}
            called = sorted(symbol for symbol in symbols if LIBM.match(symbol) and symbol not in exempt)
            if called:
                found[Path(name).name] = called
    return found


CONTROL = """
import math
import numba

@numba.njit(fastmath=True, cache=True)
def multiply_add(a, b, c):
    return a * b + math.exp(c)

multiply_add(1.0, 2.0, 3.0)
"""


@pytest.mark.skipif(shutil.which("objdump") is None, reason="needs binutils' objdump")
def test_the_flight_kernels_have_no_fast_math_no_svml_and_no_fma(tmp_path):
    """Same bits on any CPU needs each kernel's arithmetic as written: numba compiles without
    fast-math (refexmc._jit), so LLVM contracts no a * b + c into an FMA, which would round once
    where the source rounds twice and only where the CPU has FMA; and without Intel's SVML (its
    vector sin, exp, ... are not libm's); and no call to libm's exp, sin, pow, ... at all, whose
    variants glibc picks per CPU (issue 37: refexmc.core.elementary instead). Scanned: the machine
    code of every kernel in the on-disk cache after flying a run of every family. The scan finds
    the FMA and the call to ``exp`` of a fast-math kernel (the control)."""
    import numba

    from refexmc._jit import JIT_OPTIONS, cache_dir
    from refexmc.campaign.chunk import fly_chunk
    from refexmc.config.load import load_campaign

    assert JIT_OPTIONS["fastmath"] is False
    assert not numba.config.USING_SVML
    for _, name, _, changes in CAMPAIGNS:
        campaign = load_campaign(ROOT / "campaigns" / f"{name}.yaml")
        campaign.update(changes, runs=1)
        fly_chunk(campaign, range(1))
    (tmp_path / "kernels").mkdir()
    objects = _kernel_objects(cache_dir(), tmp_path / "kernels")
    assert len(objects) >= 20, f"{len(objects)} kernels in {cache_dir()}"
    assert not _fma_in(objects), "kernels with FMA instructions"
    core = {path.stem for path in (ROOT / "refexmc" / "core").glob("*.py")}  # the cache holds others' too
    flight_objects = [path for path in objects if path.name.split("-", 1)[1].split(".", 1)[0] in core]
    assert len(flight_objects) >= 20
    assert not _libm_calls_in(flight_objects), "kernels calling libm (refexmc.core.elementary has them all)"
    if "fma" in Path("/proc/cpuinfo").read_text().split():
        (tmp_path / "control").mkdir()
        (tmp_path / "control.py").write_text(CONTROL)
        _python("import control", [], {"NUMBA_CACHE_DIR": str(tmp_path / "cache"), "PYTHONPATH": str(tmp_path)})
        control = _kernel_objects(tmp_path / "cache", tmp_path / "control")
        assert _fma_in(control)
        assert list(_libm_calls_in(control).values()) == [["exp"]]
