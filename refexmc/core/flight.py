"""The run loop: one flight through the mission's mode program.

Every control period (000 sec. 5) the loop takes its named steps: navigate (trajectory and
measured state) -> advance mode (the mode's guidance reference, its exit conditions, the next
mode's start; ``core.modes``) -> actuate (controller, then PWPF + allocation table and the
per-thruster switching check, or LP allocation + pulse-width modulation; valve commands) ->
record (a history row) -> integrate (the attitude over the period in segments that end on the
thrust-profile breakpoints, each split into RK4 steps of at most ``integrator_max_step_s``).
With reaction wheels, actuate hands the controller's torque to the wheels (``wheels.drive``,
held over the period) and integrate advances the wheels with the body.
With the ``orbit`` trajectory, a burn mode first steers (``orbit_flight.steer``: core.deorbit at
the guidance rate), and after the attitude the orbit is integrated over the same period
(``orbit_flight.engine_period``, ``orbit_flight.translate``: core.orbit), the thrust direction
following the body.

Compile what is flown (docs/families.md): a vehicle family (actuation, trajectory, wheels or
not) is a kernel of its own, :func:`kernel`, a closure over the family's ids. Its branches on
them are pruned before typing, so it allocates only its family's work tuples and hands the
loop ``None`` for every other family's; the loop and its steps test ``tuple is not None``, a
test numba also prunes when the argument is typed ``none``. No other family's step is typed
or compiled. All inputs a campaign may disperse arrive as array values
(``core.inputs.RunInputs``), so one compiled kernel serves every run of its family. Outputs go
to caller-owned arrays.
"""

import math
from typing import NamedTuple

import numpy as np

from refexmc._jit import jit, jit_noalloc
from refexmc.core import (
    allocation,
    arena,
    control,
    dynamics,
    elementary,
    environment,
    feed,
    guidance,
    local_flight,
    lp_allocation,
    modes,
    navigation,
    orbit,
    orbit_flight,
    pointing,
    pulse_modulation,
    quaternion,
    rcs,
    switching,
    wheels,
)
from refexmc.core.bits import lowest_bit
from refexmc.core.layout import (
    ACTUATION_LP_PWM,
    ACTUATION_PWPF_TABLE,
    ACTUATION_WHEELS,
    F_ACCEL_MARGIN,
    F_ACTUATION,
    F_CONTROL_PERIOD,
    F_CONTROLLER,
    F_INERTIA,
    F_MIN_OFF,
    F_MIN_ON,
    F_SMC_GAIN,
    F_SMC_LAYER,
    F_SMC_SLOPE,
    F_WHEEL_FRICTION_COMPENSATION,
    FAIL_HANDOVER_ANGLE,
    FAIL_MODE_TIMEOUT,
    FAIL_NON_FINITE,
    FAIL_NONE,
    FAIL_PROPELLANT,
    FAIL_TIME_LIMIT,
    FEED_BLOW_DOWN,
    FEED_CONSTANT,
    FEED_REGULATED,
    H_ALTITUDE,
    H_FUEL,
    H_MODE,
    H_OMEGA_E,
    H_OMEGA_M,
    H_PULSE,
    H_QBAR,
    H_T,
    H_TANK_PRESSURE,
    H_THETA_E,
    H_THETA_T,
    H_VALVES,
    LV_ACCEL_MAX,
    LV_KD,
    LV_KP,
    LV_REGULATOR_PRESSURE,
    LV_THRUST,
    M_BURN_DURATION,
    M_BURN_START,
    M_CONSTANT_TORQUE,
    M_EARTH_RADIUS,
    M_GG_COEFFICIENT,
    M_GG_DIRECTION,
    M_HANDOVER_ANGLE,
    M_MAX_STEP,
    M_MAX_TIME,
    M_POINTING_FROM,
    M_SEP_ATTITUDE,
    M_SEP_FLIGHT_PATH,
    M_SEP_RATES,
    M_TRAJECTORY_MODEL,
    M_TRAJECTORY_STEP,
    MD_CALIBRATION,
    MD_KIND,
    MD_LEVEL,
    MD_TIMEOUT,
    S_ALTITUDE_END,
    S_BURN_POINTING_MAX,
    S_BURN_POINTING_RMS,
    S_ENGINE_PROPELLANT_USED,
    S_FAILURE,
    S_FAILURE_MODE,
    S_FUEL_REMAINING,
    S_FUEL_USED,
    S_HISTORY_ROWS,
    S_MODES_COMPLETED,
    S_MOMENTUM_RESIDUAL,
    S_PER_MODE,
    S_POINTING_END,
    S_POINTING_MAX,
    S_POINTING_RMS,
    S_QBAR_END,
    S_RK4_STEPS,
    S_SUCCESS,
    S_T_END,
    S_THETA_HANDOVER,
    S_WHEEL_MOMENTUM_END,
    S_WHEEL_MOMENTUM_PEAK,
    S_WHEEL_SATURATED_TIME,
    S_WHEEL_TORQUE_PEAK,
    TRAJECTORY_LOCAL,
    TRAJECTORY_NONE,
    TRAJECTORY_ORBIT,
    TRAJECTORY_PLANAR_DRAG,
    V_FEED_MODEL,
    V_INERTIA,
    V_MASS,
    V_PROPELLANT,
)
from refexmc.core.status import (
    MASK_ACTIVE,
    MASK_OPEN,
    ST_CALIBRATING,
    ST_FAILURE,
    ST_FAILURE_MODE,
    ST_FUEL,
    ST_HAS_FINAL,
    ST_MODE,
    ST_MODE_START,
    ST_MODES_COMPLETED,
    ST_NODE_INDEX,
    ST_POINTING_COUNT,
    ST_POINTING_MAX,
    ST_POINTING_SUM2,
    ST_POINTING_WINDOW_COUNT,
    ST_POINTING_WINDOW_MAX,
    ST_POINTING_WINDOW_SUM2,
    ST_RK4_STEPS,
    ST_STARTED,
    ST_WHEEL_MOMENTUM_PEAK,
    ST_WHEEL_SATURATED,
    ST_WHEEL_TORQUE_PEAK,
    STATUS_SIZE,
)

_DEG = 180.0 / math.pi
_ARCSEC = 3600.0 * _DEG


