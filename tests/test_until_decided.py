"""`refexmc run --until-decided` (refexmc.campaign.decided): a ReFEx campaign stops once its
requirements are decided, holds exactly the first runs of the full campaign, and extends later
to exactly the runs a longer campaign has."""

from pathlib import Path

import pandas as pd
import pytest
import yaml
from stored import campaign_copy, invoke_run, read_runs, snapshot

from refexmc.campaign import decided, progress
from refexmc.campaign import run as run_module
from refexmc.campaign.run import run_campaign
from refexmc.config.errors import ConfigError
from refexmc.report import make_report

# refex-mc100's dispersions with requirements a good design decides early: P(success) >= 0.6 and
# P(fuel_remaining >= 0.2) >= 0.9, both at 95 % confidence (000 sec. 7's 20 % propellant floor)
REQUIREMENTS = [
    ("  - fuel_remaining.min >= 0.20", "  - fuel_remaining.p10_lower95 >= 0.20"),
    ("  - success_rate >= 1.0", "  - success_rate_lower95 >= 0.6"),
]


@pytest.fixture
def campaign(tmp_path, monkeypatch):
    monkeypatch.setenv(run_module.CHUNK_SIZE_ENV, "5")  # two chunks per look of 10 runs
    return campaign_copy("refex-mc100.yaml", tmp_path, "decided.yaml", REQUIREMENTS)


def fly(campaign, out, **options):
    return decided.run_until_decided(campaign, out, jobs=1, batch=10, notify=lambda message: None, **options)


def test_a_passing_campaign_stops_early_with_the_first_runs_of_the_full_one(campaign, tmp_path, capsys):
    result = fly(campaign, tmp_path / "stopped", runs=100, progress="lines")
    record = result["until_decided"]
    flown = record["runs_flown"]
    assert record["stopped"] == "decided" and flown < 100
    assert [r["state"] for r in record["requirements"]] == ["PASS", "PASS"]
    assert record["looks"] == list(range(10, flown + 1, 10))
    # one progress over the budget, not one per look (each "compiling", out of the look's runs)
    lines = capsys.readouterr().err.splitlines()
    assert sum(progress.COMPILING in line for line in lines) == 1, lines
    assert lines and all("/100 runs" in line for line in lines), lines
    assert lines[-1].startswith(f"{flown}/100 runs, "), lines
    # OUT is the campaign `--runs flown`: same resolved runs, same table bit for bit
    resolved = yaml.safe_load((tmp_path / "stopped" / "campaign.resolved.yaml").read_text())
    assert resolved["runs"] == flown
    plain = run_campaign(campaign, tmp_path / "plain", runs=flown, jobs=1)
    pd.testing.assert_frame_equal(read_runs(tmp_path / "stopped"), plain["runs"])
    report = make_report(tmp_path / "stopped", html=False)
    assert report["verdict"] == "PASS"
    assert report["summary"]["until_decided"]["runs_flown"] == flown
    assert f"stopped when decided after {flown} of 100 runs" in report["text"]
    page = make_report(tmp_path / "stopped")["files"][-2].read_text()  # index.html
    assert page.index("Stopping when decided") < page.index("<h2>Requirements</h2>")


def test_an_extended_campaign_flies_only_the_new_runs(campaign, tmp_path):
    out = tmp_path / "out"
    first = fly(campaign, out, runs=100)["until_decided"]["runs_flown"]
    kept = {p: v for p, v in snapshot(out).items() if p.parts[0] in ("runs", "histories")}
    # a larger budget on the same OUT spends alpha more slowly (at 60 runs a 10 % tail needs 61
    # meeting runs of 60 with a budget of 400): the looks replay on the stored runs and it flies on
    second = fly(campaign, out, runs=400, resume=True)["until_decided"]
    assert second["runs_flown"] > first
    after = snapshot(out)
    assert all(after[p] == v for p, v in kept.items()), "a stored part was written again"
    plain = run_campaign(campaign, tmp_path / "plain", runs=second["runs_flown"], jobs=1)
    pd.testing.assert_frame_equal(read_runs(out), plain["runs"])


