"""Elementary functions written with + - * / and sqrt only: the same bits on every CPU and the GPU.

glibc's libm (what ``math.sin`` compiles to in numba) picks an FMA/AVX2 variant of exp, sin, cos,
atan2, ... per CPU, and CUDA's libdevice has its own: a flight that calls them differs in its
last bits between machines and targets (docs/campaigns.md, "The flights and elementary
functions"). These are ports of Sun's fdlibm as musl libc carries it (function names cited per
function), evaluated in a fixed order with IEEE operations that are correctly rounded on every
target (+ - * /, ``math.sqrt``), comparisons, ``math.fabs``/``copysign``, and the exact scalings
``math.frexp``; no other libm call, and no fused multiply-add (numba compiles
without fast-math; the CUDA side compiles without contraction). fdlibm's bit manipulations are
replaced by arithmetic equivalents: exponent tests by comparisons with the constant they encode,
the low-word zeroing of asin/acos/tan by a Veltkamp split (``_split_high``), which leaves an
equally exact product.

Accuracy (tests/test_elementary.py, against MPFR): below 1 ulp on the documented domain.
Domain: sin, cos, tan reduce their argument by pi/2 in three Cody-Waite parts (fdlibm's
``__rem_pio2`` "medium" path), exact to ``|x| < 2**20 * pi/2`` (~1.6e6 rad); beyond that they stay
deterministic (same operations, same bits everywhere) but lose accuracy, growing with ``|x|``;
no flight reaches it (angles are attitudes, latitudes, anomalies, headings; orbit.py's Earth
rotation angle is 7.3e-5 rad/s times the flight time). Infinite or NaN arguments give NaN.

====================================================
Copyright (C) 1993 by Sun Microsystems, Inc. All rights reserved.

Developed at SunSoft, a Sun Microsystems, Inc. business.
Permission to use, copy, modify, and distribute this
software is freely granted, provided that this notice
is preserved.
====================================================
(musl's ports: Copyright (c) 2005-2020 Rich Felker, et al., MIT licence.)
"""

import math

from refexmc._jit import jit_noalloc

# --- __rem_pio2 (medium path): pi/2 in three parts of 33 bits plus tails ---------------------
_TOINT = 1.5 / 2.220446049250313e-16  # 1.5 * 2**52: adding and subtracting it rounds to an integer
_INV_PIO2 = 6.36619772367581382433e-01
_PIO2_1 = 1.57079632673412561417e00  # first 33 bits of pi/2
_PIO2_1T = 6.07710050650619224932e-11  # pi/2 - _PIO2_1
_PIO2_2 = 6.07710050630396597660e-11  # second 33 bits of pi/2
_PIO2_2T = 2.02226624879595063154e-21  # pi/2 - (_PIO2_1 + _PIO2_2)
_PIO2_3 = 2.02226624871116645580e-21  # third 33 bits of pi/2
_PIO2_3T = 8.47842766036889956997e-32  # pi/2 - (_PIO2_1 + _PIO2_2 + _PIO2_3)
_PIO4_HIGH_WORD = 0.7853984832763671875  # fdlibm's |x| <= pi/4 test (high word <= 0x3fe921fb)

# --- __sin / __cos kernels on [-pi/4, pi/4] ---------------------------------------------------
_S1 = -1.66666666666666324348e-01
_S2 = 8.33333333332248946124e-03
_S3 = -1.98412698298579493134e-04
_S4 = 2.75573137070700676789e-06
_S5 = -2.50507602534068634195e-08
_S6 = 1.58969099521155010221e-10
_C1 = 4.16666666666666019037e-02
_C2 = -1.38888888888741095749e-03
_C3 = 2.48015872894767294178e-05
_C4 = -2.75573143513906633035e-07
_C5 = 2.08757232129817482790e-09
_C6 = -1.13596475577881948265e-11

# --- __tan kernel ------------------------------------------------------------------------------
_T0 = 3.33333333333334091986e-01
_T1 = 1.33333333333201242699e-01
_T2 = 5.39682539762260521377e-02
_T3 = 2.18694882948595424599e-02
_T4 = 8.86323982359930005737e-03
_T5 = 3.59207910759131235356e-03
_T6 = 1.45620945432529025516e-03
_T7 = 5.88041240820264096874e-04
_T8 = 2.46463134818469906812e-04
_T9 = 7.81794442939557092300e-05
_T10 = 7.14072491382608190305e-05
_T11 = -1.85586374855275456654e-05
_T12 = 2.59073051863633712884e-05
_PIO4 = 7.85398163397448278999e-01
_PIO4_LO = 3.06161699786838301793e-17
_TAN_BIG = 0.674335479736328125  # high word >= 0x3FE59428

