"""Trajectory, atmosphere and aerodynamic torque (reference-model sec. 5).

Inertial frame (fixed at the separation point at t = 0): x horizontal downrange, z down, y to
the right completing the right-handed set. The Earth is a non-rotating sphere whose centre lies
at (0, 0, R + h_sep). The trajectory is a point mass in the x-z plane under central gravity and
drag; its state is ``[x, z, v_x, v_z]``.
"""

import math

from refexmc._jit import jit_noalloc
from refexmc.core import elementary
from refexmc.core.layout import (
    M_EARTH_MU,
    M_EARTH_RADIUS,
    M_SEP_ALTITUDE,
    M_SEP_FLIGHT_PATH,
    M_SEP_SPEED,
    V_AERO_AREA,
    V_AERO_LENGTH,
    V_DRAG_AREA,
    V_MASS,
    V_MISTRIM,
)

TRAJECTORY_STATE_SIZE = 4


@jit_noalloc
def density(atmosphere, altitude):
    """Piecewise-exponential density (kg/m^3); rows ``[base altitude m, rho0, scale height m]``."""
    row = 0
    for k in range(atmosphere.shape[0] - 1, -1, -1):  # the last row whose base is below
        if altitude >= atmosphere[k, 0]:
            row = k
            break
    return atmosphere[row, 1] * elementary.exp(-(altitude - atmosphere[row, 0]) / atmosphere[row, 2])


@jit_noalloc
def initial_state(mission, out):
    """Trajectory state at separation: origin, speed along the flight-path angle."""
    gamma = mission[M_SEP_FLIGHT_PATH]
    out[0] = 0.0
    out[1] = 0.0
    out[2] = mission[M_SEP_SPEED] * elementary.cos(gamma)
    out[3] = -mission[M_SEP_SPEED] * elementary.sin(gamma)


@jit_noalloc
def radial(mission, state):
    """Vector from the Earth's centre to the vehicle (x, z components) and its length."""
    rx = state[0]
    rz = state[1] - (mission[M_EARTH_RADIUS] + mission[M_SEP_ALTITUDE])
    return rx, rz, math.sqrt(rx * rx + rz * rz)


@jit_noalloc
def altitude(mission, state):
    """Altitude above the spherical Earth (m)."""
    return radial(mission, state)[2] - mission[M_EARTH_RADIUS]


@jit_noalloc
def climb_rate(mission, state):
    """Rate of change of altitude (m/s); negative on the descending branch."""
    rx, rz, r = radial(mission, state)
    return (rx * state[2] + rz * state[3]) / r


@jit_noalloc
def dynamic_pressure(mission, vehicle, atmosphere, state):
    """q = rho V^2 / 2 (Pa)."""
    v2 = state[2] * state[2] + state[3] * state[3]
    return 0.5 * density(atmosphere, altitude(mission, state)) * v2


@jit_noalloc
def flight_conditions(mission, atmosphere, state):
    """:func:`altitude`, :func:`climb_rate` and :func:`dynamic_pressure` at once."""
    rx, rz, r = radial(mission, state)
    altitude_m = r - mission[M_EARTH_RADIUS]
    v2 = state[2] * state[2] + state[3] * state[3]
    return altitude_m, (rx * state[2] + rz * state[3]) / r, 0.5 * density(atmosphere, altitude_m) * v2


@jit_noalloc
def acceleration(mission, vehicle, atmosphere, state):
    """Gravity plus drag acceleration (x, z)."""
    rx, rz, r = radial(mission, state)
    g = -mission[M_EARTH_MU] / (r * r * r)
    vx, vz = state[2], state[3]
    speed = math.sqrt(vx * vx + vz * vz)
    rho = density(atmosphere, r - mission[M_EARTH_RADIUS])
    drag = 0.5 * rho * speed * vehicle[V_DRAG_AREA] / vehicle[V_MASS]
    return g * rx - drag * vx, g * rz - drag * vz


@jit_noalloc
def trajectory_step(mission, vehicle, atmosphere, state, h, stage):
    """Advance the trajectory by ``h`` seconds with classical RK4; ``stage`` is scratch (4,)."""
    ax1, az1 = acceleration(mission, vehicle, atmosphere, state)
    trajectory_step_from(mission, vehicle, atmosphere, state, ax1, az1, h, stage)


@jit_noalloc
def trajectory_step_from(mission, vehicle, atmosphere, state, ax1, az1, h, stage):
    """:func:`trajectory_step` given the acceleration ``(ax1, az1)`` at ``state``."""
    x0, z0, vx1, vz1 = state[0], state[1], state[2], state[3]
    stage[0] = x0 + 0.5 * h * vx1
    stage[1] = z0 + 0.5 * h * vz1
    stage[2] = vx1 + 0.5 * h * ax1
    stage[3] = vz1 + 0.5 * h * az1
    vx2, vz2 = stage[2], stage[3]
    ax2, az2 = acceleration(mission, vehicle, atmosphere, stage)
    stage[0] = x0 + 0.5 * h * vx2
    stage[1] = z0 + 0.5 * h * vz2
    stage[2] = vx1 + 0.5 * h * ax2
    stage[3] = vz1 + 0.5 * h * az2
    vx3, vz3 = stage[2], stage[3]
    ax3, az3 = acceleration(mission, vehicle, atmosphere, stage)
    stage[0] = x0 + h * vx3
    stage[1] = z0 + h * vz3
    stage[2] = vx1 + h * ax3
    stage[3] = vz1 + h * az3
    vx4, vz4 = stage[2], stage[3]
    ax4, az4 = acceleration(mission, vehicle, atmosphere, stage)
    state[0] = x0 + h / 6.0 * (vx1 + 2.0 * vx2 + 2.0 * vx3 + vx4)
    state[1] = z0 + h / 6.0 * (vz1 + 2.0 * vz2 + 2.0 * vz3 + vz4)
    state[2] = vx1 + h / 6.0 * (ax1 + 2.0 * ax2 + 2.0 * ax3 + ax4)
    state[3] = vz1 + h / 6.0 * (az1 + 2.0 * az2 + 2.0 * az3 + az4)


