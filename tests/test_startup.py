"""Start-up of `refexmc run` (issue 15): workers warm up while the parent prepares the campaign,
and no worker outlives a campaign that was refused after they started."""

import os
import subprocess
import sys
import uuid
from pathlib import Path

import pytest

from refexmc import _jit, simulate
from refexmc.campaign import run as run_module
from refexmc.campaign import storage
from refexmc.config.errors import ConfigError

ROOT = Path(__file__).resolve().parents[1]
NOMINAL = ROOT / "campaigns/nominal.yaml"

needs_proc = pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads processes from /proc")


def loky_workers(marker=None, parent=None):
    """pids of the live loky worker processes of ``parent``, or whose environment holds ``marker``."""
    found = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            state, ppid = (entry / "stat").read_text().rsplit(")", 1)[1].split()[:2]
            command, environment = (entry / "cmdline").read_bytes(), (entry / "environ").read_bytes()
        except OSError:  # gone meanwhile
            continue
        if state == "Z" or b"popen_loky_posix" not in command:
            continue
        if (parent is not None and int(ppid) == parent) or (marker is not None and marker.encode() in environment):
            found.append(int(entry.name))
    return found


@pytest.mark.skipif(_jit.DISABLED, reason="REFEXMC_DISABLE_JIT=1: no kernels")
def test_the_plan_loads_its_family_kernel_from_the_cache_and_the_first_flight_adds_nothing(inputs):
    """A worker warms up without the campaign (no flight kernel), then its plan loads the kernel
    of the campaign's vehicle family by signature from the disk cache (a hit, no compile) and no
    other family's; the first flight needs nothing more."""
    simulate.fly(inputs)  # now in the disk cache, if it was not
    script = f"""
from refexmc import simulate
from refexmc.campaign import worker
from refexmc.config.load import load_mission, load_vehicle
from refexmc.config.pack import pack

worker.warm_up()
print(len(simulate.flight.kernels()))
configs = {str(ROOT / "configs")!r}
inputs = pack(load_vehicle(configs + "/vehicles/refex.yaml"), load_mission(configs + "/missions/refex-exo.yaml"))
simulate.load_kernels([simulate.flight_family(inputs)])
(run_flight,) = simulate.flight.kernels().values()
stats = run_flight.stats
print(sum(stats.cache_hits.values()), sum(stats.cache_misses.values()), len(run_flight.signatures))
simulate.fly(inputs)
print(sum(stats.cache_misses.values()), len(run_flight.signatures), len(simulate.flight.kernels()))
"""
    lines = subprocess.run(
        [sys.executable, "-c", script], cwd=ROOT, capture_output=True, text=True, check=True
    ).stdout.splitlines()
    assert lines == ["0", "1 0 1", "0 1 1"]  # loaded, not compiled; the flight then needs no other signature


@needs_proc
def test_a_refusal_after_the_workers_started_leaves_no_worker_running(tmp_path, monkeypatch):
    started = []

    def refuse(*args, **kwargs):
        started.extend(loky_workers(parent=os.getpid()))
        raise ConfigError("refused after the workers started", file=tmp_path)

    monkeypatch.setattr(storage, "prepare_output", refuse)
    with pytest.raises(ConfigError, match="refused after the workers started"):
        run_module.run_campaign(NOMINAL, out=tmp_path / "out", jobs=1)
    assert started  # the refusal came after the workers had started
    assert not set(started) & set(loky_workers(parent=os.getpid()))
    assert list((tmp_path / "out").iterdir()) == []  # the lock is gone, nothing was written


@needs_proc
def test_cli_refusal_with_a_worker_started_exits_2_with_one_message_and_no_worker_left(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "notes.txt").write_text("not a refexmc output\n")
    marker = f"refexmc-test-{uuid.uuid4()}"
    command = [sys.executable, "-m", "refexmc.cli", "run", str(NOMINAL), "-o", str(out), "-j", "1", "--no-progress"]
    env = {**os.environ, "REFEXMC_TEST_MARKER": marker}
    result = subprocess.run(command, cwd=ROOT, capture_output=True, text=True, env=env)
    assert result.returncode == 2
    assert result.stderr.splitlines() == [
        f"error: {out}: output directory exists; use --resume to finish it or --overwrite to replace it"
    ]
    assert loky_workers(marker=marker) == []
    assert sorted(p.name for p in out.iterdir()) == ["notes.txt"]


def test_the_resource_trackers_shutdown_warnings_stay_off_the_error_message(monkeypatch):
    """loky's resource tracker inherits the environment the pool sets: its warning about semaphores
    of an executor killed while starting (CI saw it after a bad-input message) is ignored, other
    warnings and the user's own PYTHONWARNINGS are kept."""
    from refexmc.campaign import pool

    monkeypatch.setenv("PYTHONWARNINGS", "error::DeprecationWarning")
    pool._quiet_resource_tracker()
    pool._quiet_resource_tracker()  # once only
    assert os.environ["PYTHONWARNINGS"] == f"error::DeprecationWarning,{pool.QUIET_RESOURCE_TRACKER}"
    script = (
        "import warnings\n"
        "warnings.warn('resource_tracker: There appear to be 1 leaked semlock objects to clean up at shutdown')\n"
        "warnings.warn('another warning')\n"
    )
    result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=dict(os.environ))
    assert "resource_tracker" not in result.stderr
    assert "another warning" in result.stderr
