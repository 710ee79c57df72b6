"""The Parquet tables of refexmc.campaign.storage: built from numpy buffers, they hold what pa.array
would have made of the same values (schema, nulls, and every float's bits), whatever a chunk holds."""

import math
import os
import pickle
import subprocess
import sys
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from refexmc.campaign import storage
from refexmc.campaign.chunk import RunPlan, fly_chunk
from refexmc.config.load import apply_overrides, load_campaign
from refexmc.simulate import empty_result

ROOT = Path(__file__).resolve().parents[1]
NAN = float("nan")


def assert_same_array(built, expected):
    """Same type, nulls and values; floats compared by their bits (NaN == NaN, -0.0 != 0.0)."""
    assert built.type == expected.type
    assert built.null_count == expected.null_count
    assert built.is_null().to_pylist() == expected.is_null().to_pylist()
    if pa.types.is_floating(expected.type):
        width = expected.type.bit_width
        bits = [np.asarray(a.fill_null(0)).view(f"u{width // 8}") for a in (built, expected)]
        assert bits[0].tolist() == bits[1].tolist()
    else:
        assert built.to_pylist() == expected.to_pylist()


def assert_same_table(built, expected):
    assert built.schema.equals(expected.schema)
    for name in expected.column_names:
        assert_same_array(built[name].combine_chunks(), expected[name].combine_chunks())


@pytest.mark.parametrize(
    "values",
    [
        np.array([1.5, NAN, -0.0, math.inf, -1e300]),
        np.array([1.5, NAN, -0.0], dtype=np.float32),
        np.array([-128, 0, 127], dtype=np.int8),
        np.array([7, -3, 2**31 - 1], dtype=np.int32),
        np.array([2**62, -1], dtype=np.int64),
        np.array([True, False, True, True, False, False, True, False, True]),  # more than a byte of bits
        np.zeros(0, dtype=np.float32),
        np.zeros(0, dtype=np.bool_),
        np.arange(12.0)[::3],  # not contiguous
    ],
)
def test_numpy_column_is_pa_array(values):
    assert_same_array(storage.numpy_column(values), pa.array(values))


def test_numpy_column_shares_the_memory_of_a_contiguous_array():
    values = np.arange(5, dtype=np.float32)
    assert storage.numpy_column(values).buffers()[1].address == values.ctypes.data


@pytest.mark.parametrize(
    "values", [["ok", "error", ""], ["timeout (ncm)", None, "1,5"], [None, None], [], ["Größe", "θ"], [None]]
)
def test_string_column_is_pa_array(values):
    assert_same_array(storage.string_column(values), pa.array(values, type=pa.string()))


@pytest.mark.parametrize(
    "values",
    [
        [1.5, NAN, -0.0, 2.0],
        [3, 0, -7],
        [True, False, True],
        [1, 2.5],  # a mix: pa.array decides
        [1.0, None],
        [],
    ],
)
def test_python_column_is_pa_array(values):
    assert_same_array(storage.python_column(values), pa.array(values))


def reference_history_table(run_id, result):
    """The history table as pa.array builds it (the construction before numpy buffers)."""
    signals = result.history_columns()
    columns = {"run_id": pa.array(np.full(len(signals["t_s"]), run_id, dtype=np.int64))}
    for name, values in signals.items():
        columns[name] = pa.array(values)
    names = pa.array(result.mode_names, type=pa.string())
    columns["mode"] = pa.DictionaryArray.from_arrays(columns["mode"], names)
    return pa.table(columns)


def reference_runs_table(rows):
    def column(name):
        values = [row[name] for row in rows]
        if name in ("run_id", "seed"):
            return pa.array(values, type=pa.int64())
        if name in storage.STRING_COLUMNS:
            return pa.array(values, type=pa.string())
        return pa.array(values)

    return pa.table({name: column(name) for name in rows[0]})


@pytest.fixture(scope="module")
def smoke_campaign():
    return apply_overrides(load_campaign(ROOT / "campaigns/smoke.yaml"), runs=3)


@pytest.fixture(scope="module")
def smoke_flights(smoke_campaign):
    """(run id, FlightResult) of three smoke runs."""
    plan = RunPlan(smoke_campaign)
    rate = smoke_campaign["output"]["history_rate_hz"]
    return [(run_id, plan.fly(run_id, rate)[2]) for run_id in range(3)]


@pytest.fixture(scope="module")
def smoke_chunk(smoke_campaign):
    """(rows, history table) of three smoke runs, and the row of a fourth that errored."""
    rows, history = fly_chunk(smoke_campaign, range(3))
    error = RunPlan(smoke_campaign).error_row(3, "RuntimeError: boom")
    return [*rows, error], history


def test_history_table_is_the_pa_array_table(smoke_flights):
    for run_id, result in smoke_flights:
        assert_same_table(storage.history_table(run_id, result), reference_history_table(run_id, result))


def test_empty_history_table_is_the_pa_array_table():
    result = empty_result(["NCM", "SAM"], 4)
    assert storage.history_table(5, result).num_rows == 0
    assert_same_table(storage.history_table(5, result), reference_history_table(5, result))


