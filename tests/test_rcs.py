"""Reaction control system (refexmc/core/rcs.py) against the naive valve profile.

The kernels are stepped the way refexmc/core/flight.py steps them: commands at control times,
then the period is integrated in segments that end on ``next_breakpoint``. Impulses are sums of
exact trapezoids on both sides, so they agree to rounding: ``REL = 1e-12``.
"""

import copy
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from naive import ValveTimes, level, thrust_impulse, valve_knots

from refexmc.config.load import load_vehicle
from refexmc.config.pack import pack_levels, pack_thrusters, pack_vehicle
from refexmc.core import layout, rcs

REL = 1e-12  # both sides are exact piecewise-linear integrals; only rounding separates them
DT = 0.025  # control period, 000 sec. 5 (40 Hz)
DERATING = (1.00, 0.91, 0.73, 0.65)  # 000 sec. 2.1
# 000 Table 2, mean time constants in s, its fall included (the vehicle file's fall is 45 ms,
# 000 sec. 2.1): tests set them on the thrusters explicitly (set_times), the longer falls make
# more interrupted transients
LEVEL_LOW, LEVEL_HIGH = 0, 1  # rows of configs/vehicles/refex.yaml's thrust levels (low, high)
TABLE_2 = {
    LEVEL_LOW: ValveTimes(0.0191, 0.0045, 0.0516, 0.1457),
    LEVEL_HIGH: ValveTimes(0.0256, 0.0053, 0.0530, 0.1390),
}
# nominal thrust of each level (N), the value segment_thrust takes
THRUST = pack_levels(load_vehicle(Path(__file__).resolve().parents[1] / "configs/vehicles/refex.yaml"))[
    :, layout.LV_THRUST
]


def set_times(thrusters, thrust_level, times, rows=None):
    """Overwrite the valve time constants of ``rows`` (all by default) at one thrust level."""
    out = thrusters.copy()
    col = layout.time_constant_column(thrust_level, layout.ON_DELAY)
    rows = range(out.shape[0]) if rows is None else rows
    for i in rows:
        out[i, col : col + 4] = [times.on_delay, times.rise, times.off_delay, times.fall]
    return out


def fly_valves(thrusters, vehicle, commands, t_end, thrust_level, dt=DT):
    """Drive the RCS kernels like the run loop: ``commands`` maps a step to [(thruster, open)].

    Returns impulse (N s), angular impulse (N m s), the segment boundaries and the valve state.
    """
    n = thrusters.shape[0]
    valve_state = np.zeros((n, rcs.VALVE_STATE_SIZE))
    rcs.reset(valve_state)
    arms = np.empty((n, 3))
    rcs.torque_arms(thrusters, vehicle, arms)
    tau0, tau1 = np.empty(3), np.empty(3)
    impulse, angular, boundaries = 0.0, np.zeros(3), [0.0]
    for step in range(int(round(t_end / dt))):
        t = step * dt
        for i, is_open in commands.get(step, ()):
            rcs.command(valve_state, thrusters, i, is_open, t, thrust_level)
        t_seg = t
        while t_seg < t + dt - 1e-12:
            for i in range(n):
                rcs.apply_reactions(valve_state, thrusters, i, t_seg, thrust_level)
            t_next = rcs.next_breakpoint(valve_state, n, t_seg, t + dt)
            impulse += rcs.segment_thrust(
                valve_state, thrusters, vehicle, arms, THRUST[thrust_level], t_seg, t_next, tau0, tau1
            )
            angular += 0.5 * (tau0 + tau1) * (t_next - t_seg)
            boundaries.append(t_next)
            t_seg = t_next
    return impulse, angular, np.array(boundaries), valve_state


def naive_commands(commands, thruster, dt=DT):
    return [(step * dt, is_open) for step, cmds in sorted(commands.items()) for i, is_open in cmds if i == thruster]


@pytest.fixture(scope="module")
def vehicle(inputs):
    return inputs.vehicle


@pytest.fixture(scope="module")
def thrusters(inputs):
    return inputs.thrusters


def nominal_thrust(vehicle, thrust_level):
    return THRUST[thrust_level]


