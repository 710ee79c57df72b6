"""The run loop: one flight through the mission's mode program.

Every control period (000 sec. 5) the loop takes its named steps: navigate (trajectory and
measured state) -> advance mode (the mode's guidance reference, its exit conditions, the next
mode's start; ``core.modes``) -> actuate (controller, then PWPF + allocation table and the
per-thruster switching check, or LP allocation + pulse-width modulation; valve commands) ->
record (a history row) -> integrate (the attitude over the period in segments that end on the
thrust-profile breakpoints, each split into RK4 steps of at most ``integrator_max_step_s``).
With reaction wheels, actuate hands the controller's torque to the wheels (``_drive_wheels``:
core.wheels, held over the period) and integrate advances the wheels with the body.
With the ``orbit`` trajectory, a burn mode first steers (``_steer``: core.deorbit at the guidance
rate), and after the attitude the orbit is integrated over the same period (``_engine_period``,
``_translate``: core.orbit), the thrust direction following the body.
All inputs a campaign may disperse arrive as array values (``core.inputs.RunInputs``), so one
compiled kernel serves every run. Outputs go to caller-owned arrays.
"""

import math
from typing import NamedTuple

import numpy as np

from refexmc._jit import jit, jit_noalloc
from refexmc.core import (
    allocation,
    control,
    deorbit,
    dynamics,
    environment,
    guidance,
    lp_allocation,
    modes,
    navigation,
    orbit,
    pulse_modulation,
    quaternion,
    rcs,
    switching,
    wheels,
)
from refexmc.core.bits import lowest_bit
from refexmc.core.layout import (
    ACTUATION_LP_PWM,
    ACTUATION_WHEELS,
    F_ACCEL_MARGIN,
    F_ACTUATION,
    F_CONTROL_PERIOD,
    F_CONTROLLER,
    F_ENGINE_AXIS,
    F_GUIDANCE_PERIOD,
    F_GUIDANCE_POSITION_GAIN,
    F_GUIDANCE_VELOCITY_GAIN,
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
    H_ALTITUDE,
    H_FUEL,
    H_MODE,
    H_OMEGA_E,
    H_OMEGA_M,
    H_PULSE,
    H_QBAR,
    H_T,
    H_THETA_E,
    H_THETA_T,
    H_VALVES,
    LV_ACCEL_MAX,
    LV_KD,
    LV_KP,
    LV_THRUST,
    LV_THRUST_DESIGN,
    M_BURN_DURATION,
    M_BURN_START,
    M_CONSTANT_TORQUE,
    M_EARTH_MU,
    M_EARTH_RADIUS,
    M_EARTH_RATE,
    M_ENTRY_ALTITUDE,
    M_GG_COEFFICIENT,
    M_GG_DIRECTION,
    M_HANDOVER_ANGLE,
    M_MAX_STEP,
    M_MAX_TIME,
    M_ORBIT_STATE,
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
    NOMINAL_SIZE,
    S_ALTITUDE_END,
    S_BURN_POINTING_MAX,
    S_BURN_POINTING_RMS,
    S_ENGINE_PROPELLANT_USED,
    S_ENTRY,
    S_ENTRY_TIME,
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
    TRAJECTORY_ORBIT,
    TRAJECTORY_PLANAR_DRAG,
    V_COM_OFFSET,
    V_ENGINE_DIRECTION,
    V_ENGINE_ISP,
    V_ENGINE_POSITION,
    V_ENGINE_PROPELLANT,
    V_ENGINE_THRUST,
    V_INERTIA,
    V_MASS,
    V_PROPELLANT,
)

_DEG = 180.0 / math.pi
_ARCSEC = 3600.0 * _DEG