def test_histories_table_is_the_run_tables_one_after_the_other(smoke_flights):
    run_ids, results = zip(*smoke_flights, strict=True)
    assert len({len(result.history) for result in results}) > 1  # runs of different lengths
    each = pa.concat_tables([storage.history_table(run_id, result) for run_id, result in smoke_flights])
    assert_same_table(storage.histories_table(run_ids, results), each)
    empty = empty_result(results[0].mode_names, 4)
    assert_same_table(storage.histories_table([9, 2], [empty, results[2]]), storage.history_table(2, results[2]))


def test_runs_table_is_the_pa_array_table(smoke_chunk):
    rows, _ = smoke_chunk
    assert any(math.isnan(value) for value in rows[-1].values() if isinstance(value, float))
    assert_same_table(storage.runs_table(rows), reference_runs_table(rows))
    assert_same_table(storage.runs_table(rows[-1:]), reference_runs_table(rows[-1:]))


def test_the_empty_history_table_has_the_schema_of_a_flown_one(smoke_chunk):
    _, history = smoke_chunk
    assert storage.empty_history_table().schema.equals(history.schema)


def test_a_histories_folder_read_whole_keeps_its_modes_when_the_first_part_is_empty(smoke_chunk, tmp_path):
    """A chunk whose runs all errored writes an empty histories part; it must not hide the mode names."""
    _, history = smoke_chunk
    storage.write_table_atomic(storage.empty_history_table(), tmp_path / storage.part_name(0))
    storage.write_table_atomic(history, tmp_path / storage.part_name(1))
    table = pq.read_table(tmp_path)
    assert table.column("mode").to_pylist() == history.column("mode").to_pylist()


def test_encoded_parts_read_back_as_they_were(smoke_chunk):
    rows, history = smoke_chunk
    for table in (storage.runs_table(rows), history):
        assert_same_table(storage.decode_table(storage.encode_table(table)), table)


def test_floats_are_stored_byte_stream_split_and_the_other_columns_as_dictionaries(smoke_chunk):
    rows, history = smoke_chunk
    for table in (storage.runs_table(rows), history):
        metadata = pq.read_metadata(pa.BufferReader(storage.encode_table(table)))
        for k, field in enumerate(table.schema):
            column = metadata.row_group(0).column(k)
            floating = pa.types.is_floating(field.type)
            if not pa.types.is_boolean(field.type):  # Parquet has no dictionaries of booleans
                assert column.has_dictionary_page != floating, field.name
            assert ("BYTE_STREAM_SPLIT" in column.encodings) == floating, (field.name, column.encodings)


@pytest.mark.parametrize("dtype, unsigned", [(np.float64, np.uint64), (np.float32, np.uint32)])
def test_stored_floats_keep_every_bit(dtype, unsigned):
    """Byte-stream split is lossless: NaNs with payloads, -0.0, infinities, subnormals, extremes."""
    info = np.finfo(dtype)
    special = np.array([0.0, -0.0, np.inf, -np.inf, info.tiny, info.smallest_subnormal, info.max, -info.eps], dtype)
    payload_nans = (
        (
            np.array([0x7FF8000000000001, 0xFFF0000000000F0F])
            if dtype == np.float64
            else np.array([0x7FC00001, 0xFF800F0F])
        )
        .astype(unsigned)
        .view(dtype)
    )
    values = np.concatenate([special, payload_nans, np.random.default_rng(5).standard_normal(1000).astype(dtype)])
    table = pa.table({"run_id": np.arange(len(values)), "x": values})
    back = storage.decode_table(storage.encode_table(table)).column("x").to_numpy()
    assert back.dtype == dtype
    assert np.array_equal(back.view(unsigned), values.view(unsigned))


def test_a_worker_imports_neither_pandas_nor_the_validator(tmp_path):
    """What a worker does with its campaign (it comes pickled, validated): warm up, then fly and
    encode a chunk, without importing pandas (pyarrow imports it on its first pa.array call) or
    jsonschema: ~0.35 and ~0.1 s of each worker's start-up."""
    campaign = tmp_path / "campaign.pickle"
    campaign.write_bytes(pickle.dumps(apply_overrides(load_campaign(ROOT / "campaigns/smoke.yaml"), runs=2)))
    script = (
        "import pickle, sys\n"
        "from refexmc.campaign.worker import Guard, fly_guarded, warm_up\n"
        "warm_up()\n"
        f"campaign = pickle.loads(open({str(campaign)!r}, 'rb').read())\n"
        "flown = fly_guarded(campaign, [0, 1], Guard(None, 60.0))\n"
        "assert flown.runs and flown.history\n"
        "print(sorted(name for name in ('pandas', 'jsonschema') if name in sys.modules))\n"
    )
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    done = subprocess.run(
        [sys.executable, "-c", script], cwd=ROOT, env=env, capture_output=True, text=True, timeout=300
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "[]"


def test_an_exception_in_the_middle_of_a_write_leaves_no_temporary_file(tmp_path):
    """A signal stops a campaign by raising in the parent (run.CampaignInterrupted), possibly while
    it writes a part: neither the part nor its temporary file may stay (seen once in CI after SIGINT)."""

    class Interrupted(BaseException):  # not an Exception, as KeyboardInterrupt
        pass

    def write(tmp):
        tmp.write_bytes(b"half a part")
        raise Interrupted

    target = tmp_path / "runs" / "part-00002.parquet"
    with pytest.raises(Interrupted):
        storage._write_atomic(target, write)
    assert list(tmp_path.rglob("*")) == [tmp_path / "runs"]
