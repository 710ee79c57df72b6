"""Sweeps (campaign key ``sweep``, refexmc.campaign.sweep): each point is the campaign with the
point's value in the vehicle file, flown with the same run seeds as every other point; a killed
sweep resumes by flying only what is missing; `refexmc report` gives per-point statistics and the
curve over the points."""

import json
import os
import shutil
import signal
import subprocess
import sys
import time

import pandas as pd
import pytest
from click.testing import CliRunner
from scipy import stats as sps
from stored import ROOT, campaign_copy, invoke_run, read_runs, snapshot

from refexmc.campaign import run as run_module
from refexmc.campaign import storage
from refexmc.campaign.run import run_campaign
from refexmc.campaign.sweep import run_campaign_or_sweep
from refexmc.cli import main
from refexmc.config import sweep as sweep_config
from refexmc.config.errors import ConfigError
from refexmc.config.load import load_campaign
from refexmc.report import make_report

LOADS = (0.42, 0.76)  # kg: a load that runs dry in many runs, and the vehicle file's (000 sec. 2.1)
SWEPT = "p.rcs.propellant_kg"


def sweep_text(values):
    return (
        "sweep:\n  axes:\n    - parameter: rcs.propellant_kg\n"
        f"      values: [{', '.join(map(str, values))}]\n  metrics: [fuel_remaining]\n"
    )


@pytest.fixture
def sweep_file(tmp_path, monkeypatch):
    monkeypatch.setenv(run_module.CHUNK_SIZE_ENV, "4")  # three chunks per point
    path = campaign_copy(
        "refex-mc100.yaml",
        tmp_path,
        "sweep.yaml",
        [
            ("  rcs.propellant_kg: {dist: truncnorm, sigma: 0.0253, low: 0.57, high: 0.95}\n", ""),
            ("runs: 100", "runs: 12"),
        ],
    )
    path.write_text(path.read_text() + sweep_text(LOADS))
    return path


def own_campaign(tmp_path, load):
    """The point flown as a campaign of its own: refex-mc100 with the load in the vehicle file."""
    vehicle = tmp_path / f"refex-{load}.yaml"
    text = (ROOT / "configs/vehicles/refex.yaml").read_text()
    assert "  propellant_kg: 0.76\n" in text
    vehicle.write_text(text.replace("  propellant_kg: 0.76\n", f"  propellant_kg: {load}\n"))
    return campaign_copy(
        "refex-mc100.yaml",
        tmp_path,
        f"own-{load}.yaml",
        [
            ("  rcs.propellant_kg: {dist: truncnorm, sigma: 0.0253, low: 0.57, high: 0.95}\n", ""),
            ("runs: 100", "runs: 12"),
            (str(ROOT / "configs/vehicles/refex.yaml"), str(vehicle)),
        ],
    )


def test_each_point_is_the_campaign_with_its_value_and_shares_the_draws(sweep_file, tmp_path):
    result = run_campaign_or_sweep(sweep_file, tmp_path / "sweep", jobs=1)
    table = result["runs"]
    assert sorted(table["point"].unique()) == [0, 1] and len(table) == 24
    points = [table[table["point"] == k].drop(columns="point").reset_index(drop=True) for k in (0, 1)]
    for k, load in enumerate(LOADS):
        assert (points[k][SWEPT] == load).all()  # the point recorded in every run
    # common random numbers: every other input column is the same run by run at both points
    inputs = [c for c in points[0].columns if c.startswith("p.") and c != SWEPT]
    assert inputs and points[0][inputs].equals(points[1][inputs])
    assert points[0]["seed"].equals(points[1]["seed"])
    assert points[0]["success"].sum() < points[1]["success"].sum()  # 0.42 kg runs dry in some runs
    for k, load in enumerate(LOADS):
        own = run_campaign(own_campaign(tmp_path, load), tmp_path / f"own-{k}", jobs=1)["runs"]
        pd.testing.assert_frame_equal(points[k].drop(columns=SWEPT), own)
        point_report = make_report(tmp_path / "sweep" / f"points/{k:03d}", html=False)["summary"]
        own_report = make_report(tmp_path / f"own-{k}", html=False)["summary"]
        for key in ("success", "metrics", "requirements", "verdict"):
            assert point_report[key] == own_report[key], key
        own_columns = {c: s for c, s in own_report["columns"].items()}
        assert {c: s for c, s in point_report["columns"].items() if c != SWEPT} == own_columns


