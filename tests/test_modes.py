"""The mode program (core.modes): exit conditions, packing, and ReFEx's seven modes.

Exit conditions are checked against the slow twin ``naive.exit_holds``, which reads them straight
from the mission file in its units; the kernel sees them packed in SI units, grouped and sorted.
``NUDGE`` is a relative step far above float64 rounding (1e-16) and far below any margin.
"""

import itertools
import math

import naive
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from refexmc.config.pack import mode_names, pack_modes, target_quaternion
from refexmc.core import layout as L
from refexmc.core import modes, quaternion

NUDGE = 1e-9  # relative; see module docstring


def below(x):
    return x * (1 - NUDGE) if x > 0 else x - NUDGE


def above(x):
    return x * (1 + NUDGE) if x > 0 else x + NUDGE


def _kernel_exit(table, exits, m, time_in_mode, t1, rates_deg_s, rate_error_deg_s, angle_deg, altitude, climb, qbar):
    """core.modes.exit_reached on states built to have the given errors (deg, deg/s)."""
    now = np.zeros(modes.NOW_SIZE)
    now[modes.NOW_TIME_IN_MODE] = time_in_mode
    now[modes.NOW_ALTITUDE] = altitude
    now[modes.NOW_CLIMB] = climb
    now[modes.NOW_QBAR] = qbar
    rate_meas = np.radians(np.asarray(rates_deg_s, dtype=float))
    rate_ref = rate_meas.copy()
    rate_ref[0] -= math.radians(rate_error_deg_s)  # |meas - ref| = the rate error
    q_target = np.array([0.0, 0.0, 0.0, 1.0])
    q_meas = Rotation.from_rotvec([0.0, 0.0, math.radians(angle_deg)]).as_quat()
    return modes.exit_reached(table[m], exits, now, t1, rate_meas, rate_ref, q_meas, q_target)


def test_refex_mission_is_seven_modes_in_the_order_of_000(mission_config):
    """000 sec. 2.2: NCM -> RDM1 -> SAM -> SSM -> RDM2 -> EAM -> GEEM."""
    assert mode_names(mission_config) == ["NCM", "RDM1", "SAM", "SSM", "RDM2", "EAM", "GEEM"]


def test_thrust_level_per_mode(mission_config):
    """Low thrust for precision NCM..RDM2, high thrust in EAM and GEEM (000 sec. 2.2)."""
    table, _ = pack_modes(mission_config)
    high = {"EAM", "GEEM"}
    for name, row in zip(mode_names(mission_config), table, strict=True):
        assert row[L.MD_LEVEL] == (1 if name in high else 0), name  # rows of refex.yaml's levels: low, high


def test_packed_thresholds_are_the_configured_ones_in_si(mission_config):
    table, exits = pack_modes(mission_config)
    for m, mode in enumerate(mission_config["modes"]):
        first, count = int(table[m, L.MD_EXIT_FIRST]), int(table[m, L.MD_EXIT_ROWS])
        rows = exits[first : first + count]
        assert count == sum(len(group) for group in mode["exit"])
        by_id = {v: k for k, v in modes.PREDICATES.items()}
        for row in rows:
            group = mode["exit"][int(row[L.E_GROUP])]
            name = by_id[int(row[L.E_PREDICATE])]
            configured = group[name]
            expected = math.radians(configured) if name.endswith(("_deg", "_deg_s")) else float(configured)
            assert row[L.E_VALUE] == pytest.approx(expected, rel=1e-15), (mode["name"], name)
        assert np.all(np.diff(rows[:, L.E_GROUP]) >= 0), "a group's rows are contiguous"


def test_cheap_predicates_come_first_within_a_group(mission_config):
    """SAM tests its rate error before its angle error (an acos), as ReFEx's loop always did."""
    table, exits = pack_modes(mission_config)
    sam = mode_names(mission_config).index("SAM")
    first = int(table[sam, L.MD_EXIT_FIRST])
    ids = exits[first : first + 2, L.E_PREDICATE].tolist()
    assert ids == [modes.PREDICATE_RATE_ERROR_BELOW, modes.PREDICATE_ANGLE_ERROR_BELOW]


