"""A big campaign output for the report benchmark: a finished OUT repeated ``--times`` times (issue 25).

Flying 100,000 ReFEx runs takes an hour on 2 cores; the report's cost depends on how many rows it
reads, not on whether they differ. This copies SRC's runs table AND its histories ``--times`` times
into DEST, copy ``c`` with run ids shifted by ``c * runs`` and its part files numbered after the
previous copy's, so DEST is a complete output that ``refexmc report`` accepts: ``manifest.json``
(status complete, ``runs`` and ``counts`` scaled, ``resolved_sha256`` of the new resolved
campaign, ``repeated_from`` naming SRC), ``campaign.resolved.yaml`` with ``runs`` scaled (every
other line as in SRC, so the report's line numbers hold), ``runs/`` and ``histories/`` parts
written as ``refexmc run`` writes them (``storage.write_table_atomic``: zstd, the same row groups).
Only run 0 is the nominal run; runs ``runs``, ``2 runs``, ... are copies of it.

SRC must be complete and its run count a multiple of its chunk size (every part full), so that
the parts of DEST are ``part-00000`` ... in order.

Usage: .venv/bin/python benchmarks/make_big_out.py SRC DEST [--times 10] [--no-histories] [--overwrite]

E.g. ``refexmc run campaigns/refex-mc100.yaml --runs 10000 -j 1 -o /tmp/mc10k``, then
``benchmarks/make_big_out.py /tmp/mc10k /tmp/mc100k`` (1.6 GB of histories; ~2 minutes) and
``benchmarks/bench_report.py /tmp/mc100k --stages``. ``--no-histories`` repeats the runs table
only (the "runs table only" rows of RESULTS.md, issue 25).
"""

import argparse
import re
import shutil
import sys
import time
from pathlib import Path

import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq
import yaml

from refexmc.campaign import storage


def shifted(table, offset):
    """``table`` with ``offset`` added to its run_id column (int64, as stored)."""
    index = table.schema.get_field_index("run_id")
    return table.set_column(index, "run_id", pc.add(table.column("run_id"), pa.scalar(offset, pa.int64())))


def scaled_resolved(text, runs, times):
    """campaign.resolved.yaml's text with its top-level ``runs: <runs>`` line scaled by ``times``."""
    new, count = re.subn(rf"(?m)^runs: {runs}$", f"runs: {runs * times}", text)
    if count != 1:
        sys.exit(f"expected one line 'runs: {runs}' in campaign.resolved.yaml, found {count}")
    return new


def make_big_out(src, dest, times, histories=True, overwrite=False):
    """Write DEST (see the module docstring); returns (runs, parts, seconds)."""
    start = time.perf_counter()
    src, dest = Path(src), Path(dest)
    info = storage.read_manifest(src)
    runs, chunk = int(info["runs"]), int(info["chunk_size"])
    if info.get("status") != "complete":
        sys.exit(f"{src}: manifest status is {info.get('status')!r}, not 'complete'")
    if runs % chunk:
        sys.exit(f"{src}: {runs} runs is not a multiple of the chunk size {chunk}")
    parts = runs // chunk
    names = [storage.part_name(k) for k in range(parts)]
    folders = ["runs", "histories"] if histories else ["runs"]
    for folder in folders:
        missing = [name for name in names if not (src / folder / name).is_file()]
        if missing:
            sys.exit(f"{src}/{folder}: {len(missing)} parts missing ({', '.join(missing[:3])} ...)")
    if dest.exists():
        if not overwrite:
            sys.exit(f"{dest} exists; use --overwrite to replace it")
        if not storage.is_output(dest):
            sys.exit(f"{dest} is not a refexmc output; not replacing it")
        shutil.rmtree(dest)
    (dest / "runs").mkdir(parents=True)
    (dest / "histories").mkdir()
    for folder in folders:
        for k, name in enumerate(names):
            path = src / folder / name  # runs in today's column names (config.renames), as flown now
            table = storage.read_runs_part(path) if folder == "runs" else pq.read_table(path)
            for copy in range(times):
                target = dest / folder / storage.part_name(copy * parts + k)
                storage.write_table_atomic(shifted(table, copy * runs), target)
    resolved_text = scaled_resolved((src / "campaign.resolved.yaml").read_text(), runs, times)
    storage.write_text_atomic(resolved_text, dest / "campaign.resolved.yaml")
    campaign = yaml.load(resolved_text, Loader=storage._YAML_LOADER)
    info.update(
        runs=runs * times,
        resolved_sha256=storage.campaign_digest(campaign),
        counts={key: value * times for key, value in (info.get("counts") or {}).items()},
        repeated_from={"out": str(src), "times": times, "histories": histories},
    )
    storage.write_manifest(dest, info)
    return runs * times, parts * times, time.perf_counter() - start


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("src", type=Path)
    parser.add_argument("dest", type=Path)
    parser.add_argument("--times", type=int, default=10)
    parser.add_argument("--no-histories", action="store_true", help="repeat the runs table only")
    parser.add_argument("--overwrite", action="store_true")
    args = parser.parse_args()
    if args.times < 1:
        parser.error("--times must be at least 1")
    runs, parts, seconds = make_big_out(args.src, args.dest, args.times, not args.no_histories, args.overwrite)
    history_bytes = sum(p.stat().st_size for p in (args.dest / "histories").glob("part-*.parquet"))
    print(f"{args.dest}: {runs} runs in {parts} parts, {history_bytes / 2**20:.0f} MiB of histories, {seconds:.1f} s")


if __name__ == "__main__":
    main()
