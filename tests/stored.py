"""Helpers the tests share: campaign files made runnable from a temporary directory, `refexmc run`
through click, a snapshot of a directory's files, reading a stored runs table, and building an
output directory in-process."""

from pathlib import Path

import pyarrow.parquet as pq
from click.testing import CliRunner

from refexmc.campaign import storage
from refexmc.campaign.chunk import fly_chunk
from refexmc.cli import main

ROOT = Path(__file__).resolve().parents[1]


def campaign_copy(source, tmp_path, name=None, replace=(), **extra):
    """``campaigns/<source>`` written to ``tmp_path`` with config paths made absolute, the
    ``(old, new)`` text replacements applied and ``extra`` top-level keys appended."""
    text = (ROOT / "campaigns" / source).read_text().replace("../configs", str(ROOT / "configs"))
    for old, new in replace:
        text = text.replace(old, new)
    text += "".join(f"{key}: {value}\n" for key, value in extra.items())
    path = tmp_path / (name or source)
    path.write_text(text)
    return path


def invoke_run(*args):
    """`refexmc run ARGS...` through click (arguments as strings)."""
    return CliRunner().invoke(main, ["run", *map(str, args)])


def snapshot(out):
    """Every file under OUT with its modification time and content."""
    return {p.relative_to(out): (p.stat().st_mtime_ns, p.read_bytes()) for p in Path(out).rglob("*") if p.is_file()}


def read_runs(out):
    """The stored runs table of ``out`` as a DataFrame sorted by run id."""
    return pq.read_table(Path(out) / "runs").to_pandas().sort_values("run_id", ignore_index=True)


def store_campaign(campaign, out):
    """Fly every run of ``campaign`` into ``out``: resolved campaign, one runs part, one histories part."""
    storage.prepare_output(out)
    storage.write_resolved(out, campaign)
    rows, history = fly_chunk(campaign, range(campaign["runs"]))
    storage.write_table_atomic(storage.runs_table(rows), out / "runs" / storage.part_name(0))
    storage.write_table_atomic(history or storage.empty_history_table(), out / "histories" / storage.part_name(0))
    return rows
