"""core.keyed_random against numpy: the keyed uniforms of a campaign are numpy's, bit for bit."""

import naive
import numpy as np
import pytest

from refexmc.campaign.sampling import keyed_rng, keyed_uniforms
from refexmc.core import keyed_random


@pytest.mark.parametrize("words", [1, 2, 3, 4, 5, 6, 9])
def test_uniforms_equal_default_rng_of_the_seed_sequence(words):
    """Entropies of 1 to 9 32-bit words (fewer than numpy's pool of 4, as many, more: each branch of
    the mix), zeros among them, 1000 keys each, 9 doubles per key: exactly numpy's."""
    rng = np.random.default_rng(words)
    out = np.empty(9)
    for k in range(1000):
        entropy = [int(w) for w in rng.integers(0, 2**32, size=words, dtype=np.uint64)]
        if k % 4 == 0:
            entropy[k % words] = 0
        expected = np.random.default_rng(np.random.SeedSequence(entropy)).random(9)
        keyed_random.uniforms(keyed_random.entropy_words(entropy), out)
        np.testing.assert_array_equal(out, expected, err_msg=str(entropy))


def test_entropy_words_are_numpys():
    """Each integer as 32-bit words, low first, 0 one word: numpy assembles the same entropy from
    the integers as from these words (its pool and its state agree)."""
    for entropy in ([0], [1, 0, 2**32], [2**64 - 1, 5], [20261123, 17, 2**63 + 12345, 0], [2**96 + 7]):
        words = [int(w) for w in keyed_random.entropy_words(entropy)]
        assert all(0 <= w < 2**32 for w in words)
        ours, theirs = np.random.SeedSequence(words), np.random.SeedSequence(entropy)
        np.testing.assert_array_equal(ours.pool, theirs.pool)
        np.testing.assert_array_equal(ours.generate_state(8), theirs.generate_state(8))
    assert list(keyed_random.entropy_words([0, 2**32 + 3])) == [0, 3, 1]


def test_keyed_uniforms_equal_the_keyed_generator():
    """What the sampler draws is what keyed_rng(...).random(count) would draw."""
    for run_id in (0, 1, 999, 10**6 + 3):
        for name in ("inertia_kg_m2", "initial_state.rates_deg_s", "wheels.friction.coulomb_n_m"):
            for attempt in (0, 1, 7):
                expected = keyed_rng(20231121, run_id, name, attempt).random(6)
                np.testing.assert_array_equal(keyed_uniforms(20231121, run_id, name, 6, attempt), expected)


def test_the_kernel_equals_its_slow_twin():
    """tests/naive.keyed_doubles (Python integers, no numpy random) on keys of 1-7 words."""
    rng = np.random.default_rng(15)
    out = np.empty(4)
    for k in range(300):
        entropy = [int(w) for w in rng.integers(0, 2**63, size=1 + k % 7, dtype=np.uint64)]
        keyed_random.uniforms(keyed_random.entropy_words(entropy), out)
        assert list(out) == naive.keyed_doubles(entropy, 4), entropy
        assert list(np.random.SeedSequence(entropy).pool) == naive.seed_sequence_pool(entropy)


def test_a_chunk_of_runs_draws_each_run_as_numpy_would_alone():
    """uniforms_for_runs, row by row, is numpy's generator of (seed, run id, path key, attempt):
    run ids 0 and past 2^32 (one word, two words), keys of one and two words, attempts 0 and large."""
    run_ids = np.array([0, 1, 7, 999, 2**32 - 1, 2**32, 2**40 + 5, 10**12])
    for seed in (0, 20231121, 2**64 + 3):
        for key in (0, 12345, 2**63 + 99):
            for attempt in (0, 3, 2**33):
                out = np.empty((len(run_ids), 5))
                keyed_random.uniforms_for_runs(
                    keyed_random.entropy_words([seed]), run_ids, np.uint64(key), np.int64(attempt), out
                )
                for row, run_id in zip(out, run_ids, strict=True):
                    entropy = [seed, int(run_id), key, attempt]
                    expected = np.random.default_rng(np.random.SeedSequence(entropy)).random(5)
                    np.testing.assert_array_equal(row, expected, err_msg=str(entropy))
