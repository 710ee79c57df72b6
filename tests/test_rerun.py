"""`rerun`: one run of a finished campaign re-flown bit for bit from OUT alone."""

import shutil
from pathlib import Path

import pyarrow.parquet as pq
import pytest
from stored import store_campaign

from refexmc.campaign.rerun import rerun
from refexmc.config.errors import ConfigError
from refexmc.config.load import load_campaign

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def finished(tmp_path_factory):
    """A small dispersed campaign with random failures and nav noise, stored as `run` stores it."""
    tmp = tmp_path_factory.mktemp("rerun")
    source = tmp / "campaign.yaml"
    text = (ROOT / "campaigns/smoke.yaml").read_text()
    text = text.replace("../configs/", f"{ROOT}/configs/").replace("runs: 20", "runs: 6")
    text = text.replace("failures:\n  mode: none", "failures:\n  mode: random\n  count_probabilities: [0.5, 0.5]")
    source.write_text(text)
    campaign = load_campaign(source)
    out = tmp / "out"
    return out, store_campaign(campaign, out)


def test_rerun_reproduces_every_stored_row_exactly(finished):
    out, rows = finished
    assert any(row["failed_thrusters"] for row in rows)  # the campaign has failures to reproduce
    for row in rows:
        result = rerun(out, row["run_id"])
        assert result["stored"] is not None
        assert result["differ"] == [], result["differ"]
        assert result["row"]["p.rcs.thrust_scale.4"] == row["p.rcs.thrust_scale.4"]


def test_rerun_writes_a_full_rate_history(finished, tmp_path):
    out, rows = finished
    dest = tmp_path / "run3.parquet"
    result = rerun(out, 3, dest=dest)
    history = pq.read_table(dest).to_pandas()
    assert result["path"] == dest
    assert (history["run_id"] == 3).all()
    # every 25 ms control step of the flight, plus the final state
    assert abs(len(history) - rows[3]["t_end_s"] * 40.0) <= 2
    assert history["t_s"].diff().iloc[1:-1].round(9).eq(0.025).all()
    default = rerun(out, 3, history_rate_hz=2.0)
    assert default["path"] == out / "reruns" / "run-3.parquet"
    assert abs(len(pq.read_table(default["path"])) - rows[3]["t_end_s"] * 2.0) <= 2


def test_rerun_refuses_a_bad_directory_or_run_id(finished, tmp_path):
    out, _ = finished
    with pytest.raises(ConfigError, match="no campaign.resolved.yaml"):
        rerun(tmp_path, 0)
    with pytest.raises(ConfigError, match=r"run id 0\.\.5"):
        rerun(out, 6)
    copy = tmp_path / "copy"
    shutil.copytree(out, copy)
    assert rerun(copy, 2)["differ"] == []  # OUT alone is enough, wherever it is


def test_rerun_history_matches_the_stored_history_sample_by_sample(finished, tmp_path):
    """The re-flown full-rate history holds every stored (2 Hz) sample, bit for bit: the same
    flight, sampled more often (a rerun that only matched the summary row would pass the tests above)."""
    out, rows = finished
    stored = pq.read_table(out / "histories").to_pandas()
    for run_id in (0, 3):
        full = pq.read_table(rerun(out, run_id, dest=tmp_path / f"run{run_id}.parquet")["path"]).to_pandas()
        mine = stored[stored["run_id"] == run_id].reset_index(drop=True)
        assert len(mine) > 10
        # the last stored sample is the final state, not on the 2 Hz grid; both histories end with it
        picked = full.set_index("t_s").loc[mine["t_s"]].reset_index()[list(full.columns)]
        assert list(picked.columns) == list(mine.columns)
        for column in mine.columns:
            assert picked[column].equals(mine[column]), column


def test_rerun_reports_a_stored_column_the_new_row_lacks(finished, tmp_path):
    """A stored column the re-flown row does not have (a renamed or dropped output) differs."""
    import pyarrow as pa

    out, _ = finished
    copy = tmp_path / "copy"
    shutil.copytree(out, copy)
    table = pq.read_table(copy / "runs")
    table = table.append_column("an_old_output", pa.array([1.0] * table.num_rows))
    for part in (copy / "runs").glob("part-*.parquet"):
        part.unlink()
    pq.write_table(table, copy / "runs" / "part-00000.parquet")
    assert rerun(copy, 1)["differ"] == ["an_old_output"]
