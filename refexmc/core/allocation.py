"""Thruster allocation and the actuation chain from torque command to valve commands.

The actuation chain is chosen by ``actuation_id`` (layout.ACTUATION_*); later strategies (LP
fuel-optimal allocation, reaction wheels) add a branch to :func:`thruster_commands` and keep the
run loop unchanged.
"""

from refexmc._jit import jit_inline, jit_noalloc
from refexmc.core import pulse_modulation
from refexmc.core.layout import (
    ACTUATION_PWPF_TABLE,
    F_PWPF_CORRECTION,
    F_PWPF_OFF,
    F_PWPF_ON,
    F_TAU_MIN_FRACTION,
    LV_TORQUE_MAX,
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
