"""Reading a campaign output directory for the report: the runs table, the campaign, history batches.

The runs table (one row per run) is read whole: at 10,000 runs and ~130 columns it is ~10 MB.
Histories are never read whole: ``history_batches`` yields record batches of the few columns a
figure needs, part file by part file, so memory stays bounded whatever the campaign size.
"""

import json
import os
import re
import shlex
import warnings
from collections import deque
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from functools import cached_property
from itertools import islice
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import yaml

from refexmc.campaign import storage
from refexmc.config import renames
from refexmc.config.errors import ConfigError
from refexmc.config.load import read_yaml

HISTORY_BATCH_ROWS = 1 << 18
MODE_TIME_PATTERN = re.compile(r"^t_(.+)_s$")  # the runs table's time spent in each mode
FLIGHT_TIME_COLUMN = "t_end_s"  # matches the pattern but is the whole flight


def rerun_command(out, run_id):
    """The command that re-flies run ``run_id`` of the campaign written in ``out``."""
    return f"refexmc rerun {shlex.quote(str(out))} {int(run_id)}"


def mode_time_column(name):
    """The runs-table column of the time spent in mode ``name``: ``t_<name lower-cased>_s``."""
    return f"t_{name.lower()}_s"


def mode_names(manifest, runs_columns, file=None):
    """The campaign's mode display names in flight order.

    From ``manifest.json`` ``"modes"``; for an output written before that key existed, from the
    runs table's ``t_<mode>_s`` columns (other than ``t_end_s``) in table order, upper-cased.
    ConfigError (naming ``file``) when ``"modes"`` is not a list of distinct names.
    """
    listed = (manifest or {}).get("modes")
    if listed is None:
        return [
            found.group(1).upper()
            for column in runs_columns
            if column != FLIGHT_TIME_COLUMN and (found := MODE_TIME_PATTERN.match(column))
        ]
    names = listed if isinstance(listed, list) else []
    columns = [mode_time_column(name) for name in names if isinstance(name, str) and name.strip()]
    if not names or len(columns) != len(names) or len(set(columns)) != len(columns):
        raise ConfigError(f"expected a list of distinct mode names, got {listed!r}", file=file, path=("modes",))
    if FLIGHT_TIME_COLUMN in columns:
        raise ConfigError(f"no mode may be named 'end': {FLIGHT_TIME_COLUMN} is the flight", file=file, path=("modes",))
    return list(names)


@dataclass
class Campaign:
    """What the report knows about one output directory."""

    out: Path
    runs: pd.DataFrame  # every row of OUT/runs, sorted by run_id
    resolved: dict  # OUT/campaign.resolved.yaml
    resolved_lines: dict  # key path -> line in campaign.resolved.yaml
    manifest: dict = field(default_factory=dict)
    history_parts: list = field(default_factory=list)
    study_runs: pd.DataFrame | None = None  # a rare-event study's every flight; ``runs`` is its level 0

    # The populations are computed once per Campaign (the runs table is not changed after load);
    # a population that is the whole table is the table itself, not a copy: at 100,000 runs and
    # ~130 columns each copy is ~100 MB.

    @cached_property
    def ok(self):
        """Runs with status ok: the population of every statistic."""
        return self._where(self.runs["status"] == "ok")

    @cached_property
    def errored(self):
        return self._where(self.runs["status"] != "ok")

    @cached_property
    def successful(self):
        """Flights that flew (status ok) and succeeded: the population of the statistics tables."""
        return self._where((self.runs["status"] == "ok") & self.runs["success"].astype(bool))

    @cached_property
    def failed(self):
        """Flights that flew (status ok) and did not succeed."""
        return self._where((self.runs["status"] == "ok") & ~self.runs["success"].astype(bool))

    def _where(self, mask):
        return self.runs if bool(mask.all()) else self.runs[mask]

    @property
    def name(self):
        return self.resolved.get("name") or self.manifest.get("name") or self.out.name

    @property
    def nominal_run_id(self):
        """Run 0 when the campaign flies the nominal case first and run 0 is ok; else None."""
        if not self.resolved.get("nominal_first", True):
            return None
        ok_ids = self.ok["run_id"].to_numpy()
        return 0 if (ok_ids == 0).any() else None

    @property
    def thruster_count(self):
        return sum(1 for c in self.runs.columns if c.startswith("pulses_") and c[7:].isdigit())

    @property
    def parameter_columns(self):
        return [c for c in self.runs.columns if c.startswith("p.")]

    @property
    def modes(self):
        """Mode display names in flight order (:func:`mode_names`)."""
        return mode_names(self.manifest, self.runs.columns)

    @property
    def mode_time_columns(self):
        """Runs columns of the time spent in each mode, in flight order."""
        return [mode_time_column(name) for name in self.modes]

    @property
    def history_rate_hz(self):
        return float((self.resolved.get("output") or {}).get("history_rate_hz", 2.0))