def test_resume_of_a_killed_sweep_flies_only_the_gaps(sweep_file, tmp_path):
    out = tmp_path / "sweep"
    whole = run_campaign_or_sweep(sweep_file, out, jobs=1)["runs"]
    # what a kill leaves: point 1 with one chunk missing (point 0 complete)
    shutil.rmtree(out / "report", ignore_errors=True)
    (out / "points/001/runs/part-00001.parquet").unlink()
    before = snapshot(out)
    result = invoke_run(sweep_file, "-o", out, "--resume", "-j", "1", "--no-progress")
    assert result.exit_code == 0, result.output
    after = snapshot(out)
    flown = sorted(str(p) for p in after if p not in before or after[p] != before[p])
    parts = [p for p in flown if "/runs/" in p or "/histories/" in p]
    assert parts == ["points/001/histories/part-00001.parquet", "points/001/runs/part-00001.parquet"]
    tables = [read_runs(out / f"points/{k:03d}") for k in (0, 1)]
    pd.testing.assert_frame_equal(pd.concat(tables, ignore_index=True), whole.drop(columns="point"))


def test_a_changed_sweep_is_not_resumed(sweep_file, tmp_path):
    out = tmp_path / "sweep"
    run_campaign_or_sweep(sweep_file, out, jobs=1, runs=2)
    changed = sweep_file.read_text().replace("values: [0.42, 0.76]", "values: [0.42, 0.5]")
    sweep_file.write_text(changed)
    result = invoke_run(sweep_file, "-o", out, "--resume", "--runs", "2", "-j", "1")
    assert result.exit_code == 2 and "different campaign (differs in sweep)" in result.output


