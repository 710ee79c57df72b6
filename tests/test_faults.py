"""Never lose or mix a user's data: --overwrite refusals, the lock on OUT, SIGINT/SIGTERM, OS errors,
damaged parts and a stale report.

Every refusal is checked byte for byte against what was on disk before. Processes and signals are
real subprocesses (``python -m refexmc.cli``, its own session so that every process it starts can
be found). A full disk and a read-only OUT are real too where a private mount namespace can be had
(``unshare -rm``: a small tmpfs, a read-only bind mount); the full disk is also mocked, always.
"""

import errno
import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest
import yaml
from click.testing import CliRunner
from stored import campaign_copy, invoke_run, read_runs, snapshot

from refexmc.campaign import lock, storage
from refexmc.campaign import run as run_module
from refexmc.cli import main

CHUNKED = {run_module.CHUNK_SIZE_ENV: "5"}
# 400 runs: a signal after the first part lands mid-campaign; the signal tests fly chunks of 2 (in
# chunks of 5 a Dask campaign could write its last part before the signal landed, once runs got faster)
SIGNAL_RUNS = 400


def smoke(tmp_path, name="smoke.yaml"):
    """campaigns/smoke.yaml (20 dispersed runs: every row differs) runnable from ``tmp_path``."""
    return campaign_copy("smoke.yaml", tmp_path, name)


def one_line_error(result, *words):
    """Exit 2, a single `error: ...` line on stderr holding ``words``, no traceback."""
    assert result.exit_code == 2, result.output
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), result.stderr
    assert "Traceback" not in result.output
    for word in words:
        assert word in lines[0], (word, lines[0])


def start_run(campaign, out, *args, env=CHUNKED):
    """`refexmc run` in a subprocess of its own session (its id is the session's)."""
    command = [sys.executable, "-m", "refexmc.cli", "run", campaign, "-o", out, "--no-progress", *args]
    return subprocess.Popen(
        list(map(str, command)), env={**os.environ, **env}, start_new_session=True, stderr=subprocess.PIPE, text=True
    )


def wait_for(condition, process, what, timeout_s=180):
    """Poll until ``condition()``; fail if ``process`` ends first (a cold numba cache compiles first)."""
    deadline = time.monotonic() + timeout_s
    while not condition():
        assert process.poll() is None, f"ended before {what}: {process.stderr.read()}"
        assert time.monotonic() < deadline, f"no {what}"
        time.sleep(0.005)


def has_part(out):
    return (out / "runs").is_dir() and any((out / "runs").glob("part-*.parquet"))


def live_in_session(session_id):
    """Pids of processes of session ``session_id`` that have not exited (zombies are exited)."""
    pids = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            fields = (entry / "stat").read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        state, session = fields[0], int(fields[3])
        if session == session_id and state not in ("Z", "X"):
            pids.append(int(entry.name))
    return pids


def part_files(out):
    return {path: data for path, data in snapshot(out).items() if path.parts[0] in ("runs", "histories")}


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """The uninterrupted smoke campaign of SIGNAL_RUNS runs: campaign file and runs table."""
    folder = tmp_path_factory.mktemp("reference")
    campaign = smoke(folder)
    result = invoke_run(campaign, "-o", folder / "out", "--runs", SIGNAL_RUNS, "--no-progress")
    assert result.exit_code == 0, result.output
    return campaign, read_runs(folder / "out")


@pytest.fixture(scope="module")
def finished_once(tmp_path_factory):
    """The 6-run smoke campaign of :func:`finished`, flown once for the module (a `refexmc run`
    starts its process pool: seconds per test otherwise)."""
    folder = tmp_path_factory.mktemp("finished")
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv(run_module.CHUNK_SIZE_ENV, "2")
        assert invoke_run(smoke(folder), "-o", folder / "out", "--runs", 6, "--no-progress").exit_code == 0
    return folder


@pytest.fixture
def finished(finished_once, tmp_path, monkeypatch):
    """A finished 6-run smoke campaign in chunks of 2: (campaign file, OUT), a test's own copy of
    :func:`finished_once` whose manifest names the copied campaign file, as its own flight would."""
    monkeypatch.setenv(run_module.CHUNK_SIZE_ENV, "2")
    campaign, out = smoke(tmp_path), tmp_path / "out"
    shutil.copytree(finished_once / "out", out)
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["campaign_file"] == str(finished_once / "smoke.yaml")
    storage.write_manifest(out, {**manifest, "campaign_file": str(campaign)})
    return campaign, out