# --- exp ---------------------------------------------------------------------------------------
_LN2_HI = 6.93147180369123816490e-01  # 32 bits: k * _LN2_HI is exact for |k| < 2**21
_LN2_LO = 1.90821492927058770002e-10
_INV_LN2 = 1.44269504088896338700e00
_P1 = 1.66666666666666019037e-01
_P2 = -2.77777777770155933842e-03
_P3 = 6.61375632143793436117e-05
_P4 = -1.65339022054652515390e-06
_P5 = 4.13813679705723846039e-08
_EXP_OVERFLOW = 709.782712893383973096  # above: inf
_EXP_UNDERFLOW = -745.13321910194110842  # below: 0
_HALF_LN2 = 0.3465735912322998046875  # high word >= 0x3fd62e43
_THREE_HALVES_LN2 = 1.03972053527832031250  # high word >= 0x3ff0a2b2

# --- log ---------------------------------------------------------------------------------------
_LG1 = 6.666666666666735130e-01
_LG2 = 3.999999999940941908e-01
_LG3 = 2.857142874366239149e-01
_LG4 = 2.222219843214978396e-01
_LG5 = 1.818357216161805012e-01
_LG6 = 1.531383769920937332e-01
_LG7 = 1.479819860511658591e-01
_SQRT_HALF_HIGH_WORD = 0.70710659027099609375  # fdlibm's mantissa test (0x6a09e) on [0.5, 1)

# --- atan --------------------------------------------------------------------------------------
_ATAN_HI_0 = 4.63647609000806093515e-01  # atan(0.5)
_ATAN_HI_1 = 7.85398163397448278999e-01  # atan(1)
_ATAN_HI_2 = 9.82793723247329054082e-01  # atan(1.5)
_ATAN_HI_3 = 1.57079632679489655800e00  # atan(inf)
_ATAN_LO_0 = 2.26987774529616870924e-17
_ATAN_LO_1 = 3.06161699786838301793e-17
_ATAN_LO_2 = 1.39033110312309984516e-17
_ATAN_LO_3 = 6.12323399573676603587e-17
_AT0 = 3.33333333333329318027e-01
_AT1 = -1.99999999998764832476e-01
_AT2 = 1.42857142725034663711e-01
_AT3 = -1.11111104054623557880e-01
_AT4 = 9.09088713343650656196e-02
_AT5 = -7.69187620504482999495e-02
_AT6 = 6.66107313738753120669e-02
_AT7 = -5.83357013379057348645e-02
_AT8 = 4.97687799461593236017e-02
_AT9 = -3.65315727442169155270e-02
_AT10 = 1.62858201153657823623e-02
_PI = 3.1415926535897931160e00
_PI_LO = 1.2246467991473531772e-16

# --- asin / acos -------------------------------------------------------------------------------
_PIO2_HI = 1.57079632679489655800e00
_PIO2_LO = 6.12323399573676603587e-17
_PS0 = 1.66666666666666657415e-01
_PS1 = -3.25565818622400915405e-01
_PS2 = 2.01212532134862925881e-01
_PS3 = -4.00555345006794114027e-02
_PS4 = 7.91534994289814532176e-04
_PS5 = 3.47933107596021167570e-05
_QS1 = -2.40339491173441421878e00
_QS2 = 2.02094576023350569471e00
_QS3 = -6.88283971605453293030e-01
_QS4 = 7.70381505559019352791e-02
_ASIN_NEAR_ONE = 0.974999904632568359375  # high word >= 0x3fef3333

_VELTKAMP = 134217729.0  # 2**27 + 1
_TINY_SPLIT = 2.0**-450  # Dekker products of numbers within these stay exact (no under/overflow)
_HUGE_SPLIT = 2.0**450
_TWO_M16 = 2.0**-16
_TWO_P62 = 2.0**62
_TWO_M62 = 2.0**-62
_TWO_M1022 = 2.0**-1022
_TWO_M49 = 2.0**-49


@jit_noalloc
def _split_high(x):
    """The leading 26 bits of ``x`` (Veltkamp split): ``_split_high(x)**2`` is exact. For |x| < 2**996."""
    c = x * _VELTKAMP
    return c - (c - x)


