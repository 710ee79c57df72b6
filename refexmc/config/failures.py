"""What a campaign's failure keys fail, and the sets ``enumerate`` flies.

Apart from ``refexmc.config.load`` (which validates the keys) so that a worker, which draws each
run's failures, does not import the validator (jsonschema, ~0.1 s of its start-up).
"""

import itertools
from typing import NamedTuple

NO_FAILURES = {"mode": "none"}


class FailureKind(NamedTuple):
    """What a campaign's failure key fails: ``failures`` thrusters, ``wheel_failures`` wheels."""

    key: str  # the campaign key
    units_key: str  # its list of failed units (mode fixed)
    word: str  # one unit, in messages


THRUSTER_FAILURES = FailureKind("failures", "thrusters", "thruster")
WHEEL_FAILURES = FailureKind("wheel_failures", "wheels", "wheel")


def failure_sets(sizes, n_units):
    """Every set of failed units (1-based, ascending) of the given sizes, smallest sizes first."""
    return [combo for k in sorted(sizes) for combo in itertools.combinations(range(1, n_units + 1), k)]
