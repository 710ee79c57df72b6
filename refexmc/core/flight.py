"""The run loop: one exoatmospheric flight from separation to hand-over.

Every 25 ms control period (000 sec. 5): navigation -> mode logic -> guidance -> controller ->
actuation (pulse modulation + allocation) -> per-thruster switching check -> valve commands;
then the attitude is integrated over the period in segments that end on the thrust-profile
breakpoints (each split into RK4 steps of at most ``integrator_max_step_s``), and the trajectory
by one RK4 step. All inputs a campaign may disperse arrive as array values, so one compiled
kernel serves every run. Outputs go to caller-owned arrays.
"""

import math

import numpy as np

from refexmc._jit import jit, jit_noalloc
from refexmc.core import (
    allocation,
    control,
    dynamics,
    environment,
    guidance,
    modes,
    navigation,
    pulse_modulation,
    quaternion,
    rcs,
    switching,
)
from refexmc.core.bits import lowest_bit
from refexmc.core.layout import (
    F_ACCEL_MARGIN,
    F_ACCEL_MAX,
    F_ACTUATION,
    F_CONTROL_PERIOD,
    F_CONTROLLER,
    F_INERTIA,
    F_KD,
    F_KP,
    F_MIN_OFF,
    F_MIN_ON,
    FAIL_HANDOVER_ANGLE,
    FAIL_NON_FINITE,
    FAIL_NONE,
    FAIL_PROPELLANT,
    FAIL_RDM1_TIMEOUT,
    FAIL_SAM_TIMEOUT,
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
    M_EAM_ALPHA,
    M_EAM_BANK,
    M_EAM_BETA,
    M_EAM_EXIT_ALTITUDE,
    M_EAM_T1_DESIGN,
    M_HANDOVER_ANGLE,
    M_MAX_STEP,
    M_MAX_TIME,
    M_RDM1_TIMEOUT,
    M_SAM_RATE,
    M_SAM_TIMEOUT,
    M_SEP_ATTITUDE,
    M_SEP_FLIGHT_PATH,
    M_SEP_RATES,
    M_SSM_RATE,
    M_SUN_DIRECTION,
    M_TRAJECTORY_STEP,
    MODE_DONE,
    MODE_EAM,
    MODE_GEEM,
    MODE_NCM,
    MODE_RDM1,
    MODE_RDM2,
    MODE_SAM,
    MODE_SSM,
    N_MODES,
    S_ALTITUDE_END,
    S_FAILURE,
    S_FUEL_REMAINING,
    S_FUEL_USED,
    S_HISTORY_ROWS,
    S_MODES_COMPLETED,
    S_QBAR_END,
    S_RK4_STEPS,
    S_SUCCESS,
    S_T1_MODE,
    S_T_END,
    S_T_MODE,
    S_THETA_HANDOVER,
    V_INERTIA,
    V_PROPELLANT,
)

_DEG = 180.0 / math.pi


@jit_noalloc
def _write_history(
    history,
    row,
    t,
    mode,
    theta_t,
    rate_meas,
    q_error,
    rate_error,
    attitude_controlled,
    fuel_fraction,
    valves,
    pulse,
    altitude,
    qbar,
    rotvec,
):
    history[row, H_T] = t
    history[row, H_MODE] = mode
    history[row, H_THETA_T] = theta_t * _DEG
    history[row, H_OMEGA_M] = math.sqrt(rate_meas[0] ** 2 + rate_meas[1] ** 2 + rate_meas[2] ** 2) * _DEG
    if attitude_controlled:
        quaternion.to_rotation_vector(q_error, rotvec)
    for i in range(3):
        history[row, H_THETA_E + i] = rotvec[i] * _DEG if attitude_controlled else math.nan
        history[row, H_OMEGA_E + i] = rate_error[i] * _DEG
        history[row, H_PULSE + i] = pulse[i]
    history[row, H_FUEL] = fuel_fraction
    history[row, H_VALVES] = valves
    history[row, H_ALTITUDE] = altitude
    history[row, H_QBAR] = qbar


