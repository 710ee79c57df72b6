"""The campaign key ``published``: a source's values beside the same statistic of the flown runs.

The report's numbers are checked against numpy on the stored runs table of a small SPORE
campaign (the 004 Table 2 ISS entry of campaigns/spore-deorbit-iss.yaml); bad input is refused
with file, line and key path, at load time and by the report.
"""

import json
import shutil

import numpy as np
import pyarrow.parquet as pq
import pytest
import yaml
from click.testing import CliRunner
from stored import campaign_copy, store_campaign

from refexmc.cli import main
from refexmc.config.errors import ConfigError
from refexmc.config.load import load_campaign
from refexmc.config.published import Published, check_published, statistic_meaning
from refexmc.report import make_report

RUNS = 12  # enough for a standard deviation; ~3 s of flight
# 004 Table 2, ISS column: 3-sigma entry state uncertainties (as in campaigns/spore-deorbit-iss.yaml)
TABLE_2_ISS = {
    "entry_longitude_deg": 0.4993,
    "entry_latitude_deg": 0.1176,
    "entry_speed_m_s": 0.0379,
    "entry_flight_path_angle_deg": 0.0036,
    "entry_heading_deg": 0.0189,
}


def _line_of(path, text):
    return next(n for n, line in enumerate(path.read_text().splitlines(), 1) if text in line)


def test_the_spore_campaign_carries_004_table_2(tmp_path):
    campaign = load_campaign(campaign_copy("spore-deorbit-iss.yaml", tmp_path))
    [entry] = campaign["published"]
    assert entry["statistic"] == "three_sigma" and entry["values"] == TABLE_2_ISS
    assert "004 Table 2" in entry["source"] and "ISS" in entry["source"]


def test_a_campaign_without_published_resolves_without_the_key(tmp_path):
    """A file without ``published`` resolves as before the key existed (same digest, --resume works)."""
    campaign = load_campaign(campaign_copy("smoke.yaml", tmp_path))
    assert "published" not in campaign


def test_check_published_accepts_grammar_statistics_and_campaign_columns():
    columns = ["run_id", "seed", "fuel_remaining", "t_sam_s", "pulses_1", "p.rcs.isp_s"]
    entries = [
        {"source": "a", "statistic": "three_sigma", "values": {"fuel_remaining": 0.1, "pulses_total": 900}},
        {"source": "b", "statistic": "p99.865", "values": {"t_sam_s": 30.0, "p.rcs.isp_s": 71.0}},
        {"source": "c", "statistic": "p1_lower95", "values": {"fuel_remaining": 0.3}},
    ]
    parsed = check_published(entries, columns)
    assert parsed[0] == Published("a", "three_sigma", {"fuel_remaining": 0.1, "pulses_total": 900})
    assert [p.statistic for p in parsed] == ["three_sigma", "p99.865", "p1_lower95"]
    assert statistic_meaning("three_sigma") == "3 x sample standard deviation (ddof 1)"
    assert statistic_meaning("p99.865") == "99.865th percentile"
    for bad_column in ("run_id", "seed", "fuel_left"):
        with pytest.raises(ConfigError, match=f"'{bad_column}' is not a runs column"):
            check_published([{"source": "a", "statistic": "max", "values": {bad_column: 1.0}}], columns)
    for bad_stat in ("3sigma", "sigma", "p101", "mean_plus_2sd"):
        with pytest.raises(ConfigError, match=f"unknown statistic '{bad_stat}'"):
            check_published([{"source": "a", "statistic": bad_stat, "values": {"t_sam_s": 1.0}}], columns)


# (case, text replacement in campaigns/spore-deorbit-iss.yaml, the line's text, key path, words)
BAD = [
    (
        "misspelt-column",
        ("entry_speed_m_s: 0.0379", "entry_sped_m_s: 0.0379"),
        "entry_sped_m_s",
        "published.0.values.entry_sped_m_s",
        ["'entry_sped_m_s' is not a runs column of this campaign", "did you mean 'entry_speed_m_s'"],
    ),
    (
        "unknown-statistic",
        ("statistic: three_sigma", "statistic: 3sigma"),
        "statistic: 3sigma",
        "published.0.statistic",
        ["unknown statistic '3sigma'", "did you mean 'three_sigma'"],
    ),
    (
        "value-not-a-number",
        ("entry_heading_deg: 0.0189", "entry_heading_deg: small"),
        "entry_heading_deg: small",
        "published.0.values.entry_heading_deg",
        ["expected number, got 'small'"],
    ),
    (
        "unknown-key",
        ("statistic: three_sigma", "stat: three_sigma"),
        "stat: three_sigma",
        "published.0.stat",
        ["unknown key 'stat'", "did you mean 'statistic'"],
    ),
]


@pytest.mark.parametrize(("replace", "line_text", "key", "words"), [c[1:] for c in BAD], ids=[c[0] for c in BAD])
def test_bad_published_entries_are_refused_with_file_line_and_key_path(tmp_path, replace, line_text, key, words):
    path = campaign_copy("spore-deorbit-iss.yaml", tmp_path, replace=[replace])
    assert line_text in path.read_text()
    for command in (["validate", str(path)], ["run", str(path), "-o", str(tmp_path / "out"), "--no-progress"]):
        result = CliRunner().invoke(main, command)
        assert result.exit_code == 2, result.output
        assert "Traceback" not in result.output
        message = result.output.strip()
        assert message.startswith(f"error: {path}:")
        assert f"{path}:{_line_of(path, line_text)}: {key}:" in message, message
        for word in words:
            assert word in message, (word, message)
    assert not (tmp_path / "out").exists()


