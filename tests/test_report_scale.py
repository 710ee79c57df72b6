"""The report's reading and binning at scale (issue 25): the fast paths count what the obvious ones count."""

import bisect
import importlib.util
import json
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from test_report import synthetic_runs, write_out

from refexmc.campaign import storage
from refexmc.config import renames
from refexmc.config.errors import ConfigError
from refexmc.report import aggregate, data, factors, make_report, stats

ROOT = Path(__file__).resolve().parents[1]


def naive_counts(groups, time_bins, dt, edges, group, tau, values):
    """[group, time bin, value bin] sample counts, one sample at a time (bisect for the value bin)."""
    counts = np.zeros((groups, time_bins, len(edges) + 1), dtype=np.int64)
    for g, s, v in zip(group.tolist(), tau.tolist(), values.tolist(), strict=True):
        if not (np.isfinite(v) and np.isfinite(s) and 0 <= g < groups):
            continue
        counts[g, min(int(max(s, 0.0) / dt), time_bins - 1), bisect.bisect_right(edges.tolist(), v)] += 1
    return counts


def awkward_values(edges, rng, n=3000, dtype=np.float64):
    """Values on and beside every edge, below and above the range, 0, negatives, NaN, inf and random ones."""
    edges = edges.astype(dtype).astype(float)  # the float32 values nearest the edges, as a history stores them
    beside = np.concatenate([edges, np.nextafter(edges, -np.inf), np.nextafter(edges, np.inf)])
    extremes = [0.0, -1.0, -edges[-1], edges[0] / 7, edges[-1] * 3, np.nan, np.inf, -np.inf]
    low = edges[0] / 10 if edges[0] > 0 else 1e-9
    spread = np.exp(rng.uniform(np.log(low), np.log(edges[-1] * 10), n))
    return np.concatenate([beside, extremes, spread, rng.uniform(edges[0], edges[-1], n)]).astype(dtype)


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@pytest.mark.parametrize(
    "edges, log",
    [
        (aggregate.log_edges(1e-3, 1e3), True),
        (aggregate.log_edges(1e-7, 1e1), True),
        (np.linspace(0.0, 1.0, 1001), False),
        (np.array([0.5]), False),
        (np.concatenate([-aggregate.log_edges(1e-3, 1e1)[::-1], [0.0], aggregate.log_edges(1e-3, 1e1)]), False),
        (np.array([0.0, 0.1, 0.15, 2.0, 2.5]), True),  # not evenly spaced: the binary search
    ],
)
def test_value_bin_is_the_searchsorted_bin_for_every_value(edges, log, dtype):
    binned = aggregate.BinnedQuantiles(1, 1, 1.0, edges, log=log)
    values = awkward_values(edges, np.random.default_rng(3), dtype=dtype)
    values = values[np.isfinite(values)]  # add_cells leaves the others out before binning
    expected = np.searchsorted(edges, values, side="right")  # numpy compares float32 values as float64
    assert (binned.value_bin(values) == expected).all()


def test_counts_flushed_in_pieces_equal_the_sample_by_sample_histogram():
    rng = np.random.default_rng(7)
    edges = aggregate.log_edges(1e-2, 1e2)
    binned = aggregate.BinnedQuantiles(3, 40, 0.5, edges, log=True)
    binned._flush_samples = 500  # counted every ~500 samples: batches meet flushes at all points, the last at the end
    groups, taus, values = [], [], []
    for size in (0, 1, 17, 900, 4000, 333):
        group = rng.integers(-1, 4, size)  # -1 and 3: out of range, left out
        tau = np.where(rng.random(size) < 0.05, np.nan, rng.uniform(-1.0, 25.0, size))  # < 0: bin 0; > 20 s: last
        value = awkward_values(edges, rng, n=size)[rng.integers(0, 3 * len(edges) + 8 + 2 * size, size)]
        binned.add(group, tau, value)
        groups.append(group), taus.append(tau), values.append(value)
    group, tau, value = (np.concatenate(a) for a in (groups, taus, values))
    expected = naive_counts(3, 40, 0.5, edges, group, tau, value)
    assert expected.sum() > 2500
    assert (binned.counts == expected).all()
    assert (binned.sample_counts() == expected.sum(axis=2)).all()
    binned.add(group, tau, value)  # counting on after a read of the counts
    assert (binned.counts == 2 * expected).all()