def test_each_predicate_switches_exactly_at_its_threshold(mission_config):
    """Every ReFEx exit predicate just either side of its threshold, with the others satisfied."""
    table, exits = pack_modes(mission_config)
    names = mode_names(mission_config)
    ok = dict(time_in_mode=1e6, t1=0.0, rates=[0.0, 0.0, 0.0], rate_error=0.0, angle=0.0, altitude=0.0, climb=-1.0)
    cases = {
        "NCM": [("time_in_mode", 5.0, "ge")],
        "RDM1": [("rates", 0.3, "lt")],
        "SAM": [("angle", 1.0, "lt"), ("rate_error", 0.1, "lt")],
        "SSM": [("altitude", 110000.0, "lt"), ("climb", 0.0, "lt")],
        "RDM2": [("time_in_mode", 8.0, "ge")],
        "EAM": [("altitude", 70000.0, "lt")],
    }
    for name, checks in cases.items():
        m = names.index(name)
        for key, threshold, op in checks:
            cases_at = [(below(threshold), op == "lt"), (threshold, op == "ge"), (above(threshold), op == "ge")]
            if key in ("angle", "rate_error"):  # rebuilt through rotations: 1e-7 relative, no equality case
                cases_at = [(threshold * (1 - 1e-7), True), (threshold * (1 + 1e-7), False)]
            for value, expected in cases_at:
                state = dict(ok, qbar=0.0)
                if key == "rates":
                    state["rates"] = [0.0, -value, 0.0]  # any axis, either sign
                else:
                    state[key] = value
                got = _kernel_exit(
                    table,
                    exits,
                    m,
                    state["time_in_mode"],
                    state["t1"],
                    state["rates"],
                    state["rate_error"],
                    state["angle"],
                    state["altitude"],
                    state["climb"],
                    state["qbar"],
                )
                assert got == expected, (name, key, value)


def test_rate_damping_needs_its_profile_finished(mission_config):
    table, exits = pack_modes(mission_config)
    m = mode_names(mission_config).index("RDM1")
    t1 = 12.0
    args = ([0.0, 0.0, 0.0], 0.0, 0.0, 0.0, -1.0, 0.0)
    assert _kernel_exit(table, exits, m, above(t1), t1, *args)
    assert not _kernel_exit(table, exits, m, t1, t1, *args), "t > t1 is required"


def test_geem_hands_over_at_qbar_or_floor_altitude(mission_config):
    """GEEM's two exit groups: q-bar >= 1 kPa OR below 50 km (an OR of groups)."""
    table, exits = pack_modes(mission_config)
    m = mode_names(mission_config).index("GEEM")
    args = dict(time_in_mode=1.0, t1=0.0, rates_deg_s=[0, 0, 0], rate_error_deg_s=0.0, angle_deg=0.0, climb=-1.0)
    assert _kernel_exit(table, exits, m, altitude=above(50000.0), qbar=1000.0, **args)
    assert not _kernel_exit(table, exits, m, altitude=above(50000.0), qbar=below(1000.0), **args)
    assert _kernel_exit(table, exits, m, altitude=below(50000.0), qbar=below(1000.0), **args)
    assert not _kernel_exit(table, exits, m, altitude=50000.0, qbar=below(1000.0), **args)


