"""Navigation errors: what the flight software measures (reference-model sec. 5).

Measured attitude = truth (x) rotation(bias * calibration + noise); measured rate = truth +
bias + noise. The attitude bias decays with the calibration time constant while a mode flagged
``navigation_calibration`` runs (ReFEx: the sun scan, SSM) and keeps its decayed value
afterwards (000 sec. 2.2, 6.2).
"""

import math

from refexmc._jit import jit_inline, jit_noalloc
from refexmc.core import quaternion, rng
from refexmc.core.layout import N_ATT_BIAS, N_ATT_NOISE, N_CALIBRATION_TIME, N_RATE_BIAS, N_RATE_NOISE


@jit_noalloc
def calibration_factor(nav, time_calibrating):
    """Fraction of the attitude bias left after ``time_calibrating`` seconds in calibrating modes."""
    tau = nav[N_CALIBRATION_TIME]
    if tau <= 0.0 or time_calibrating <= 0.0:
        return 1.0
    return math.exp(-time_calibrating / tau)


@jit_inline
def measure(x, nav, time_calibrating, rng_state, q_out, rate_out, work4):
    """Measured attitude quaternion and body rates from the true state ``x``."""
    no_bias = nav[N_ATT_BIAS] == 0.0 and nav[N_ATT_BIAS + 1] == 0.0 and nav[N_ATT_BIAS + 2] == 0.0
    factor = 1.0 if no_bias else calibration_factor(nav, time_calibrating)  # it only scales the bias
    sigma_att = nav[N_ATT_NOISE]
    sigma_rate = nav[N_RATE_NOISE]
    ex = factor * nav[N_ATT_BIAS]
    ey = factor * nav[N_ATT_BIAS + 1]
    ez = factor * nav[N_ATT_BIAS + 2]
    if sigma_att > 0.0:
        ex += sigma_att * rng.next_normal(rng_state)
        ey += sigma_att * rng.next_normal(rng_state)
        ez += sigma_att * rng.next_normal(rng_state)
    if ex == 0.0 and ey == 0.0 and ez == 0.0:
        for i in range(4):
            q_out[i] = x[i]
    else:
        quaternion.from_rotation_vector(ex, ey, ez, work4)
        quaternion.multiply(x[0:4], work4, q_out)
    for i in range(3):
        rate_out[i] = x[4 + i] + nav[N_RATE_BIAS + i]
        if sigma_rate > 0.0:
            rate_out[i] += sigma_rate * rng.next_normal(rng_state)
