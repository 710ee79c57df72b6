"""The one place where JIT options are set.

Every kernel in ``refexmc.core`` is decorated with :func:`jit`. Compiled code is cached on
disk (``cache=True``) so that a new process starts without recompiling; ``fastmath`` stays off
so that results are bit-for-bit reproducible. ``REFEXMC_DISABLE_JIT=1`` runs the kernels as
plain Python (slow; for debugging and coverage).

Numba keys a cached function on its own source file only, so an edit to a kernel that another
file's kernel calls would leave a stale cache behind. The cache therefore lives in a directory
named by a hash of every core source file: any change to the core starts a fresh cache.
Location: ``$NUMBA_CACHE_DIR/refexmc-<hash>`` if that variable is set, else
``$XDG_CACHE_HOME/refexmc/numba-<hash>`` (default ``~/.cache``).

Same bits on any CPU (docs/campaigns.md): without fast-math LLVM contracts no multiply-add into
an FMA; Intel's SVML (numba uses it where the ``icc_rt`` package is installed) would replace
libm's exp, sin, ... in vectorised loops with its own, so it is turned off before numba is
imported (``numba -s`` shows ``config.USING_SVML``). ``tests/test_cpu_independence.py`` checks both.
"""

import hashlib
import os
from pathlib import Path

os.environ.setdefault("NUMBA_DISABLE_INTEL_SVML", "1")  # before numba reads its configuration

import numba  # noqa: E402

JIT_OPTIONS = {"cache": True, "fastmath": False, "nogil": True, "error_model": "numpy"}
DISABLED = os.environ.get("REFEXMC_DISABLE_JIT", "0") not in ("", "0")


def _source_hash():
    package = Path(__file__).resolve().parent
    digest = hashlib.sha256()
    for path in sorted([package / "_jit.py", *(package / "core").glob("*.py")]):
        digest.update(path.name.encode())
        digest.update(path.read_bytes())
    digest.update(numba.__version__.encode())
    return digest.hexdigest()[:16]


def cache_dir():
    """Where compiled kernels of this exact core source are cached."""
    tag = _source_hash()
    if os.environ.get("NUMBA_CACHE_DIR"):
        return Path(os.environ["NUMBA_CACHE_DIR"]) / f"refexmc-{tag}"
    base = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    return base / "refexmc" / f"numba-{tag}"


numba.config.CACHE_DIR = str(cache_dir())


def jit(function):
    """Compile ``function`` with refexmc's JIT options (or leave it as Python if disabled)."""
    if DISABLED:
        return function
    return numba.njit(**JIT_OPTIONS)(function)


def jit_noalloc(function=None, *, force_inline=False):
    """Like :func:`jit`, for kernels that allocate no arrays: compiled without numba's runtime.

    Numba's reference counting (NRT) increments and decrements the count of every array a
    jitted function is handed, on every call, with atomic instructions; in the run loop that
    was most of the flight's time (benchmarks/RESULTS.md, issue 2). A kernel that only reads
    and writes caller-owned arrays needs none of it. ``_nrt`` is a private numba option (the
    ``nrt`` compiler flag); it is safe here because every caller holds its own reference to the
    arrays for the whole call, and a kernel that tried to allocate would fail to compile. The
    flag is part of the decorator, so the on-disk cache always holds code compiled with it.

    ``@jit_noalloc(force_inline=True)`` also has LLVM inline the kernel into its callers
    (numba's public ``forceinline``; unlike ``inline="always"`` it costs no extra numba
    compilation): for mid-sized kernels called every control step, whose array arguments
    would otherwise each be passed as seven machine words.
    """
    if function is None:
        return lambda f: jit_noalloc(f, force_inline=force_inline)
    if DISABLED:
        return function
    options = dict(JIT_OPTIONS, _nrt=False)
    if force_inline:
        options["forceinline"] = True
    return numba.njit(**options)(function)


def jit_inline(function):
    """Like :func:`jit`, but inlined into its callers at numba IR level.

    For thin dispatchers called every control step: inlining removes a call layer whose array
    arguments would each cost a reference-count increment and decrement.
    """
    if DISABLED:
        return function
    return numba.njit(inline="always", **JIT_OPTIONS)(function)


# --- the GPU target (refexmc run --backend cuda, docs/gpu.md) ---------------------------------
# The same kernels, compiled by numba-cuda (the `cuda` extra): a jitted function that a CUDA
# kernel calls becomes a device function compiled from its Python source with the options above
# (fastmath off; numba-cuda's CUDATypingContext does it for every @jit function it meets), so the
# core has no second copy. Under numba-cuda's simulator (NUMBA_ENABLE_CUDASIM=1) a kernel runs as
# Python, one thread per run; what it calls then runs as the CPU kernel on the thread's rows.

CUDA_SIMULATOR = os.environ.get("NUMBA_ENABLE_CUDASIM", "0") not in ("", "0")


def cuda_unavailable():
    """Why CUDA kernels cannot run in this process (one line), or None when they can: numba-cuda
    is installed and a GPU with its driver answers, or the simulator is on."""
    import importlib.util

    if importlib.util.find_spec("numba_cuda") is None:
        return "numba-cuda is not installed (pip install 'refexmc[cuda]')"
    if CUDA_SIMULATOR:
        return None
    try:
        from numba import cuda

        if cuda.is_available():
            return None
    except Exception as exc:  # noqa: BLE001 - any failure to reach the driver means: no GPU here
        return f"no CUDA GPU can be used here ({type(exc).__name__})"
    return "no CUDA GPU or driver found here (NUMBA_ENABLE_CUDASIM=1 runs numba-cuda's simulator instead)"


def cuda_kernel(function):
    """``function`` as a CUDA kernel (launched ``kernel[blocks, threads](...)``), fast-math off."""
    from numba import cuda

    return cuda.jit(fastmath=False)(function)


def cuda_device(kernel):
    """What a CUDA kernel calls to run the jitted ``kernel``: ``kernel`` itself (numba-cuda makes it
    a device function of the same source), or under the simulator a Python function that hands
    the CPU kernel the host arrays behind the simulator's fake device arrays."""
    if not CUDA_SIMULATOR:
        return kernel

    def host(value):
        if isinstance(value, tuple):
            parts = [host(part) for part in value]
            return type(value)(*parts) if hasattr(value, "_fields") else tuple(parts)
        return getattr(value, "_ary", value)  # numba-cuda's FakeCUDAArray holds its array as _ary

    def simulated(*args):
        return kernel(*[host(arg) for arg in args])

    return simulated
