"""Named numpy arrays in one block of memory, which worker processes can attach to by name.

The GPU backend (refexmc.campaign.cuda_backend) keeps a launch's host arrays here: its workers
write the runs' packed inputs into them and read the launch's outputs from them, so that no run's
tables or ~190 kB of history go through a pickle. A block is POSIX shared memory
(``multiprocessing.shared_memory``, /dev/shm on Linux) when workers use it, private memory when
only this process does (``refexmc run -j 1``): the same :class:`Arrays` either way.

The process that allocates a block owns it: :meth:`Arrays.release` unlinks it, and Python's
resource tracker unlinks it if that process dies first. A worker that attaches maps the block's
file and owns nothing (:func:`attached`).
"""

import contextlib
import math
import mmap
import os
import secrets
import shutil
from multiprocessing import shared_memory
from typing import NamedTuple

import numpy as np

_ALIGN = 64  # bytes: every array starts on a cache line
SHARED_FOLDER = "/dev/shm"  # where Linux keeps POSIX shared memory (its free space bounds a block)
NAME_PREFIX = "refexmc-"  # a block's name: refexmc-<pid of its owner>-<random>


class Handle(NamedTuple):
    """What a worker needs to attach to a block: its name and each array's (name, shape, dtype, offset)."""

    name: str | None  # None: private memory (nothing to attach to)
    specs: tuple


def _layout(shapes):
    """(specs, total bytes) of arrays ``{name: (shape, dtype)}`` laid out one after the other."""
    specs, offset = [], 0
    for name, (shape, dtype) in shapes.items():
        dtype = np.dtype(dtype)
        specs.append((name, tuple(int(n) for n in shape), dtype.str, offset))
        size = math.prod(shape) * dtype.itemsize
        offset += -(-size // _ALIGN) * _ALIGN
    return tuple(specs), max(offset, 1)


def shareable():
    """Whether worker processes can attach to a block here (Linux: POSIX shared memory is a file
    in /dev/shm; elsewhere a GPU campaign's host work stays in its own process)."""
    return os.path.isdir(SHARED_FOLDER) and os.access(SHARED_FOLDER, os.W_OK)


def shared_free_bytes():
    """Free bytes for shared memory on this machine (0 where there is no /dev/shm)."""
    try:
        return shutil.disk_usage(SHARED_FOLDER).free
    except OSError:
        return 0


class Arrays:
    """Arrays ``{name: (shape, dtype)}``, zeroed: in one shared block that workers may attach to,
    or (``shared`` false) numpy's own."""

    def __init__(self, shapes, shared):
        self.specs, size = _layout(shapes)
        self._memory = None
        if shared:  # starts zeroed, its pages given as they are first written
            name = f"{NAME_PREFIX}{os.getpid()}-{secrets.token_hex(4)}"  # whose it is, in /dev/shm
            self._memory = shared_memory.SharedMemory(name=name, create=True, size=size)
            self.arrays = _views(self._memory.buf, self.specs)
        else:  # numpy's zeros: calloc's pages, as lazy
            self.arrays = {name: np.zeros(shape, dtype=dtype) for name, (shape, dtype) in shapes.items()}

    def __getitem__(self, name):
        return self.arrays[name]

    def handle(self):
        """The :class:`Handle` a worker attaches with (:func:`attached`)."""
        return Handle(self._memory.name if self._memory is not None else None, self.specs)

    def release(self):
        """Free the block (shared: unlink its name). Views of it that live on (a worker's, a thread's
        still copying) keep their mapping until they are gone: nothing is unmapped under them."""
        self.arrays = {}
        if self._memory is not None:
            memory, self._memory = self._memory, None
            memory.unlink()
            with contextlib.suppress(BufferError):  # views still exported: unmapped when they go
                memory.close()


def _views(buffer, specs):
    """The arrays of ``specs`` in ``buffer``; an empty one is numpy's own (its strides are numpy's
    zeros, as a device array's, not those a view of a buffer computes)."""
    return {
        name: np.ndarray(shape, dtype=np.dtype(dtype), buffer=buffer, offset=offset)
        if math.prod(shape)
        else np.zeros(shape, dtype=np.dtype(dtype))
        for name, shape, dtype, offset in specs
    }


@contextlib.contextmanager
def attached(target):
    """The arrays of ``target`` (:class:`Arrays` in this process, or a shared block's
    :class:`Handle`), by name, while the ``with`` lasts."""
    if isinstance(target, Arrays):
        yield target.arrays
        return
    # mapped as the file Linux keeps it in, not through SharedMemory: Python < 3.13 registers every
    # attach with the resource tracker, which then unlinks the block when this process exits or
    # warns of a block unlinked twice (a loky worker may share its parent's tracker, or not)
    with open(os.path.join(SHARED_FOLDER, target.name.lstrip("/")), "r+b") as file:
        memory = mmap.mmap(file.fileno(), 0)
    arrays = _views(memory, target.specs)
    try:
        yield arrays
    finally:
        arrays.clear()
        with contextlib.suppress(BufferError):  # a view the caller kept: unmapped when it goes
            memory.close()