def test_sweep_report_gives_each_point_and_the_curve(sweep_file, tmp_path):
    out = tmp_path / "sweep"
    run_campaign_or_sweep(sweep_file, out, jobs=1)
    result = make_report(out)
    assert result["passed"] and result["verdict"] == "COMPLETE"
    summary = json.loads((out / "report/summary.json").read_text())
    assert [p["values"] for p in summary["points"]] == [{"rcs.propellant_kg": v} for v in LOADS]
    for point in summary["points"]:
        runs = read_runs(out / point["folder"])
        s, n = int(runs["success"].sum()), len(runs)
        assert point["successes"] == s and point["runs"] == n
        # the two-sided 95 % Clopper-Pearson interval from the beta quantiles
        low = sps.beta.ppf(0.025, s, n - s + 1) if s > 0 else 0.0
        high = sps.beta.ppf(0.975, s + 1, n - s) if s < n else 1.0
        assert point["success_ci95"] == pytest.approx([low, high], rel=1e-12)
        fuel = runs.loc[runs["success"], "fuel_remaining"]
        assert point["metrics"]["fuel_remaining"]["p50"] == pytest.approx(fuel.median(), rel=1e-12)
        assert (out / point["folder"] / "report/index.html").is_file()
    assert (out / "report/sweep.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "P(success)" in (out / "report/index.html").read_text()
    assert "sweep over rcs.propellant_kg: 2 points" in result["text"]


@pytest.mark.parametrize(
    "axis, expected",
    [
        ("parameter: rcs.propellant_kg\n      values: [-0.1]", "outside the physical range"),
        ("parameter: initial_state.rates_deg_s\n      values: [1.0]", "expected a scalar parameter path"),
        ("parameter: rcs.isp_s\n      values: [60]\n      range: {start: 1, stop: 2, count: 3}", "exactly one"),
        ("parameter: rcs.isp_s\n      range: {start: 60, stop: 70, count: 1}", "expected a value >= 2"),
        ("parameter: rcs.isp_s\n      values: [60]\n      step: 1", "step"),
    ],
)
def test_bad_sweeps_are_refused_with_their_key_path(tmp_path, axis, expected):
    path = campaign_copy("nominal.yaml", tmp_path)
    path.write_text(path.read_text() + f"sweep:\n  axes:\n    - {axis}\n")
    with pytest.raises(ConfigError, match=expected) as error:
        load_campaign(path)
    assert "sweep" in str(error.value)


def test_a_swept_path_cannot_also_be_dispersed(tmp_path):
    path = campaign_copy("refex-mc100.yaml", tmp_path)
    path.write_text(path.read_text() + "sweep:\n  axes:\n    - parameter: rcs.propellant_kg\n      values: [0.5]\n")
    result = invoke_run(path, "-o", tmp_path / "out")
    assert result.exit_code == 2 and "refex-mc100.yaml:76: sweep.axes.0.parameter: " in result.output
    assert "swept and dispersed" in result.output and "Traceback" not in result.output
    assert not (tmp_path / "out").exists()


def test_an_unfinished_sweep_reports_incomplete_and_rerun_points_to_a_point(sweep_file, tmp_path):
    out = tmp_path / "sweep"
    run_campaign_or_sweep(sweep_file, out, jobs=1, runs=2)
    shutil.rmtree(out / "points/001")  # killed before the second point started
    result = make_report(out, html=False)
    assert result["verdict"] == "INCOMPLETE" and not result["passed"]
    assert result["summary"]["incomplete_points"] == [1] and len(result["summary"]["points"]) == 1
    rerun = CliRunner().invoke(main, ["rerun", str(out), "0"])
    assert rerun.exit_code == 2 and "OUT/points/NNN" in rerun.output


def test_run_campaign_alone_refuses_a_sweep(sweep_file, tmp_path):
    with pytest.raises(ConfigError, match="a sweep flies with"):
        run_campaign(sweep_file, tmp_path / "out")
    assert not (tmp_path / "out").exists()


@pytest.mark.slow
def test_a_sweep_killed_mid_point_resumes_to_the_uninterrupted_tables(tmp_path):
    """SIGKILL of `refexmc run` (CLI and workers) once the second point has a part; --resume flies
    the rest of that point and the third, keeps what was done and gives the uninterrupted tables."""
    path = campaign_copy(
        "refex-mc100.yaml",
        tmp_path,
        "sweep.yaml",
        [
            ("  rcs.propellant_kg: {dist: truncnorm, sigma: 0.0253, low: 0.57, high: 0.95}\n", ""),
            ("runs: 100", "runs: 60"),
        ],
    )
    path.write_text(path.read_text() + sweep_text((0.42, 0.6, 0.76)))
    out = tmp_path / "killed"
    env = {**os.environ, run_module.CHUNK_SIZE_ENV: "5"}  # 12 chunks per point
    command = [sys.executable, "-m", "refexmc.cli", "run", str(path), "-o", str(out), "-j", "2", "--no-progress"]
    process = subprocess.Popen(command, env=env, start_new_session=True, stderr=subprocess.PIPE)
    deadline = time.monotonic() + 180  # a cold numba cache compiles first
    second = out / "points/001/runs"
    while not second.is_dir() or not any(second.glob("part-*.parquet")):
        assert process.poll() is None, process.stderr.read().decode()
        assert time.monotonic() < deadline, "no part of the second point appeared"
        time.sleep(0.005)
    os.killpg(process.pid, signal.SIGKILL)
    process.wait()
    process.stderr.close()
    kept = {p: v for p, v in snapshot(out).items() if p.suffix == ".parquet"}
    assert len([p for p in kept if "001/runs" in str(p)]) < 12  # the second point is not complete
    resumed = invoke_run(path, "-o", out, "--resume", "-j", 2, "--no-progress")
    assert resumed.exit_code == 0, resumed.output
    after = snapshot(out)
    assert all(after[p] == v for p, v in kept.items()), "a part flown before the kill was written again"
    reference = tmp_path / "reference"
    assert invoke_run(path, "-o", reference, "-j", 2, "--no-progress").exit_code == 0
    for k in range(3):
        pd.testing.assert_frame_equal(read_runs(out / f"points/{k:03d}"), read_runs(reference / f"points/{k:03d}"))
    assert storage.read_manifest(out)["status"] == "complete"


def test_a_grid_of_two_axes_flies_every_combination(tmp_path):
    path = campaign_copy("nominal.yaml", tmp_path, replace=[("runs: 1", "runs: 2")])
    path.write_text(
        path.read_text() + "sweep:\n  axes:\n    - parameter: rcs.propellant_kg\n      values: [0.5, 0.76]\n"
        "    - parameter: rcs.isp_s\n      range: {start: 60, stop: 80, count: 3}\n"
    )
    campaign = load_campaign(path)
    points = sweep_config.points(campaign)
    assert (
        points[:4]
        == [
            {"rcs.propellant_kg": 0.5, "rcs.isp_s": 60.0},
            {"rcs.propellant_kg": 0.5, "rcs.isp_s": 70.0},
            {"rcs.propellant_kg": 0.5, "rcs.isp_s": 80.0},
            {"rcs.propellant_kg": 0.76, "rcs.isp_s": 60.0},
        ]
        and len(points) == 6
    )
    plain = sweep_config.point_campaign(campaign, 4, points[4])
    assert plain["vehicle"]["rcs"]["isp_s"] == 70.0 and plain["vehicle"]["rcs"]["propellant_kg"] == 0.76
    assert plain["dispersions"]["rcs.isp_s"] == {"dist": "constant", "value": 70.0} and "sweep" not in plain
    out = tmp_path / "grid"
    table = run_campaign_or_sweep(path, out, jobs=1)["runs"]
    assert len(table) == 12 and (table.groupby("point")["p.rcs.isp_s"].first() == [60, 70, 80] * 2).all()
    # the nominal flight burns more propellant at a lower specific impulse (the same impulse)
    nominal = table[table["run_id"] == 0].set_index("point")["fuel_used_kg"]
    assert nominal[0] > nominal[1] > nominal[2] and nominal[3] == pytest.approx(nominal[0], rel=1e-12)
    result = make_report(out)
    assert result["passed"] and len(result["summary"]["points"]) == 6
    assert (out / "report/sweep.png").is_file()


def test_sweeping_a_dispersion_parameter_scales_the_same_draws(tmp_path):
    """A sweep of a distribution's sigma: the same uniforms at every point (common random numbers),
    so every run's deviation from the mean scales with sigma (docs/campaigns.md sec. 5)."""
    path = campaign_copy(
        "nominal.yaml",
        tmp_path,
        replace=[("runs: 1", "runs: 6"), ("dispersions: {}", "dispersions:\n  rcs.isp_s: {dist: normal, sigma: 1.0}")],
    )
    path.write_text(
        path.read_text() + "sweep:\n  axes:\n    - parameter: rcs.isp_s\n      dispersion: sigma\n"
        "      values: [0.5, 2.0]\n"
    )
    table = run_campaign_or_sweep(path, tmp_path / "out", jobs=1)["runs"]
    isp = [table.loc[table["point"] == k, "p.rcs.isp_s"].to_numpy() - 70.0 for k in (0, 1)]
    assert isp[0][0] == isp[1][0] == 0.0  # run 0: the nominal flight at every point
    assert len(set(isp[0][1:])) == 5
    assert isp[1][1:] == pytest.approx(4.0 * isp[0][1:], rel=1e-12)
    manifest = storage.read_manifest(tmp_path / "out")
    assert manifest["sweep"]["axes"] == ["rcs.isp_s:sigma"]
    too_wide = path.read_text().replace("values: [0.5, 2.0]", "values: [0.5, 10.0]")
    path.write_text(too_wide)
    with pytest.raises(ConfigError, match="at sigma = 10: .*range") as error:
        load_campaign(path)
    assert error.value.path[:3] == ("sweep", "axes", 0)
    path.write_text(too_wide.replace("dispersion: sigma", "dispersion: low"))
    with pytest.raises(ConfigError, match="'normal' has no parameter 'low' to sweep; expected one of: sigma, mean"):
        load_campaign(path)


def test_the_yaml_examples_of_studies_md_validate(tmp_path):
    """Each ```yaml block of docs/studies.md, added to refex-mc100 without its propellant dispersion
    (a sweep of the blow-down feed: to the surveyor hop without that path's dispersion)."""
    import re

    import yaml

    text = (ROOT / "docs/studies.md").read_text()
    blocks = [yaml.safe_load(b) for b in re.findall(r"```yaml\n(.*?)```", text, flags=re.S)]
    assert len(blocks) >= 2
    for k, block in enumerate(blocks):
        axes = (block.get("sweep") or {}).get("axes", [])
        swept = [axis["parameter"] for axis in axes if "dispersion" not in axis]  # file values: not dispersed
        feed = any(p.startswith("rcs.feed.") for p in swept)
        base = yaml.safe_load((ROOT / "campaigns" / ("surveyor-hop.yaml" if feed else "refex-mc100.yaml")).read_text())
        for path in [*swept, "rcs.propellant_kg"]:
            base["dispersions"].pop(path, None)
        data = {**base, **block}
        for part in ("vehicle", "mission"):
            data[part] = str((ROOT / "campaigns" / data[part]).resolve())
        path = tmp_path / f"example-{k}.yaml"
        path.write_text(yaml.safe_dump(data))
        load_campaign(path)


def test_the_sweep_figure_fits_its_page_and_draws_each_requirement():
    """Issue 34: four panels side by side were 2080 px on a 1300 px page, with no requirement
    lines; now two a row (at most 1280 px) and each panel's metric with its bound."""
    from refexmc.report.studies import SWEEP_DPI, sweep_figure, sweep_matplotlib_figure

    metrics = ["position_error_end_m", "t_hop_s", "tank_pressure_end_pa"]
    requirements = [
        {"requirement": "success_rate >= 0.95", "metric": "success_rate", "value": 0.95, "passed": True},
        {"requirement": "position_error_end_m.p95 <= 0.05", "metric": "position_error_end_m.p95", "value": 0.05},
        {"requirement": "tank_pressure_end_pa.p5 >= 1e6", "metric": "tank_pressure_end_pa.p5", "value": 1.0e6},
    ]
    points = [
        {
            "values": {"rcs.feed.tank_volume_m3": v},
            "success_rate": 1.0,
            "success_ci95": [0.7, 1.0],
            "requirements": requirements,
            "metrics": {m: {"p1": k, "p50": k + 1.0, "p99": k + 2.0} for k, m in enumerate(metrics)},
        }
        for v in (0.6e-3, 0.8e-3, 1.0e-3)
    ]
    summary = {"axes": ["rcs.feed.tank_volume_m3"], "metrics": metrics, "points": points}
    png = sweep_figure(summary)
    assert int.from_bytes(png[16:20], "big") <= 1300  # the PNG's width, px
    figure = sweep_matplotlib_figure(summary)
    assert figure.get_size_inches()[0] * SWEEP_DPI <= 1300
    lines = {
        ax.get_title(): sorted(line.get_ydata()[0] for line in ax.get_lines() if line.get_linestyle() == "--")
        for ax in figure.axes
    }
    assert lines == {
        "P(success)": [0.95],
        "position_error_end_m": [0.05],
        "t_hop_s": [],
        "tank_pressure_end_pa": [1.0e6],
    }
