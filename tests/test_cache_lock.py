"""The kernel cache's locks (issue 37 point 6, ``refexmc._jit``): two processes compiling two
families at once into one numba cache directory lose or mix up neither family's kernel, a load
never reads a save half done (``cache_files_lock`` around numba's cache files), and a process
waits for another's compile only when it needs the same family (``compile_lock``)."""

import fcntl
import json
import os
import subprocess
import sys
import threading
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

# What the children below begin with: refexmc's lock on numba's cache files (ARGV[3] == "1") or numba's
# own unguarded files, and a meeting directory where each marks what it did ("<what>-<ARGV[4]>").
PRELUDE = """
import fcntl, json, sys, time
from pathlib import Path
import numba
from numba.core import caching
from refexmc import _jit
import race_family

constant, meeting, locked, who = int(sys.argv[1]), Path(sys.argv[2]), sys.argv[3] == "1", sys.argv[4]
if not locked:
    caching.IndexDataCacheFile.save = caching.IndexDataCacheFile.unguarded_save
    caching.IndexDataCacheFile.load = caching.IndexDataCacheFile.unguarded_load

def mark(what):
    (meeting / f"{what}-{who}").touch()

def the_other_has(*whats):
    return any(p.name.startswith(whats) and not p.name.endswith(f"-{who}") for p in meeting.iterdir())

def wait_for_the_other(*whats):
    deadline = time.monotonic() + 120.0  # a bound only: the other child gets there long before
    while not the_other_has(*whats) and time.monotonic() < deadline:
        time.sleep(0.01)

flock = fcntl.flock
def flock_noting_a_wait(fd, operation):
    if operation == fcntl.LOCK_EX:
        try:
            return flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            mark("blocked")
    return flock(fd, operation)
fcntl.flock = flock_noting_a_wait
"""

# A child compiles family ARGV[1] into the cache. Instrumented to force the race's interleaving: when
# its save of the family has read numba's cache index (IndexDataCacheFile._load_index inside .save),
# it waits until the other child has read it too, or is blocked on the lock (then waiting would never
# end). So without the lock both children always read the index before either writes it; with the
# lock the second one reads what the first wrote.
CHILD = """
save, load_index = caching.IndexDataCacheFile.save, caching.IndexDataCacheFile._load_index
def noted_save(self, key, data):
    self.saving = True
    return save(self, key, data)
def load_index_then_meet(self):
    overloads = load_index(self)
    if getattr(self, "saving", False) and ".family-" in self._index_name:
        mark("read")
        wait_for_the_other("read", "blocked")
    return overloads
caching.IndexDataCacheFile.save, caching.IndexDataCacheFile._load_index = noted_save, load_index_then_meet

kernel = race_family.family_kernel(constant)
mark("started")
wait_for_the_other("started")  # both children compile at the same moment
kernel.compile((numba.float64,))
print(json.dumps({"misses": sum(kernel.stats.cache_misses.values()), "value": kernel(2.0)}))
"""

# A child saves family ARGV[1] and, between writing the index and writing the data file, waits until
# the other child (LOADER) has loaded the family, or is blocked on the lock.
SAVER = """
save_index, save_data = caching.IndexDataCacheFile._save_index, caching.IndexDataCacheFile._save_data
def save_index_noted(self, overloads):
    save_index(self, overloads)
    if ".family-" in self._index_name:
        mark("indexed")
def save_data_after_meeting(self, name, data):
    if ".family-" in self._index_name:
        wait_for_the_other("loaded", "blocked")
    return save_data(self, name, data)
caching.IndexDataCacheFile._save_index = save_index_noted
caching.IndexDataCacheFile._save_data = save_data_after_meeting

kernel = race_family.family_kernel(constant)
kernel.compile((numba.float64,))
print(json.dumps({"misses": sum(kernel.stats.cache_misses.values()), "value": kernel(2.0)}))
"""

# A child loads family ARGV[1] as soon as the SAVER has written its index.
LOADER = """
kernel = race_family.family_kernel(constant)
wait_for_the_other("indexed")
kernel.compile((numba.float64,))
mark("loaded")
print(json.dumps({"hits": sum(kernel.stats.cache_hits.values()), "value": kernel(2.0)}))
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
    flag = "1" if locked else "0"
    children = [_python(PRELUDE + CHILD, [str(c), str(meeting), flag, str(c)], tmp_path) for c in (3, 5)]
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


def load_during_a_save(tmp_path, locked):
    """Family 7 compiled into the cache, then the family's source edited (numba's index of the new
    source starts again at data file 1, over family 7's), then family 3 saved by one child while
    another loads it between the save's index and its data. Returns what the loader found."""
    (tmp_path / "race_family.py").write_text(FAMILY_SOURCE)
    assert _result(_python(READER, ["7"], tmp_path))["7"] == {"hits": 0, "value": 15.0}
    (tmp_path / "race_family.py").write_text(FAMILY_SOURCE + "# edited\n")  # same lines, another stamp
    meeting = tmp_path / "meeting"
    meeting.mkdir()
    flag = "1" if locked else "0"
    saver = _python(PRELUDE + SAVER, ["3", str(meeting), flag, "saver"], tmp_path)
    loader = _python(PRELUDE + LOADER, ["3", str(meeting), flag, "loader"], tmp_path)
    assert _result(saver) == {"misses": 1, "value": 7.0}
    return _result(loader)


