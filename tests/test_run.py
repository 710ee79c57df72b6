"""`refexmc run` execution: -j, resume after SIGKILL, the per-run time limit, crashes, refusals, progress.

Small chunks (``REFEXMC_CHUNK_SIZE``) give many parts from few runs, so that kills, resumes and
worker deaths happen in the middle of a campaign while the tests stay short.
"""

import io
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pyarrow.parquet as pq
import pytest
from stored import campaign_copy, invoke_run, read_runs, snapshot

from refexmc.campaign import progress as progress_module
from refexmc.campaign import run as run_module
from refexmc.campaign.progress import Progress
from refexmc.campaign.worker import TEST_CRASH_ENV, TEST_HANG_ENV

ROOT = Path(__file__).resolve().parents[1]
NOMINAL = ROOT / "campaigns/nominal.yaml"
SMOKE = ROOT / "campaigns/smoke.yaml"  # 20 dispersed runs (LHS): every row differs


def campaign_file(tmp_path, runs, name="nominal.yaml", **extra):
    """campaigns/nominal.yaml with ``runs`` and extra top-level keys, config paths made absolute."""
    return campaign_copy("nominal.yaml", tmp_path, name, [("runs: 1\n", f"runs: {runs}\n")], **extra)


def parts(out):
    """Complete part files (a kill during a write also leaves a hidden temporary file)."""
    return sorted(p.name for p in (Path(out) / "runs").glob("part-*.parquet"))


def test_jobs_1_and_2_give_identical_tables(tmp_path, monkeypatch):
    monkeypatch.setenv(run_module.CHUNK_SIZE_ENV, "3")
    one, two = tmp_path / "j1", tmp_path / "j2"
    assert invoke_run(SMOKE, "-o", one, "-j", 1, "--no-progress").exit_code == 0
    assert invoke_run(SMOKE, "-o", two, "-j", 2, "--no-progress").exit_code == 0
    assert len(parts(one)) == 7  # 20 runs in chunks of 3
    first, second = read_runs(one), read_runs(two)
    assert len(first) == 20 and first["status"].eq("ok").all()
    assert first["fuel_remaining"].nunique() == 20  # dispersed: equal tables are not equal by accident
    pd.testing.assert_frame_equal(first, second)
    histories = [pq.read_table(out / "histories").to_pandas().sort_values(["run_id", "t_s"]) for out in (one, two)]
    pd.testing.assert_frame_equal(*(h.reset_index(drop=True) for h in histories))


@pytest.mark.slow
def test_killed_campaign_resumes_to_the_uninterrupted_table(tmp_path):
    campaign = campaign_file(tmp_path, runs=400)
    out = tmp_path / "killed"
    env = {**os.environ, run_module.CHUNK_SIZE_ENV: "5"}  # 80 chunks
    command = [sys.executable, "-m", "refexmc.cli", "run", str(campaign), "-o", str(out), "-j", "2", "--no-progress"]
    process = subprocess.Popen(command, env=env, start_new_session=True, stderr=subprocess.PIPE)
    deadline = time.monotonic() + 180  # a cold numba cache compiles first
    while not (out / "runs").is_dir() or not any((out / "runs").glob("part-*.parquet")):
        assert process.poll() is None, process.stderr.read().decode()
        assert time.monotonic() < deadline, "no part file appeared"
        time.sleep(0.005)
    os.killpg(process.pid, signal.SIGKILL)  # the CLI and its workers, mid-campaign
    process.wait()
    process.stderr.close()
    done_before = parts(out)
    assert 1 <= len(done_before) < 80, done_before
    assert run_module.storage.read_manifest(out)["status"] == "running"
    for folder in ("runs", "histories"):  # what a kill during a write leaves behind
        (out / folder / ".part-00079.parquet.tmp-99999").write_bytes(b"partial")
    mtimes = {name: (out / "runs" / name).stat().st_mtime_ns for name in done_before}

    resumed = invoke_run(campaign, "-o", out, "--resume", "-j", 2, "--no-progress")
    assert resumed.exit_code == 0, resumed.output
    assert "taking over the lock left by pid" in resumed.stderr  # the killed run's
    assert parts(out) == [f"part-{k:05d}.parquet" for k in range(80)]
    assert sorted(p.name for p in (out / "histories").iterdir()) == parts(out)
    assert not list(out.rglob("*.tmp-*")) and not (out / run_module.WORK_DIR).exists()
    assert {name: (out / "runs" / name).stat().st_mtime_ns for name in done_before} == mtimes  # kept, not redone
    manifest = run_module.storage.read_manifest(out)
    assert manifest["status"] == "complete" and manifest["chunk_size"] == 5 and len(manifest["resumed"]) == 1

    reference = tmp_path / "reference"  # uninterrupted, default chunk size
    assert invoke_run(campaign, "-o", reference, "--no-progress").exit_code == 0
    table = read_runs(out)
    assert table["run_id"].tolist() == list(range(400))  # no run twice, none missing
    pd.testing.assert_frame_equal(table, read_runs(reference))


