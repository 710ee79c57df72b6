"""Command line: exit codes, outputs of interface.md, nothing written on bad input."""

import json
import re
from pathlib import Path

import pyarrow.parquet as pq
import pytest
import yaml
from click.testing import CliRunner

from refexmc.cli import main

ROOT = Path(__file__).resolve().parents[1]
NOMINAL = ROOT / "campaigns/nominal.yaml"
VEHICLE = ROOT / "configs/vehicles/refex.yaml"

# 000 eq. 2-3 and Table 1, as printed
OMEGA_DOT_MAX = {"low": [0.037, 0.019, 0.009], "high": [0.152, 0.077, 0.038]}
GAINS = {
    "low": {"kp": [3.55, 1.79, 0.88], "kd": [3.77, 2.68, 1.88]},
    "high": {"kp": [14.69, 7.41, 3.65], "kd": [7.67, 5.45, 3.82]},
}


def _printed_equal(value, published, decimals):
    # equal at printed precision: within half a unit of the last printed digit (+ float slack)
    return abs(value - published) <= 0.5 * 10.0**-decimals + 1e-12


def test_inspect_json_reproduces_the_paper():
    result = CliRunner().invoke(main, ["inspect", str(VEHICLE), "--json"])
    assert result.exit_code == 0, result.output
    info = json.loads(result.output)
    for level in ("low", "high"):
        for value, published in zip(info["omega_dot_max_rad_s2"][level], OMEGA_DOT_MAX[level], strict=True):
            assert _printed_equal(value, published, 3), (level, value, published)
        for key in ("kp", "kd"):
            for value, published in zip(info["gains"][level][key], GAINS[level][key], strict=True):
                assert _printed_equal(value, published, 2), (level, key, value, published)
    assert info["f_min_fraction"] == pytest.approx(0.375)
    assert info["allocation"]["+y-z"] == [1, 2, 5, 7]


def test_inspect_gives_the_valve_pulse_quantities_and_warns_on_a_mismatched_correction():
    """Per thrust level the full-thrust width of the 25 ms hardware pulse (~75 ms) and the
    impulse-matching correction (~50 ms) with the 45 ms fall; with 000 Table 2's fall the matching
    correction is ~100 ms and the text warns that the configured 50 ms does not match it."""
    info = json.loads(CliRunner().invoke(main, ["inspect", str(VEHICLE), "--json"]).output)
    for level in ("low", "high"):
        assert abs(info["pulse_equivalent_ms"][level] - 75.0) <= 5.0
        assert abs(info["pulse_correction_matching_ms"][level] - 50.0) <= 5.0
    text = CliRunner().invoke(main, ["inspect", str(VEHICLE)]).output
    assert "WARNING" not in text
    printed = [float(v) for v in re.findall(r"impulse-matching correction ([0-9.-]+) ms", text)]
    expected = [info["pulse_correction_matching_ms"][level] for level in ("low", "high")]
    assert printed == pytest.approx(expected, abs=0.005)  # printed to 0.01 ms
    table2 = VEHICLE.with_name("refex-table2-fall.yaml")
    variant = CliRunner().invoke(main, ["inspect", str(table2)])
    assert variant.exit_code == 0
    matching = json.loads(CliRunner().invoke(main, ["inspect", str(table2), "--json"]).output)
    warnings = [line for line in variant.output.splitlines() if "WARNING" in line]
    assert len(warnings) == 2
    for line, level in zip(warnings, ("low", "high"), strict=True):
        value = matching["pulse_correction_matching_ms"][level]
        assert f"{level}-thrust impulse-matching correction {value:.2f} ms" in line


def test_inspect_text_and_campaign_input():
    result = CliRunner().invoke(main, ["inspect", str(NOMINAL)])
    assert result.exit_code == 0, result.output
    assert "f_min 37.5 %" in result.output
    assert "Kp" in result.output


def test_validate_good_and_bad(tmp_path):
    runner = CliRunner()
    ok = runner.invoke(main, ["validate", str(NOMINAL), str(VEHICLE)])
    assert ok.exit_code == 0, ok.output
    bad = tmp_path / "bad.yaml"
    bad.write_text(NOMINAL.read_text().replace("runs: 1", "runs: 0"))
    result = runner.invoke(main, ["validate", str(NOMINAL), str(bad)])
    assert result.exit_code == 2
    assert "runs: expected a value >= 1" in result.output
    assert "Traceback" not in result.output