@jit_noalloc
def _rem_pio2(x):
    """``(n, y0, y1)`` with ``x = n pi/2 + y0 + y1``, ``|y0| <= ~pi/4`` (fdlibm ``__rem_pio2``, medium).

    Exact reduction for ``|x| < 2**20 pi/2``; larger ``|x|`` lose accuracy (module docstring).
    The second and third rounds run where fdlibm's would (exponent drop over 16 and 49 bits),
    tested on magnitudes: a superset of its cases, which only adds precision.
    """
    fn = (x * _INV_PIO2 + _TOINT) - _TOINT
    r = x - fn * _PIO2_1
    w = fn * _PIO2_1T  # first round, good to 85 bits
    y0 = r - w
    ax = math.fabs(x)
    if math.fabs(y0) < ax * _TWO_M16:  # second round, good to 118 bits
        t = r
        w = fn * _PIO2_2
        r = t - w
        w = fn * _PIO2_2T - ((t - r) - w)
        y0 = r - w
        if math.fabs(y0) < ax * _TWO_M49:  # third round, good to 151 bits
            t = r
            w = fn * _PIO2_3
            r = t - w
            w = fn * _PIO2_3T - ((t - r) - w)
            y0 = r - w
    y1 = (r - y0) - w
    return int(fn), y0, y1


@jit_noalloc
def _kernel_sin(x, y):
    """sin(x + y) on [-pi/4, pi/4], ``y`` the tail of ``x`` (fdlibm ``__kernel_sin``, iy = 1)."""
    z = x * x
    w = z * z
    r = _S2 + z * (_S3 + z * _S4) + z * w * (_S5 + z * _S6)
    v = z * x
    return x - ((z * (0.5 * y - v * r) - y) - v * _S1)


@jit_noalloc
def _kernel_cos(x, y):
    """cos(x + y) on [-pi/4, pi/4] (fdlibm ``__kernel_cos``)."""
    z = x * x
    w = z * z
    r = z * (_C1 + z * (_C2 + z * _C3)) + w * w * (_C4 + z * (_C5 + z * _C6))
    hz = 0.5 * z
    w = 1.0 - hz
    return w + (((1.0 - w) - hz) + (z * r - x * y))


@jit_noalloc
def sin(x):
    """sin x (radians); NaN for inf or NaN (fdlibm ``sin``)."""
    if math.fabs(x) <= _PIO4_HIGH_WORD:
        if math.fabs(x) < 1.4901161193847656e-08:  # |x| < 2**-26: sin x rounds to x
            return x
        return _kernel_sin(x, 0.0)
    if not math.fabs(x) < math.inf:
        return x - x
    n, y0, y1 = _rem_pio2(x)
    quadrant = n & 3
    if quadrant == 0:
        return _kernel_sin(y0, y1)
    if quadrant == 1:
        return _kernel_cos(y0, y1)
    if quadrant == 2:
        return -_kernel_sin(y0, y1)
    return -_kernel_cos(y0, y1)


@jit_noalloc
def cos(x):
    """cos x (radians); NaN for inf or NaN (fdlibm ``cos``)."""
    if math.fabs(x) <= _PIO4_HIGH_WORD:
        if math.fabs(x) < 1.0536709282860102e-08:  # high word < 0x3e46a09e (~2**-27 sqrt(2)): rounds to 1
            return 1.0
        return _kernel_cos(x, 0.0)
    if not math.fabs(x) < math.inf:
        return x - x
    n, y0, y1 = _rem_pio2(x)
    quadrant = n & 3
    if quadrant == 0:
        return _kernel_cos(y0, y1)
    if quadrant == 1:
        return -_kernel_sin(y0, y1)
    if quadrant == 2:
        return -_kernel_cos(y0, y1)
    return _kernel_sin(y0, y1)


@jit_noalloc
def sincos(x):
    """``(sin x, cos x)`` with one argument reduction: the same bits as :func:`sin` and :func:`cos`."""
    ax = math.fabs(x)
    if ax <= _PIO4_HIGH_WORD:
        s = x if ax < 1.4901161193847656e-08 else _kernel_sin(x, 0.0)
        c = 1.0 if ax < 1.0536709282860102e-08 else _kernel_cos(x, 0.0)
        return s, c
    if not ax < math.inf:
        return x - x, x - x
    n, y0, y1 = _rem_pio2(x)
    s = _kernel_sin(y0, y1)
    c = _kernel_cos(y0, y1)
    quadrant = n & 3
    if quadrant == 0:
        return s, c
    if quadrant == 1:
        return c, -s
    if quadrant == 2:
        return -s, -c
    return -c, s