@jit_noalloc
def velocity_pitch(state):
    """Angle of the velocity above the inertial x axis, a rotation about +y (rad)."""
    return elementary.atan2(-state[3], state[2])


@jit_noalloc
def predicted_velocity_pitch(mission, state, exit_altitude):
    """:func:`velocity_pitch` the vehicle will have descending through ``exit_altitude``.

    The flight software's trajectory model: the navigated state on a two-body (drag-free) conic,
    in closed form. Angular momentum h = r v_t and energy give speed and radial speed at the
    exit radius; the true anomaly follows from e cos(nu) = h^2/(mu r) - 1, e sin(nu) = v_r h/mu;
    the velocity turns by the change of flight-path angle minus the central angle travelled.
    Returns the current direction when the vehicle is already below ``exit_altitude`` or its
    conic never descends to it.
    """
    rx, rz, r = radial(mission, state)
    vx, vz = state[2], state[3]
    mu = mission[M_EARTH_MU]
    pitch_now = elementary.atan2(-vz, vx)
    r_exit = mission[M_EARTH_RADIUS] + exit_altitude
    h = abs(rx * vz - rz * vx)  # specific angular momentum, motion in the x-z plane
    v_radial = (rx * vx + rz * vz) / r
    speed2_exit = vx * vx + vz * vz + 2.0 * mu * (1.0 / r_exit - 1.0 / r)
    v_transverse_exit = h / r_exit
    radial2_exit = speed2_exit - v_transverse_exit * v_transverse_exit
    if r <= r_exit or radial2_exit <= 0.0:
        return pitch_now
    v_radial_exit = -math.sqrt(radial2_exit)  # descending branch
    anomaly_now = elementary.atan2(v_radial * h / mu, h * h / (mu * r) - 1.0)
    anomaly_exit = elementary.atan2(v_radial_exit * h / mu, h * h / (mu * r_exit) - 1.0)
    travelled = anomaly_exit - anomaly_now
    if travelled < 0.0:
        travelled += 2.0 * math.pi
    gamma_now = elementary.atan2(v_radial, h / r)
    gamma_exit = elementary.atan2(v_radial_exit, v_transverse_exit)
    return pitch_now + (gamma_exit - gamma_now) - travelled


@jit_noalloc
def velocity_pitch_rate(mission, vehicle, atmosphere, state):
    """Time derivative of :func:`velocity_pitch` (rad/s)."""
    ax, az = acceleration(mission, vehicle, atmosphere, state)
    vx, vz = state[2], state[3]
    return (vz * ax - vx * az) / (vx * vx + vz * vz)


@jit_noalloc
def local_horizontal(mission, state, out):
    """Unit downrange horizontal direction at the vehicle (inertial, y = 0)."""
    rx, rz, r = radial(mission, state)
    out[0] = -rz / r
    out[1] = 0.0
    out[2] = rx / r


@jit_noalloc
def aerodynamic_torque(vehicle, qbar, out):
    """Mistrim torque q S L c_m per body axis (N m)."""
    scale = qbar * vehicle[V_AERO_AREA] * vehicle[V_AERO_LENGTH]
    for i in range(3):
        out[i] = scale * vehicle[V_MISTRIM + i]


@jit_noalloc
def interpolate(node_a, accel_a, node_b, accel_b, span, tau, out):
    """Cubic Hermite interpolation of the trajectory between two RK4 nodes ``span`` apart.

    Positions use the nodes' velocities, velocities the nodes' accelerations; the error is
    O(span^4) times the fourth derivative, far below a metre for spans of a second.
    """
    s = tau / span
    s2 = s * s
    s3 = s2 * s
    h00 = 2.0 * s3 - 3.0 * s2 + 1.0
    h10 = s3 - 2.0 * s2 + s
    h01 = -2.0 * s3 + 3.0 * s2
    h11 = s3 - s2
    for k in range(2):
        out[k] = h00 * node_a[k] + h10 * span * node_a[2 + k] + h01 * node_b[k] + h11 * span * node_b[2 + k]
        out[2 + k] = h00 * node_a[2 + k] + h10 * span * accel_a[k] + h01 * node_b[2 + k] + h11 * span * accel_b[k]


@jit_noalloc
def advance_nodes(mission, vehicle, atmosphere, nodes, accels, span, stage):
    """Move node b to a and integrate a new node b one ``span`` ahead (RK4).

    ``accels[1]`` must hold the acceleration at ``nodes[1]``; it is the new step's first stage.
    """
    for k in range(4):
        nodes[0, k] = nodes[1, k]
    accels[0, 0] = accels[1, 0]
    accels[0, 1] = accels[1, 1]
    trajectory_step_from(mission, vehicle, atmosphere, nodes[1], accels[0, 0], accels[0, 1], span, stage)
    ax, az = acceleration(mission, vehicle, atmosphere, nodes[1])
    accels[1, 0] = ax
    accels[1, 1] = az
