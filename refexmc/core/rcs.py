"""Reaction control system: valve transients, derating, torque and propellant.

Each thruster's normalised thrust level L(t) in [0, 1] is piecewise linear (000 Fig. 6): after an
open command it keeps its course for the on-delay, then rises at 1/rise_time; after a close
command it keeps its course for the off-delay, then falls at 1/fall_time. A reaction that takes
effect mid-transient starts its ramp from the level at that instant. A later command that would
react earlier than a pending one supersedes it. Failed thrusters never open (000 sec. 5).

Valve state: one row per thruster, columns below; all arrays are owned by the caller.
"""

from refexmc._jit import jit_noalloc
from refexmc.core.bits import lowest_bit
from refexmc.core.layout import (
    DERATING_MAX_VALVES,
    FALL,
    OFF_DELAY,
    ON_DELAY,
    RISE,
    T_DIRECTION,
    T_FAILED,
    T_POSITION,
    T_SCALE,
    T_TIME_CONSTANTS,
    TIME_CONSTANTS_PER_LEVEL,
    V_COM_OFFSET,
    V_DERATING,
    V_ISP,
)

STANDARD_GRAVITY = 9.80665  # m/s^2, defines Isp in seconds

MAX_PENDING = 4
VS_LEVEL = 0  # level at VS_TIME
VS_TIME = 1
VS_SLOPE = 2  # 1/s
VS_PENDING_COUNT = 3
VS_PENDING = 4  # pairs (reaction time, 1 open / 0 close), ascending in time
VS_KINK = VS_PENDING + 2 * MAX_PENDING  # while ramping: time the level reaches 0 or 1
VALVE_STATE_SIZE = VS_KINK + 1

ALL_THRUSTERS = -1  # bit mask with every thruster's bit set
_EPS_T = 1e-12


@jit_noalloc
def reset(valve_state):
    """All valves closed, nothing pending."""
    valve_state[:, :] = 0.0


@jit_noalloc
def level_at(valve_state, i, t):
    """Normalised thrust level of thruster ``i`` at time ``t`` (before pending reactions)."""
    v = valve_state[i, VS_LEVEL] + valve_state[i, VS_SLOPE] * (t - valve_state[i, VS_TIME])
    if v < 0.0:
        return 0.0
    if v > 1.0:
        return 1.0
    return v


@jit_noalloc
def time_constant(thrusters, i, thrust_level, which):
    """On-delay, rise, off-delay or fall time (s) of thruster ``i`` at the given thrust level."""
    return thrusters[i, T_TIME_CONSTANTS + TIME_CONSTANTS_PER_LEVEL * thrust_level + which]


@jit_noalloc
def command(valve_state, thrusters, i, open_valve, t, thrust_level):
    """Send an open (True) or close command to thruster ``i`` at time ``t``."""
    if thrusters[i, T_FAILED] != 0.0:
        return
    delay = time_constant(thrusters, i, thrust_level, ON_DELAY if open_valve else OFF_DELAY)
    t_react = t + delay
    n = int(valve_state[i, VS_PENDING_COUNT])
    while n > 0 and valve_state[i, VS_PENDING + 2 * (n - 1)] > t_react:
        n -= 1  # superseded by this later command
    if n == MAX_PENDING:  # cannot happen at 40 Hz with delays < 4 periods; keep the newest
        for k in range(MAX_PENDING - 1):
            valve_state[i, VS_PENDING + 2 * k] = valve_state[i, VS_PENDING + 2 * k + 2]
            valve_state[i, VS_PENDING + 2 * k + 1] = valve_state[i, VS_PENDING + 2 * k + 3]
        n -= 1
    valve_state[i, VS_PENDING + 2 * n] = t_react
    valve_state[i, VS_PENDING + 2 * n + 1] = 1.0 if open_valve else 0.0
    valve_state[i, VS_PENDING_COUNT] = n + 1