def test_refuses_what_it_cannot_stop(tmp_path):
    lhs = campaign_copy("smoke.yaml", tmp_path)
    with pytest.raises(ConfigError, match="sampling: random"):
        decided.run_until_decided(lhs, tmp_path / "out")
    bare = campaign_copy("nominal.yaml", tmp_path, replace=[("  - success_rate >= 1.0\n", "")])
    bare.write_text(bare.read_text().replace("requirements:\n", "requirements: []\n"))
    with pytest.raises(ConfigError, match="needs requirements"):
        decided.run_until_decided(bare, tmp_path / "out")
    assert not (tmp_path / "out").exists()
    result = invoke_run(campaign_copy("nominal.yaml", tmp_path), "-o", tmp_path / "out", "--batch", "10")
    assert result.exit_code == 2 and "--batch and --alpha go with --until-decided" in result.output
    result = invoke_run(lhs, "-o", tmp_path / "out", "--until-decided")
    assert result.exit_code == 2 and "sampling" in result.output and "Traceback" not in result.output
    assert not Path(tmp_path / "out").exists()


def test_a_failing_requirement_stops_the_campaign_with_exit_1(tmp_path, monkeypatch):
    """A FAIL decides the campaign: it stops at the look that saw it (run exits 1), although
    ``success_rate >= 1.0`` can never PASS and would otherwise fly the whole budget."""
    monkeypatch.setenv(run_module.CHUNK_SIZE_ENV, "5")
    failing = [("  - fuel_remaining.min >= 0.20", "  - fuel_remaining.min >= 0.95")]  # every flight uses > 5 %
    campaign = campaign_copy("refex-mc100.yaml", tmp_path, "failing.yaml", failing)
    result = invoke_run(campaign, "-o", tmp_path / "out", "--runs", 100, "--until-decided", "--batch", 10, "-j", 1)
    assert result.exit_code == 1, result.output
    assert "stopped when decided after 10 of 100 runs" in result.output
    assert ": FAIL (1 requirement failed" in result.output
    assert len(read_runs(tmp_path / "out")) == 10


def test_stopping_record_reads_as_one_line_per_requirement():
    record = {
        "stopped": "budget",
        "budget_runs": 200,
        "batch_runs": 20,
        "alpha": 0.05,
        "requirements": [
            {"state": "open", "decided_at_runs": None, "requirement": "t_end_s.median <= 250", "test": "at the budget"},
            {"state": "FAIL", "decided_at_runs": 40, "requirement": "success_rate >= 0.99", "test": "P(success)"},
        ],
    }
    lines = decided.format_stopping(record).splitlines()
    assert lines[0].startswith("flew the whole budget of 200 runs")
    assert lines[1].strip().startswith("open: t_end_s.median") and "FAIL at 40 runs" in lines[2]
    stopped = {**record, "stopped": "decided", "runs_flown": 40}  # a record without "verdict" (older OUTs) too
    for verdict in (None, "FAIL"):
        head = decided.format_stopping({**stopped, "verdict": verdict}).splitlines()[0]
        assert head.startswith("stopped when decided after 40 of 200 runs") and ": FAIL (1 requirement failed" in head
    passed = {**stopped, "verdict": "PASS", "requirements": record["requirements"][1:]}
    passed["requirements"] = [{**passed["requirements"][0], "state": "PASS"}]
    assert decided.format_stopping(passed).splitlines()[0].endswith("alpha 0.05): PASS")


def test_a_batch_beyond_the_budget_is_one_look_at_the_budget(tmp_path, monkeypatch):
    failing = [("  - fuel_remaining.min >= 0.20", "  - fuel_remaining.min >= 0.95")]
    campaign = campaign_copy("refex-mc100.yaml", tmp_path, "failing.yaml", failing)
    result = decided.run_until_decided(campaign, tmp_path / "out", runs=6, batch=500, jobs=1, notify=lambda m: None)
    record = result["until_decided"]
    assert record["looks"] == [6] and record["batch_runs"] == 6
    assert "(looks every 6 runs," in decided.format_stopping(record)


def test_chunks_end_on_the_looks():
    assert decided.batch_chunk_size(250) == 50 and decided.batch_chunk_size(97) == 97
    assert decided.batch_chunk_size(20) == 20 and decided.batch_chunk_size(1000) == 100
