"""A closed-loop entry (issue 24, 003): 6-DOF flight over a rotating spherical Earth with body
flaps, rudders and RCS blended for least propellant.

- Translation: 003 eq. 3 (core.entry) with alpha, beta and bank taken from the body attitude
  (core.entry_attitude) at every integration stage.
- Rotation: 003 eq. 4, Euler's equation with the full inertia (I_xz), core.dynamics, under the
  aerodynamic moments (static sideslip terms, C_m at zero deflection, the surfaces' moments at
  their actual deflections) and the thruster moments held over the control period.
- Control, every period: outer loop on the aerodynamic angles (the angle errors and, below the
  RCS-only altitude, their clamped integrals, times a gain give the rates of alpha, beta and
  bank, turned into body rates by the kinematics of the aerodynamic angles with the flight-path
  terms neglected); inner loop by dynamic inversion of eq. 4
  (M = J omega_dot_d + omega x J omega less the static aerodynamic moment); the moment is blended
  by core.blending (003 eq. 5-10) and the thrusters' share saturated at their per-axis capacity.
  Propellant: 003 eq. 5 with the vehicle's weights (config.entry.propellant_weights).
- Mode program (003): RCS alone above ``CT_RCS_ONLY_ABOVE_M`` (surfaces held where they are),
  flaps and RCS below, rudders below ``SF_RUDDER_MACH``; a blocked flap stays at its deflection and
  the flight software knows it.
- Surfaces: first-order lag with a rate limit, within their deflection limits; the flaps also
  within the hinge-moment limit (003 Table 1) as a deflection limit that falls with q.
- Guidance: alpha(Mach) and bank(speed) schedules, beta = 0; with a flap blocked, the angle of
  attack at which the flaps trim at the blocked deflection (003: alpha "has to be increased"),
  corrected by feedback on the free flap's misalignment (:func:`align`).

- Thrusters: the moment of each control period acts ``CT_RCS_DELAY_S`` after the control instant
  (valve opening and closing); until then the previous period's moment acts (:func:`advance`).
- Mass properties: the dynamics fly the true inertia, the dynamic inversion the flight
  software's (``EntryVehicle.fsw_inertia``).

Metrics: RCS propellant, tracking errors, peak q, load factor and stagnation-point heat flux
(Sutton-Graves), down- and cross-range at the end. Not modelled yet: navigation errors, the valve
rise and fall (the moment steps). Units SI, angles rad.
"""

import math
from typing import NamedTuple

import numpy as np

from refexmc._jit import jit, jit_noalloc
from refexmc.core import aerodynamics, blending, dynamics, elementary, entry, entry_attitude, quaternion
from refexmc.core.aerodynamics import (
    AC_DRAG,
    AC_LIFT,
    AC_PITCH,
    AC_PITCH_ELEVON,
    AC_ROLL_AILERON,
    AC_ROLL_BETA,
    AC_ROLL_RUDDER,
    AC_SIDE_BETA,
    AC_YAW_AILERON,
    AC_YAW_BETA,
    AC_YAW_RUDDER,
)
from refexmc.core.entry import ENTRY_STATE_SIZE, PLANET_ROTATION, REF_AREA, REF_LENGTH

FLIGHT_STATE_SIZE = ENTRY_STATE_SIZE + dynamics.STATE_SIZE  # [entry (6), quaternion (4), rates (3)]

# surfaces: limits (rad), rates (rad/s), lag (s), the blocked flap
SF_FLAP_MIN, SF_FLAP_MAX, SF_RUDDER_MIN, SF_RUDDER_MAX = 0, 1, 2, 3
SF_RUDDER_MACH = 4  # rudders move below this Mach; neutral above (003: 6)
SF_FLAP_RATE, SF_RUDDER_RATE, SF_TIME_CONSTANT = 5, 6, 7
SF_BLOCKED_FLAP = 8  # -1 none, 0 left, 1 right
SF_BLOCKED_DEFLECTION = 9
SF_HAS_RUDDERS = 10
SF_HINGE_MOMENT_MAX = 11  # N m; 0: no hinge-moment limit
SF_HINGE_AREA_ARM = 12  # S_f c, m^3
SF_BLOCKED_KNOWN = 13  # 1: the flight software knows the blocked flap; 0: it commands it as free
SURFACE_PARAMETERS = 14

