"""Flying runs on a GPU (``refexmc run --backend cuda``, docs/gpu.md): one run per CUDA thread.

A launch flies a batch of runs: each input table of the batch's runs is stacked into one device
array (run k's table is row k), each run gets its rows of the output arrays (summary, pulse counts,
history, pointing samples) and of four flat work buffers sized at launch (core.arena,
``core.flight.work_sizes``), and thread k calls the family's jitted ``fly_run``
(core.flight.kernel_parts) on row k: the CPU kernel's source, compiled by numba-cuda as a device
function (refexmc._jit). The host then names each run's outputs as the CPU path does
(:func:`refexmc.simulate.flight_result`). This module is the GPU's peer of refexmc.simulate: the
campaign layer (refexmc.campaign.cuda_backend) flies through it and never imports the core.
"""

import math

import numpy as np
from numba import cuda

from refexmc import _jit, simulate
from refexmc.core import flight, pointing
from refexmc.core import layout as L
from refexmc.core.inputs import RunInputs

THREADS_PER_BLOCK = 64  # a flight's state is large (registers, local memory): small blocks fill the SMs best
MEMORY_FRACTION = 0.5  # of the device's free memory, for one batch's arrays
MAX_LAUNCH_RUNS = 65536  # runs per launch at most (ReFEx: 7.6 GB of history rows; two batches on the host)
SIMULATOR_LAUNCH_RUNS = 16  # under the simulator each run is a Python thread

# families whose kernel does not compile for CUDA yet, with why (tests/test_cuda_backend.py compiles
# every other family's kernel to PTX); the entry flight (core.entry_flight) has no GPU kernel at all
REFUSED_FAMILIES = {}


def family_refusal(vehicle, mission):
    """Why the vehicle family of ``vehicle`` and ``mission`` (config dicts) cannot fly on the GPU
    yet, or None."""
    from refexmc.config.pack import pack

    return REFUSED_FAMILIES.get(flight.family(pack(vehicle, mission)))


_grid_kernels = {}


def grid_kernel(family):
    """The CUDA kernel of a vehicle family: thread k flies run k of a launch."""
    if family not in _grid_kernels:
        fly_run = _jit.cuda_device(flight.kernel_parts(*family).fly_run)
        _grid_kernels[family] = _jit.cuda_kernel(
            _fly_runs(fly_run), cache_key=("fly_runs", tuple(int(v) for v in family))
        )
    return _grid_kernels[family]


def _fly_runs(fly_run):
    def fly_runs(
        vehicle, thrusters, levels, fsw, mission, modes, exits, nav, atmosphere, allocation, nominal, wheels,
        wheel_distribution, seeds, every, summaries, pulses, histories, p_table, p_samples, p_counts, p_work,
        f, i, u, b,
    ):  # fmt: skip
        k = cuda.grid(1)
        if k < seeds.shape[0]:
            inputs = RunInputs(
                vehicle[k], thrusters[k], levels[k], fsw[k], mission[k], modes[k], exits[k], nav[k], atmosphere[k],
                allocation[k], nominal[k], wheels[k], wheel_distribution[k],
            )  # fmt: skip
            record = pointing.Record(p_table, p_samples[k], p_counts[k], p_work[k])
            fly_run(inputs, seeds[k], every[k], summaries[k], pulses[k], histories[k], record, f[k], i[k], u[k], b[k])

    return fly_runs