def arms_of(thrusters, vehicle):
    arms = np.empty((thrusters.shape[0], 3))
    rcs.torque_arms(thrusters, vehicle, arms)
    return arms


# --- one valve: analytic impulse --------------------------------------------------------------


@pytest.mark.parametrize("thrust_level", [LEVEL_LOW, LEVEL_HIGH])
@pytest.mark.parametrize("close_step", [1, 4, 9])
def test_single_pulse_impulse_is_analytic(vehicle, thrusters, thrust_level, close_step):
    """Open at 0, close at t1 (000 Fig. 6): full thrust from lambda_on + delta_r / 2 to
    t1 + lambda_off + delta_f / 2 in area, so impulse = F (t1 + lambda_off + delta_f/2 - lambda_on - delta_r/2).

    Valid while the close reaction comes after the rise: t1 + lambda_off > lambda_on + delta_r.
    """
    c = TABLE_2[thrust_level]
    t1 = close_step * DT
    commands = {0: [(6, True)], close_step: [(6, False)]}
    thrusters = set_times(thrusters, thrust_level, c)
    impulse, angular, _, _ = fly_valves(thrusters, vehicle, commands, 0.5, thrust_level)
    force = nominal_thrust(vehicle, thrust_level)
    expected = force * (t1 + c.off_delay + 0.5 * c.fall - c.on_delay - 0.5 * c.rise)
    assert impulse == pytest.approx(expected, rel=REL)
    # thruster 7 pushes +z at x = -1.05 m: pitch arm +1.05 m, nothing on roll or yaw
    np.testing.assert_allclose(angular, [0.0, 1.05 * expected, 0.0], rtol=REL, atol=1e-15)


# --- sequences with transients interrupted: kernels against the naive profile ------------------

LOW = LEVEL_LOW
SLOW_RISE = ValveTimes(on_delay=0.0191, rise=0.060, off_delay=0.010, fall=0.1457)  # synthetic

SEQUENCES = {
    # name: (times, {step: [(thruster, open)]}, duration)
    "min pulse (25 ms command)": (TABLE_2[LOW], {0: [(0, True)], 1: [(0, False)]}, 0.4),
    # close at 100 ms falls from 151.6 ms; the open at 200 ms reacts at 219.1 ms mid-fall (level 0.54)
    "open during the fall": (TABLE_2[LOW], {0: [(0, True)], 4: [(0, False)], 8: [(0, True)], 12: [(0, False)]}, 0.7),
    # Table 2's off delay outlasts the rise, so a close can only react mid-rise with a slower
    # valve: open at 0 rises from 19.1 ms over 60 ms; the close at 25 ms reacts at 35 ms (0.265)
    "close during the rise": (SLOW_RISE, {0: [(0, True)], 1: [(0, False)]}, 0.4),
    # open at 125 ms reacts (144.1 ms) before the pending close of 100 ms (151.6 ms): it wins
    "later open supersedes pending close": (
        TABLE_2[LOW],
        {0: [(0, True)], 4: [(0, False)], 5: [(0, True)], 12: [(0, False)]},
        0.7,
    ),
    "high thrust pulse train": (
        TABLE_2[LEVEL_HIGH],
        {0: [(0, True)], 3: [(0, False)], 11: [(0, True)], 14: [(0, False)]},
        0.7,
    ),
}


@pytest.mark.parametrize("name", SEQUENCES)
def test_command_sequence_matches_naive_profile(vehicle, thrusters, name):
    times, commands, duration = SEQUENCES[name]
    thrust_level = LEVEL_HIGH if times == TABLE_2[LEVEL_HIGH] else LOW
    thr = set_times(thrusters, thrust_level, times)
    impulse, angular, boundaries, _ = fly_valves(thr, vehicle, commands, duration, thrust_level)
    knots = valve_knots(naive_commands(commands, 0), times)
    expected, expected_angular = thrust_impulse(
        [knots], nominal_thrust(vehicle, thrust_level), DERATING, 0.0, duration, arms_of(thr, vehicle)[:1]
    )
    assert impulse == pytest.approx(expected, rel=REL)
    np.testing.assert_allclose(angular, expected_angular, rtol=REL, atol=1e-15)
    # every kink of the profile is a segment boundary, so each RK4 step sees a linear torque
    for t_knot, _ in knots:
        if t_knot < duration:
            assert np.abs(boundaries - t_knot).min() < 1e-12, f"kink at {t_knot} s is not a segment end"


