"""Fly one run: allocate the caller-owned output arrays, call the core, name what it returns.

The one place outside ``refexmc.config`` that knows the core's array layouts: the campaign and
the report see named values only (runs-table values, history columns), named from the files.
"""

import copy
import math

import numpy as np

from refexmc import _jit
from refexmc.config.requirements import (
    ENTRY_COLUMNS,
    LOCAL_COLUMNS,
    ORBIT_COLUMNS,
    POINTING_COLUMNS,
    WHEEL_COLUMNS,
    mode_time_columns,
)
from refexmc.core import flight, pointing
from refexmc.core import layout as L
from refexmc.core import modes as core_modes

AXES = "xyz"


def failure_name(code, mode_name=None):
    """The failure reason of a ``layout.FAIL_*`` code (a timeout names its mode)."""
    name = L.FAILURE_NAMES[int(code)]
    return name.format(mode=(mode_name or "mode").lower()) if name else None


class FlightResult:
    """One flight's outputs, named."""

    def __init__(
        self,
        summary,
        pulse_counts,
        history,
        mode_names,
        orbit=False,
        pointing=False,
        wheels=False,
        local=False,
        requirement_values=None,
        trajectory=L.TRAJECTORY_PLANAR_DRAG,
        tank=False,
        attitude=True,
        thrusters=True,
    ):
        self.summary = summary  # layout.SUMMARY then per-mode values
        self.pulse_counts = pulse_counts  # valve open commands sent, per thruster
        self.history = history  # rows x layout.history_size(wheels)
        self.mode_names = list(mode_names)
        self.orbit = orbit  # the orbit trajectory: entry-state values (config.requirements.ORBIT_COLUMNS)
        self.pointing = pointing  # a pointing window: config.requirements.POINTING_COLUMNS
        self.wheels = wheels  # reaction wheels: config.requirements.WHEEL_COLUMNS
        self.local = local  # the local trajectory: config.requirements.LOCAL_COLUMNS
        # the pointing requirements' per-run values by runs column (config.pointing, core.pointing)
        self.requirement_values = dict(requirement_values or {})
        self.trajectory = trajectory  # layout.TRAJECTORY_*: which of altitude_m, qbar_pa the flight has
        self.tank = tank  # a blow-down or regulated feed: tank_pressure_pa
        self.attitude = attitude  # some mode controls the attitude: the attitude columns
        self.thrusters = thrusters  # thrusters fire (not actuation wheels): propellant, valves, pulses

    def value(self, name):
        """A summary value by name; ``t_mode_s`` and ``t1_mode_s`` give one value per mode."""
        n = len(self.mode_names)
        if name == "t_mode_s":
            return self.summary[L.S_PER_MODE : L.S_PER_MODE + n]
        if name == "t1_mode_s":
            return self.summary[L.S_PER_MODE + n : L.S_PER_MODE + 2 * n]
        offset, size = L.SUMMARY.slices[name]
        return self.summary[offset] if size == 1 else self.summary[offset : offset + size]

    @property
    def success(self):
        return bool(self.summary[L.S_SUCCESS])

    @property
    def failure_reason(self):
        mode = int(self.summary[L.S_FAILURE_MODE])
        return failure_name(self.summary[L.S_FAILURE], self.mode_names[mode] if mode < len(self.mode_names) else None)

    def column(self, name):
        """A history signal by its ``layout.HISTORY`` name (all rows)."""
        offset, size = L.HISTORY.slices[name]
        return self.history[:, offset] if size == 1 else self.history[:, offset : offset + size]

    def runs_values(self):
        """The flown run's values of the runs table, in column order (interface.md ``runs``)."""
        row = {
            "fuel_remaining": float(self.value("fuel_remaining")),
            "fuel_used_kg": float(self.value("fuel_used_kg")),
            "t_end_s": float(self.value("t_end_s")),
        }
        for name, value in zip(mode_time_columns(self.mode_names), self.value("t_mode_s"), strict=True):
            row[name] = float(value)
        row["attitude_error_end_deg"] = float(self.value("attitude_error_end_deg"))
        if self.orbit:
            entry = self.value("entry_state")
            for k, name in enumerate(ORBIT_COLUMNS[:5]):
                row[name] = float(entry[k])
            for name in ORBIT_COLUMNS[5:]:
                row[name] = float(self.value(name))
        if self.local:
            switches = self.value("switches")
            values = [self.value(name) for name in LOCAL_COLUMNS[:3]] + list(switches)
            for name, value in zip(LOCAL_COLUMNS, values, strict=True):
                row[name] = float(value)
        if self.pointing:
            end, rms = self.value("pointing_end_arcsec"), self.value("pointing_rms_arcsec")
            values = [*end, *rms, self.value("pointing_max_arcsec")]
            for name, value in zip(POINTING_COLUMNS, values, strict=True):
                row[name] = float(value)
        if self.wheels:
            for name in WHEEL_COLUMNS:
                row[name] = float(self.value(name))
        row.update(self.requirement_values)
        row["modes_completed"] = int(self.value("modes_completed"))
        for i, count in enumerate(self.pulse_counts):
            row[f"pulses_{i + 1}"] = int(count)
        return row

    @staticmethod
    def joined(results):
        """(one result whose history is the rows of ``results``' one after the other, each
        one's number of rows): their history columns converted at once
        (``campaign.storage.histories_table``); the runs are of one campaign, so of one family.
        The joined rows are stored column by column (Fortran order): each output column is then
        converted from contiguous memory (a 1,000-run chunk: 0.11 -> 0.06 ms per run)."""
        together = copy.copy(results[0])
        lengths = [len(result.history) for result in results]
        together.history = np.empty((sum(lengths), results[0].history.shape[1]), order="F")
        np.concatenate([result.history for result in results], out=together.history)
        return together, lengths

    def non_finite_reason(self):
        """Why the result is not usable (a non-finite state), or None."""
        # without propellant (reaction wheels only) the fraction remaining is 0/0: NaN by definition
        fraction = ("fuel_remaining",) if not self.wheels or self.value("fuel_used_kg") > 0.0 else ()
        for name in (*fraction, "fuel_used_kg", "t_end_s"):
            if not np.isfinite(self.value(name)):
                return f"non-finite {name} in the summary"
        signals = [L.H_T, L.H_OMEGA_M, *([L.H_FUEL] if fraction else []), L.H_ALTITUDE]
        finite = self.history[:, signals]
        if not np.isfinite(finite).all():
            row = int(np.argmax(~np.isfinite(finite).all(axis=1)))
            return f"non-finite state at t = {self.column('t_s')[row]:.3f} s"
        return None

    @property
    def wheel_count(self):
        return (self.history.shape[1] - L.HISTORY_SIZE) // L.HISTORY_PER_WHEEL

    def history_columns(self):
        """History signals by output column name (interface.md ``histories``, without run_id): the
        columns the flight's family produces, no others (a hop has no attitude error or altitude).

        ``mode`` is the index into :attr:`mode_names`; time is float64, the sampled signals
        float32 (7 significant digits: far below any sensor or model accuracy).
        """
        col = self.column

        def signal(name, k=None):
            values = col(name) if k is None else col(name)[:, k]
            return values.astype(np.float32)

        columns = {"t_s": col("t_s").copy(), "mode": col("mode").astype(np.int32)}
        if self.attitude:  # a hop (translate modes only) controls no attitude and reads no rate
            columns["theta_t_deg"] = signal("theta_t_deg")
            columns["omega_m_deg_s"] = signal("omega_m_deg_s")
            for k, axis in enumerate(AXES):
                columns[f"theta_e_{axis}_deg"] = signal("theta_e_deg", k)
            for k, axis in enumerate(AXES):
                columns[f"omega_e_{axis}_deg_s"] = signal("omega_e_deg_s", k)
        if self.thrusters:
            columns["fuel_remaining"] = signal("fuel_remaining")
            halves = col("valves_open").astype(np.int64)  # bits 0-31 and 32-62 of the mask
            columns["valves_open"] = halves[:, 0] | (halves[:, 1] << 32)
        if self.attitude and self.thrusters:
            for k, axis in enumerate(AXES):
                columns[f"pulse_{axis}"] = col("pulse_command")[:, k].astype(np.int8)
        if self.trajectory in (L.TRAJECTORY_PLANAR_DRAG, L.TRAJECTORY_ORBIT):
            columns["altitude_m"] = signal("altitude_m")
        if self.trajectory == L.TRAJECTORY_PLANAR_DRAG:
            columns["qbar_pa"] = signal("qbar_pa")
        if self.tank:
            columns["tank_pressure_pa"] = signal("tank_pressure_pa")
        if self.local:
            for k, axis in enumerate(AXES):
                columns[f"position_{axis}_m"] = signal("position_m", k)
            for k, axis in enumerate(AXES):
                columns[f"velocity_{axis}_m_s"] = signal("velocity_m_s", k)
            columns["position_error_m"] = signal("position_error_m")
            columns["speed_m_s"] = signal("speed_m_s")
            for k, axis in enumerate(AXES):
                columns[f"translation_command_{axis}"] = col("translation_command")[:, k].astype(np.int8)
        for i in range(self.wheel_count):
            first = L.HISTORY_SIZE + L.HISTORY_PER_WHEEL * i
            columns[f"wheel_momentum_{i + 1}_n_m_s"] = self.history[:, first + L.HW_MOMENTUM].astype(np.float32)
            columns[f"wheel_torque_{i + 1}_n_m"] = self.history[:, first + L.HW_TORQUE].astype(np.float32)
        return columns


