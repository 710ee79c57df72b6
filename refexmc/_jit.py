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


# --- the kernel cache's locks (issue 37 point 6) --------------------------------------------
# Numba's cache keeps one index file per function (``<name>-<line>.pyXY.nbi``: a pickled dict from
# signature, CPU and closure-cell hash to a data file ``<name>-<line>.pyXY.<n>.nbc``). Saving a
# compiled kernel loads the index, picks the first free ``n``, writes the index, then the data
# (``IndexDataCacheFile.save`` in ``numba/core/caching.py``); each file is replaced atomically, but
# nothing orders two processes. Two processes saving two families at once both read the same index
# and both pick ``n = 1`` for their own family's ``fly_run`` (one function, keyed by its closure):
# the index written last loses the other family's entry, and the data file written last may hold
# the other family's kernel under this family's key (a third process loading it would fly the
# wrong family). A load between a save's index and its data reads a data file that is not there
# yet, or an older one of the same name (the index of an edited source starts again at ``n = 1``).
# ``tests/test_cache_lock.py`` forces these interleavings. Hence two locks, both ``flock``s that
# the kernel releases however their holder ends:
# - :func:`cache_files_lock`: ``cache.lock`` in the directory of the index, held by every read and
#   write of numba's cache files (:func:`guard_cache_files` wraps numba's ``IndexDataCacheFile``),
#   milliseconds at a time: saves never interleave, and a load sees a save whole or not at all;
# - :func:`compile_lock`: ``compile-<name>.lock``, held by a family's compile (seconds to minutes):
#   a second process that needs the same family waits and then loads it; other families compile
#   or load meanwhile.

CACHE_FILES_LOCK_NAME = "cache.lock"


class _FileLock:
    """An exclusive ``flock`` on one file, re-entrant within a process (its threads take turns).
    Where the file cannot be opened (a cache directory that cannot be written) nothing is locked:
    numba caches nothing there either."""

    def __init__(self, path):
        self.path = path
        self._thread = threading.RLock()
        self._depth = 0
        self._fd = None

    @contextlib.contextmanager
    def held(self):
        with self._thread:
            if self._depth == 0:
                self._fd = _locked_descriptor(self.path)
            self._depth += 1
            try:
                yield
            finally:
                self._depth -= 1
                if self._depth == 0 and self._fd is not None:
                    os.close(self._fd)  # closing the file releases the flock
                    self._fd = None


def _locked_descriptor(path):
    try:
        fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o666)
    except OSError:
        return None
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
    except OSError:
        os.close(fd)
        return None
    return fd


_file_locks = {}
_file_locks_guard = threading.Lock()


def _file_lock(path):
    with _file_locks_guard:
        return _file_locks.setdefault(str(path), _FileLock(str(path)))


def cache_files_lock(directory):
    """Hold the lock on the numba cache files in ``directory`` (see above)."""
    return _file_lock(Path(directory) / CACHE_FILES_LOCK_NAME).held()


def compile_lock(name):
    """Hold the lock on compiling ``name`` (a family's kernel; see above) into the kernel cache:
    one process compiles it, the others that need it wait and then load it from the cache. Held by
    ``simulate.load_kernels`` (which a family's first ``fly`` in a process calls too),
    ``simulate.load_entry_kernel`` and a GPU kernel's first launch. No lock where the JIT is
    disabled."""
    if DISABLED:
        return contextlib.nullcontext()
    directory = Path(numba.config.CACHE_DIR)
    with contextlib.suppress(OSError):
        directory.mkdir(parents=True, exist_ok=True)
    return _file_lock(directory / f"compile-{name}.lock").held()


def guard_cache_files(caching):
    """Every read and write of ``caching.IndexDataCacheFile`` (numba's ``numba.core.caching``, or
    numba-cuda's ``numba.cuda.core.caching``) under :func:`cache_files_lock` of its directory. Its
    unguarded methods stay as ``unguarded_save`` and ``unguarded_load`` (the tests' control)."""
    files = caching.IndexDataCacheFile
    if "unguarded_save" in vars(files):
        return
    files.unguarded_save, files.unguarded_load = files.save, files.load

    def save(self, key, data):
        with cache_files_lock(self._cache_path):
            return files.unguarded_save(self, key, data)

    def load(self, key):
        with cache_files_lock(self._cache_path):
            return files.unguarded_load(self, key)

    files.save, files.load = save, load


if not DISABLED:
    from numba.core import caching as _numba_caching

    guard_cache_files(_numba_caching)


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
    compiles or loads it, holds its :func:`compile_lock`."""
    from numba import cuda

    dispatcher = cuda.jit(fastmath=False)(function)
    name = "cuda"
    if cache_key is not None and not CUDA_SIMULATOR:
        dispatcher._cache = _keyed_cuda_cache(function, cache_key)
        name = f"cuda-{_cuda_cache_key(cache_key)[:16]}"
    return _UncontractedKernel(dispatcher, name)


class _UncontractedKernel:
    """A numba-cuda kernel whose launches (the first one compiles it) run under
    :func:`cuda_without_contraction`, the first one under its :func:`compile_lock` too."""

    def __init__(self, dispatcher, name):
        self.dispatcher = dispatcher
        self.name = name
        self.launched = False

    def __getitem__(self, launch_configuration):
        launcher = self.dispatcher[launch_configuration]

        def launch(*args):
            first = compile_lock(self.name) if not self.launched else contextlib.nullcontext()
            with first, cuda_without_contraction():
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

    from numba.cuda.core import caching as cuda_caching
    from numba.cuda.core import config as cuda_config
    from numba.cuda.dispatcher import CUDACache

    guard_cache_files(cuda_caching)
    cuda_config.CACHE_DIR = str(cache_dir() / "cuda")
    stable = _cuda_cache_key(cache_key)

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


def _cuda_cache_key(cache_key):
    return hashlib.sha256(repr(cache_key).encode()).hexdigest()


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
