"""Time-optimal state feedback for a thrust that falls with the fuel (002 sec. 4, eq. 21-46).

The normalised plant (002 eq. 21): x1' = x2, x2' = u x3, x3' = -|u| x3, u in {-1, 0, +1}; x1 is
position, x2 velocity, x3 the fuel (tank pressure) that is also the acceleration. The law eq. 44
switches on three surfaces: sigma0 (eq. 41, start coasting: the time-optimal switch), sigma1
(eq. 42, the fuel reserve x3_min) and sigma2 (eq. 43, start braking: braking from it ends at the
origin). Bang-bang, the comparison of 002 Fig. 8, is u = -sign(sigma2) alone.

The physical direct-feed plant (002 eq. 18-20 in vacuum; core.feed) maps onto eq. 21 exactly.
With a thruster of thrust k P (k = C_F A_t s / m: acceleration per pascal, eq. 15 at P_a = 0)
and tank time constant tau (eq. 16: dP/dt = -|u| P / tau), the scaled time s = t / tau and
X1 = x1 / L, X2 = x2 tau / L, X3 = k P tau^2 / L satisfy eq. 21 for any length L (:func:`scale`).
sigma0 and sigma2 are homogeneous (sign(sigma(lambda X)) = sign(sigma(X))) and sigma1 scales
with X, so the law does not depend on L: it needs tau and k only. What the scaling does not
carry: an ambient pressure (eq. 19's -epsilon P_a makes f1 affine) and the mass the gas takes
away (eq. 14 divides by a constant mass); both are zero in 002's example.

Closed forms per control period with u held (eq. 24-26 evaluated, cf. eq. 27, 30, 33):
u = +-1: x3 e^-h, x2 + u x3 (1 - e^-h), x1 + x2 h + u x3 (h - 1 + e^-h); u = 0: x1 + x2 h.
"""

import math

from refexmc._jit import jit_noalloc
from refexmc.core import elementary

# columns of a history row of fly_normalised
TO_T, TO_X1, TO_X2, TO_X3, TO_U = 0, 1, 2, 3, 4
TO_HISTORY_SIZE = 5


@jit_noalloc
def _sign(value):
    if value > 0.0:
        return 1.0
    if value < 0.0:
        return -1.0
    return 0.0


@jit_noalloc
def sigma0(x1, x2, x3):
    """Coasting surface, 002 eq. 41 (only its sign is used; sign(x1) inf at x2 = 0, the limit)."""
    a = abs(x2)
    if x2 == 0.0:
        return _sign(x1) * math.inf if x1 != 0.0 else 0.0
    if x3 <= a:  # the origin is out of reach from here (eq. 46): brake
        return _sign(x2) * math.inf
    bracket = x1 + (x3 + a) / (x3 - a) * x2 - _sign(x2) * (x3 + a) * elementary.log(x3 / (x3 - a))
    return x3 / (x2 * x2) * bracket


@jit_noalloc
def sigma1(x2, x3, x3_min):
    """Fuel-reserve surface, 002 eq. 42."""
    return x3 - x3_min - abs(x2)


@jit_noalloc
def sigma2(x1, x2, x3):
    """Braking surface, 002 eq. 43: braking from sigma2 = 0 stops at the origin."""
    a = abs(x2)
    if x3 <= a:  # out of reach (eq. 46): brake
        return _sign(x2) * math.inf
    return x1 + x2 - _sign(x2) * (x3 - a) * elementary.log(x3 / (x3 - a))


@jit_noalloc
def command(x1, x2, x3, x3_min, bang_bang):
    """u in {-1, 0, +1}: 002 eq. 44, or bang-bang -sign(sigma2) when ``bang_bang``."""
    s2 = _sign(sigma2(x1, x2, x3))
    if bang_bang:
        return -s2 if s2 != 0.0 else 0.0
    if sigma1(x2, x3, x3_min) > 0.0:
        return -0.5 * (_sign(sigma0(x1, x2, x3)) + s2)
    return -0.5 * (_sign(x2) + s2)


@jit_noalloc
def scale(position, velocity, accel_per_pa, pressure, tau, length):
    """The physical direct-feed state (m, m/s, Pa) as eq. 21's (X1, X2, X3): see the module doc."""
    return position / length, velocity * tau / length, accel_per_pa * pressure * tau * tau / length


@jit_noalloc
def advance(x1, x2, x3, u, h):
    """eq. 21 over ``h`` with ``u`` held: the closed form (module doc)."""
    if u == 0.0:
        return x1 + x2 * h, x2, x3
    decay = elementary.exp(-h)
    return x1 + x2 * h + u * x3 * (h - 1.0 + decay), x2 + u * x3 * (1.0 - decay), x3 * decay


@jit_noalloc
def fly_normalised(x1, x2, x3, x3_min, dt, bang_bang, tolerance, max_steps, history):
    """Sampled eq. 44 on eq. 21: u computed every ``dt`` and held, the plant exact in between,
    until |x1| <= tolerance and |x2| <= tolerance. Rows of ``history`` (TO_*): one per step until
    full; returns (steps flown, arrived)."""
    t = 0.0
    for step in range(max_steps):
        arrived = abs(x1) <= tolerance and abs(x2) <= tolerance
        u = 0.0 if arrived else command(x1, x2, x3, x3_min, bang_bang)
        if step < history.shape[0]:
            row = history[step]
            row[TO_T], row[TO_X1], row[TO_X2], row[TO_X3], row[TO_U] = t, x1, x2, x3, u
        if arrived:
            return step, True
        x1, x2, x3 = advance(x1, x2, x3, u, dt)
        t = (step + 1) * dt
    return max_steps, False