def empty_result(mode_names, n_thrusters):
    """A result with no history rows (the shape of an errored run's outputs)."""
    n = len(mode_names)
    return FlightResult(
        np.zeros(L.summary_size(n)), np.zeros(n_thrusters, dtype=np.int64), np.zeros((0, L.HISTORY_SIZE)), mode_names
    )


def kernels_loaded():
    """True while every flight kernel this process has asked for is compiled or loaded from the
    cache (or JIT is disabled): False while a family's first flight compiles its kernel."""
    return all(getattr(kernel, "signatures", True) for kernel in flight.kernels().values())


def history_every(inputs, history_rate_hz):
    """Control steps between history samples (at least 1)."""
    period = inputs.fsw[L.F_CONTROL_PERIOD]
    return max(1, int(round(1.0 / (history_rate_hz * period))))


def control_period(inputs):
    return float(inputs.fsw[L.F_CONTROL_PERIOD])


def pointing_capacity(inputs, table):
    """Samples a pointing requirement's buffer needs: the control steps of its window within the
    flight time (both ends), the largest over ``table``'s rows."""
    period = inputs.fsw[L.F_CONTROL_PERIOD]
    end = inputs.mission[L.M_MAX_TIME]
    steps = 1
    for row in table:
        span = min(row[L.P_WINDOW_TO], end + period) - max(row[L.P_WINDOW_FROM], 0.0)
        steps = max(steps, int(math.ceil(max(span, 0.0) / period)) + 2)
    return steps


