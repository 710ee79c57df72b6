"""Output directory: Parquet part files (written atomically), manifest and resolved campaign."""

import functools
import hashlib
import itertools
import json
import os
import platform
import re
import shutil
from contextlib import suppress
from datetime import UTC, datetime
from importlib import metadata
from pathlib import Path
from typing import NamedTuple

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import yaml

import refexmc
from refexmc.config import renames
from refexmc.config.errors import ConfigError


def now():
    return datetime.now(UTC).isoformat(timespec="seconds")


PARQUET_COMPRESSION = "zstd"
# zstd's fast level -1 (Arrow's default is 1): a 1,000-run ReFEx history part encodes 17 % faster
# and is no larger (15.19 against 15.23 MB), a runs part 2 % larger; any zstd reader decodes it
PARQUET_COMPRESSION_LEVEL = -1


def write_options(schema):
    """``pq.write_table`` options of a table: zstd (level -1); dictionary encoding but for floating-point
    columns, which are stored byte-stream split.

    Float values hardly repeat: a dictionary only costs hashing each value, and makes larger files
    than plain values (a history part: 0.36 -> 0.15 ms per run to encode, 25.9 -> 17.4 kB per run).
    Byte-stream split (Parquet's BYTE_STREAM_SPLIT: the values' first bytes, then their second
    bytes, ...) puts the signs, exponents and high mantissa bytes of a signal side by side, which
    zstd compresses; the low mantissa bytes stay noise. Lossless, as every encoding: a ReFEx
    history 17.4 -> 15.3 kB per run, a runs row 1.37 -> 1.29 kB, encoding as fast, decoding
    faster (benchmarks/RESULTS.md, issue 37). Readers need Parquet format 2.8 (pyarrow >= 2).
    """
    floating = [field.name for field in schema if pa.types.is_floating(field.type)]
    dictionary = [field.name for field in schema if field.name not in floating]
    return {
        "compression": PARQUET_COMPRESSION,
        "compression_level": PARQUET_COMPRESSION_LEVEL,
        "use_dictionary": dictionary,
        "column_encoding": dict.fromkeys(floating, "BYTE_STREAM_SPLIT"),
    }


def encode_table(table):
    """A table as the bytes of a Parquet file: workers compress, the writing process only writes."""
    sink = pa.BufferOutputStream()
    pq.write_table(table, sink, **write_options(table.schema))
    return sink.getvalue().to_pybytes()


def decode_table(data):
    """The table of Parquet file bytes (:func:`encode_table`)."""
    return pq.read_table(pa.BufferReader(data))


def _write_atomic(path, write):
    """Call ``write(tmp)`` for a temporary name beside ``path``, then rename: readers never see a partial file.

    An OSError (disk full, read-only file system) removes the temporary file and is raised again naming
    ``path`` (a failed ``write`` names no file); any other exception, such as the signal that stops
    a campaign (``run.CampaignInterrupted``) in the middle of a write, removes it too.
    """
    path = Path(path)
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        write(tmp)
        os.replace(tmp, path)
    except OSError as exc:
        with suppress(OSError):
            tmp.unlink(missing_ok=True)
        raise OSError(exc.errno, exc.strerror or str(exc), str(path)) from exc
    except BaseException:
        with suppress(OSError):
            tmp.unlink(missing_ok=True)
        raise


def write_bytes_atomic(data, path):
    """Write bytes under a temporary name, then rename: readers never see a partial file."""
    _write_atomic(path, lambda tmp: tmp.write_bytes(data))


def place_part(part, path):
    """Put a chunk's part at ``path`` atomically: its Parquet bytes written under a temporary name
    and renamed, or the file a worker wrote them to (a Path in the campaign's work directory, on
    OUT's file system: refexmc.campaign.cuda_backend) renamed."""
    if isinstance(part, Path):
        _write_atomic(path, lambda tmp: os.replace(part, tmp))
    else:
        write_bytes_atomic(part, path)


def write_table_atomic(table, path):
    """Write a Parquet file under a temporary name, then rename: readers never see a partial file."""
    _write_atomic(path, lambda tmp: pq.write_table(table, tmp, **write_options(table.schema)))


def write_text_atomic(text, path):
    _write_atomic(path, lambda tmp: tmp.write_text(text))


def part_name(chunk_index):
    return f"part-{chunk_index:05d}.parquet"


class Failures(NamedTuple):
    """The failed units of one run: 1-based ids, ascending."""

    thrusters: tuple = ()
    wheels: tuple = ()


def _ids(units):
    return ",".join(str(u) for u in sorted(units))


