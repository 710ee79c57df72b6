"""Per-thruster switching check before commands are sent (000 sec. 5).

A thruster stays open until it has been open for ``min_on`` and stays closed until it has rested
for ``min_off``. State per thruster: ``[is_open, t_opened, t_closed]``.
"""

from refexmc._jit import jit_noalloc

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


@jit_noalloc
def enforce(state, desired, t, min_on, min_off, changes):
    """Apply ``desired`` (0/1) where the limits allow; ``changes[i]`` = +1 opened, -1 closed, 0."""
    eps = 1e-9
    for i in range(state.shape[0]):
        changes[i] = 0
        is_open = state[i, SW_OPEN] != 0.0
        if desired[i] != 0 and not is_open:
            if t - state[i, SW_T_CLOSED] >= min_off - eps:
                state[i, SW_OPEN] = 1.0
                state[i, SW_T_OPENED] = t
                changes[i] = 1
        elif desired[i] == 0 and is_open:
            if t - state[i, SW_T_OPENED] >= min_on - eps:
                state[i, SW_OPEN] = 0.0
                state[i, SW_T_CLOSED] = t
                changes[i] = -1
