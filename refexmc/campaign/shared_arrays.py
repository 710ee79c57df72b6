"""Named numpy arrays in one block of memory, which worker processes can attach to.

The GPU backend (refexmc.campaign.cuda_backend) keeps a launch's host arrays here: its workers
write the runs' packed inputs into them and read the launch's outputs from them, so that no run's
tables or ~190 kB of history go through a pickle. A block is an anonymous memory file
(``os.memfd_create``, Linux) when workers use it, private memory when only this process does
(``refexmc run -j 1``): the same :class:`Arrays` either way.

A memory file lives in RAM, not in /dev/shm: a container's /dev/shm (64 MB by default) does not
bound it, and it has no name to leave behind. The process that allocates a block holds it open;
a worker attaches by opening ``/proc/<owner pid>/fd/<fd>`` and maps it (:func:`attached`). The
block is freed when the owner closes it (:meth:`Arrays.release`, or its exit, however it ends)
and the last mapping is gone.
"""

import contextlib
import math
import mmap
import os
from typing import NamedTuple

import numpy as np

_ALIGN = 64  # bytes: every array starts on a cache line
_FD_FOLDER = "/proc/self/fd"  # a worker opens the owner's /proc/<pid>/fd/<fd>


class Handle(NamedTuple):
    """What a worker needs to attach to a block: the path it opens and each array's (name, shape,
    dtype, offset)."""

    path: str | None  # None: private memory (nothing to attach to)
    specs: tuple
    identity: tuple = ()  # (device, inode) of the memory file: a descriptor number can be reused


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
    """Whether worker processes can attach to a block here (Linux: memory files and /proc; elsewhere a
    GPU campaign's host work stays in its own process)."""
    return hasattr(os, "memfd_create") and os.path.isdir(_FD_FOLDER)


def available_bytes():
    """The memory this machine can still give without swapping (Linux's MemAvailable; elsewhere its
    free pages), or None where it cannot say."""
    with contextlib.suppress(OSError, ValueError), open("/proc/meminfo") as meminfo:
        for line in meminfo:
            if line.startswith("MemAvailable:"):
                return int(line.split()[1]) * 1024
    with contextlib.suppress(AttributeError, OSError, ValueError):
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    return None


class Arrays:
    """Arrays ``{name: (shape, dtype)}``, zeroed: in one shared block that workers may attach to,
    or (``shared`` false) numpy's own."""

    def __init__(self, shapes, shared):
        self.specs, size = _layout(shapes)
        self._memory = self._fd = None
        if shared:  # starts zeroed, its pages given as they are first written
            self._fd = os.memfd_create("refexmc-launch", os.MFD_CLOEXEC)
            try:
                os.ftruncate(self._fd, size)
                self._memory = mmap.mmap(self._fd, size)
            except BaseException:
                os.close(self._fd)
                raise
            self.arrays = _views(self._memory, self.specs)
        else:  # numpy's zeros: calloc's pages, as lazy
            self.arrays = {name: np.zeros(shape, dtype=dtype) for name, (shape, dtype) in shapes.items()}

    def __getitem__(self, name):
        return self.arrays[name]

    def handle(self):
        """The :class:`Handle` a worker attaches with (:func:`attached`)."""
        if self._fd is None:
            return Handle(None, self.specs)
        stat = os.fstat(self._fd)
        return Handle(f"/proc/{os.getpid()}/fd/{self._fd}", self.specs, (stat.st_dev, stat.st_ino))

    def release(self):
        """Free the block (shared: close it, so that no worker can attach any more). Views of it
        that live on (a worker's, a thread's still copying) keep their mapping until they are gone:
        nothing is unmapped under them."""
        self.arrays = {}
        if self._fd is not None:
            fd, memory, self._fd, self._memory = self._fd, self._memory, None, None
            os.close(fd)
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
    try:  # the owner's memory file, by its descriptor (not open(): it may be a pipe now, see below)
        fd = os.open(target.path, os.O_RDWR | os.O_CLOEXEC)
    except PermissionError as exc:  # a /proc this process may not read: say so, it is not a release
        raise PermissionError(
            f"{target.path}: cannot open the GPU launch's memory of that process ({exc.strerror}); "
            "fly with -j 1 (the host's work in one process)"
        ) from None
    except OSError as exc:  # released: no such descriptor, or one given to a socket
        raise FileNotFoundError(f"{target.path}: the block was released ({exc.strerror})") from None
    try:
        stat = os.fstat(fd)
        if (stat.st_dev, stat.st_ino) != target.identity:  # released, its number given to another file
            raise FileNotFoundError(f"{target.path}: the block was released")
        memory = mmap.mmap(fd, 0)
    finally:
        os.close(fd)
    arrays = _views(memory, target.specs)
    try:
        yield arrays
    finally:
        arrays.clear()
        with contextlib.suppress(BufferError):  # a view the caller kept: unmapped when it goes
            memory.close()
