"""The kernel cache's lock (issue 37 point 6): two processes compiling two families at once into
one numba cache directory lose or mix up neither family's kernel (``refexmc._jit.cache_lock``)."""

import fcntl
import json
import os
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import numba
import numpy as np
import pytest

from refexmc import _jit, simulate
from refexmc.core import entry_flight as ef
from refexmc.core import flight

ROOT = Path(__file__).resolve().parents[1]

# A family in miniature: a jitted closure over an int, like core.flight's run_flight, so that every
# family has the same signature, one cache index, and an entry of its own keyed by its cell contents.
FAMILY_SOURCE = """
from refexmc._jit import jit


def family_kernel(constant):
    def family(x):
        return x * constant + 1.0

    return jit(family)
"""

# A child compiles family ARGV[1] into the cache, with refexmc's lock (ARGV[3] == "1") or without.
# Instrumented to force the race's interleaving: when its save of the family has read numba's cache
# index (IndexDataCacheFile._load_index inside .save), it waits until the other child has read it too,
# or is blocked on the lock (then waiting would never end). So without the lock both children always
# read the index before either writes it; with the lock the second one reads what the first wrote.
CHILD = """
import fcntl, json, sys, time
from contextlib import nullcontext
from pathlib import Path
from types import SimpleNamespace
import numba
from numba.core import caching
from refexmc import _jit
import race_family

constant, meeting, locked = int(sys.argv[1]), Path(sys.argv[2]), sys.argv[3] == "1"

def mark(what):
    (meeting / f"{what}-{constant}").touch()

def the_other_has(*whats):
    return any(p.name.startswith(whats) and not p.name.endswith(f"-{constant}") for p in meeting.iterdir())

flock = fcntl.flock
def flock_noting_a_wait(fd, operation):
    if operation == fcntl.LOCK_EX:
        try:
            return flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            mark("blocked")
    return flock(fd, operation)
fcntl.flock = flock_noting_a_wait

save, load_index = caching.IndexDataCacheFile.save, caching.IndexDataCacheFile._load_index
def noted_save(self, key, data):
    self.saving = True
    return save(self, key, data)
def load_index_then_meet(self):
    overloads = load_index(self)
    if getattr(self, "saving", False) and ".family-" in self._index_name:
        mark("read")
        deadline = time.monotonic() + 120.0  # a bound only: the other child reads or blocks long before
        while not the_other_has("read", "blocked") and time.monotonic() < deadline:
            time.sleep(0.01)
    return overloads
caching.IndexDataCacheFile.save, caching.IndexDataCacheFile._load_index = noted_save, load_index_then_meet

kernel = race_family.family_kernel(constant)
mark("started")
while not the_other_has("started"):  # both children compile at the same moment
    time.sleep(0.01)
with _jit.cache_lock() if locked else nullcontext():
    kernel.compile((numba.float64,))
print(json.dumps({"misses": sum(kernel.stats.cache_misses.values()), "value": kernel(2.0)}))
"""

# A third process: each family's kernel from the cache, and what it computes.
READER = """
import json, sys
import numba
import race_family

found = {}
for constant in map(int, sys.argv[1:]):
    kernel = race_family.family_kernel(constant)
    kernel.compile((numba.float64,))
    found[constant] = {"hits": sum(kernel.stats.cache_hits.values()), "value": kernel(2.0)}
print(json.dumps(found))
"""


def _python(code, args, tmp_path):
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "cache"), PYTHONPATH=str(tmp_path))
    env.pop("REFEXMC_DISABLE_JIT", None)
    return subprocess.Popen(
        [sys.executable, "-c", code, *args],
        cwd=ROOT,
        env=env,
        text=True,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )


def _result(process):
    stdout, stderr = process.communicate(timeout=300)
    assert process.returncode == 0, stderr
    return json.loads(stdout.strip().splitlines()[-1])


def compile_two_families_at_once(tmp_path, locked):
    """Two children compile families 3 and 5 into a fresh cache at once; then a third process loads
    both. Returns {family: {"hits": cache hits, "value": kernel(2.0)}} as the third process found them."""
    (tmp_path / "race_family.py").write_text(FAMILY_SOURCE)
    meeting = tmp_path / "meeting"
    meeting.mkdir()
    children = [_python(CHILD, [str(c), str(meeting), "1" if locked else "0"], tmp_path) for c in (3, 5)]
    for constant, child in zip((3, 5), children, strict=True):
        compiled = _result(child)
        assert compiled == {"misses": 1, "value": 2.0 * constant + 1.0}  # each child compiled its own family
    names = {p.name.split("-")[0] for p in meeting.iterdir()}
    assert "read" in names  # the instrumented save ran: the test saw the index being read
    found = _result(_python(READER, ["3", "5"], tmp_path))
    return {int(c): v for c, v in found.items()}


def test_two_families_compiled_at_once_are_both_found_in_the_cache(tmp_path):
    found = compile_two_families_at_once(tmp_path, locked=True)
    for constant in (3, 5):
        assert found[constant] == {"hits": 1, "value": 2.0 * constant + 1.0}, found


def test_without_the_lock_the_forced_interleaving_loses_a_family(tmp_path):
    """The check above can fail: without the lock the same two compiles leave one family out of the
    cache (its index entry overwritten), or a family's key naming the other one's kernel."""
    found = compile_two_families_at_once(tmp_path, locked=False)
    lost = [c for c in (3, 5) if found[c]["hits"] == 0]
    mixed = [c for c in (3, 5) if found[c]["value"] != 2.0 * c + 1.0]
    assert lost or mixed, found


def _lock_is_held():
    """True while some open file description holds the cache's flock (ours, here)."""
    fd = os.open(Path(numba.config.CACHE_DIR) / _jit._CACHE_LOCK_NAME, os.O_RDWR | os.O_CREAT)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        return True
    finally:
        os.close(fd)
    return False


class _Kernel:
    """A family kernel that is not compiled yet and records whether the lock was held when it was."""

    def __init__(self):
        self.signatures, self.locked = [], []

    def compile(self, _types):
        self.locked.append(_lock_is_held())
        self.signatures.append("compiled")

    def __call__(self, *args):
        pass


@pytest.mark.skipif(_jit.DISABLED, reason="no cache and no lock with REFEXMC_DISABLE_JIT")
def test_a_family_kernel_is_compiled_holding_the_lock_and_the_lock_is_reentrant(tmp_path, monkeypatch, inputs):
    monkeypatch.setattr(numba.config, "CACHE_DIR", str(tmp_path))
    kernel = _Kernel()
    monkeypatch.setattr(flight, "kernel_parts", lambda *family: SimpleNamespace(fly_run=kernel, run_flight=kernel))
    monkeypatch.setattr(simulate, "keyed_uniforms", lambda *args: None)  # loaded too; not what is checked here
    monkeypatch.setattr(simulate, "keyed_uniforms_for_runs", lambda *args: None)
    simulate.load_kernels([(0, 0, 0, 0)])
    assert kernel.locked == [True]
    assert not _lock_is_held()  # released after
    held = []  # the entry kernel's first compile (a flight that ends at once) likewise
    monkeypatch.setattr(ef, "fly", _Kernel())
    monkeypatch.setattr(simulate, "fly_entry", lambda flown, initial: held.append(_lock_is_held()))
    simulate.load_entry_kernel(SimpleNamespace(control=np.ones(ef.CT_MAX_TIME_S + 1)), None)
    assert held == [True]
    with _jit.cache_lock(), _jit.cache_lock():  # nested (fly's first flight calls load_kernels): no self-deadlock
        assert _lock_is_held()
    assert not _lock_is_held()
