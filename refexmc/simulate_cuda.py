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


INPUT_TABLES = RunInputs._fields  # a launch's input arrays: each RunInputs table stacked, then seeds and every
OUTPUTS = ("summaries", "pulses", "histories", "p_samples", "p_counts", "p_work")


def input_shapes(nominal_inputs, n):
    """``{name: (shape, dtype)}`` of the input arrays of a launch of ``n`` runs of a campaign whose
    undispersed inputs are ``nominal_inputs`` (every run of a campaign has their shapes)."""
    shapes = {name: ((n, *getattr(nominal_inputs, name).shape), np.float64) for name in INPUT_TABLES}
    return {**shapes, "seeds": ((n,), np.int64), "every": ((n,), np.int64)}


def output_shapes(nominal_inputs, n, history_rows, requirements, capacity):
    """``{name: (shape, dtype)}`` of the output arrays of a launch of ``n`` runs: ``history_rows``
    and pointing ``capacity`` are the largest of its runs' (:func:`run_sizes`)."""
    n_modes, n_thrusters = nominal_inputs.modes.shape[0], nominal_inputs.thrusters.shape[0]
    n_requirements = pointing_table(requirements).shape[0]
    return {
        "summaries": ((n, L.summary_size(n_modes)), np.float64),
        "pulses": ((n, n_thrusters), np.int64),
        "histories": ((n, history_rows, L.history_size(nominal_inputs.wheels.shape[0])), np.float64),
        "p_samples": ((n, n_requirements, max(capacity, 1), pointing.SAMPLE_SIZE), np.float64),
        "p_counts": ((n, n_requirements), np.int64),
        "p_work": ((n, 2, 4), np.float64),
    }


def run_sizes(inputs, history_rate_hz, requirements):
    """(history every, history rows, pointing capacity) of a run of ``inputs``: what its rows of a
    launch's arrays must hold."""
    every = simulate.history_every(inputs, history_rate_hz)
    capacity = 1
    if requirements is not None and requirements.columns:
        capacity = simulate.pointing_capacity(inputs, requirements.table)
    return every, simulate.history_rows(inputs, every), capacity


def pointing_table(requirements):
    """The requirements' table each thread reads (the CPU's ``pointing.empty_record()`` without any)."""
    if requirements is None or not requirements.columns:
        return np.zeros((0, L.POINTING_SIZE))
    return np.ascontiguousarray(requirements.table, dtype=np.float64)


class Batch:
    """One launch's host arrays (``arrays``: :func:`input_shapes` and :func:`output_shapes` by
    name, in any memory): run k of the launch is row k of each."""

    def __init__(self, arrays, family, requirements):
        self.inputs = RunInputs(*(arrays[name] for name in INPUT_TABLES))
        self.seeds, self.every = arrays["seeds"], arrays["every"]
        self.summaries, self.pulses, self.histories = arrays["summaries"], arrays["pulses"], arrays["histories"]
        self.p_samples, self.p_counts, self.p_work = arrays["p_samples"], arrays["p_counts"], arrays["p_work"]
        self.p_table = pointing_table(requirements)
        self.family = family
        self.error = None

    def __len__(self):
        return self.seeds.shape[0]

    def run_inputs(self, j):
        """The inputs of run ``j`` of the launch (views of its rows)."""
        return RunInputs(*(table[j] for table in self.inputs))

    def work_sizes(self):
        """The lengths of one run's flat work buffers (the runs of a batch have the same shapes)."""
        if len(self) == 0:
            return (0, 0, 0, 0)
        fly_run = flight.kernel_parts(*self.family).fly_run
        return tuple(int(v) for v in flight.work_sizes(fly_run, self.run_inputs(0)))

    def arguments(self, buffers):
        """The kernel's arguments on the host, after the four flat work ``buffers``."""
        outputs = (self.summaries, self.pulses, self.histories)
        record = (self.p_table, self.p_samples, self.p_counts, self.p_work)
        return (*self.inputs, self.seeds, self.every, *outputs, *record, *buffers)

    def typing_arguments(self):
        """:meth:`arguments` with empty work buffers: what types the kernel (``numba.cuda.compile_ptx``)."""
        dtypes = (np.float64, np.int64, np.uint64, np.bool_)
        return self.arguments(tuple(np.zeros((len(self), 0), dtype=dtype) for dtype in dtypes))

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
        n = len(self)
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

    def result(self, j, mode_names, requirements):
        """The :class:`refexmc.simulate.FlightResult` of run ``j`` of the flown launch (views of its rows)."""
        record = pointing.Record(self.p_table, self.p_samples[j], self.p_counts[j], self.p_work[j])
        outputs = (self.summaries[j], self.pulses[j], self.histories[j], record)
        return simulate.flight_result(self.run_inputs(j), *outputs, mode_names, requirements)


def batch_of_runs(plan, inputs, seeds, history_rate_hz):
    """A :class:`Batch` of runs of ``plan`` (a campaign's RunPlan) in private memory: ``inputs``
    (each run's RunInputs, of the campaign's shapes) and their nav ``seeds``."""
    n = len(inputs)
    sizes = [run_sizes(x, history_rate_hz, plan.pointing) for x in inputs]
    rows = max((s[1] for s in sizes), default=1)
    capacity = max((s[2] for s in sizes), default=1)
    shapes = {
        **input_shapes(plan.nominal_inputs, n),
        **output_shapes(plan.nominal_inputs, n, rows, plan.pointing, capacity),
    }
    arrays = {name: np.zeros(shape, dtype=dtype) for name, (shape, dtype) in shapes.items()}
    for k, x in enumerate(inputs):
        for name in INPUT_TABLES:
            arrays[name][k] = getattr(x, name)
    arrays["seeds"][:] = seeds
    arrays["every"][:] = [s[0] for s in sizes]
    return Batch(arrays, plan.family, plan.pointing)


def _host_bytes(probe):
    return 2 * sum(a.nbytes for a in probe.arguments(()))


def launch_runs(plan, history_rate_hz, host_free_bytes=None):
    """Runs per launch: what half the free device memory holds (one run's arrays measured on the
    nominal inputs, doubled for the dispersed ones' margins), at most MAX_LAUNCH_RUNS; with
    ``host_free_bytes`` (the host memory still available), also what a quarter of it holds: two
    launches' host arrays live at once (one named while the next flies), beside the workers'."""
    if _jit.CUDA_SIMULATOR:
        return SIMULATOR_LAUNCH_RUNS
    probe = batch_of_runs(plan, [plan.nominal_inputs], [0], history_rate_hz)
    nf, ni, nu, nb = probe.work_sizes()
    host = _host_bytes(probe)
    per_run = host + 2 * (8 * (nf + ni + nu) + nb)
    free, _ = cuda.current_context().get_memory_info()
    runs = int(MEMORY_FRACTION * free / max(per_run, 1))
    if host_free_bytes is not None:
        runs = min(runs, int(host_free_bytes / 4 / max(host, 1)))
    return max(THREADS_PER_BLOCK, min(MAX_LAUNCH_RUNS, runs))