class Body(NamedTuple):
    """The true attitude state and what integrating it needs."""

    x: np.ndarray  # dynamics state [q, omega]
    rk4: np.ndarray  # RK4 scratch
    inertia: np.ndarray  # truth, 3x3
    inertia_inv: np.ndarray
    torques: np.ndarray  # rows: thrust at segment start and end, RK4 step start and end, aerodynamic
    scratch: np.ndarray  # (2, 3): the gravity gradient's without reaction wheels (core.wheels.gravity_gradient)


class Trajectory(NamedTuple):
    """Planar point-mass trajectory (trajectory ``planar_drag``): RK4 nodes, Hermite-interpolated
    at the control rate into ``Work.trajectory_state``."""

    nodes: np.ndarray  # (2, 4)
    node_accels: np.ndarray  # (2, 2)
    stage: np.ndarray  # RK4 stage scratch


class Sensed(NamedTuple):
    """What the flight software knows this control period."""

    q_meas: np.ndarray
    rate_meas: np.ndarray
    now: np.ndarray  # modes.NOW_* (time in mode, altitude, climb rate, dynamic pressure)
    rng_state: np.ndarray  # navigation noise generator
    work4: np.ndarray
    knowledge: np.ndarray  # the Gauss-Markov knowledge errors (navigation.KNOWLEDGE_SIZE)


class Guide(NamedTuple):
    """Guidance state and its reference."""

    state: np.ndarray  # guidance.G_*
    q_ref: np.ndarray
    rate_ref: np.ndarray
    accel_ref: np.ndarray
    q_final: np.ndarray  # the mode's target attitude
    rotations: np.ndarray  # (3, 4) constant factors of an entry target
    work: np.ndarray  # (6, 4) scratch
    accels: np.ndarray  # (levels, 3) guidance acceleration limits (000 eq. 13)


class Actuation(NamedTuple):
    """Controller to valves: errors, commands, valve states."""

    q_error: np.ndarray
    rate_error: np.ndarray
    torque_cmd: np.ndarray
    pulse: np.ndarray  # modulator output per axis
    rotvec: np.ndarray  # history scratch
    gains: np.ndarray  # (levels, 2, 3): kp, kd per axis (contiguous rows for the controller)
    fsw_inertia: np.ndarray  # the inertia the flight software knows (000 eq. 30)
    valve_state: np.ndarray
    arms: np.ndarray  # torque arms about the actual CoM
    smc: np.ndarray  # (3, 3): sliding-mode slope, gain, boundary layer per axis (001 eq. 12)


class Modulator(NamedTuple):
    """PWPF + allocation table + switching check (actuation ``pwpf_table``)."""

    pwpf_state: np.ndarray
    row_masks: np.ndarray  # allocation table rows as bit masks
    switch_state: np.ndarray


class Work(NamedTuple):
    """The work arrays every family's flight uses."""

    body: Body
    trajectory_state: np.ndarray  # [x, z, vx, vz] of the planar trajectory now (zeros without it)
    sensed: Sensed
    guide: Guide
    actuation: Actuation
    status: np.ndarray  # ST_*
    masks: np.ndarray  # MASK_*, int64


_ACTUATIONS = (ACTUATION_PWPF_TABLE, ACTUATION_LP_PWM, ACTUATION_WHEELS)
_TRAJECTORIES = (TRAJECTORY_NONE, TRAJECTORY_PLANAR_DRAG, TRAJECTORY_ORBIT, TRAJECTORY_LOCAL)
_FEEDS = (FEED_CONSTANT, FEED_BLOW_DOWN, FEED_REGULATED)
_kernels = {}  # (actuation, trajectory, wheels, feed) -> the family's jitted fly_run
_parts = {}  # the same -> its Parts


def family(inputs):
    """The vehicle family of packed inputs: (actuation id, trajectory id, 1 with reaction wheels
    else 0, feed id), the arguments of :func:`kernel`."""
    return (
        int(inputs.fsw[F_ACTUATION]),
        int(inputs.mission[M_TRAJECTORY_MODEL]),
        1 if inputs.wheels.shape[0] > 0 else 0,
        int(inputs.vehicle[V_FEED_MODEL]),
    )


def kernel(actuation, trajectory, wheels_flown, feed_model=FEED_CONSTANT):
    """The flight kernel of one vehicle family, made once per process (disk-cached per family):
    ``run_flight(inputs, nav_seed, history_every, summary, pulse_counts, history, pointing_record)``.

    ``actuation``: layout.ACTUATION_*; ``trajectory``: layout.TRAJECTORY_*; ``wheels_flown``:
    1 when the vehicle has reaction wheels (``inputs.wheels`` has rows); ``feed_model``:
    layout.FEED_* of the rcs (core.feed). :func:`family` derives them from packed inputs.
    ``run_flight`` allocates the run's work buffers and calls the family's jitted
    :attr:`Parts.fly_run` (:func:`kernel_parts`), the function a GPU thread calls too.
    """
    return kernel_parts(actuation, trajectory, wheels_flown, feed_model).run_flight


class Parts(NamedTuple):
    """A family's flight kernel: the jitted ``fly_run`` on caller-owned flat work buffers (what
    a GPU thread calls: refexmc.campaign.cuda_backend) and ``run_flight``, which allocates them."""

    run_flight: object  # run_flight(inputs, nav_seed, history_every, summary, pulse_counts, history, pointing_record)
    fly_run: object  # fly_run(..., pointing_record, f, i, u, b) -> the buffer lengths a run needs


def kernel_parts(actuation, trajectory, wheels_flown, feed_model=FEED_CONSTANT):
    """:class:`Parts` of a family's kernel (:func:`kernel`), made once per process."""
    key = (int(actuation), int(trajectory), int(wheels_flown), int(feed_model))
    if key[0] not in _ACTUATIONS or key[1] not in _TRAJECTORIES or key[2] not in (0, 1) or key[3] not in _FEEDS:
        raise ValueError(f"no flight kernel for the family (actuation, trajectory, wheels, feed) = {key}")
    if key[1] == TRAJECTORY_LOCAL and (key[3] == FEED_CONSTANT or key[0] != ACTUATION_PWPF_TABLE):
        raise ValueError(f"the local trajectory flies a tank (rcs.feed) with actuation pwpf_table, not {key}")
    if key not in _parts:
        fly_run = _make_kernel(*key)
        _parts[key] = Parts(_allocating(fly_run), fly_run)
        _kernels[key] = fly_run
    return _parts[key]


def kernels():
    """The jitted flight kernels (:attr:`Parts.fly_run`) made in this process so far, by family."""
    return dict(_kernels)


_EMPTY = (np.zeros(0), np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.uint64), np.zeros(0, dtype=np.bool_))


