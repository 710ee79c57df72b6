"""Names for any mission (issue 34): old key names load with a warning naming the new one
(``--strict`` refuses them), outputs written under the old names read as if written under the new
ones (report, compare, rerun, --resume), with the same bits (config.renames)."""

import json
import re
import shutil

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from click.testing import CliRunner
from stored import ROOT, store_campaign

from refexmc.campaign import storage
from refexmc.cli import main
from refexmc.config import renames
from refexmc.config.errors import ConfigError
from refexmc.config.load import apply_overrides, load_campaign, load_mission
from refexmc.report import data

BASELINE = ROOT / "baselines" / "smoke"  # written before issue 34: p.separation.*, theta_t_handover_deg
OLD_COLUMNS = ("theta_t_handover_deg", "p.separation.rates_deg_s.x", "p.separation.attitude_error_deg.z")
NEW_COLUMNS = ("attitude_error_end_deg", "p.initial_state.rates_deg_s.x", "p.initial_state.attitude_rotvec_deg.z")


def _old_names(text):
    """A shipped file written back in the names of before issue 34."""
    for old, new in (
        ("initial_state.attitude_rotvec_deg", "separation.attitude_error_deg"),
        ("initial_state:", "separation:"),
        ("initial_state.", "separation."),
        ("attitude_rotvec_deg:", "attitude_error_deg:"),
        ("attitude_error_end_max_deg", "handover_max_angle_deg"),
        ("attitude_error_end_deg", "theta_t_handover_deg"),
    ):
        text = text.replace(old, new)
    return text


@pytest.fixture
def old_slew(tmp_path):
    """campaigns/generic-slew.yaml and its mission in the old names (its vehicle as shipped)."""
    mission = tmp_path / "mission.yaml"
    mission.write_text(_old_names((ROOT / "configs/missions/generic-slew.yaml").read_text()))
    text = _old_names((ROOT / "campaigns/generic-slew.yaml").read_text())
    text = text.replace("../configs/missions/generic-slew.yaml", str(mission))
    campaign = tmp_path / "campaign.yaml"
    campaign.write_text(text.replace("../configs", str(ROOT / "configs")))
    return campaign, mission


def _line(path, fragment):
    return next(n for n, line in enumerate(path.read_text().splitlines(), 1) if fragment in line)


def test_old_names_load_as_the_new_ones_with_a_warning_naming_each(old_slew):
    campaign_file, mission_file = old_slew
    warnings = []
    old = load_campaign(campaign_file, warnings)
    new = load_campaign(ROOT / "campaigns/generic-slew.yaml")
    assert storage.normalized_campaign(old) == storage.normalized_campaign(new)  # the same campaign, new names
    where = {(str(w.file), w.line, ".".join(map(str, w.path))): w.message for w in warnings}
    expected = {
        (str(campaign_file), _line(campaign_file, "separation.rates_deg_s"), "dispersions.separation.rates_deg_s"): (
            "initial_state.rates_deg_s"
        ),
        (str(campaign_file), _line(campaign_file, "theta_t_handover_deg.max"), "requirements.1"): (
            "attitude_error_end_deg.max <= 1.5"
        ),
        (str(mission_file), _line(mission_file, "separation:"), "separation"): "'initial_state'",
        (str(mission_file), _line(mission_file, "attitude_error_deg:"), "separation.attitude_error_deg"): (
            "'attitude_rotvec_deg' (the initial attitude itself, not an error)"
        ),
        (str(mission_file), _line(mission_file, "handover_max_angle_deg"), "handover_max_angle_deg"): (
            "'attitude_error_end_max_deg'"
        ),
    }
    for key, new_name in expected.items():
        assert new_name in where[key], (key, where.get(key))
        assert "--strict refuses it" in where[key]
    assert len(warnings) == 6  # the five above and the attitude dispersion's path


