"""Keyed uniforms, bit for bit those of ``numpy.random.default_rng(SeedSequence(entropy)).random(n)``.

A campaign draws each run's parameters from a generator keyed by (seed, run id, path, attempt)
(``refexmc.campaign.sampling``). Building that generator in numpy costs ~35 us (the SeedSequence
entropy mix, then PCG64's seeding), more than the draws; this kernel does the same arithmetic in
one call of a few microseconds:

1. numpy's SeedSequence: the entropy as 32-bit words mixed into a pool of 4 (hashmix / mix);
2. ``generate_state(4, uint64)``: the seed and the increment of PCG64;
3. PCG64's ``srandom_r``, then per double one LCG step (128-bit, multiplier 0x2360ed051fc65da4
   4385df649fccf645), its XSL-RR output, and ``(x >> 11) * 2^-53``.

The constants are numpy's (``numpy/random/bit_generator.pyx``, ``src/pcg64``);
``tests/test_keyed_random.py`` checks the result against numpy on thousands of keys.
"""

import numpy as np

from refexmc._jit import jit, jit_noalloc

_M32 = np.uint64(0xFFFFFFFF)
_INIT_A = np.uint64(0x43B0D7E5)
_MULT_A = np.uint64(0x931E8875)
_INIT_B = np.uint64(0x8B51F9DD)
_MULT_B = np.uint64(0x58F38DED)
_MIX_L = np.uint64(0xCA01F9DD)
_MIX_R = np.uint64(0x4973F715)
_XSHIFT = np.uint64(16)
_PCG_MULT_HI = np.uint64(2549297995355413924)
_PCG_MULT_LO = np.uint64(4865540595714422341)
_SHIFT32 = np.uint64(32)
_SHIFT64_LESS_ONE = np.uint64(63)
_ONE = np.uint64(1)
_ZERO = np.uint64(0)
_DOUBLE_UNIT = 1.0 / 9007199254740992.0  # 2^-53


def entropy_words(values):
    """numpy's SeedSequence words of non-negative integers: each as 32-bit words, low first (0: one word)."""
    words = []
    for value in values:
        value = int(value)
        if value == 0:
            words.append(0)
        while value > 0:
            words.append(value & 0xFFFFFFFF)
            value >>= 32
    return np.array(words, dtype=np.uint64)


@jit_noalloc
def _hashmix(value, hash_const):
    """SeedSequence's hashmix on 32-bit values held in uint64; returns (value, new hash constant)."""
    value = (value ^ hash_const) & _M32
    hash_const = (hash_const * _MULT_A) & _M32
    value = (value * hash_const) & _M32
    return value ^ (value >> _XSHIFT), hash_const


@jit_noalloc
def _mix(x, y):
    result = (_MIX_L * x - _MIX_R * y) & _M32
    return result ^ (result >> _XSHIFT)


@jit_noalloc
def _mul_hi(a, b):
    """The high 64 bits of the 128-bit product of two uint64."""
    a0, a1 = a & _M32, a >> _SHIFT32
    b0, b1 = b & _M32, b >> _SHIFT32
    p00, p01, p10, p11 = a0 * b0, a0 * b1, a1 * b0, a1 * b1
    middle = (p00 >> _SHIFT32) + (p01 & _M32) + (p10 & _M32)
    return p11 + (p01 >> _SHIFT32) + (p10 >> _SHIFT32) + (middle >> _SHIFT32)


@jit_noalloc
def _step(hi, lo, inc_hi, inc_lo):
    """One PCG64 LCG step: state * multiplier + increment, mod 2^128."""
    new_hi = _mul_hi(lo, _PCG_MULT_LO) + lo * _PCG_MULT_HI + hi * _PCG_MULT_LO
    new_lo = lo * _PCG_MULT_LO
    total_lo = new_lo + inc_lo
    carry = _ONE if total_lo < new_lo else _ZERO
    return new_hi + inc_hi + carry, total_lo


@jit
def uniforms(words, out):
    """``out[:] = default_rng(SeedSequence(entropy)).random(len(out))``, ``words`` the entropy's
    32-bit words (:func:`entropy_words`) as uint64. ``out`` is caller-owned."""
    pool = np.empty(4, dtype=np.uint64)
    hash_const = _INIT_A
    n_words = words.shape[0]
    for i in range(4):
        value = words[i] if i < n_words else _ZERO
        pool[i], hash_const = _hashmix(value, hash_const)
    for src in range(4):
        for dst in range(4):
            if src != dst:
                mixed, hash_const = _hashmix(pool[src], hash_const)
                pool[dst] = _mix(pool[dst], mixed)
    for src in range(4, n_words):
        for dst in range(4):
            mixed, hash_const = _hashmix(words[src], hash_const)
            pool[dst] = _mix(pool[dst], mixed)
    # generate_state(4, uint64): 8 words, paired low-high
    state64 = np.empty(4, dtype=np.uint64)
    hash_b = _INIT_B
    for k in range(4):
        halves = np.empty(2, dtype=np.uint64)
        for j in range(2):
            value = (pool[(2 * k + j) % 4] ^ hash_b) & _M32
            hash_b = (hash_b * _MULT_B) & _M32
            value = (value * hash_b) & _M32
            halves[j] = value ^ (value >> _XSHIFT)
        state64[k] = halves[0] | (halves[1] << _SHIFT32)
    # PCG64 srandom_r: state 0, inc = initseq << 1 | 1, step, state += initstate, step
    inc_hi = (state64[2] << _ONE) | (state64[3] >> _SHIFT64_LESS_ONE)
    inc_lo = (state64[3] << _ONE) | _ONE
    hi, lo = _step(_ZERO, _ZERO, inc_hi, inc_lo)
    new_lo = lo + state64[1]
    hi = hi + state64[0] + (_ONE if new_lo < lo else _ZERO)
    lo = new_lo
    hi, lo = _step(hi, lo, inc_hi, inc_lo)
    for n in range(out.shape[0]):
        hi, lo = _step(hi, lo, inc_hi, inc_lo)
        x = hi ^ lo
        rot = hi >> np.uint64(58)
        x = (x >> rot) | (x << ((np.uint64(64) - rot) & _SHIFT64_LESS_ONE))
        out[n] = np.float64(x >> np.uint64(11)) * _DOUBLE_UNIT


@jit_noalloc
def _append_words(value, words, n):
    """Append numpy's SeedSequence words of ``value`` (uint64: 32-bit words, low first; 0 is one
    word) at ``words[n]``; return the new word count (:func:`entropy_words` for one integer)."""
    if value == _ZERO:
        words[n] = _ZERO
        return n + 1
    while value > _ZERO:
        words[n] = value & _M32
        value = value >> _SHIFT32
        n += 1
    return n


@jit
def uniforms_for_runs(leading_words, run_ids, path_key, attempt, out):
    """Row i of ``out``: :func:`uniforms` of the entropy (leading integers, ``run_ids[i]``,
    ``path_key``, ``attempt``), i.e. the keyed draws of a campaign's runs for one parameter path.
    ``leading_words``: the words of the integers before the run id (:func:`entropy_words`);
    run ids, key and attempt are non-negative and below 2^64."""
    n_leading = leading_words.shape[0]
    words = np.empty(n_leading + 6, dtype=np.uint64)
    words[:n_leading] = leading_words
    for i in range(run_ids.shape[0]):
        n = _append_words(np.uint64(run_ids[i]), words, n_leading)
        n = _append_words(path_key, words, n)
        n = _append_words(np.uint64(attempt), words, n)
        uniforms(words[:n], out[i])
