"""The Dask backend: same runs table as loky on a real LocalCluster (worker processes), a worker
killed mid-campaign costs no run, a hung or crashing run is one error row, bad options and a
missing extra are bad input. The recovery logic itself is also driven by a fake client.

Most tests share one LocalCluster of 2 worker processes (one thread each) whose scheduler gives a
task up after its second worker died (``allowed-failures`` 1, default 3), to keep crashes short.
"""

import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path
from types import SimpleNamespace

import pandas as pd
import pyarrow.parquet as pq
import pytest

distributed = pytest.importorskip("distributed")
import dask  # noqa: E402 - after the skip: the extra is optional
from stored import campaign_copy, invoke_run, read_runs  # noqa: E402

from refexmc.campaign import dask_backend  # noqa: E402
from refexmc.campaign import run as run_module  # noqa: E402
from refexmc.campaign.run import resolve_campaign, run_campaign  # noqa: E402
from refexmc.campaign.worker import TEST_CRASH_ENV, TEST_HANG_ENV, Flown, Guard  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
SMOKE = ROOT / "campaigns/smoke.yaml"  # dispersed (LHS): every row differs


def smoke_file(tmp_path, **extra):
    return campaign_copy("smoke.yaml", tmp_path, **extra)


def histories(out):
    table = pq.read_table(Path(out) / "histories").to_pandas()
    return table.sort_values(["run_id", "t_s"], ignore_index=True)


def parts(out):
    return sorted(p.name for p in (Path(out) / "runs").glob("part-*.parquet")) if (Path(out) / "runs").is_dir() else []


def child_pids():
    """This process's children but multiprocessing's resource tracker (it lives as long as this process)."""
    import psutil  # a dependency of distributed

    def counted(process):
        try:
            return not any("resource_tracker" in part for part in process.cmdline())
        except psutil.Error:  # gone meanwhile
            return False

    return {p.pid for p in psutil.Process().children(recursive=True) if counted(p)}


@pytest.fixture(scope="module")
def cluster():
    with dask.config.set({"distributed.scheduler.allowed-failures": 1}):
        local = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0")
    with local:
        yield local


def test_local_cluster_gives_the_loky_tables_and_is_closed(tmp_path, monkeypatch):
    monkeypatch.setenv(run_module.CHUNK_SIZE_ENV, "3")
    campaign = smoke_file(tmp_path)
    loky, dask_out = tmp_path / "loky", tmp_path / "dask"
    assert invoke_run(campaign, "-o", loky, "-j", 2, "--no-progress").exit_code == 0
    before = child_pids()
    result = invoke_run(campaign, "-o", dask_out, "--backend", "dask", "--scheduler", "local:2", "--no-progress")
    assert result.exit_code == 0, result.output
    assert "20 runs, 20 succeeded" in result.output
    assert child_pids() <= before  # the LocalCluster's workers and nannies are gone
    assert len(parts(dask_out)) == 7  # 20 runs in chunks of 3
    table = read_runs(dask_out)
    assert table["fuel_remaining"].nunique() == 20  # dispersed: equal tables are not equal by accident
    pd.testing.assert_frame_equal(table, read_runs(loky))
    pd.testing.assert_frame_equal(histories(dask_out), histories(loky))
    manifest = run_module.storage.read_manifest(dask_out)
    assert (manifest["backend"], manifest["scheduler"], manifest["status"]) == ("dask", "local:2", "complete")
    assert not (dask_out / run_module.WORK_DIR).exists()


def test_an_interrupted_campaign_closes_its_local_cluster(tmp_path, monkeypatch):
    def interrupt(data, path):
        raise KeyboardInterrupt

    monkeypatch.setattr(run_module.storage, "write_bytes_atomic", interrupt)
    campaign, before = smoke_file(tmp_path), child_pids()
    with pytest.raises(KeyboardInterrupt):
        run_campaign(campaign, out=tmp_path / "out", runs=6, backend="dask", scheduler="local:1", chunk_size=2)
    assert child_pids() <= before