@jit
def run_flight(
    vehicle,
    thrusters,
    fsw,
    mission,
    nav,
    atmosphere,
    allocation_table,
    nav_seed,
    history_every,
    summary,
    pulse_counts,
    history,
):
    """Fly one exoatmospheric phase; fill ``summary``, ``pulse_counts`` and ``history``.

    ``history`` has one row per ``history_every`` control steps (plus the final state) until
    it is full; ``summary[S_HISTORY_ROWS]`` says how many rows were written.
    """
    n_thr = thrusters.shape[0]
    work = (
        np.empty(dynamics.STATE_SIZE),  # x
        np.empty((8, dynamics.STATE_SIZE)),  # RK4 scratch
        np.empty((3, 3, 3)),  # inertia, its inverse, the flight software's inertia
        np.empty((4, environment.TRAJECTORY_STATE_SIZE)),  # interpolated state, 2 RK4 nodes, stage
        np.empty((2, 2)),  # trajectory node accelerations
        np.zeros((n_thr, rcs.VALVE_STATE_SIZE)),
        np.empty((n_thr, 3)),  # torque arms
        np.empty((3, pulse_modulation.PWPF_STATE_SIZE)),
        np.empty((n_thr, switching.SWITCH_STATE_SIZE)),
        np.empty(allocation_table.shape[0], dtype=np.int64),  # allocation table rows as bit masks
        np.zeros(guidance.GUIDANCE_STATE_SIZE),
        np.zeros((13, 3)),  # 3-vectors
        np.zeros((5, 4)),  # quaternions
        np.empty((5, 4)),  # entry attitude: its constant rotations, scratch
        np.empty((3, 3)),
        np.empty((3, 3)),  # horizontal, sun, spin rate
        np.empty((2, 2, 3)),  # gains [level][kp, kd][axis]
        np.empty((2, 3)),  # guidance accelerations, low and high thrust
        np.empty(1, dtype=np.uint64),  # navigation noise generator
    )
    _fly(
        vehicle,
        thrusters,
        fsw,
        mission,
        nav,
        atmosphere,
        allocation_table,
        nav_seed,
        history_every,
        summary,
        pulse_counts,
        history,
        work,
    )


