"""`refexmc report` and `refexmc rerun` through the command line: exit codes and outputs."""

from pathlib import Path

import pytest
from click.testing import CliRunner

from refexmc.cli import main

ROOT = Path(__file__).resolve().parents[1]


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