def _warmed_up():
    """On a worker: whether the process warmed up (imports and kernels) before any task."""
    from refexmc.campaign import dask_backend

    return dask_backend._warm and "refexmc.simulate" in sys.modules


def test_a_local_cluster_started_early_is_taken_by_the_campaign_with_its_workers_warm():
    before = child_pids()
    dask_backend.start_local_early(1)
    with dask_backend.connect("local:1", 1) as client:
        assert dask_backend._early is None  # taken, not started again
        assert list(client.run(_warmed_up).values()) == [True]  # by the preload, no task run yet
    assert child_pids() <= before


def test_a_refusal_closes_the_local_cluster_started_before_the_campaign_was_read(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "notes.txt").write_text("not a refexmc output\n")
    before = child_pids()
    result = invoke_run(smoke_file(tmp_path), "-o", out, "--backend", "dask", "--scheduler", "local:1")
    assert result.exit_code == 2 and "output directory exists" in result.stderr
    assert dask_backend._early is None and child_pids() <= before
    assert sorted(p.name for p in out.iterdir()) == ["notes.txt"]


def test_worker_killed_mid_campaign_costs_no_run(tmp_path, cluster):
    campaign, runs, chunk_size = smoke_file(tmp_path), 160, 4  # 40 chunks
    reference = run_campaign(campaign, out=tmp_path / "loky", runs=runs, jobs=2, chunk_size=chunk_size)["runs"]
    out = tmp_path / "dask"
    outcome = {}

    def fly():
        try:
            outcome["result"] = run_campaign(
                campaign, out=out, runs=runs, backend="dask", scheduler=cluster.scheduler_address, chunk_size=chunk_size
            )
        except BaseException as exc:  # noqa: BLE001 - handed to the test thread
            outcome["error"] = exc

    with distributed.Client(cluster) as client:
        pids = client.run(os.getpid)
        thread = threading.Thread(target=fly)
        thread.start()
        deadline = time.monotonic() + 120
        while not parts(out):
            assert thread.is_alive() and time.monotonic() < deadline, outcome
            time.sleep(0.005)
        busy = {worker: keys for worker, keys in client.processing().items() if keys}
        victim = next(iter(busy))
        os.kill(pids[victim], signal.SIGKILL)
        done_at_kill = len(parts(out))
        thread.join(180)
        assert not thread.is_alive()
        restarted = client.run(os.getpid)
    assert "error" not in outcome, outcome
    assert any(key.startswith("refexmc-") for key in busy[victim])  # it was flying (or holding) a chunk of ours
    assert done_at_kill < runs // chunk_size  # mid-campaign
    assert pids[victim] not in restarted.values()  # the kill happened (the nanny started a new worker)
    table = read_runs(out)
    assert table["run_id"].tolist() == list(range(runs))  # none lost, none twice
    pd.testing.assert_frame_equal(table, reference)
    assert outcome["result"]["counts"]["ok"] == runs


def test_hung_run_is_one_error_and_costs_one_worker(tmp_path, cluster, monkeypatch):
    monkeypatch.setenv(run_module.CHUNK_SIZE_ENV, "3")
    campaign = smoke_file(tmp_path, run_time_limit_s=3)  # a cold worker's first run may take a second
    clean = tmp_path / "clean"
    assert invoke_run(campaign, "-o", clean, "--runs", 8, "-j", 2, "--no-progress").exit_code == 0
    monkeypatch.setenv(TEST_HANG_ENV, "5")
    out = tmp_path / "out"
    with distributed.Client(cluster) as client:
        before = set(client.run(os.getpid).values())
        on_dask = ("--backend", "dask", "--scheduler", cluster.scheduler_address)
        result = invoke_run(campaign, "-o", out, "--runs", 8, *on_dask)
        after = set(client.run(os.getpid).values())
    assert result.exit_code == 1, result.output
    assert "runs with errors: 5" in result.stderr
    table, reference = read_runs(out), read_runs(clean)
    assert list(table.columns) == list(reference.columns)
    # the attempt after the watchdog ended the worker found the hung run on record: the loky reason, one restart
    assert table.loc[5, "failure_reason"] == "wall-time limit exceeded (3 s)"
    assert len(before - after) == 1
    params = ["seed", "failed_thrusters", *(c for c in table.columns if c.startswith("p."))]
    assert table.loc[5, params].tolist() == reference.loc[5, params].tolist()
    others = table["run_id"] != 5
    pd.testing.assert_frame_equal(table[others], reference[others])
    assert set(pq.read_table(out / "histories", columns=["run_id"]).column("run_id").to_pylist()) == set(range(8)) - {5}