RUNS_PARTS_PER_GROUP = 64  # runs parts read and joined into one table by one thread
MAX_THREADS = 16  # threads of the report's parallel stages, at most


def threads():
    """Threads for the report's parallel stages: the CPUs this process may use (at most MAX_THREADS).
    pyarrow decodes and numpy sorts, bins and counts without the GIL, so they run on every core."""
    try:
        available = len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        available = os.cpu_count() or 1
    return max(1, min(MAX_THREADS, available))


def map_on_threads(function, items):
    """``[function(item) for item in items]``, computed on :func:`threads` threads: for numpy work
    on whole columns (sorting, ranking), which runs without the GIL."""
    items = list(items)
    if len(items) < 2 or threads() < 2:
        return [function(item) for item in items]
    with ThreadPoolExecutor(min(threads(), len(items))) as pool:
        return list(pool.map(function, items))


def _join(tables):
    """``pa.concat_tables`` of ``tables``, their schemas unified (a column missing or typed null in
    some); the schemas of one output's parts are usually equal, and then join ~8x faster."""
    try:
        return pa.concat_tables(tables)
    except pa.ArrowInvalid:  # schemas differ
        return pa.concat_tables(tables, promote_options="default")


def _read_group(parts):
    """One table of the runs ``parts``, each column in one chunk; columns in today's names (their
    failure reasons are renamed once, on the joined table: :func:`read_runs_parts`)."""
    # pre_buffer (coalesced reads on pyarrow's I/O threads, made for object stores) only adds waiting here
    tables = [
        renames.runs_table(pq.ParquetFile(part, pre_buffer=False).read(use_threads=False), reasons=False)
        for part in parts
    ]
    return _join(tables).combine_chunks()


def read_runs_parts(parts):
    """The runs table of the part files ``parts``, in their order (as ``pq.read_table`` of each, joined).

    A large campaign has a thousand parts of 100 rows and ~140 columns: read one by one
    (``pq.read_table``) they took 9 s at 100,000 runs, and holding a thousand small tables costs
    ~2.7 times their data in Arrow's per-array objects (a 111 MB table held 300 MB). Groups of
    parts are read on threads and each joined into contiguous columns as soon as it is read.
    """
    groups = [parts[k : k + RUNS_PARTS_PER_GROUP] for k in range(0, len(parts), RUNS_PARTS_PER_GROUP)]
    if len(groups) == 1:
        return renames.runs_failure_reasons(_read_group(groups[0]))
    with ThreadPoolExecutor(min(threads(), len(groups))) as pool:
        tables = list(pool.map(_read_group, groups))
    return renames.runs_failure_reasons(_join(tables))


JSON_TYPES = {list: "a list", str: "a string", int: "a number", float: "a number", bool: "a boolean"}


def read_manifest(path):
    """``manifest.json`` at ``path`` as a dict, its column names as now named (``storage.read_manifest``);
    ConfigError naming the file (and the line of a JSON error) when it is not a JSON object."""
    path = Path(path)
    try:
        info = json.loads(path.read_bytes().decode("utf-8"))
    except json.JSONDecodeError as exc:  # cut short by a full disk or a kill, or edited by hand
        raise ConfigError(f"not valid JSON: {exc.msg} (column {exc.colno})", file=path, line=exc.lineno) from None
    except UnicodeDecodeError as exc:
        raise ConfigError(f"not valid JSON: not UTF-8 text (byte {exc.start})", file=path) from None
    if not isinstance(info, dict):
        got = "null" if info is None else JSON_TYPES.get(type(info), type(info).__name__)
        raise ConfigError(f"expected a JSON object, got {got} (`refexmc run` writes an object)", file=path)
    return renames.manifest(info)