# control and run: period, gains, mode switch, terminal conditions, RCS capacity and weights
CT_PERIOD = 0
CT_ANGLE_GAIN = 1  # alpha, beta, bank errors -> their rates (1/s), three slots
CT_RATE_GAIN = 4  # body-rate error -> angular acceleration (1/s)
CT_RCS_ONLY_ABOVE_M = 5
CT_TERMINAL_MACH = 6
CT_FLOOR_ALTITUDE_M = 7
CT_MAX_TIME_S = 8
CT_RCS_CAPACITY = 9  # largest thruster moment per body axis (N m), three slots
CT_WEIGHTS = 12  # b_th K_i, kg/s per N m, three slots
CT_TRANSIENT_S = 15  # tracking errors count after this time and this long after a mode change
CT_MASS = 16
CT_NOSE_RADIUS_M = 17  # for the stagnation-point heat flux; 0: not computed
CT_INTEGRAL_GAIN = 18  # integral of the angle errors in the outer loop (1/s); 0: none
CT_INTEGRAL_LIMIT = 19  # anti-windup: |integral of the alpha, beta, bank error| at most (rad s), three slots
CT_ALIGN_GAIN = 22  # blocked flap known: alpha bias rate per rad of free-flap misalignment (1/s)
CT_ALIGN_LIMIT = 23  # |alpha bias| at most this (rad)
CT_RCS_DELAY_S = 24  # the thrusters' moment acts this long after the control instant (s), below CT_PERIOD
CONTROL_PARAMETERS = 25
SUTTON_GRAVES_EARTH = 1.7415e-4  # kg^0.5 / m: q_dot = k sqrt(rho / R_n) V^3 (W/m^2), Earth air

# summary
SU_TIME, SU_PROPELLANT, SU_ALPHA_ERROR, SU_BETA_ERROR, SU_BANK_ERROR = 0, 1, 2, 3, 4
SU_PEAK_QBAR, SU_PEAK_LOAD, SU_STATUS, SU_STEPS = 5, 6, 7, 8
SU_PEAK_HEAT_FLUX, SU_DOWN_RANGE, SU_CROSS_RANGE = 9, 10, 11  # W/m^2, m, m (at the end)
SU_MODE_TIME = 12  # time flown in each mode (HI_MODE order), s, three slots
SUMMARY_SIZE = 15
STATUS_TERMINAL_MACH, STATUS_FLOOR, STATUS_TIME_LIMIT = 1, 2, 3

# history columns, one row per second
HI_TIME, HI_ALTITUDE, HI_SPEED, HI_MACH, HI_ALPHA, HI_BETA, HI_BANK = 0, 1, 2, 3, 4, 5, 6
HI_ALPHA_CMD, HI_BANK_CMD, HI_LEFT, HI_RIGHT, HI_RUDDER, HI_PROPELLANT, HI_QBAR = 7, 8, 9, 10, 11, 12, 13
HI_MODE = 14  # the mode program's mode: 0 RCS alone, 1 flaps and RCS, 2 flaps, rudders and RCS
HI_LOAD = 15  # aerodynamic load factor |L + D + Y| / (m g0)
HI_HEAT_FLUX = 16  # stagnation-point heat flux (Sutton-Graves), W/m^2; NaN without a nose radius
HISTORY_COLUMNS = 17  # the mode names: config.entry.MODE_NAMES


class EntryVehicle(NamedTuple):
    """What an entry flight flies: the true aerodynamic model (dispersed air and coefficients),
    the flight software's (nominal) one, mass properties and the parameters."""

    model: entry.EntryModel  # the truth the dynamics fly
    inertia: np.ndarray  # (3, 3) kg m^2, with I_xz (003 eq. 4): the truth the dynamics fly
    inertia_inv: np.ndarray
    surfaces: np.ndarray  # SF_*
    control: np.ndarray  # CT_*
    alpha_schedule: np.ndarray  # (2, n): Mach (increasing), alpha (rad)
    bank_schedule: np.ndarray  # (2, n): speed m/s (increasing), bank (rad)
    fsw_model: entry.EntryModel  # what the flight software's control, blending and guidance use
    fsw_inertia: np.ndarray  # (3, 3) kg m^2: what the flight software's dynamic inversion uses