def runs_row(run_id, seed, failed, result, value_columns, n_thrusters, error=None, wheels=False):
    """One row of the ``runs`` table (interface.md) as a dict; ``failed``: a :class:`Failures`
    (or the failed thruster ids alone); ``wheels``: the vehicle has wheels (a ``failed_wheels`` column).

    ``result`` is a ``refexmc.simulate.FlightResult`` (None for an errored run, whose
    ``value_columns``, from ``config.requirements.run_value_columns``, are NaN).
    """
    row = {
        "run_id": run_id,
        "seed": seed,
        "status": "error" if error else "ok",
        "success": False,
        "failure_reason": error,
    }
    if not isinstance(failed, Failures):
        failed = Failures(tuple(failed))
    row["failed_thrusters"] = _ids(failed.thrusters)
    if wheels:
        row["failed_wheels"] = _ids(failed.wheels)
    if result is None:
        for name in value_columns:
            row[name] = float("nan")
        row["modes_completed"] = 0
        for i in range(n_thrusters):
            row[f"pulses_{i + 1}"] = 0
        return row
    row["success"] = result.success
    row["failure_reason"] = result.failure_reason
    row.update(result.runs_values())
    return row


STRING_COLUMNS = ("status", "failure_reason", "failed_thrusters", "failed_wheels")

# Arrays are built from numpy buffers (pa.Array.from_buffers), not by pa.array: pyarrow 26 imports
# pandas on the first pa.array call, ~0.35 s of every worker's start-up, and a worker has no use for it.


def numpy_column(values):
    """The Arrow array of a 1-D numpy array, without nulls (NaN is a value, as pa.array keeps it).

    No copy of a contiguous array (but bool, which Arrow stores as bits): the array shares its memory.
    """
    values = np.ascontiguousarray(values)
    data = np.packbits(values, bitorder="little") if values.dtype == np.bool_ else values
    return pa.Array.from_buffers(_arrow_type(values.dtype), len(values), [None, pa.py_buffer(data)], null_count=0)


@functools.cache
def _arrow_type(dtype):
    return pa.from_numpy_dtype(dtype)


def string_column(values):
    """The Arrow string array of Python strings, None a null."""
    encoded = [b"" if value is None else value.encode() for value in values]
    offsets = np.array([0, *itertools.accumulate(map(len, encoded))], dtype=np.int32)
    nulls = sum(value is None for value in values)
    validity = pa.py_buffer(np.packbits([value is not None for value in values], bitorder="little")) if nulls else None
    buffers = [validity, pa.py_buffer(offsets), pa.py_buffer(b"".join(encoded))]
    return pa.Array.from_buffers(pa.string(), len(values), buffers, null_count=nulls)


# the numpy dtype of a column whose values are all of one Python type: the Arrow type pa.array infers
_NUMPY_DTYPES = {float: np.float64, int: np.int64, bool: np.bool_}


def python_column(values):
    """The Arrow array of Python values, of the type pa.array infers: a column of floats, of ints or of
    bools from numpy (ints beyond int64 raise); any other column (a mix of types, None) by pa.array."""
    kinds = {type(value) for value in values}
    dtype = _NUMPY_DTYPES.get(kinds.pop()) if len(kinds) == 1 else None
    return numpy_column(np.array(values, dtype=dtype)) if dtype else pa.array(values)


def runs_table(rows):
    """The ``runs`` table of ``rows`` (dicts with the same keys, in column order)."""

    def column(name):
        values = [row[name] for row in rows]
        # fixed types where a chunk's values may all be null, so that every part has one schema
        if name in ("run_id", "seed"):
            return numpy_column(np.array(values, dtype=np.int64))
        if name in STRING_COLUMNS:
            return string_column(values)
        return python_column(values)

    return pa.table({name: column(name) for name in rows[0]})


def history_table(run_id, result):
    """Long history table of one run (interface.md ``histories`` columns) from its
    ``refexmc.simulate.FlightResult``; ``mode`` is a dictionary column of the mission's mode names."""
    signals = result.history_columns()
    return _history_arrow(np.full(len(signals["t_s"]), run_id, dtype=np.int64), signals, result.mode_names)


def histories_table(run_ids, results):
    """The :func:`history_table` of several runs of one mission, one run after the other.

    Building a chunk's histories at once pays Arrow's per-column cost once, not once per run:
    flown a chunk at a time, history and encoding cost 0.27 ms per run against 0.64 run by run;
    a FlightResult's raw rows are joined first and converted to the output columns once
    (``FlightResult.joined``; the same values: each conversion is per element).
    """
    joined = getattr(type(results[0]), "joined", None)
    if joined is not None:  # the runs' raw rows one after the other, converted at once
        together, lengths = joined(results)
        signals = together.history_columns()
    else:  # an entry run's (campaign.entry_plan.EntryRun)
        runs = [result.history_columns() for result in results]
        signals = {name: np.concatenate([run[name] for run in runs]) for name in runs[0]}
        lengths = [len(run["t_s"]) for run in runs]
    ids = np.repeat(np.asarray(run_ids, dtype=np.int64), lengths)
    return _history_arrow(ids, signals, results[0].mode_names)