def work_sizes(fly_run, inputs):
    """The lengths of the flat work buffers (float64, int64, uint64, bool) a run of ``inputs``
    needs: ``fly_run`` on empty buffers carves nothing, flies nothing and says."""
    no_history, no_record = np.zeros((0, 0)), pointing.empty_record()
    counts = np.zeros(0, dtype=np.int64)
    return fly_run(inputs, np.int64(0), np.int64(1), np.zeros(0), counts, no_history, no_record, *_EMPTY)


def _allocating(fly_run):
    """``run_flight``: ``fly_run`` on work buffers allocated once per flight."""

    def run_flight(inputs, nav_seed, history_every, summary, pulse_counts, history, pointing_record):
        nf, ni, nu, nb = fly_run(inputs, nav_seed, history_every, summary, pulse_counts, history, pointing_record,
                                 *_EMPTY)  # fmt: skip
        buffers = np.empty(nf), np.empty(ni, dtype=np.int64), np.empty(nu, dtype=np.uint64), np.empty(nb, dtype=bool)
        fly_run(inputs, nav_seed, history_every, summary, pulse_counts, history, pointing_record, *buffers)

    return run_flight


def _make_kernel(actuation, trajectory, wheels_flown, feed_model):
    """:func:`kernel_parts`' ``fly_run``: a closure over the family's ids only (numba's disk cache
    keys a closure by its cell contents, so that each family's kernel is cached apart), compiled
    with ``refexmc._jit.jit``. Its tests of the ids are constants numba prunes before typing."""
    ACTUATION = actuation  # noqa: N806 - compile-time constants of the closure
    TRAJECTORY = trajectory  # noqa: N806
    WHEELS = wheels_flown  # noqa: N806
    FEED = feed_model  # noqa: N806

    def fly_run(inputs, nav_seed, history_every, summary, pulse_counts, history, pointing_record, f, i, u, b):
        """Fly ``inputs`` (``core.inputs.RunInputs``) of this kernel's family on the caller's flat
        work buffers ``f`` (float64), ``i`` (int64), ``u`` (uint64), ``b`` (bool), zeroed here
        (core.arena); fill ``summary``, ``pulse_counts``, ``history`` and the pointing
        requirements' samples (``core.pointing.Record``). Returns the lengths the buffers need;
        when one is shorter (e.g. empty), nothing is written and nothing flies.

        ``summary`` has ``layout.summary_size(n_modes)`` slots; ``history`` one row per
        ``history_every`` control steps (plus the final state) until it is full;
        ``summary[S_HISTORY_ROWS]`` says how many rows were written.
        """
        work, fa, ia, ua = _carve_work(inputs, f, i, u)
        ba = 0
        if ACTUATION == ACTUATION_PWPF_TABLE:
            table, fa, ia = _carve_modulator(inputs, f, fa, i, ia)
        else:
            table = None
        if ACTUATION == ACTUATION_LP_PWM:
            opt, fa, ia, ba = lp_allocation.carve_optimiser(inputs.thrusters.shape[0], f, fa, i, ia, b, ba)
        else:
            opt = None
        if WHEELS == 1:
            wh, fa = wheels.carve_plant(inputs.wheels, f, fa)
        else:
            wh = None
        if TRAJECTORY == TRAJECTORY_PLANAR_DRAG:
            traj, fa = _carve_trajectory(f, fa)
        else:
            traj = None
        if TRAJECTORY == TRAJECTORY_ORBIT:
            orb, fa = orbit_flight.carve_work(f, fa)
        else:
            orb = None
        if ACTUATION == ACTUATION_WHEELS:  # no thruster fires: no valve step is compiled
            fire = None
        else:
            fire = True
        if FEED == FEED_CONSTANT:  # core.feed is compiled for a blow-down or regulated tank only
            tank = None
        else:
            tank, fa = feed.carve_tank(f, fa)
        if TRAJECTORY == TRAJECTORY_LOCAL:
            loc, fa = local_flight.carve_work(f, fa)
        else:
            loc = None
        if f.shape[0] < fa or i.shape[0] < ia or u.shape[0] < ua or b.shape[0] < ba:
            return fa, ia, ua, ba
        arena.clear(f, i, u, b)
        _fly(
            inputs, nav_seed, history_every, summary, pulse_counts, history, work, fire, table, opt, wh, traj, orb,
            tank, loc, pointing_record,
        )  # fmt: skip
        return fa, ia, ua, ba

    return jit(fly_run)


@jit
def _carve_work(inputs, f, i, u):
    """The :class:`Work` every family uses, as views of ``f``, ``i``, ``u`` (core.arena); the cursors after."""
    n_thr, n_levels = inputs.thrusters.shape[0], inputs.levels.shape[0]
    fa, ia, ua = 0, 0, 0
    x, fa = arena.vector(f, fa, dynamics.STATE_SIZE)
    rk4, fa = arena.matrix(f, fa, 8, dynamics.STATE_SIZE)
    inertia, fa = arena.matrix(f, fa, 3, 3)
    inertia_inv, fa = arena.matrix(f, fa, 3, 3)
    torques, fa = arena.matrix(f, fa, 5, 3)
    body_scratch, fa = arena.matrix(f, fa, 2, 3)
    trajectory_state, fa = arena.vector(f, fa, environment.TRAJECTORY_STATE_SIZE)
    q_meas, fa = arena.vector(f, fa, 4)
    rate_meas, fa = arena.vector(f, fa, 3)
    now, fa = arena.vector(f, fa, modes.NOW_SIZE)
    rng_state, ua = arena.vector(u, ua, 1)
    work4, fa = arena.vector(f, fa, 4)
    knowledge, fa = arena.vector(f, fa, navigation.KNOWLEDGE_SIZE)
    g_state, fa = arena.vector(f, fa, guidance.GUIDANCE_STATE_SIZE)
    q_ref, fa = arena.vector(f, fa, 4)
    rate_ref, fa = arena.vector(f, fa, 3)
    accel_ref, fa = arena.vector(f, fa, 3)
    q_final, fa = arena.vector(f, fa, 4)
    rotations, fa = arena.matrix(f, fa, 3, 4)
    g_work, fa = arena.matrix(f, fa, 6, 4)
    accels, fa = arena.matrix(f, fa, n_levels, 3)
    q_error, fa = arena.vector(f, fa, 4)
    rate_error, fa = arena.vector(f, fa, 3)
    torque_cmd, fa = arena.vector(f, fa, 3)
    pulse, fa = arena.vector(f, fa, 3)
    rotvec, fa = arena.vector(f, fa, 3)
    gains, fa = arena.cube(f, fa, n_levels, 2, 3)
    fsw_inertia, fa = arena.matrix(f, fa, 3, 3)
    valve_state, fa = arena.matrix(f, fa, n_thr, rcs.VALVE_STATE_SIZE)
    arms, fa = arena.matrix(f, fa, n_thr, 3)
    smc, fa = arena.matrix(f, fa, 3, 3)
    status, fa = arena.vector(f, fa, STATUS_SIZE)
    masks, ia = arena.vector(i, ia, 2)
    work = Work(
        Body(x, rk4, inertia, inertia_inv, torques, body_scratch),
        trajectory_state,
        Sensed(q_meas, rate_meas, now, rng_state, work4, knowledge),
        Guide(g_state, q_ref, rate_ref, accel_ref, q_final, rotations, g_work, accels),
        Actuation(q_error, rate_error, torque_cmd, pulse, rotvec, gains, fsw_inertia, valve_state, arms, smc),
        status,
        masks,
    )
    return work, fa, ia, ua


