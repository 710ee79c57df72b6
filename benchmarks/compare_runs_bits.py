"""Compare the runs tables of two sets of campaign outputs column by column, by their bits.

A refactor that should not change what is flown (issue 26 part 6: the parameter table) is
checked by flying every shipped campaign before and after it into two folders of outputs
(``refexmc run campaigns/NAME.yaml -o BEFORE/NAME ...``) and comparing them here: the same
columns in the same order, and every value the same bits (floats by their IEEE pattern, so
NaN equals NaN and -0.0 differs from 0.0).

    .venv/bin/python benchmarks/compare_runs_bits.py /tmp/params_before /tmp/params_after

Exit status 0 when every output found in BEFORE has an identical runs table in AFTER, else 1.
"""

import sys
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq


def column_bits(column):
    """A column's values as bytes: floats by their IEEE pattern, anything else by its Python values."""
    column = column.combine_chunks() if isinstance(column, pa.ChunkedArray) else column
    if pa.types.is_floating(column.type):
        return column.to_numpy(zero_copy_only=False).astype(np.float64).view(np.uint64).tobytes()
    return repr(column.to_pylist()).encode()


def differences(before_dir, after_dir):
    """The names of the columns that differ (or 'columns' / 'rows' when their lists differ)."""
    before = pq.read_table(Path(before_dir) / "runs").sort_by("run_id")
    after = pq.read_table(Path(after_dir) / "runs").sort_by("run_id")
    if before.column_names != after.column_names:
        return ["columns"]
    if before.num_rows != after.num_rows:
        return ["rows"]
    return [name for name in before.column_names if column_bits(before[name]) != column_bits(after[name])]


def main(argv):
    before_root, after_root = (Path(a) for a in argv)
    failed = False
    # a campaign's output, or a sweep's points (points/NNN, each a campaign output)
    outputs = sorted({p.parent for pattern in ("*/runs", "*/points/*/runs") for p in before_root.glob(pattern)})
    for before in outputs:
        name = before.relative_to(before_root)
        after = after_root / name
        if not (after / "runs").exists():
            print(f"{name}: missing in {after_root}")
            failed = True
            continue
        table = pq.read_table(before / "runs")
        bad = differences(before, after)
        failed |= bool(bad)
        verdict = "identical" if not bad else "DIFFERENT: " + ", ".join(bad)
        print(f"{name}: {table.num_rows} runs, {table.num_columns} columns {verdict}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
