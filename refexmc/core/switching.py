"""Per-thruster switching check before commands are sent (000 sec. 5).

A thruster stays open until it has been open for ``min_on`` and stays closed until it has rested
for ``min_off``. State per thruster: ``[is_open, t_opened, t_closed]``.
"""

from refexmc._jit import jit_noalloc
from refexmc.core.bits import lowest_bit

SW_OPEN = 0
SW_T_OPENED = 1
SW_T_CLOSED = 2
SWITCH_STATE_SIZE = 3


@jit_noalloc
def reset(state):
    """All closed, long rested."""
    for i in range(state.shape[0]):
        state[i, SW_OPEN] = 0.0
        state[i, SW_T_OPENED] = -1.0e9
        state[i, SW_T_CLOSED] = -1.0e9


@jit_noalloc(force_inline=True)
def enforce(state, desired, is_open, t, min_on, min_off):
    """Apply the ``desired`` open set where the limits allow; returns ``(opened, closed)``.

    ``desired``, ``is_open`` (the thrusters now open, as ``state`` has them) and the results
    are bit masks, bit i for thruster i; only thrusters whose state would change are visited.
    """
    eps = 1e-9
    opened = 0
    closed = 0
    m = desired ^ is_open
    while m != 0:
        i = lowest_bit(m)
        m &= m - 1
        if (desired >> i) & 1:
            if t - state[i, SW_T_CLOSED] >= min_off - eps:
                state[i, SW_OPEN] = 1.0
                state[i, SW_T_OPENED] = t
                opened |= 1 << i
        elif t - state[i, SW_T_OPENED] >= min_on - eps:
            state[i, SW_OPEN] = 0.0
            state[i, SW_T_CLOSED] = t
            closed |= 1 << i
    return opened, closed