def test_open_during_fall_restarts_from_current_level(thrusters):
    """000 sec. 5 / reference model: a new command mid-transient starts from the current level."""
    times = SEQUENCES["open during the fall"][0]
    thr = set_times(thrusters, LOW, times)
    # open at 0, close at 100 ms, open at 200 ms; stop at the last reaction to read the level
    valve_state = np.zeros((8, rcs.VALVE_STATE_SIZE))
    for t, is_open in [(0.0, True), (0.1, False), (0.2, True)]:
        rcs.apply_reactions(valve_state, thr, 0, t, LOW)
        rcs.command(valve_state, thr, 0, is_open, t, LOW)
    t_react = 0.2 + times.on_delay
    rcs.apply_reactions(valve_state, thr, 0, t_react, LOW)
    level_before = 1.0 - (t_react - 0.1 - times.off_delay) / times.fall  # on the fall, 0.537
    assert rcs.level_at(valve_state, 0, t_react) == pytest.approx(level_before, rel=1e-12)
    # then it rises at the full-swing slope 1/delta_r and reaches 1 after (1 - L) delta_r
    t_full = t_react + (1.0 - level_before) * times.rise
    assert rcs.level_at(valve_state, 0, t_full - 1e-4) == pytest.approx(1.0 - 1e-4 / times.rise, rel=1e-9)
    assert rcs.next_breakpoint(valve_state, 8, t_react, 1.0) == pytest.approx(t_full, abs=1e-12)
    assert rcs.level_at(valve_state, 0, t_full + 0.05) == 1.0


# random command streams on all eight thrusters, with derating during overlapping transients
streams = st.lists(
    st.lists(st.booleans(), min_size=24, max_size=24),  # per step: does this thruster toggle?
    min_size=8,
    max_size=8,
)


@settings(deadline=None, max_examples=40)
@given(streams, st.sampled_from([LEVEL_LOW, LEVEL_HIGH]))
def test_random_command_streams_match_naive(inputs, toggles, thrust_level):
    vehicle = inputs.vehicle
    thrusters = set_times(inputs.thrusters, thrust_level, TABLE_2[thrust_level])
    commands = {}
    for i, row in enumerate(toggles):
        is_open = False
        for step, toggle in enumerate(row):
            if toggle:
                is_open = not is_open
                commands.setdefault(step, []).append((i, is_open))
    duration = 24 * DT + 0.25  # let the last falls finish
    impulse, angular, _, _ = fly_valves(thrusters, vehicle, commands, duration, thrust_level)
    knots = [valve_knots(naive_commands(commands, i), TABLE_2[thrust_level]) for i in range(8)]
    expected, expected_angular = thrust_impulse(
        knots, nominal_thrust(vehicle, thrust_level), DERATING, 0.0, duration, arms_of(thrusters, vehicle)
    )
    assert impulse == pytest.approx(expected, rel=1e-11, abs=1e-14)
    np.testing.assert_allclose(angular, expected_angular, rtol=1e-11, atol=1e-12)


