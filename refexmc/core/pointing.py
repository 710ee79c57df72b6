"""Pointing and knowledge error indices of ECSS-E-ST-60-10C at the control rate (reference-model
sec. 7, docs/pointing.md).

Each control step in a requirement's window, :func:`record` writes the error vector e (rad, the
rotation vector of the error, or its part that the requirement's ``error`` names) and the time
into the caller-owned ``Record.samples`` (sized at launch for the window's control steps: no
allocation per step). After the flight, :func:`reduce` computes each requirement's per-run value:

- the index's samples: APE |e(t)|; MPE |mean e| per interval delta_t; RPE |e(t) - mean of its
  interval|; PDE |difference of consecutive interval means| within an observation period; PRE
  |difference of consecutive observation periods' means| (a period: a contiguous stretch of the
  window); the knowledge indices (AKE, MKE, RKE, KDE, KRE) the same on e = estimated - true;
- the interpretation: temporal, the P_C quantile of those samples (exact: the ceil(P_C m)-th
  smallest of m, so never above their largest); ensemble, their largest; mixed, the fraction of
  them above the bound.
"""

import math
from typing import NamedTuple

import numpy as np

from refexmc._jit import jit, jit_noalloc
from refexmc.core import elementary, quaternion
from refexmc.core.layout import (
    ERROR_AXIS,
    ERROR_LOS,
    INTERPRETATION_ENSEMBLE,
    INTERPRETATION_MIXED,
    P_AXIS,
    P_BOUND,
    P_DELTA_T,
    P_ERROR,
    P_INDEX,
    P_INTERPRETATION,
    P_KNOWLEDGE,
    P_MODE_MASK,
    P_PROBABILITY,
    P_WINDOW_FROM,
    P_WINDOW_TO,
    POINTING_INDEX_ABSOLUTE,
    POINTING_INDEX_DRIFT,
    POINTING_INDEX_MEAN,
    POINTING_INDEX_RELATIVE,
    POINTING_INDEX_REPRODUCIBILITY,
    POINTING_SIZE,
)

SAMPLE_SIZE = 4  # e (3, rad), t (s)
PERIOD_GAP = 1.5  # control periods: a longer gap between samples starts a new observation period
MAX_MODES = 32  # the mode mask's bits (schema.MAX_MODES; a float64 holds the mask exactly)


class Record(NamedTuple):
    """The requirements (``layout.POINTING`` rows) and their caller-owned sample buffers."""

    table: np.ndarray  # (requirements, POINTING_SIZE)
    samples: np.ndarray  # (requirements, capacity, SAMPLE_SIZE)
    counts: np.ndarray  # (requirements,) int64: samples written; capacity + 1: the buffer overflowed
    work: np.ndarray  # (2, 4) scratch


def empty_record():
    """A record without requirements: the flight records nothing."""
    return Record(np.zeros((0, POINTING_SIZE)), np.zeros((0, 1, SAMPLE_SIZE)), np.zeros(0, np.int64), np.zeros((2, 4)))


def new_record(table, capacity):
    """Buffers for ``table``'s requirements, ``capacity`` samples each (the window's control steps)."""
    n = table.shape[0]
    return Record(
        np.ascontiguousarray(table, dtype=np.float64),
        np.empty((n, max(int(capacity), 1), SAMPLE_SIZE)),
        np.zeros(n, np.int64),
        np.zeros((2, 4)),
    )


@jit_noalloc
def error_vector(dq, row, work, out):
    """The error of rotation ``dq`` (scalar last) as the requirement ``row`` defines it (rad, 3):
    total, the rotation vector; axis, its component along the row's unit axis; los, the rotation
    taking the boresight b to dq b, of angle atan2(|b x dq b|, b . dq b) exactly."""
    q = work[0]
    sign = -1.0 if dq[3] < 0.0 else 1.0  # the shortest rotation
    for i in range(4):
        q[i] = sign * dq[i]
    error = int(row[P_ERROR])
    if error == ERROR_LOS:
        b = row[P_AXIS : P_AXIS + 3]
        moved = work[1]
        quaternion.rotate(q, b, moved)
        cx = b[1] * moved[2] - b[2] * moved[1]
        cy = b[2] * moved[0] - b[0] * moved[2]
        cz = b[0] * moved[1] - b[1] * moved[0]
        s = math.sqrt(cx * cx + cy * cy + cz * cz)
        if s == 0.0:
            out[0], out[1], out[2] = 0.0, 0.0, 0.0
            return
        angle = elementary.atan2(s, b[0] * moved[0] + b[1] * moved[1] + b[2] * moved[2])
        out[0], out[1], out[2] = cx / s * angle, cy / s * angle, cz / s * angle
        return
    quaternion.to_rotation_vector(q, out)
    if error == ERROR_AXIS:
        a = row[P_AXIS : P_AXIS + 3]
        c = out[0] * a[0] + out[1] * a[1] + out[2] * a[2]
        out[0], out[1], out[2] = c * a[0], c * a[1], c * a[2]