class Work(NamedTuple):
    state: np.ndarray  # FLIGHT_STATE_SIZE
    stage: np.ndarray  # (5, FLIGHT_STATE_SIZE)
    axes: np.ndarray  # entry_attitude.AXES_SCRATCH
    deflection: np.ndarray  # (3,) actual: left, right, rudder
    command: np.ndarray  # (3,) commanded deflections
    thruster: np.ndarray  # (3,) thruster moment held over the period (N m)
    torque: np.ndarray  # (3,) scratch
    effectiveness: np.ndarray  # (3, 3)
    offset: np.ndarray  # (3,)
    lower: np.ndarray  # (3,)
    upper: np.ndarray  # (3,)
    blend_work: np.ndarray  # blending.scratch_shape()
    basis: np.ndarray  # (3,) int64
    in_basis: np.ndarray  # (BLEND_COLUMNS,) bool
    coefficients: np.ndarray  # (AERO_COEFFICIENTS,) at the current stage
    integral: np.ndarray  # (3,) integrals of the alpha, beta, bank errors (rad s)
    alpha_bias: np.ndarray  # (1,) the alignment guidance's correction to the trim alpha (rad)
    thruster_previous: np.ndarray  # (3,) the previous period's thruster moment (N m), acting until the delay


@jit
def work():
    """An entry flight's work arrays (allocated once per flight)."""
    return Work(
        np.zeros(FLIGHT_STATE_SIZE),
        np.zeros((5, FLIGHT_STATE_SIZE)),
        np.zeros((8, 3)),
        np.zeros(3),
        np.zeros(3),
        np.zeros(3),
        np.zeros(3),
        np.zeros((3, 3)),
        np.zeros(3),
        np.zeros(3),
        np.zeros(3),
        np.zeros((11, blending.BLEND_COLUMNS)),
        np.zeros(3, dtype=np.int64),
        np.zeros(blending.BLEND_COLUMNS, dtype=np.bool_),
        np.zeros(aerodynamics.AERO_COEFFICIENTS),
        np.zeros(3),
        np.zeros(1),
        np.zeros(3),
    )


@jit_noalloc
def schedule(table, x):
    """Piecewise-linear ``table[1]`` over ``table[0]`` at ``x``, held at the ends."""
    k, f = aerodynamics.axis_cell(table[0], x)
    if table.shape[1] == 1:
        return table[1, 0]
    return table[1, k] + f * (table[1, k + 1] - table[1, k])


@jit_noalloc
def _coefficient(model, slot, alpha, mach):
    return aerodynamics.coefficient(model.alpha_axis, model.mach_axis, model.coefficients, slot, alpha, mach)


@jit_noalloc
def aerodynamic_moment(c, beta, qsl, deflection, out):
    """Body moments (N m) for the coefficients ``c`` (AERO_COEFFICIENTS, at the flight
    condition): static sideslip terms, C_m at zero deflection and the surfaces at ``deflection``
    (left, right, rudder): elevon (l + r) / 2, aileron (l - r) / 2."""
    elevon = 0.5 * (deflection[0] + deflection[1])
    aileron = 0.5 * (deflection[0] - deflection[1])
    rudder = deflection[2]
    out[0] = qsl * (c[AC_ROLL_BETA] * beta + c[AC_ROLL_AILERON] * aileron + c[AC_ROLL_RUDDER] * rudder)
    out[1] = qsl * (c[AC_PITCH] + c[AC_PITCH_ELEVON] * elevon)
    out[2] = qsl * (c[AC_YAW_BETA] * beta + c[AC_YAW_AILERON] * aileron + c[AC_YAW_RUDDER] * rudder)


@jit_noalloc
def _air_and_coefficients(model, wk, translation, alpha):
    """(qbar, mach, q S L) at ``translation``; every coefficient at (alpha, mach) into
    ``wk.coefficients``."""
    _, qbar, mach = entry.air_data(model, translation)
    aerodynamics.coefficients_at(model.alpha_axis, model.mach_axis, model.coefficients, alpha, mach, wk.coefficients)
    return qbar, mach, qbar * model.reference[REF_AREA] * model.reference[REF_LENGTH]