# --- --overwrite ------------------------------------------------------------------------------------


def test_overwrite_of_a_directory_that_is_not_an_output_is_refused_untouched(tmp_path):
    out = tmp_path / "thesis"
    (out / "figures").mkdir(parents=True)
    (out / "thesis.tex").write_text("\\chapter{Results}\n")
    (out / "figures" / "plot.pdf").write_bytes(b"%PDF-1.5 ...")
    before = snapshot(out)
    result = invoke_run(smoke(tmp_path), "-o", out, "--overwrite", "--runs", 2)
    one_line_error(result, str(out), "only a refexmc output directory", "nothing was touched")
    assert snapshot(out) == before and sorted(p.name for p in out.iterdir()) == ["figures", "thesis.tex"]


def test_overwrite_of_an_output_holding_other_files_is_refused_untouched(finished):
    campaign, out = finished
    (out / "notes.txt").write_text("run 3 looks odd")
    (out / "analysis").mkdir()
    before = snapshot(out)
    result = invoke_run(campaign, "-o", out, "--overwrite", "--runs", 6)
    one_line_error(result, "files refexmc did not write: analysis, notes.txt")
    assert snapshot(out) == before


@pytest.mark.parametrize(
    ("mine", "named"),  # a folder of the user's is named, not each file in it
    [
        ("report/my-analysis.ipynb", "report/my-analysis.ipynb"),
        ("runs/extra.txt", "runs/extra.txt"),
        ("histories/mine/a.csv", "histories/mine"),
        ("report/figures/plot.pdf", "report/figures/plot.pdf"),
    ],
)
def test_overwrite_of_an_output_with_a_users_file_in_its_folders_is_refused_untouched(finished, mine, named):
    """Inside the folders refexmc writes too (before: only OUT's top level was looked at, and
    --overwrite deleted a user's notebook in report/ with the rest)."""
    campaign, out = finished
    assert CliRunner().invoke(main, ["report", str(out)]).exit_code == 0
    (out / mine).parent.mkdir(parents=True, exist_ok=True)
    (out / mine).write_text("my own work")
    before = snapshot(out)
    result = invoke_run(campaign, "-o", out, "--overwrite", "--runs", 6)
    one_line_error(result, f"files refexmc did not write: {named};")
    assert snapshot(out) == before


def test_a_resume_removes_the_stale_report_but_not_a_users_file_in_it(finished):
    campaign, out = finished
    assert CliRunner().invoke(main, ["report", str(out)]).exit_code == 0
    (out / "report" / "notes.md").write_text("run 3 looks odd")
    next((out / "runs").iterdir()).unlink()  # a chunk to fly again: the report no longer describes OUT
    result = invoke_run(campaign, "-o", out, "--resume", "--runs", 6, "--no-progress")
    assert result.exit_code == 0, result.output
    assert sorted(p.relative_to(out).as_posix() for p in (out / "report").rglob("*")) == ["report/notes.md"]
    assert (out / "report" / "notes.md").read_text() == "run 3 looks odd"


def test_overwrite_never_deletes_the_campaign_file(finished):
    campaign, out = finished
    inside = out / "reruns" / "campaign.yaml"  # a name refexmc writes, holding the campaign file
    inside.parent.mkdir()
    shutil.copy(campaign, inside)
    before = snapshot(out)
    result = invoke_run(inside, "-o", out, "--overwrite", "--runs", 6)
    one_line_error(result, f"would delete {inside}")
    assert snapshot(out) == before


@pytest.mark.parametrize("where", [".", ".."], ids=["cwd", "parent-of-cwd"])
def test_overwrite_never_deletes_the_current_directory(finished, monkeypatch, where):
    campaign, out = finished
    before = snapshot(out)
    monkeypatch.chdir(out if where == "." else out / "runs")
    result = invoke_run(campaign, "-o", where, "--overwrite", "--runs", 6)
    one_line_error(result, "current directory")
    assert snapshot(out) == before


