"""One writer per output directory: an exclusive lock on OUT for `run`, `--resume` and `--overwrite`.

The lock is the file ``OUT/.refexmc.lock``: an advisory ``flock`` on it, which the kernel releases
however its holder ends (even SIGKILL), and the holder's pid, host and start time written in it for
the messages. It lives inside OUT, so that ``--overwrite`` holds it while it replaces the rest of
OUT, and it is removed when the writer is done (unlinked while still locked: a process that opened
the old file meanwhile sees that the path no longer names it and tries again).

A lock file whose flock is free was left by a writer that was killed: it is taken over, with a
message, when its holder is a process of this host (gone, or another process under a reused pid).
One written on another host is refused: its process cannot be checked from here, and on a file
system without working locks between hosts it may still be running.
"""

import fcntl
import json
import os
import socket
from contextlib import contextmanager, suppress
from pathlib import Path

from refexmc.campaign import storage
from refexmc.config.errors import ConfigError

LOCK_NAME = storage.LOCK_NAME
_ATTEMPTS = 5  # a lock that changes hands this often while we look is reported as in use


def _read(fd):
    """The holder's record (dict) in the open lock file, {} when empty or unreadable."""
    data = os.pread(fd, 4096, 0)
    try:
        holder = json.loads(data.decode())
    except (UnicodeDecodeError, json.JSONDecodeError):
        return {}
    return holder if isinstance(holder, dict) else {}


def _describe(holder):
    if not holder:
        return "another process"
    return f"pid {holder.get('pid')} on host {holder.get('host')} (since {holder.get('started')})"


def _in_use(path, holder):
    return ConfigError(
        f"in use by another refexmc run: {_describe(holder)}; wait for it to finish or choose another -o",
        file=path,
    )


def _pid_alive(pid):
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def holder(out):
    """The record of the process holding OUT's lock, or None when OUT is not locked. Writes nothing."""
    path = Path(out) / LOCK_NAME
    try:
        fd = os.open(path, os.O_RDONLY)
    except (FileNotFoundError, NotADirectoryError):
        return None
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
        except BlockingIOError:
            return _read(fd)
        return None
    finally:
        os.close(fd)


def check_free(out):
    """ConfigError (naming the holder) when another process holds OUT's lock. Writes nothing."""
    record = holder(out)
    if record is not None:
        raise _in_use(Path(out) / LOCK_NAME, record)


def _same_file(fd, path):
    try:
        return os.path.samestat(os.fstat(fd), os.stat(path))
    except FileNotFoundError:
        return False


def acquire(out, notify):
    """Take OUT's lock (OUT must exist); return its file descriptor. ConfigError when another writer holds it.

    ``notify(message)`` is told when a stale lock of a killed writer is taken over.
    """
    path = Path(out) / LOCK_NAME
    for _ in range(_ATTEMPTS):
        fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            record = _read(fd)
            os.close(fd)
            raise _in_use(path, record) from None
        except BaseException:
            os.close(fd)
            raise
        if not _same_file(fd, path):  # its holder removed it after we opened it: look again
            os.close(fd)
            continue
        try:
            _take(fd, path, notify)
        except BaseException:
            os.close(fd)
            raise
        return fd
    raise _in_use(path, {})


def _take(fd, path, notify):
    """Write this process's record into the lock file, after checking what a killed writer left in it."""
    stale = _read(fd)
    here = socket.gethostname()
    if stale:
        if stale.get("host") != here:
            raise ConfigError(
                f"locked by {_describe(stale)}, which cannot be checked from this host; "
                f"if that run is over, remove {path} and run again",
                file=path,
            )
        gone = not isinstance(stale.get("pid"), int) or not _pid_alive(stale["pid"])
        why = "that process is gone" if gone else "that pid is now another process, which does not hold the lock"
        notify(f"{path}: taking over the lock left by {_describe(stale)}: {why}")
    record = {"pid": os.getpid(), "host": here, "started": storage.now()}
    os.ftruncate(fd, 0)
    os.pwrite(fd, (json.dumps(record) + "\n").encode(), 0)


def release(out, fd):
    """Remove OUT's lock file and release the lock."""
    with suppress(FileNotFoundError):
        os.unlink(Path(out) / LOCK_NAME)
    os.close(fd)


@contextmanager
def locked(out, notify):
    """Hold OUT's lock (OUT is created if missing) for the body of the ``with``."""
    Path(out).mkdir(parents=True, exist_ok=True)
    fd = acquire(out, notify)
    try:
        yield
    finally:
        release(out, fd)
