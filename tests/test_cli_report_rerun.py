"""`refexmc report` and `refexmc rerun` through the command line: exit codes and outputs."""

import json
import re
import subprocess
import sys
from pathlib import Path

import pytest
from click.testing import CliRunner
from stored import campaign_copy, invoke_run, read_runs
from test_report import synthetic_runs, write_out

from refexmc.cli import main
from refexmc.report import make_report

ROOT = Path(__file__).resolve().parents[1]
IMAGES = re.compile(r"data:image/png;base64,[A-Za-z0-9+/=]*")  # base64 may spell anything


def report_subprocess(out, *args):
    """`refexmc report OUT ARGS...` in its own process, as CI calls it."""
    script = Path(sys.executable).with_name("refexmc")
    command = [str(script)] if script.is_file() else [sys.executable, "-c", "from refexmc.cli import main; main()"]
    return subprocess.run([*command, "report", str(out), *args], capture_output=True, text=True, timeout=300)


def page_text(out):
    """index.html without its base64 figures."""
    return IMAGES.sub("", (Path(out) / "report" / "index.html").read_text())


@pytest.fixture(scope="module")
def out(tmp_path_factory):
    out = tmp_path_factory.mktemp("cli") / "smoke"
    result = CliRunner().invoke(
        main, ["run", str(ROOT / "campaigns/smoke.yaml"), "--runs", "6", "-j", "1", "-o", str(out), "--no-progress"]
    )
    assert result.exit_code == 0, result.output
    return out


def test_report_passes_its_campaign_requirements(out):
    result = CliRunner().invoke(main, ["report", str(out), "--no-html"])
    assert result.exit_code == 0, result.output
    assert "verdict: PASS" in result.output
    assert (out / "report" / "summary.json").is_file()


def test_report_fails_a_requirement_with_exit_1(out):
    result = CliRunner().invoke(main, ["report", str(out), "--no-html", "--require", "fuel_remaining.min >= 0.99"])
    assert result.exit_code == 1, result.output
    assert "FAIL  fuel_remaining.min >= 0.99" in result.output


def test_report_unknown_metric_is_bad_input(out):
    result = CliRunner().invoke(main, ["report", str(out), "--require", "fuel_remainig.min >= 0.2"])
    assert result.exit_code == 2
    assert "did you mean 'fuel_remaining.min'" in result.output
    assert "Traceback" not in result.output


def test_rerun_reproduces_a_run_and_writes_its_history(out, tmp_path):
    dest = tmp_path / "run3.parquet"
    result = CliRunner().invoke(main, ["rerun", str(out), "3", "-o", str(dest)])
    assert result.exit_code == 0, result.output
    assert "summary row identical to the stored one" in result.output
    assert dest.is_file()
    bad = CliRunner().invoke(main, ["rerun", str(out), "99"])
    assert bad.exit_code == 2 and "run id 0..5" in bad.output
    # the message names the output directory and the argument, not a placeholder file
    assert bad.output.strip() == f"error: {out}: RUN_ID: expected a run id 0..5, got 99", bad.output


def test_report_of_an_incomplete_campaign_never_passes(tmp_path):
    """180 of 3,000 planned runs, all successful, manifest still 'running' (a killed campaign):
    every requirement holds on the stored runs, yet the verdict is INCOMPLETE with exit 1."""
    rows = synthetic_runs(n=180, errored=(), failed=())
    out = write_out(tmp_path / "out", rows, requirements=["fuel_remaining.min >= 0.20", "success_rate >= 1.0"])
    resolved = out / "campaign.resolved.yaml"
    resolved.write_text(resolved.read_text().replace("runs: 180", "runs: 3000"))
    (out / "manifest.json").write_text(json.dumps({"name": "synthetic", "status": "running", "chunk_size": 90}))
    result = report_subprocess(out)
    assert result.returncode == 1, result.stdout + result.stderr
    first = result.stdout.splitlines()[0]
    assert first.startswith("*** INCOMPLETE campaign: 180 of 3000 planned runs stored; manifest status is 'running'")
    assert "missing run ids 180-2999" in first
    assert "verdict: INCOMPLETE (2 of 2 requirements met)" in result.stdout
    assert "PASS" not in result.stdout and "PASS" not in page_text(out)
    page = page_text(out)
    assert page.index('class="banner">INCOMPLETE campaign') < page.index("<h1>")
    assert "INCOMPLETE: 2 of 2 requirements met on the stored runs; no overall verdict" in page
    summary = json.loads((out / "report" / "summary.json").read_text())
    assert summary["verdict"] == "INCOMPLETE" and summary["passed"] is False
    assert summary["banner"] in first and summary["completeness"]["missing_run_count"] == 2820