@jit_noalloc
def derivative(vehicle, wk, x, t, out):
    """d/dt of the flight state ``x`` at time ``t``: 003 eq. 3 and eq. 4 coupled through the
    aerodynamic angles of the body attitude; surfaces and thruster moments as held in ``wk``."""
    model = vehicle.model
    rotation = model.planet[PLANET_ROTATION]
    translation = x[0:ENTRY_STATE_SIZE]
    rotational = x[ENTRY_STATE_SIZE:FLIGHT_STATE_SIZE]
    alpha, beta, bank = entry_attitude.aerodynamic_angles(translation, t, rotation, rotational[0:4], wk.axes)
    qbar, mach, qsl = _air_and_coefficients(model, wk, translation, alpha)
    c = wk.coefficients
    qs = qbar * model.reference[REF_AREA]
    lift, drag, side = qs * c[AC_LIFT], qs * c[AC_DRAG], qs * c[AC_SIDE_BETA] * beta
    entry.equations_of_motion(
        model, translation, vehicle.control[CT_MASS], bank, lift, drag, side, out[0:ENTRY_STATE_SIZE]
    )
    aerodynamic_moment(c, beta, qsl, wk.deflection, wk.torque)
    for i in range(3):
        wk.torque[i] += wk.thruster[i]
    dynamics.derivative(
        rotational, wk.torque, vehicle.inertia, vehicle.inertia_inv, out[ENTRY_STATE_SIZE:FLIGHT_STATE_SIZE]
    )


@jit_noalloc
def rk4_step(vehicle, wk, t, dt):
    """One RK4 step of the flight state in ``wk.state``; the quaternion is renormalised."""
    x, stage = wk.state, wk.stage
    k1, k2, k3, k4, tmp = stage[0], stage[1], stage[2], stage[3], stage[4]
    n = FLIGHT_STATE_SIZE
    derivative(vehicle, wk, x, t, k1)
    for i in range(n):
        tmp[i] = x[i] + 0.5 * dt * k1[i]
    derivative(vehicle, wk, tmp, t + 0.5 * dt, k2)
    for i in range(n):
        tmp[i] = x[i] + 0.5 * dt * k2[i]
    derivative(vehicle, wk, tmp, t + 0.5 * dt, k3)
    for i in range(n):
        tmp[i] = x[i] + dt * k3[i]
    derivative(vehicle, wk, tmp, t + dt, k4)
    for i in range(n):
        x[i] += dt / 6.0 * (k1[i] + 2.0 * (k2[i] + k3[i]) + k4[i])
    quaternion.normalize(x[ENTRY_STATE_SIZE : ENTRY_STATE_SIZE + 4])


@jit_noalloc
def trim_alpha(model, mach, deflection, fallback):
    """The lowest angle of attack at which the flaps trim at ``deflection`` (003: with a flap
    blocked, "the commanded angle of attack has to be increased" so that the free flap aligns
    with the blocked one): delta_trim(alpha) = -C_m / C_m_delta_e = deflection; ``fallback`` where
    the table has no such alpha. At a fixed Mach both coefficients are linear in alpha on each
    cell of the alpha axis, so on a cell C_m + deflection C_m_delta_e = 0 is solved exactly."""
    axis = model.alpha_axis
    previous = 0.0
    for k in range(axis.shape[0]):
        value = _coefficient(model, AC_PITCH, axis[k], mach) + deflection * _coefficient(
            model, AC_PITCH_ELEVON, axis[k], mach
        )
        if value == 0.0:
            return axis[k]
        if k > 0 and previous * value < 0.0:
            share = previous / (previous - value)
            return axis[k - 1] + share * (axis[k] - axis[k - 1])
        previous = value
    return fallback


@jit_noalloc
def hinge_limit(qbar, alpha, hinge_moment_max, area_arm):
    """Largest flap deflection (rad) whose hinge moment 2 q S_f c sin^2(alpha + delta) (Newtonian
    pressure on the flap) stays within ``hinge_moment_max`` (003 Table 1); pi/2 - alpha where any
    deflection does."""
    if hinge_moment_max <= 0.0 or qbar <= 0.0:
        return 0.5 * math.pi - alpha
    ratio = hinge_moment_max / (2.0 * qbar * area_arm)
    if ratio >= 1.0:
        return 0.5 * math.pi - alpha
    return elementary.asin(math.sqrt(ratio)) - alpha