def test_run_positions_find_each_run_or_minus_one():
    run_ids = np.array([0, 2, 3, 7, 8], dtype=np.int64)
    rid = np.array([2, 2, 2, 5, 5, 0, 7, 7, 9, 3, 2, 2], dtype=np.int64)  # 5 and 9: errored runs
    expected = [([*run_ids].index(r) if r in run_ids else -1) for r in rid]
    assert aggregate.run_positions(run_ids, rid).tolist() == expected
    assert aggregate.run_positions(run_ids, rid[:0]).tolist() == []


def write_parts(folder, tables):
    folder.mkdir(parents=True)
    for k, table in enumerate(tables):
        storage.write_table_atomic(table, folder / storage.part_name(k))
    return sorted(folder.glob("part-*.parquet"))


def test_runs_parts_read_on_threads_equal_the_parts_read_one_by_one(tmp_path, monkeypatch):
    monkeypatch.setattr(data, "RUNS_PARTS_PER_GROUP", 3)  # 10 parts: four groups, on threads
    rows = synthetic_runs(n=50)
    for row in rows[20:30]:  # a part whose failure_reason is all None next to parts with strings
        row["failure_reason"] = None
    parts = write_parts(tmp_path / "runs", [storage.runs_table(rows[k : k + 5]) for k in range(0, 50, 5)])
    expected = pa.concat_tables([pq.read_table(p) for p in parts], promote_options="default")
    table = data.read_runs_parts(parts)
    assert table.equals(expected)
    assert table.column("run_id").num_chunks == 4  # one contiguous chunk per group
    # load: the rows sorted by run id even when the parts are not in run order
    out = write_out(tmp_path / "out", rows, parts=5)
    for k, name in enumerate(["tmp-a", "tmp-b"]):  # swap parts 0 and 4
        (out / "runs" / storage.part_name(4 * k)).rename(out / "runs" / name)
    (out / "runs" / "tmp-a").rename(out / "runs" / storage.part_name(4))
    (out / "runs" / "tmp-b").rename(out / "runs" / storage.part_name(0))
    runs = data.load(out).runs
    assert runs["run_id"].tolist() == list(range(50))
    frame = pd.DataFrame(rows)
    assert np.array_equal(runs["fuel_remaining"].to_numpy(), frame["fuel_remaining"].to_numpy())