def fly(inputs, nav_seed=0, history_rate_hz=2.0, mode_names=None, requirements=None):
    """Fly ``inputs`` (config.pack.RunInputs); history at ``history_rate_hz``.

    ``mode_names`` (``config.pack.mode_names``) name the result's per-mode values and failures;
    without them the modes are ``mode_1``, ``mode_2``, ...; ``requirements``: the campaign's
    pointing requirements (``config.pointing.PointingPlan``), computed in the flight at the control rate.
    """
    every = history_every(inputs, history_rate_hz)
    summary = np.zeros(L.summary_size(inputs.modes.shape[0]))
    pulses = np.zeros(inputs.thrusters.shape[0], dtype=np.int64)
    history = np.zeros((history_rows(inputs, every), L.history_size(inputs.wheels.shape[0])))
    family = flight.family(inputs)
    run_flight = flight.kernel(*family)  # the vehicle family's own kernel (docs/families.md)
    if not getattr(
        flight.kernel_parts(*family).fly_run, "signatures", True
    ):  # first flight here: compiled under the lock
        load_kernels([family])
    if requirements is None or not requirements.columns:
        record = pointing.empty_record()
    else:
        record = pointing.new_record(requirements.table, pointing_capacity(inputs, requirements.table))
    run_flight(inputs, np.int64(nav_seed), np.int64(every), summary, pulses, history, record)
    return flight_result(inputs, summary, pulses, history, record, mode_names, requirements)


def history_rows(inputs, every):
    """History rows a flight of ``inputs`` sampled every ``every`` control steps can write."""
    period = inputs.fsw[L.F_CONTROL_PERIOD]
    return int(math.ceil(inputs.mission[L.M_MAX_TIME] / period / every)) + 3