def test_strict_refuses_an_old_name_and_a_file_may_not_give_both(old_slew, tmp_path):
    campaign_file, mission_file = old_slew
    runner = CliRunner()
    lenient = runner.invoke(main, ["validate", str(mission_file)])
    assert lenient.exit_code == 0 and "'separation' is now 'initial_state'" in lenient.output
    strict = runner.invoke(main, ["validate", "--strict", str(campaign_file)])
    assert strict.exit_code == 2
    assert f"{campaign_file}:{_line(campaign_file, 'separation.rates_deg_s')}: dispersions.separation" in strict.output
    both = tmp_path / "both.yaml"
    given_twice = "initial_state: {rates_deg_s: [0, 0, 0]}\nseparation:"
    both.write_text(mission_file.read_text().replace("separation:", given_twice))
    with pytest.raises(ConfigError, match="separation"):  # two names of one key: the old one is unknown
        load_mission(both)


def test_renamed_paths_draw_what_they_drew_under_their_old_names():
    from refexmc.campaign.sampling import path_key

    for old, new in renames.PATHS.items():
        assert path_key(new) == path_key(old)
    assert path_key("initial_state.rates_deg_s") != path_key("navigation.rate_bias_deg_s")


def test_an_old_runs_table_reads_in_the_new_names_with_its_bits():
    raw = pq.read_table(BASELINE / "runs")
    read = storage.read_runs_part(BASELINE / "runs")
    assert all(c in raw.column_names for c in OLD_COLUMNS) and all(c in read.column_names for c in NEW_COLUMNS)
    for old, new in zip(raw.column_names, read.column_names, strict=True):
        assert renames.new_column(old) == new
        assert raw[old].equals(read[new])
    reasons = pa.table({"failure_reason": ["handover_angle_error", None, "rdm1_timeout"]})
    renamed = renames.runs_table(reasons)["failure_reason"].to_pylist()
    assert renamed == ["attitude_error_end_above_max", None, "rdm1_timeout"]


def _as_new_output(out):
    """``out`` (a copy of the baseline) rewritten as the same runs would be stored now."""
    storage.write_table_atomic(storage.read_runs_part(out / "runs"), out / "runs" / storage.part_name(0))
    storage.write_resolved(out, load_campaign(ROOT / "campaigns/smoke.yaml"))
    storage.write_manifest(out, storage.read_manifest(out))


def test_old_output_reports_compares_and_reruns(tmp_path):
    old, new = tmp_path / "old", tmp_path / "new"
    shutil.copytree(BASELINE, old)
    shutil.copytree(BASELINE, new)
    _as_new_output(new)
    assert "theta_t_handover_deg" in json.loads((old / "manifest.json").read_text())["columns"]["runs"]
    a, b = data.load(old), data.load(new)
    assert list(a.runs.columns) == list(b.runs.columns) and a.runs.equals(b.runs)
    assert "initial_state" in a.resolved["mission"] and "separation" not in a.resolved["mission"]
    runner = CliRunner()
    compared = runner.invoke(main, ["compare", str(old), str(new), "--tolerance", "theta_t_handover_deg=0.1"])
    assert compared.exit_code == 0, compared.output
    assert "paired run by run on 20 runs" in compared.output and "attitude_error_end_deg" in compared.output
    reported = runner.invoke(main, ["report", str(old), "--no-html"])
    assert reported.exit_code == 0, reported.output
    summary = (old / "report" / "summary.json").read_text()
    assert "attitude_error_end_deg" in reported.output + summary and "theta_t_handover" not in reported.output + summary
    rerun = runner.invoke(main, ["rerun", str(old), "3"])  # the stored row of old names, the new row: equal
    assert rerun.exit_code == 0, rerun.output
    assert "summary row identical to the stored one" in rerun.output


