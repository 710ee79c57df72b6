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

import contextlib
import fcntl
import hashlib
import os
import threading
from pathlib import Path

import refexmc

os.environ.setdefault("NUMBA_DISABLE_INTEL_SVML", "1")  # before numba reads its configuration

import numba  # noqa: E402

JIT_OPTIONS = {"cache": True, "fastmath": False, "nogil": True, "error_model": "numpy"}
DISABLED = os.environ.get("REFEXMC_DISABLE_JIT", "0") not in ("", "0")


def _source_hash():
    return refexmc.flight_code_digest(numba.__version__)


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


_CACHE_LOCK_NAME = "compile.lock"
_cache_lock_thread = threading.RLock()  # one thread of this process at a time holds the file lock
_cache_lock_depth = 0


@contextlib.contextmanager
def cache_lock():
    """Hold the kernel cache's inter-process lock while compiling kernels into it.

    Numba's cache keeps one index file per function (``<name>-<line>.pyXY.nbi``: a pickled dict
    from signature, CPU and closure-cell hash to a data file ``<name>-<line>.pyXY.<n>.nbc``). Saving
    a compiled kernel loads the index, picks the first free ``n``, writes the index, then the data
    (``IndexDataCacheFile.save`` in ``numba/core/caching.py``); each file is replaced atomically,
    but nothing orders two processes. Two processes compiling two families at once both read the
    same index, both pick ``n = 1`` for their own family's ``run_flight`` (and ``_fly``, and each
    step typed apart): the index written last loses the other family's entry, and the data file
    written last may hold the other family's kernel under this family's key (the third process
    that loads it would fly the wrong family). ``tests/test_cache_lock.py`` forces that interleaving.

    Every compile refexmc asks for (``simulate.load_kernels``, which a family's first ``fly`` in a
    process calls too, and ``simulate.load_entry_kernel``) holds this lock: an ``flock`` on
    ``compile.lock`` in the cache directory, released by the kernel however its holder ends. A
    second process waits for the first one's compile, and then finds it in the cache. Re-entrant
    within a process; no lock where the JIT is disabled or the cache directory cannot be written
    (numba then caches nothing).
    """
    global _cache_lock_depth
    with _cache_lock_thread:
        if _cache_lock_depth or DISABLED:
            _cache_lock_depth += 1
            try:
                yield
            finally:
                _cache_lock_depth -= 1
            return
        fd = None
        try:
            Path(numba.config.CACHE_DIR).mkdir(parents=True, exist_ok=True)
            fd = os.open(Path(numba.config.CACHE_DIR) / _CACHE_LOCK_NAME, os.O_RDWR | os.O_CREAT, 0o666)
            fcntl.flock(fd, fcntl.LOCK_EX)
        except OSError:
            if fd is not None:
                os.close(fd)
            fd = None
        _cache_lock_depth += 1
        try:
            yield
        finally:
            _cache_lock_depth -= 1
            if fd is not None:
                os.close(fd)  # closing the file releases the flock


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


def cuda_kernel(function, cache_key=None):
    """``function`` as a CUDA kernel (launched ``kernel[blocks, threads](...)``), fast-math off and
    compiled without contraction (:func:`cuda_without_contraction`). With a ``cache_key`` (a
    repr-stable description of what ``function``'s closure captures), the compiled kernel is kept
    on disk beside the CPU kernels (:func:`_keyed_cuda_cache`), and the first launch, which
    compiles or loads it, holds :func:`cache_lock`."""
    from numba import cuda

    dispatcher = cuda.jit(fastmath=False)(function)
    if cache_key is not None and not CUDA_SIMULATOR:
        dispatcher._cache = _keyed_cuda_cache(function, cache_key)
    return _UncontractedKernel(dispatcher)


class _UncontractedKernel:
    """A numba-cuda kernel whose launches (the first one compiles it) run under
    :func:`cuda_without_contraction`, the first one under :func:`cache_lock` too."""

    def __init__(self, dispatcher):
        self.dispatcher = dispatcher
        self.launched = False

    def __getitem__(self, launch_configuration):
        launcher = self.dispatcher[launch_configuration]

        def launch(*args):
            with cache_lock() if not self.launched else contextlib.nullcontext(), cuda_without_contraction():
                result = launcher(*args)
            self.launched = True
            return result

        return launch


def _keyed_cuda_cache(function, cache_key):
    """numba-cuda's disk cache for the kernel ``function``, keyed by ``cache_key`` where numba-cuda
    keys a closure by its pickled cells: a cell holding a jitted CPU function pickles with that
    dispatcher's per-process uuid, so numba-cuda's own key would never match in another process
    (and its index would grow by one entry a run). The device functions' source is in the cache
    directory's name (:func:`cache_dir`), the kernel's own bytecode and source stamp in numba-cuda's
    key. A failure to load or save is a recompile, not a failed campaign."""
    import warnings

    from numba.cuda.core import config as cuda_config
    from numba.cuda.dispatcher import CUDACache

    cuda_config.CACHE_DIR = str(cache_dir() / "cuda")
    stable = hashlib.sha256(repr(cache_key).encode()).hexdigest()

    class KeyedCUDACache(CUDACache):
        def _index_key(self, sig, codegen):
            key = super()._index_key(sig, codegen)  # (sig, magic, version, (code, cells), [launch config])
            return (*key[:3], (key[3][0], stable), *key[4:])

        def load_overload(self, sig, target_context):
            try:
                return super().load_overload(sig, target_context)
            except Exception:  # noqa: BLE001 - an unreadable entry is compiled again
                return None

        def save_overload(self, sig, data):
            try:
                super().save_overload(sig, data)
            except Exception as exc:  # noqa: BLE001 - the kernel flies; only the next process recompiles
                warnings.warn(f"the GPU kernel was not cached ({type(exc).__name__}: {exc})", stacklevel=2)

    return KeyedCUDACache(function)


@contextlib.contextmanager
def cuda_without_contraction():
    """numba-cuda compiles with NVVM's default ``-fma=1`` even with fast-math off: a*b + c becomes
    one fused multiply-add, rounded once, where the CPU rounds twice (about 2,100 ``fma.rn.f64`` in
    each family's PTX). While this context is open, numba-cuda's NVVM compilations get ``-fma=0``,
    so the device does each + and * as the CPU does. numba-cuda 0.30 has no public option for it
    (its ``fastmath`` switches -fma on, never off): the option is added where numba-cuda turns its
    options into NVVM's (``numba.cuda.cudadrv.nvvm.compile_ir``). ``make test-cuda`` compiles every
    family's PTX under it and finds no ``fma``, so a numba-cuda that moves this fails there."""
    if CUDA_SIMULATOR:  # the simulator runs Python: nothing is compiled
        yield
        return
    from numba.cuda.cudadrv import nvvm

    compile_ir = nvvm.compile_ir

    def compile_ir_without_fma(llvmir, **options):
        if not options.get("fastmath"):
            options["fma"] = False
        return compile_ir(llvmir, **options)

    with _CUDA_COMPILE_PATCH:
        nvvm.compile_ir = compile_ir_without_fma
        try:
            yield
        finally:
            nvvm.compile_ir = compile_ir


_CUDA_COMPILE_PATCH = threading.RLock()


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