def test_crashing_run_is_one_error_and_costs_no_other_run(tmp_path, cluster, monkeypatch):
    monkeypatch.setenv(run_module.CHUNK_SIZE_ENV, "4")
    campaign = smoke_file(tmp_path)
    clean = tmp_path / "clean"
    assert invoke_run(campaign, "-o", clean, "--runs", 10, "-j", 2, "--no-progress").exit_code == 0
    monkeypatch.setenv(TEST_CRASH_ENV, "6")
    out = tmp_path / "out"
    on_dask = ("--backend", "dask", "--scheduler", cluster.scheduler_address)
    result = invoke_run(campaign, "-o", out, "--runs", 10, *on_dask)
    assert result.exit_code == 1, result.output
    assert "runs with errors: 6" in result.stderr
    table, reference = read_runs(out), read_runs(clean)
    assert table.loc[6, "status"] == "error" and table.loc[6, "failure_reason"] == dask_backend.DIED
    others = table["run_id"] != 6
    pd.testing.assert_frame_equal(table[others], reference[others])


def test_missing_extra_is_bad_input_and_writes_nothing(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "distributed", None)  # import distributed raises ImportError
    out = tmp_path / "out"
    result = invoke_run(smoke_file(tmp_path), "-o", out, "--backend", "dask", "--scheduler", "local:2")
    assert result.exit_code == 2, result.output
    assert "the dask backend needs the optional extra: pip install 'refexmc[dask]'" in result.output
    assert "Traceback" not in result.output and not out.exists()


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--scheduler", "local:2"], "--scheduler is for --backend dask"),
        (["--backend", "dask"], "--backend dask needs --scheduler"),
        (["--backend", "dask", "--scheduler", "local:0"], "local:N with an integer N >= 1"),
        (["--backend", "dask", "--scheduler", "local:two"], "local:N with an integer N >= 1"),
        (["--backend", "dask", "--scheduler", "tcp://127.0.0.1:9"], "cannot connect to the Dask scheduler"),
        (["--backend", "dask", "--scheduler", "/nonexistent/scheduler.json"], "no scheduler file"),
    ],
    ids=["scheduler-with-loky", "dask-without-scheduler", "local-0", "local-word", "unreachable", "no-file"],
)
def test_bad_backend_options_are_refused_before_anything_is_written(tmp_path, args, message):
    out = tmp_path / "out"
    with dask.config.set({"distributed.comm.timeouts.connect": "1s"}):
        result = invoke_run(smoke_file(tmp_path), "-o", out, *args)
    assert result.exit_code == 2, result.output
    assert message in result.output and "Traceback" not in result.output
    assert not out.exists()