@settings(max_examples=300, deadline=None)
@given(
    m=st.integers(0, 6),
    time_in_mode=st.floats(0.0, 200.0),
    t1=st.floats(0.0, 100.0),
    rates=st.lists(st.floats(-1.0, 1.0), min_size=3, max_size=3),
    rate_error=st.floats(0.0, 0.3),
    angle=st.floats(0.0, 3.0),
    altitude=st.floats(30000.0, 150000.0),
    climb=st.floats(-100.0, 100.0),
    qbar=st.floats(0.0, 3000.0),
)
def test_exit_conditions_equal_the_mission_file_read_naively(
    mission_config, m, time_in_mode, t1, rates, rate_error, angle, altitude, climb, qbar
):
    """Packing (units, groups, order) and the kernel agree with the file's words (naive twin).

    The angle and rate errors are rebuilt from rotations and vectors, so values within 1e-9 of a
    threshold could round either way; those draws are skipped."""
    mode = mission_config["modes"][m]
    for group in mode["exit"]:
        for name, v in group.items():
            if isinstance(v, bool):
                continue
            value = {"angle_error_below_deg": angle, "rate_error_below_deg_s": rate_error}.get(name)
            if value is not None and abs(value - v) < 1e-9:
                return
    table, exits = pack_modes(mission_config)
    expected = naive.exit_holds(mode, time_in_mode, t1, rates, rate_error, angle, altitude, climb, qbar)
    got = _kernel_exit(table, exits, m, time_in_mode, t1, rates, rate_error, angle, altitude, climb, qbar)
    assert got == expected


def test_inertial_targets_from_euler_angles_equal_scipy():
    """An inertial target given as Euler angles is scipy's quaternion (scalar last)."""
    target = {"type": "inertial", "euler_deg": [60.0, -20.0, 5.0], "sequence": "ZYX"}
    q = target_quaternion(target)
    expected = Rotation.from_euler("ZYX", [60.0, -20.0, 5.0], degrees=True).as_quat()
    assert np.allclose(q, expected, atol=1e-15)
    q2 = target_quaternion({"type": "inertial", "quaternion": [0.0, 0.0, 2.0, 2.0]})
    assert np.allclose(q2, [0.0, 0.0, math.sqrt(0.5), math.sqrt(0.5)], atol=1e-15)
    assert quaternion.angle_between(q, expected) < 1e-7


EULER_SEQUENCES = ["".join(p) for p in itertools.product("xyz", repeat=3) if p[0] != p[1] and p[1] != p[2]]


@settings(max_examples=60, deadline=None)
@given(
    sequence=st.sampled_from(EULER_SEQUENCES + [s.upper() for s in EULER_SEQUENCES]),
    angles=st.lists(st.floats(-360.0, 360.0), min_size=3, max_size=3),
)
def test_euler_angles_give_scipys_quaternion_and_rotation_vector_without_libm(sequence, angles):
    """refexmc composes Euler angles itself (correctly rounded sin/cos/atan2: the same bits on
    every CPU) in scipy's order: each of the 12 sequences, extrinsic and intrinsic, gives scipy's
    quaternion, same sign, within 2 ulp of 1 (one rounding of each sin/cos differs from libm's by
    at most an ulp, and a product of three rounds three times), and its rotation vector within
    4 ulp of pi (the atan2 and the scale, rounded twice more)."""
    from refexmc.config import derived

    q = derived.euler_quaternion(sequence, angles)
    expected = Rotation.from_euler(sequence, angles, degrees=True)
    assert np.max(np.abs(q - expected.as_quat())) <= 2 * np.spacing(1.0)
    assert np.max(np.abs(derived.rotation_vector(q) - expected.as_rotvec())) <= 4 * np.spacing(math.pi)


def test_only_the_profiled_kinds_report_a_transition_time():
    """has_profile (the kinds whose guidance has a transition time t1, reported per mode): rate
    damping's cubic (000 eq. 15-19), the slew's quintic (eq. 4-14), the spin-up's quartic
    (eq. 20-27) and the burn from ignition to cut-off; locked, hold, track and translate have
    none. Every kind the module declares is asked."""
    kinds = {name: value for name, value in vars(modes).items() if name.startswith("KIND_")}
    assert len(set(kinds.values())) == len(kinds) == 8
    profiled = {name for name, kind in kinds.items() if modes.has_profile(kind)}
    assert profiled == {"KIND_RATE_DAMPING", "KIND_SLEW", "KIND_SPIN_UP", "KIND_BURN"}


