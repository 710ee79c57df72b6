"""Out-of-core aggregation of the histories: percentile envelopes over runs, batch by batch.

Each envelope is a 3-D histogram of counts [group, time bin, value bin] filled from record
batches; quantiles are read from the cumulative counts. Memory is fixed by the bin counts, not
by the number of runs. A quantile is exact to one value bin: on the logarithmic axes of angle
and rate errors 80 bins per decade (2.9 % of the value), on the linear propellant axis 0.1 %
of the load.
"""

import math
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from refexmc.config import renames
from refexmc.report import data

MAX_TIME_BINS = 600
ENVELOPE_PERCENTS = (0.0, 1.0, 50.0, 99.0, 100.0)


EVEN_SPACING = 1e-6  # edges whose steps differ by less than this fraction are evenly spaced: a guess within 1e-3 bin


class BinnedQuantiles:
    """Streaming histogram of values per (group, time bin) on fixed value edges (increasing).

    Samples are counted in bulk: their flat cell indices wait until a quarter of ``counts.size``
    (at least ``FLUSH_SAMPLES``) have come, then one ``np.bincount`` adds them, so that the cost
    of the counts array is paid per ~250,000 samples, not per part file (a 100-run part has ~46,000).
    The value bin of a sample is the one ``np.searchsorted(edges, value, side="right")`` gives,
    found from the edges' even spacing (in log for ``log``) and corrected to the exact edge:
    ~3.5 times faster than the binary search on a history's values.
    """

    # Each flush also costs bincount's output and its addition, ~counts.size: flushing every
    # counts.size / 4 samples rather than every counts.size took ~0.1 s more CPU at 100,000 ReFEx
    # runs (3.5 s for the envelopes) and held 20 MiB less of pending indices at 10,000 runs.
    FLUSH_SAMPLES = 1 << 18

    def __init__(self, groups, time_bins, dt, edges, log=False):
        self.groups, self.time_bins, self.dt = groups, time_bins, float(dt)
        self.edges = np.asarray(edges, dtype=float)
        self.log = log
        self.value_bins = len(self.edges) + 1  # below the first edge, between edges, above the last
        self._counts = np.zeros((groups, time_bins, self.value_bins), dtype=np.int64)
        self._pending, self._pending_samples = [], 0
        self._flush_samples = max(self.FLUSH_SAMPLES, self._counts.size // 4)
        # edges[i] = first * step**i (log) or first + i * step: the bin's guess from the value; for
        # edges spaced otherwise (an entry's signed log edges, issue 24) the binary search
        first, n = self.edges[0], len(self.edges)
        self._guess_log = bool(log and first > 0)
        scaled = np.log(self.edges) if self._guess_log else self.edges
        steps = np.diff(scaled)
        even = n > 1 and steps.min() > 0 and steps.max() - steps.min() <= EVEN_SPACING * steps.mean()
        self._origin = scaled[0]
        self._per_step = (n - 1) / (scaled[-1] - scaled[0]) if even else 0.0
        self._previous_edge = np.concatenate([[-np.inf], self.edges])  # [i]: edges[i - 1]
        self._next_edge = np.concatenate([self.edges, [np.nan]])  # [i]: edges[i]; no value is >= NaN

    @property
    def counts(self):
        """Samples per [group, time bin, value bin]."""
        self._flush()
        return self._counts

    def add(self, group, tau, values):
        """Add samples: ``group`` int array, ``tau`` time since the group's start [s], ``values``."""
        self.add_cells(self.cells(group, tau), values)

    def cells(self, group, tau):
        """Flat (group, time bin) index of each sample; -1 where the group is out of range or tau is not finite.

        Histograms with the same groups, time bins and dt share these (:meth:`add_cells`).
        """
        tbin = np.maximum(tau, 0.0)
        tbin /= self.dt
        with np.errstate(invalid="ignore"):  # NaN tau: its cell is -1 below
            tbin = np.clip(tbin.astype(np.int64), 0, self.time_bins - 1)
        cell = group.astype(np.int64) * self.time_bins + tbin
        bad = ~np.isfinite(tau) | (group < 0) | (group >= self.groups)
        cell[bad] = -1
        return cell

    def add_cells(self, cells, values):
        """Add samples by their :meth:`cells` (of a histogram with the same groups and time bins)."""
        self.add_flat(self.flat_indices(cells, values))

    def flat_indices(self, cells, values):
        """Flat index into the counts of each sample given by its :meth:`cells`, without the samples
        of cell -1 or of a value that is not finite. Changes nothing: may run on several threads."""
        keep = np.isfinite(values) & (cells >= 0)
        if not keep.all():
            cells, values = cells[keep], values[keep]
        flat = cells * self.value_bins
        flat += self.value_bin(values)
        return flat

    def add_flat(self, flat):
        """Count samples by their :meth:`flat_indices`."""
        self._pending.append(flat)
        self._pending_samples += len(flat)
        if self._pending_samples >= self._flush_samples:
            self._flush()

    def value_bin(self, values):
        """``np.searchsorted(self.edges, values, side="right")`` of finite ``values``, as int64."""
        n = len(self.edges)
        if self._per_step == 0.0:
            return np.searchsorted(self.edges, values, side="right").astype(np.int64)
        with np.errstate(divide="ignore", invalid="ignore"):  # log of 0 or of a negative: below every edge
            guess = np.log(values) if self._guess_log else np.array(values, dtype=float)
            guess -= self._origin
            guess *= self._per_step
            guess = np.floor(guess, out=guess)
        guess = np.fmin(np.fmax(guess, -1.0), n - 1.0)  # fmax: NaN (log of a negative) -> -1
        index = guess.astype(np.int64)
        index += 1  # edges[index - 1] <= value < edges[index], or close: corrected to exactly that
        while True:
            down = values < self._previous_edge[index]
            up = values >= self._next_edge[index]
            if not (down.any() or up.any()):
                return index
            index -= down
            index += up

    def _flush(self):
        if self._pending:
            flat = self._pending[0] if len(self._pending) == 1 else np.concatenate(self._pending)
            self._pending, self._pending_samples = [], 0
            self._counts += np.bincount(flat, minlength=self._counts.size).reshape(self._counts.shape)

    def bin_values(self):
        """A representative value per value bin (geometric or arithmetic centre; the edge outside)."""
        e = self.edges
        inner = np.sqrt(e[:-1] * e[1:]) if self.log else 0.5 * (e[:-1] + e[1:])
        return np.concatenate([[e[0]], inner, [e[-1]]])

    def quantiles(self, percents):
        """Array [group, time bin, len(percents)] of percentiles; NaN where a bin holds no sample."""
        cumulative = np.cumsum(self.counts, axis=2)
        total = cumulative[:, :, -1]
        values = self.bin_values()
        out = np.full((self.groups, self.time_bins, len(percents)), np.nan)
        for k, percent in enumerate(percents):
            # the value bin holding the sample of rank ceil(p * total) (rank 1 for p = 0)
            rank = np.maximum(1, np.ceil(percent / 100.0 * total)).astype(np.int64)
            index = (cumulative < rank[:, :, None]).sum(axis=2)
            out[:, :, k] = np.where(total > 0, values[np.minimum(index, self.value_bins - 1)], np.nan)
        return out

    def sample_counts(self):
        return self.counts.sum(axis=2)


def log_edges(low, high, per_decade=80):
    return np.geomspace(low, high, int(round(math.log10(high / low) * per_decade)) + 1)


MAX_DECADES = 8  # log axes span at most this many decades below the largest value
DEFAULT_RANGES = {"theta_t_deg": (1e-4, 1e3), "omega_m_deg_s": (1e-5, 1e3)}


def history_range(campaign, column):
    """Decade-rounded (low, high) of a history column's positive values (:func:`history_ranges`)."""
    return history_ranges(campaign, [column])[column]


def statistics_min_max(parts, columns):
    """{column: (min, max)} over the Parquet row-group statistics of ``parts`` (no data read; each
    part's footer once, on threads); a column that no part has, or without statistics in some row
    group, is left out."""
    low, high, missing = {}, {}, set()
    for part_low, part_high, part_missing in data.map_on_threads(lambda part: _part_min_max(part, columns), parts):
        missing |= part_missing
        for column, value in part_low.items():
            low[column] = min(low.get(column, math.inf), value)
            high[column] = max(high.get(column, -math.inf), part_high[column])
    return {c: (low[c], high[c]) for c in low if c not in missing}


def _part_min_max(part, columns):
    """({column: min}, {column: max}, {columns without statistics}) of one part's footer."""
    import pyarrow.parquet as pq

    metadata = pq.read_metadata(part)
    # a part written before a rename (config.renames): its columns by their names of now
    names = [renames.new_column(name) for name in metadata.schema.names]
    low, high, missing = {}, {}, set()
    for column in columns:
        if column not in names:
            continue
        index = names.index(column)
        for group in range(metadata.num_row_groups):
            statistics = metadata.row_group(group).column(index).statistics
            if statistics is None or not statistics.has_min_max:
                missing.add(column)
                break
            low[column] = min(low.get(column, math.inf), float(statistics.min))
            high[column] = max(high.get(column, -math.inf), float(statistics.max))
    return low, high, missing


def history_ranges(campaign, columns):
    """{column: decade-rounded (low, high) of its positive values}, from the Parquet row-group
    statistics (:func:`statistics_min_max`): the log axes and their bins follow the data, so a
    fine-pointing mission's arcsec errors are not cut at a floor made for degrees. At most
    ``MAX_DECADES`` decades; ``DEFAULT_RANGES`` when the parts carry no statistics."""
    ranges = statistics_min_max(campaign.history_parts, columns)
    out = {}
    for column in columns:
        if column not in ranges:
            out[column] = DEFAULT_RANGES[column]
            continue
        smallest, largest = ranges[column]
        positive_low = smallest if smallest > 0 else 0.0  # the smallest positive bound seen, else 0
        out[column] = _decades(positive_low, max(abs(largest), abs(smallest)), column)
    return out


def _decades(low, high, column):
    if not math.isfinite(high) or high <= 0.0:
        return DEFAULT_RANGES[column]
    top = 10.0 ** math.ceil(math.log10(high))
    floor = max(low, high * 10.0**-MAX_DECADES) if low > 0 else high * 10.0**-MAX_DECADES
    bottom = 10.0 ** math.floor(math.log10(floor))
    return bottom, max(top, bottom * 10)


def mode_starts(runs, mode_time_columns):
    """[run, mode] start time of each mode [s] from the runs table's time per mode (modes are sequential)."""
    times = runs[mode_time_columns].to_numpy(dtype=float)
    times = np.nan_to_num(times, nan=0.0)
    return np.concatenate([np.zeros((len(runs), 1)), np.cumsum(times, axis=1)[:, :-1]], axis=1)


def run_positions(run_ids, rid):
    """Index of each of ``rid`` in the sorted ``run_ids``; -1 where it is not there.

    Looked up once per stretch of equal ids (a history part holds each run's rows together).
    """
    if len(rid) == 0:
        return np.zeros(0, dtype=np.int64)
    first = np.flatnonzero(np.concatenate([[True], rid[1:] != rid[:-1]]))
    ids = rid[first]
    position = np.searchsorted(run_ids, ids)
    found = position < len(run_ids)
    found[found] = run_ids[position[found]] == ids[found]
    position[~found] = -1
    return np.repeat(position, np.diff(np.append(first, len(rid))))


def aggregate_histories(campaign):
    """Envelopes of theta_t and |omega_m| per mode (aligned at mode start) and of propellant over time.

    Returns a dict: ``mode_names`` (the campaign's, in flight order: the groups of the envelopes),
    ``modes`` {quantity: (BinnedQuantiles, percentiles)}, ``propellant``
    (BinnedQuantiles over absolute time, percentiles), ``mode_durations`` (max per mode),
    ``valve_samples`` (per mode, samples with a valve open),
    ``nominal`` (the nominal run's samples as arrays, or None) and ``rows`` (samples read).
    Only runs with status ok contribute.
    """
    ok = campaign.ok
    if not campaign.history_parts or ok.empty:
        return None
    if "entry_flight" in (campaign.resolved.get("mission") or {}):  # an entry campaign: no attitude envelopes
        return None
    run_ids = ok["run_id"].to_numpy(dtype=np.int64)
    modes = campaign.modes
    time_columns = campaign.mode_time_columns
    starts = mode_starts(ok, time_columns)
    durations = np.nan_to_num(ok[time_columns].to_numpy(dtype=float), nan=0.0).max(axis=0)
    t_end = float(np.nanmax(ok["t_end_s"].to_numpy(dtype=float))) if "t_end_s" in ok else 0.0
    sample_dt = 1.0 / campaign.history_rate_hz
    longest_mode = float(durations.max(initial=0.0))
    mode_dt = max(sample_dt, longest_mode / MAX_TIME_BINS)
    mode_bins = int(longest_mode / mode_dt) + 2
    fuel_dt = max(sample_dt, t_end / MAX_TIME_BINS)
    fuel_bins = int(t_end / fuel_dt) + 2
    ranges = history_ranges(campaign, ["theta_t_deg", "omega_m_deg_s"])
    angle = BinnedQuantiles(len(modes), mode_bins, mode_dt, log_edges(*ranges["theta_t_deg"]), log=True)
    rate = BinnedQuantiles(len(modes), mode_bins, mode_dt, log_edges(*ranges["omega_m_deg_s"]), log=True)
    fuel = BinnedQuantiles(1, fuel_bins, fuel_dt, np.linspace(0.0, 1.0, 1001))
    valve_samples = np.zeros(len(modes), dtype=np.int64)
    nominal_id = campaign.nominal_run_id
    nominal_parts = []
    rows = 0
    present = data.present_columns(campaign)  # a hop records no attitude: its rows stay empty
    columns = ["run_id", "t_s", "mode", "theta_t_deg", "omega_m_deg_s", "fuel_remaining", "valves_open"]
    columns = [c for c in columns if c in present]
    if not {"run_id", "t_s", "mode"} <= present:
        return None

    def values(batch, column, missing=np.nan):  # a column the family does not write: all ``missing``
        if column in present:
            return batch.column(column).to_numpy(zero_copy_only=False)
        return np.full(batch.num_rows, missing, dtype=np.float32)

    starts = starts.ravel()  # [run position * modes + mode]

    def samples(batch):  # on the reading threads: nothing shared is changed
        read = batch.num_rows
        rid = batch.column("run_id").to_numpy(zero_copy_only=False)
        position = run_positions(run_ids, rid)
        if (position < 0).any():  # rows of errored runs: not in the statistics
            flown = position >= 0
            batch = batch.filter(flown)
            rid, position = rid[flown], position[flown]
        t = batch.column("t_s").to_numpy(zero_copy_only=False)
        mode = data.mode_codes(batch.column("mode"), modes).astype(np.int64)
        theta = values(batch, "theta_t_deg")
        omega = np.abs(values(batch, "omega_m_deg_s"))
        propellant = values(batch, "fuel_remaining")
        known = mode >= 0
        valves = values(batch, "valves_open", 0)
        valve_counts = np.bincount(mode[known & (valves != 0)], minlength=len(modes))
        if known.all():
            tau = t - starts[position * len(modes) + mode]
        else:
            tau = np.full(len(t), np.nan)
            tau[known] = t[known] - starts[position[known] * len(modes) + mode[known]]
        cells = angle.cells(mode, tau)  # the rate's too: the same modes, time bins and dt
        flats = (
            angle.flat_indices(cells, theta),
            rate.flat_indices(cells, omega),
            fuel.flat_indices(fuel.cells(np.zeros(len(t), dtype=np.int64), t), propellant),
        )
        nominal_part = None
        if nominal_id is not None:
            mine = rid == nominal_id
            if mine.any():
                nominal_part = (t[mine], mode[mine], tau[mine], theta[mine], omega[mine], propellant[mine])
        return read, valve_counts, flats, nominal_part

    # Each histogram counts on a thread of its own (np.bincount runs without the GIL), one batch at a
    # time in batch order, beside the reading threads: at a million runs the counting is ~1/4 of the
    # envelopes' CPU, and on this thread it was the report's longest serial stage (benchmarks/RESULTS.md).
    counting = [None, None, None]  # the last batch each histogram's thread is counting
    with ThreadPoolExecutor(3) as counters:
        for batch_rows, valve_counts, flats, nominal_part in data.map_history_batches(campaign, columns, samples):
            rows += batch_rows
            valve_samples += valve_counts
            for k, (binned, flat) in enumerate(zip((angle, rate, fuel), flats, strict=True)):
                if counting[k] is not None:
                    counting[k].result()  # at most one batch waits per histogram; raises what it raised
                counting[k] = counters.submit(binned.add_flat, flat)
            if nominal_part is not None:
                nominal_parts.append(nominal_part)
        for future in counting:
            if future is not None:
                future.result()
    nominal = None
    if nominal_parts:
        arrays = [np.concatenate(column) for column in zip(*nominal_parts, strict=True)]
        order = np.argsort(arrays[0], kind="stable")
        nominal = dict(
            zip(("t_s", "mode", "tau", "theta_t_deg", "omega_m_deg_s", "fuel_remaining"), arrays, strict=True)
        )
        nominal = {key: value[order] for key, value in nominal.items()}
    return {
        "mode_names": list(modes),
        "modes": {
            "theta_t_deg": (angle, angle.quantiles(ENVELOPE_PERCENTS)),
            "omega_m_deg_s": (rate, rate.quantiles(ENVELOPE_PERCENTS)),
        },
        "propellant": (fuel, fuel.quantiles(ENVELOPE_PERCENTS)),
        "mode_durations": durations,
        "valve_samples": valve_samples,
        "percents": ENVELOPE_PERCENTS,
        "nominal": nominal,
        "rows": rows,
    }


MIN_SAMPLES_PER_RUN = 3  # a mode panel needs this many history samples per run on average


def modes_with_samples(aggregate, runs):
    """{quantity: [mode index]} of the modes with at least ``MIN_SAMPLES_PER_RUN`` samples of the
    quantity per run, and {quantity: {mode name: samples per run}} of those left out with some."""
    shown, left_out = {}, {}
    for quantity, (binned, _) in aggregate["modes"].items():
        per_run = binned.sample_counts().sum(axis=1) / max(runs, 1)
        shown[quantity] = [int(m) for m in np.flatnonzero(per_run >= MIN_SAMPLES_PER_RUN)]
        left_out[quantity] = {
            aggregate["mode_names"][m]: float(per_run[m])
            for m in np.flatnonzero((per_run > 0) & (per_run < MIN_SAMPLES_PER_RUN))
        }
    return shown, left_out


def plotted_modes(aggregate):
    """Indices of the modes to plot, in flight order: those where the vehicle is controlled, that is
    with a finite angle error or a valve open in some run. A coast (ReFEx's NCM) has neither; a rate
    damping mode (RDM1) has valves but no angle error. When no mode is controlled, those with samples."""
    angle, _ = aggregate["modes"]["theta_t_deg"]
    rate, _ = aggregate["modes"]["omega_m_deg_s"]
    controlled = np.flatnonzero(angle.sample_counts().sum(axis=1) + aggregate["valve_samples"])
    return [int(m) for m in (controlled if len(controlled) else np.flatnonzero(rate.sample_counts().sum(axis=1)))]