@jit_noalloc
def _kernel_tan(x, y, odd):
    """tan(x + y) on [-pi/4, pi/4], or -1/tan where ``odd`` (fdlibm ``__kernel_tan``)."""
    big = math.fabs(x) >= _TAN_BIG
    negative = x < 0.0
    if big:
        if negative:
            x = -x
            y = -y
        x = (_PIO4 - x) + (_PIO4_LO - y)
        y = 0.0
    z = x * x
    w = z * z
    r = _T1 + w * (_T3 + w * (_T5 + w * (_T7 + w * (_T9 + w * _T11))))
    v = z * (_T2 + w * (_T4 + w * (_T6 + w * (_T8 + w * (_T10 + w * _T12)))))
    s = z * x
    r = y + z * (s * (r + v) + y) + s * _T0
    w = x + r
    if big:
        s = 1.0 - 2.0 * odd
        v = s - 2.0 * (x + (r - w * w / (w + s)))
        return -v if negative else v
    if odd == 0:
        return w
    # -1/(x + r) computed accurately: w0, a0 carry 26 bits so that a0 * w0 is exact
    w0 = _split_high(w)
    v = r - (w0 - x)  # w0 + v = r + x
    a = -1.0 / w
    a0 = _split_high(a)
    return a0 + a * (1.0 + a0 * w0 + a0 * v)


@jit_noalloc
def tan(x):
    """tan x (radians); NaN for inf or NaN (fdlibm ``tan``)."""
    if math.fabs(x) <= _PIO4_HIGH_WORD:
        if math.fabs(x) < 7.450580596923828e-09:  # |x| < 2**-27
            return x
        return _kernel_tan(x, 0.0, 0)
    if not math.fabs(x) < math.inf:
        return x - x
    n, y0, y1 = _rem_pio2(x)
    return _kernel_tan(y0, y1, n & 1)


@jit_noalloc
def exp(x):
    """e**x: inf above 709.78, 0 below -745.13, subnormal between (fdlibm ``exp``)."""
    if x != x:
        return x
    if x > _EXP_OVERFLOW:
        return math.inf
    if x < _EXP_UNDERFLOW:
        return 0.0
    ax = math.fabs(x)
    if ax >= _HALF_LN2:  # reduce: x = k ln2 + r, |r| <= ln2 / 2
        if ax >= _THREE_HALVES_LN2:
            k = int(_INV_LN2 * x + math.copysign(0.5, x))
        else:
            k = 1 if x > 0.0 else -1
        hi = x - k * _LN2_HI  # exact
        lo = k * _LN2_LO
        x = hi - lo
    elif ax > 3.725290298461914e-09:  # |x| > 2**-28
        k = 0
        hi = x
        lo = 0.0
    else:
        return 1.0 + x
    xx = x * x
    c = x - xx * (_P1 + xx * (_P2 + xx * (_P3 + xx * (_P4 + xx * _P5))))
    t = x * c / (2.0 - c) - lo + hi  # e**x = (1 + t) 2**k
    if k < -1021:  # subnormal result: 2**k and t 2**k each on the subnormal grid, one rounding
        if k < -1074:  # (1 + t) 2**-1075 rounds to the least subnormal where t > 0, else to 0
            return 5e-324 if t > 0.0 else 0.0
        step = _times_power_of_two(1.0, k + 1022)  # 2**(k + 1022), k + 1022 in [-52, -1]: exact
        return step * _TWO_M1022 + (t * step) * _TWO_M1022  # one rounding, in the last product
    y = 1.0 + t
    if k == 0:
        return y
    return _times_power_of_two(y, k)


@jit_noalloc
def _times_power_of_two(y, k):
    """``y * 2**k`` exactly where every partial product is normal (what math.ldexp gives; numba's
    ldexp is a call into its C helpers, ~5x the time of this): steps of 2**62, then one of
    ``float(1 << |k|)``."""
    while k > 62:
        y *= _TWO_P62
        k -= 62
    while k < -62:
        y *= _TWO_M62
        k += 62
    if k >= 0:
        return y * float(1 << k)
    return y / float(1 << -k)