def test_overwrite_replaces_an_output_and_fills_an_empty_directory(finished, tmp_path):
    campaign, out = finished
    assert CliRunner().invoke(main, ["report", str(out), "--no-html"]).exit_code == 0
    assert (out / "report" / "summary.json").is_file()
    result = invoke_run(campaign, "-o", out, "--overwrite", "--runs", 4, "--no-progress")
    assert result.exit_code == 0, result.output
    assert sorted(p.name for p in out.iterdir()) == ["campaign.resolved.yaml", "histories", "manifest.json", "runs"]
    assert read_runs(out)["run_id"].tolist() == [0, 1, 2, 3] and len(list((out / "runs").iterdir())) == 2
    empty = tmp_path / "empty"
    empty.mkdir()
    assert invoke_run(campaign, "-o", empty, "--runs", 2, "--no-progress").exit_code == 0
    assert len(read_runs(empty)) == 2


# --- the lock ---------------------------------------------------------------------------------------


def test_a_held_lock_refuses_every_writer_untouched(finished):
    campaign, out = finished
    (out / "runs" / "part-00001.parquet").unlink()  # something for --resume to do
    before = snapshot(out)
    fd = lock.acquire(out, notify=pytest.fail)
    try:
        held = snapshot(out)
        for flag in ("--resume", "--overwrite"):
            result = invoke_run(campaign, "-o", out, flag, "--runs", 6)
            one_line_error(result, "in use by another refexmc run", f"pid {os.getpid()} on host")
            assert snapshot(out) == held
    finally:
        lock.release(out, fd)
    assert snapshot(out) == before  # the lock file is gone with the lock


def test_a_stale_lock_of_a_dead_process_is_taken_over(finished):
    campaign, out = finished
    dead = subprocess.Popen(["true"])
    dead.wait()
    (out / lock.LOCK_NAME).write_text(f'{{"pid": {dead.pid}, "host": "{socket.gethostname()}", "started": "x"}}\n')
    (out / "runs" / "part-00001.parquet").unlink()
    result = invoke_run(campaign, "-o", out, "--resume", "--runs", 6, "--no-progress")
    assert result.exit_code == 0, result.output
    assert f"taking over the lock left by pid {dead.pid}" in result.stderr and "process is gone" in result.stderr
    assert not (out / lock.LOCK_NAME).exists() and len(read_runs(out)) == 6


def test_a_lock_from_another_host_is_refused_untouched(finished):
    campaign, out = finished
    (out / lock.LOCK_NAME).write_text('{"pid": 1, "host": "elsewhere.example", "started": "x"}\n')
    before = snapshot(out)
    result = invoke_run(campaign, "-o", out, "--resume", "--runs", 6)
    one_line_error(result, "host elsewhere.example", "cannot be checked from this host", "remove")
    assert snapshot(out) == before


@pytest.mark.slow
def test_a_second_writer_is_refused_and_the_first_completes_unmixed(tmp_path, reference):
    campaign, table = reference
    out = tmp_path / "out"
    first = start_run(campaign, out, "--runs", SIGNAL_RUNS, "-j", 1)
    wait_for(lambda: (out / lock.LOCK_NAME).is_file(), first, "lock file")
    overwrite = invoke_run(campaign, "-o", out, "--overwrite", "--seed", 7, "--runs", SIGNAL_RUNS)
    one_line_error(overwrite, "in use by another refexmc run", f"pid {first.pid}")
    resume = invoke_run(campaign, "-o", out, "--resume", "--runs", SIGNAL_RUNS)
    one_line_error(resume, "in use by another refexmc run")
    assert first.wait(timeout=300) == 0, first.stderr.read()
    first.stderr.close()
    manifest = storage.read_manifest(out)
    resolved = yaml.safe_load((out / "campaign.resolved.yaml").read_text())
    assert manifest["seed"] == resolved["seed"] == 20231121 and manifest["status"] == "complete"
    pd.testing.assert_frame_equal(read_runs(out), table)  # every row the first writer's, none of seed 7


# --- signals ----------------------------------------------------------------------------------------


