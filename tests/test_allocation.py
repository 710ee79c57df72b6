"""Thruster allocation against 000 Table 3, typed in here from the paper."""

import copy
import itertools
import math
from pathlib import Path

import naive
import numpy as np
import pytest

from refexmc.campaign.chunk import RunPlan, fly_chunk
from refexmc.config import derived
from refexmc.config.load import load_campaign
from refexmc.core import allocation, rcs
from refexmc.core import layout as L

FAILURE_1_8 = Path(__file__).resolve().parents[1] / "campaigns/failure-1-8.yaml"
FAILURE_SWEEP = Path(__file__).resolve().parents[1] / "campaigns/failure-sweep.yaml"

# 000 Table 3: thrusters opened for each commanded torque (diagonal) or pair of torques.
TABLE_3 = {
    "+x": {2, 3},
    "-x": {1, 4},
    "+y": {1, 2, 7},
    "-y": {3, 4, 8},
    "+z": {6},
    "-z": {5},
    "+x+y": {2, 3, 7},
    "+x-y": {2, 3, 8},
    "+x+z": {2, 3, 6},
    "+x-z": {2, 3, 5},
    "-x+y": {1, 4, 7},
    "-x-y": {1, 4, 8},
    "-x+z": {1, 4, 6},
    "-x-z": {1, 4, 5},
    "+y+z": {1, 2, 7, 6},
    "+y-z": {1, 2, 7, 5},
    "-y+z": {3, 4, 8, 6},
    "-y-z": {3, 4, 8, 5},
}
ALL_COMMANDS = [w for w in itertools.product((-1, 0, 1), repeat=3) if any(w)]


def key(w):
    return "".join(("+" if v > 0 else "-") + axis for v, axis in zip(w, "xyz", strict=True) if v)


def expected_set(w):
    """Table 3; a three-axis command opens its x-y entry plus the yaw thruster (000 sec. 5)."""
    if all(w):
        return TABLE_3[key((w[0], w[1], 0))] | TABLE_3[key((0, 0, w[2]))]
    return TABLE_3[key(w)]


def test_table_3_has_its_18_entries():
    assert len(TABLE_3) == 18
    assert len(ALL_COMMANDS) == 26  # 18 single/two-axis + 8 three-axis


@pytest.mark.parametrize("w", ALL_COMMANDS, ids=key)
def test_derived_table_and_lookup_equal_table_3(vehicle_config, w):
    table = derived.allocation_table(vehicle_config)
    row = table[(w[0] + 1) * 9 + (w[1] + 1) * 3 + (w[2] + 1)]
    assert {i + 1 for i in np.flatnonzero(row)} == expected_set(w)
    out = np.full(table.shape[1], -1, dtype=np.int64)
    allocation.table_lookup(table, float(w[0]), float(w[1]), float(w[2]), out)
    assert {i + 1 for i in np.flatnonzero(out)} == expected_set(w)
    assert set(np.unique(out)) <= {0, 1}


def test_no_command_opens_nothing(vehicle_config):
    table = derived.allocation_table(vehicle_config)
    out = np.ones(table.shape[1], dtype=np.int64)
    allocation.table_lookup(table, 0.0, 0.0, 0.0, out)
    assert not out.any()


def test_table_rows_are_distinct_and_cover_all_27():
    rows = {allocation.table_row(float(a), float(b), float(c)) for a, b, c in itertools.product((-1, 0, 1), repeat=3)}
    assert rows == set(range(27))


@pytest.mark.parametrize("w", ALL_COMMANDS, ids=key)
def test_naive_allocation_rule_reproduces_table_3(w):
    """The rule in 000 sec. 5's text (tests/naive.py) gives the table: a check on both."""
    assert naive.allocate(*w) == expected_set(w)


@pytest.mark.parametrize("w", ALL_COMMANDS, ids=key)
def test_allocated_torque_has_the_commanded_signs(inputs, w):
    """With equal thrust on every open valve (one derating factor), the net torque of each set
    has the commanded sign on each commanded axis and none on the others (r x F arms)."""
    arms = np.empty((inputs.thrusters.shape[0], 3))
    rcs.torque_arms(inputs.thrusters, inputs.vehicle, arms)
    out = np.zeros(arms.shape[0], dtype=np.int64)
    allocation.table_lookup(inputs.allocation, float(w[0]), float(w[1]), float(w[2]), out)
    torque = arms[out.astype(bool)].sum(axis=0)
    for axis in range(3):
        if w[axis]:
            assert np.sign(torque[axis]) == w[axis], f"axis {'xyz'[axis]}: torque {torque}"
            assert abs(torque[axis]) >= 0.171 - 1e-12  # at least one roll arm's worth
        else:
            assert abs(torque[axis]) < 1e-12, f"axis {'xyz'[axis]} disturbed: torque {torque}"


# --- detected failures: what "knows the failure" means for the table ----------------------------


@pytest.mark.parametrize("detected", [False, True])
def test_a_detected_failure_leaves_the_table_and_marks_the_thruster_known(detected):
    """failures.detected reaches the run's inputs: the thruster is marked failed either way, and
    known with its column of the run's allocation table zero only when detected; the plan's own
    (nominal) table is untouched (each run has its copy)."""
    campaign = copy.deepcopy(load_campaign(FAILURE_1_8))
    campaign["failures"]["detected"] = detected
    plan = RunPlan(campaign)
    _, failed, _, inputs = plan.prepare(0)
    assert failed.thrusters == (1, 8)
    assert inputs.thrusters[:, L.T_FAILED].tolist() == [1, 0, 0, 0, 0, 0, 0, 1]
    known = [1, 0, 0, 0, 0, 0, 0, 1] if detected else [0] * 8
    assert inputs.thrusters[:, L.T_FAILURE_KNOWN].tolist() == known
    table = derived.allocation_table(campaign["vehicle"])
    assert np.array_equal(plan.nominal_inputs.allocation, table)
    if detected:
        table[:, [0, 7]] = 0
    assert np.array_equal(inputs.allocation, table)


def test_a_detected_failure_changes_only_the_commands_to_the_dead_valves():
    """ReFEx's failure sweep (campaigns/failure-sweep.yaml: all 36 single and double sets, 000
    Table 4), undetected and detected. The table is not re-planned, so the detected flight opens
    the same working valves at the same times: every runs column of every set is bit-identical
    except the pulse counts of the failed thrusters, which are 0 detected (the undetected software
    kept commanding valves that never open). 000 Table 4's verdicts therefore hold detected too."""
    campaign = load_campaign(FAILURE_SWEEP)
    told = copy.deepcopy(campaign)
    told["failures"]["detected"] = True
    undetected, _ = fly_chunk(campaign, range(campaign["runs"]))
    detected, _ = fly_chunk(told, range(told["runs"]))

    def same(a, b):
        return a == b or (isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b))

    commanded = 0
    for before, after in zip(undetected, detected, strict=True):
        failed = [f"pulses_{t}" for t in before["failed_thrusters"].split(",") if t]
        differing = {k for k in before if not same(before[k], after[k])}
        assert differing <= set(failed), (before["failed_thrusters"], differing)
        assert all(after[k] == 0 for k in failed)
        commanded += sum(before[k] for k in failed)
    assert len(detected) == 37 and commanded > 0  # undetected, the dead valves were commanded
