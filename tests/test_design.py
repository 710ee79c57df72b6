"""Design quantities derived from the reference vehicle config (refexmc.config.derived)
against 000 eq. 1-3, eq. 34, eq. 38, eq. 44 and Table 1.

Published values are compared at their printed precision: |computed - published| <= half a
unit of the last printed digit (``half_unit``). Recomputations from the equations are compared
tightly (1e-12 relative: the same few float64 operations in another order).
"""

import copy
import math
from pathlib import Path

import numpy as np
import pytest
from naive import ValveTimes, thrust_impulse, valve_knots

from refexmc.config import derived
from refexmc.config.load import load_vehicle
from refexmc.config.pack import pack_fsw, pack_levels
from refexmc.core import layout as L

REFEX_LEVELS = ("low", "high")  # 000 sec. 2.1: the two thrust modes of configs/vehicles/refex.yaml

EQ_2_LOW = (0.037, 0.019, 0.009)  # rad/s^2, 000 eq. 2
EQ_3_HIGH = (0.152, 0.077, 0.038)  # rad/s^2, 000 eq. 3
TABLE_1 = {  # 000 Table 1, per body axis x, y, z
    "low": {"kp": (3.55, 1.79, 0.88), "kd": (3.77, 2.68, 1.88)},
    "high": {"kp": (14.69, 7.41, 3.65), "kd": (7.67, 5.45, 3.82)},
}
LEVER_ARMS = (0.171, 1.05, 1.05)  # m, reference-model sec. 2
TIGHT = 1e-12
CONFIGS = Path(__file__).resolve().parents[1] / "configs" / "vehicles"


def half_unit(printed):
    """Half a unit of the last digit of a value as printed in the paper (e.g. 0.037 -> 5e-4)."""
    decimals = len(repr(printed).split(".")[1]) if "." in repr(printed) else 0
    return 0.5 * 10.0**-decimals


def from_equations(vehicle, level):
    """omega_dot_max (eq. 1), Kp (eq. 38), Kd (eq. 34) recomputed here from the config."""
    rcs, fsw = vehicle["rcs"], vehicle["flight_software"]
    r = np.array([t["position_m"] for t in rcs["thrusters"]], float)
    d = np.array([t["direction"] for t in rcs["thrusters"]], float)
    arms = np.abs(np.cross(r, d / np.linalg.norm(d, axis=1, keepdims=True))).max(axis=0)
    j_diag = np.diag(np.array(vehicle["inertia_kg_m2"], float))
    accel = arms * np.array(fsw["thrusters_per_axis"], float) * rcs["thrust_n"][level] / j_diag
    phi_db = math.radians(fsw["deadband_angle_deg"])
    kp = np.abs(fsw["pwpf"]["tau_min_fraction"] * accel / math.sin(phi_db / 2))
    kd = 2.0 * fsw["damping_ratio"] * np.sqrt(kp)
    return arms, accel, kp, kd


@pytest.mark.parametrize(("level", "published"), [("low", EQ_2_LOW), ("high", EQ_3_HIGH)])
def test_omega_dot_max_reproduces_eq_2_3(vehicle_config, level, published):
    computed = derived.omega_dot_max(vehicle_config, level)
    for axis in range(3):
        assert abs(computed[axis] - published[axis]) <= half_unit(published[axis]), (
            f"{level} axis {'xyz'[axis]}: {computed[axis]:.5f} does not print as {published[axis]}"
        )
    np.testing.assert_allclose(computed, from_equations(vehicle_config, level)[1], rtol=TIGHT)


@pytest.mark.parametrize("level", ["low", "high"])
def test_gains_reproduce_table_1(vehicle_config, level):
    kp, kd = derived.gains(vehicle_config, level)
    for name, values in (("kp", kp), ("kd", kd)):
        for axis in range(3):
            published = TABLE_1[level][name][axis]
            assert abs(values[axis] - published) <= half_unit(published), (
                f"{level} {name} {'xyz'[axis]}: {values[axis]:.4f} does not print as {published} (000 Table 1)"
            )
    _, _, kp_eq, kd_eq = from_equations(vehicle_config, level)
    np.testing.assert_allclose(kp, kp_eq, rtol=TIGHT)
    np.testing.assert_allclose(kd, kd_eq, rtol=TIGHT)
    np.testing.assert_allclose(kd, 2.0 * np.sqrt(kp), rtol=TIGHT)  # zeta = 1, eq. 34


def test_lever_arms_come_from_the_geometry(vehicle_config):
    arms = derived.lever_arms(vehicle_config)
    np.testing.assert_allclose(arms, LEVER_ARMS, rtol=TIGHT)
    np.testing.assert_allclose(arms, from_equations(vehicle_config, "low")[0], rtol=TIGHT)


def test_f_min_fraction_eq_44(vehicle_config):
    assert derived.f_min_fraction(vehicle_config) == pytest.approx(0.375, rel=1e-15)  # 75 / (75 + 125)


