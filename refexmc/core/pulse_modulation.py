"""Kienitz-Bals PWPF modulation with switching restrictions and delay correction (000 eq. 41-48).

One modulator per body axis; its state is a caller-owned row ``[t_s_on, t_s_off, w]``.
"""

from refexmc._jit import jit_inline, jit_noalloc

P_T_ON = 0  # time the axis last started a pulse
P_T_OFF = 1  # time the axis last ended a pulse
P_OUTPUT = 2  # last output w in {-1, 0, 1}
PWPF_STATE_SIZE = 3
_NEVER = -1.0e9
# Eq. 47-48 on the control grid: a pulse lasts the fewest whole periods that make it at least
# gamma - delta gamma, a rest at least T - gamma + delta gamma. At f_min that is exactly the 25 ms
# hardware pulse and 175 ms rest, where 000 sec. 5 wants both restrictions met with equality
# (reading "<=" literally at 40 Hz adds a period to each: 50 ms pulses, 200 ms rests; docs/model.md).
# Times are step * dt, so t - t_s carries ~1e-15 s of roundoff; at 40 Hz the bounds are often whole
# control periods, and the comparison must not be decided by that roundoff.
_EPS_T = 1e-9


@jit_noalloc
def reset(state):
    """No pulse yet: the first may start at once."""
    for axis in range(state.shape[0]):
        state[axis, P_T_ON] = 2.0 * _NEVER
        state[axis, P_T_OFF] = _NEVER
        state[axis, P_OUTPUT] = 0.0


@jit_noalloc
def shaped_command(torque_cmd, torque_max, torque_min):
    """f(tau_c) of 000 eq. 43: saturation at tau_max, deadband below tau_min."""
    magnitude = abs(torque_cmd)
    if magnitude < torque_min:
        return 0.0
    if magnitude > torque_max:
        return torque_max if torque_cmd > 0.0 else -torque_max
    return torque_cmd


@jit_noalloc
def pulse_timing(f_abs, torque_max, t_on, t_off):
    """Pulse width gamma_k and period T_k of 000 eq. 44-46 for |f| in (0, tau_max)."""
    f_min = torque_max * t_on / (t_on + t_off)  # eq. 44
    if f_abs >= f_min:
        gamma = t_off * f_abs / (torque_max - f_abs)
    else:
        gamma = t_on
    return gamma, torque_max * gamma / f_abs


@jit_inline
def modulate(state, axis, torque_cmd, torque_max, tau_min_fraction, t_on, t_off, correction, t):
    """Modulator output w in {-1, 0, 1} for this control step (000 eq. 47-48)."""
    f = shaped_command(torque_cmd, torque_max, tau_min_fraction * torque_max)
    firing = state[axis, P_T_ON] > state[axis, P_T_OFF]
    if f == 0.0:
        w = 0.0
    else:
        sign = 1.0 if f > 0.0 else -1.0
        f_abs = abs(f)
        if f_abs >= torque_max:
            # eq. 45-48 in the limit |f| -> tau_max: an endless pulse after a rest of t_off + delta gamma
            if firing:
                w = sign
            else:
                w = 0.0 if t - state[axis, P_T_OFF] < t_off + correction - _EPS_T else sign
        else:
            gamma, period = pulse_timing(f_abs, torque_max, t_on, t_off)
            if firing:
                w = sign if t - state[axis, P_T_ON] < gamma - correction - _EPS_T else 0.0  # eq. 47
            else:
                w = 0.0 if t - state[axis, P_T_OFF] < period - (gamma - correction) - _EPS_T else sign  # eq. 48
    if firing and w == 0.0:
        state[axis, P_T_OFF] = t
    elif not firing and w != 0.0:
        state[axis, P_T_ON] = t
    state[axis, P_OUTPUT] = w
    return w
