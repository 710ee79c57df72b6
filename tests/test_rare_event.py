"""A rare-event study flown (campaign key ``rare_event``, refexmc.campaign.rare_event): every
flight a run with level, chain, step and margin; the same table whatever -j, chunking or resume;
any flight re-flown bit for bit; the report's estimate is the algorithm's on the stored margins;
bad input refused with file, line and key path.
"""

import json
import math
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from click.testing import CliRunner

from refexmc.campaign import rare_event, storage, study_plan, subset
from refexmc.campaign.rerun import rerun
from refexmc.campaign.sweep import run_campaign_or_sweep
from refexmc.cli import main
from refexmc.config.load import load_campaign
from refexmc.report import make_report

ROOT = Path(__file__).resolve().parents[1]
FUEL_EVENT = 0.35  # P(fuel_remaining <= 0.35) ~ 1e-2 under these dispersions: two levels of 100
STUDY = f"""name: rare-test
vehicle: {ROOT}/configs/vehicles/refex.yaml
mission: {ROOT}/configs/missions/refex-exo.yaml
seed: 7
nominal_first: false
dispersions:
  initial_state.rates_deg_s: {{dist: normal, sigma: [1.0, 1.0, 1.0]}}
  inertia_kg_m2: {{dist: inertia, moments_sigma_fraction: [0.033, 0.033, 0.033], axes_sigma_deg: [0.5, 0.5, 0.5]}}
  rcs.propellant_kg: {{dist: truncnorm, sigma: 0.0253, low: 0.57, high: 0.95}}
  navigation.rate_noise_deg_s: {{dist: uniform, low: 0.0, high: 0.02}}
  atmosphere.density_scale: {{dist: constant, value: 1.0}}
output:
  history_rate_hz: 0.5
requirements:
  - fuel_remaining.min >= 0.0
rare_event:
  event: fuel_remaining <= {FUEL_EVENT}
  per_level: 100
  p0: 0.1
  max_levels: 4
"""


def _fly(tmp_path, name, **options):
    campaign = tmp_path / "study.yaml"
    campaign.write_text(STUDY)
    return run_campaign_or_sweep(campaign, out=tmp_path / name, notify=lambda message: None, **options)


