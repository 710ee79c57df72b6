"""Navigation errors: what the flight software measures (reference-model sec. 5 and 7).

Measured attitude = truth (x) rotation(bias * calibration + white + Gauss-Markov); measured rate
= truth + bias + white + Gauss-Markov. The attitude bias decays with the calibration time
constant while a mode flagged ``navigation_calibration`` runs (ReFEx: the sun scan, SSM) and
keeps its decayed value afterwards (000 sec. 2.2, 6.2).

The Gauss-Markov part is a gyro-stellar estimator's steady-state error (Farrenkopf; Markley,
NASA 20000086664; reference-model sec. 7): per axis the exact discrete-time update of a
first-order process, x_{k+1} = a x_k + sqrt(1 - a^2) sigma w_k with a = exp(-dt / tau), stationary
for any step dt (variance a^2 sigma^2 + (1 - a^2) sigma^2 = sigma^2). It starts in its stationary
distribution, x_0 ~ N(0, sigma^2). A zero sigma draws nothing: the other noise keeps its bits.
The state is a caller-owned array of ``KNOWLEDGE_SIZE``: the attitude (3) and rate (3) processes,
then each process's a and sqrt(1 - a^2).
"""

import math

from refexmc._jit import jit_inline, jit_noalloc
from refexmc.core import elementary, quaternion, rng
from refexmc.core.layout import (
    N_ATT_BIAS,
    N_ATT_GM_SIGMA,
    N_ATT_GM_TAU,
    N_ATT_NOISE,
    N_CALIBRATION_TIME,
    N_RATE_BIAS,
    N_RATE_GM_SIGMA,
    N_RATE_GM_TAU,
    N_RATE_NOISE,
)

K_ATTITUDE = 0  # attitude Gauss-Markov state (rad), 3
K_RATE = 3  # rate Gauss-Markov state (rad/s), 3
K_ATT_DECAY = 6  # a = exp(-dt / tau) of the attitude process
K_ATT_DRIVE = 7  # sqrt(1 - a^2)
K_RATE_DECAY = 8
K_RATE_DRIVE = 9
KNOWLEDGE_SIZE = 10


@jit_noalloc
def calibration_factor(nav, time_calibrating):
    """Fraction of the attitude bias left after ``time_calibrating`` seconds in calibrating modes."""
    tau = nav[N_CALIBRATION_TIME]
    if tau <= 0.0 or time_calibrating <= 0.0:
        return 1.0
    return elementary.exp(-time_calibrating / tau)


@jit_noalloc
def gauss_markov_coefficients(dt, tau):
    """(a, sqrt(1 - a^2)) of the exact discrete first-order Gauss-Markov step ``dt`` (core.elementary)."""
    a = elementary.exp(-dt / tau)
    return a, math.sqrt(1.0 - a * a)


@jit_noalloc
def start(nav, dt, rng_state, knowledge):
    """The Gauss-Markov processes at t = 0 (stationary draws) and their coefficients for step ``dt``;
    a process whose sigma is zero stays zero and draws nothing."""
    for k in range(KNOWLEDGE_SIZE):
        knowledge[k] = 0.0
    sigma_att, sigma_rate = nav[N_ATT_GM_SIGMA], nav[N_RATE_GM_SIGMA]
    if sigma_att > 0.0:
        knowledge[K_ATT_DECAY], knowledge[K_ATT_DRIVE] = gauss_markov_coefficients(dt, nav[N_ATT_GM_TAU])
        for i in range(3):
            knowledge[K_ATTITUDE + i] = sigma_att * rng.next_normal(rng_state)
    if sigma_rate > 0.0:
        knowledge[K_RATE_DECAY], knowledge[K_RATE_DRIVE] = gauss_markov_coefficients(dt, nav[N_RATE_GM_TAU])
        for i in range(3):
            knowledge[K_RATE + i] = sigma_rate * rng.next_normal(rng_state)


@jit_noalloc
def propagate(nav, rng_state, knowledge):
    """One control period of the Gauss-Markov processes (exact update; none where sigma is zero)."""
    sigma_att, sigma_rate = nav[N_ATT_GM_SIGMA], nav[N_RATE_GM_SIGMA]
    if sigma_att > 0.0:
        a, b = knowledge[K_ATT_DECAY], knowledge[K_ATT_DRIVE] * sigma_att
        for i in range(3):
            knowledge[K_ATTITUDE + i] = a * knowledge[K_ATTITUDE + i] + b * rng.next_normal(rng_state)
    if sigma_rate > 0.0:
        a, b = knowledge[K_RATE_DECAY], knowledge[K_RATE_DRIVE] * sigma_rate
        for i in range(3):
            knowledge[K_RATE + i] = a * knowledge[K_RATE + i] + b * rng.next_normal(rng_state)


@jit_inline
def measure(x, nav, time_calibrating, rng_state, knowledge, q_out, rate_out, work4):
    """Measured attitude quaternion and body rates from the true state ``x``; then the
    Gauss-Markov processes advance one control period (:func:`propagate`)."""
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
    if nav[N_ATT_GM_SIGMA] > 0.0:
        ex += knowledge[K_ATTITUDE]
        ey += knowledge[K_ATTITUDE + 1]
        ez += knowledge[K_ATTITUDE + 2]
    if ex == 0.0 and ey == 0.0 and ez == 0.0:
        for i in range(4):
            q_out[i] = x[i]
    else:
        quaternion.from_rotation_vector(ex, ey, ez, work4)
        quaternion.multiply(x[0:4], work4, q_out)
    gm_rate = nav[N_RATE_GM_SIGMA] > 0.0
    for i in range(3):
        rate_out[i] = x[4 + i] + nav[N_RATE_BIAS + i]
        if sigma_rate > 0.0:
            rate_out[i] += sigma_rate * rng.next_normal(rng_state)
        if gm_rate:
            rate_out[i] += knowledge[K_RATE + i]
    propagate(nav, rng_state, knowledge)