def test_run_writes_the_output_contract(tmp_path):
    out = tmp_path / "out"
    result = CliRunner().invoke(main, ["run", str(NOMINAL), "-o", str(out), "--no-progress"])
    assert result.exit_code == 0, result.output
    assert "succeeded" in result.output
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["status"] == "complete"
    for key in ("refexmc", "python", "numpy", "numba", "campaign_sha256", "seed", "runs", "started", "finished"):
        assert key in manifest
    resolved = yaml.safe_load((out / "campaign.resolved.yaml").read_text())
    assert resolved["vehicle"]["name"] == "refex" and resolved["mission"]["name"] == "refex-exo"
    runs = pq.read_table(out / "runs").to_pandas()
    for column in (
        "run_id seed status success failure_reason failed_thrusters fuel_remaining fuel_used_kg t_end_s "
        "t_ncm_s t_rdm1_s t_sam_s t_ssm_s t_rdm2_s t_eam_s t_geem_s attitude_error_end_deg pulses_1 pulses_8"
    ).split():
        assert column in runs.columns, column
    assert runs["run_id"].dtype == "int64" and runs["seed"].dtype == "int64"
    assert runs.loc[0, "status"] == "ok" and bool(runs.loc[0, "success"])
    assert runs.loc[0, "failed_thrusters"] == ""
    history = pq.read_table(out / "histories").to_pandas()
    for column in (
        "run_id t_s mode theta_t_deg omega_m_deg_s theta_e_x_deg theta_e_y_deg theta_e_z_deg omega_e_x_deg_s "
        "omega_e_y_deg_s omega_e_z_deg_s fuel_remaining valves_open"
    ).split():
        assert column in history.columns, column
    assert set(history["mode"].astype(str)) == {"NCM", "RDM1", "SAM", "SSM", "RDM2", "EAM", "GEEM"}
    # 2 Hz history over a ~230 s flight
    assert abs(len(history) - 2.0 * runs.loc[0, "t_end_s"]) <= 3


def test_existing_output_is_refused_and_untouched(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    keep = out / "keep.txt"
    keep.write_text("precious")
    result = CliRunner().invoke(main, ["run", str(NOMINAL), "-o", str(out)])
    assert result.exit_code == 2
    assert "exists" in result.output and "Traceback" not in result.output
    assert keep.read_text() == "precious"
    assert sorted(p.name for p in out.iterdir()) == ["keep.txt"]


def test_bad_campaign_writes_nothing(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text(NOMINAL.read_text().replace("../configs", str(ROOT / "configs")).replace("seed:", "sed:"))
    out = tmp_path / "out"
    result = CliRunner().invoke(main, ["run", str(bad), "-o", str(out)])
    assert result.exit_code == 2
    assert "did you mean 'seed'" in result.output
    assert not out.exists()


def test_fixed_failure_campaign_records_failed_thrusters(tmp_path):
    campaign = NOMINAL.read_text().replace("../configs", str(ROOT / "configs"))
    campaign = campaign.replace("  mode: none", "  mode: fixed\n  thrusters: [8, 1]")
    path = tmp_path / "fail.yaml"
    path.write_text(campaign)
    out = tmp_path / "out"
    result = CliRunner().invoke(main, ["run", str(path), "-o", str(out), "--no-progress"])
    assert result.exit_code == 0, result.output
    runs = pq.read_table(out / "runs").to_pandas()
    assert runs.loc[0, "failed_thrusters"] == "1,8"
    assert bool(runs.loc[0, "success"])


def test_overwrite_and_resume(tmp_path):
    out = tmp_path / "out"
    runner = CliRunner()
    assert runner.invoke(main, ["run", str(NOMINAL), "-o", str(out), "--no-progress"]).exit_code == 0
    first = pq.read_table(out / "runs").to_pandas()
    again = runner.invoke(main, ["run", str(NOMINAL), "-o", str(out), "--overwrite", "--no-progress"])
    assert again.exit_code == 0
    assert pq.read_table(out / "runs").to_pandas().equals(first)
    part = out / "runs" / "part-00000.parquet"
    mtime = part.stat().st_mtime_ns
    resumed = runner.invoke(main, ["run", str(NOMINAL), "-o", str(out), "--resume", "--no-progress"])
    assert resumed.exit_code == 0
    assert part.stat().st_mtime_ns == mtime  # nothing recomputed
    both = runner.invoke(main, ["run", str(NOMINAL), "-o", str(out), "--resume", "--overwrite"])
    assert both.exit_code == 2