@jit_noalloc
def _fly(
    vehicle,
    thrusters,
    fsw,
    mission,
    nav,
    atmosphere,
    allocation_table,
    nav_seed,
    history_every,
    summary,
    pulse_counts,
    history,
    work,
):
    """The run loop of :func:`run_flight` on the work arrays it allocated (no allocation, no
    reference counting: see ``refexmc._jit.jit_noalloc``)."""
    (
        x,
        rk4_work,
        matrices,
        trajectory,
        node_accels,
        valve_state,
        arms,
        pwpf_state,
        switch_state,
        row_masks,
        guid,
        vec,
        quat,
        quat_work,
        work33,
        side,
        gains,
        accels,
        rng_state,
    ) = work
    n_thr = thrusters.shape[0]
    dt = fsw[F_CONTROL_PERIOD]
    max_step = mission[M_MAX_STEP]
    inertia, inertia_inv, fsw_inertia = matrices[0], matrices[1], matrices[2]
    for i in range(3):
        for j in range(3):
            inertia[i, j] = vehicle[V_INERTIA + 3 * i + j]
            fsw_inertia[i, j] = fsw[F_INERTIA + 3 * i + j]
    dynamics.invert_3x3(inertia, inertia_inv)
    propellant0 = vehicle[V_PROPELLANT]
    traj, nodes, stage = trajectory[0], trajectory[1:3], trajectory[3]
    allocation.table_masks(allocation_table, row_masks)
    rate_meas, rate_ref, accel_ref, rate_error = vec[0], vec[1], vec[2], vec[3]
    torque_cmd, pulse, tau0, tau1, tau_a, tau_b, aero = vec[4], vec[5], vec[6], vec[7], vec[8], vec[9], vec[10]
    rotvec = vec[11]
    inertial_rate = vec[12]  # GEEM reference rate, inertial axes
    q_meas, q_ref, q_error, q_final, tmp4 = quat[0], quat[1], quat[2], quat[3], quat[4]
    for lv in range(2):
        for i in range(3):
            gains[lv, 0, i] = fsw[F_KP + 3 * lv + i]
            gains[lv, 1, i] = fsw[F_KD + 3 * lv + i]
    kp_low, kd_low, kp_high, kd_high = gains[0, 0], gains[0, 1], gains[1, 0], gains[1, 1]
    accel_low, accel_high = accels[0], accels[1]
    aero_rotations, work24 = quat_work[0:3], quat_work[3:5]
    guidance.aerodynamic_rotations(mission[M_EAM_ALPHA], mission[M_EAM_BETA], mission[M_EAM_BANK], aero_rotations)
    rng_state[0] = np.uint64(nav_seed)
    # Segments up to this long are one RK4 step: their ceil(span / max_step - 1e-9) is 1 (the
    # division and subtraction are monotone and this bound divides to 1 + 1e-10 -+ 1 ulp).
    one_step_limit = max_step * (1.0 + 1e-10)
    valves_active = 0  # bit mask of thrusters not closed and settled (rcs.update)
    valves_open = 0  # bit mask of thrusters commanded open (switching.enforce)

    margin = fsw[F_ACCEL_MARGIN]
    for i in range(3):
        accel_low[i] = margin * fsw[F_ACCEL_MAX + i]
        accel_high[i] = margin * fsw[F_ACCEL_MAX + 3 + i]
        side[1, i] = mission[M_SUN_DIRECTION + i]
        side[2, i] = 0.0
    side[2, 0] = mission[M_SSM_RATE]

    # --- initial state: body x along the velocity, wings level, then the separation error -----
    span = mission[M_TRAJECTORY_STEP]
    environment.initial_state(mission, nodes[1])
    node_accels[1, 0], node_accels[1, 1] = environment.acceleration(mission, vehicle, atmosphere, nodes[1])
    environment.advance_nodes(mission, vehicle, atmosphere, nodes, node_accels, span, stage)
    node_index = 0  # nodes[0] is at node_index * span
    environment.interpolate(nodes[0], node_accels[0], nodes[1], node_accels[1], span, 0.0, traj)
    quaternion.from_rotation_vector(0.0, mission[M_SEP_FLIGHT_PATH], 0.0, tmp4)
    sep = mission[M_SEP_ATTITUDE : M_SEP_ATTITUDE + 3]
    quaternion.from_rotation_vector(sep[0], sep[1], sep[2], q_ref)
    quaternion.multiply(tmp4, q_ref, x[0:4])
    for i in range(3):
        x[4 + i] = mission[M_SEP_RATES + i]
    rcs.reset(valve_state)
    rcs.torque_arms(thrusters, vehicle, arms)
    pulse_modulation.reset(pwpf_state)
    switching.reset(switch_state)
    for i in range(n_thr):
        pulse_counts[i] = 0

    for k in range(summary.shape[0]):
        summary[k] = 0.0
    fuel = propellant0
    mode = MODE_NCM
    t_mode_start = 0.0
    time_in_ssm = 0.0
    failure = FAIL_NONE
    modes_completed = 0
    theta_handover = math.nan
    rk4_steps = 0
    rows = 0
    step = 0
    t = 0.0
    altitude = environment.altitude(mission, traj)
    qbar = 0.0

    while True:
        t = step * dt
        while t >= (node_index + 1) * span - 1e-9:
            environment.advance_nodes(mission, vehicle, atmosphere, nodes, node_accels, span, stage)
            node_index += 1
        environment.interpolate(nodes[0], node_accels[0], nodes[1], node_accels[1], span, t - node_index * span, traj)
        altitude, climb, qbar = environment.flight_conditions(mission, atmosphere, traj)
        navigation.measure(x, nav, time_in_ssm, rng_state, q_meas, rate_meas, tmp4)

        # --- mode logic: each mode left by its own exit condition ---------------------------
        time_in_mode = t - t_mode_start
        previous_mode = mode
        if mode == MODE_NCM:
            if modes.ncm_done(mission, time_in_mode):
                mode = MODE_RDM1
                guidance.start_rate_damping(guid, t, rate_meas, accel_low)
        elif mode == MODE_RDM1:
            if modes.rdm1_done(mission, time_in_mode, guid[guidance.G_T1], rate_meas):
                mode = MODE_SAM
                environment.local_horizontal(mission, traj, side[0])
                guidance.sun_attitude(side[1], side[0], q_final, work33)
                guidance.start_slerp(guid, t, q_meas, q_final, accel_low, 0.0, tmp4)
            elif time_in_mode > mission[M_RDM1_TIMEOUT]:
                failure = FAIL_RDM1_TIMEOUT
        elif mode == MODE_SAM:
            guidance.slerp_reference(guid, t, q_ref, rate_ref, accel_ref)
            rate_error_norm = math.sqrt(
                (rate_meas[0] - rate_ref[0]) ** 2
                + (rate_meas[1] - rate_ref[1]) ** 2
                + (rate_meas[2] - rate_ref[2]) ** 2
            )
            # both errors must be below their thresholds: the angle (an acos) is only needed
            # once the rate error is (about one SAM step in ten in the nominal flight)
            if rate_error_norm < mission[M_SAM_RATE] and modes.sam_done(
                mission, quaternion.angle_between(q_meas, q_final), rate_error_norm
            ):
                mode = MODE_SSM
                guidance.start_spin_up(guid, t, q_final, side[2], accel_low)
            elif time_in_mode > mission[M_SAM_TIMEOUT]:
                failure = FAIL_SAM_TIMEOUT
        elif mode == MODE_SSM:
            if modes.ssm_done(mission, altitude, climb):
                mode = MODE_RDM2
                guidance.start_rate_damping(guid, t, rate_meas, accel_low)
        elif mode == MODE_RDM2:
            if modes.rdm2_done(mission, time_in_mode):
                mode = MODE_EAM
                # the entry attitude to the velocity predicted at the EAM exit, held inertially
                # (reference-model sec. 4); GEEM then tracks the current velocity
                exit_pitch = environment.predicted_velocity_pitch(mission, traj, mission[M_EAM_EXIT_ALTITUDE])
                guidance.entry_attitude_from(exit_pitch, aero_rotations, q_final, work24)
                guidance.start_slerp(guid, t, q_meas, q_final, accel_high, mission[M_EAM_T1_DESIGN], tmp4)
        elif mode == MODE_EAM:
            if modes.eam_done(mission, altitude):
                mode = MODE_GEEM
        elif mode == MODE_GEEM:
            if modes.geem_done(mission, altitude, qbar):
                mode = MODE_DONE
        if mode != previous_mode:
            modes_completed += 1
            t_mode_start = t
            if mode < N_MODES and mode != MODE_GEEM:
                summary[S_T1_MODE + mode] = guid[guidance.G_T1]
        if failure == FAIL_NONE and mode != MODE_DONE and t >= mission[M_MAX_TIME]:
            failure = FAIL_TIME_LIMIT

        # --- guidance reference ----------------------------------------------------------------
        attitude_controlled = True
        has_attitude_reference = True
        if mode == MODE_RDM1 or mode == MODE_RDM2:
            guidance.rate_damping_reference(guid, t, rate_ref, accel_ref)
            attitude_controlled = False
            has_attitude_reference = False
        elif mode == MODE_SAM or mode == MODE_EAM:
            if mode != previous_mode or mode == MODE_EAM:  # SAM: already done for its exit test
                guidance.slerp_reference(guid, t, q_ref, rate_ref, accel_ref)
        elif mode == MODE_SSM:
            guidance.spin_up_reference(guid, t, q_ref, rate_ref, accel_ref, tmp4)
        elif mode == MODE_GEEM or mode == MODE_DONE:
            guidance.entry_attitude_from(environment.velocity_pitch(traj), aero_rotations, q_ref, work24)
            pitch_rate = environment.velocity_pitch_rate(mission, vehicle, atmosphere, traj)
            inertial_rate[1] = pitch_rate  # the velocity turns about inertial y
            quaternion.rotate_inverse(q_ref, inertial_rate, rate_ref)
            for i in range(3):
                accel_ref[i] = 0.0
        else:  # NCM: no reference, actuators locked
            attitude_controlled = False
            has_attitude_reference = False
            for i in range(3):
                rate_ref[i] = 0.0
                accel_ref[i] = 0.0

        # total angle error: true attitude to the mode's final reference attitude (000 sec. 6.1)
        finished = mode == MODE_DONE or failure != FAIL_NONE
        record = (step % history_every == 0 or finished) and rows < history.shape[0]
        theta_t = math.nan
        if record or mode == MODE_DONE:
            if mode == MODE_SAM or mode == MODE_EAM:
                theta_t = quaternion.angle_between(x[0:4], q_final)
            elif has_attitude_reference:
                theta_t = quaternion.angle_between(x[0:4], q_ref)
        if mode == MODE_DONE:
            theta_handover = theta_t
            if theta_t > mission[M_HANDOVER_ANGLE]:
                failure = FAIL_HANDOVER_ANGLE

        # --- controller, actuation, switching check, valve commands --------------------------
        level = modes.thrust_level(mode)
        if has_attitude_reference:
            control.control_errors(q_meas, rate_meas, q_ref, rate_ref, q_error, rate_error)
        else:
            for i in range(4):
                q_error[i] = 0.0
            q_error[3] = 1.0
            for i in range(3):
                rate_error[i] = rate_meas[i] - rate_ref[i]
        if mode == MODE_NCM or mode == MODE_DONE or failure != FAIL_NONE:
            desired = 0
            for i in range(3):
                pulse[i] = 0.0
        else:
            control.torque_command(
                int(fsw[F_CONTROLLER]),
                q_error,
                rate_error,
                rate_meas,
                accel_ref,
                kp_high if level == rcs.LEVEL_HIGH else kp_low,
                kd_high if level == rcs.LEVEL_HIGH else kd_low,
                fsw_inertia,
                attitude_controlled,
                torque_cmd,
            )
            desired = allocation.thruster_commands(
                int(fsw[F_ACTUATION]), fsw, level, torque_cmd, pwpf_state, row_masks, t, pulse
            )
        opened, closed = switching.enforce(switch_state, desired, valves_open, t, fsw[F_MIN_ON], fsw[F_MIN_OFF])
        valves_open = (valves_open | opened) & ~closed
        valves_active |= opened | closed
        m = opened | closed
        while m != 0:
            i = lowest_bit(m)
            m &= m - 1
            rcs.command(valve_state, thrusters, i, (opened >> i) & 1 != 0, t, level)
            if (opened >> i) & 1:
                pulse_counts[i] += 1

        # --- history ----------------------------------------------------------------------------
        finished = mode == MODE_DONE or failure != FAIL_NONE
        if record:
            _write_history(
                history,
                rows,
                t,
                min(mode, MODE_GEEM),
                theta_t,
                rate_meas,
                q_error,
                rate_error,
                attitude_controlled,
                fuel / propellant0,
                rcs.open_mask(valve_state, n_thr, t),
                pulse,
                altitude,
                qbar,
                rotvec,
            )
            rows += 1
        if finished:
            break

        # --- integrate attitude over the control period, segment by segment ------------------
        environment.aerodynamic_torque(vehicle, qbar, aero)
        t_seg = t
        t_end = t + dt
        exhausted = False
        while t_seg < t_end - 1e-12:
            valves_active = rcs.update(valve_state, thrusters, n_thr, t_seg, level, valves_active)
            active = valves_active != 0
            if active:
                t_next = rcs.next_breakpoint(valve_state, n_thr, t_seg, t_end, valves_active)
            else:  # coasting: the whole rest of the period is one thrust-free segment
                t_next = t_end
            if active and fuel > 0.0:
                impulse = rcs.segment_thrust(
                    valve_state, thrusters, vehicle, arms, level, t_seg, t_next, tau0, tau1, valves_active
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
                dynamics.rk4_step(x, h, tau_a, tau_b, inertia, inertia_inv, rk4_work)
                rk4_steps += 1
            fuel -= rcs.propellant_for_impulse(vehicle, impulse)
            if fuel <= 0.0 and impulse > 0.0:
                fuel = 0.0
                exhausted = True
            t_seg = t_next
        if mode < N_MODES:
            summary[S_T_MODE + mode] += dt
        if mode == MODE_SSM:
            time_in_ssm += dt
        step += 1
        if exhausted:
            failure = FAIL_PROPELLANT
        finite = True
        for i in range(dynamics.STATE_SIZE):
            if not math.isfinite(x[i]):
                finite = False
        if not finite:
            failure = FAIL_NON_FINITE

    summary[S_SUCCESS] = 1.0 if failure == FAIL_NONE and mode == MODE_DONE else 0.0
    summary[S_FAILURE] = failure
    summary[S_FUEL_REMAINING] = fuel / propellant0
    summary[S_FUEL_USED] = propellant0 - fuel
    summary[S_T_END] = t
    summary[S_THETA_HANDOVER] = theta_handover * _DEG
    summary[S_MODES_COMPLETED] = modes_completed
    summary[S_ALTITUDE_END] = altitude
    summary[S_QBAR_END] = qbar
    summary[S_RK4_STEPS] = rk4_steps
    summary[S_HISTORY_ROWS] = rows
