"""Per-run seeds derived from the campaign seed and the run id, never from worker state."""

import numpy as np


def run_seed(campaign_seed, run_id):
    """A 63-bit seed for run ``run_id``: the same whatever order or process runs it."""
    state = np.random.SeedSequence([int(campaign_seed), int(run_id)]).generate_state(2, np.uint32)
    return int((int(state[0]) << 31) ^ int(state[1])) & (2**63 - 1)
