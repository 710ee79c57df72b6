"""Thruster allocation and the actuation chain from torque command to valve commands.

The actuation chain is chosen by ``actuation_id`` (layout.ACTUATION_*): the PWPF per axis with
the allocation table (:func:`thruster_commands`), or the LP allocation of ``core.lp_allocation``
realised by pulse-width modulation (:func:`pwm_on_time`, in the run loop's actuate step).
"""

from refexmc._jit import jit_inline, jit_noalloc
from refexmc.core import elementary, pulse_modulation
from refexmc.core.layout import (
    ACTUATION_PWPF_TABLE,
    F_PWPF_CORRECTION,
    F_PWPF_OFF,
    F_PWPF_ON,
    F_TAU_MIN_FRACTION,
    LV_TORQUE_MAX,
    T_DIRECTION,
    T_FAILURE_KNOWN,
    T_POSITION,
)


@jit_noalloc
def table_row(wx, wy, wz):
    """Row of the allocation table for modulator outputs (wx, wy, wz) in {-1, 0, 1}^3."""
    return int((wx + 1.0) * 9.0 + (wy + 1.0) * 3.0 + (wz + 1.0))


@jit_noalloc
def table_lookup(table, wx, wy, wz, out):
    """Thrusters to open for the modulator outputs (000 Table 3); ``out`` is 0/1 per thruster."""
    row = table_row(wx, wy, wz)
    for i in range(table.shape[1]):
        out[i] = table[row, i]


@jit_noalloc
def table_masks(table, out):
    """Each row of the allocation table as a bit mask of thrusters (bit i for thruster i)."""
    for row in range(table.shape[0]):
        mask = 0
        for i in range(table.shape[1]):
            if table[row, i] != 0:
                mask |= 1 << i
        out[row] = mask


@jit_inline
def thruster_commands(actuation_id, fsw, level, torque_cmd, pwpf_state, row_masks, t, pulse_out):
    """Bit mask of the thrusters to open for this control step (bit i for thruster i).

    ``level`` is the row of the thrust level flown (layout.LEVEL); ``row_masks`` is the
    allocation table as bit masks (:func:`table_masks`); ``pulse_out``
    receives the per-axis modulator outputs for the history.
    """
    if actuation_id == ACTUATION_PWPF_TABLE:
        for axis in range(3):
            pulse_out[axis] = pulse_modulation.modulate(
                pwpf_state,
                axis,
                torque_cmd[axis],
                level[LV_TORQUE_MAX + axis],
                fsw[F_TAU_MIN_FRACTION],
                fsw[F_PWPF_ON],
                fsw[F_PWPF_OFF],
                fsw[F_PWPF_CORRECTION],
                t,
            )
        return row_masks[table_row(pulse_out[0], pulse_out[1], pulse_out[2])]
    return 0


@jit_noalloc
def pwm_on_time(u, u_max, period, min_on):
    """On-time in the control period that gives thrust ``u`` of at most ``u_max`` on average.

    u / u_max of the period, rounded to the nearest possible pulse where it is shorter than the
    hardware minimum ``min_on``: nothing below min_on / 2, min_on from there (the average
    error is then at most min_on / 2 of full thrust per period, either way).
    """
    if u_max <= 0.0 or u <= 0.0:
        return 0.0
    on = period * (u / u_max if u < u_max else 1.0)
    if on < min_on:
        return 0.0 if on < 0.5 * min_on else elementary.smaller(min_on, period)
    return on


@jit_noalloc
def nominal_arms(thrusters, out):
    """(3, n) torque per newton the flight software assumes: nominal position x direction (the
    nominal centre of mass is the origin; the actual one is not known to it).

    A thruster whose failure the flight software knows (``T_FAILURE_KNOWN``, a detected failure)
    makes no torque in its model: its column is zero. The LP (``core.lp_allocation``) then never
    gives it thrust: a zero column's reduced cost is its own cost (0 in phase A, 1 in phase B), so
    it never enters the basis and every pivot is the one of the LP without that column (Bland's
    rule takes the lowest improving index). One kernel for every run; an undetected failure keeps
    its column (000 sec. 5).
    """
    for i in range(thrusters.shape[0]):
        if thrusters[i, T_FAILURE_KNOWN] != 0.0:
            out[0, i] = 0.0
            out[1, i] = 0.0
            out[2, i] = 0.0
            continue
        rx, ry, rz = thrusters[i, T_POSITION], thrusters[i, T_POSITION + 1], thrusters[i, T_POSITION + 2]
        dx, dy, dz = thrusters[i, T_DIRECTION], thrusters[i, T_DIRECTION + 1], thrusters[i, T_DIRECTION + 2]
        out[0, i] = ry * dz - rz * dy
        out[1, i] = rz * dx - rx * dz
        out[2, i] = rx * dy - ry * dx
