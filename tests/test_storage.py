"""The Parquet tables of refexmc.campaign.storage: their schema and values, whatever a chunk holds."""

from pathlib import Path

import pyarrow.parquet as pq
import pytest

from refexmc.campaign import storage
from refexmc.campaign.chunk import fly_chunk
from refexmc.config.load import apply_overrides, load_campaign

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def smoke_chunk():
    """(rows, history tables) of three smoke runs."""
    campaign = apply_overrides(load_campaign(ROOT / "campaigns/smoke.yaml"), runs=3)
    return fly_chunk(campaign, range(3))


def test_the_empty_history_table_has_the_schema_of_a_flown_one(smoke_chunk):
    _, histories = smoke_chunk
    assert storage.empty_history_table().schema.equals(histories[0].schema)


def test_a_histories_folder_read_whole_keeps_its_modes_when_the_first_part_is_empty(smoke_chunk, tmp_path):
    """A chunk whose runs all errored writes an empty histories part; it must not hide the mode names."""
    _, histories = smoke_chunk
    storage.write_table_atomic(storage.empty_history_table(), tmp_path / storage.part_name(0))
    storage.write_table_atomic(histories[0], tmp_path / storage.part_name(1))
    table = pq.read_table(tmp_path)
    assert table.column("mode").to_pylist() == histories[0].column("mode").to_pylist()