def _history_arrow(run_ids, signals, mode_names):
    """The history table of a run_id column, the signals (``FlightResult.history_columns``) and mode names."""
    columns = {"run_id": numpy_column(run_ids)}
    for name, values in signals.items():
        columns[name] = numpy_column(values)
    columns["mode"] = pa.DictionaryArray.from_arrays(columns["mode"], string_column(mode_names))
    return pa.table(columns)


def empty_history_table():
    """A history table with no rows (the histories part of a chunk whose runs all errored)."""
    from refexmc.simulate import empty_result  # the core's kernels: only when a chunk has no history

    return history_table(0, empty_result([], 0))


# libyaml when PyYAML has it (the same documents, ~8x faster than the pure-Python emitter and parser)
_YAML_DUMPER = getattr(yaml, "CSafeDumper", yaml.SafeDumper)
_YAML_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


def resolved_yaml(campaign):
    """The resolved campaign as YAML text (``campaign.resolved.yaml`` without its comment line)."""
    return yaml.dump(campaign, Dumper=_YAML_DUMPER, sort_keys=False)


def normalized_campaign(campaign):
    """The resolved campaign as plain YAML data: what ``campaign.resolved.yaml`` reads back as."""
    return yaml.load(resolved_yaml(campaign), Loader=_YAML_LOADER)