@jit
def _carve_modulator(inputs, f, fa, i, ia):
    """The pwpf_table family's :class:`Modulator` as views (core.arena); the cursors after."""
    pwpf_state, fa = arena.matrix(f, fa, 3, pulse_modulation.PWPF_STATE_SIZE)
    row_masks, ia = arena.vector(i, ia, inputs.allocation.shape[0])
    switch_state, fa = arena.matrix(f, fa, inputs.thrusters.shape[0], switching.SWITCH_STATE_SIZE)
    return Modulator(pwpf_state, row_masks, switch_state), fa, ia


@jit
def _carve_trajectory(f, fa):
    """The planar_drag family's :class:`Trajectory` as views (core.arena); the cursor after."""
    nodes, fa = arena.matrix(f, fa, 2, environment.TRAJECTORY_STATE_SIZE)
    node_accels, fa = arena.matrix(f, fa, 2, 2)
    stage, fa = arena.vector(f, fa, environment.TRAJECTORY_STATE_SIZE)
    return Trajectory(nodes, node_accels, stage), fa


@jit_noalloc
def _start(
    inputs, nav_seed, summary, pulse_counts, body, traj_state, sensed, guide, act, status, masks, fire, table, wh,
    traj,
):  # fmt: skip
    """Initial state: body x along the velocity, wings level, then the separation error; the
    wheels' momenta and the total angular momentum. ``table``, ``wh``, ``traj``: the family's
    work tuples, or None (:func:`kernel`)."""
    vehicle, fsw, mission = inputs.vehicle, inputs.fsw, inputs.mission
    for i in range(3):
        for j in range(3):
            body.inertia[i, j] = vehicle[V_INERTIA + 3 * i + j]
            act.fsw_inertia[i, j] = fsw[F_INERTIA + 3 * i + j]
    dynamics.invert_3x3(body.inertia, body.inertia_inv)
    for i in range(3):
        act.smc[0, i] = fsw[F_SMC_SLOPE + i]
        act.smc[1, i] = fsw[F_SMC_GAIN + i]
        act.smc[2, i] = fsw[F_SMC_LAYER + i]
    if table is not None:
        allocation.table_masks(inputs.allocation, table.row_masks)
    margin = fsw[F_ACCEL_MARGIN]
    levels = inputs.levels
    for lv in range(levels.shape[0]):
        for i in range(3):
            act.gains[lv, 0, i] = levels[lv, LV_KP + i]
            act.gains[lv, 1, i] = levels[lv, LV_KD + i]
            guide.accels[lv, i] = margin * levels[lv, LV_ACCEL_MAX + i]
    sensed.rng_state[0] = np.uint64(nav_seed)
    navigation.start(inputs.nav, fsw[F_CONTROL_PERIOD], sensed.rng_state, sensed.knowledge)

    if traj is not None:  # trajectory planar_drag
        span = mission[M_TRAJECTORY_STEP]
        environment.initial_state(mission, traj.nodes[1])
        traj.node_accels[1, 0], traj.node_accels[1, 1] = environment.acceleration(
            mission, vehicle, inputs.atmosphere, traj.nodes[1]
        )
        environment.advance_nodes(mission, vehicle, inputs.atmosphere, traj.nodes, traj.node_accels, span, traj.stage)
        environment.interpolate(
            traj.nodes[0], traj.node_accels[0], traj.nodes[1], traj.node_accels[1], span, 0.0, traj_state
        )
    else:
        for k in range(traj_state.shape[0]):
            traj_state[k] = 0.0
    tmp4, sep_q = sensed.work4, guide.q_ref  # q_ref is free until the first mode with a reference
    quaternion.from_rotation_vector(0.0, mission[M_SEP_FLIGHT_PATH], 0.0, tmp4)
    sep = mission[M_SEP_ATTITUDE : M_SEP_ATTITUDE + 3]
    quaternion.from_rotation_vector(sep[0], sep[1], sep[2], sep_q)
    quaternion.multiply(tmp4, sep_q, body.x[0:4])
    for i in range(3):
        body.x[4 + i] = mission[M_SEP_RATES + i]
    if fire is not None:  # thrusters fire (with actuation wheels they never do: no valve is touched)
        rcs.reset(act.valve_state)
        rcs.torque_arms(inputs.thrusters, vehicle, act.arms)
    if table is not None:
        pulse_modulation.reset(table.pwpf_state)
        switching.reset(table.switch_state)
    for i in range(pulse_counts.shape[0]):
        pulse_counts[i] = 0
    for k in range(summary.shape[0]):
        summary[k] = 0.0
    for k in range(STATUS_SIZE):
        status[k] = 0.0
    masks[MASK_OPEN] = 0
    masks[MASK_ACTIVE] = 0
    status[ST_FUEL] = vehicle[V_PROPELLANT]
    if wh is not None:
        gg = M_GG_DIRECTION
        wheels.start(wh, body.inertia, body.x, mission[M_GG_COEFFICIENT], mission[gg : gg + 3])