@settings(deadline=None, max_examples=40)
@given(streams, st.sampled_from([LEVEL_LOW, LEVEL_HIGH]), st.sets(st.integers(0, 7), max_size=2))
def test_update_settles_ramps_and_skips_idle_valves_without_changing_a_bit(
    vehicle_config, inputs, toggles, thrust_level, failed
):
    """rcs.update (settled ramps, bit mask of active thrusters), as the run loop uses it, gives
    exactly the segments, torques and impulses of applying every reaction and looking at every
    thruster; with the mask at 0 the segment is the thrust-free coasting segment."""
    vehicle = inputs.vehicle
    thrusters = pack_thrusters(vehicle_config, failed=tuple(i + 1 for i in failed))
    n = thrusters.shape[0]
    plain, masked = np.zeros((n, rcs.VALVE_STATE_SIZE)), np.zeros((n, rcs.VALVE_STATE_SIZE))
    arms = arms_of(thrusters, vehicle)
    tau = np.empty((4, 3))
    active = 0
    is_open = [False] * n
    for step in range(24 + 12):  # then let the last falls finish and settle
        t = step * DT
        for i in range(n):
            if (step < 24 and toggles[i][step]) or (step == 24 and is_open[i]):  # all closed at 24
                is_open[i] = not is_open[i]
                rcs.command(plain, thrusters, i, is_open[i], t, thrust_level)
                rcs.command(masked, thrusters, i, is_open[i], t, thrust_level)
                active |= 1 << i
        t_seg = t
        while t_seg < t + DT - 1e-12:
            for i in range(n):
                rcs.apply_reactions(plain, thrusters, i, t_seg, thrust_level)
            t_next = rcs.next_breakpoint(plain, n, t_seg, t + DT)
            impulse = rcs.segment_thrust(
                plain, thrusters, vehicle, arms, THRUST[thrust_level], t_seg, t_next, tau[0], tau[1]
            )
            active = rcs.update(masked, thrusters, n, t_seg, thrust_level, active)
            if active:
                assert rcs.next_breakpoint(masked, n, t_seg, t + DT, active) == t_next
                assert (
                    rcs.segment_thrust(
                        masked, thrusters, vehicle, arms, THRUST[thrust_level], t_seg, t_next, tau[2], tau[3], active
                    )
                    == impulse
                )
                assert np.array_equal(tau[0:2], tau[2:4])
            else:  # coasting: the run loop integrates to the period's end without thrust
                assert t_next == t + DT and impulse == 0.0 and not tau[0:2].any()
            for i in range(n):
                assert rcs.level_at(masked, i, t_seg) == rcs.level_at(plain, i, t_seg)
                assert rcs.level_at(masked, i, t_next) == rcs.level_at(plain, i, t_next)
                if not (active >> i) & 1:
                    assert rcs.level_at(masked, i, t_seg) == 0.0 and masked[i, rcs.VS_PENDING_COUNT] == 0
            t_seg = t_next
    assert active == 0, "every valve closed and settled 300 ms after the last command"


def test_set_bits_of_a_thruster_mask_are_visited_in_order():
    """The run loop's idiom over a thruster mask (refexmc/core/bits.py), jitted like the core."""
    from refexmc._jit import jit_noalloc
    from refexmc.core.bits import lowest_bit

    @jit_noalloc
    def visit(mask, out):
        n = 0
        m = mask
        while m != 0:
            out[n] = lowest_bit(m)
            m &= m - 1
            n += 1
        return n

    out = np.empty(64, dtype=np.int64)
    for mask in [*range(256), 1 << 62, (1 << 63) - 1]:
        expected = [i for i in range(64) if (mask >> i) & 1]
        n = visit(mask, out)
        assert list(out[:n]) == expected, f"mask {mask:#x}"


# --- derating, failures, torque arms, propellant ----------------------------------------------

IDEAL = ValveTimes(0.0, 0.0, 0.0, 0.0)


@pytest.mark.parametrize("n_open", range(1, 9))
@pytest.mark.parametrize("thrust_level", [LEVEL_LOW, LEVEL_HIGH])
def test_derating_by_number_of_open_valves(vehicle, thrusters, n_open, thrust_level):
    """Thrust per thruster F * derating[n]: 1.00 / 0.91 / 0.73 / 0.65, and 0.65 beyond four."""
    thr = set_times(thrusters, thrust_level, IDEAL)
    commands = {0: [(i, True) for i in range(n_open)]}
    impulse, _, _, _ = fly_valves(thr, vehicle, commands, DT, thrust_level)
    factor = DERATING[min(n_open, 4) - 1]
    assert impulse == pytest.approx(n_open * nominal_thrust(vehicle, thrust_level) * factor * DT, rel=REL)
    assert rcs.derating_factor(vehicle, n_open) == factor
    assert rcs.derating_factor(vehicle, 0) == 1.0


