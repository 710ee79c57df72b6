"""X-38 entry campaigns (issue 24): campaigns/x38-blocked-flap.yaml flown a few runs through
run_campaign; each run's metrics equal the direct simulate.fly_entry of the same drawn values;
the dispersions reach the flight; bad entry-campaign input is exit 2 with file, line and key path."""

import json
import re
import shutil
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest
from click.testing import CliRunner

from refexmc import simulate
from refexmc.campaign.run import run_campaign
from refexmc.campaign.sampling import Sampler
from refexmc.cli import main
from refexmc.config import entry as config_entry
from refexmc.config.load import load_campaign

ROOT = Path(__file__).resolve().parents[1]
BLOCKED = ROOT / "campaigns/x38-blocked-flap.yaml"


@pytest.fixture(scope="module")
def flown(tmp_path_factory):
    out = tmp_path_factory.mktemp("x38") / "out"
    result = run_campaign(BLOCKED, out=out, runs=4, jobs=1)
    return result, out


def test_a_few_runs_fly_and_each_equals_the_direct_flight_of_its_draws(flown):
    result, _ = flown
    runs = result["runs"].sort_values("run_id")
    assert list(runs["status"]) == ["ok"] * 4
    campaign = load_campaign(BLOCKED)
    sampler = Sampler(campaign)
    for _, row in runs.iterrows():
        values = sampler.values(int(row["run_id"]))
        # the direct route: the vehicle and mission with the drawn values written in by hand
        vehicle, mission = dict(campaign["vehicle"]), {**campaign["mission"]}
        vehicle["mass_kg"] = float(values["mass_kg"][0])
        flight = {**mission["entry_flight"]}
        flight["state"] = {**flight["state"]}
        for key in ("altitude_m", "speed_m_s", "flight_path_angle_deg", "heading_deg"):
            flight["state"][key] = float(values[f"entry_flight.state.{key}"][0])
        flight["blocked_flap"] = {
            **flight["blocked_flap"],
            "deflection_deg": float(values["entry_flight.blocked_flap.deflection_deg"][0]),
        }
        flight["rcs_delay_ms"] = float(values["entry_flight.rcs_delay_ms"][0])
        mission["entry_flight"] = flight
        xx, yy, zz, xy, xz, yz = values["inertia_kg_m2"]
        inertia = [[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]]
        factors = {
            path.rsplit(".", 1)[1]: float(value[0])
            for path, value in values.items()
            if path.startswith("entry_flight.coefficient_scale.")
        }
        direct = simulate.fly_entry(
            *config_entry.entry_flight_from_mission(
                vehicle,
                mission,
                density_factor=float(values["entry_flight.density_scale"][0]),
                coefficient_factors=factors,
                inertia=inertia,
            )
        ).runs_values()
        for name, value in direct.items():
            assert row[name] == value, (int(row["run_id"]), name)
        assert (
            row["p.entry_flight.blocked_flap.deflection_deg"] == values["entry_flight.blocked_flap.deflection_deg"][0]
        )
        assert bool(row["success"]) and row["terminal_mach"] < 2.0


def test_run_0_is_the_nominal_entry_and_the_draws_move_the_metrics(flown):
    result, _ = flown
    runs = result["runs"].sort_values("run_id").reset_index(drop=True)
    assert runs.loc[0, "p.entry_flight.blocked_flap.deflection_deg"] == 14.0
    assert runs.loc[0, "p.entry_flight.density_scale"] == 1.0
    assert runs.loc[0, "p.entry_flight.rcs_delay_ms"] == 0.0
    delays = runs["p.entry_flight.rcs_delay_ms"]
    assert ((delays >= 0.0) & (delays <= 60.0)).all() and delays.nunique() == 4
    blocked = runs["p.entry_flight.blocked_flap.deflection_deg"]
    assert ((blocked >= 10.0) & (blocked <= 20.0)).all() and blocked.nunique() == 4
    # different draws, different flights (the dispersions reach the kernel)
    assert runs["cross_range_m"].nunique() == 4 and runs["rcs_propellant_kg"].nunique() == 4