@jit_noalloc(force_inline=True)
def _navigate(mission, vehicle, atmosphere, nav, x, traj_state, traj, orb, sensed, status, t, loc, tank):
    """Trajectory at ``t`` (new RK4 nodes as needed), flight conditions, measured attitude and
    rates. ``traj``: the planar trajectory's work (or None), ``orb`` the orbit's (or None)."""
    altitude, climb, qbar = 0.0, 0.0, 0.0
    if orb is not None:  # integrated with the attitude, period by period (orbit_flight.translate)
        altitude = orbit.radius(orb.state) - mission[M_EARTH_RADIUS]
        climb = orbit.climb_rate(orb.state)
    elif traj is not None:
        span = mission[M_TRAJECTORY_STEP]
        node_index = status[ST_NODE_INDEX]
        while t >= (node_index + 1) * span - 1e-9:
            environment.advance_nodes(mission, vehicle, atmosphere, traj.nodes, traj.node_accels, span, traj.stage)
            node_index += 1
        status[ST_NODE_INDEX] = node_index
        environment.interpolate(
            traj.nodes[0],
            traj.node_accels[0],
            traj.nodes[1],
            traj.node_accels[1],
            span,
            t - node_index * span,
            traj_state,
        )
        altitude, climb, qbar = environment.flight_conditions(mission, atmosphere, traj_state)
    sensed.now[modes.NOW_TIME_IN_MODE] = t - status[ST_MODE_START]
    sensed.now[modes.NOW_ALTITUDE] = altitude
    sensed.now[modes.NOW_CLIMB] = climb
    sensed.now[modes.NOW_QBAR] = qbar
    sensed.now[modes.NOW_TIME] = t
    if loc is not None:
        local_flight.navigate(nav, loc, tank, sensed.rng_state, sensed.now)
    calibrating = status[ST_CALIBRATING]
    navigation.measure(
        x, nav, calibrating, sensed.rng_state, sensed.knowledge, sensed.q_meas, sensed.rate_meas, sensed.work4
    )


@jit_noalloc(force_inline=True)
def _reference(row, mission, vehicle, atmosphere, traj_state, t, guide):
    """The guidance reference of the mode of table row ``row`` at ``t`` (core.modes.reference)."""
    return modes.reference(
        row,
        mission,
        vehicle,
        atmosphere,
        traj_state,
        t,
        guide.state,
        guide.q_final,
        guide.rotations,
        guide.q_ref,
        guide.rate_ref,
        guide.accel_ref,
        guide.work,
    )


@jit_noalloc
def _start_mode(row, mission, traj_state, sensed, guide, status, t):
    """Start the guidance of the mode of table row ``row`` at ``t`` (core.modes.start); its t1, or 0."""
    has_final = modes.start(
        row,
        mission,
        traj_state,
        t,
        sensed.q_meas,
        sensed.rate_meas,
        guide.accels[int(row[MD_LEVEL])],
        guide.state,
        guide.q_final,
        status[ST_HAS_FINAL] != 0.0,
        guide.rotations,
        guide.work,
    )
    status[ST_HAS_FINAL] = 1.0 if has_final else 0.0
    return guide.state[guidance.G_T1] if modes.has_profile(int(row[MD_KIND])) else 0.0


@jit_noalloc(force_inline=True)
def _advance_mode(program, exits, mission, vehicle, atmosphere, traj_state, sensed, guide, status, summary, t):
    """Leave the mode whose exit conditions hold and start the next; fail a mode past its timeout.

    The reference of the mode flown is computed first (exit conditions may compare against it)
    and again for a mode that starts; when the program is done the last mode's guidance goes on.
    Returns ``(attitude_controlled, has_attitude_reference)``.
    """
    n_modes = program.shape[0]
    mode = int(status[ST_MODE])
    if status[ST_STARTED] == 0.0:  # the first mode starts at the first control step
        status[ST_STARTED] = 1.0
        summary[S_PER_MODE + n_modes + mode] = _start_mode(program[mode], mission, traj_state, sensed, guide, status, t)
    q_ref, rate_ref = guide.q_ref, guide.rate_ref
    controlled, has_reference = _reference(
        program[min(mode, n_modes - 1)], mission, vehicle, atmosphere, traj_state, t, guide
    )
    if mode == n_modes:
        return controlled, has_reference
    row = program[mode]
    q_target = guide.q_final if int(row[MD_KIND]) == modes.KIND_SLEW else q_ref
    t1 = guide.state[guidance.G_T1]
    if modes.exit_reached(row, exits, sensed.now, t1, sensed.rate_meas, rate_ref, sensed.q_meas, q_target):
        mode += 1
        status[ST_MODE] = mode
        status[ST_MODES_COMPLETED] += 1
        status[ST_MODE_START] = t
        if mode < n_modes:
            row = program[mode]
            summary[S_PER_MODE + n_modes + mode] = _start_mode(row, mission, traj_state, sensed, guide, status, t)
            controlled, has_reference = _reference(row, mission, vehicle, atmosphere, traj_state, t, guide)
    elif sensed.now[modes.NOW_TIME_IN_MODE] > row[MD_TIMEOUT]:
        status[ST_FAILURE] = FAIL_MODE_TIMEOUT
        status[ST_FAILURE_MODE] = mode
    return controlled, has_reference


@jit_noalloc(force_inline=True)
def _actuate(
    fsw, levels, thrusters, sensed, guide, act, table, opt, masks, t, level, active, controlled, has_reference,
    pulse_counts, translation,
):  # fmt: skip
    """Controller, actuation (pulse modulation + allocation), switching check and valve commands.

    ``active``: False when the mode is locked, the program done or the run failed. ``table``:
    the PWPF + allocation table's work (or None), ``opt`` the LP allocation's (or None); with
    neither the wheels take ``act.torque_cmd`` (``wheels.drive``). ``translation`` >= 0: the
    valves a translation law wants (core.local_flight.desired) instead of the table's.
    """
    actuation = int(fsw[F_ACTUATION])
    if has_reference:
        control.control_errors(
            sensed.q_meas, sensed.rate_meas, guide.q_ref, guide.rate_ref, act.q_error, act.rate_error
        )
    else:
        for i in range(4):
            act.q_error[i] = 0.0
        act.q_error[3] = 1.0
        for i in range(3):
            act.rate_error[i] = sensed.rate_meas[i] - guide.rate_ref[i]
    if not active:
        desired = 0
        for i in range(3):
            act.pulse[i] = 0.0
            act.torque_cmd[i] = 0.0
    else:
        control.torque_command(
            int(fsw[F_CONTROLLER]),
            act.q_error,
            act.rate_error,
            sensed.rate_meas,
            guide.accel_ref,
            act.gains[level, 0],
            act.gains[level, 1],
            act.smc,
            act.fsw_inertia,
            controlled,
            act.torque_cmd,
        )
        if table is not None:
            desired = allocation.thruster_commands(
                actuation, fsw, levels[level], act.torque_cmd, table.pwpf_state, table.row_masks, t, act.pulse
            )
            if translation >= 0:
                desired = translation
    if opt is not None:
        lp_allocation.pulse_width(fsw, levels, thrusters, act, opt, masks, t, level, active, pulse_counts)
    if table is None:  # lp_pwm, or the wheels take act.torque_cmd (wheels.drive)
        return
    valves_open = masks[MASK_OPEN]
    opened, closed = switching.enforce(table.switch_state, desired, valves_open, t, fsw[F_MIN_ON], fsw[F_MIN_OFF])
    masks[MASK_OPEN] = (valves_open | opened) & ~closed
    masks[MASK_ACTIVE] |= opened | closed
    m = opened | closed
    while m != 0:
        i = lowest_bit(m)
        m &= m - 1
        rcs.command(act.valve_state, thrusters, i, (opened >> i) & 1 != 0, t, level)
        if (opened >> i) & 1:
            pulse_counts[i] += 1