@jit_noalloc(force_inline=True)
def apply_reactions(valve_state, thrusters, i, t, thrust_level):
    """Start the ramps of all reactions of thruster ``i`` due at or before ``t``."""
    n = int(valve_state[i, VS_PENDING_COUNT])
    done = 0
    while done < n and valve_state[i, VS_PENDING + 2 * done] <= t + _EPS_T:
        t_react = valve_state[i, VS_PENDING + 2 * done]
        opening = valve_state[i, VS_PENDING + 2 * done + 1] != 0.0
        level = level_at(valve_state, i, t_react)
        ramp = time_constant(thrusters, i, thrust_level, RISE if opening else FALL)
        valve_state[i, VS_TIME] = t_react
        if ramp <= 0.0:  # ideal valve: jump
            valve_state[i, VS_LEVEL] = 1.0 if opening else 0.0
            valve_state[i, VS_SLOPE] = 0.0
        else:
            slope = 1.0 / ramp if opening else -1.0 / ramp
            valve_state[i, VS_LEVEL] = level
            valve_state[i, VS_SLOPE] = slope
            valve_state[i, VS_KINK] = t_react + ((1.0 if opening else 0.0) - level) / slope
        done += 1
    if done > 0:
        for k in range(n - done):
            valve_state[i, VS_PENDING + 2 * k] = valve_state[i, VS_PENDING + 2 * (k + done)]
            valve_state[i, VS_PENDING + 2 * k + 1] = valve_state[i, VS_PENDING + 2 * (k + done) + 1]
        valve_state[i, VS_PENDING_COUNT] = n - done


@jit_noalloc
def next_breakpoint(valve_state, n_thrusters, t_start, t_end, active=ALL_THRUSTERS):
    """Earliest kink of any thruster's level in (t_start, t_end), or ``t_end``.

    Only thrusters in the bit mask ``active`` (see :func:`update`) are looked at.
    """
    t_next = t_end
    m = active & ((1 << n_thrusters) - 1)
    while m != 0:
        i = lowest_bit(m)
        m &= m - 1
        if valve_state[i, VS_PENDING_COUNT] > 0.0:
            tr = valve_state[i, VS_PENDING]
            if t_start + _EPS_T < tr < t_next:
                t_next = tr
        if valve_state[i, VS_SLOPE] != 0.0:
            t_kink = valve_state[i, VS_KINK]
            if t_start + _EPS_T < t_kink < t_next:
                t_next = t_kink
    return t_next


@jit_noalloc
def torque_arms(thrusters, vehicle, out):
    """Torque per newton of each thruster about the actual CoM: (r - com_offset) x direction."""
    for i in range(thrusters.shape[0]):
        rx = thrusters[i, T_POSITION] - vehicle[V_COM_OFFSET]
        ry = thrusters[i, T_POSITION + 1] - vehicle[V_COM_OFFSET + 1]
        rz = thrusters[i, T_POSITION + 2] - vehicle[V_COM_OFFSET + 2]
        dx = thrusters[i, T_DIRECTION]
        dy = thrusters[i, T_DIRECTION + 1]
        dz = thrusters[i, T_DIRECTION + 2]
        out[i, 0] = ry * dz - rz * dy
        out[i, 1] = rz * dx - rx * dz
        out[i, 2] = rx * dy - ry * dx


@jit_noalloc
def derating_factor(vehicle, n_open):
    """Thrust factor with ``n_open`` valves open (000 sec. 2.1); 1 when none is open."""
    if n_open <= 0:
        return 1.0
    if n_open > DERATING_MAX_VALVES:
        n_open = DERATING_MAX_VALVES
    return vehicle[V_DERATING + n_open - 1]


@jit_noalloc(force_inline=True)
def open_count(valve_state, n_thrusters, active, t):
    """Valves open (level > 0) at time ``t`` among the thrusters in the bit mask ``active``: the
    count that sets the derating within a segment (at its midpoint)."""
    n_open = 0
    m = active & ((1 << n_thrusters) - 1)
    while m != 0:
        i = lowest_bit(m)
        m &= m - 1
        if level_at(valve_state, i, t) > 0.0:
            n_open += 1
    return n_open