# --- flight status: the loop's scalars, one float64 array ------------------------------------
ST_MODE = 0  # index of the mode flown; n_modes when the program is done
ST_MODE_START = 1  # time the mode began (s)
ST_FAILURE = 2  # layout.FAIL_*
ST_FAILURE_MODE = 3
ST_FUEL = 4  # propellant left (kg)
ST_CALIBRATING = 5  # time spent in calibrating modes (s)
ST_HAS_FINAL = 6  # 1: guidance has a target attitude (Guide.q_final)
ST_MODES_COMPLETED = 7
ST_RK4_STEPS = 8
ST_NODE_INDEX = 9  # trajectory node a is at node_index * trajectory_step_s
ST_STARTED = 10  # 1 once the first mode has started
ST_GUIDANCE_TICK = 11  # orbit: time of the last burn-guidance step
ST_POINTING_SUM2 = 12  # sum of squared pointing errors (rad^2) over control steps with the engine on
ST_POINTING_COUNT = 13
ST_POINTING_MAX = 14
ST_ENTERED = 15  # 1 once the entry interface was crossed
ST_ENGINE_ON = 16  # engine on-time in the coming control period: start, end (s)
ST_ENGINE_OFF = 17
ST_POINTING_WINDOW_SUM2 = 18  # per body axis: sum of squared pointing errors (rad^2) in the pointing window
ST_POINTING_WINDOW_COUNT = 21
ST_POINTING_WINDOW_MAX = 22  # largest total angle there (rad)
ST_WHEEL_MOMENTUM_PEAK = 23  # largest |I_w Omega| of any wheel (N m s)
ST_WHEEL_TORQUE_PEAK = 24  # largest motor torque demand before limits (N m)
ST_WHEEL_SATURATED = 25  # time with a wheel limit acting (s)
STATUS_SIZE = 26
# --- thruster bit masks (bit i for thruster i), one int64 array --------------------------------
MASK_OPEN = 0  # commanded open (switching.enforce)
MASK_ACTIVE = 1  # not closed and settled (rcs.update)


class Body(NamedTuple):
    """The true attitude state and what integrating it needs."""

    x: np.ndarray  # dynamics state [q, omega]
    rk4: np.ndarray  # RK4 scratch
    inertia: np.ndarray  # truth, 3x3
    inertia_inv: np.ndarray
    torques: np.ndarray  # rows: thrust at segment start and end, RK4 step start and end, aerodynamic


class Trajectory(NamedTuple):
    """Planar point-mass trajectory: RK4 nodes, Hermite-interpolated at the control rate."""

    state: np.ndarray  # interpolated [x, z, vx, vz] now
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
    """Controller to valves: errors, commands, modulator, switching and valve states."""

    q_error: np.ndarray
    rate_error: np.ndarray
    torque_cmd: np.ndarray
    pulse: np.ndarray  # modulator output per axis
    rotvec: np.ndarray  # history scratch
    gains: np.ndarray  # (levels, 2, 3): kp, kd per axis (contiguous rows for the controller)
    fsw_inertia: np.ndarray  # the inertia the flight software knows (000 eq. 30)
    pwpf_state: np.ndarray
    row_masks: np.ndarray  # allocation table rows as bit masks
    switch_state: np.ndarray
    valve_state: np.ndarray
    arms: np.ndarray  # torque arms about the actual CoM
    smc: np.ndarray  # (3, 3): sliding-mode slope, gain, boundary layer per axis (001 eq. 12)


class Optimiser(NamedTuple):
    """LP allocation and its pulse-width modulation (actuation lp_pwm, core.lp_allocation)."""

    arms: np.ndarray  # (3, n) torque arms the flight software knows: nominal geometry and CoM
    u: np.ndarray  # thrust per thruster (N)
    u_max: np.ndarray  # the flight software's thrust per thruster at the level flown (N)
    scratch: np.ndarray  # lp_allocation.scratch_shape
    basis: np.ndarray  # (3,) int64
    in_basis: np.ndarray  # bool


class Orbit(NamedTuple):
    """The orbit trajectory (core.orbit) and the deorbit burn guidance (core.deorbit)."""

    state: np.ndarray  # [r, v, m], ECI
    prev: np.ndarray  # the state at the start of the control period
    stage: np.ndarray  # (6, 7) RK4 scratch
    measured: np.ndarray  # GPS position and velocity at the last guidance step
    nominal: np.ndarray  # the nominal row then
    command: np.ndarray  # commanded thrust direction (unit, ECI)
    thrust_dirs: np.ndarray  # (2, 3) true thrust direction at the period's start and end (ECI)
    torque: np.ndarray  # gravity-gradient + engine torque over the period (body, N m)
    crossing: np.ndarray  # the state at the entry interface
    work: np.ndarray  # (9, 3) scratch


class Work(NamedTuple):
    body: Body
    trajectory: Trajectory
    sensed: Sensed
    guide: Guide
    actuation: Actuation
    status: np.ndarray  # ST_*
    masks: np.ndarray  # MASK_*, int64
    optimiser: Optimiser
    orbit: Orbit
    wheels: wheels.Plant