@jit_noalloc
def _pointing(q, q_ref, scratch, out):
    """True attitude against the reference: the error's rotation vector (rad, body axes) in ``out``;
    returns its angle. ``scratch``: 4 values."""
    quaternion.conj_multiply(q_ref, q, scratch)
    if scratch[3] < 0.0:
        for i in range(4):
            scratch[i] = -scratch[i]
    quaternion.to_rotation_vector(scratch, out)
    return math.sqrt(out[0] * out[0] + out[1] * out[1] + out[2] * out[2])


@jit_noalloc
def _record(history, row, t, mode, theta_t, controlled, fuel_fraction, valves, rate_meas, act, now):
    """One history row (``mode``: the index of the mode flown)."""
    rotvec = act.rotvec
    history[row, H_T] = t
    history[row, H_MODE] = mode
    history[row, H_THETA_T] = theta_t * _DEG
    rate_squared = rate_meas[0] * rate_meas[0] + rate_meas[1] * rate_meas[1] + rate_meas[2] * rate_meas[2]
    history[row, H_OMEGA_M] = math.sqrt(rate_squared) * _DEG
    if controlled:
        quaternion.to_rotation_vector(act.q_error, rotvec)
    for i in range(3):
        history[row, H_THETA_E + i] = rotvec[i] * _DEG if controlled else math.nan
        history[row, H_OMEGA_E + i] = act.rate_error[i] * _DEG
        history[row, H_PULSE + i] = act.pulse[i]
    history[row, H_FUEL] = fuel_fraction
    history[row, H_VALVES] = valves & 0xFFFFFFFF  # two exact halves of the 63-bit mask
    history[row, H_VALVES + 1] = (valves >> 32) & 0xFFFFFFFF
    history[row, H_ALTITUDE] = now[modes.NOW_ALTITUDE]
    history[row, H_QBAR] = now[modes.NOW_QBAR]


@jit_noalloc(force_inline=True)
def _integrate(
    mission, vehicle, thrusters, thrust, max_step, dt, body, act, fire, wh, orb, status, masks, qbar, t, level, tank,
    loc,
):  # fmt: skip
    """Integrate the attitude over one control period, segment by segment, ``thrust`` (N) being the
    level's nominal thrust, with the orbit (``orb`` not None) a further disturbance torque
    ``orb.torque`` (its gravity gradient and main engine), plus the mission's constant torque;
    with reaction wheels (``wh`` not None) the wheels' momenta too (core.wheels), the gravity
    gradient of 001 eq. 11 then evaluated at every RK4 stage (else held over the period).
    ``fire``: True when thrusters fire, None with actuation wheels (no thrust: one coasting
    segment per period). ``tank``: the feed's work (core.feed), None with the constant feed,
    whose thrust is ``thrust``. ``loc``: the local trajectory (core.local_flight) or None: its
    position and velocity advance segment by segment with the thrusters' force.
    Returns True when the propellant ran out."""
    n_thr = thrusters.shape[0]
    gg_coefficient = mission[M_GG_COEFFICIENT]
    # Segments up to this long are one RK4 step: their ceil(span / max_step - 1e-9) is 1 (the
    # division and subtraction are monotone and this bound divides to 1 + 1e-10 -+ 1 ulp).
    one_step_limit = max_step * (1.0 + 1e-10)
    tau0, tau1, tau_a, tau_b, aero = body.torques[0], body.torques[1], body.torques[2], body.torques[3], body.torques[4]
    environment.aerodynamic_torque(vehicle, qbar, aero)
    if orb is not None:
        for i in range(3):
            aero[i] += orb.torque[i]
    for i in range(3):
        aero[i] += mission[M_CONSTANT_TORQUE + i]
    if gg_coefficient != 0.0 and wh is None:
        gg = M_GG_DIRECTION
        wheels.gravity_gradient(body.x[0:4], gg_coefficient, mission[gg : gg + 3], body.inertia, body.scratch, aero)
    fuel = status[ST_FUEL]
    valves_active = masks[MASK_ACTIVE]
    rk4_steps = 0
    t_seg = t
    t_end = t + dt
    exhausted = False
    while t_seg < t_end - 1e-12:
        if fire is not None:
            valves_active = rcs.update(act.valve_state, thrusters, n_thr, t_seg, level, valves_active)
            active = valves_active != 0
            if active:
                t_next = rcs.next_breakpoint(act.valve_state, n_thr, t_seg, t_end, valves_active)
            else:  # coasting: the whole rest of the period is one thrust-free segment
                t_next = t_end
            if active and fuel > 0.0:
                if tank is not None:  # thrust and gas follow the tank pressure (core.feed)
                    pressure_start = tank.state[feed.TK_PRESSURE]
                    impulse = feed.segment(
                        act.valve_state, thrusters, vehicle, act.arms, tank, t_seg, t_next, tau0, tau1, valves_active
                    )  # here: the gas used (kg)
                    if loc is not None:
                        local_flight.segment_force(
                            vehicle, act.valve_state, thrusters, tank, pressure_start, t_seg, t_next,
                            valves_active, loc,
                        )  # fmt: skip
                else:
                    impulse = rcs.segment_thrust(
                        act.valve_state, thrusters, vehicle, act.arms, thrust, t_seg, t_next, tau0, tau1, valves_active
                    )
            else:
                impulse = 0.0
                for i in range(3):
                    tau0[i] = 0.0
                    tau1[i] = 0.0
                if loc is not None:
                    local_flight.no_force(loc)
        else:  # no thruster fires: one thrust-free segment
            t_next = t_end
            impulse = 0.0
            for i in range(3):
                tau0[i] = 0.0
                tau1[i] = 0.0
        span_seg = t_next - t_seg
        if span_seg <= one_step_limit:  # the general branch gives n_sub = 1, h = span_seg
            n_sub = 1
            h = span_seg
        else:
            n_sub = int(math.ceil(span_seg / max_step - 1e-9))
            if n_sub < 1:
                n_sub = 1
            h = span_seg / n_sub
        fb = 0.0
        for j in range(n_sub):
            fa = fb  # j / n_sub
            fb = 1.0 if j + 1 == n_sub else (j + 1) / n_sub
            for i in range(3):
                tau_a[i] = aero[i] + tau0[i] + (tau1[i] - tau0[i]) * fa
                tau_b[i] = aero[i] + tau0[i] + (tau1[i] - tau0[i]) * fb
            if wh is not None:  # sub-steps end where a wheel crosses its friction's zero-speed zone
                rk4_steps += wheels.step(body.x, h, tau_a, tau_b, wh)
            else:
                dynamics.rk4_step(body.x, h, tau_a, tau_b, body.inertia, body.inertia_inv, body.rk4)
                rk4_steps += 1
        if loc is not None:
            local_flight.advance(mission, loc, body.x[0:4], span_seg)
        if tank is not None:  # the gas left is the tank's, P V / (R T) (002 eq. 1)
            fuel = feed.gas(tank)
        elif fire is not None:  # without thrust: no propellant used
            fuel -= rcs.propellant_for_impulse(vehicle, impulse)
            if fuel <= 0.0 and impulse > 0.0:
                fuel = 0.0
                exhausted = True
        t_seg = t_next
    status[ST_FUEL] = fuel
    masks[MASK_ACTIVE] = valves_active
    status[ST_RK4_STEPS] += rk4_steps
    return exhausted