@jit_noalloc
def align(vehicle, wk, mach, blocked, fallback):
    """Angle-of-attack command with a flap blocked and known (003: "aligning the remaining body
    flap with the blocked one"): the model's trim alpha for the blocked deflection
    (:func:`trim_alpha`) plus a bias that feedback on the free flap's misalignment builds below
    the RCS-only altitude, so that model errors do not leave the free flap trimming against the
    blocked one. The bias moves alpha by the model's d(delta_trim)/d(alpha) towards alignment at
    ``CT_ALIGN_GAIN`` per second, within +-``CT_ALIGN_LIMIT``."""
    ct, sf, model = vehicle.control, vehicle.surfaces, vehicle.fsw_model
    block = sf[SF_BLOCKED_DEFLECTION]
    base = trim_alpha(model, mach, block, fallback)
    if wk.state[entry.EN_ALTITUDE] < ct[CT_RCS_ONLY_ABOVE_M] and ct[CT_ALIGN_GAIN] > 0.0:
        alpha = base + wk.alpha_bias[0]
        step = 0.01
        slope = (_trim_deflection(model, alpha + step, mach) - _trim_deflection(model, alpha - step, mach)) / (
            2.0 * step
        )
        if slope != 0.0:
            misalignment = wk.deflection[1 - blocked] - block
            bias = wk.alpha_bias[0] - ct[CT_ALIGN_GAIN] * ct[CT_PERIOD] * misalignment / slope
            wk.alpha_bias[0] = min(max(bias, -ct[CT_ALIGN_LIMIT]), ct[CT_ALIGN_LIMIT])
    return base + wk.alpha_bias[0]


@jit_noalloc
def _trim_deflection(model, alpha, mach):
    """delta_trim = -C_m / C_m_delta_e of the model (003 eq. 6)."""
    return -_coefficient(model, AC_PITCH, alpha, mach) / _coefficient(model, AC_PITCH_ELEVON, alpha, mach)


@jit_noalloc
def _wrap(angle):
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


