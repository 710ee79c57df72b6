"""The flight kernels' machine code (issues 22, 32 and 37): no fast-math, no SVML, no FMA, no call to
libm's rounded functions, in every kernel of the on-disk cache.

It flies a run of every family (tests/test_cpu_independence.py's ``CAMPAIGNS``) and reads what numba
cached. ``make test`` runs this file last (tests/conftest.py ``LAST``): by then the other files have
compiled every family into the shared cache, so its flights load their kernels instead of
compiling them beside the other worker; alone, it compiles them itself.
"""

import itertools
import re
import shutil
import struct
import subprocess
from pathlib import Path

import pytest
from test_cpu_independence import CAMPAIGNS, ROOT, _python

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