@pytest.mark.parametrize("level", ["low", "high"])
def test_torque_max_is_inertia_times_acceleration(vehicle_config, level):
    j_diag = np.diag(np.array(vehicle_config["inertia_kg_m2"], float))
    np.testing.assert_allclose(
        derived.torque_max(vehicle_config, level), j_diag * derived.omega_dot_max(vehicle_config, level), rtol=TIGHT
    )
    # and that is l n_t F: the inertia cancels (000 eq. 1)
    thrust = vehicle_config["rcs"]["thrust_n"][level]
    np.testing.assert_allclose(
        derived.torque_max(vehicle_config, level), np.array(LEVER_ARMS) * [2, 2, 1] * thrust, rtol=TIGHT
    )


def test_packed_flight_software_carries_the_derived_values(vehicle_config):
    fsw = pack_fsw(vehicle_config)
    levels = pack_levels(vehicle_config)
    assert derived.level_names(vehicle_config) == list(REFEX_LEVELS)
    for k, level in enumerate(REFEX_LEVELS):
        kp, kd = derived.gains(vehicle_config, level)
        row = levels[k]
        assert row[L.LV_THRUST] == vehicle_config["rcs"]["thrust_n"][level]
        np.testing.assert_array_equal(row[L.LV_KP : L.LV_KP + 3], kp)
        np.testing.assert_array_equal(row[L.LV_KD : L.LV_KD + 3], kd)
        np.testing.assert_array_equal(
            row[L.LV_ACCEL_MAX : L.LV_ACCEL_MAX + 3], derived.omega_dot_max(vehicle_config, level)
        )
        np.testing.assert_array_equal(
            row[L.LV_TORQUE_MAX : L.LV_TORQUE_MAX + 3], derived.torque_max(vehicle_config, level)
        )
    assert fsw[L.F_PWPF_ON] == 0.075 and fsw[L.F_PWPF_OFF] == 0.125 and fsw[L.F_PWPF_CORRECTION] == 0.050
    assert fsw[L.F_MIN_ON] == 0.025 and fsw[L.F_MIN_OFF] == 0.175
    assert fsw[L.F_CONTROL_PERIOD] == 0.025
    assert fsw[L.F_ACCEL_MARGIN] == 0.65


# --- computed, not typed in: perturb a config value, the design follows -------------------------


def test_thrust_scales_acceleration_and_gains(vehicle_config):
    scaled = copy.deepcopy(vehicle_config)
    scaled["rcs"]["thrust_n"]["low"] *= 1.1
    for level, factor in (("low", 1.1), ("high", 1.0)):
        np.testing.assert_allclose(
            derived.omega_dot_max(scaled, level), factor * derived.omega_dot_max(vehicle_config, level), rtol=TIGHT
        )
        kp, kd = derived.gains(scaled, level)
        kp0, kd0 = derived.gains(vehicle_config, level)
        np.testing.assert_allclose(kp, factor * kp0, rtol=TIGHT)  # eq. 38: Kp ~ omega_dot_max
        np.testing.assert_allclose(kd, math.sqrt(factor) * kd0, rtol=TIGHT)  # eq. 34: Kd ~ sqrt(Kp)


def test_inertia_scales_acceleration_of_its_axis_only(vehicle_config):
    heavier = copy.deepcopy(vehicle_config)
    heavier["inertia_kg_m2"][0][0] *= 2.0
    ratio = derived.omega_dot_max(heavier, "high") / derived.omega_dot_max(vehicle_config, "high")
    np.testing.assert_allclose(ratio, [0.5, 1.0, 1.0], rtol=TIGHT)
    np.testing.assert_allclose(
        derived.torque_max(heavier, "high"), derived.torque_max(vehicle_config, "high"), rtol=TIGHT
    )


def test_thruster_position_changes_lever_arm(vehicle_config):
    wider = copy.deepcopy(vehicle_config)
    for thruster in wider["rcs"]["thrusters"]:
        thruster["position_m"][1] *= 1.2  # roll thrusters further out
    np.testing.assert_allclose(derived.lever_arms(wider), [0.171 * 1.2, 1.05, 1.05], rtol=TIGHT)
    ratio = derived.omega_dot_max(wider, "low") / derived.omega_dot_max(vehicle_config, "low")
    np.testing.assert_allclose(ratio, [1.2, 1.0, 1.0], rtol=TIGHT)


def test_deadband_and_tau_min_set_kp(vehicle_config):
    changed = copy.deepcopy(vehicle_config)
    changed["flight_software"]["deadband_angle_deg"] = 0.84
    changed["flight_software"]["pwpf"]["tau_min_fraction"] = 0.5
    kp0 = derived.gains(vehicle_config, "low")[0]
    phi0 = math.radians(vehicle_config["flight_software"]["deadband_angle_deg"])
    expected = kp0 * (0.5 / 0.35) * math.sin(phi0 / 2) / math.sin(math.radians(0.84) / 2)
    np.testing.assert_allclose(derived.gains(changed, "low")[0], expected, rtol=TIGHT)