@jit_noalloc
def log(x):
    """Natural logarithm: -inf at +-0, NaN below 0, subnormals included (fdlibm ``log``)."""
    if not x > 0.0:
        if x == 0.0:
            return -math.inf
        return math.nan  # negative or NaN
    if x == math.inf:
        return x
    m, e = math.frexp(x)  # x = m 2**e, m in [0.5, 1): exact, subnormals too
    if m >= _SQRT_HALF_HIGH_WORD:  # reduce into [sqrt(2)/2, sqrt(2)) as fdlibm does
        k = e
        f = m - 1.0
    else:
        k = e - 1
        f = 2.0 * m - 1.0
    hfsq = 0.5 * f * f
    s = f / (2.0 + f)
    z = s * s
    w = z * z
    t1 = w * (_LG2 + w * (_LG4 + w * _LG6))
    t2 = z * (_LG1 + w * (_LG3 + w * (_LG5 + w * _LG7)))
    big_r = t2 + t1
    dk = float(k)
    return s * (hfsq + big_r) + dk * _LN2_LO - hfsq + f + dk * _LN2_HI


@jit_noalloc
def _atan_positive(x, tail):
    """atan(x + tail) as ``(high, u)``, the value ``high - u``, for x >= 0 or NaN, ``tail`` far below
    an ulp of ``x`` (fdlibm ``atan`` after its sign handling; the tail, atan2's division remainder,
    enters as tail / (1 + x**2); atan2 adds pi to the two parts apart)."""
    if not x < 7.378697629483821e19:  # x >= 2**66 or NaN
        if x != x:
            return x, 0.0
        return _ATAN_HI_3, 0.0
    if x < 0.4375:
        if x < 7.450580596923828e-09:  # 2**-27
            return x, -tail
        z = x * x
        w = z * z
        s1 = z * (_AT0 + w * (_AT2 + w * (_AT4 + w * (_AT6 + w * (_AT8 + w * _AT10)))))
        s2 = w * (_AT1 + w * (_AT3 + w * (_AT5 + w * (_AT7 + w * _AT9))))
        return x, x * (s1 + s2) - tail / (1.0 + z)
    slope_tail = 0.0 if tail == 0.0 else tail / (1.0 + x * x)
    if x < 1.1875:
        if x < 0.6875:
            hi, lo = _ATAN_HI_0, _ATAN_LO_0
            x = (2.0 * x - 1.0) / (2.0 + x)
        else:
            hi, lo = _ATAN_HI_1, _ATAN_LO_1
            x = (x - 1.0) / (x + 1.0)
    elif x < 2.4375:
        hi, lo = _ATAN_HI_2, _ATAN_LO_2
        x = (x - 1.5) / (1.0 + 1.5 * x)
    else:
        hi, lo = _ATAN_HI_3, _ATAN_LO_3
        x = -1.0 / x
    z = x * x
    w = z * z
    s1 = z * (_AT0 + w * (_AT2 + w * (_AT4 + w * (_AT6 + w * (_AT8 + w * _AT10)))))
    s2 = w * (_AT1 + w * (_AT3 + w * (_AT5 + w * (_AT7 + w * _AT9))))
    return hi, (x * (s1 + s2) - lo - x) - slope_tail


@jit_noalloc
def atan(x):
    """arctan x in [-pi/2, pi/2] (fdlibm ``atan``); odd exactly."""
    high, u = _atan_positive(math.fabs(x), 0.0)
    z = high - u
    return -z if x < 0.0 else z


@jit_noalloc
def _quotient_tail(a, b):
    """``a / b - fl(a / b)`` to a few ulps of itself (a Dekker product gives the exact remainder
    ``a - q b``), for positive ``a``, ``b`` within 2**-450 .. 2**450 (else 0): without it, the rounding
    of y / x alone puts fdlibm's atan2 up to 1.3 ulp off."""
    if not (_TINY_SPLIT < a < _HUGE_SPLIT and _TINY_SPLIT < b < _HUGE_SPLIT):
        return 0.0
    q = a / b
    if not _TINY_SPLIT < q < _HUGE_SPLIT:
        return 0.0
    p = q * b
    q_high = _split_high(q)
    b_high = _split_high(b)
    q_low = q - q_high
    b_low = b - b_high
    product_error = ((q_high * b_high - p) + q_high * b_low + q_low * b_high) + q_low * b_low  # q b - p, exact
    return ((a - p) - product_error) / b  # a - p is exact (Sterbenz)