@jit_noalloc
def control(vehicle, wk, t, alpha_cmd, bank_cmd):
    """One control period's commands: surfaces to ``wk.command``, thruster moment to
    ``wk.thruster``; returns (propellant rate kg/s, alpha, beta, bank, mach, qbar, mode)."""
    model, ct, sf = vehicle.fsw_model, vehicle.control, vehicle.surfaces
    x = wk.state
    translation = x[0:ENTRY_STATE_SIZE]
    rotation = model.planet[PLANET_ROTATION]
    alpha, beta, bank = entry_attitude.aerodynamic_angles(
        translation, t, rotation, x[ENTRY_STATE_SIZE : ENTRY_STATE_SIZE + 4], wk.axes
    )
    qbar, mach, qsl = _air_and_coefficients(model, wk, translation, alpha)
    c = wk.coefficients
    p, q, r = x[ENTRY_STATE_SIZE + 4], x[ENTRY_STATE_SIZE + 5], x[ENTRY_STATE_SIZE + 6]
    # outer loop: angle errors -> rates of alpha, beta, bank -> body rates (kinematics of the
    # aerodynamic angles, flight-path terms neglected: bank_dot = p_s / cos b, alpha_dot = q -
    # tan b p_s, beta_dot = -r_s with stability-axis rates p_s = p cos a + r sin a, r_s = r cos a - p sin a)
    # with integral action on the angle errors below the RCS-only altitude (the flight software's
    # model is not the truth: 003's "dynamic inversion plus feedback"), clamped against wind-up
    errors_alpha, errors_beta, errors_bank = alpha_cmd - alpha, 0.0 - beta, _wrap(bank_cmd - bank)
    if translation[entry.EN_ALTITUDE] < ct[CT_RCS_ONLY_ABOVE_M] and ct[CT_INTEGRAL_GAIN] > 0.0:
        dt = ct[CT_PERIOD]
        limit = ct[CT_INTEGRAL_LIMIT]
        wk.integral[0] = min(max(wk.integral[0] + errors_alpha * dt, -limit), limit)
        limit = ct[CT_INTEGRAL_LIMIT + 1]
        wk.integral[1] = min(max(wk.integral[1] + errors_beta * dt, -limit), limit)
        limit = ct[CT_INTEGRAL_LIMIT + 2]
        wk.integral[2] = min(max(wk.integral[2] + errors_bank * dt, -limit), limit)
    ki = ct[CT_INTEGRAL_GAIN]
    alpha_dot = ct[CT_ANGLE_GAIN] * (errors_alpha + ki * wk.integral[0])
    beta_dot = ct[CT_ANGLE_GAIN + 1] * (errors_beta + ki * wk.integral[1])
    bank_dot = ct[CT_ANGLE_GAIN + 2] * (errors_bank + ki * wk.integral[2])
    sa, ca = elementary.sincos(alpha)
    p_s = bank_dot * elementary.cos(beta)
    r_s = -beta_dot
    p_cmd = p_s * ca - r_s * sa
    q_cmd = alpha_dot + elementary.tan(beta) * p_s
    r_cmd = p_s * sa + r_s * ca
    # inner loop: dynamic inversion of 003 eq. 4
    k = ct[CT_RATE_GAIN]
    wdx, wdy, wdz = k * (p_cmd - p), k * (q_cmd - q), k * (r_cmd - r)
    j = vehicle.fsw_inertia
    hx = j[0, 0] * p + j[0, 1] * q + j[0, 2] * r
    hy = j[1, 0] * p + j[1, 1] * q + j[1, 2] * r
    hz = j[2, 0] * p + j[2, 1] * q + j[2, 2] * r
    tau = wk.torque
    tau[0] = j[0, 0] * wdx + j[0, 1] * wdy + j[0, 2] * wdz + (q * hz - r * hy)
    tau[1] = j[1, 0] * wdx + j[1, 1] * wdy + j[1, 2] * wdz + (r * hx - p * hz)
    tau[2] = j[2, 0] * wdx + j[2, 1] * wdy + j[2, 2] * wdz + (p * hy - q * hx)
    tau[0] -= qsl * c[AC_ROLL_BETA] * beta
    tau[2] -= qsl * c[AC_YAW_BETA] * beta
    # mode program (003) and the surfaces' bounds for the blend
    aero_mode = translation[entry.EN_ALTITUDE] < ct[CT_RCS_ONLY_ABOVE_M]
    rudders_usable = sf[SF_HAS_RUDDERS] > 0.0 and mach < sf[SF_RUDDER_MACH]
    flap_top = min(sf[SF_FLAP_MAX], hinge_limit(qbar, alpha, sf[SF_HINGE_MOMENT_MAX], sf[SF_HINGE_AREA_ARM]))
    for i in range(2):
        if aero_mode:
            wk.lower[i], wk.upper[i] = sf[SF_FLAP_MIN], max(flap_top, sf[SF_FLAP_MIN])
        else:
            wk.lower[i] = wk.upper[i] = wk.deflection[i]
    blocked = int(sf[SF_BLOCKED_FLAP])
    if blocked >= 0 and sf[SF_BLOCKED_KNOWN] > 0.0:
        wk.lower[blocked] = wk.upper[blocked] = sf[SF_BLOCKED_DEFLECTION]
    if rudders_usable and aero_mode:
        wk.lower[2], wk.upper[2] = sf[SF_RUDDER_MIN], sf[SF_RUDDER_MAX]
    else:
        wk.lower[2] = wk.upper[2] = 0.0
    c_m_de = c[AC_PITCH_ELEVON]
    trim = -c[AC_PITCH] / c_m_de if c_m_de != 0.0 else 0.0
    blending.surface_moments(
        qsl, c[AC_ROLL_AILERON], c_m_de, c[AC_YAW_AILERON], c[AC_ROLL_RUDDER], c[AC_YAW_RUDDER], trim,
        wk.effectiveness, wk.offset,
    )  # fmt: skip
    weights = ct[CT_WEIGHTS : CT_WEIGHTS + 3]
    blending.blend(
        wk.effectiveness,
        wk.offset,
        tau,
        wk.lower,
        wk.upper,
        weights,
        wk.command,
        wk.thruster,
        wk.blend_work,
        wk.basis,
        wk.in_basis,
    )
    rate = 0.0
    for i in range(3):
        cap = ct[CT_RCS_CAPACITY + i]
        wk.thruster[i] = min(max(wk.thruster[i], -cap), cap)
        rate += weights[i] * abs(wk.thruster[i])
    mode = 0 if not aero_mode else (2 if rudders_usable else 1)
    return rate, alpha, beta, bank, mach, qbar, mode