def test_an_old_output_resumes_under_the_new_names(tmp_path):
    """A smoke OUT of before issue 34 with its first 10 runs stored: --resume with the renamed
    campaign file flies the other 10; the table (old part and new part) is the baseline's bits."""
    out = tmp_path / "out"
    shutil.copytree(BASELINE, out)
    first = pq.read_table(BASELINE / "runs").sort_by("run_id").slice(0, 10)
    storage.write_table_atomic(first, out / "runs" / storage.part_name(0))
    storage.write_table_atomic(storage.empty_history_table(), out / "histories" / storage.part_name(0))
    manifest = json.loads((out / "manifest.json").read_text())
    # as if flown by this flight code: its manifest is older, but issue 37's elementary functions
    # (which --resume refuses for) left these 20 runs' bits as they were (test_generic_missions)
    manifest = {**manifest, "chunk_size": 10, "status": "running", "flight_code": storage.flight_code()}
    (out / "manifest.json").write_text(json.dumps(manifest))
    smoke = tmp_path / "smoke.yaml"
    smoke.write_text((ROOT / "campaigns/smoke.yaml").read_text().replace("../configs", str(ROOT / "configs")))
    result = CliRunner().invoke(main, ["run", str(smoke), "-o", str(out), "--resume", "--no-progress", "-j", "1"])
    assert result.exit_code == 0, result.output
    assert "theta_t_handover_deg" in pq.read_table(out / "runs" / storage.part_name(0)).column_names
    assert "attitude_error_end_deg" in pq.read_table(out / "runs" / storage.part_name(1)).column_names
    resumed = data.load(out).runs
    baseline = data.load(BASELINE).runs
    assert list(resumed.columns) == list(baseline.columns)
    for column in baseline.columns:
        a, b = resumed[column].to_numpy(), baseline[column].to_numpy()
        if a.dtype.kind == "f":
            assert np.array_equal(a.view(np.uint64), b.view(np.uint64)), column
        else:
            assert list(a) == list(b), column


# every shipped mission but ReFEx's (whose words are 000's: hand-over, separation); the hop's
# sequential variant and the second IRASSI mission ride on their campaign's vehicle
OTHER_MISSIONS = ("spore-deorbit-iss", "irassi-fine-pointing", "generic-slew", "surveyor-hop", "x38-nominal")
REFEX_WORDS = re.compile(r"hand-?over|separation", re.I)  # in any form: prose, keys, columns, paths


@pytest.mark.slow
@pytest.mark.parametrize("name", OTHER_MISSIONS)
def test_no_output_of_another_mission_says_separation_or_hand_over(name, tmp_path):
    """Two runs of each shipped campaign that is not ReFEx's, stored, reported (text and JSON),
    re-flown, inspected and validated: no user-facing text holds a ReFEx word."""
    campaign_file = ROOT / "campaigns" / f"{name}.yaml"
    out = tmp_path / "out"
    store_campaign(apply_overrides(load_campaign(campaign_file), runs=2), out)
    runner = CliRunner()
    texts = {}
    for command in (
        ["report", str(out), "--no-html"],  # the HTML page: tests/test_report_missions.py
        ["rerun", str(out), "1"],
        ["inspect", str(campaign_file)],
        ["validate", "--strict", str(campaign_file)],
    ):
        result = runner.invoke(main, command)
        assert result.exit_code in (0, 1), result.output  # 1: a requirement two runs cannot show
        texts[command[0]] = result.output
    texts["summary.json"] = (out / "report" / "summary.json").read_text()
    texts["runs columns"] = " ".join(pq.read_table(out / "runs").column_names)
    texts["failure reasons"] = " ".join(map(str, pq.read_table(out / "runs")["failure_reason"].to_pylist()))
    for where, text in texts.items():
        found = REFEX_WORDS.search(text)
        context = text[max(0, found.start() - 80) : found.end() + 40] if found else ""
        assert not found, f"{name} {where}: {found.group()!r} in ...{context}"
    assert "attitude_error_end" in texts["runs columns"] or name.startswith("x38")
