"""Build a campaign output directory in-process, as `refexmc run` stores it (for report/rerun tests)."""

import pyarrow as pa

from refexmc.campaign import storage
from refexmc.campaign.chunk import fly_chunk


def store_campaign(campaign, out):
    """Fly every run of ``campaign`` into ``out``: resolved campaign, one runs part, one histories part."""
    storage.prepare_output(out)
    storage.write_resolved(out, campaign)
    rows, histories = fly_chunk(campaign, range(campaign["runs"]))
    storage.write_table_atomic(storage.runs_table(rows), out / "runs" / storage.part_name(0))
    storage.write_table_atomic(pa.concat_tables(histories), out / "histories" / storage.part_name(0))
    return rows