def test_each_thruster_scales_its_thrust_and_torque(vehicle, thrusters):
    """Thrust scales 0.8, 1.25 and 0.9 (a dispersed or mixed set) on three ideal valves open for
    one period: impulse F 0.73 (0.8 + 1.25 + 0.9) dt and angular impulse F 0.73 dt times the sum
    of s_i r_i x d_i (000 sec. 2.1's derating for three open; the shipped vehicles all have
    scale 1, where a scale that divides passes)."""
    thr = set_times(thrusters, LOW, IDEAL)
    scales = {0: 0.8, 1: 1.25, 6: 0.9}
    for i, scale in scales.items():
        thr[i, layout.T_SCALE] = scale
    commands = {0: [(i, True) for i in scales]}
    impulse, angular, _, _ = fly_valves(thr, vehicle, commands, DT, LOW)
    force = nominal_thrust(vehicle, LOW) * 0.73
    assert impulse == pytest.approx(force * sum(scales.values()) * DT, rel=REL)
    arms = arms_of(thr, vehicle)
    expected = force * DT * sum(scale * arms[i] for i, scale in scales.items())
    np.testing.assert_allclose(angular, expected, rtol=REL, atol=1e-15)


def test_open_mask_is_the_thrusters_with_thrust_at_each_instant(thrusters):
    """rcs.open_mask (what the history records as open valves) against the naive valve profile
    (Table 2 delays and ramps): thrusters 2 and 7 opened at 0 and closed at 0.1 s, thruster 3
    opened at 0.05 s; bit i-1 is set exactly while thruster i's level is above zero (not before
    the on-delay, not after the fall, never for a thruster not commanded)."""
    times = TABLE_2[LOW]
    thr = set_times(thrusters, LOW, times)
    n = thr.shape[0]
    commands = {0: [(1, True), (6, True)], 10: [(2, True)], 20: [(1, False), (6, False)]}  # steps of 5 ms
    knots = {i: valve_knots(naive_commands(commands, i, dt=0.005), times) for i in (1, 2, 6)}
    valve_state = np.zeros((n, rcs.VALVE_STATE_SIZE))
    rcs.reset(valve_state)
    for step in range(80):  # the ramps after the closes end before 0.4 s
        t = step * 0.005
        for i, is_open in commands.get(step, ()):
            rcs.command(valve_state, thr, i, is_open, t, LOW)
        for i in range(n):
            rcs.apply_reactions(valve_state, thr, i, t, LOW)
        expected = sum(1 << i for i, k in knots.items() if level(k, t) > 0.0)
        assert rcs.open_mask(valve_state, n, t) == expected, f"at {t} s"


def test_derating_with_table_2_transients(vehicle, thrusters):
    """Steady state with Table 2 valves: three open give 3 x 0.73 F after the rise."""
    commands = {0: [(0, True), (1, True), (6, True)]}
    impulse_a, _, _, _ = fly_valves(thrusters, vehicle, commands, 0.2, LOW)
    impulse_b, _, _, _ = fly_valves(thrusters, vehicle, commands, 0.3, LOW)
    assert impulse_b - impulse_a == pytest.approx(3 * 0.73 * nominal_thrust(vehicle, LOW) * 0.1, rel=1e-10)


def test_failed_thrusters_never_open_and_use_no_propellant(vehicle_config, inputs):
    thrusters = pack_thrusters(vehicle_config, failed=(2, 5))
    vehicle = inputs.vehicle
    commands = {0: [(i, True) for i in range(8)], 4: [(i, False) for i in range(8)]}
    impulse, angular, _, valve_state = fly_valves(thrusters, vehicle, commands, 0.5, LOW)
    for failed in (1, 4):  # 0-based rows of thrusters 2 and 5
        assert valve_state[failed, rcs.VS_PENDING_COUNT] == 0 and valve_state[failed, rcs.VS_LEVEL] == 0.0
    # the same as commanding only the six working thrusters (derating counts six open valves)
    working = [i for i in range(8) if i not in (1, 4)]
    reference = {0: [(i, True) for i in working], 4: [(i, False) for i in working]}
    impulse_ref, angular_ref, _, _ = fly_valves(inputs.thrusters, vehicle, reference, 0.5, LOW)
    assert impulse == pytest.approx(impulse_ref, rel=REL)
    np.testing.assert_allclose(angular, angular_ref, rtol=REL, atol=1e-15)
    # and the open mask never shows them
    valve_state = np.zeros((8, rcs.VALVE_STATE_SIZE))
    for i in range(8):
        rcs.command(valve_state, thrusters, i, True, 0.0, LOW)
        rcs.apply_reactions(valve_state, thrusters, i, 0.1, LOW)
    assert rcs.open_mask(valve_state, 8, 0.1) == 0b11111111 & ~0b10010
    # commanding only failed thrusters: no thrust, no torque, no propellant
    only_failed = {0: [(1, True), (4, True)], 4: [(1, False), (4, False)]}
    impulse, angular, _, _ = fly_valves(thrusters, vehicle, only_failed, 0.5, LOW)
    assert impulse == 0.0 and not angular.any()
    assert rcs.propellant_for_impulse(vehicle, impulse) == 0.0