@jit_noalloc(force_inline=True)
def segment_thrust(
    valve_state, thrusters, vehicle, arms, nominal, t_start, t_end, tau_start, tau_end, active=ALL_THRUSTERS
):
    """Torques at both ends of a segment without kinks, and its total impulse (N s).

    ``nominal`` is the thrust (N) of the level flown, before derating and per-thruster scale.
    Within the segment each level is linear; the number of open valves (level > 0 at the
    midpoint) and hence the derating are constant. Thrusters outside the bit mask ``active``
    (closed and settled, see :func:`update`) are skipped.
    """
    n = thrusters.shape[0]
    n_open = open_count(valve_state, n, active, 0.5 * (t_start + t_end))
    force = nominal * derating_factor(vehicle, n_open)
    sx, sy, sz = 0.0, 0.0, 0.0  # sums in registers, in the same order as into the arrays
    ex, ey, ez = 0.0, 0.0, 0.0
    impulse = 0.0
    m = active & ((1 << n) - 1)
    while m != 0:
        i = lowest_bit(m)
        m &= m - 1
        f0 = force * thrusters[i, T_SCALE] * level_at(valve_state, i, t_start)
        f1 = force * thrusters[i, T_SCALE] * level_at(valve_state, i, t_end)
        if f0 == 0.0 and f1 == 0.0:
            continue
        sx += f0 * arms[i, 0]
        sy += f0 * arms[i, 1]
        sz += f0 * arms[i, 2]
        ex += f1 * arms[i, 0]
        ey += f1 * arms[i, 1]
        ez += f1 * arms[i, 2]
        impulse += 0.5 * (f0 + f1) * (t_end - t_start)
    tau_start[0], tau_start[1], tau_start[2] = sx, sy, sz
    tau_end[0], tau_end[1], tau_end[2] = ex, ey, ez
    return impulse


@jit_noalloc
def propellant_for_impulse(vehicle, impulse):
    """Propellant mass (kg) that an impulse (N s) uses: impulse / (Isp g0)."""
    return impulse / (vehicle[V_ISP] * STANDARD_GRAVITY)


@jit_noalloc
def open_mask(valve_state, n_thrusters, t):
    """Bit mask of thrusters producing thrust at ``t`` (bit i-1 for thruster i)."""
    mask = 0
    for i in range(n_thrusters):
        if level_at(valve_state, i, t) > 0.0:
            mask |= 1 << i
    return mask


@jit_noalloc(force_inline=True)
def update(valve_state, thrusters, n_thrusters, t, thrust_level, active):
    """Start the reactions due at ``t`` and settle finished ramps; the new mask of active thrusters.

    ``active`` is a bit mask (bit i for thruster i) that includes every thruster that has a
    reaction pending, a ramp or a level above 0; the others are skipped. A thruster is dropped
    from the mask once it is closed and settled.

    A ramp that had reached 0 or 1 by ``t - 1e-9`` becomes a steady level (slope 0). Levels are
    only asked for at or after ``t - 1e-12`` from here on, and ``level_at`` is monotone along a
    ramp in floating point too, so it returns exactly the same clamped 0.0 or 1.0 as before; the
    segments then see no breakpoint in the past, and a closed thruster counts as idle.
    """
    still_active = 0
    m = active & ((1 << n_thrusters) - 1)
    while m != 0:
        i = lowest_bit(m)
        m &= m - 1
        if valve_state[i, VS_PENDING_COUNT] > 0.0 and valve_state[i, VS_PENDING] <= t + _EPS_T:
            apply_reactions(valve_state, thrusters, i, t, thrust_level)
        slope = valve_state[i, VS_SLOPE]
        if slope != 0.0:
            v = valve_state[i, VS_LEVEL] + slope * ((t - 1e-9) - valve_state[i, VS_TIME])
            if slope < 0.0 and v <= 0.0:
                valve_state[i, VS_LEVEL] = 0.0
                valve_state[i, VS_SLOPE] = 0.0
            elif slope > 0.0 and v >= 1.0:
                valve_state[i, VS_LEVEL] = 1.0
                valve_state[i, VS_SLOPE] = 0.0
        if valve_state[i, VS_PENDING_COUNT] > 0.0 or valve_state[i, VS_SLOPE] != 0.0 or valve_state[i, VS_LEVEL] > 0.0:
            still_active |= 1 << i
    return still_active