def test_importing_refexmc_does_not_import_dask():
    code = (
        "import sys, refexmc.cli, refexmc.campaign.run, refexmc.campaign.backends; "
        "print(sorted(m for m in sys.modules if m.split('.')[0] in ('dask', 'distributed')))"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert result.stdout.strip() == "[]"


def test_scheduler_forms():
    assert dask_backend.parse_scheduler("local:3") == ("local", 3)
    assert dask_backend.parse_scheduler(" local ") == ("local", None)  # -j workers
    assert dask_backend.parse_scheduler("tcp://head:8786") == ("address", "tcp://head:8786")


# --- the client's recovery, driven by a fake cluster ------------------------------------------------


class _Killed(Exception):
    pass


class _Future:
    def __init__(self, key, outcome):
        self.key = key
        self.status, self._value = outcome

    def result(self):
        if self.status == "error":
            raise self._value
        return self._value

    def exception(self):
        return self._value if self.status == "error" else None


class _Client:
    """Runs each task at once: ``behaviour(run_ids)`` gives ('finished', Flown) or ('error', exc)."""

    def __init__(self, behaviour, hung=None):
        self.behaviour = behaviour
        self.hung = hung or {}
        self.submitted = []
        self.inflight_at_submit = []
        self.pending = []

    def submit(self, func, campaign, run_ids, guard, key):
        self.inflight_at_submit.append(len(self.pending))
        self.submitted.append(list(run_ids))
        future = _Future(key, self.behaviour(list(run_ids)))
        self.pending.append(future)
        return future

    def nthreads(self):
        return {"worker": 2}

    def get_metadata(self, keys, default=None):
        return self.hung.get(keys[0], default)

    def cancel(self, futures):
        pass


def _fake_distributed(client):
    def wait(futures, return_when):
        done = futures[:1]
        client.pending = [f for f in client.pending if f not in done]
        return SimpleNamespace(done=done)

    return SimpleNamespace(wait=wait, KilledWorker=_Killed)


def _ok(run_ids):
    return "finished", Flown([{"run_id": r, "status": "ok", "failure_reason": None} for r in run_ids], None, None)


def _fly(client, chunks):
    _, campaign = resolve_campaign(SMOKE)
    guard = Guard(None, 5.0)
    return list(dask_backend._fly_chunks(_fake_distributed(client), client, campaign, chunks, guard))


def test_a_chunk_dask_gave_up_is_flown_run_by_run_and_costs_no_run():
    attempts = []

    def behaviour(run_ids):  # the first attempt's workers died (external kills); alone every run flies
        attempts.append(run_ids)
        return ("error", _Killed()) if len(attempts) == 1 else _ok(run_ids)

    client = _Client(behaviour)
    finished = _fly(client, [(0, range(4)), (1, range(4, 6))])
    rows = {c: r for c, r, _, _ in finished}
    assert sorted(rows) == [0, 1]
    assert [row["run_id"] for row in rows[0]] == [0, 1, 2, 3]
    assert all(row["status"] == "ok" for row in rows[0])
    assert client.submitted == [[0, 1, 2, 3], [4, 5], [0], [1], [2], [3]]
    assert client.inflight_at_submit[2:] == [0, 0, 0, 0]  # flown alone, nothing else in flight


def test_a_run_that_kills_its_workers_alone_is_an_error_row():
    client = _Client(lambda run_ids: ("error", _Killed()) if 2 in run_ids else _ok(run_ids))
    ((chunk, rows, runs, history),) = _fly(client, [(0, range(4))])
    assert [row["status"] for row in rows] == ["ok", "ok", "error", "ok"]
    assert rows[2]["failure_reason"] == dask_backend.DIED
    assert client.submitted == [[0, 1, 2, 3], [0], [1], [2], [3]]


def test_a_run_on_record_as_hung_is_a_limit_error_and_its_chunk_is_flown_again_whole():
    first = []

    def behaviour(run_ids):
        first.append(run_ids)
        return ("error", _Killed()) if len(first) == 1 else _ok(run_ids)

    client = _Client(behaviour)
    client.hung = {}
    original_submit = client.submit

    def submit(func, campaign, run_ids, guard, key):
        future = original_submit(func, campaign, run_ids, guard, key)
        if len(first) == 1:
            client.hung[key] = {"1": True}  # the watchdog's record under the task's key
        return future

    client.submit = submit
    ((chunk, rows, runs, history),) = _fly(client, [(0, range(4))])
    assert rows[1]["failure_reason"] == "wall-time limit exceeded (5 s)"
    assert [row["status"] for row in rows] == ["ok", "error", "ok", "ok"]
    assert client.submitted == [[0, 1, 2, 3], [0, 2, 3]]


def test_a_result_with_a_run_twice_is_refused():
    client = _Client(lambda run_ids: _ok(run_ids + run_ids[:1]))
    with pytest.raises(RuntimeError, match="other runs than it was given"):
        _fly(client, [(0, range(3))])