def test_a_load_during_a_save_waits_for_the_save_whole(tmp_path):
    assert load_during_a_save(tmp_path, locked=True) == {"hits": 1, "value": 7.0}


def test_without_the_lock_a_load_during_a_save_flies_an_older_kernel(tmp_path):
    """The check above can fail: unguarded, the loader reads the new index's entry and the data file
    it names before the save has written it, which still holds family 7's kernel."""
    assert load_during_a_save(tmp_path, locked=False) == {"hits": 1, "value": 15.0}


def _is_held(path):
    """True while some open file description holds the flock on ``path`` (ours, here)."""
    fd = os.open(path, os.O_RDWR | os.O_CREAT)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        return True
    finally:
        os.close(fd)
    return False


def _compile_lock_path(family):
    return Path(numba.config.CACHE_DIR) / ("compile-flight-" + "-".join(map(str, family)) + ".lock")


def _cache_files_held():
    return _is_held(Path(numba.config.CACHE_DIR) / _jit.CACHE_FILES_LOCK_NAME)


class _Kernel:
    """A family kernel that is not compiled yet and records, when it is, whether its compile lock
    and the cache files' lock were held."""

    def __init__(self, family=(0, 0, 0, 0)):
        self.family, self.signatures, self.locked = family, [], []

    def compile(self, _types):
        self.locked.append((_is_held(_compile_lock_path(self.family)), _cache_files_held()))
        self.signatures.append("compiled")

    def __call__(self, *args):
        pass


@pytest.fixture
def fake_families(tmp_path, monkeypatch):
    """simulate.load_kernels over :class:`_Kernel` families in a cache directory of the test's own."""
    monkeypatch.setattr(numba.config, "CACHE_DIR", str(tmp_path))
    kernels = {}

    def parts(*family):
        kernel = kernels.setdefault(family, _Kernel(family))
        return SimpleNamespace(fly_run=kernel, run_flight=kernel)

    monkeypatch.setattr(flight, "kernel_parts", parts)
    monkeypatch.setattr(simulate, "_keyed_uniforms_loaded", True)  # not what is checked here
    return kernels


@pytest.mark.skipif(_jit.DISABLED, reason="no cache and no lock with REFEXMC_DISABLE_JIT")
def test_a_family_kernel_is_compiled_holding_its_lock_and_the_lock_is_reentrant(fake_families, monkeypatch):
    simulate.load_kernels([(0, 0, 0, 0)])
    # its family's compile lock, not the cache files' (another process loads what it needs meanwhile)
    assert fake_families[(0, 0, 0, 0)].locked == [(True, False)]
    assert not _is_held(_compile_lock_path((0, 0, 0, 0)))  # released after
    held = []  # the entry kernel's first compile (a flight that ends at once) likewise
    monkeypatch.setattr(ef, "fly", _Kernel())
    entry_lock = Path(numba.config.CACHE_DIR) / "compile-entry.lock"
    monkeypatch.setattr(simulate, "fly_entry", lambda flown, initial: held.append(_is_held(entry_lock)))
    simulate.load_entry_kernel(SimpleNamespace(control=np.ones(ef.CT_MAX_TIME_S + 1)), None)
    assert held == [True]
    with _jit.compile_lock("x"), _jit.compile_lock("x"):  # nested (fly's first flight calls load_kernels)
        assert _is_held(Path(numba.config.CACHE_DIR) / "compile-x.lock")
    assert not _is_held(Path(numba.config.CACHE_DIR) / "compile-x.lock")


@pytest.mark.skipif(_jit.DISABLED, reason="no cache and no lock with REFEXMC_DISABLE_JIT")
def test_a_compile_waits_only_for_the_same_familys_compile(fake_families):
    """Another process compiling family A (its lock held on a description of its own): loading
    family B goes on at once; loading family A waits until that compile ends."""
    a, b = (0, 0, 0, 0), (1, 0, 0, 0)
    other = os.open(_compile_lock_path(a), os.O_RDWR | os.O_CREAT)
    fcntl.flock(other, fcntl.LOCK_EX)
    try:
        other_family = threading.Thread(target=simulate.load_kernels, args=([b],), daemon=True)
        other_family.start()
        other_family.join(30.0)  # a bound only: it does not wait for A's compile
        assert not other_family.is_alive() and fake_families[b].signatures == ["compiled"]
        waiting = threading.Thread(target=simulate.load_kernels, args=([a],), daemon=True)
        waiting.start()
        waiting.join(0.5)
        assert waiting.is_alive() and fake_families[a].signatures == []
    finally:
        os.close(other)  # the other process's compile ends
    waiting.join(30.0)
    assert not waiting.is_alive() and fake_families[a].signatures == ["compiled"]