# 000 Table 3 / reference-model sec. 2: sign of (roll, pitch, yaw) torque of each thruster
SIGN_TABLE = {
    1: (-1, +1, 0),
    2: (+1, +1, 0),
    3: (+1, -1, 0),
    4: (-1, -1, 0),
    5: (0, 0, -1),
    6: (0, 0, +1),
    7: (0, +1, 0),
    8: (0, -1, 0),
}


def test_torque_arms_are_r_cross_f_with_reference_signs(vehicle_config, inputs):
    arms = arms_of(inputs.thrusters, inputs.vehicle)
    r = np.array([t["position_m"] for t in vehicle_config["rcs"]["thrusters"]], float)
    d = np.array([t["direction"] for t in vehicle_config["rcs"]["thrusters"]], float)
    np.testing.assert_allclose(arms, np.cross(r, d / np.linalg.norm(d, axis=1, keepdims=True)), atol=1e-15)
    for tid, signs in SIGN_TABLE.items():
        np.testing.assert_array_equal(np.sign(np.round(arms[tid - 1], 12)), signs, err_msg=f"thruster {tid}")
    np.testing.assert_allclose(arms[1], [0.171, 1.05, 0.0], atol=1e-15)  # reference-model check line


def test_torque_arms_about_a_shifted_centre_of_mass(vehicle_config):
    shifted = copy.deepcopy(vehicle_config)
    shifted["com_offset_m"] = [0.02, -0.01, 0.03]
    vehicle = pack_vehicle(shifted)
    thrusters = pack_thrusters(shifted)
    arms = arms_of(thrusters, vehicle)
    r = thrusters[:, layout.T_POSITION : layout.T_POSITION + 3] - np.array([0.02, -0.01, 0.03])
    d = thrusters[:, layout.T_DIRECTION : layout.T_DIRECTION + 3]
    np.testing.assert_allclose(arms, np.cross(r, d), atol=1e-15)


def test_propellant_is_impulse_over_isp_g0(vehicle):
    isp = vehicle[layout.V_ISP]
    assert isp == 70.0
    assert rcs.propellant_for_impulse(vehicle, 10.0) == pytest.approx(10.0 / (70.0 * 9.80665), rel=1e-15)
    assert rcs.STANDARD_GRAVITY == 9.80665  # defines Isp in seconds


def test_idle_valves_have_no_breakpoints_and_no_thrust(vehicle, thrusters):
    valve_state = np.zeros((8, rcs.VALVE_STATE_SIZE))
    assert rcs.next_breakpoint(valve_state, 8, 0.0, 0.025) == 0.025
    tau0, tau1 = np.ones(3), np.ones(3)
    assert (
        rcs.segment_thrust(
            valve_state, thrusters, vehicle, arms_of(thrusters, vehicle), THRUST[LOW], 0.0, 0.025, tau0, tau1
        )
        == 0.0
    )
    assert not tau0.any() and not tau1.any()


def test_naive_profile_sanity():
    """The twin itself: a 100 ms command gives the Fig. 6 trapezoid."""
    c = TABLE_2[LOW]
    knots = valve_knots([(0.0, True), (0.1, False)], c)
    expected = [
        (c.on_delay, 0.0),
        (c.on_delay + c.rise, 1.0),
        (0.1 + c.off_delay, 1.0),
        (0.1 + c.off_delay + c.fall, 0.0),
    ]
    np.testing.assert_allclose(knots, expected, atol=1e-15)
    assert level(knots, 0.01) == 0.0 and level(knots, 0.05) == 1.0