def test_an_orbit_column_on_a_vehicle_without_the_orbit_trajectory_is_refused(tmp_path):
    path = campaign_copy("smoke.yaml", tmp_path)
    base = path.read_text()
    path.write_text(base + "published:\n  - source: x\n    statistic: std\n    values: {entry_speed_m_s: 1.0}\n")
    with pytest.raises(ConfigError) as info:
        load_campaign(path)
    assert info.value.path == ("published", 0, "values", "entry_speed_m_s")
    assert info.value.line == _line_of(path, "entry_speed_m_s")
    assert "orbit trajectory only" in str(info.value)
    path.write_text(base + "published:\n  - source: x\n    statistic: std\n    values: {}\n")
    with pytest.raises(ConfigError, match="should be non-empty") as info:
        load_campaign(path)
    assert info.value.path == ("published", 0, "values")
    path.write_text(base + "published: []\n")  # an empty list: nothing to show
    assert load_campaign(path)["published"] == []


# --- the report, on real flights --------------------------------------------------------------


@pytest.fixture(scope="module")
def flown(tmp_path_factory):
    """A 12-run SPORE campaign stored as `run` stores it, and `refexmc report` of it."""
    tmp = tmp_path_factory.mktemp("published")
    campaign = load_campaign(campaign_copy("spore-deorbit-iss.yaml", tmp, replace=[("runs: 1000", f"runs: {RUNS}")]))
    out = tmp / "out"
    store_campaign(campaign, out)
    result = CliRunner().invoke(main, ["report", str(out)])
    assert result.exit_code == 0, result.output
    return out, result.output


def _ours(out, column, stat=lambda x: 3.0 * np.std(x, ddof=1)):
    """The statistic over the stored runs table, read with pyarrow: ok runs, finite values."""
    runs = pq.read_table(out / "runs").to_pandas()
    values = runs.loc[runs["status"] == "ok", column].to_numpy(dtype=float)
    values = values[np.isfinite(values)]
    return stat(values), len(values)


def test_summary_json_holds_004_table_2_beside_3_std_of_the_runs(flown):
    out, _ = flown
    summary = json.loads((out / "report" / "summary.json").read_text())
    [section] = summary["published"]
    assert section["source"] == "004 Table 2, ISS column (3-sigma entry state uncertainties)"
    assert section["statistic"] == "three_sigma"
    assert [row["column"] for row in section["rows"]] == list(TABLE_2_ISS)
    for row in section["rows"]:
        ours, n = _ours(out, row["column"])
        assert n == RUNS and row["n"] == RUNS
        assert ours > 0.0, row["column"]  # dispersed runs: a spread to compare with
        assert row["ours"] == pytest.approx(ours, rel=1e-12), row["column"]
        assert row["published"] == TABLE_2_ISS[row["column"]]
        assert row["ratio_published_to_ours"] == pytest.approx(TABLE_2_ISS[row["column"]] / ours, rel=1e-12)


def test_text_and_html_show_the_section(flown):
    out, text = flown
    lines = text.splitlines()
    start = lines.index("published: 004 Table 2, ISS column (3-sigma entry state uncertainties)")
    assert lines[start + 1].startswith(
        "  ours: three_sigma = 3 x sample standard deviation (ddof 1), over the 12 flown"
    )
    assert lines[start + 2].split() == ["n", "ours", "published", "published/ours"]
    for k, column in enumerate(TABLE_2_ISS):
        cells = lines[start + 3 + k].split()
        ours, _ = _ours(out, column)
        assert cells[0] == column and cells[1] == str(RUNS)
        assert float(cells[2]) == pytest.approx(ours, rel=1e-3)  # printed with 4 significant digits
        assert float(cells[3]) == TABLE_2_ISS[column]
        assert float(cells[4]) == pytest.approx(TABLE_2_ISS[column] / ours, rel=1e-2)
    page = (out / "report" / "index.html").read_text()
    assert "<h2>Published values beside this campaign's</h2>" in page
    assert "<h3>004 Table 2, ISS column (3-sigma entry state uncertainties)</h3>" in page
    for column, value in TABLE_2_ISS.items():
        assert f"<tr><td><code>{column}</code></td><td>{RUNS}</td>" in page
        assert f"<td>{value:.4g}</td>" in page


def _edit_resolved(out, edit):
    path = out / "campaign.resolved.yaml"
    data = yaml.safe_load(path.read_text())
    edit(data)
    path.write_text(yaml.safe_dump(data, sort_keys=False))


def test_a_campaign_without_published_shows_no_section(flown, tmp_path):
    out, _ = flown
    copy = tmp_path / "out"
    shutil.copytree(out, copy, ignore=shutil.ignore_patterns("report"))
    _edit_resolved(copy, lambda data: data.pop("published"))
    report = make_report(copy, html=True)
    assert report["summary"]["published"] == []
    assert "published" not in report["text"]
    page = (copy / "report" / "index.html").read_text()
    assert "Published values" not in page and "published / ours" not in page


def test_the_report_refuses_a_column_the_stored_table_lacks(flown, tmp_path):
    out, _ = flown
    copy = tmp_path / "out"
    shutil.copytree(out, copy, ignore=shutil.ignore_patterns("report"))
    _edit_resolved(copy, lambda data: data["published"][0]["values"].update({"entry_sped_m_s": 1.0}))
    result = CliRunner().invoke(main, ["report", str(copy)])
    assert result.exit_code == 2, result.output
    assert "Traceback" not in result.output
    resolved = copy / "campaign.resolved.yaml"
    line = _line_of(resolved, "entry_sped_m_s")
    assert f"{resolved}:{line}: published.0.values.entry_sped_m_s:" in result.output
    assert "did you mean 'entry_speed_m_s'" in result.output
    assert not (copy / "report").exists()