@jit
def run_flight(inputs, nav_seed, history_every, summary, pulse_counts, history):
    """Fly ``inputs`` (``core.inputs.RunInputs``); fill ``summary``, ``pulse_counts`` and ``history``.

    ``summary`` has ``layout.summary_size(n_modes)`` slots; ``history`` one row per
    ``history_every`` control steps (plus the final state) until it is full;
    ``summary[S_HISTORY_ROWS]`` says how many rows were written.
    """
    n_thr = inputs.thrusters.shape[0]
    n_levels = inputs.levels.shape[0]
    n_wheels = inputs.wheels.shape[0]
    work = Work(
        Body(
            np.empty(dynamics.STATE_SIZE),
            np.empty((8, dynamics.STATE_SIZE)),
            np.empty((3, 3)),
            np.empty((3, 3)),
            np.zeros((5, 3)),
        ),
        Trajectory(
            np.empty(environment.TRAJECTORY_STATE_SIZE),
            np.empty((2, environment.TRAJECTORY_STATE_SIZE)),
            np.empty((2, 2)),
            np.empty(environment.TRAJECTORY_STATE_SIZE),
        ),
        Sensed(np.zeros(4), np.zeros(3), np.zeros(modes.NOW_SIZE), np.empty(1, dtype=np.uint64), np.zeros(4)),
        Guide(
            np.zeros(guidance.GUIDANCE_STATE_SIZE),
            np.zeros(4),
            np.zeros(3),
            np.zeros(3),
            np.zeros(4),
            np.zeros((3, 4)),
            np.zeros((6, 4)),
            np.empty((n_levels, 3)),
        ),
        Actuation(
            np.zeros(4),
            np.zeros(3),
            np.zeros(3),
            np.zeros(3),
            np.zeros(3),
            np.empty((n_levels, 2, 3)),
            np.empty((3, 3)),
            np.empty((3, pulse_modulation.PWPF_STATE_SIZE)),
            np.empty(inputs.allocation.shape[0], dtype=np.int64),
            np.empty((n_thr, switching.SWITCH_STATE_SIZE)),
            np.zeros((n_thr, rcs.VALVE_STATE_SIZE)),
            np.empty((n_thr, 3)),
            np.zeros((3, 3)),
        ),
        np.zeros(STATUS_SIZE),
        np.zeros(2, dtype=np.int64),
        Optimiser(
            np.zeros((3, n_thr)),
            np.zeros(n_thr),
            np.zeros(n_thr),
            # lp_allocation.scratch_shape(n_thr), written out: a Python function cannot run here
            np.zeros((lp_allocation.N_ROWS + 8, max(n_thr + 1 + lp_allocation.N_ROWS, 6))),
            np.zeros(lp_allocation.N_ROWS, dtype=np.int64),
            np.zeros(n_thr + 1 + lp_allocation.N_ROWS, dtype=np.bool_),
        ),
        Orbit(
            np.zeros(orbit.ORBIT_STATE_SIZE),
            np.zeros(orbit.ORBIT_STATE_SIZE),
            np.zeros((6, orbit.ORBIT_STATE_SIZE)),
            np.zeros(6),
            np.zeros(NOMINAL_SIZE),
            np.zeros(3),
            np.zeros((2, 3)),
            np.zeros(3),
            np.zeros(orbit.ORBIT_STATE_SIZE),
            np.zeros((9, 3)),
        ),
        wheels.Plant(  # as wheels.plant(inputs.wheels) (a Python function cannot run here)
            inputs.wheels,
            np.zeros(n_wheels + wheels.IMPULSE),
            np.zeros(n_wheels),
            np.zeros(n_wheels),
            np.zeros((3, 3)),
            np.zeros((3, 3)),
            np.zeros((3, 3)),
            np.zeros(4),
            np.zeros((5, 7)),
            np.zeros((5, n_wheels + wheels.IMPULSE)),
            np.zeros((5, 3)),
            np.zeros((3, 3)),
            np.zeros(2),
        ),
    )
    _fly(inputs, nav_seed, history_every, summary, pulse_counts, history, work)


