"""A small counter-free PRNG for navigation noise inside the run loop.

SplitMix64 (Steele, Lea, Flood 2014) seeded per run, with Box-Muller normals. It keeps the core
independent of any global random state: the same seed gives the same noise on any process.
The state is a caller-owned ``uint64`` array of length 1.
"""

import math

import numpy as np

from refexmc._jit import jit_noalloc
from refexmc.core import elementary

_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_MIX1 = np.uint64(0xBF58476D1CE4E5B9)
_MIX2 = np.uint64(0x94D049BB133111EB)
_TWO_POW_MINUS_53 = 1.0 / 9007199254740992.0


@jit_noalloc
def next_uniform(state):
    """Uniform draw in (0, 1); advances ``state``."""
    state[0] += _GOLDEN
    z = state[0]
    z = (z ^ (z >> np.uint64(30))) * _MIX1
    z = (z ^ (z >> np.uint64(27))) * _MIX2
    z = z ^ (z >> np.uint64(31))
    return (float(z >> np.uint64(11)) + 0.5) * _TWO_POW_MINUS_53


@jit_noalloc
def next_normal(state):
    """Standard normal draw (Box-Muller, one of the pair); advances ``state`` twice."""
    u1 = next_uniform(state)
    u2 = next_uniform(state)
    return math.sqrt(-2.0 * elementary.log(u1)) * elementary.cos(2.0 * math.pi * u2)
