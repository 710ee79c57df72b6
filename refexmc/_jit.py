"""The one place where JIT options are set.

Every kernel in ``refexmc.core`` is decorated with :func:`jit`. Compiled code is cached on
disk (``cache=True``) so that a new process starts without recompiling; ``fastmath`` stays off
so that results are bit-for-bit reproducible. ``REFEXMC_DISABLE_JIT=1`` runs the kernels as
plain Python (slow; for debugging and coverage).
"""

import os

import numba

JIT_OPTIONS = {"cache": True, "fastmath": False, "nogil": True, "error_model": "numpy"}
DISABLED = os.environ.get("REFEXMC_DISABLE_JIT", "0") not in ("", "0")


def jit(function):
    """Compile ``function`` with refexmc's JIT options (or leave it as Python if disabled)."""
    if DISABLED:
        return function
    return numba.njit(**JIT_OPTIONS)(function)