@jit_noalloc
def actuate(vehicle, wk, dt):
    """Surfaces towards their commands over one period: first-order lag, rate limit; a blocked
    flap does not move."""
    sf = vehicle.surfaces
    tau = sf[SF_TIME_CONSTANT]
    share = 1.0 - elementary.exp(-dt / tau) if tau > 0.0 else 1.0
    blocked = int(sf[SF_BLOCKED_FLAP])
    for i in range(3):
        if i == blocked:
            wk.deflection[i] = sf[SF_BLOCKED_DEFLECTION]
            continue
        limit = (sf[SF_RUDDER_RATE] if i == 2 else sf[SF_FLAP_RATE]) * dt
        step = min(max((wk.command[i] - wk.deflection[i]) * share, -limit), limit)
        wk.deflection[i] += step


@jit_noalloc
def advance(vehicle, wk, t, dt, delay):
    """The flight state over one control period from ``t``: the thrusters give
    ``wk.thruster_previous`` until ``t + delay`` and ``wk.thruster`` (this period's) after it, an
    RK4 step on each side of the switch (one step when ``delay`` is 0). Afterwards both hold this
    period's moment."""
    if delay <= 0.0:
        rk4_step(vehicle, wk, t, dt)
    else:
        for i in range(3):
            held = wk.thruster_previous[i]
            wk.thruster_previous[i] = wk.thruster[i]
            wk.thruster[i] = held
        rk4_step(vehicle, wk, t, delay)
        for i in range(3):
            wk.thruster[i] = wk.thruster_previous[i]
        rk4_step(vehicle, wk, t + delay, dt - delay)
    for i in range(3):
        wk.thruster_previous[i] = wk.thruster[i]