def load(out):
    """Read OUT for the report; ConfigError when OUT is not a campaign output with runs."""
    out = Path(out)
    resolved_path = out / "campaign.resolved.yaml"
    if not out.is_dir():
        raise ConfigError("output directory not found", file=out)
    if not resolved_path.is_file():
        raise ConfigError("not a refexmc output directory (no campaign.resolved.yaml)", file=out)
    parts = sorted((out / "runs").glob("part-*.parquet"))
    if not parts:
        raise ConfigError("no runs/part-*.parquet: the campaign has not stored any run yet", file=out)
    resolved, lines = read_yaml(resolved_path)
    renames.migrate_campaign(resolved, lines)  # written before a rename: read as of now (issue 34)
    manifest_path = out / "manifest.json"
    manifest = read_manifest(manifest_path) if manifest_path.is_file() else {}
    # a column at a time (split_blocks), each freed once converted: at 10^6 runs the table is ~1 GB,
    # and one 2-D block of its float columns would hold a second copy before the first is freed
    runs = read_runs_parts(parts).to_pandas(self_destruct=True, split_blocks=True)
    pa.default_memory_pool().release_unused()  # Arrow's pool keeps freed pages otherwise
    if not runs["run_id"].is_monotonic_increasing:  # parts in chunk order hold their runs in order
        runs = runs.sort_values("run_id", kind="stable").reset_index(drop=True)
    pulse_columns = [c for c in runs.columns if c.startswith("pulses_") and c[7:].isdigit()]
    if pulse_columns:
        with warnings.catch_warnings():  # a frame of one block per column is "fragmented" on purpose
            warnings.simplefilter("ignore", pd.errors.PerformanceWarning)
            runs["pulses_total"] = runs[pulse_columns].sum(axis=1)
    for column in ("failure_reason", "failed_thrusters"):
        if column in runs:
            runs[column] = runs[column].astype(object).where(runs[column].notna(), None)
    if "failed_thrusters" in runs:
        runs["failed_thrusters"] = runs["failed_thrusters"].fillna("")
    study_runs, history_parts = None, sorted((out / "histories").glob("part-*.parquet"))
    if "rare_event" in (resolved or {}) and "level" in runs.columns:  # the statistics are level 0's (issue 36)
        study_runs = runs
        runs = runs[runs["level"] == 0].drop(columns=list(STUDY_COLUMNS)).reset_index(drop=True)
        per_level = int(resolved.get("runs") or len(runs) or 1)  # a study's runs: per_level (config.rare_event)
        level0_parts = -(-per_level // max(1, int(manifest.get("chunk_size") or per_level)))
        history_parts = [p for p in history_parts if int(p.stem.split("-")[1]) < level0_parts]
    names = mode_names(manifest, runs.columns, file=manifest_path)
    missing = [mode_time_column(name) for name in names if mode_time_column(name) not in runs.columns]
    if missing:
        raise ConfigError(
            f"the runs table lacks the time of modes listed in manifest.json: {', '.join(missing)}",
            file=manifest_path,
            path=("modes",),
        )
    return Campaign(
        out=out,
        runs=runs,
        resolved=resolved or {},
        resolved_lines=lines,
        manifest=manifest,
        history_parts=history_parts,
        study_runs=study_runs,
    )


def completeness(campaign):
    """Did every planned run fly? A dict (JSON-ready) the verdict is built on.

    Incomplete when the manifest's status is not ``complete`` (``run`` writes ``running`` first
    and ``complete`` last), when run ids 0..runs-1 are not all in the runs table, or when chunks
    (``part-*.parquet`` of runs, or of histories where the campaign stored histories) are
    missing. Without a manifest the runs table alone decides. Errored: runs with status error.
    """
    planned = campaign.resolved.get("runs")
    stored_ids = campaign.runs["run_id"].to_numpy(dtype=np.int64)
    problems = []
    status = campaign.manifest.get("status") if campaign.manifest else None
    if campaign.manifest and status != "complete":
        problems.append(f"manifest status is '{status}', not 'complete'")
    missing_ids = []
    if planned is not None:
        missing_ids = missing_run_ids(int(planned), stored_ids).tolist()
        if missing_ids:
            problems.append(f"{len(missing_ids)} of {planned} planned runs missing from the runs table")
    duplicates = duplicate_count(stored_ids)
    if duplicates:
        problems.append(f"{duplicates} run ids stored twice")
    runs_parts = {p.name for p in (campaign.out / "runs").glob("part-*.parquet")}
    history_parts = {p.name for p in campaign.history_parts}
    expected_parts = set()
    chunk_size = campaign.manifest.get("chunk_size") if campaign.manifest else None
    if planned is not None and isinstance(chunk_size, int) and chunk_size > 0:
        expected_parts = {storage.part_name(k) for k in range(-(-int(planned) // chunk_size))}
    if campaign.study_runs is not None and expected_parts:  # a rare-event study: level 0's parts are the campaign's
        runs_parts &= expected_parts
    missing_chunks = sorted((expected_parts - runs_parts) | ((runs_parts - history_parts) if history_parts else set()))
    if missing_chunks:
        problems.append(
            f"{len(missing_chunks)} chunk part files missing ({', '.join(missing_chunks[:5])}"
            + (", ..." if len(missing_chunks) > 5 else "")
            + ")"
        )
    errored_ids = campaign.errored["run_id"].astype(int).tolist()
    return {
        "complete": not problems,
        "problems": problems,
        "manifest_status": status,
        "runs_planned": None if planned is None else int(planned),
        "runs_stored": int(len(stored_ids)),
        "missing_run_count": len(missing_ids),
        "missing_run_ids": id_ranges(missing_ids),
        "missing_chunks": missing_chunks,
        "errored_count": len(errored_ids),
        "errored_run_ids": errored_ids[:LISTED_IDS],
        "resume_command": resume_command(campaign),
    }


def missing_run_ids(planned, stored_ids):
    """Run ids 0..planned-1 not in ``stored_ids``, ascending (``np.setdiff1d`` of the range, in
    linear time: at 10^6 runs the sorts of ``setdiff1d`` took 3 s)."""
    present = np.zeros(max(planned, 0), dtype=bool)
    present[stored_ids[(stored_ids >= 0) & (stored_ids < planned)]] = True
    return np.flatnonzero(~present).astype(np.int64)


def duplicate_count(ids):
    """How many of ``ids`` repeat an earlier one (``len(ids) - len(np.unique(ids))``); the runs
    table is sorted by run id, so mostly without a sort."""
    if len(ids) < 2:
        return 0
    ordered = ids if bool((ids[1:] >= ids[:-1]).all()) else np.sort(ids)
    return int((ordered[1:] == ordered[:-1]).sum())


LISTED_IDS = 20
STUDY_COLUMNS = ("level", "chain", "step", "margin")  # a rare-event study's own columns (campaign.rare_event)


def resume_command(campaign):
    """The `refexmc run ... --resume` command that finishes OUT: the campaign file its manifest
    names (CAMPAIGN when none) with the ``--runs`` and ``--seed`` OUT was started with where they
    are not the file's own (a campaign started with ``--runs 50`` resumes only with ``--runs 50``)."""
    from refexmc.campaign.run import resume_command as command

    resolved = campaign.resolved
    file = (campaign.manifest or {}).get("campaign_file")
    own = {}
    if file and Path(file).is_file():
        try:
            own = yaml.safe_load(Path(file).read_text()) or {}
        except (OSError, yaml.YAMLError):
            own = {}
    own = own if isinstance(own, dict) else {}
    enumerated = any((resolved.get(key) or {}).get("mode") == "enumerate" for key in ("failures", "wheel_failures"))
    runs, seed = resolved.get("runs"), resolved.get("seed")
    return command(
        file or "CAMPAIGN",
        campaign.out,
        runs=None if enumerated or own.get("runs") == runs else runs,  # enumerate derives its runs
        seed=None if own.get("seed") == seed else seed,
    )


def id_ranges(ids, limit=LISTED_IDS):
    """``[0, 1, 2, 5, 7, 8]`` -> ``"0-2, 5, 7-8"`` (at most ``limit`` ranges, then "...")."""
    ids = sorted(int(i) for i in ids)
    ranges = []
    for i in ids:
        if ranges and i == ranges[-1][1] + 1:
            ranges[-1][1] = i
        else:
            ranges.append([i, i])
    text = [f"{a}" if a == b else f"{a}-{b}" for a, b in ranges[:limit]]
    return ", ".join(text) + (", ..." if len(ranges) > limit else "")


def mode_codes(column, modes):
    """Mode of each history row as an index into ``modes`` (-1 for an unknown name).

    Names match without regard to case, as their ``t_<mode>_s`` columns do (an output without
    ``"modes"`` in its manifest knows them only upper-cased).
    """
    if pa.types.is_dictionary(column.type):
        index = {name.lower(): k for k, name in enumerate(modes)}
        names = column.dictionary.to_pylist()
        lookup = np.array([index.get(str(n).lower(), -1) for n in names], dtype=np.int16)
        indices = column.indices.to_numpy(zero_copy_only=False)
        return lookup[indices] if len(lookup) else np.full(len(indices), -1, np.int16)
    return mode_codes(column.dictionary_encode(), modes)


def present_columns(campaign):
    """History columns every part of the OUT with rows has (a part without rows, of a chunk whose
    runs all errored, has the columns of no family): each family writes only its own columns."""
    names = None
    for metadata in map_on_threads(pq.read_metadata, campaign.history_parts):  # 10^6 runs: 10,000 footers
        if metadata.num_rows == 0:
            continue
        here = set(metadata.schema.names)
        names = here if names is None else names & here
    return names or set()


HISTORY_READ_AHEAD = None  # parts read (and mapped) on threads ahead of the one being used: threads(), at least 2


def _history_part_batches(part, columns, batch_rows, function=None):
    parquet = pq.ParquetFile(part, pre_buffer=False)
    if parquet.metadata.num_rows == 0:  # a chunk whose runs all errored: no rows, any columns
        return []
    present = [c for c in columns if c in parquet.schema_arrow.names]
    if len(present) < len(columns):
        missing = sorted(set(columns) - set(present))
        raise ConfigError(f"histories part lacks columns {', '.join(missing)}", file=part)
    batches = parquet.iter_batches(batch_size=batch_rows, columns=columns, use_threads=False)
    return [batch if function is None else function(batch) for batch in batches]


def map_history_batches(campaign, columns, function=None, batch_rows=HISTORY_BATCH_ROWS, read_ahead=HISTORY_READ_AHEAD):
    """Yield ``function(batch)`` (the batch itself without a function) for the record batches of
    ``columns`` of every histories part, part by part, in order.

    The next ``read_ahead`` parts (default: one per core, :func:`threads`) are read, and mapped,
    on threads while the caller uses this one's results: pyarrow decodes and numpy computes on
    arrays without holding the GIL, so the histories are read and binned on every core.
    ``function`` must not change shared state. At most ``read_ahead + 1`` parts' results are
    held: a part is what one worker held when it flew.
    """
    parts = iter(campaign.history_parts)
    if read_ahead is None:
        read_ahead = max(2, threads())
    if read_ahead < 1:
        for part in parts:
            yield from _history_part_batches(part, columns, batch_rows, function)
        return
    with ThreadPoolExecutor(read_ahead) as pool:
        queue = deque(
            pool.submit(_history_part_batches, part, columns, batch_rows, function)
            for part in islice(parts, read_ahead)
        )
        while queue:
            results = queue.popleft().result()
            part = next(parts, None)
            if part is not None:
                queue.append(pool.submit(_history_part_batches, part, columns, batch_rows, function))
            yield from results


def history_batches(campaign, columns, batch_rows=HISTORY_BATCH_ROWS, read_ahead=HISTORY_READ_AHEAD):
    """Yield record batches of ``columns`` from every histories part, part by part, in order
    (read ahead on threads: :func:`map_history_batches`)."""
    return map_history_batches(campaign, columns, batch_rows=batch_rows, read_ahead=read_ahead)
