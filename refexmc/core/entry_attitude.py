"""The aerodynamic angles alpha, beta and bank mu from the body attitude and the air-relative
velocity, and back (issue 24: 003's alpha, beta, mu "taken from the body attitude").

Frames: inertial (z the Earth's spin axis, x through longitude 0 at t = 0), the local
north-east-down frame at the vehicle, body axes (x forward, y right, z down) and wind axes (x along
the air-relative velocity). The attitude is the body-to-inertial quaternion of core.quaternion
(scalar last). Wind axes in body axes: x_w = (cos a cos b, sin b, sin a cos b), z_w = (-sin a, 0,
cos a), y_w = z_w x x_w; the lift acts along -z_w, the side force along y_w. The bank is the angle
about the velocity from the zero-bank lift direction (the local up, less its part along the
velocity) to the lift direction, positive towards the right: core.entry's convention.
"""

import math

from refexmc._jit import jit_noalloc
from refexmc.core import elementary, quaternion
from refexmc.core.entry import EN_FLIGHT_PATH, EN_HEADING, EN_LATITUDE, EN_LONGITUDE

AXES_SCRATCH = (8, 3)  # rows: north, east, down, velocity unit, lift0, right0, lift, spare


@jit_noalloc
def local_frame(state, t, rotation, scratch):
    """Rows 0-2 of ``scratch``: north, east and down unit vectors in inertial axes at time ``t``
    (the Earth turned by rotation t); row 3: the unit air-relative velocity."""
    lon = state[EN_LONGITUDE] + rotation * t
    lat = state[EN_LATITUDE]
    sl, cl = elementary.sincos(lon)
    sd, cd = elementary.sincos(lat)
    north, east, down, along = scratch[0], scratch[1], scratch[2], scratch[3]
    north[0], north[1], north[2] = -sd * cl, -sd * sl, cd
    east[0], east[1], east[2] = -sl, cl, 0.0
    down[0], down[1], down[2] = -cd * cl, -cd * sl, -sd
    sg, cg = elementary.sincos(state[EN_FLIGHT_PATH])
    sc, cc = elementary.sincos(state[EN_HEADING])
    for i in range(3):
        along[i] = cg * cc * north[i] + cg * sc * east[i] - sg * down[i]


@jit_noalloc
def _zero_bank_axes(scratch):
    """Rows 4-5: the zero-bank lift direction (up less its part along the velocity) and the
    right-hand direction velocity x lift0."""
    down, along, lift0, right0 = scratch[2], scratch[3], scratch[4], scratch[5]
    dot = -(down[0] * along[0] + down[1] * along[1] + down[2] * along[2])
    norm = 0.0
    for i in range(3):
        lift0[i] = -down[i] - dot * along[i]
        norm += lift0[i] * lift0[i]
    norm = math.sqrt(norm)
    for i in range(3):
        lift0[i] /= norm
    right0[0] = along[1] * lift0[2] - along[2] * lift0[1]
    right0[1] = along[2] * lift0[0] - along[0] * lift0[2]
    right0[2] = along[0] * lift0[1] - along[1] * lift0[0]


@jit_noalloc
def aerodynamic_angles(state, t, rotation, attitude, scratch):
    """(alpha, beta, bank) in rad of the body attitude ``attitude`` (body to inertial) flying
    ``state`` (core.entry) at time ``t``; ``scratch`` of AXES_SCRATCH."""
    local_frame(state, t, rotation, scratch)
    _zero_bank_axes(scratch)
    along, lift0, right0, work = scratch[3], scratch[4], scratch[5], scratch[6]
    for i in range(3):
        work[i] = along[i]
    quaternion.rotate_inverse(attitude, work, work)  # velocity direction in body axes
    u, v, w = work[0], work[1], work[2]
    alpha = elementary.atan2(w, u)
    beta = elementary.asin(min(max(v, -1.0), 1.0))
    sa, ca = elementary.sincos(alpha)
    work[0], work[1], work[2] = sa, 0.0, -ca  # lift direction -z_w in body axes
    quaternion.rotate(attitude, work, work)
    bank = elementary.atan2(
        work[0] * right0[0] + work[1] * right0[1] + work[2] * right0[2],
        work[0] * lift0[0] + work[1] * lift0[1] + work[2] * lift0[2],
    )
    return alpha, beta, bank


@jit_noalloc
def attitude_from_angles(state, t, rotation, alpha, beta, bank, scratch, out):
    """The body-to-inertial quaternion ``out`` that flies ``state`` at (alpha, beta, bank)."""
    local_frame(state, t, rotation, scratch)
    _zero_bank_axes(scratch)
    lift0, right0 = scratch[4], scratch[5]
    x_w, y_w, z_w = scratch[3], scratch[6], scratch[7]  # x_w: the velocity direction
    sm, cm = elementary.sincos(bank)
    for i in range(3):
        lift = cm * lift0[i] + sm * right0[i]
        y_w[i] = cm * right0[i] - sm * lift0[i]
        z_w[i] = -lift
    sa, ca = elementary.sincos(alpha)
    sb, cb = elementary.sincos(beta)
    # body axes from wind axes: columns of the body-to-wind matrix (module docstring)
    bx0 = ca * cb * x_w[0] - ca * sb * y_w[0] - sa * z_w[0]
    bx1 = ca * cb * x_w[1] - ca * sb * y_w[1] - sa * z_w[1]
    bx2 = ca * cb * x_w[2] - ca * sb * y_w[2] - sa * z_w[2]
    by0 = sb * x_w[0] + cb * y_w[0]
    by1 = sb * x_w[1] + cb * y_w[1]
    by2 = sb * x_w[2] + cb * y_w[2]
    bz0 = sa * cb * x_w[0] - sa * sb * y_w[0] + ca * z_w[0]
    bz1 = sa * cb * x_w[1] - sa * sb * y_w[1] + ca * z_w[1]
    bz2 = sa * cb * x_w[2] - sa * sb * y_w[2] + ca * z_w[2]
    scratch[4, 0], scratch[4, 1], scratch[4, 2] = bx0, bx1, bx2
    scratch[5, 0], scratch[5, 1], scratch[5, 2] = by0, by1, by2
    scratch[6, 0], scratch[6, 1], scratch[6, 2] = bz0, bz1, bz2
    quaternion.from_axes(scratch[4], scratch[5], scratch[6], out)