def test_resume_of_a_complete_output_recomputes_nothing(tmp_path, monkeypatch):
    monkeypatch.setenv(run_module.CHUNK_SIZE_ENV, "2")
    campaign = campaign_file(tmp_path, runs=5)
    out = tmp_path / "out"
    assert invoke_run(campaign, "-o", out, "-j", 2, "--no-progress").exit_code == 0
    before = snapshot(out)
    assert len(parts(out)) == 3
    resumed = invoke_run(campaign, "-o", out, "--resume", "--no-progress")
    assert resumed.exit_code == 0, resumed.output
    after = snapshot(out)
    assert {k: v for k, v in after.items() if k.parts[0] in ("runs", "histories")} == {
        k: v for k, v in before.items() if k.parts[0] in ("runs", "histories")
    }
    assert "5 runs, 5 succeeded" in resumed.output


@pytest.mark.parametrize(
    "change",
    [["--seed", "7"], ["--runs", "6"], ["other campaign file"]],
    ids=["seed", "runs", "file"],
)
def test_resume_of_a_different_campaign_is_refused(tmp_path, change):
    campaign = campaign_file(tmp_path, runs=3)
    out = tmp_path / "out"
    assert invoke_run(campaign, "-o", out, "--no-progress").exit_code == 0
    before = snapshot(out)
    if change == ["other campaign file"]:
        other = campaign_file(tmp_path, runs=3, name="other.yaml", run_time_limit_s=30)
        result = invoke_run(other, "-o", out, "--resume")
    else:
        result = invoke_run(campaign, "-o", out, "--resume", *change)
    assert result.exit_code == 2, result.output
    assert "different campaign" in result.output and "Traceback" not in result.output
    assert result.output.startswith("error: ") and len(result.output.strip().splitlines()) == 1
    assert snapshot(out) == before


@pytest.mark.parametrize("flown_by", ["0123456789abcdef", None], ids=["other-flight-code", "before-issue-37"])
def test_resume_of_an_output_flown_by_other_flight_code_is_refused(tmp_path, flown_by):
    """A partial OUT whose manifest names other flight code (or none: written before issue 37
    changed every flight's bits) is not finished with this code's bits: exit 2, one line, untouched."""
    campaign = campaign_file(tmp_path, runs=3)
    out = tmp_path / "out"
    assert invoke_run(campaign, "-o", out, "--no-progress").exit_code == 0
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["flight_code"] == run_module.storage.flight_code()
    manifest = {**manifest, "status": "running", "flight_code": flown_by}
    (out / "manifest.json").write_text(json.dumps({k: v for k, v in manifest.items() if v is not None}))
    before = snapshot(out)
    result = invoke_run(campaign, "-o", out, "--resume", "--no-progress")
    assert result.exit_code == 2, result.output
    assert "other flight code" in result.output and (flown_by or "before issue 37") in result.output
    assert result.output.startswith("error: ") and len(result.output.strip().splitlines()) == 1
    assert snapshot(out) == before


