"""The same bits on any CPU (issue 22): drawn parameters and runs tables do not depend on the
machine's SIMD features, its BLAS kernels or its libm variant.

A subprocess stands in for an older CPU: numpy limited to SSE4.2 (``NPY_ENABLE_CPU_FEATURES``;
``NPY_DISABLE_CPU_FEATURES`` does not turn AVX-512 off), numpy's OpenBLAS on its SSE kernels
without FMA (``OPENBLAS_CORETYPE=Nehalem``), glibc's libm without its FMA/AVX2 variants
(``GLIBC_TUNABLES``; the draws only, see below), numba compiling for ``NUMBA_CPU_NAME=generic``
(x86-64 baseline: SSE2, no FMA), in a cold kernel cache of its own. On the old sampler (numpy's
``np.exp``, LAPACK's eigh and BLAS products for the inertia, libm's sin/cos/atan2 for rotations)
each of these changed some draws by an ulp on an AVX-512 machine with FMA.
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

ROOT = Path(__file__).resolve().parents[1]
SSE42 = "SSE SSE2 SSE3 SSSE3 SSE41 POPCNT SSE42"
OLD_CPU = {
    "NPY_ENABLE_CPU_FEATURES": SSE42,
    "OPENBLAS_CORETYPE": "Nehalem",
}
# numpy refuses x86 feature names on other machines
x86_64_only = pytest.mark.skipif(platform.machine() not in ("x86_64", "AMD64"), reason="x86-64 SIMD features")
# glibc >= 2.33 names; older glibc ignores unknown tunables (then the check is weaker, not wrong)
NO_FMA_LIBM = {"GLIBC_TUNABLES": "glibc.cpu.hwcaps=-AVX512F,-AVX512DQ,-AVX2,-FMA,-AVX"}

# every distribution kind, on a path it applies to; sizes large enough to have caught the old
# np.exp (with AVX-512, ~5 % of lognormal draws one ulp off) and libm's FMA variants (~1 in 1,500)
DRAWS = """
import sys
import numpy as np
from scipy import special
from refexmc.campaign import sampling
from refexmc.config import dispersions
from refexmc.config.load import load_campaign

nominal = load_campaign("campaigns/nominal.yaml")
campaign = dict(nominal, dispersions={
    "atmosphere.density_scale": {"dist": "lognormal", "median": 1.0, "sigma": 0.3},
    "separation.rates_deg_s": {"dist": "normal", "mean": [1.0, 0.0, -2.0], "sigma": [0.5, 2.0, 1.0]},
    "rcs.thrust_scale": {"dist": "truncnorm", "mean": 1.0, "sigma": 0.05, "low": 0.9, "high": 1.2},
    "rcs.valve_time_constants_ms.high.fall": {"dist": "truncnorm", "sigma": 2.25, "low": 0.0},
    "navigation.rate_noise_deg_s": {"dist": "uniform", "low": 0.0, "high": 0.02},
    "rcs.isp_s": {"dist": "choice", "values": [60.0, 65.0, 70.0], "probabilities": [0.2, 0.5, 0.3]},
    "com_offset_m": {"dist": "constant", "value": [0.001, 0.0, 0.0]},
    "separation.attitude_error_deg": {"dist": "uniform_so3"},
    "inertia_kg_m2": {"dist": "inertia", "moments_sigma_fraction": 0.05, "axes_sigma_deg": 5.0},
})
sampler = sampling.Sampler(campaign)
rows = {"atmosphere.density_scale": 200_000, "separation.attitude_error_deg": 40_000, "inertia_kg_m2": 40_000}
out = {}
for k, (path, spec) in enumerate(sampler.specs.items()):
    n = sampling.dims(spec, dispersions.size(path, campaign["vehicle"]))
    u = np.random.default_rng(k).random((rows.get(path, 20_000), n))
    u = np.clip(u, dispersions.UNIFORM_EPS, 1.0 - dispersions.UNIFORM_EPS)
    out[path] = sampling.transform_rows(spec, u, sampler.nominal[path])
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
from refexmc.campaign.chunk import fly_chunk
from refexmc.config.load import load_campaign

