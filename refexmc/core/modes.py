"""The mode program: what each mode guides toward and when it ends (reference-model sec. 4).

A mission is a list of modes flown in order (``layout.MODE`` rows). Each mode has a guidance
kind, a target, a thrust level, flags and exit conditions (``layout.EXIT`` rows: predicates
combined as an OR of AND groups); a mode that outlasts its timeout fails the run. ReFEx's
NCM -> RDM1 -> SAM -> SSM -> RDM2 -> EAM -> GEEM is seven such rows
(configs/missions/refex-exo.yaml).

Adding a kind, target or predicate: an id and its name below, a branch in :func:`start`,
:func:`reference` or :func:`predicate_holds`, and its entry in ``refexmc.config.schema``.
"""

import math

from refexmc._jit import jit_noalloc
from refexmc.core import environment, guidance, quaternion
from refexmc.core.layout import (
    E_GROUP,
    E_PREDICATE,
    E_VALUE,
    M_BURN_DURATION,
    M_BURN_START,
    M_SUN_DIRECTION,
    MD_ANGLES,
    MD_EXIT_FIRST,
    MD_EXIT_ROWS,
    MD_KIND,
    MD_PREDICT_ALTITUDE,
    MD_QUATERNION,
    MD_RATE,
    MD_T1_DESIGN,
    MD_TARGET,
)

# --- guidance kinds ------------------------------------------------------------------------
KIND_LOCKED = 0  # no reference, actuators off (000 sec. 2.2, NCM)
KIND_RATE_DAMPING = 1  # cubic rate profile to zero from the measured rates (000 eq. 15-19)
KIND_SLEW = 2  # SLERP paced by the quintic to the target (000 eq. 4-14)
KIND_SPIN_UP = 3  # quartic spin-up about a body rate vector from the last target (000 eq. 20-27)
KIND_HOLD = 4  # the target attitude at zero rate
KIND_TRACK = 5  # a target that moves, recomputed every control period
KIND_BURN = 6  # main engine on from the planned ignition to cut-off, steered by core.deorbit
KIND_TRANSLATE = 7  # trajectory local: no attitude reference; the translation law drives the valves
KINDS = {
    "locked": KIND_LOCKED,
    "rate_damping": KIND_RATE_DAMPING,
    "slew": KIND_SLEW,
    "spin_up": KIND_SPIN_UP,
    "hold": KIND_HOLD,
    "track": KIND_TRACK,
    "burn": KIND_BURN,
    "translate": KIND_TRANSLATE,
}

# --- targets -------------------------------------------------------------------------------
TARGET_NONE = 0
TARGET_SUN_HORIZONTAL = 1  # body +y at the sun, body x nearest the local horizontal
TARGET_ENTRY_PREDICTED = 2  # alpha, beta, bank to the velocity predicted at an altitude (two-body)
TARGET_ENTRY_VELOCITY = 3  # alpha, beta, bank to the current velocity
TARGET_INERTIAL = 4  # a fixed inertial attitude
TARGET_PREVIOUS = 5  # the attitude the previous mode targeted (the measured one if none did)
TARGETS = {
    "none": TARGET_NONE,
    "sun_horizontal": TARGET_SUN_HORIZONTAL,
    "entry_predicted": TARGET_ENTRY_PREDICTED,
    "entry_velocity": TARGET_ENTRY_VELOCITY,
    "inertial": TARGET_INERTIAL,
    "previous": TARGET_PREVIOUS,
}

# --- exit predicates (threshold in SI units) -------------------------------------------------
PREDICATE_TIME_IN_MODE = 0  # time in mode >= value
PREDICATE_GUIDANCE_FINISHED = 1  # time in mode > t1 of the mode's profile
PREDICATE_RATES_BELOW = 2  # every |measured body rate| < value
PREDICATE_RATE_ERROR_BELOW = 3  # |measured - reference rate| < value
PREDICATE_ANGLE_ERROR_BELOW = 4  # angle measured attitude -> target < value
PREDICATE_ALTITUDE_BELOW = 5  # navigated altitude < value
PREDICATE_DESCENDING = 6  # navigated climb rate < 0
PREDICATE_QBAR_ABOVE = 7  # dynamic pressure >= value
PREDICATE_MISSION_TIME = 8  # time since t = 0 >= value
PREDICATE_POSITION_ERROR_BELOW = 9  # trajectory local: |position - target| <= value
PREDICATE_SPEED_BELOW = 10  # trajectory local: |velocity| <= value
PREDICATES = {
    "time_in_mode_s": PREDICATE_TIME_IN_MODE,
    "guidance_finished": PREDICATE_GUIDANCE_FINISHED,
    "rates_below_deg_s": PREDICATE_RATES_BELOW,
    "rate_error_below_deg_s": PREDICATE_RATE_ERROR_BELOW,
    "angle_error_below_deg": PREDICATE_ANGLE_ERROR_BELOW,
    "altitude_below_m": PREDICATE_ALTITUDE_BELOW,
    "descending": PREDICATE_DESCENDING,
    "dynamic_pressure_above_pa": PREDICATE_QBAR_ABOVE,
    "mission_time_s": PREDICATE_MISSION_TIME,
    "position_error_below_m": PREDICATE_POSITION_ERROR_BELOW,
    "speed_below_m_s": PREDICATE_SPEED_BELOW,
}