def flight_result(inputs, summary, pulses, history, record, mode_names=None, requirements=None):
    """The :class:`FlightResult` of a flight of ``inputs`` that filled these outputs (:func:`fly`;
    the GPU backend's rows of its batch arrays: refexmc.campaign.cuda_backend)."""
    if mode_names is None:
        mode_names = [f"mode_{m + 1}" for m in range(inputs.modes.shape[0])]
    values = {}
    if requirements is not None and requirements.columns:
        reduced = np.empty(len(requirements.columns))
        pointing.reduce(record, inputs.fsw[L.F_CONTROL_PERIOD], reduced)
        values = {c: float(v * f) for c, v, f in zip(requirements.columns, reduced, requirements.scales, strict=True)}
    rows = int(summary[L.S_HISTORY_ROWS])
    orbit = int(inputs.mission[L.M_TRAJECTORY_MODEL]) == L.TRAJECTORY_ORBIT
    wheels = inputs.wheels.shape[0] > 0
    local = int(inputs.mission[L.M_TRAJECTORY_MODEL]) == L.TRAJECTORY_LOCAL
    window = bool(np.isfinite(inputs.mission[L.M_POINTING_FROM]))
    trajectory = int(inputs.mission[L.M_TRAJECTORY_MODEL])
    tank = int(inputs.vehicle[L.V_FEED_MODEL]) != L.FEED_CONSTANT
    attitude = bool((inputs.modes[:, L.MD_KIND] != core_modes.KIND_TRANSLATE).any())
    thrusters = int(inputs.fsw[L.F_ACTUATION]) != L.ACTUATION_WHEELS
    result = FlightResult(
        summary, pulses, history[:rows], mode_names, orbit, window, wheels, local, values, trajectory, tank, attitude,
        thrusters,
    )  # fmt: skip
    result.pointing_record = record  # the error samples at the control rate (core.pointing.Record)
    return result


def keyed_uniforms(entropy, count):
    """``numpy.random.default_rng(SeedSequence(entropy)).random(count)``, bit for bit, in one numba
    call (core.keyed_random): the campaign's keyed draws without building a generator each."""
    from refexmc.core import keyed_random

    out = np.empty(count)
    keyed_random.uniforms(keyed_random.entropy_words(entropy), out)
    return out


def keyed_uniforms_for_runs(leading, run_ids, path_key, attempt, count):
    """Row i: :func:`keyed_uniforms` of the entropy ``(*leading, run_ids[i], path_key, attempt)``;
    one numba call for a chunk's runs (core.keyed_random.uniforms_for_runs)."""
    from refexmc.core import keyed_random

    out = np.empty((len(run_ids), count))
    words = keyed_random.entropy_words(leading)
    ids = np.asarray(run_ids, dtype=np.int64)
    keyed_random.uniforms_for_runs(words, ids, np.uint64(path_key), np.int64(attempt), out)
    return out


_VECTOR_TABLES = ("vehicle", "fsw", "mission", "nav")  # the 1-d tables of RunInputs; the others are 2-d


def flight_family(inputs):
    """The vehicle family of packed inputs (``core.flight.family``): what :func:`load_kernels` takes."""
    return flight.family(inputs)


def _flight_argument_types():
    """The numba types of a flight kernel's arguments as :func:`fly` passes them (packed inputs);
    the same for every family."""
    import numba

    from refexmc.core.inputs import RunInputs

    def table(name):
        shape = (0,) if name in _VECTOR_TABLES else (0, 0)
        return np.empty(shape, dtype=np.int64 if name == "allocation" else np.float64)

    inputs = RunInputs(**{name: table(name) for name in RunInputs._fields})
    record = pointing.empty_record()
    arguments = (inputs, np.int64(0), np.int64(1), np.empty(0), np.empty(0, dtype=np.int64), np.empty((0, 0)), record)
    buffers = (np.empty(0), np.empty(0, dtype=np.int64), np.empty(0, dtype=np.uint64), np.empty(0, dtype=np.bool_))
    return tuple(numba.typeof(argument) for argument in (*arguments, *buffers))


def load_kernels(families=()):
    """Load the keyed-uniform kernels and the flight kernels of ``families`` (:func:`flight_family`
    values) from numba's disk cache, compiling what is not there, without flying: a worker loads
    the keyed kernels while the parent still prepares the campaign (numba's first load also sets
    up its target, ~0.4 s) and its campaign's family before its first run (``chunk.RunPlan``),
    so that the run costs the run only. Other families' kernels are neither loaded nor compiled.
    Compiles hold the cache's lock (``refexmc._jit.cache_lock``): two processes never save into
    one cache index at once."""
    with _jit.cache_lock():
        for family in families:
            fly_run = flight.kernel_parts(*family).fly_run
            if hasattr(fly_run, "compile") and not fly_run.signatures:  # not with REFEXMC_DISABLE_JIT
                fly_run.compile(_flight_argument_types())
        keyed_uniforms((0,), 1)
        keyed_uniforms_for_runs((0,), [0], 0, 0, 1)


# --- the entry flight (issue 24, docs/x38.md): core.entry_flight, a kernel of its own ---

ENTRY_FAILURES = {2: "floor altitude", 3: "time limit"}  # core.entry_flight.STATUS_*: why an entry failed