@pytest.mark.slow
@pytest.mark.parametrize(
    ("signum", "backend"),
    [(signal.SIGTERM, "loky"), (signal.SIGINT, "loky"), (signal.SIGTERM, "dask")],
    ids=["sigterm", "sigint", "sigterm-dask"],
)
def test_a_signal_stops_every_process_keeps_the_parts_and_resume_completes(tmp_path, reference, signum, backend):
    options = ["--backend", "dask", "--scheduler", "local:2"] if backend == "dask" else ["-j", 2]
    if backend == "dask":
        pytest.importorskip("distributed")
    campaign, table = reference
    out = tmp_path / "out"
    for _attempt in range(3):  # a campaign that completed before the signal came tests nothing: fly it again
        shutil.rmtree(out, ignore_errors=True)
        process = start_run(campaign, out, "--runs", SIGNAL_RUNS, *options, env={run_module.CHUNK_SIZE_ENV: "2"})
        wait_for(lambda: has_part(out), process, "part file")
        process.send_signal(signum)  # to the CLI alone: it must stop its workers itself
        stderr = process.communicate(timeout=60)[1]
        if process.returncode != 0:
            break
    assert process.returncode == 128 + signum, stderr
    deadline = time.monotonic() + 5
    while live_in_session(process.pid) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not live_in_session(process.pid), "a worker outlived the campaign by 5 s"
    command = f"refexmc run {campaign} -o {out} --resume --runs {SIGNAL_RUNS}"
    assert f"interrupted by {signal.Signals(signum).name}: " in stderr and f"finish with: {command}" in stderr
    assert "Traceback" not in stderr, stderr
    kept = part_files(out)
    assert kept and len(kept) < 2 * SIGNAL_RUNS // 2, "the signal came after the end"  # 2 parts per 2-run chunk
    assert storage.read_manifest(out)["status"] == "interrupted" and not (out / lock.LOCK_NAME).exists()

    resumed = invoke_run(*command.split()[2:], "--no-progress")
    assert resumed.exit_code == 0, resumed.output
    assert {path: data for path, data in part_files(out).items() if path in kept} == kept  # not flown again
    pd.testing.assert_frame_equal(read_runs(out), table)


# --- OS errors --------------------------------------------------------------------------------------


def test_a_full_disk_is_one_line_and_loses_nothing(finished, monkeypatch):
    campaign, out = finished
    (out / "runs" / "part-00001.parquet").unlink()
    (out / "histories" / "part-00002.parquet").unlink()
    before = part_files(out)
    write_bytes = Path.write_bytes

    def disk_full(path, data):
        if path.name.startswith(".part-"):
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))  # as a failed write: no file name
        return write_bytes(path, data)

    monkeypatch.setattr(Path, "write_bytes", disk_full)
    result = invoke_run(campaign, "-o", out, "--resume", "--runs", 6, "--no-progress")
    one_line_error(result, "run stopped: ", "/histories/part-0000", "No space left on device (ENOSPC)", "--resume")
    assert part_files(out) == before and not list(out.rglob("*.tmp-*"))
    assert not (out / lock.LOCK_NAME).exists()


def _namespace_script(script):
    """Run ``sh -c script`` as root of a private user and mount namespace; skip where there is none."""
    if shutil.which("unshare") is None or subprocess.run(["unshare", "-rm", "true"], capture_output=True).returncode:
        pytest.skip("no private mount namespace here (unshare -rm)")
    env = {**os.environ, "PATH": f"{Path(sys.executable).parent}:{os.environ['PATH']}", **CHUNKED}
    return subprocess.run(["unshare", "-rm", "sh", "-c", script], capture_output=True, text=True, env=env)


def _cli(*args):
    return " ".join([sys.executable, "-m", "refexmc.cli", *map(str, args)])


@pytest.mark.slow
def test_a_real_full_disk_is_one_line_exit_2(tmp_path):
    disk = tmp_path / "disk"
    disk.mkdir()
    campaign = smoke(tmp_path)
    script = (
        f"mount -t tmpfs -o size=200k tmpfs {disk} && echo mine > {disk}/notes.txt && "
        f"{_cli('run', campaign, '-o', disk / 'out', '--runs', 40, '-j', 1, '--no-progress')}; "
        f"echo rc=$? >&2; cat {disk}/notes.txt >&2; ls {disk}/out/runs {disk}/out/histories >&2"
    )
    done = _namespace_script(script)
    lines = done.stderr.strip().splitlines()
    assert lines[0].startswith("error: run stopped: ") and "No space left on device (ENOSPC)" in lines[0], lines
    assert lines[1:3] == ["rc=2", "mine"] and "Traceback" not in done.stderr
    assert not [line for line in lines[3:] if ".tmp-" in line]  # no partial file takes the space