# what the flight software knows this control period, as the predicates read it (``now`` array)
NOW_TIME_IN_MODE = 0
NOW_ALTITUDE = 1
NOW_CLIMB = 2
NOW_QBAR = 3
NOW_TIME = 4
NOW_POSITION_ERROR = 5  # trajectory local (core.local_flight.navigate); else 0
NOW_SPEED = 6
NOW_SIZE = 7


@jit_noalloc
def has_profile(kind):
    """Kinds whose guidance has a transition time t1 (000 eq. 13-14, 19)."""
    return kind == KIND_RATE_DAMPING or kind == KIND_SLEW or kind == KIND_SPIN_UP or kind == KIND_BURN


@jit_noalloc
def target_attitude(mode, mission, traj, q_meas, q_final, has_final, rotations, work):
    """The mode's target attitude at mode start into ``q_final``; ``work`` is (6, 4) scratch."""
    target = int(mode[MD_TARGET])
    if target == TARGET_SUN_HORIZONTAL:
        horizontal = work[3, 0:3]
        environment.local_horizontal(mission, traj, horizontal)
        guidance.sun_attitude(mission[M_SUN_DIRECTION : M_SUN_DIRECTION + 3], horizontal, q_final, work[0:3, 0:3])
    elif target == TARGET_ENTRY_PREDICTED:
        pitch = environment.predicted_velocity_pitch(mission, traj, mode[MD_PREDICT_ALTITUDE])
        guidance.entry_attitude_from(pitch, rotations, q_final, work[4:6])
    elif target == TARGET_ENTRY_VELOCITY:
        guidance.entry_attitude_from(environment.velocity_pitch(traj), rotations, q_final, work[4:6])
    elif target == TARGET_INERTIAL:
        for i in range(4):
            q_final[i] = mode[MD_QUATERNION + i]
    elif not has_final:  # TARGET_PREVIOUS (or none) with no previous target: hold what is measured
        for i in range(4):
            q_final[i] = q_meas[i]


@jit_noalloc
def start(mode, mission, traj, t, q_meas, rate_meas, accel, guid, q_final, has_final, rotations, work):
    """Begin ``mode`` (its row of the mode table) at ``t``; returns whether ``q_final`` is set.

    ``accel`` is the guidance acceleration limit of the mode's thrust level; ``rotations`` (3, 4)
    receives the constant factors of an entry target; ``work`` is (6, 4) scratch.
    """
    kind = int(mode[MD_KIND])
    target = int(mode[MD_TARGET])
    if target == TARGET_ENTRY_PREDICTED or target == TARGET_ENTRY_VELOCITY:
        guidance.aerodynamic_rotations(mode[MD_ANGLES], mode[MD_ANGLES + 1], mode[MD_ANGLES + 2], rotations)
    if kind == KIND_RATE_DAMPING:
        guidance.start_rate_damping(guid, t, rate_meas, accel)
        return has_final
    if kind == KIND_SPIN_UP:
        if not has_final:
            for i in range(4):
                q_final[i] = q_meas[i]
        guidance.start_spin_up(guid, t, q_final, mode[MD_RATE : MD_RATE + 3], accel)
        return True
    if kind == KIND_BURN:  # t1: the planned cut-off; the target follows core.deorbit's steering
        guid[guidance.G_T1] = mission[M_BURN_START] + mission[M_BURN_DURATION] - t
        return has_final
    if kind == KIND_SLEW or kind == KIND_HOLD:
        target_attitude(mode, mission, traj, q_meas, q_final, has_final, rotations, work)
        if kind == KIND_SLEW:
            guidance.start_slerp(guid, t, q_meas, q_final, accel, mode[MD_T1_DESIGN], work[3])
        return True
    return has_final