out = {}
for name, runs in json.loads(sys.argv[2]):
    campaign = load_campaign(f"campaigns/{name}.yaml")
    campaign["runs"] = runs
    rows, _ = fly_chunk(campaign, range(runs))
    table = storage.runs_table(rows)
    for column in table.column_names:
        values = table[column].combine_chunks()
        if pa.types.is_floating(values.type):
            out[f"{name}/{column}"] = values.to_numpy(zero_copy_only=False).view(np.uint64).tolist()
        else:
            out[f"{name}/{column}"] = values.to_pylist()
json.dump(out, open(sys.argv[1], "w"))
"""
CAMPAIGNS = [("smoke", 20), ("refex-mc100", 6), ("irassi-fine-pointing", 3)]


@pytest.mark.slow
@x86_64_only
def test_runs_tables_are_the_same_bits_with_sse42_numpy_and_generic_numba_kernels(tmp_path):
    """The smoke, refex-mc100 and irassi-fine-pointing runs tables (a few runs each) flown here
    and in a subprocess whose numpy and OpenBLAS stop at SSE4.2 and whose kernels numba compiles
    for a generic x86-64 (cold, in a cache of its own: ~1 min). glibc's libm keeps its variant:
    the flight kernels call it (numba's math.exp, math.sin, ...), see docs/campaigns.md."""
    tables = {}
    for name, env in [("host", {}), ("older", {**OLD_CPU, "NUMBA_CPU_NAME": "generic"})]:
        if env:
            env["NUMBA_CACHE_DIR"] = str(tmp_path / "numba-cache")
        _python(FLY, [tmp_path / f"{name}.json", json.dumps(CAMPAIGNS)], env)
        tables[name] = json.loads((tmp_path / f"{name}.json").read_text())
    host, older = tables["host"], tables["older"]
    assert sorted(host) == sorted(older)
    assert {key.split("/")[0] for key in host} == {name for name, _ in CAMPAIGNS}
    differing = sorted(key for key in host if host[key] != older[key])
    assert not differing, f"columns with other bits: {differing}"


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
    from refexmc.campaign.sampling import symmetric_eigen

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

    from refexmc.campaign.sampling import rotation_matrices, so3_rotation_vectors_deg

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


CONTROL = """
import numba

@numba.njit(fastmath=True, cache=True)
def multiply_add(a, b, c):
    return a * b + c

multiply_add(1.0, 2.0, 3.0)
"""


@pytest.mark.skipif(shutil.which("objdump") is None, reason="needs binutils' objdump")
def test_the_flight_kernels_have_no_fast_math_no_svml_and_no_fma(tmp_path):
    """Same bits on any CPU needs each kernel's arithmetic as written: numba compiles without
    fast-math (refexmc._jit), so LLVM contracts no a * b + c into an FMA, which would round once
    where the source rounds twice and only where the CPU has FMA; and without Intel's SVML (its
    vector sin, exp, ... are not libm's). Scanned: the machine code of every kernel in the
    on-disk cache after flying ReFEx and IRASSI runs. The scan finds the FMA that a fast-math
    kernel gets on a CPU with FMA (the control)."""
    import numba

    from refexmc._jit import JIT_OPTIONS, cache_dir
    from refexmc.campaign.chunk import fly_chunk
    from refexmc.config.load import load_campaign

    assert JIT_OPTIONS["fastmath"] is False
    assert not numba.config.USING_SVML
    for name in ("smoke", "irassi-fine-pointing"):
        campaign = load_campaign(ROOT / "campaigns" / f"{name}.yaml")
        campaign["runs"] = 2
        fly_chunk(campaign, range(2))
    (tmp_path / "kernels").mkdir()
    objects = _kernel_objects(cache_dir(), tmp_path / "kernels")
    assert len(objects) >= 20, f"{len(objects)} kernels in {cache_dir()}"
    assert not _fma_in(objects), "kernels with FMA instructions"
    if "fma" in Path("/proc/cpuinfo").read_text().split():
        (tmp_path / "control").mkdir()
        (tmp_path / "control.py").write_text(CONTROL)
        _python("import control", [], {"NUMBA_CACHE_DIR": str(tmp_path / "cache"), "PYTHONPATH": str(tmp_path)})
        assert _fma_in(_kernel_objects(tmp_path / "cache", tmp_path / "control"))