def test_the_history_holds_the_mode_program_and_the_blocked_flap(flown):
    _, out = flown
    table = pq.read_table(out / "histories").to_pandas()
    run0 = table[table["run_id"] == 0]
    assert set(run0["mode"].astype(str)) == {"rcs", "flaps", "flaps_rudders"}
    assert abs(run0["flap_right_deg"] - 14.0).max() < 1e-5  # float32: 14 to 7 digits
    high = run0["altitude_m"] > 90_000.0
    assert (run0.loc[high, "mode"].astype(str) == "rcs").all()


def _bad(tmp_path, text, words):
    shutil.copy(ROOT / "configs/vehicles/x38.yaml", tmp_path / "x38.yaml")
    shutil.copy(ROOT / "configs/missions/x38-entry-right-flap-blocked.yaml", tmp_path / "mission.yaml")
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    result = CliRunner().invoke(main, ["validate", str(path)])
    assert result.exit_code == 2, result.output
    assert "Traceback" not in result.output
    assert re.search(rf"{re.escape(str(path))}:\d+: ", result.output), result.output
    for word in words:
        assert word in result.output, f"{word!r} not in {result.output!r}"


TEXT = (
    BLOCKED.read_text()
    .replace("../configs/vehicles/x38.yaml", "x38.yaml")
    .replace("../configs/missions/x38-entry-right-flap-blocked.yaml", "mission.yaml")
)


@pytest.mark.parametrize(
    ("case", "text", "words"),
    [
        (
            "blocked-draws-outside-the-flap-limits",
            TEXT.replace("{dist: uniform, low: 10.0, high: 20.0}", "{dist: uniform, low: 10.0, high: 45.0}"),
            ["dispersions.entry_flight.blocked_flap.deflection_deg", "within the flap limits [-10.0, 40.0]"],
        ),
        (
            "rcs-delay-draws-reaching-the-control-period",
            TEXT.replace(
                "{dist: truncnorm, sigma: 10.0, low: 0.0, high: 60.0}", "{dist: uniform, low: 50.0, high: 150.0}"
            ),
            ["dispersions.entry_flight.rcs_delay_ms", "within the control period [0.0, 100.0) ms"],
        ),
        (
            "inertia-not-as-a-tensor",
            TEXT.replace(
                "inertia_kg_m2: {dist: inertia, moments_sigma_fraction: 0.0333, axes_sigma_deg: 0.333}",
                "inertia_kg_m2: {dist: normal, sigma: 100.0}",
            ),
            ["dispersions.inertia_kg_m2", "only dist: inertia"],
        ),
        (
            "a-path-the-entry-does-not-fly",
            TEXT.replace("  mass_kg: {dist", "  rcs.isp_s: {dist"),
            ["dispersions.rcs.isp_s", "not flown by an entry mission"],
        ),
        (
            "history-faster-than-the-kernel-records",
            TEXT.replace("history_rate_hz: 1.0", "history_rate_hz: 10.0"),
            ["output.history_rate_hz", "at most 1 Hz with an entry mission"],
        ),
        (
            "thruster-failures",
            TEXT + "failures: {mode: fixed, thrusters: [1]}\n",
            ["failures", "not available with an entry mission"],
        ),
        (
            "unknown-metric",
            TEXT.replace("alpha_error_max_deg.max < 1", "alpha_error_deg.max < 1"),
            ["requirements.1", "alpha_error_deg"],
        ),
        (
            "a-coefficient-without-a-factor",
            TEXT.replace("coefficient_scale.drag:", "coefficient_scale.side_force_per_beta_rad:"),
            ["dispersions.entry_flight.coefficient_scale.side_force_per_beta_rad", "unknown parameter path"],
        ),
    ],
    ids=lambda v: v if isinstance(v, str) and "\n" not in v and len(v) < 60 else "",
)
def test_bad_entry_campaign_input_is_exit_2_with_file_line_and_key_path(case, text, words, tmp_path):
    _bad(tmp_path, text, words)