@jit_noalloc
def _fly(
    inputs, nav_seed, history_every, summary, pulse_counts, history, w, fire, table, opt, wh, traj, orb, tank, loc,
    pointing_record,
):  # fmt: skip
    """The run loop of a :func:`kernel`'s ``run_flight`` on the work arrays it allocated (no
    allocation, no reference counting: see ``refexmc._jit.jit_noalloc``). Each step gets the
    arrays it uses only: every further array argument costs compile time (numba types each one).

    ``fire`` (True where thrusters fire, None with actuation wheels), ``table``
    (PWPF + allocation table), ``opt`` (LP allocation), ``wh`` (reaction wheels), ``traj``
    (planar trajectory), ``orb`` (orbit trajectory), ``tank`` (blow-down or regulated feed),
    ``loc`` (local trajectory): the family's work, None for the others.
    Every step of a family runs under ``if <its work> is not None``, which numba prunes before
    typing where the argument is None: one compiled loop per family."""
    body, traj_state, sensed, guide, act, status, masks = (
        w.body,
        w.trajectory_state,
        w.sensed,
        w.guide,
        w.actuation,
        w.status,
        w.masks,
    )
    vehicle, thrusters, fsw, mission = inputs.vehicle, inputs.thrusters, inputs.fsw, inputs.mission
    program, exits, atmosphere = inputs.modes, inputs.exits, inputs.atmosphere
    _start(
        inputs, nav_seed, summary, pulse_counts, body, traj_state, sensed, guide, act, status, masks, fire, table,
        wh, traj,
    )  # fmt: skip
    if orb is not None:
        orbit_flight.start(mission, vehicle, orb, status, summary)
    cutoff = mission[M_BURN_START] + mission[M_BURN_DURATION]
    if opt is not None:
        allocation.nominal_arms(thrusters, opt.arms)
    n_modes = program.shape[0]
    n_thr = thrusters.shape[0]
    dt = fsw[F_CONTROL_PERIOD]
    max_step = mission[M_MAX_STEP]
    propellant0 = vehicle[V_PROPELLANT]
    if tank is not None:  # the gas in the tank, P0 V / (R T) of the dispersed tank (002 eq. 1)
        feed.start(vehicle, tank)
        propellant0 = feed.gas(tank)
        status[ST_FUEL] = propellant0
        if loc is not None:
            local_flight.start(mission, inputs.modes, loc, tank)
    pointing_from = mission[M_POINTING_FROM]
    window_error = act.rotvec  # free between history rows (_record fills it when it writes one)
    theta_handover = math.nan
    rows = 0
    step = 0
    t = 0.0
    while True:
        t = step * dt
        _navigate(mission, vehicle, atmosphere, inputs.nav, body.x, traj_state, traj, orb, sensed, status, t, loc, tank)
        controlled, has_reference = _advance_mode(
            program, exits, mission, vehicle, atmosphere, traj_state, sensed, guide, status, summary, t
        )
        mode = int(status[ST_MODE])
        done = mode == n_modes
        flown = min(mode, n_modes - 1)  # when done, the last mode's guidance goes on
        if status[ST_FAILURE] == FAIL_NONE and not done and t >= mission[M_MAX_TIME]:
            status[ST_FAILURE] = FAIL_TIME_LIMIT

        # total angle error: true attitude to the mode's final reference attitude (000 sec. 6.1)
        finished = done or status[ST_FAILURE] != FAIL_NONE
        record = (step % history_every == 0 or finished) and rows < history.shape[0]
        theta_t = math.nan
        if (record or done) and has_reference:
            target = guide.q_final if int(program[flown, MD_KIND]) == modes.KIND_SLEW else guide.q_ref
            theta_t = quaternion.angle_between(body.x[0:4], target)
        if done:
            theta_handover = theta_t
            if theta_t > mission[M_HANDOVER_ANGLE]:
                status[ST_FAILURE] = FAIL_HANDOVER_ANGLE

        level = int(program[flown, MD_LEVEL])
        kind = int(program[flown, MD_KIND])
        active = not done and status[ST_FAILURE] == FAIL_NONE and kind != modes.KIND_LOCKED
        burn_mode = False
        if orb is not None:
            burn_mode = active and kind == modes.KIND_BURN
            if burn_mode:
                firing = mission[M_BURN_START] <= t < cutoff
                orbit_flight.steer(
                    inputs.nominal, fsw, inputs.nav, vehicle, body.x, orb, guide, sensed.rng_state, status, t, firing
                )
        translation = -1
        if loc is not None:
            local_flight.target(program[flown], loc)
            if active and kind == modes.KIND_TRANSLATE:
                translation = local_flight.desired(fsw, mission, loc, sensed.q_meas)
        _actuate(
            fsw,
            inputs.levels,
            thrusters,
            sensed,
            guide,
            act,
            table,
            opt,
            masks,
            t,
            level,
            active,
            controlled,
            has_reference,
            pulse_counts,
            translation,
        )
        if wh is not None:
            compensate = fsw[F_WHEEL_FRICTION_COMPENSATION] != 0.0
            wheels.drive(
                inputs.wheel_distribution, wh, sensed.rate_meas, body.x[4:7], act.torque_cmd, compensate, active,
                status, dt,
            )  # fmt: skip
        if t >= pointing_from and has_reference:  # true attitude against the reference (001: PE)
            angle = _pointing(body.x[0:4], guide.q_ref, sensed.work4, window_error)
            for i in range(3):
                status[ST_POINTING_WINDOW_SUM2 + i] += window_error[i] * window_error[i]
            status[ST_POINTING_WINDOW_COUNT] += 1.0
            status[ST_POINTING_WINDOW_MAX] = elementary.larger(status[ST_POINTING_WINDOW_MAX], angle)
        if pointing_record.table.shape[0] > 0:  # pointing requirements (core.pointing), at the control rate
            pointing.record(pointing_record, body.x[0:4], guide.q_ref, sensed.q_meas, has_reference, flown, t)

        finished = done or status[ST_FAILURE] != FAIL_NONE
        if record:
            valves_open = 0
            if fire is not None:
                valves_open = rcs.open_mask(act.valve_state, n_thr, t)
            fraction = status[ST_FUEL] / propellant0
            _record(
                history, rows, t, flown, theta_t, controlled, fraction, valves_open, sensed.rate_meas, act, sensed.now
            )
            if tank is not None:
                history[rows, H_TANK_PRESSURE] = tank.state[feed.TK_PRESSURE]
            if loc is not None:
                local_flight.record(loc, history[rows])
            if wh is not None:
                wheels.record(wh, body.x[4:7], history[rows])
            rows += 1
        if finished:
            break

        qbar = sensed.now[modes.NOW_QBAR]
        thrust = inputs.levels[level, LV_THRUST]
        if tank is not None:  # a regulated feed holds the level's set pressure (core.feed)
            tank.state[feed.TK_REGULATOR] = inputs.levels[level, LV_REGULATOR_PRESSURE]
        if orb is not None:
            orbit_flight.engine_period(mission, vehicle, body.inertia, body.x, orb, status, t, dt, burn_mode)
        exhausted = _integrate(
            mission, vehicle, thrusters, thrust, max_step, dt, body, act, fire, wh, orb, status, masks, qbar, t, level,
            tank, loc,
        )  # fmt: skip
        if wh is not None:
            peak = wheels.largest_relative_momentum(wh.table, wh.h, body.x[4:7])
            status[ST_WHEEL_MOMENTUM_PEAK] = elementary.larger(status[ST_WHEEL_MOMENTUM_PEAK], peak)
        if orb is not None:
            orbit_flight.translate(mission, vehicle, body.x, orb, status, summary, t, dt)
        summary[S_PER_MODE + mode] += dt
        if program[mode, MD_CALIBRATION] != 0.0:
            status[ST_CALIBRATING] += dt
        step += 1
        if exhausted:
            status[ST_FAILURE] = FAIL_PROPELLANT
        finite = True
        for i in range(dynamics.STATE_SIZE):
            if not math.isfinite(body.x[i]):
                finite = False
        if not finite:
            status[ST_FAILURE] = FAIL_NON_FINITE

    fuel = status[ST_FUEL]
    failure = status[ST_FAILURE]
    summary[S_SUCCESS] = 1.0 if failure == FAIL_NONE and int(status[ST_MODE]) == n_modes else 0.0
    summary[S_FAILURE] = failure
    summary[S_FAILURE_MODE] = status[ST_FAILURE_MODE]
    summary[S_FUEL_REMAINING] = fuel / propellant0
    summary[S_FUEL_USED] = propellant0 - fuel
    summary[S_T_END] = t
    summary[S_THETA_HANDOVER] = theta_handover * _DEG
    summary[S_MODES_COMPLETED] = status[ST_MODES_COMPLETED]
    summary[S_ALTITUDE_END] = sensed.now[modes.NOW_ALTITUDE]
    summary[S_QBAR_END] = sensed.now[modes.NOW_QBAR]
    summary[S_RK4_STEPS] = status[ST_RK4_STEPS]
    summary[S_HISTORY_ROWS] = rows
    for i in range(3):
        summary[S_POINTING_END + i] = math.nan
        summary[S_POINTING_RMS + i] = math.nan
    summary[S_POINTING_MAX] = math.nan
    if has_reference:
        _pointing(body.x[0:4], guide.q_ref, sensed.work4, window_error)
        for i in range(3):
            summary[S_POINTING_END + i] = window_error[i] * _ARCSEC
    count = status[ST_POINTING_WINDOW_COUNT]
    if count > 0.0:
        for i in range(3):
            summary[S_POINTING_RMS + i] = math.sqrt(status[ST_POINTING_WINDOW_SUM2 + i] / count) * _ARCSEC
        summary[S_POINTING_MAX] = status[ST_POINTING_WINDOW_MAX] * _ARCSEC
    if wh is not None:
        summary[S_WHEEL_MOMENTUM_PEAK] = status[ST_WHEEL_MOMENTUM_PEAK]
        summary[S_WHEEL_MOMENTUM_END] = wheels.largest_relative_momentum(wh.table, wh.h, body.x[4:7])
        summary[S_WHEEL_TORQUE_PEAK] = status[ST_WHEEL_TORQUE_PEAK]
        summary[S_WHEEL_SATURATED_TIME] = status[ST_WHEEL_SATURATED]
        summary[S_MOMENTUM_RESIDUAL] = wheels.momentum_residual(body.x, wh)
    if loc is not None:
        local_flight.finish(mission, loc, tank, summary)
    if orb is not None:
        summary[S_ENGINE_PROPELLANT_USED] = vehicle[V_MASS] - orb.state[6]
        if status[ST_POINTING_COUNT] > 0.0:
            summary[S_BURN_POINTING_RMS] = math.sqrt(status[ST_POINTING_SUM2] / status[ST_POINTING_COUNT]) * _DEG
            summary[S_BURN_POINTING_MAX] = status[ST_POINTING_MAX] * _DEG