def test_history_batches_read_ahead_yield_the_parts_in_order_and_report_a_bad_part(tmp_path):
    tables = [pa.table({"run_id": np.full(k + 3, k, dtype=np.int64), "t_s": np.arange(k + 3.0)}) for k in range(7)]
    campaign = data.Campaign(tmp_path, pd.DataFrame(), {}, {}, history_parts=write_parts(tmp_path / "h", tables))
    for read_ahead in (0, 1, 2, 5, 9):
        batches = list(data.history_batches(campaign, ["t_s", "run_id"], batch_rows=4, read_ahead=read_ahead))
        joined = pa.Table.from_batches(batches)
        assert joined.column_names == ["t_s", "run_id"]
        assert joined.equals(pa.concat_tables(tables).select(["t_s", "run_id"]))
    # a function of each batch runs on the reading threads; its results come in the batches' order
    sizes = list(data.map_history_batches(campaign, ["run_id"], lambda b: b.num_rows, batch_rows=4, read_ahead=3))
    assert sizes == [size for k in range(7) for size in ([4] * ((k + 3) // 4) + [(k + 3) % 4] * ((k + 3) % 4 > 0))]
    with pytest.raises(ConfigError, match="histories part lacks columns mode") as error:
        list(data.history_batches(campaign, ["run_id", "mode"], read_ahead=2))
    assert "part-00000" in str(error.value)


def load_make_big_out():
    spec = importlib.util.spec_from_file_location("make_big_out", ROOT / "benchmarks" / "make_big_out.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_a_campaign_repeated_three_times_reports_the_same_envelopes(tmp_path):
    """make_big_out (the 100,000-run benchmark OUT): a complete output of 3n runs whose history
    envelopes equal the original's bin for bin: the sample of rank ceil(3 p n) among three copies
    is the one of rank ceil(p n) in one."""
    rows = synthetic_runs(n=40, errored=(7,), failed=())
    src = write_out(tmp_path / "src", rows, parts=4)
    manifest = storage.read_manifest(src)
    manifest.update(runs=40, chunk_size=10, counts={"runs": 40, "ok": 39})
    storage.write_manifest(src, manifest)
    tool = load_make_big_out()
    runs, parts, _ = tool.make_big_out(src, tmp_path / "big", 3)
    assert (runs, parts) == (120, 12)
    big = data.load(tmp_path / "big")
    assert big.runs["run_id"].tolist() == list(range(120))
    assert data.completeness(big)["complete"]
    info = json.loads((tmp_path / "big" / "manifest.json").read_text())
    assert info["counts"] == {"runs": 120, "ok": 117} and info["repeated_from"]["times"] == 3
    one, three = aggregate.aggregate_histories(data.load(src)), aggregate.aggregate_histories(big)
    for quantity in ("theta_t_deg", "omega_m_deg_s"):
        assert (three["modes"][quantity][0].counts == 3 * one["modes"][quantity][0].counts).all()
        assert np.array_equal(three["modes"][quantity][1], one["modes"][quantity][1], equal_nan=True)
    assert np.array_equal(three["propellant"][1], one["propellant"][1], equal_nan=True)
    assert three["rows"] == 3 * one["rows"]
    assert make_report(tmp_path / "big", html=False)["summary"]["counts"]["runs"] == 120
    # --no-histories: the runs table alone, still complete (no histories part is expected then)
    tool.make_big_out(src, tmp_path / "runs_only", 2, histories=False)
    runs_only = data.load(tmp_path / "runs_only")
    assert len(runs_only.runs) == 80 and not runs_only.history_parts and data.completeness(runs_only)["complete"]
    with pytest.raises(SystemExit, match="exists"):
        tool.make_big_out(src, tmp_path / "runs_only", 2)
    with pytest.raises(SystemExit, match="not a multiple"):
        manifest.update(chunk_size=7)
        storage.write_manifest(src, manifest)
        tool.make_big_out(src, tmp_path / "other", 2)


def test_runs_parts_of_old_and_new_names_join_in_todays_names(tmp_path, monkeypatch):
    """Parts written before and after the issue-34 renames (an OUT resumed across versions), and one
    without a column, join in today's names and reasons whatever the grouping, as read one by one."""
    rows = synthetic_runs(n=40, failed=(3, 11, 27))
    for row in rows[3:4] + rows[27:28]:
        row["failure_reason"] = "attitude_error_end_above_max"
    tables = [storage.runs_table(rows[k : k + 10]) for k in range(0, 40, 10)]
    old_names = {new: old for old, new in renames.COLUMNS.items()}
    tables[0] = tables[0].rename_columns([old_names.get(c, c) for c in tables[0].column_names])
    old_reasons = {new: old for old, new in renames.FAILURE_REASONS.items()}
    reasons = [old_reasons.get(v, v) for v in tables[2].column("failure_reason").to_pylist()]
    tables[2] = tables[2].set_column(4, "failure_reason", pa.array(reasons, pa.string()))
    tables[3] = tables[3].drop_columns(["p.rcs.isp_s"])
    parts = write_parts(tmp_path / "runs", tables)
    assert pq.read_schema(parts[0]).names != pq.read_schema(parts[1]).names
    expected = pa.concat_tables([storage.read_runs_part(p) for p in parts], promote_options="default")
    for per_group in (1, 2, 3, 64):
        monkeypatch.setattr(data, "RUNS_PARTS_PER_GROUP", per_group)
        table = data.read_runs_parts(parts)
        assert table.equals(expected)
    assert "attitude_error_end_deg" in table.column_names and "theta_t_handover_deg" not in table.column_names
    assert table.column("failure_reason").to_pylist().count("attitude_error_end_above_max") == 2
    assert table.column("p.rcs.isp_s").null_count == 10


def test_rank_gram_is_the_exact_integer_gram_at_a_million_runs_on_any_split(monkeypatch):
    """At 10^6 runs a block's sum of rank products passes 2^53: the Gram matrix is summed as
    integers, so it is the exact one (int64 products of the ranks, numpy's integer matmul, no
    floats) rounded once, however the rows are split over threads."""
    n = 1_000_000
    rng = np.random.default_rng(7)
    ranks = np.column_stack([stats.doubled_centred_ranks(rng.permutation(n)) for _ in range(2)])
    ranks[:, 1] = np.where(ranks[:, 0] > 0, ranks[:, 0], ranks[:, 1])  # correlated: large off-diagonal sums
    output = stats.doubled_centred_ranks(ranks[:, 0] + rng.normal(0.0, n / 10, n))
    both = np.column_stack([ranks, output]).astype(np.int64)
    exact = both.T @ both  # |sums| < n^3 < 2^63
    assert exact[0, 0] == n * (n * n - 1) // 3 > 2**53  # sum of (2i - n - 1)^2: above float64's integers
    gram = stats.rank_gram(ranks, output)
    assert np.array_equal(gram, exact.astype(float))
    monkeypatch.setattr(stats, "GRAM_THREAD_ROWS", 99_991)  # 11 uneven tasks
    assert np.array_equal(stats.rank_gram(ranks, output), gram)
    # beyond ~2 million runs the blocks add up as Python integers: the same sums, no int64 to overflow
    rows = stats._gram_rows(ranks, output, 0, 50_000, 4093, dtype=object)
    assert all(type(v) is int for v in rows.ravel())
    assert np.array_equal(rows.astype(np.int64), both[:50_000].T @ both[:50_000])


def test_missing_and_repeated_run_ids_are_those_of_setdiff1d_and_unique():
    rng = np.random.default_rng(5)
    for planned, ids in [
        (0, np.array([], dtype=np.int64)),
        (5, np.arange(5, dtype=np.int64)),
        (10, np.array([0, 1, 1, 4, 4, 4, 9], dtype=np.int64)),
        (50, rng.integers(-5, 60, 80)),  # unsorted, repeated, negative and beyond the plan
        (1000, np.sort(rng.integers(0, 1000, 900))),
    ]:
        expected = np.setdiff1d(np.arange(planned, dtype=np.int64), ids)
        assert data.missing_run_ids(planned, ids).tolist() == expected.tolist()
        assert data.duplicate_count(ids) == len(ids) - len(np.unique(ids))


def test_failure_factors_parsed_per_distinct_text_equal_those_parsed_per_run():
    """``factors`` parses each distinct failed-units text once: the indicators and the set labels
    are those of parsing every run's text (the obvious loop, written here)."""
    texts = np.array(["", "3", "1,3", None, "3,1", "", "12", "3", None, "1,3"] * 7, dtype=object)
    runs = pd.DataFrame({"run_id": np.arange(len(texts)), "failed_thrusters": texts})
    campaign = data.Campaign(Path("."), runs, {"failures": {"detected": True}}, {})
    sets = [[int(u) for u in str(t or "").split(",") if u.strip()] for t in texts]
    expected = [
        (f"thruster {u} failed (detected)", "failure", np.array([u in s for s in sets], dtype=np.int8))
        for u in (1, 3, 12)
    ]
    expected.append(("failed thruster set (detected)", "failure set", [",".join(map(str, sorted(s))) for s in sets]))
    found = factors.factors(campaign, runs)
    assert [(name, kind) for name, kind, _ in found] == [(name, kind) for name, kind, _ in expected]
    for (_, _, labels), (_, _, wanted) in zip(found, expected, strict=True):
        assert np.asarray(labels).tolist() == list(wanted)
        assert np.asarray(labels).dtype == np.asarray(wanted, dtype=labels.dtype).dtype