def test_a_mission_rcs_delay_of_a_control_period_is_refused_at_its_line(tmp_path):
    shutil.copy(ROOT / "configs/vehicles/x38.yaml", tmp_path / "x38.yaml")
    mission = (ROOT / "configs/missions/x38-entry-right-flap-blocked.yaml").read_text()
    assert "  rcs_delay_ms: 0.0\n" in mission
    (tmp_path / "mission.yaml").write_text(mission.replace("  rcs_delay_ms: 0.0\n", "  rcs_delay_ms: 100.0\n"))
    line = next(n for n, text in enumerate(mission.splitlines(), 1) if text.startswith("  rcs_delay_ms:"))
    (tmp_path / "campaign.yaml").write_text(TEXT)
    result = CliRunner().invoke(main, ["validate", str(tmp_path / "campaign.yaml")])
    assert result.exit_code == 2, result.output
    where = f"{tmp_path / 'mission.yaml'}:{line}: entry_flight.rcs_delay_ms"
    assert f"{where}: expected an RCS delay below" in result.output
    assert "(100 ms), got 100" in result.output and "Traceback" not in result.output

    text = (ROOT / "campaigns/smoke.yaml").read_text()
    text = re.sub(
        r"\ndispersions:\n", "\ndispersions:\n  entry_flight.density_scale: {dist: normal, sigma: 0.1}\n", text
    )
    path = tmp_path / "smoke.yaml"
    path.write_text(text.replace("../configs/", f"{ROOT}/configs/"))
    result = CliRunner().invoke(main, ["validate", str(path)])
    assert result.exit_code == 2 and "entry_flight.density_scale" in result.output, result.output


def test_the_report_gives_the_entry_metrics_and_requirements(flown):
    _, out = flown
    result = CliRunner().invoke(main, ["report", str(out), "--no-html"])
    assert result.exit_code == 0, result.output
    for word in ("rcs_propellant_kg", "cross_range_m", "rcs_propellant_kg.p99 < 100", "verdict: PASS"):
        assert word in result.output, word
    summary = json.loads((out / "report/summary.json").read_text())
    assert summary["modes"] == ["rcs", "flaps", "flaps_rudders"]


def test_a_rerun_flies_the_stored_row_again_bit_for_bit(flown, tmp_path):
    _, out = flown
    result = CliRunner().invoke(main, ["rerun", str(out), "3", "-o", str(tmp_path / "run3.parquet")])
    assert result.exit_code == 0, result.output
    assert "summary row identical to the stored one" in result.output
    history = pq.read_table(tmp_path / "run3.parquet").to_pandas()
    assert history["mode"].astype(str).iloc[0] == "rcs" and history["mach"].iloc[-1] < 2.2


def test_every_entry_dispersion_path_changes_the_entry():
    """No entry dispersion is silently ignored: each path alone, moved off its nominal, changes
    the flight (the blocked flap's deflection on the blocked-flap mission)."""
    from refexmc.campaign.entry_plan import EntryRunPlan
    from refexmc.config import dispersions

    campaign = load_campaign(BLOCKED)
    plan = EntryRunPlan(campaign)
    vehicle, mission = campaign["vehicle"], campaign["mission"]
    reference = simulate.fly_entry(*plan.flight({})).summary
    paths = [p for p in dispersions.PARAMETERS if p.startswith("entry_flight.")] + ["mass_kg", "inertia_kg_m2"]
    assert not [p for p in paths if dispersions.undeclared(p, vehicle, mission)]  # all flown here
    # state, blocked flap, density, coefficient tables, RCS delay, mass, inertia
    assert len(paths) == 8 + 1 + 1 + 8 + 1 + 1 + 1
    for path in paths:
        nominal = dispersions.nominal(path, vehicle, mission)
        moved = np.where(nominal != 0.0, nominal * 1.02, 0.5) if path != "inertia_kg_m2" else nominal * 1.02
        summary = simulate.fly_entry(*plan.flight({path: moved})).summary
        assert not (summary == reference).all(), path