@jit_noalloc(force_inline=True)
def reference(mode, mission, vehicle, atmosphere, traj, t, guid, q_final, rotations, q_ref, rate_ref, accel_ref, work):
    """Reference attitude, rate and acceleration of ``mode`` at ``t``; ``work`` is (6, 4) scratch.

    Returns ``(attitude_controlled, has_attitude_reference)``: rate damping controls rates only,
    a locked mode nothing.
    """
    kind = int(mode[MD_KIND])
    if kind == KIND_RATE_DAMPING:
        guidance.rate_damping_reference(guid, t, rate_ref, accel_ref)
        return False, False
    if kind == KIND_SLEW:
        guidance.slerp_reference(guid, t, q_ref, rate_ref, accel_ref)
    elif kind == KIND_SPIN_UP:
        guidance.spin_up_reference(guid, t, q_ref, rate_ref, accel_ref, work[3])
    elif kind == KIND_TRACK:  # entry attitude to the current velocity (000 sec. 2.2, GEEM)
        guidance.entry_attitude_from(environment.velocity_pitch(traj), rotations, q_ref, work[4:6])
        inertial_rate = work[3]
        inertial_rate[0] = 0.0
        inertial_rate[1] = environment.velocity_pitch_rate(mission, vehicle, atmosphere, traj)
        inertial_rate[2] = 0.0  # the velocity turns about inertial y
        quaternion.rotate_inverse(q_ref, inertial_rate[0:3], rate_ref)
        for i in range(3):
            accel_ref[i] = 0.0
    elif kind == KIND_HOLD or kind == KIND_BURN:
        for i in range(4):
            q_ref[i] = q_final[i]
        for i in range(3):
            rate_ref[i] = 0.0
            accel_ref[i] = 0.0
    else:  # locked: no reference, actuators off
        for i in range(3):
            rate_ref[i] = 0.0
            accel_ref[i] = 0.0
        return False, False
    return True, True


@jit_noalloc
def predicate_holds(predicate, value, now, t1, rate_meas, rate_ref, q_meas, q_target):
    """One exit predicate (``PREDICATE_*``) against its threshold ``value``."""
    if predicate == PREDICATE_TIME_IN_MODE:
        return now[NOW_TIME_IN_MODE] >= value
    if predicate == PREDICATE_GUIDANCE_FINISHED:
        return now[NOW_TIME_IN_MODE] > t1
    if predicate == PREDICATE_RATES_BELOW:
        return abs(rate_meas[0]) < value and abs(rate_meas[1]) < value and abs(rate_meas[2]) < value
    if predicate == PREDICATE_RATE_ERROR_BELOW:
        dx, dy, dz = rate_meas[0] - rate_ref[0], rate_meas[1] - rate_ref[1], rate_meas[2] - rate_ref[2]
        error = math.sqrt(dx * dx + dy * dy + dz * dz)
        return error < value
    if predicate == PREDICATE_ANGLE_ERROR_BELOW:
        return quaternion.angle_between(q_meas, q_target) < value
    if predicate == PREDICATE_ALTITUDE_BELOW:
        return now[NOW_ALTITUDE] < value
    if predicate == PREDICATE_DESCENDING:
        return now[NOW_CLIMB] < 0.0
    if predicate == PREDICATE_QBAR_ABOVE:
        return now[NOW_QBAR] >= value
    if predicate == PREDICATE_MISSION_TIME:
        return now[NOW_TIME] >= value
    if predicate == PREDICATE_POSITION_ERROR_BELOW:
        return now[NOW_POSITION_ERROR] <= value
    if predicate == PREDICATE_SPEED_BELOW:
        return now[NOW_SPEED] <= value
    return False


@jit_noalloc
def exit_reached(mode, exits, now, t1, rate_meas, rate_ref, q_meas, q_target):
    """Whether every predicate of one of the mode's exit groups holds (rows in group order)."""
    first = int(mode[MD_EXIT_FIRST])
    last = first + int(mode[MD_EXIT_ROWS])
    row = first
    while row < last:
        group = exits[row, E_GROUP]
        holds = True
        while row < last and exits[row, E_GROUP] == group:
            if holds:  # the rest of a failed group is skipped (cheap predicates come first)
                holds = predicate_holds(
                    int(exits[row, E_PREDICATE]), exits[row, E_VALUE], now, t1, rate_meas, rate_ref, q_meas, q_target
                )
            row += 1
        if holds:
            return True
    return False