def campaign_digest(campaign):
    """sha256 of the resolved campaign (runs and seed included): the identity of a campaign's results."""
    text = json.dumps(normalized_campaign(campaign), sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()


@functools.cache
def flight_code():
    """The flight code of runs flown now (:func:`refexmc.flight_code_digest`, with numba's version
    not imported: the writing process never flies; the same digest names the kernel cache). Any change there may move a
    run's last bits (issue 37 moved every flight's), so ``--resume`` refuses an output whose
    manifest names other flight code (campaign.run.check_resumable): its runs and the ones flown
    now would not be one campaign's bits."""
    return refexmc.flight_code_digest(metadata.version("numba"))


def manifest(campaign_file, campaign, chunk_size, status, started, finished=None, counts=None, **extra):
    """manifest.json content; ``extra`` (execution details: jobs, backend, ...) is added as is."""
    data = Path(campaign_file).read_bytes() if campaign_file else b""
    return {
        "refexmc": refexmc.__version__,
        "python": platform.python_version(),
        "numpy": np.__version__,
        "numba": metadata.version("numba"),  # not imported: the writing process never flies
        "flight_code": flight_code(),
        "pyarrow": pa.__version__,
        "campaign_file": str(campaign_file) if campaign_file else None,
        "campaign_sha256": hashlib.sha256(data).hexdigest(),
        "resolved_sha256": campaign_digest(campaign),
        "name": campaign["name"],
        "seed": campaign["seed"],
        "runs": campaign["runs"],
        "chunk_size": chunk_size,
        "status": status,
        "started": started,
        "finished": finished,
        "counts": counts or {},
        **output_names(campaign),
        **extra,
    }


def output_names(campaign):
    """The names the outputs take from the campaign's files: ``modes`` (display names in flight
    order, the history's ``mode`` values) and ``columns`` (the runs table's numeric columns)."""
    from refexmc.config import derived, dispersions, pointing, requirements  # config: what the files declare

    vehicle, mission = campaign["vehicle"], campaign["mission"]
    parameters = [c for key in campaign["dispersions"] for c in dispersions.columns(key, vehicle)]
    if "entry_flight" in mission:  # an entry campaign (campaign.entry_plan, issue 24)
        from refexmc.config.entry import MODE_NAMES

        return {"modes": list(MODE_NAMES), "columns": {"runs": requirements.entry_metric_columns(parameters)}}
    modes = [mode["name"] for mode in mission["modes"]]
    options = requirements.column_options(vehicle, mission)
    columns = requirements.runs_metric_columns(modes, derived.thruster_count(vehicle), parameters, **options)
    columns += [req.column for req in pointing.of_campaign(campaign)]  # pointing requirements' columns
    return {"modes": modes, "columns": {"runs": columns}}


def read_manifest(out):
    """manifest.json, its column names as now named (config.renames: written before a rename)."""
    return renames.manifest(json.loads((Path(out) / "manifest.json").read_text()))


def read_runs_part(path, **options):
    """One runs part file (``pq.read_table`` ``options``), with the columns and failure reasons of
    now: an output written before a rename (config.renames, issue 34) reads as if written after it.
    Every reader of a runs table goes through here. A file without options is read by
    ``ParquetFile`` (``read_table`` imports pyarrow.dataset, ~0.4 s)."""
    path = Path(path)
    table = pq.ParquetFile(path).read() if path.is_file() and not options else pq.read_table(path, **options)
    return renames.runs_table(table)


def read_runs_parts(paths, **options):
    """The runs parts ``paths`` joined (:func:`read_runs_part` each: parts of before and after a
    rename, as a resumed output holds, have the same columns)."""
    tables = [read_runs_part(path, **options) for path in paths]
    return pa.concat_tables(tables, promote_options="default") if tables else None


def write_manifest(out, info):
    write_text_atomic(json.dumps(info, indent=2) + "\n", Path(out) / "manifest.json")


def write_resolved(out, campaign):
    text = "# Resolved campaign: vehicle and mission inlined; enough to redo any run.\n"
    text += resolved_yaml(campaign)
    write_text_atomic(text, Path(out) / "campaign.resolved.yaml")


WORK_DIR = ".refexmc-work"  # private to a running campaign: worker state files
LOCK_NAME = ".refexmc.lock"  # the lock of the process writing OUT (refexmc.campaign.lock)
REPORT_DIR = "report"  # written by `refexmc report`
# what refexmc writes at the top of an output directory, besides the temporary files of atomic writes
OUTPUT_ENTRIES = frozenset(
    {"manifest.json", "campaign.resolved.yaml", "runs", "histories", REPORT_DIR, "reruns", WORK_DIR, LOCK_NAME}
    | {"points"}  # a sweep's points (refexmc.campaign.sweep)
)
_TEMPORARY = re.compile(r"\..+\.tmp-\d+")


def is_empty(out):
    """True when OUT holds nothing but a lock file (a missing OUT is empty too)."""
    out = Path(out)
    return not out.exists() or all(path.name == LOCK_NAME for path in out.iterdir())


def is_output(out):
    """True when OUT holds a refexmc ``manifest.json``."""
    try:
        info = read_manifest(out)
    except (OSError, ValueError):
        return False
    return isinstance(info, dict) and {"refexmc", "resolved_sha256", "chunk_size"} <= info.keys()


# what refexmc writes in OUT's folders (paths relative to the folder); anything else there is the user's
_PART = re.compile(r"part-\d{5,}\.parquet")
WRITTEN_IN = {
    "runs": _PART,
    "histories": _PART,
    "reruns": re.compile(r"run-\d+\.parquet"),  # refexmc rerun
    REPORT_DIR: re.compile(r"index\.html|summary\.json|sweep\.png|figures|figures/[\w.-]+\.png"),  # refexmc report
}
_POINT = re.compile(r"\d{3,}")  # a sweep's points/NNN (an OUT of its own) and points/NNN.yaml


def _written(folder, relative):
    pattern = WRITTEN_IN.get(folder)
    name = relative.rsplit("/", 1)[-1]
    return pattern is None or pattern.fullmatch(relative) is not None or _TEMPORARY.fullmatch(name) is not None


def foreign_entries(out):
    """Paths in OUT (relative, '/'-separated) that refexmc does not write: at the top, and in the
    folders of :data:`WRITTEN_IN` and a sweep's points at any depth (a user's notebook in report/)."""
    out = Path(out)
    foreign = []
    for path in sorted(out.iterdir()):
        name = path.name
        if name not in OUTPUT_ENTRIES and not _TEMPORARY.fullmatch(name):
            foreign.append(name)
        elif name == "points" and path.is_dir() and not path.is_symlink():
            for point in sorted(path.iterdir()):
                stem = point.name.removesuffix(".yaml")
                if not _POINT.fullmatch(stem) or (point.is_dir() != (stem == point.name)):
                    foreign.append(f"points/{point.name}")
                elif point.is_dir():
                    foreign += [f"points/{point.name}/{entry}" for entry in foreign_entries(point)]
        elif name in WRITTEN_IN and path.is_dir() and not path.is_symlink():
            for folder, folders, files in os.walk(path):
                for entry in sorted(folders + files):
                    relative = (Path(folder) / entry).relative_to(path).as_posix()
                    if not _written(name, relative):
                        foreign.append(f"{name}/{relative}")
                folders[:] = [
                    f for f in folders if f"{name}/{Path(folder, f).relative_to(path).as_posix()}" not in foreign
                ]
    return sorted(foreign)


def _within(path, folder):
    path = Path(path).resolve()
    return path == folder or folder in path.parents


def check_output(out, overwrite=False, resume=False, protect=()):
    """Refuse (ConfigError) an OUT that this run must not write; writes nothing.

    A missing or empty OUT is always fine. An existing output needs ``resume`` (kept) or
    ``overwrite`` (replaced), and ``overwrite`` replaces only a directory that holds a refexmc
    manifest and nothing refexmc does not write, that is neither the current directory nor
    contains it, nor contains any of the ``protect`` files (the campaign file).
    """
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise ConfigError("expected a directory for the output, got a file", file=out)
    if is_empty(out):
        return
    if not resume and not overwrite:
        raise ConfigError("output directory exists; use --resume to finish it or --overwrite to replace it", file=out)
    if not overwrite:
        return
    folder = out.resolve()
    if _within(Path.cwd(), folder):
        raise ConfigError("--overwrite would delete the current directory's files; choose another -o", file=out)
    kept = [str(path) for path in protect if path is not None and _within(path, folder)]
    if kept:
        raise ConfigError(f"--overwrite would delete {', '.join(kept)}; choose another -o", file=out)
    if not is_output(out):
        raise ConfigError(
            "--overwrite replaces only a refexmc output directory (with a manifest.json) or an empty one; "
            "this is neither, nothing was touched",
            file=out,
        )
    foreign = foreign_entries(out)
    if foreign:
        raise ConfigError(
            f"--overwrite would delete files refexmc did not write: {', '.join(foreign)}; "
            "move them or choose another -o (nothing was touched)",
            file=out,
        )


def prepare_output(out, overwrite=False, resume=False, protect=()):
    """Create OUT, checked with :func:`check_output`: emptied with ``overwrite`` (but its lock), kept with ``resume``.

    The temporary files a killed campaign left behind are removed.
    """
    out = Path(out)
    check_output(out, overwrite=overwrite, resume=resume, protect=protect)
    if overwrite and out.exists():
        for path in out.iterdir():
            if path.name == LOCK_NAME:
                continue
            if path.is_dir() and not path.is_symlink():
                shutil.rmtree(path)
            else:
                path.unlink()
    if out.exists():
        remove_temporary_files(out)
    (out / "runs").mkdir(parents=True, exist_ok=True)
    (out / "histories").mkdir(exist_ok=True)


def remove_report(out):
    """Delete what ``refexmc report`` wrote in OUT/report/: it describes contents that are about to
    change. Anything else there (a user's own analysis) is kept, and so is the folder then."""
    report = Path(out) / REPORT_DIR
    if not report.is_dir() or report.is_symlink():
        return
    written = [path for path in report.rglob("*") if _written(REPORT_DIR, path.relative_to(report).as_posix())]
    for path in sorted(written, key=lambda path: len(path.parts), reverse=True):  # files before their folder
        if path.is_dir() and not path.is_symlink():
            with suppress(OSError):  # a user's file inside it: kept
                path.rmdir()
        else:
            path.unlink()
    with suppress(OSError):
        report.rmdir()


def remove_temporary_files(out):
    """Delete the ``.<name>.tmp-<pid>`` files of interrupted atomic writes in OUT, runs/ and histories/."""
    out = Path(out)
    for folder in (out, out / "runs", out / "histories"):
        for path in folder.glob(".*.tmp-*") if folder.is_dir() else ():
            path.unlink()


def part_problem(out, chunk, run_ids):
    """Why chunk ``chunk``'s two parts in OUT are not a complete record of ``run_ids``; None when they are.

    The runs part must be readable Parquet holding exactly those runs; the histories part readable
    Parquet holding no other runs (a run that errored has no history).
    """
    name = part_name(chunk)
    runs, histories = Path(out) / "runs" / name, Path(out) / "histories" / name
    if not runs.is_file() or not histories.is_file():
        return "missing"
    expected = list(run_ids)
    try:
        stored = sorted(pq.read_table(runs).column("run_id").to_pylist())
        if stored != expected:
            return f"runs/{name} holds runs {_span(stored)}, expected {_span(expected)}"
        history_ids = set(pq.read_table(histories, columns=["run_id"]).column("run_id").to_pylist())
        if not history_ids <= set(expected):
            return f"histories/{name} holds runs of another chunk"
    except (OSError, KeyError, pa.ArrowException) as exc:
        return f"unreadable: {exc}"
    return None


def _span(ids):
    return f"{ids[0]}..{ids[-1]} ({len(ids)})" if ids else "none"