def test_f_min_follows_algorithm_constants(vehicle_config):
    changed = copy.deepcopy(vehicle_config)
    changed["flight_software"]["pwpf"]["t_on_ms"] = 25.0
    changed["flight_software"]["pwpf"]["t_off_ms"] = 175.0
    assert derived.f_min_fraction(changed) == pytest.approx(0.125, rel=1e-15)


# --- what the valve transients make of a pulse (000 sec. 5, Fig. 6) ------------------------------


def _naive_equivalent_ms(vehicle, level, width_ms):
    """Full-thrust width of a command ``width_ms`` long: the exact integral of the naive valve
    profile (tests/naive.py, written from 000 Fig. 6), in ms."""
    c = vehicle["rcs"]["valve_time_constants_ms"][level]
    times = ValveTimes(c["on_delay"] / 1e3, c["rise"] / 1e3, c["off_delay"] / 1e3, c["fall"] / 1e3)
    knots = valve_knots([(0.0, True), (width_ms / 1e3, False)], times)
    impulse, _ = thrust_impulse([knots], 1.0, (1.0,), 0.0, 2.0)
    return 1e3 * impulse


@pytest.mark.parametrize("level", REFEX_LEVELS)
def test_pulse_equivalent_and_matching_correction_are_the_integral_of_the_ramps(vehicle_config, level):
    """The 25 ms hardware pulse gives ~75 ms of full thrust and the impulse-matching correction is
    ~50 ms at both levels with the 45 ms fall (000 sec. 2.1, 5; reference-model sec. 2).

    Both are compared with the exact trapezoid integral of the naive profile (rounding only: 1e-9
    ms); the correction is what a long pulse delivers beyond its command, for any width."""
    equivalent = derived.pulse_equivalent_ms(vehicle_config, level)
    matching = derived.pulse_correction_matching_ms(vehicle_config, level)
    min_on = vehicle_config["rcs"]["switching_limits_ms"]["min_on"]
    assert equivalent == pytest.approx(_naive_equivalent_ms(vehicle_config, level, min_on), abs=1e-9)
    for width_ms in (50.0, 175.0, 400.0):
        beyond = _naive_equivalent_ms(vehicle_config, level, width_ms) - width_ms
        assert matching == pytest.approx(beyond, abs=1e-9)
    assert abs(matching - 50.0) <= 5.0  # 000 sec. 5: delta gamma = 50 ms matches "for both"
    assert abs(equivalent - 75.0) <= 5.0  # the algorithm's shifted t_on = 75 ms
    assert abs(matching - vehicle_config["flight_software"]["pwpf"]["correction_ms"]) <= derived.CORRECTION_WARNING_MS


def test_pulse_impulse_covers_interrupted_and_cancelled_pulses():
    """A close that reacts mid-rise falls from the level reached; one that reacts before the open
    reaction cancels the pulse (reference-model sec. 2; the naive profile, to rounding)."""
    slow = {"on_delay": 19.1, "rise": 60.0, "off_delay": 10.0, "fall": 45.0}
    vehicle = {"rcs": {"valve_time_constants_ms": {"low": slow}}}
    for width_ms in (0.0, 5.0, 9.1, 25.0, 40.0, 69.1, 100.0):
        got = derived.pulse_impulse_ms(width_ms, *derived.valve_constants(vehicle, "low"))
        assert got == pytest.approx(_naive_equivalent_ms(vehicle, "low", width_ms), abs=1e-9), width_ms
    assert derived.pulse_impulse_ms(5.0, *derived.valve_constants(vehicle, "low")) == 0.0


def test_table2_fall_variant_differs_only_in_the_fall(vehicle_config):
    """configs/vehicles/refex-table2-fall.yaml is refex.yaml with 000 Table 2's fall times, so a
    sensitivity study flies the same vehicle otherwise."""
    variant = load_vehicle(CONFIGS / "refex-table2-fall.yaml")
    assert {lv: variant["rcs"]["valve_time_constants_ms"][lv]["fall"] for lv in REFEX_LEVELS} == {
        "low": 145.7,
        "high": 139.0,
    }  # 000 Table 2
    same = copy.deepcopy(variant)
    for lv in REFEX_LEVELS:
        reference = vehicle_config["rcs"]["valve_time_constants_ms"][lv]["fall"]
        same["rcs"]["valve_time_constants_ms"][lv]["fall"] = reference
    same["name"] = vehicle_config["name"]
    assert same == vehicle_config
    for lv in REFEX_LEVELS:  # its matching correction is ~100 ms: far from the PWPF's 50 ms
        assert derived.pulse_correction_matching_ms(variant, lv) > 90.0