@pytest.fixture(scope="module")
def flown(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("rare")
    return tmp, _fly(tmp, "a", jobs=1)


def _sorted(table):
    return table.sort_values("run_id", ignore_index=True)


def test_every_flight_is_a_run_with_its_level_chain_step_and_margin(flown):
    _, result = flown
    table = result["study_runs"]
    design = subset.Design(100, 0.1, 4)
    assert (table["level"] == 0).sum() == 100 and list(result["runs"]["run_id"]) == list(range(100))
    later = table[table["level"] > 0]
    assert len(later) > 0
    expected = [
        subset.run_index(design, lv, st, ch) for lv, st, ch in zip(later.level, later.step, later.chain, strict=True)
    ]
    assert list(later["run_id"]) == expected
    ok = table[table["status"] == "ok"]
    np.testing.assert_array_equal(ok["margin"], ok["fuel_remaining"] - FUEL_EVENT)  # the event's margin, its unit
    record = result["rare_event"]
    assert record["flights"] == len(table)
    assert [lv["level"] for lv in record["levels"]] == list(range(len(record["levels"])))


def test_the_estimate_is_the_algorithm_on_the_stored_margins(flown):
    tmp, result = flown
    campaign = load_campaign(tmp / "a" / "campaign.resolved.yaml")
    study = rare_event.replay(campaign, rare_event.stored_margins(tmp / "a"))
    record = result["rare_event"]
    assert study.probability == (record["probability"] or 0.0)
    assert [lv.threshold for lv in study.levels] == [lv["threshold"] for lv in record["levels"]]
    # the later levels moved towards the event: each threshold below the one before
    thresholds = [lv["threshold"] for lv in record["levels"][1:]]
    assert thresholds == sorted(thresholds, reverse=True)


def test_jobs_and_chunking_give_the_same_table(flown, tmp_path, monkeypatch):
    _, result = flown
    monkeypatch.setenv("REFEXMC_CHUNK_SIZE", "7")
    other = _fly(tmp_path, "b", jobs=2)
    pd.testing.assert_frame_equal(_sorted(result["study_runs"]), _sorted(other["study_runs"]))
    assert other["rare_event"]["probability"] == result["rare_event"]["probability"]


def test_resume_finishes_a_killed_study_with_the_same_table(flown, tmp_path):
    source, result = flown
    out = tmp_path / "a"
    shutil.copytree(source / "a", out)
    parts = sorted((out / "runs").glob("part-*.parquet"))
    for part in parts[len(parts) // 2 :]:  # killed in the middle of level 1 or later
        part.unlink()
        (out / "histories" / part.name).unlink()
    manifest = storage.read_manifest(out)
    storage.write_manifest(out, {**manifest, "status": "interrupted"})
    resumed = _fly(tmp_path, "a", jobs=1, resume=True)
    pd.testing.assert_frame_equal(_sorted(result["study_runs"]), _sorted(resumed["study_runs"]))


def test_a_later_level_flight_is_re_flown_bit_for_bit(flown):
    tmp, result = flown
    table = result["study_runs"]
    run_id = int(table[table["level"] == table["level"].max()]["run_id"].iloc[-1])
    again = rerun(tmp / "a", run_id, history_rate_hz=0.5, dest=tmp / "rerun.parquet")
    assert again["stored"] is not None and again["differ"] == []


def test_the_report_judges_level_0_and_reports_the_estimate(flown):
    tmp, result = flown
    report = make_report(tmp / "a", html=True)
    summary = report["summary"]
    assert summary["completeness"]["complete"], summary["completeness"]
    assert summary["completeness"]["runs_stored"] == 100  # level 0 alone
    section = summary["rare_event"]
    for key in ("probability", "ci95", "cov", "flights", "levels"):
        assert key in section
    assert section["levels"][1]["threshold"] is not None and "conditional_probability" in section["levels"][1]
    if section["probability"] is not None:
        lo, hi = section["ci95"]
        assert lo <= section["probability"] <= hi
        assert section["failing_runs"] and all(r["margin"] <= 0 for r in section["failing_runs"])
        assert section["drivers"][0]["parameter"].startswith("p.")
        # the separation rates to damp drive the propellant used (000 sec. 2.2: RDM1), more than the 3 %
        # spread of the propellant loaded: the event's flights have them shifted most
        assert section["drivers"][0]["parameter"].startswith("p.initial_state.rates_deg_s.")
        shifts = [abs(d["shift_sigma"]) for d in section["drivers"]]
        assert shifts == sorted(shifts, reverse=True) and shifts[0] > 1.0
    page = (tmp / "a" / "report" / "index.html").read_text()
    assert "Rare event: fuel_remaining" in page and "What drives the event" in page
    assert json.loads((tmp / "a" / "report" / "summary.json").read_text())["rare_event"]["flights"] == len(
        result["study_runs"]
    )


def test_random_failures_move_through_their_uniforms():
    """The failed set of ``failed_from_uniforms``: the count from u[0] through the cumulative
    probabilities, the units of smallest u[1:]; uniform u give each unit equal odds."""
    assert study_plan.failed_from_uniforms(np.array([0.5, 0.3, 0.1, 0.9]), [0.4, 0.6]) == (2,)
    assert study_plan.failed_from_uniforms(np.array([0.1, 0.3, 0.1, 0.9]), [0.4, 0.6]) == ()
    rng = np.random.default_rng(0)
    counts = np.zeros(6)
    for _ in range(3000):
        for unit in study_plan.failed_from_uniforms(rng.random(7), [0.0, 0.5, 0.5]):
            counts[unit - 1] += 1
    # 4500 failed units over 6: 750 each, binomial sd ~25
    assert np.all(np.abs(counts - 750) < 5 * 25), counts


def _edit(old, new):
    assert old in STUDY, old
    return STUDY.replace(old, new)


def _line(text, prefix):
    return next(n for n, line in enumerate(text.splitlines(), 1) if line.strip().startswith(prefix))


BAD = [
    ("unknown-metric", _edit("event: fuel_remaining <=", "event: fuel_remainig <="), "rare_event.event", "event:"),
    ("p0-above", _edit("p0: 0.1", "p0: 0.6"), "rare_event.p0", "p0:"),
    ("p0-zero", _edit("p0: 0.1", "p0: 0.0"), "rare_event.p0", "p0:"),
    ("per-level-small", _edit("per_level: 100", "per_level: 50"), "rare_event.per_level", "per_level:"),
    ("saltelli", _edit("nominal_first: false", "nominal_first: false\nsampling: saltelli"), "sampling", "sampling:"),
    (
        "sweep",
        STUDY + "sweep:\n  axes:\n    - {parameter: rcs.isp_s, values: [60, 70]}\n",
        "rare_event",
        "rare_event:",
    ),
    ("nominal-first", _edit("nominal_first: false", "nominal_first: true"), "nominal_first", "nominal_first:"),
]


@pytest.mark.parametrize(("text", "key", "prefix"), [b[1:] for b in BAD], ids=[b[0] for b in BAD])
def test_bad_study_is_refused_with_file_line_and_key_path(tmp_path, text, key, prefix):
    campaign = tmp_path / "study.yaml"
    campaign.write_text(text)
    out = tmp_path / "out"
    result = CliRunner().invoke(main, ["run", str(campaign), "-o", str(out), "--no-progress"])
    assert result.exit_code == 2, result.output
    assert "Traceback" not in result.output
    assert f"{campaign}:{_line(text, prefix)}: {key}" in result.output, result.output
    assert not out.exists()


def test_runs_override_is_refused(tmp_path):
    campaign = tmp_path / "study.yaml"
    campaign.write_text(STUDY)
    result = CliRunner().invoke(main, ["run", str(campaign), "-o", str(tmp_path / "o"), "--runs", "5"])
    assert result.exit_code == 2 and "per_level" in result.output


def test_the_shipped_studies_validate():
    for name in ("refex-rare-exhaustion.yaml", "surveyor-hop-rare.yaml"):
        campaign = load_campaign(ROOT / "campaigns" / name)
        assert campaign["runs"] == campaign["rare_event"]["per_level"]
        assert math.isclose(campaign["rare_event"]["p0"], 0.1)


@pytest.mark.slow
def test_dask_gives_the_same_table(flown, tmp_path):
    """On a Dask LocalCluster (one for the whole study): the loky table, row for row."""
    pytest.importorskip("distributed")
    _, result = flown
    other = _fly(tmp_path, "dask", jobs=2, backend="dask", scheduler="local:2")
    pd.testing.assert_frame_equal(_sorted(result["study_runs"]), _sorted(other["study_runs"]))


def test_margins_of_events_and_requirements_are_signed_distances_in_the_metric_unit():
    from refexmc.config.rare_event import parse_event, requirement_event
    from refexmc.config.requirements import parse_requirement

    columns = ["fuel_remaining", "position_error_end_m"]
    low = parse_event("fuel_remaining <= 0.0", columns)
    np.testing.assert_array_equal(low.margins([0.3, 0.0, -0.0, np.nan]), [0.3, 0.0, 0.0, -np.inf])
    high = parse_event("position_error_end_m > 0.05", columns)
    np.testing.assert_allclose(high.margins([0.01, 0.07]), [0.04, -0.02])
    required = requirement_event(parse_requirement("fuel_remaining.min >= 0.2", columns))
    assert (required.metric, required.op) == ("fuel_remaining", "<")
    np.testing.assert_allclose(required.margins([0.5, 0.1]), [0.3, -0.1])
    assert requirement_event(parse_requirement("success_rate >= 0.9", columns)) is None