@jit_noalloc
def _start(inputs, nav_seed, summary, pulse_counts, body, traj, sensed, guide, act, status, masks, wh):
    """Initial state: body x along the velocity, wings level, then the separation error; the
    wheels' momenta and the total angular momentum."""
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
    allocation.table_masks(inputs.allocation, act.row_masks)
    margin = fsw[F_ACCEL_MARGIN]
    levels = inputs.levels
    for lv in range(levels.shape[0]):
        for i in range(3):
            act.gains[lv, 0, i] = levels[lv, LV_KP + i]
            act.gains[lv, 1, i] = levels[lv, LV_KD + i]
            guide.accels[lv, i] = margin * levels[lv, LV_ACCEL_MAX + i]
    sensed.rng_state[0] = np.uint64(nav_seed)

    if int(mission[M_TRAJECTORY_MODEL]) == TRAJECTORY_PLANAR_DRAG:
        span = mission[M_TRAJECTORY_STEP]
        environment.initial_state(mission, traj.nodes[1])
        traj.node_accels[1, 0], traj.node_accels[1, 1] = environment.acceleration(
            mission, vehicle, inputs.atmosphere, traj.nodes[1]
        )
        environment.advance_nodes(mission, vehicle, inputs.atmosphere, traj.nodes, traj.node_accels, span, traj.stage)
        environment.interpolate(
            traj.nodes[0], traj.node_accels[0], traj.nodes[1], traj.node_accels[1], span, 0.0, traj.state
        )
    else:
        for k in range(traj.state.shape[0]):
            traj.state[k] = 0.0
    tmp4, sep_q = sensed.work4, guide.q_ref  # q_ref is free until the first mode with a reference
    quaternion.from_rotation_vector(0.0, mission[M_SEP_FLIGHT_PATH], 0.0, tmp4)
    sep = mission[M_SEP_ATTITUDE : M_SEP_ATTITUDE + 3]
    quaternion.from_rotation_vector(sep[0], sep[1], sep[2], sep_q)
    quaternion.multiply(tmp4, sep_q, body.x[0:4])
    for i in range(3):
        body.x[4 + i] = mission[M_SEP_RATES + i]
    rcs.reset(act.valve_state)
    rcs.torque_arms(inputs.thrusters, vehicle, act.arms)
    pulse_modulation.reset(act.pwpf_state)
    switching.reset(act.switch_state)
    for i in range(pulse_counts.shape[0]):
        pulse_counts[i] = 0
    for k in range(summary.shape[0]):
        summary[k] = 0.0
    for k in range(STATUS_SIZE):
        status[k] = 0.0
    masks[MASK_OPEN] = 0
    masks[MASK_ACTIVE] = 0
    status[ST_FUEL] = vehicle[V_PROPELLANT]
    if wh.table.shape[0] > 0:
        gg = M_GG_DIRECTION
        wheels.start(wh, body.inertia, body.x, mission[M_GG_COEFFICIENT], mission[gg : gg + 3])