@jit_noalloc
def atan2(y, x):
    """The angle of (x, y) in [-pi, pi], C99 Annex F's signed zeros, infinities and NaN (fdlibm ``atan2``)."""
    if not (x == x and y == y):
        return x + y
    y_negative = math.copysign(1.0, y) < 0.0
    x_negative = math.copysign(1.0, x) < 0.0
    ax = math.fabs(x)
    ay = math.fabs(y)
    if ay == 0.0:
        if not x_negative:
            return y  # atan2(+-0, +anything) = +-0
        return -_PI if y_negative else _PI  # atan2(+-0, -anything) = +-pi
    if ax == 0.0:
        return -_PIO2_HI if y_negative else _PIO2_HI
    if ax == math.inf:
        if ay == math.inf:
            z = 3.0 * _PIO4 if x_negative else _PIO4
        else:
            z = _PI if x_negative else 0.0
        return -z if y_negative else z
    if ay == math.inf:
        return -_PIO2_HI if y_negative else _PIO2_HI
    high, u = _atan_positive(ay / ax, _quotient_tail(ay, ax))  # y / x = inf: pi/2 (fdlibm's 2**64 test)
    if x_negative:  # pi - (high - u), pi - high exactly (Knuth's two-sum): one rounding at the end
        s = _PI - high
        moved = s - _PI
        e = (_PI - (s - moved)) - (high + moved)
        z = s + (e + (_PI_LO + u))
    else:
        z = high - u
    return -z if y_negative else z


@jit_noalloc
def _asin_rational(z):
    """fdlibm's R(z) of asin/acos: (asin(x) - x) / x**3 as a rational function of z = x**2."""
    p = z * (_PS0 + z * (_PS1 + z * (_PS2 + z * (_PS3 + z * (_PS4 + z * _PS5)))))
    q = 1.0 + z * (_QS1 + z * (_QS2 + z * (_QS3 + z * _QS4)))
    return p / q


@jit_noalloc
def asin(x):
    """arcsin x in [-pi/2, pi/2]; NaN outside [-1, 1] (fdlibm ``asin``)."""
    ax = math.fabs(x)
    if not ax < 1.0:
        if ax == 1.0:
            return math.copysign(_PIO2_HI, x)
        return math.nan
    if ax < 0.5:
        if ax < 1.4901161193847656e-08:  # 2**-26: asin x rounds to x
            return x
        return x + x * _asin_rational(x * x)
    z = (1.0 - ax) * 0.5
    s = math.sqrt(z)
    r = _asin_rational(z)
    if ax >= _ASIN_NEAR_ONE:
        t = _PIO2_HI - (2.0 * (s + s * r) - _PIO2_LO)
    else:
        f = _split_high(s)  # f + c = sqrt(z); f * f exact
        c = (z - f * f) / (s + f)
        t = 0.5 * _PIO2_HI - (2.0 * s * r - (_PIO2_LO - 2.0 * c) - (0.5 * _PIO2_HI - 2.0 * f))
    return -t if x < 0.0 else t


@jit_noalloc
def acos(x):
    """arccos x in [0, pi]; NaN outside [-1, 1] (fdlibm ``acos``)."""
    ax = math.fabs(x)
    if not ax < 1.0:
        if x == 1.0:
            return 0.0
        if x == -1.0:
            return 2.0 * _PIO2_HI
        return math.nan
    if ax < 0.5:
        if ax < 6.938893903907228e-18:  # 2**-57
            return _PIO2_HI
        return _PIO2_HI - (x - (_PIO2_LO - x * _asin_rational(x * x)))
    if x < 0.0:
        z = (1.0 + x) * 0.5
        s = math.sqrt(z)
        w = _asin_rational(z) * s - _PIO2_LO
        return 2.0 * (_PIO2_HI - (s + w))
    z = (1.0 - x) * 0.5
    s = math.sqrt(z)
    df = _split_high(s)
    c = (z - df * df) / (s + df)
    w = _asin_rational(z) * s + c
    return 2.0 * (df + w)


# --- min and max of floats -------------------------------------------------------------------
# numba-cuda compiles the builtin min/max of floats to libdevice's fmin/fmax (PTX min.f64/max.f64),
# which answer otherwise than numba's CPU min/max (a comparison and a select, Python's rule) for a
# NaN first argument and for zeros of opposite signs; these two are that select on both targets.


@jit_noalloc(force_inline=True)
def smaller(a, b):
    """min(a, b) as Python takes it: ``b`` only if ``b < a``, else ``a`` (a NaN ``a`` stays)."""
    return b if b < a else a


@jit_noalloc(force_inline=True)
def larger(a, b):
    """max(a, b) as Python takes it: ``b`` only if ``b > a``, else ``a`` (a NaN ``a`` stays)."""
    return b if b > a else a
