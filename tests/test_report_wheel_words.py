"""A wheel vehicle (IRASSI) reads no propellant words: the report leaves out the propellant columns it
does not produce and names them in the terminal as on the page; `rerun` prints the end angle with
digits that show it (docs/report.md "Columns the mission does not produce")."""

import math

import pytest
from test_factors import IRASSI_MODES, irassi_like_runs
from test_report import write_out

from refexmc.campaign.rerun import summary_lines
from refexmc.report import make_report


@pytest.fixture(scope="module")
def wheel_report(tmp_path_factory):
    rows = irassi_like_runs(n=40)
    for row in rows:  # as a wheel vehicle's runs table has them: no propellant load, nothing used, no valves
        row.update(fuel_remaining=math.nan, fuel_used_kg=0.0, failed_thrusters="")
        for k in range(1, 9):
            row.pop(f"pulses_{k}")
    out = write_out(
        tmp_path_factory.mktemp("wheels") / "out",
        rows,
        requirements=["pointing_max_arcsec.p99 <= 3.0"],
        histories=False,
        modes=IRASSI_MODES,
        vehicle="irassi",
    )
    report = make_report(out, html=True)
    return report, (out / "report" / "index.html").read_text()


def test_a_wheel_vehicle_reads_no_propellant(wheel_report):
    report, page = wheel_report
    plan = report["summary"]["outputs"]
    assert plan["not_produced"] == ["fuel_remaining", "fuel_used_kg"]
    assert "fuel_used_kg" not in plan["constant_columns"] and "fuel_used_kg" not in plan["other_columns"]
    assert "fuel_used_kg = 0" not in report["text"]
    assert "propellant" not in report["text"].lower()
    assert "propellant" not in page.lower(), page[page.lower().find("propellant") - 200 :][:400]


def test_the_terminal_names_the_columns_not_produced_as_the_page_does(wheel_report):
    report, page = wheel_report
    line = "not produced by this mission, left out: fuel_remaining, fuel_used_kg"
    assert line in report["text"]
    assert line.capitalize() in page


def rerun_result(row, actuation):
    mission = {"modes": [{"name": "science", "exit": [{"mission_time_s": 79200.0}]}]}
    vehicle = {"flight_software": {"actuation": actuation}}
    return {"row": row, "campaign": {"name": "c", "mission": mission, "vehicle": vehicle}}


def test_rerun_prints_a_wheel_vehicles_run_without_propellant_and_its_small_angle_in_arcsec():
    row = {
        "run_id": 1,
        "success": True,
        "status": "ok",
        "failure_reason": None,
        "fuel_remaining": math.nan,
        "fuel_used_kg": 0.0,
        "t_end_s": 79200.0,
        "attitude_error_end_deg": 4.0e-5,  # 0.144 arcsec, printed "0.000 deg" before
        "failed_thrusters": "",
        "failed_wheels": "2",
    }
    text = "\n".join(summary_lines(rerun_result(row, "wheels")))
    assert "propellant" not in text and "nan" not in text
    assert "total angle error 0.144 arcsec" in text
    assert "failed thrusters" not in text and "failed wheels [2]" in text
    thrusters = dict(row, fuel_remaining=0.42, attitude_error_end_deg=1.25, failed_wheels=None)
    thrusters.pop("failed_wheels")
    text = "\n".join(summary_lines(rerun_result(thrusters, "pwpf_table")))
    assert "propellant remaining 42.0 %" in text and "total angle error 1.250 deg" in text
    assert "failed thrusters []" in text


def test_refexmc_rerun_prints_the_summary_lines(monkeypatch, tmp_path):
    """The command prints :func:`summary_lines` (it printed its own propellant line before)."""
    from click.testing import CliRunner

    from refexmc.campaign import rerun as rerun_module
    from refexmc.cli import main

    row = {"run_id": 1, "success": True, "status": "ok", "failure_reason": None, "fuel_remaining": math.nan}
    row.update(fuel_used_kg=0.0, t_end_s=79200.0, attitude_error_end_deg=4.0e-5, failed_thrusters="")
    result = {**rerun_result(row, "wheels"), "path": tmp_path / "run-1.parquet", "stored": row, "differ": []}
    monkeypatch.setattr(rerun_module, "rerun", lambda *args, **kwargs: result)
    printed = CliRunner().invoke(main, ["rerun", str(tmp_path), "1"])
    assert printed.exit_code == 0, printed.output
    lines = summary_lines(result)
    assert printed.output.splitlines()[: len(lines)] == lines and "propellant" not in printed.output
