"""Correctly rounded exp, log, pow, sin, cos, asin and atan2, elementwise: the same bits on every CPU.

A campaign's draws must not depend on the machine that draws them (a campaign and seed give the
same runs table anywhere). Two ways the usual functions do:

- numpy's transcendental ufuncs on arrays (``np.exp``, ``np.log``, ``np.sin``, ``np.cos``,
  ``np.power``, ...) run SIMD code chosen at run time: with AVX-512, ``np.exp`` is one ulp away
  from the scalar result for ~5 % of lognormal draws (issue 22);
- glibc's scalar libm (``math.exp``, also what numba and scipy's C code call) picks an FMA/AVX2
  variant of exp, log, sin, cos and atan2 where the CPU has them: it differs from the plain
  variant in about 1 result in 1,500 (``GLIBC_TUNABLES=glibc.cpu.hwcaps=-AVX2,-FMA`` turns it
  off: ``tests/test_cpu_independence.py``).

A correctly rounded result has one value whatever the CPU and library. These functions get it
from MPFR (through gmpy2) in IEEE binary64 (53-bit significand, round to nearest, subnormals),
~1.5 us per value: the draws of a chunk take a few milliseconds. Everything else the sampler
computes is + - * / and sqrt (correctly rounded IEEE operations, SIMD or not) in a fixed order.
"""

import gmpy2
import numpy as np

_BINARY64 = gmpy2.ieee(64)


def _elementwise(function, *arguments):
    """``function`` of each element (broadcast), as a float array of the broadcast shape."""
    arrays = np.broadcast_arrays(*(np.asarray(argument, dtype=float) for argument in arguments))
    flat = [array.ravel().tolist() for array in arrays]
    values = [float(function(*numbers)) for numbers in zip(*flat, strict=True)]
    return np.array(values, dtype=float).reshape(arrays[0].shape)


def exp(x):
    """e**x of each element, correctly rounded."""
    return _elementwise(_BINARY64.exp, x)


def log(x):
    """Natural logarithm of each element, correctly rounded (-inf at 0, NaN below)."""
    return _elementwise(_BINARY64.log, x)


def pow(x, y):  # noqa: A001 - the C name; refexmc.crmath.pow never shadows the builtin where imported
    """x**y of each pair of elements, correctly rounded."""
    return _elementwise(_BINARY64.pow, x, y)


def asin(x):
    """arcsin of each element (radians, in [-pi/2, pi/2]; NaN outside [-1, 1]), correctly rounded."""
    return _elementwise(_BINARY64.asin, x)


def sin(x):
    """sin x of each element (radians), correctly rounded."""
    return _elementwise(_BINARY64.sin, x)


def cos(x):
    """cos x of each element (radians), correctly rounded."""
    return _elementwise(_BINARY64.cos, x)


def atan2(y, x):
    """atan2(y, x) of each pair of elements (radians, in [-pi, pi]), correctly rounded."""
    return _elementwise(_BINARY64.atan2, y, x)