@jit_noalloc
def fly(vehicle, wk, initial, history, summary):
    """Fly from ``initial`` (FLIGHT_STATE_SIZE) to the terminal Mach, the altitude floor or the
    time limit. ``history``: (rows, HISTORY_COLUMNS), one row per second while it lasts;
    ``summary``: SUMMARY_SIZE. Returns the number of history rows written."""
    ct = vehicle.control
    dt = ct[CT_PERIOD]
    for i in range(FLIGHT_STATE_SIZE):
        wk.state[i] = initial[i]
    blocked = int(vehicle.surfaces[SF_BLOCKED_FLAP])
    for i in range(3):
        wk.deflection[i] = 0.0
        wk.command[i] = 0.0
        wk.thruster[i] = 0.0
        wk.thruster_previous[i] = 0.0
        wk.integral[i] = 0.0
    wk.alpha_bias[0] = 0.0
    if blocked >= 0:
        wk.deflection[blocked] = vehicle.surfaces[SF_BLOCKED_DEFLECTION]
    for i in range(SUMMARY_SIZE):
        summary[i] = 0.0
    t = 0.0
    propellant = 0.0
    rows = 0
    next_row = 0.0
    last_mode = -1
    mode_since = 0.0
    steps = 0
    status = STATUS_TIME_LIMIT
    delay = ct[CT_RCS_DELAY_S]
    previous_rate = 0.0  # propellant rate of the moment acting until the delay
    while t < ct[CT_MAX_TIME_S]:
        speed = wk.state[entry.EN_SPEED]
        _, _, mach_now = entry.air_data(vehicle.fsw_model, wk.state[0:ENTRY_STATE_SIZE])
        alpha_cmd = schedule(vehicle.alpha_schedule, mach_now)
        if blocked >= 0 and vehicle.surfaces[SF_BLOCKED_KNOWN] > 0.0:  # fly where the flaps trim at it
            alpha_cmd = align(vehicle, wk, mach_now, blocked, alpha_cmd)
        bank_cmd = schedule(vehicle.bank_schedule, speed)
        rate, alpha, beta, bank, _, _, mode = control(vehicle, wk, t, alpha_cmd, bank_cmd)
        qbar, mach, _ = _air_and_coefficients(vehicle.model, wk, wk.state[0:ENTRY_STATE_SIZE], alpha)  # the truth
        if mach < ct[CT_TERMINAL_MACH]:
            status = STATUS_TERMINAL_MACH
            break
        if wk.state[entry.EN_ALTITUDE] < ct[CT_FLOOR_ALTITUDE_M]:
            status = STATUS_FLOOR
            break
        if mode != last_mode:
            last_mode = mode
            mode_since = t
        if t >= ct[CT_TRANSIENT_S] and t - mode_since >= ct[CT_TRANSIENT_S]:
            summary[SU_ALPHA_ERROR] = max(summary[SU_ALPHA_ERROR], abs(alpha_cmd - alpha))
            summary[SU_BETA_ERROR] = max(summary[SU_BETA_ERROR], abs(beta))
            summary[SU_BANK_ERROR] = max(summary[SU_BANK_ERROR], abs(_wrap(bank_cmd - bank)))
        summary[SU_PEAK_QBAR] = max(summary[SU_PEAK_QBAR], qbar)
        c = wk.coefficients  # true, at the control period's condition
        force = qbar * vehicle.model.reference[REF_AREA]
        lift, drag, side = force * c[AC_LIFT], force * c[AC_DRAG], force * c[AC_SIDE_BETA] * beta
        load = math.sqrt(lift * lift + drag * drag + side * side) / (ct[CT_MASS] * 9.80665)
        summary[SU_PEAK_LOAD] = max(summary[SU_PEAK_LOAD], load)
        heat = math.nan
        if ct[CT_NOSE_RADIUS_M] > 0.0:
            rho = 2.0 * qbar / (speed * speed)
            heat = SUTTON_GRAVES_EARTH * math.sqrt(rho / ct[CT_NOSE_RADIUS_M]) * speed * speed * speed
            summary[SU_PEAK_HEAT_FLUX] = max(summary[SU_PEAK_HEAT_FLUX], heat)
        if t >= next_row and rows < history.shape[0]:
            h = history[rows]
            h[HI_TIME], h[HI_ALTITUDE], h[HI_SPEED], h[HI_MACH] = t, wk.state[entry.EN_ALTITUDE], speed, mach
            h[HI_ALPHA], h[HI_BETA], h[HI_BANK] = alpha, beta, bank
            h[HI_ALPHA_CMD], h[HI_BANK_CMD] = alpha_cmd, bank_cmd
            h[HI_LEFT], h[HI_RIGHT], h[HI_RUDDER] = wk.deflection[0], wk.deflection[1], wk.deflection[2]
            h[HI_PROPELLANT], h[HI_QBAR], h[HI_MODE] = propellant, qbar, mode
            h[HI_LOAD], h[HI_HEAT_FLUX] = load, heat
            rows += 1
            next_row += 1.0
        actuate(vehicle, wk, dt)
        advance(vehicle, wk, t, dt, delay)
        if delay > 0.0:  # 003 eq. 5 over the period, for the moment that acts
            propellant += previous_rate * delay + rate * (dt - delay)
            previous_rate = rate
        else:
            propellant += rate * dt
        summary[SU_MODE_TIME + mode] += dt
        t += dt
        steps += 1
        if not math.isfinite(wk.state[entry.EN_SPEED]):  # lost: end as at the floor
            status = STATUS_FLOOR
            break
    summary[SU_TIME] = t
    summary[SU_PROPELLANT] = propellant
    summary[SU_STATUS] = status
    summary[SU_STEPS] = steps
    down, cross = entry.ranges(initial[0:ENTRY_STATE_SIZE], wk.state[0:ENTRY_STATE_SIZE], vehicle.model.planet[0])
    summary[SU_DOWN_RANGE] = down
    summary[SU_CROSS_RANGE] = cross
    return rows