class Batch:
    """The host arrays of one launch: the runs' stacked inputs and their outputs."""

    def __init__(self, plan, run_ids, prepared, history_rate_hz):
        self.run_ids = run_ids
        self.prepared = _same_shapes(prepared)
        prepared = self.prepared
        self.flown = [k for k, p in enumerate(prepared) if not isinstance(p, Exception)]
        self.row_of_run = {k: j for j, k in enumerate(self.flown)}  # run k of the batch: row j of the arrays
        inputs = [prepared[k][3] for k in self.flown]
        self.inputs = RunInputs(*(_stack([getattr(x, name) for x in inputs]) for name in RunInputs._fields))
        n = len(inputs)
        self.seeds = np.array([prepared[k][0] for k in self.flown], dtype=np.int64)
        self.every = np.array([simulate.history_every(x, history_rate_hz) for x in inputs], dtype=np.int64)
        rows = max((simulate.history_rows(x, e) for x, e in zip(inputs, self.every, strict=True)), default=1)
        n_modes, n_thr = self.inputs.modes.shape[1], self.inputs.thrusters.shape[1]
        self.summaries = np.zeros((n, L.summary_size(n_modes)))
        self.pulses = np.zeros((n, n_thr), dtype=np.int64)
        self.histories = np.zeros((n, rows, L.history_size(self.inputs.wheels.shape[1])))
        requirements = plan.pointing
        self.p_table, capacity = np.zeros((0, L.POINTING_SIZE)), 1  # the CPU's pointing.empty_record()
        if requirements.columns:
            self.p_table = np.ascontiguousarray(requirements.table, dtype=np.float64)
            capacity = max(simulate.pointing_capacity(x, requirements.table) for x in inputs) if n else 1
        self.p_samples = np.zeros((n, self.p_table.shape[0], max(capacity, 1), pointing.SAMPLE_SIZE))
        self.p_counts = np.zeros((n, self.p_table.shape[0]), dtype=np.int64)
        self.p_work = np.zeros((n, 2, 4))
        self.family = plan.family
        self.error = None

    def work_sizes(self):
        """The lengths of one run's flat work buffers (the runs of a batch have the same shapes)."""
        if not self.flown:
            return (0, 0, 0, 0)
        fly_run = flight.kernel_parts(*self.family).fly_run
        return tuple(int(v) for v in flight.work_sizes(fly_run, self.prepared[self.flown[0]][3]))

    def arguments(self, buffers):
        """The kernel's arguments on the host, after the four flat work ``buffers``."""
        outputs = (self.summaries, self.pulses, self.histories)
        record = (self.p_table, self.p_samples, self.p_counts, self.p_work)
        return (*self.inputs, self.seeds, self.every, *outputs, *record, *buffers)

    def typing_arguments(self):
        """:meth:`arguments` with empty work buffers: what types the kernel (``numba.cuda.compile_ptx``)."""
        n = len(self.flown)
        dtypes = (np.float64, np.int64, np.uint64, np.bool_)
        return self.arguments(tuple(np.zeros((n, 0), dtype=dtype) for dtype in dtypes))

    def launch(self, kernel):
        """:meth:`fly` in a thread of its own: an exception is kept for :meth:`join` to raise."""
        try:
            self.fly(kernel)
        except BaseException as exc:  # noqa: BLE001 - raised again in the caller's thread
            self.error = exc

    def join(self, thread):
        thread.join()
        if self.error is not None:
            raise self.error

    def fly(self, kernel):
        """Fly the batch on the device; its outputs are back in the host arrays when this returns."""
        n = len(self.flown)
        if n == 0:
            return
        dtypes = (np.float64, np.int64, np.uint64, np.bool_)
        sizes = self.work_sizes()
        buffers = [cuda.device_array((n, size), dtype=dtype) for size, dtype in zip(sizes, dtypes, strict=True)]
        host = self.arguments(())
        # the history rows and pointing samples a run writes are all that is read of them (up to
        # summary[S_HISTORY_ROWS] and the counts): not uploaded; everything else is
        unread = {id(self.histories), id(self.p_samples)}
        device = [cuda.device_array_like(a) if id(a) in unread else cuda.to_device(a) for a in host]
        kernel[math.ceil(n / THREADS_PER_BLOCK), THREADS_PER_BLOCK](*device, *buffers)
        written = {id(a) for a in (self.summaries, self.pulses, self.histories, self.p_samples, self.p_counts)}
        for on_host, on_device in zip(host, device, strict=True):
            if id(on_host) in written:
                on_device.copy_to_host(on_host)

    def rows(self, plan, start, stop):
        """(runs row, FlightResult or None) of the batch's runs ``start`` to ``stop``, in run order."""
        out = []
        for k in range(start, stop):
            prepared = self.prepared[k]
            if isinstance(prepared, Exception):
                out.append((plan.error_row(self.run_ids[k], plan.failure_reason(prepared)), None))
                continue
            j = self.row_of_run[k]
            record = pointing.Record(self.p_table, self.p_samples[j], self.p_counts[j], self.p_work[j])
            outputs = (self.summaries[j], self.pulses[j], self.histories[j], record)
            result = simulate.flight_result(prepared[3], *outputs, plan.mode_names, plan.pointing)
            out.append(plan.result_row(self.run_ids[k], prepared, result))
        return out


def _same_shapes(prepared):
    """``prepared`` with each run whose input tables have other shapes than the first run's replaced
    by an exception (an error row): a launch stacks its runs' tables (a campaign's runs share them)."""
    shapes = [tuple(t.shape for t in p[3]) if not isinstance(p, Exception) else None for p in prepared]
    first = next((shape for shape in shapes if shape is not None), None)
    return [
        p if shape is None or shape == first else ValueError("input tables of other shapes than its launch's")
        for p, shape in zip(prepared, shapes, strict=True)
    ]


def _stack(tables):
    """Run k's table as row k of one array; tables of different shapes (not a campaign's) are refused."""
    shapes = {table.shape for table in tables}
    if len(shapes) > 1:
        raise ValueError(f"the runs of a GPU launch have input tables of different shapes: {sorted(shapes)}")
    return np.ascontiguousarray(np.stack(tables)) if tables else np.zeros((0, 1))


def launch_runs(plan, history_rate_hz):
    """Runs per launch: what half the free device memory holds (one run's arrays measured on the
    nominal inputs, doubled for the dispersed ones' margins), at most MAX_LAUNCH_RUNS."""
    if _jit.CUDA_SIMULATOR:
        return SIMULATOR_LAUNCH_RUNS
    probe = Batch(plan, [0], [(0, None, {}, plan.nominal_inputs)], history_rate_hz)
    nf, ni, nu, nb = probe.work_sizes()
    per_run = 2 * (sum(a.nbytes for a in probe.arguments(())) + 8 * (nf + ni + nu) + nb)
    free, _ = cuda.current_context().get_memory_info()
    return max(THREADS_PER_BLOCK, min(MAX_LAUNCH_RUNS, int(MEMORY_FRACTION * free / max(per_run, 1))))