@pytest.mark.slow
def test_a_read_only_output_is_one_line_exit_2_and_unchanged(finished):
    campaign, out = finished
    (out / "runs" / "part-00001.parquet").unlink()
    before = snapshot(out)
    script = (
        f"mount --bind {out} {out} && mount -o remount,bind,ro {out} && "
        f"{_cli('run', campaign, '-o', out, '--resume', '--runs', 6, '--no-progress')}; echo rc=$? >&2; "
        f"{_cli('report', out, '--no-html')}; echo rc=$? >&2"
    )
    done = _namespace_script(script)
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 4 and lines[1::2] == ["rc=2", "rc=2"], done.stderr
    assert lines[0].startswith(f"error: run stopped: {out}/") and "Read-only file system (EROFS)" in lines[0]
    assert lines[2].startswith(f"error: report failed: {out}/report") and "(EROFS)" in lines[2]
    assert snapshot(out) == before


def test_rerun_into_an_impossible_path_is_one_line(finished, tmp_path):
    _, out = finished
    blocker = tmp_path / "file.txt"
    blocker.write_text("not a folder")
    result = CliRunner().invoke(main, ["rerun", str(out), "1", "-o", str(blocker / "run-1.parquet")])
    one_line_error(result, "rerun failed: ", str(blocker / "run-1.parquet"))
    assert blocker.read_text() == "not a folder"


@pytest.mark.parametrize("damaged", ["manifest.json", "campaign.resolved.yaml"])
def test_resume_of_an_output_with_a_damaged_manifest_is_refused_untouched(finished, damaged):
    campaign, out = finished
    if damaged == "manifest.json":
        _truncate(out / damaged)
    else:
        (out / damaged).write_bytes(b"name: [\xff\xfe")  # neither UTF-8 nor YAML
    before = snapshot(out)
    result = invoke_run(campaign, "-o", out, "--resume", "--runs", 6)
    one_line_error(result, "cannot resume: ", "remove OUT or use another -o")
    assert snapshot(out) == before


# --- damaged parts and a stale report ---------------------------------------------------------------


def _truncate(path):
    path.write_bytes(path.read_bytes()[: path.stat().st_size // 2])


@pytest.mark.parametrize(
    "damage",
    ["runs-truncated", "histories-truncated", "runs-of-another-chunk"],
)
def test_resume_flies_a_damaged_chunk_again_and_drops_the_stale_report(finished, damage):
    campaign, out = finished
    table = read_runs(out)
    assert CliRunner().invoke(main, ["report", str(out), "--no-html"]).exit_code == 0
    part = "part-00001.parquet"
    if damage == "runs-truncated":
        _truncate(out / "runs" / part)
    elif damage == "histories-truncated":
        _truncate(out / "histories" / part)
    else:
        shutil.copy(out / "runs" / "part-00000.parquet", out / "runs" / part)
    if damage == "runs-truncated":
        report = CliRunner().invoke(main, ["report", str(out), "--no-html"])
        one_line_error(report, f"report failed: cannot read {out}", "--resume")
        compared = CliRunner().invoke(main, ["compare", str(out), str(out)])
        one_line_error(compared, "compare failed: cannot read", "--resume")
        rerun = CliRunner().invoke(main, ["rerun", str(out), "2", "-o", str(out.parent / "run-2.parquet")])
        one_line_error(rerun, "rerun failed: cannot read", "--resume")
    others = {path: data for path, data in part_files(out).items() if path.name != part}

    resumed = invoke_run(campaign, "-o", out, "--resume", "--runs", 6, "--no-progress")
    assert resumed.exit_code == 0, resumed.output
    assert "chunk 1 (runs 2..3) is damaged, flying it again" in resumed.stderr
    assert {path: data for path, data in part_files(out).items() if path.name != part} == others
    pd.testing.assert_frame_equal(read_runs(out), table)
    assert not (out / "report").exists()  # it described the damaged contents

    assert CliRunner().invoke(main, ["report", str(out), "--no-html"]).exit_code == 0
    again = invoke_run(campaign, "-o", out, "--resume", "--runs", 6, "--no-progress")
    assert again.exit_code == 0 and "damaged" not in again.stderr
    assert (out / "report" / "summary.json").is_file()  # nothing changed: the report stays
