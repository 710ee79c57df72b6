"""The blocked deflection swept (issue 24, 003 Fig. 8): campaigns/x38-blocked-flap-sweep.yaml flown
a few runs per point; each point's swept column holds its level, run 0 of each point is the direct
entry with the flap blocked there, the other draws are the same at every point; the report draws
the curve; bad entry sweeps are exit 2 with file, line and key path, nothing written."""

import json
import re
import shutil
from pathlib import Path

import pytest
from click.testing import CliRunner

from refexmc import simulate
from refexmc.campaign.sweep import run_campaign_or_sweep
from refexmc.cli import main
from refexmc.config import entry as config_entry
from refexmc.config.load import load_mission, load_vehicle

ROOT = Path(__file__).resolve().parents[1]
SWEEP = ROOT / "campaigns/x38-blocked-flap-sweep.yaml"
SWEPT = "p.entry_flight.blocked_flap.deflection_deg"
LEVELS = [10.0, 12.0, 14.0, 16.0, 18.0, 20.0]


@pytest.fixture(scope="module")
def swept(tmp_path_factory):
    out = tmp_path_factory.mktemp("x38-sweep") / "out"
    return run_campaign_or_sweep(SWEEP, out, runs=3, jobs=1), out


def test_each_point_flies_its_blocked_deflection_with_the_same_other_draws(swept):
    result, _ = swept
    table = result["runs"]
    assert (table["status"] == "ok").all() and len(table) == 3 * len(LEVELS)
    for point, level in enumerate(LEVELS):
        rows = table[table["point"] == point]
        assert list(rows[SWEPT]) == [level] * 3
    # common random numbers: every other input is drawn the same, run by run, at every point
    for column in ("p.entry_flight.density_scale", "p.inertia_kg_m2.yy", "p.entry_flight.rcs_delay_ms"):
        assert table.groupby("run_id")[column].nunique().eq(1).all(), column
    # and the blocked deflection moves the flight: 003 Fig. 7, a lower flap gives less cross range
    nominal = table[table["run_id"] == 0].sort_values("point")
    assert nominal["cross_range_m"].is_monotonic_increasing and nominal["cross_range_m"].nunique() == len(LEVELS)


@pytest.mark.parametrize("point", [0, 5])
def test_run_0_of_a_point_is_the_direct_entry_blocked_at_its_level(swept, point):
    result, _ = swept
    row = result["runs"].query(f"point == {point} and run_id == 0").iloc[0]
    mission = load_mission(ROOT / "configs/missions/x38-entry-right-flap-blocked.yaml")
    mission["entry_flight"]["blocked_flap"]["deflection_deg"] = LEVELS[point]
    direct = simulate.fly_entry(
        *config_entry.entry_flight_from_mission(load_vehicle(ROOT / "configs/vehicles/x38.yaml"), mission)
    )
    for name, value in direct.runs_values().items():
        assert row[name] == value, name


def test_the_report_draws_success_and_propellant_against_the_blocked_deflection(swept):
    _, out = swept
    result = CliRunner().invoke(main, ["report", str(out), "--no-html"])
    assert result.exit_code == 0, result.output
    assert "sweep over entry_flight.blocked_flap.deflection_deg: 6 points" in result.output
    summary = json.loads((out / "report/summary.json").read_text())
    assert [p["values"]["entry_flight.blocked_flap.deflection_deg"] for p in summary["points"]] == LEVELS
    assert summary["metrics"][0] == "rcs_propellant_kg"
    assert [p["successes"] for p in summary["points"]] == [3] * len(LEVELS)
    propellant = [p["metrics"]["rcs_propellant_kg"]["p50"] for p in summary["points"]]
    assert all(0.0 < kg < 100.0 for kg in propellant)  # 003: under 100 kg with a flap blocked
    assert (out / "points/002/report/summary.json").is_file()  # each point's own report


TEXT = (
    SWEEP.read_text()
    .replace("../configs/vehicles/x38.yaml", "x38.yaml")
    .replace("../configs/missions/x38-entry-right-flap-blocked.yaml", "mission.yaml")
)
AXIS = "    - parameter: entry_flight.blocked_flap.deflection_deg"
VALUES = "      values: [10.0, 12.0, 14.0, 16.0, 18.0, 20.0]"


@pytest.mark.parametrize(
    ("case", "text", "words"),
    [
        (
            "beyond-the-flap-limits",
            TEXT.replace(VALUES, "      values: [10.0, 45.0]"),
            ["sweep.axes.0.values", "within the flap limits [-10.0, 40.0] deg, got 45"],
        ),
        (
            "an-rcs-delay-of-a-control-period",
            TEXT.replace("  entry_flight.rcs_delay_ms: {dist", "  mass_kg_unused: {dist")
            .replace("  mass_kg_unused: {dist: truncnorm, sigma: 10.0, low: 0.0, high: 60.0}\n", "")
            .replace(AXIS, "    - parameter: entry_flight.rcs_delay_ms")
            .replace(VALUES, "      values: [0.0, 50.0, 100.0]"),
            ["sweep.axes.0.values", "within the control period [0.0, 100.0) ms, got 100"],
        ),
        (
            "a-path-the-entry-does-not-fly",
            TEXT.replace(AXIS, "    - parameter: rcs.isp_s").replace(VALUES, "      values: [200.0, 220.0]"),
            ["sweep.axes.0.values", "at 200: 'rcs.isp_s' is not flown by an entry mission"],
        ),
        (
            "a-dispersion-reaching-beyond-the-flap-limits",
            TEXT.replace(
                "dispersions:\n",
                "dispersions:\n  entry_flight.blocked_flap.deflection_deg: {dist: uniform, low: 10.0, high: 20.0}\n",
            )
            .replace(AXIS, AXIS + "\n      dispersion: high")
            .replace(VALUES, "      values: [20.0, 30.0, 50.0]"),
            ["sweep.axes.0.values", "at high = 50: expected draws within the flap limits [-10.0, 40.0] deg"],
        ),
        (
            "swept-and-dispersed",
            TEXT.replace(
                "dispersions:\n",
                "dispersions:\n  entry_flight.blocked_flap.deflection_deg: {dist: uniform, low: 10.0, high: 20.0}\n",
            ),
            ["sweep.axes.0.parameter", "swept and dispersed"],
        ),
    ],
    ids=lambda v: v if isinstance(v, str) and "\n" not in v and len(v) < 60 else "",
)
def test_bad_entry_sweeps_are_exit_2_with_file_line_and_key_path(case, text, words, tmp_path):
    shutil.copy(ROOT / "configs/vehicles/x38.yaml", tmp_path / "x38.yaml")
    shutil.copy(ROOT / "configs/missions/x38-entry-right-flap-blocked.yaml", tmp_path / "mission.yaml")
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    assert text != TEXT
    result = CliRunner().invoke(main, ["run", str(path), "-o", str(tmp_path / "out")])
    assert result.exit_code == 2, result.output
    assert "Traceback" not in result.output
    assert re.search(rf"{re.escape(str(path))}:\d+: ", result.output), result.output
    for word in words:
        assert word in result.output, f"{word!r} not in {result.output!r}"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.yaml", "mission.yaml", "x38.yaml"]