def test_resume_refuses_a_directory_that_is_not_an_output(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    result = invoke_run(campaign_file(tmp_path, runs=1), "-o", out, "--resume")
    assert result.exit_code == 2 and "not a refexmc output directory" in result.output
    assert sorted(p.name for p in out.iterdir()) == ["notes.txt"]


def test_existing_output_without_a_flag_is_refused_untouched(tmp_path):
    campaign = campaign_file(tmp_path, runs=2)
    out = tmp_path / "out"
    assert invoke_run(campaign, "-o", out, "--no-progress").exit_code == 0
    before = snapshot(out)
    result = invoke_run(campaign, "-o", out)
    assert result.exit_code == 2 and "exists" in result.output and "Traceback" not in result.output
    assert snapshot(out) == before


def test_hung_run_is_an_error_and_the_others_complete(tmp_path, monkeypatch):
    monkeypatch.setenv(run_module.CHUNK_SIZE_ENV, "1")  # the hung run is a chunk of its own
    campaign = tmp_path / "smoke.yaml"
    campaign.write_text(SMOKE.read_text().replace("../configs", str(ROOT / "configs")) + "run_time_limit_s: 1\n")
    clean = tmp_path / "clean"
    assert invoke_run(campaign, "-o", clean, "--runs", 8, "--no-progress").exit_code == 0
    monkeypatch.setenv(TEST_HANG_ENV, "5")
    out = tmp_path / "out"
    result = invoke_run(campaign, "-o", out, "--runs", 8, "-j", 2, "--no-progress")
    assert result.exit_code == 1, result.output
    assert "runs with errors: 5" in result.stderr
    table, reference = read_runs(out), read_runs(clean)
    assert list(table.columns) == list(reference.columns)  # p.<path> columns included
    hung, expected = table.loc[5], reference.loc[5]
    assert hung["status"] == "error" and hung["failure_reason"] == "wall-time limit exceeded (1 s)"
    params = ["seed", "failed_thrusters", *(c for c in table.columns if c.startswith("p."))]
    assert hung[params].tolist() == expected[params].tolist()  # the hung run's own draws
    others = table["run_id"] != 5
    assert table.loc[others, "status"].eq("ok").all() and others.sum() == 7
    # the runs flown again after the worker died are the same runs
    pd.testing.assert_frame_equal(table[others], reference[others])
    assert not (out / run_module.WORK_DIR).exists()
    history_ids = set(pq.read_table(out / "histories", columns=["run_id"]).column("run_id").to_pylist())
    assert history_ids == set(range(8)) - {5}


def test_crashing_run_costs_no_other_run(tmp_path, monkeypatch):
    monkeypatch.setenv(run_module.CHUNK_SIZE_ENV, "4")
    monkeypatch.setenv(TEST_CRASH_ENV, "6")
    out = tmp_path / "out"
    result = invoke_run(campaign_file(tmp_path, runs=10), "-o", out, "-j", 2, "--no-progress")
    assert result.exit_code == 1, result.output
    assert "runs with errors: 6" in result.stderr
    table = read_runs(out).set_index("run_id")
    assert table.loc[6, "status"] == "error"
    assert table.loc[6, "failure_reason"].startswith("worker process died during this run")
    assert (table.drop(index=6)["status"] == "ok").all() and len(table) == 10


def test_default_campaign_and_output(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    result = invoke_run("--runs", 2, "--no-progress")
    assert result.exit_code == 0, result.output
    assert len(read_runs(tmp_path / "runs" / "refex-mc100")) == 2
    monkeypatch.setattr(run_module, "DEFAULT_CAMPAIGN", tmp_path / "campaigns" / "refex-mc100.yaml")
    missing = invoke_run("--runs", 2)
    assert missing.exit_code == 2
    assert "default campaign is missing" in missing.output and "Traceback" not in missing.output


@pytest.mark.parametrize(
    ("args", "message"),
    [(["-j", "0"], "jobs"), (["--backend", "dask"], "dask"), (["--resume", "--overwrite"], "exclude")],
)
def test_bad_run_options(tmp_path, args, message):
    out = tmp_path / "out"
    result = invoke_run(campaign_file(tmp_path, runs=1), "-o", out, *args)
    assert result.exit_code == 2 and message in result.output and "Traceback" not in result.output
    assert not out.exists()


def test_progress_lines_and_silence(tmp_path):
    campaign = campaign_file(tmp_path, runs=2)
    loud = invoke_run(campaign, "-o", tmp_path / "loud")
    assert loud.exit_code == 0 and "2/2 runs" in loud.stderr  # stderr is no terminal here: plain lines
    quiet = invoke_run(campaign, "-o", tmp_path / "quiet", "--no-progress")
    assert quiet.exit_code == 0 and quiet.stderr == ""


def test_progress_bar_shows_runs_rate_and_eta():
    stream = io.StringIO()
    meter = Progress(100, done=20, mode="bar", stream=stream)
    meter.update(30)
    meter.close()
    text = stream.getvalue()
    assert "50/100" in text and "run/s" in text and "<" in text  # tqdm: n/total [elapsed<ETA, rate]


@pytest.mark.parametrize("backend", ["loky", "cuda"])
@pytest.mark.parametrize("runs", [1, 9, 20, 100, 319, 320, 321, 1000, 3200, 3201, 10_000, 100_000, 1_000_000])
def test_default_chunk_size_gives_about_target_chunks_within_bounds(runs, backend):
    """About TARGET_CHUNKS chunks, 10 to 100 runs each; on the GPU (host work only) up to 1,000."""
    largest = run_module.MAX_GPU_CHUNK_SIZE if backend == "cuda" else run_module.MAX_CHUNK_SIZE
    size = run_module.default_chunk_size(runs, backend)
    assert run_module.MIN_CHUNK_SIZE <= size <= largest
    chunks = len(run_module.plan_chunks(runs, size))
    if size < largest:  # at most the target count of chunks ...
        assert chunks <= run_module.TARGET_CHUNKS
    if run_module.MIN_CHUNK_SIZE < size < largest:  # ... and the smallest size that does it
        assert (size - 1) * run_module.TARGET_CHUNKS < runs
    assert run_module.default_chunk_size(runs + 1, backend) >= size  # more runs never give smaller chunks
    assert size >= run_module.default_chunk_size(runs)  # never smaller than loky's


def test_a_new_outs_chunk_size_follows_its_backend_unless_the_environment_sets_it(monkeypatch):
    monkeypatch.delenv(run_module.CHUNK_SIZE_ENV, raising=False)
    assert run_module._chunk_size(None, 100_000, "cuda") == run_module.MAX_GPU_CHUNK_SIZE
    assert run_module._chunk_size(None, 100_000, "loky") == run_module._chunk_size(None, 100_000, "dask") == 100
    monkeypatch.setenv(run_module.CHUNK_SIZE_ENV, "7")
    assert run_module._chunk_size(None, 100_000, "cuda") == 7


def test_progress_says_compiling_and_leaves_the_first_runs_out_of_the_eta(monkeypatch):
    """The first runs carry the JIT compile: the first line says so and the ETA is timed after them
    (a 10 s compile before 10 runs of 0.1 s each would otherwise give an ETA of ~900 s for 90 runs)."""
    clock = [0.0]
    monkeypatch.setattr(progress_module.time, "monotonic", lambda: clock[0])
    stream = io.StringIO()
    meter = Progress(100, mode="lines", stream=stream)
    clock[0] = 10.0  # compile + the first 10 runs
    meter.update(10)
    clock[0] = 16.0  # 60 more runs at 10 runs/s
    meter.update(60)
    meter.close()
    lines = stream.getvalue().splitlines()
    assert "compiling" in lines[0] and "ETA" not in lines[0].split(";")[0]
    assert lines[1].startswith("10/100 runs, the first in 10 s (JIT compile included)")
    assert lines[2] == "70/100 runs, 10 runs/s, ETA 3 s"  # 30 runs at 10 runs/s, not 30 at 70/16 s