@jit_noalloc(force_inline=True)
def _navigate(mission, vehicle, atmosphere, nav, x, traj, orbit_state, sensed, status, t):
    """Trajectory at ``t`` (new RK4 nodes as needed), flight conditions, measured attitude and rates."""
    altitude, climb, qbar = 0.0, 0.0, 0.0
    model = int(mission[M_TRAJECTORY_MODEL])
    if model == TRAJECTORY_ORBIT:  # integrated with the attitude, period by period (_translate)
        altitude = orbit.radius(orbit_state) - mission[M_EARTH_RADIUS]
        climb = orbit.climb_rate(orbit_state)
    elif model == TRAJECTORY_PLANAR_DRAG:
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
            traj.state,
        )
        altitude, climb, qbar = environment.flight_conditions(mission, atmosphere, traj.state)
    sensed.now[modes.NOW_TIME_IN_MODE] = t - status[ST_MODE_START]
    sensed.now[modes.NOW_ALTITUDE] = altitude
    sensed.now[modes.NOW_CLIMB] = climb
    sensed.now[modes.NOW_QBAR] = qbar
    sensed.now[modes.NOW_TIME] = t
    navigation.measure(x, nav, status[ST_CALIBRATING], sensed.rng_state, sensed.q_meas, sensed.rate_meas, sensed.work4)


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
    fsw, levels, thrusters, sensed, guide, act, opt, masks, t, level, active, controlled, has_reference, pulse_counts
):
    """Controller, actuation (pulse modulation + allocation), switching check and valve commands.

    ``active``: False when the mode is locked, the program done or the run failed.
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
        if actuation != ACTUATION_LP_PWM and actuation != ACTUATION_WHEELS:
            desired = allocation.thruster_commands(
                actuation, fsw, levels[level], act.torque_cmd, act.pwpf_state, act.row_masks, t, act.pulse
            )
    if actuation == ACTUATION_WHEELS:  # the wheels take act.torque_cmd (_drive_wheels)
        return
    if actuation == ACTUATION_LP_PWM:
        _pulse_width(fsw, levels, thrusters, act, opt, masks, t, level, active, pulse_counts)
        return
    valves_open = masks[MASK_OPEN]
    opened, closed = switching.enforce(act.switch_state, desired, valves_open, t, fsw[F_MIN_ON], fsw[F_MIN_OFF])
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
def _pulse_width(fsw, levels, thrusters, act, opt, masks, t, level, active, pulse_counts):
    """LP allocation of the commanded torque (004 eq. 2-5), each thruster realised as one pulse
    from the start of the control period: open at ``t``, closed after its on-time
    (``allocation.pwm_on_time``; saturated thrusters stay open into the next period)."""
    n = thrusters.shape[0]
    dt = fsw[F_CONTROL_PERIOD]
    if active:
        design = levels[level, LV_THRUST_DESIGN]
        for i in range(n):
            opt.u_max[i] = design
        lp_allocation.allocate(opt.arms, opt.u_max, act.torque_cmd, opt.u, opt.scratch, opt.basis, opt.in_basis)
    for i in range(3):
        act.pulse[i] = 0.0
    was_open = masks[MASK_OPEN]
    now_open = 0
    touched = 0
    for i in range(n):
        on = allocation.pwm_on_time(opt.u[i], opt.u_max[i], dt, fsw[F_MIN_ON]) if active else 0.0
        bit = 1 << i
        if on > 0.0:
            if was_open & bit == 0:
                rcs.command(act.valve_state, thrusters, i, True, t, level)
                pulse_counts[i] += 1
            if on < dt - 1e-12:
                rcs.command(act.valve_state, thrusters, i, False, t + on, level)
            else:
                now_open |= bit
            touched |= bit
        elif was_open & bit != 0:
            rcs.command(act.valve_state, thrusters, i, False, t, level)
            touched |= bit
    masks[MASK_OPEN] = now_open
    masks[MASK_ACTIVE] |= touched


@jit_noalloc
def _drive_wheels(distribution, wh, rate_meas, omega, torque_cmd, compensate, active, status, dt):
    """Motor torques for this control period (core.wheels.command) and the wheel statistics; none
    when ``active`` is False (a locked mode, the program done or the run failed)."""
    if not active:
        for i in range(wh.motor.shape[0]):
            wh.motor[i] = 0.0
        return
    peak, limited = wheels.command(distribution, wh, rate_meas, omega, torque_cmd, compensate)
    status[ST_WHEEL_TORQUE_PEAK] = max(status[ST_WHEEL_TORQUE_PEAK], peak)
    if limited:
        status[ST_WHEEL_SATURATED] += dt


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
    history[row, H_OMEGA_M] = math.sqrt(rate_meas[0] ** 2 + rate_meas[1] ** 2 + rate_meas[2] ** 2) * _DEG
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
    mission, vehicle, thrusters, thrust, max_step, dt, body, act, wh, status, masks, qbar, t, level, extra, has_extra
):
    """Integrate the attitude over one control period, segment by segment, ``thrust`` (N) being the
    level's nominal thrust, ``extra`` a further disturbance torque when ``has_extra`` (the orbit's
    gravity gradient and main engine), plus the mission's constant torque; with reaction wheels
    the wheels' momenta too (core.wheels), the gravity gradient of 001 eq. 11 then evaluated at
    every RK4 stage (else held over the period). Returns True when the propellant ran out."""
    n_thr = thrusters.shape[0]
    has_wheels = wh.table.shape[0] > 0
    gg_coefficient = mission[M_GG_COEFFICIENT]
    # Segments up to this long are one RK4 step: their ceil(span / max_step - 1e-9) is 1 (the
    # division and subtraction are monotone and this bound divides to 1 + 1e-10 -+ 1 ulp).
    one_step_limit = max_step * (1.0 + 1e-10)
    tau0, tau1, tau_a, tau_b, aero = body.torques[0], body.torques[1], body.torques[2], body.torques[3], body.torques[4]
    environment.aerodynamic_torque(vehicle, qbar, aero)
    if has_extra:
        for i in range(3):
            aero[i] += extra[i]
    for i in range(3):
        aero[i] += mission[M_CONSTANT_TORQUE + i]
    if gg_coefficient != 0.0 and not has_wheels:
        gg = M_GG_DIRECTION
        wheels.gravity_gradient(body.x[0:4], gg_coefficient, mission[gg : gg + 3], body.inertia, wh.scratch[0:2], aero)
    fuel = status[ST_FUEL]
    valves_active = masks[MASK_ACTIVE]
    rk4_steps = 0
    t_seg = t
    t_end = t + dt
    exhausted = False
    while t_seg < t_end - 1e-12:
        valves_active = rcs.update(act.valve_state, thrusters, n_thr, t_seg, level, valves_active)
        active = valves_active != 0
        if active:
            t_next = rcs.next_breakpoint(act.valve_state, n_thr, t_seg, t_end, valves_active)
        else:  # coasting: the whole rest of the period is one thrust-free segment
            t_next = t_end
        if active and fuel > 0.0:
            impulse = rcs.segment_thrust(
                act.valve_state, thrusters, vehicle, act.arms, thrust, t_seg, t_next, tau0, tau1, valves_active
            )
        else:
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
            if has_wheels:
                wheels.rk4_step(body.x, h, tau_a, tau_b, wh)
            else:
                dynamics.rk4_step(body.x, h, tau_a, tau_b, body.inertia, body.inertia_inv, body.rk4)
            rk4_steps += 1
        fuel -= rcs.propellant_for_impulse(vehicle, impulse)
        if fuel <= 0.0 and impulse > 0.0:
            fuel = 0.0
            exhausted = True
        t_seg = t_next
    status[ST_FUEL] = fuel
    masks[MASK_ACTIVE] = valves_active
    status[ST_RK4_STEPS] += rk4_steps
    return exhausted


# --- the orbit trajectory and the deorbit burn (004 sec. III) -----------------------------------


@jit_noalloc
def _start_orbit(mission, vehicle, orb, status, summary):
    """Orbit state at t = 0 (mass: the vehicle's, main-engine propellant included); outputs NaN."""
    for i in range(6):
        orb.state[i] = mission[M_ORBIT_STATE + i]
    orb.state[6] = vehicle[V_MASS]
    status[ST_GUIDANCE_TICK] = -math.inf
    for i in range(5):
        summary[S_ENTRY + i] = math.nan
    summary[S_ENTRY_TIME] = math.nan
    summary[S_BURN_POINTING_RMS] = math.nan
    summary[S_BURN_POINTING_MAX] = math.nan


@jit_noalloc
def _thrust_direction(vehicle, q, out):
    """The engine's true force direction in ECI at attitude ``q``."""
    quaternion.rotate(q, vehicle[V_ENGINE_DIRECTION : V_ENGINE_DIRECTION + 3], out)


@jit_noalloc
def _steer(nominal, fsw, nav, vehicle, x, orb, guide, rng_state, status, t, burning):
    """Burn guidance every guidance period (core.deorbit): GPS, the nominal row, the commanded
    direction and the attitude that points the engine's nominal axis along it (the mode's target
    and reference). While the engine fires, the angle between its true force and the commanded
    direction is accumulated (004 Fig. 5)."""
    if t >= status[ST_GUIDANCE_TICK] + fsw[F_GUIDANCE_PERIOD] - 1e-9:
        status[ST_GUIDANCE_TICK] = t
        deorbit.measure(orb.state, nav, rng_state, orb.measured)
        deorbit.nominal_at(nominal, t, orb.nominal)
        deorbit.steer(
            orb.measured, orb.nominal, fsw[F_GUIDANCE_POSITION_GAIN], fsw[F_GUIDANCE_VELOCITY_GAIN], orb.command
        )
        deorbit.thrust_attitude(
            orb.command,
            orb.measured[0:3],
            orb.measured[3:6],
            fsw[F_ENGINE_AXIS : F_ENGINE_AXIS + 3],
            guide.q_final,
            orb.work,
        )
        for i in range(4):
            guide.q_ref[i] = guide.q_final[i]
    if burning:
        d = orb.work[0]
        _thrust_direction(vehicle, x[0:4], d)
        c = d[0] * orb.command[0] + d[1] * orb.command[1] + d[2] * orb.command[2]
        angle = math.acos(max(-1.0, min(1.0, c)))
        status[ST_POINTING_SUM2] += angle * angle
        status[ST_POINTING_COUNT] += 1.0
        status[ST_POINTING_MAX] = max(status[ST_POINTING_MAX], angle)


@jit_noalloc
def _engine_period(mission, vehicle, inertia, x, orb, status, t, dt, burn_mode):
    """Before the attitude is integrated over ``[t, t + dt]``: the engine's on-time in it (the
    burn mode, the planned ignition and cut-off, the propellant left), the true thrust direction
    at its start, and the disturbance torque over it (gravity gradient at its start, engine torque
    times the fraction of the period it fires)."""
    on, off = t, t
    if burn_mode:
        mass_flow = vehicle[V_ENGINE_THRUST] / (vehicle[V_ENGINE_ISP] * orbit.G0)
        left = vehicle[V_ENGINE_PROPELLANT] - (vehicle[V_MASS] - orb.state[6])
        on = max(t, mission[M_BURN_START])
        off = min(t + dt, mission[M_BURN_START] + mission[M_BURN_DURATION], t + left / mass_flow)
        if off < on:
            off = on
    status[ST_ENGINE_ON] = on
    status[ST_ENGINE_OFF] = off
    _thrust_direction(vehicle, x[0:4], orb.thrust_dirs[0])
    r_body = orb.work[0]
    quaternion.rotate_inverse(x[0:4], orb.state[0:3], r_body)
    orbit.gravity_gradient_torque(r_body, mission[M_EARTH_MU], inertia, orb.torque)
    if off > on:
        force = vehicle[V_ENGINE_THRUST] * (off - on) / dt  # mean over the period
        arm = orb.work[1]
        for i in range(3):
            arm[i] = vehicle[V_ENGINE_POSITION + i] - vehicle[V_COM_OFFSET + i]
        e = vehicle[V_ENGINE_DIRECTION : V_ENGINE_DIRECTION + 3]
        orb.torque[0] += force * (arm[1] * e[2] - arm[2] * e[1])
        orb.torque[1] += force * (arm[2] * e[0] - arm[0] * e[2])
        orb.torque[2] += force * (arm[0] * e[1] - arm[1] * e[0])


@jit_noalloc
def _translate(mission, vehicle, x, orb, status, summary, t, dt):
    """Integrate the orbit over ``[t, t + dt]`` after the attitude: coast / engine / coast
    segments, the thrust direction following the body from the period's start to its end (004's
    3+3 DOF); record the entry state where the radius first falls through the entry interface."""
    _thrust_direction(vehicle, x[0:4], orb.thrust_dirs[1])
    for i in range(orbit.ORBIT_STATE_SIZE):
        orb.prev[i] = orb.state[i]
    mu = mission[M_EARTH_MU]
    on, off = status[ST_ENGINE_ON], status[ST_ENGINE_OFF]
    thrust = vehicle[V_ENGINE_THRUST]
    mass_flow = thrust / (vehicle[V_ENGINE_ISP] * orbit.G0)
    d0, d1 = orb.thrust_dirs[0], orb.thrust_dirs[1]
    if off <= on:
        orbit.rk4_step(orb.state, dt, mu, 0.0, 0.0, d0, d1, 0.0, 1.0, orb.stage)
    else:
        if on > t:
            orbit.rk4_step(orb.state, on - t, mu, 0.0, 0.0, d0, d1, 0.0, (on - t) / dt, orb.stage)
        orbit.rk4_step(orb.state, off - on, mu, thrust, mass_flow, d0, d1, (on - t) / dt, (off - t) / dt, orb.stage)
        if off < t + dt:
            orbit.rk4_step(orb.state, t + dt - off, mu, 0.0, 0.0, d0, d1, (off - t) / dt, 1.0, orb.stage)
    r_entry = mission[M_EARTH_RADIUS] + mission[M_ENTRY_ALTITUDE]
    if status[ST_ENTERED] == 0.0 and orbit.radius(orb.state) < r_entry and orbit.climb_rate(orb.state) < 0.0:
        status[ST_ENTERED] = 1.0  # the crossing is coasted to from the period's start (engine off)
        h = orbit.coast_to_radius(orb.prev, r_entry, 0.5 * dt, mu, orb.stage, orb.crossing)
        summary[S_ENTRY_TIME] = t + h
        orbit.entry_state(orb.crossing, t + h, mission[M_EARTH_RATE], summary[S_ENTRY : S_ENTRY + 5])


@jit_noalloc
def _fly(inputs, nav_seed, history_every, summary, pulse_counts, history, w):
    """The run loop of :func:`run_flight` on the work arrays it allocated (no allocation, no
    reference counting: see ``refexmc._jit.jit_noalloc``). Each step gets the arrays it uses
    only: every further array argument costs compile time (numba types each one)."""
    body, traj, sensed, guide, act, status, masks = (
        w.body,
        w.trajectory,
        w.sensed,
        w.guide,
        w.actuation,
        w.status,
        w.masks,
    )
    opt = w.optimiser
    orb = w.orbit
    wh = w.wheels
    n_wheels = wh.table.shape[0]
    vehicle, thrusters, fsw, mission = inputs.vehicle, inputs.thrusters, inputs.fsw, inputs.mission
    program, exits, atmosphere = inputs.modes, inputs.exits, inputs.atmosphere
    _start(inputs, nav_seed, summary, pulse_counts, body, traj, sensed, guide, act, status, masks, wh)
    orbit_model = int(mission[M_TRAJECTORY_MODEL]) == TRAJECTORY_ORBIT
    if orbit_model:
        _start_orbit(mission, vehicle, orb, status, summary)
    cutoff = mission[M_BURN_START] + mission[M_BURN_DURATION]
    allocation.nominal_arms(thrusters, opt.arms)
    n_modes = program.shape[0]
    n_thr = thrusters.shape[0]
    dt = fsw[F_CONTROL_PERIOD]
    max_step = mission[M_MAX_STEP]
    propellant0 = vehicle[V_PROPELLANT]
    pointing_from = mission[M_POINTING_FROM]
    pointing = act.rotvec  # free between history rows (_record fills it when it writes one)
    theta_handover = math.nan
    rows = 0
    step = 0
    t = 0.0
    while True:
        t = step * dt
        _navigate(mission, vehicle, atmosphere, inputs.nav, body.x, traj, orb.state, sensed, status, t)
        controlled, has_reference = _advance_mode(
            program, exits, mission, vehicle, atmosphere, traj.state, sensed, guide, status, summary, t
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
        burn_mode = orbit_model and active and kind == modes.KIND_BURN
        if burn_mode:
            firing = mission[M_BURN_START] <= t < cutoff
            _steer(inputs.nominal, fsw, inputs.nav, vehicle, body.x, orb, guide, sensed.rng_state, status, t, firing)
        _actuate(
            fsw,
            inputs.levels,
            thrusters,
            sensed,
            guide,
            act,
            opt,
            masks,
            t,
            level,
            active,
            controlled,
            has_reference,
            pulse_counts,
        )
        if n_wheels > 0:
            compensate = fsw[F_WHEEL_FRICTION_COMPENSATION] != 0.0
            _drive_wheels(
                inputs.wheel_distribution, wh, sensed.rate_meas, body.x[4:7], act.torque_cmd, compensate, active,
                status, dt,
            )  # fmt: skip
        if t >= pointing_from and has_reference:  # true attitude against the reference (001: PE)
            angle = _pointing(body.x[0:4], guide.q_ref, sensed.work4, pointing)
            for i in range(3):
                status[ST_POINTING_WINDOW_SUM2 + i] += pointing[i] * pointing[i]
            status[ST_POINTING_WINDOW_COUNT] += 1.0
            status[ST_POINTING_WINDOW_MAX] = max(status[ST_POINTING_WINDOW_MAX], angle)

        finished = done or status[ST_FAILURE] != FAIL_NONE
        if record:
            valves = rcs.open_mask(act.valve_state, n_thr, t)
            fraction = status[ST_FUEL] / propellant0
            _record(history, rows, t, flown, theta_t, controlled, fraction, valves, sensed.rate_meas, act, sensed.now)
            rows += 1
        if finished:
            break

        qbar = sensed.now[modes.NOW_QBAR]
        thrust = inputs.levels[level, LV_THRUST]
        if orbit_model:
            _engine_period(mission, vehicle, body.inertia, body.x, orb, status, t, dt, burn_mode)
        exhausted = _integrate(
            mission, vehicle, thrusters, thrust, max_step, dt, body, act, wh, status, masks, qbar, t, level, orb.torque,
            orbit_model,
        )  # fmt: skip
        if n_wheels > 0:
            peak = wheels.largest_relative_momentum(wh.table, wh.h, body.x[4:7])
            status[ST_WHEEL_MOMENTUM_PEAK] = max(status[ST_WHEEL_MOMENTUM_PEAK], peak)
        if orbit_model:
            _translate(mission, vehicle, body.x, orb, status, summary, t, dt)
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
        _pointing(body.x[0:4], guide.q_ref, sensed.work4, pointing)
        for i in range(3):
            summary[S_POINTING_END + i] = pointing[i] * _ARCSEC
    count = status[ST_POINTING_WINDOW_COUNT]
    if count > 0.0:
        for i in range(3):
            summary[S_POINTING_RMS + i] = math.sqrt(status[ST_POINTING_WINDOW_SUM2 + i] / count) * _ARCSEC
        summary[S_POINTING_MAX] = status[ST_POINTING_WINDOW_MAX] * _ARCSEC
    if n_wheels > 0:
        summary[S_WHEEL_MOMENTUM_PEAK] = status[ST_WHEEL_MOMENTUM_PEAK]
        summary[S_WHEEL_MOMENTUM_END] = wheels.largest_relative_momentum(wh.table, wh.h, body.x[4:7])
        summary[S_WHEEL_TORQUE_PEAK] = status[ST_WHEEL_TORQUE_PEAK]
        summary[S_WHEEL_SATURATED_TIME] = status[ST_WHEEL_SATURATED]
        summary[S_MOMENTUM_RESIDUAL] = wheels.momentum_residual(body.x, wh)
    if orbit_model:
        summary[S_ENGINE_PROPELLANT_USED] = vehicle[V_MASS] - orb.state[6]
        if status[ST_POINTING_COUNT] > 0.0:
            summary[S_BURN_POINTING_RMS] = math.sqrt(status[ST_POINTING_SUM2] / status[ST_POINTING_COUNT]) * _DEG
            summary[S_BURN_POINTING_MAX] = status[ST_POINTING_MAX] * _DEG