@pytest.mark.parametrize("has_final", [False, True])
def test_target_attitude_inertial_previous_and_none(has_final):
    """modes.target_attitude without a trajectory: an inertial target is the mode's quaternion;
    the previous target (or none) keeps q_final when a previous mode set one, else holds the
    measured attitude. Exact copies: nothing is computed."""
    q_meas = Rotation.from_rotvec([0.1, -0.2, 0.3]).as_quat()
    q_mode = Rotation.from_rotvec([-0.4, 0.5, 0.05]).as_quat()
    q_previous = Rotation.from_rotvec([0.7, 0.0, -0.1]).as_quat()
    mission, traj, rotations = np.zeros(L.MISSION_SIZE), np.zeros(16), np.zeros((3, 4))  # not read here
    for target in (modes.TARGET_INERTIAL, modes.TARGET_PREVIOUS, modes.TARGET_NONE):
        mode = np.zeros(L.MODE_SIZE)
        mode[L.MD_TARGET] = target
        mode[L.MD_QUATERNION : L.MD_QUATERNION + 4] = q_mode
        q_final = np.append(q_previous.copy(), np.nan)  # a fifth slot that must stay untouched
        modes.target_attitude(mode, mission, traj, q_meas, q_final[:4], has_final, rotations, np.zeros((6, 4)))
        if target == modes.TARGET_INERTIAL:
            expected = q_mode
        else:
            expected = q_previous if has_final else q_meas
        np.testing.assert_array_equal(q_final[:4], expected)
        assert np.isnan(q_final[4])


def test_each_predicate_at_its_threshold_as_docs_missions_states():
    """modes.predicate_holds against docs/missions.md's table, at the threshold itself and on
    either side: "below" is strict, "at most" and "since t = 0 >= T" include it; every body
    axis counts on its own for rates_below, every axis of the rate error counts in the norm.
    Thresholds at the tie are the values the kernel computes (same operations, same bits)."""
    q_meas = Rotation.from_rotvec([0.1, -0.2, 0.3]).as_quat()
    q_target = Rotation.from_rotvec([0.15, -0.1, 0.25]).as_quat()
    zero3 = np.zeros(3)

    def holds(predicate, value, now=None, rate_meas=zero3, rate_ref=zero3):
        now = np.zeros(modes.NOW_SIZE) if now is None else now
        return bool(modes.predicate_holds(predicate, value, now, 0.0, rate_meas, rate_ref, q_meas, q_target))

    for axis in range(3):  # one axis at the threshold, the others well below: not below
        rates = np.full(3, 0.001)
        rates[axis] = -0.02
        assert not holds(modes.PREDICATE_RATES_BELOW, 0.02, rate_meas=rates)
        assert holds(modes.PREDICATE_RATES_BELOW, 0.0201, rate_meas=rates)
    rate_meas, rate_ref = np.array([0.01, 0.3, -0.02]), np.array([0.0, 0.0, 0.01])
    norm = math.sqrt((0.01 - 0.0) ** 2 + (0.3 - 0.0) ** 2 + (-0.02 - 0.01) ** 2)
    for value, expected in ((norm, False), (norm * (1 + 1e-12), True), (0.9 * norm, False)):
        assert holds(modes.PREDICATE_RATE_ERROR_BELOW, value, rate_meas=rate_meas, rate_ref=rate_ref) is expected
    angle = quaternion.angle_between(q_meas, q_target)
    assert not holds(modes.PREDICATE_ANGLE_ERROR_BELOW, angle)
    assert holds(modes.PREDICATE_ANGLE_ERROR_BELOW, angle * (1 + 1e-12))
    at_most = ((modes.PREDICATE_MISSION_TIME, modes.NOW_TIME, True), (modes.PREDICATE_POSITION_ERROR_BELOW,
               modes.NOW_POSITION_ERROR, False), (modes.PREDICATE_SPEED_BELOW, modes.NOW_SPEED, False))  # fmt: skip
    for predicate, slot, at_least in at_most:
        now = np.zeros(modes.NOW_SIZE)
        now[slot] = 2.5
        assert holds(predicate, 2.5, now)  # the threshold itself holds
        assert holds(predicate, 2.0, now) is at_least
        assert holds(predicate, 3.0, now) is not at_least
    assert not holds(99, 0.0)  # no such predicate: never holds