ENTRY_HISTORY = {  # an entry campaign's history column -> (core.entry_flight HI_* name, factor to its unit)
    "altitude_m": ("HI_ALTITUDE", 1.0),
    "speed_m_s": ("HI_SPEED", 1.0),
    "mach": ("HI_MACH", 1.0),
    "alpha_deg": ("HI_ALPHA", 180.0 / np.pi),
    "beta_deg": ("HI_BETA", 180.0 / np.pi),
    "bank_deg": ("HI_BANK", 180.0 / np.pi),
    "alpha_command_deg": ("HI_ALPHA_CMD", 180.0 / np.pi),
    "bank_command_deg": ("HI_BANK_CMD", 180.0 / np.pi),
    "flap_left_deg": ("HI_LEFT", 180.0 / np.pi),
    "flap_right_deg": ("HI_RIGHT", 180.0 / np.pi),
    "rudder_deg": ("HI_RUDDER", 180.0 / np.pi),
    "rcs_propellant_kg": ("HI_PROPELLANT", 1.0),
    "qbar_pa": ("HI_QBAR", 1.0),
    "load_factor_g": ("HI_LOAD", 1.0),
    "heat_flux_w_m2": ("HI_HEAT_FLUX", 1.0),
}


class EntryResult:
    """One entry flight's outputs, named: the summary (core.entry_flight.SU_*), the final flight
    state and the history (core.entry_flight.HI_*, one row per second)."""

    def __init__(self, summary, final_state, terminal_mach, history):
        self.summary = summary
        self.final_state = final_state
        self.terminal_mach = terminal_mach
        self.history = history

    @property
    def success(self):
        from refexmc.core import entry_flight as ef

        return int(self.summary[ef.SU_STATUS]) == ef.STATUS_TERMINAL_MACH

    @property
    def failure_reason(self):
        from refexmc.core import entry_flight as ef

        return None if self.success else ENTRY_FAILURES[int(self.summary[ef.SU_STATUS])]

    def history_columns(self, every):
        """History signals by column name, every ``every``-th row: ``t_s`` float64, ``mode`` int32
        (index into ``config.entry.MODE_NAMES``), the others float32 (7 significant digits)."""
        from refexmc.core import entry_flight as ef

        h = self.history[::every]
        columns = {"t_s": h[:, ef.HI_TIME].copy(), "mode": h[:, ef.HI_MODE].astype(np.int32)}
        for name, (slot, factor) in ENTRY_HISTORY.items():
            columns[name] = (h[:, getattr(ef, slot)] * factor).astype(np.float32)
        return columns

    def runs_values(self):
        """The entry's metrics by ``ENTRY_COLUMNS`` name (SI units; angles in degrees)."""
        from refexmc.core import entry_flight as ef

        s = self.summary
        values = (
            s[ef.SU_PROPELLANT],
            math.degrees(s[ef.SU_ALPHA_ERROR]),
            math.degrees(s[ef.SU_BETA_ERROR]),
            math.degrees(s[ef.SU_BANK_ERROR]),
            s[ef.SU_PEAK_QBAR],
            s[ef.SU_PEAK_LOAD],
            s[ef.SU_PEAK_HEAT_FLUX],
            s[ef.SU_DOWN_RANGE],
            s[ef.SU_CROSS_RANGE],
            self.terminal_mach,
            self.final_state[0],
            s[ef.SU_TIME],
            *s[ef.SU_MODE_TIME : ef.SU_MODE_TIME + 3],
        )
        return {name: float(value) for name, value in zip(ENTRY_COLUMNS, values, strict=True)}


def fly_entry(flown, initial):
    """Fly an entry (``config.entry.entry_flight_from_mission``'s vehicle and initial state)."""
    from refexmc.core import entry
    from refexmc.core import entry_flight as ef

    wk = ef.work()
    max_rows = int(math.ceil(flown.control[ef.CT_MAX_TIME_S])) + 2
    history = np.zeros((max_rows, ef.HISTORY_COLUMNS))
    summary = np.zeros(ef.SUMMARY_SIZE)
    rows = ef.fly(flown, wk, initial, history, summary)
    final = wk.state.copy()
    _, _, mach = entry.air_data(flown.model, final[: entry.ENTRY_STATE_SIZE])
    return EntryResult(summary, final, float(mach), history[:rows])


def load_entry_kernel(flown, initial):
    """Compile (or load from numba's disk cache) the entry kernel by flying an entry that ends at
    once (``flown``, ``initial``: ``config.entry.entry_flight_from_mission``'s; ``flown`` is changed)."""
    from refexmc.core import entry_flight as ef

    if hasattr(ef.fly, "signatures") and not ef.fly.signatures:
        flown.control[ef.CT_MAX_TIME_S] = 0.0
        with _jit.cache_lock():  # see load_kernels
            fly_entry(flown, initial)
