"""A run's work arrays as views of caller-owned flat buffers (no allocation in the flight).

A flight's work (core.flight.Work and each family's work tuple) is carved out of four flat
buffers, one per element type (float64, int64, uint64, bool), from a cursor ``at`` that each
take advances. The CPU kernel allocates the buffers once per flight; the GPU backend hands each
thread its rows of device buffers sized at launch (refexmc.campaign.cuda_backend). The same
carving measures the sizes: given a buffer too short (``measuring``: empty), a take returns an
empty view of the right type and still advances the cursor, so the final cursors are the
buffer lengths a run needs (core.flight.work_sizes).
"""

from refexmc._jit import jit


@jit
def vector(buf, at, n):
    """``buf[at : at + n]`` and the cursor after it (an empty view when ``buf`` is too short)."""
    if buf.shape[0] < at + n:
        return buf[0:0], at + n
    return buf[at : at + n], at + n


@jit
def matrix(buf, at, rows, cols):
    """An (rows, cols) C-ordered view from ``at`` and the cursor after it."""
    size = rows * cols
    if buf.shape[0] < at + size:
        return buf[0:0].reshape((0, cols)), at + size
    return buf[at : at + size].reshape((rows, cols)), at + size


@jit
def cube(buf, at, n0, n1, n2):
    """An (n0, n1, n2) C-ordered view from ``at`` and the cursor after it."""
    size = n0 * n1 * n2
    if buf.shape[0] < at + size:
        return buf[0:0].reshape((0, n1, n2)), at + size
    return buf[at : at + size].reshape((n0, n1, n2)), at + size


@jit
def clear(f, i, u, b):
    """Zero the four flat buffers (a GPU's device buffers hold what the last launch left)."""
    for k in range(f.shape[0]):
        f[k] = 0.0
    for k in range(i.shape[0]):
        i[k] = 0
    for k in range(u.shape[0]):
        u[k] = 0
    for k in range(b.shape[0]):
        b[k] = False