def test_incomplete_hint_resumes_with_the_runs_the_out_was_started_with(tmp_path):
    """OUT started with `--runs 180` from a file of 3,000 runs (same seed): finishing it needs
    `--runs 180` (without it --resume refuses a different campaign), and no --seed."""
    rows = synthetic_runs(n=120, errored=(), failed=())
    out = write_out(tmp_path / "out", rows, requirements=["success_rate >= 1.0"])
    resolved = out / "campaign.resolved.yaml"
    resolved.write_text(resolved.read_text().replace("runs: 120", "runs: 180"))
    campaign = tmp_path / "campaign.yaml"
    campaign.write_text("name: synthetic\nruns: 3000\nseed: 5\n")
    manifest = {"name": "synthetic", "status": "running", "chunk_size": 60, "campaign_file": str(campaign)}
    (out / "manifest.json").write_text(json.dumps(manifest))
    report = make_report(out, html=False)
    assert f"(finish it with `refexmc run {campaign} -o {out} --resume --runs 180`)" in report["summary"]["banner"]
    campaign.write_text("name: synthetic\nruns: 180\nseed: 6\n")  # the file's runs, another seed
    report = make_report(out, html=False)
    assert f"(finish it with `refexmc run {campaign} -o {out} --resume --seed 5`)" in report["summary"]["banner"]


def test_report_of_a_campaign_whose_flights_all_failed(tmp_path):
    """Thruster 5 failed in every run: no flight reaches hand-over; fuel_remaining.min >= 0.20 holds for the
    stored numbers (little propellant used before the timeout) but must FAIL, naming the failed runs."""
    source = campaign_copy("smoke.yaml", tmp_path, replace=[("mode: none", "mode: fixed\n  thrusters: [5]")])
    out = tmp_path / "failing"
    flown = invoke_run(source, "--runs", "3", "-j", "1", "-o", out, "--no-progress")
    assert flown.exit_code == 0, flown.output
    runs = read_runs(out)
    assert not runs["success"].any() and (runs["status"] == "ok").all()
    assert runs["fuel_remaining"].min() >= 0.20  # what the old report averaged into a PASS
    (reason,) = set(runs["failure_reason"])
    result = report_subprocess(out)
    assert result.returncode == 1, result.stdout + result.stderr
    text = result.stdout
    assert "FAIL  fuel_remaining.min >= 0.20" in text and "fails because of the failed flights 0, 1, 2" in text
    assert "FAIL  success_rate >= 1.0" in text and "verdict: FAIL (0 of 2 requirements met)" in text
    assert re.search(rf"failed flight +{reason} +3  runs 0, 1, 2", text), text
    assert "PASS" not in text and "PASS" not in page_text(out)
    summary = json.loads((out / "report" / "summary.json").read_text())
    fuel = summary["requirements"][0]
    assert fuel["actual"] is None and fuel["failing_run_ids"] == [0, 1, 2] and fuel["passed"] is False
    assert summary["columns"]["fuel_remaining"]["n"] == 0  # the tables cover successful flights: none
    assert summary["failure_reasons"] == [
        {"kind": "failed flight", "status": "ok", "reason": reason, "count": 3, "example_run_ids": [0, 1, 2]}
    ]