@jit_noalloc
def in_window(row, mode, t):
    """Whether control step ``t``, flying mode ``mode``, is in the requirement's window."""
    if t < row[P_WINDOW_FROM] or t > row[P_WINDOW_TO]:
        return False
    return (int(row[P_MODE_MASK]) >> min(mode, MAX_MODES)) & 1 == 1


@jit_noalloc
def record(rec, q_true, q_ref, q_meas, has_reference, mode, t):
    """One control step: each requirement in its window gets its error sample (performance
    indices need the mode's reference attitude; knowledge indices compare measured and true)."""
    table, samples, counts, work = rec.table, rec.samples, rec.counts, rec.work
    capacity = samples.shape[1]
    for r in range(table.shape[0]):
        row = table[r]
        if not in_window(row, mode, t):
            continue
        knowledge = row[P_KNOWLEDGE] != 0.0
        if not knowledge and not has_reference:
            continue
        k = counts[r]
        if k >= capacity:
            counts[r] = capacity + 1
            continue
        dq = work[1]
        if knowledge:
            quaternion.conj_multiply(q_true, q_meas, dq)  # true body -> estimated body
        else:
            quaternion.conj_multiply(q_ref, q_true, dq)  # reference -> true body
        sample = samples[r, k]
        error_vector(dq, row, work, sample)  # copies dq to work[0] before it reuses work[1]
        sample[3] = t
        counts[r] = k + 1


@jit_noalloc
def _norm3(x, y, z):
    return math.sqrt(x * x + y * y + z * z)


@jit
def index_samples(row, samples, n, dt, out):
    """The index's per-sample values of one requirement's ``n`` samples into ``out``; their count."""
    index = int(row[P_INDEX])
    if index == POINTING_INDEX_ABSOLUTE:
        for k in range(n):
            out[k] = _norm3(samples[k, 0], samples[k, 1], samples[k, 2])
        return n
    delta_t = math.inf if index == POINTING_INDEX_REPRODUCIBILITY else row[P_DELTA_T]
    m = 0
    start = 0  # first sample of the current interval
    period_start_t = samples[0, 3]
    interval = 0
    previous = np.zeros(3)
    has_previous = False  # a previous interval (drift: in this period; reproducibility: a period)
    for k in range(1, n + 1):
        new_period = k == n or samples[k, 3] - samples[k - 1, 3] > PERIOD_GAP * dt
        if not new_period and math.isfinite(delta_t):
            next_interval = int(math.floor((samples[k, 3] - period_start_t) / delta_t + 1e-9))
        else:
            next_interval = interval
        if not new_period and next_interval == interval:
            continue
        count = k - start
        mx, my, mz = 0.0, 0.0, 0.0
        for i in range(start, k):
            mx += samples[i, 0]
            my += samples[i, 1]
            mz += samples[i, 2]
        mx, my, mz = mx / count, my / count, mz / count
        if index == POINTING_INDEX_MEAN:
            out[m] = _norm3(mx, my, mz)
            m += 1
        elif index == POINTING_INDEX_RELATIVE:
            for i in range(start, k):
                out[m] = _norm3(samples[i, 0] - mx, samples[i, 1] - my, samples[i, 2] - mz)
                m += 1
        elif has_previous:  # drift or reproducibility
            out[m] = _norm3(mx - previous[0], my - previous[1], mz - previous[2])
            m += 1
        previous[0], previous[1], previous[2] = mx, my, mz
        has_previous = True
        if new_period and index == POINTING_INDEX_DRIFT:
            has_previous = False  # drift compares intervals within one period
        start = k
        interval = next_interval
        if new_period and k < n:
            period_start_t = samples[k, 3]
            interval = 0
    return m


@jit
def reduce(rec, dt, values):
    """Each requirement's per-run value into ``values`` (NaN: no sample, or too few for the
    index, or an overflowed buffer): temporal, the exact P_C quantile; ensemble, the largest;
    mixed, the fraction above the bound."""
    table, samples, counts = rec.table, rec.samples, rec.counts
    capacity = samples.shape[1]
    scratch = np.empty(capacity)
    for r in range(table.shape[0]):
        row = table[r]
        n = counts[r]
        values[r] = math.nan
        if n == 0 or n > capacity:
            continue
        m = index_samples(row, samples[r], n, dt, scratch)
        if m == 0:
            continue
        interpretation = int(row[P_INTERPRETATION])
        if interpretation == INTERPRETATION_ENSEMBLE:
            values[r] = scratch[:m].max()
        elif interpretation == INTERPRETATION_MIXED:
            above = 0
            for k in range(m):
                if scratch[k] > row[P_BOUND]:
                    above += 1
            values[r] = above / m
        else:
            ordered = np.sort(scratch[:m])
            rank = int(math.ceil(row[P_PROBABILITY] * m - 1e-9))  # the smallest with >= P_C of samples at or below
            values[r] = ordered[min(max(rank, 1), m) - 1]
