"""Reaction wheels, the sliding-mode controller and 001's disturbances on the config side (issue 14):
the distribution matrix against numpy and 001's closed form, what ``pack`` makes of IRASSI, bad input,
and the runs columns of a wheel vehicle and a pointing window. Nothing here flies."""

import json
import math
from pathlib import Path

import numpy as np
import pytest
import yaml
from click.testing import CliRunner
from scipy.spatial.transform import Rotation

from refexmc.cli import main
from refexmc.config import derived, dispersions, requirements
from refexmc.config.errors import ConfigError
from refexmc.config.load import load_campaign, load_mission, load_vehicle
from refexmc.config.pack import pack
from refexmc.core import layout as L

ROOT = Path(__file__).resolve().parents[1]
IRASSI = ROOT / "configs/vehicles/irassi.yaml"
SMALL = ROOT / "configs/missions/irassi-small-angle.yaml"
LARGE = ROOT / "configs/missions/irassi-large-angle.yaml"
REFEX = ROOT / "configs/vehicles/refex.yaml"
REFEX_MISSION = ROOT / "configs/missions/refex-exo.yaml"
# numpy's SVD-based pinv against a closed form or an inverse: agreement to rounding
EXACT = 1e-12
# 001 eq. 11 at L2 (the mission files): the Sun (mu 1.32712440018e20 m^3/s^2 at 1.511e11 m) and the
# Earth (3.986004418e14 m^3/s^2 at 1.5e9 m)
GG_COEFFICIENT = 1.32712440018e20 / 1.511e11**3 + 3.986004418e14 / 1.5e9**3


def _w4(a, b, c, d):
    """001 sec. 8.1's pyramid: W4 = [[b, c, b, c], [0, d, 0, -d], [a, 0, -a, 0]]."""
    return np.array([[b, c, b, c], [0.0, d, 0.0, -d], [a, 0.0, -a, 0.0]])


def _w4_pinv(a, b, c, d):
    """001 sec. 9.1's closed form of W4's pseudo-inverse."""
    e = b * b + c * c
    return 0.5 * np.array(
        [[b / e, 0.0, 1.0 / a], [c / e, 1.0 / d, 0.0], [b / e, 0.0, -1.0 / a], [c / e, -1.0 / d, 0.0]]
    )


def _irassi_abcd():
    """a, b, c, d of 001 sec. 8.1 read from the vehicle file's (normalised) axes."""
    w = derived.wheel_axes(load_vehicle(IRASSI))
    return w[2, 0], w[0, 0], w[0, 1], w[1, 1]


def _with_axes(vehicle, w):
    vehicle = json.loads(json.dumps(vehicle))
    for unit, axis in zip(vehicle["wheels"]["units"], w.T, strict=True):
        unit["axis"] = axis.tolist()
    return vehicle


# --- the distribution matrix (001 sec. 8.1, 9.1) ----------------------------------------------------


def test_irassi_axes_are_001s_pyramid():
    """The vehicle file's axes are W4 with a^2 + b^2 = c^2 + d^2 = 1 (001 sec. 8.1)."""
    a, b, c, d = _irassi_abcd()
    w = derived.wheel_axes(load_vehicle(IRASSI))
    np.testing.assert_allclose(w, _w4(a, b, c, d), rtol=0.0, atol=EXACT)
    assert a * a + b * b == pytest.approx(1.0, abs=EXACT) and c * c + d * d == pytest.approx(1.0, abs=EXACT)


@pytest.mark.parametrize(
    "angles_deg",
    [None, (54.7356, 54.7356), (50.0, 65.0)],
    ids=["vehicle-file", "54.74-deg-pyramid", "unequal-half-angles"],
)
def test_distribution_is_numpys_pinv_and_001s_closed_form(angles_deg):
    """D = numpy.linalg.pinv(W4) = 001 sec. 9.1's closed form; n4 spans W4's null space."""
    vehicle = load_vehicle(IRASSI)
    if angles_deg is None:
        a, b, c, d = _irassi_abcd()
    else:  # b, c: the x components of the x-z and x-y wheel pairs
        b, c = (math.cos(math.radians(t)) for t in angles_deg)
        a, d = math.sqrt(1.0 - b * b), math.sqrt(1.0 - c * c)
        vehicle = _with_axes(vehicle, _w4(a, b, c, d))
    w4 = _w4(a, b, c, d)
    distribution = derived.wheel_distribution(vehicle)
    np.testing.assert_allclose(distribution, np.linalg.pinv(w4), rtol=0.0, atol=EXACT)
    np.testing.assert_allclose(distribution, _w4_pinv(a, b, c, d), rtol=0.0, atol=EXACT)
    np.testing.assert_allclose(w4 @ distribution, np.eye(3), rtol=0.0, atol=EXACT)  # it makes the torque asked
    n4 = np.array([c, -b, c, -b]) / math.sqrt(2.0 * (b * b + c * c))
    np.testing.assert_allclose(w4 @ n4, 0.0, atol=EXACT)  # 001 sec. 8.1: n4 spans the null space
    assert np.linalg.norm(n4) == pytest.approx(1.0, abs=EXACT)
    null = derived.wheel_null_space(vehicle)
    assert null.shape == (4, 1)
    np.testing.assert_allclose(null[:, 0], n4, rtol=0.0, atol=1e-9)


@pytest.mark.parametrize("excluded", [1, 2, 3, 4])
def test_three_wheels_of_four_are_the_inverse_of_their_3x3(excluded):
    """Without one wheel (a failure the flight software knows of) the pinv is the 3x3 inverse."""
    vehicle = load_vehicle(IRASSI)
    w = derived.wheel_axes(vehicle)
    used = [i for i in range(4) if i != excluded - 1]
    distribution = derived.wheel_distribution(vehicle, excluded=(excluded,))
    np.testing.assert_array_equal(distribution[excluded - 1], 0.0)
    np.testing.assert_allclose(distribution[used], np.linalg.inv(w[:, used]), rtol=0.0, atol=EXACT)
    np.testing.assert_allclose(w @ distribution, np.eye(3), rtol=0.0, atol=EXACT)


# --- what pack makes of IRASSI --------------------------------------------------------------------


def _field(array, fields, name):
    offset, size = fields.slices[name]
    return array[offset] if size == 1 else array[offset : offset + size]


def test_pack_irassi_wheel_and_level_tables():
    vehicle = load_vehicle(IRASSI)
    inputs = pack(vehicle, load_mission(SMALL))
    # wheels only: no thrusters, no allocation columns, no propellant; one level, "wheels"
    assert inputs.thrusters.shape[0] == 0 and inputs.allocation.shape == (27, 0)
    assert _field(inputs.vehicle, L.VEHICLE, "propellant_kg") == 0.0
    assert derived.level_names(vehicle) == ["wheels"] and inputs.levels.shape == (1, L.LEVEL_SIZE)
    assert inputs.wheels.shape == (4, L.WHEEL_SIZE) and inputs.wheel_distribution.shape == (4, 3)
    axes = inputs.wheels[:, L.W_AXIS : L.W_AXIS + 3]
    np.testing.assert_allclose(np.linalg.norm(axes, axis=1), 1.0, rtol=0.0, atol=EXACT)
    raw = np.array([unit["axis"] for unit in vehicle["wheels"]["units"]], dtype=float)
    np.testing.assert_allclose(axes, raw / np.linalg.norm(raw, axis=1, keepdims=True), rtol=0.0, atol=EXACT)
    # 001 Table 3 (rotor, friction) and Table 6 / sec. 11.2.1 (68 N m s, 0.2 N m), as in the file
    for name, value in [
        ("spin_inertia_kg_m2", 0.1295),
        ("torque_max_n_m", 0.2),
        ("momentum_max_n_m_s", 68.0),
        ("coulomb_friction_n_m", 0.005),
        ("viscous_friction_n_m_s", 2.1241e-5),
        ("failed", 0.0),
        ("initial_momentum_n_m_s", 0.0),
    ]:
        np.testing.assert_array_equal(inputs.wheels[:, L.WHEEL.slices[name][0]], value, err_msg=name)
    np.testing.assert_allclose(inputs.wheel_distribution, np.linalg.pinv(axes.T), rtol=0.0, atol=EXACT)
    # the level: no thrust; omega_dot_max per body axis = the largest torque the wheels make about it
    # over J_ii. Independently: sum_i |W[k, i]| tau_max (every wheel at its limit, the other axes
    # cancelling, as they do in this symmetric pyramid)
    level = inputs.levels[0]
    assert level[L.LV_THRUST] == 0.0 and level[L.LV_THRUST_DESIGN] == 0.0
    torque = np.abs(axes.T).sum(axis=1) * 0.2
    j = np.diag(np.asarray(vehicle["inertia_kg_m2"], dtype=float))
    np.testing.assert_allclose(_field(level, L.LEVEL, "torque_max_n_m"), torque, rtol=EXACT)
    np.testing.assert_allclose(_field(level, L.LEVEL, "accel_max_rad_s2"), torque / j, rtol=EXACT)
    np.testing.assert_array_equal(_field(level, L.LEVEL, "kp"), 0.0)  # smc: no PD gains
    np.testing.assert_array_equal(_field(level, L.LEVEL, "kd"), 0.0)
    # flight software: smc on wheels, 1 Hz, the file's gains
    assert inputs.fsw[L.F_CONTROLLER] == L.CONTROLLER_SMC and inputs.fsw[L.F_ACTUATION] == L.ACTUATION_WHEELS
    assert inputs.fsw[L.F_CONTROL_PERIOD] == 1.0
    smc = vehicle["flight_software"]["smc"]
    np.testing.assert_array_equal(_field(inputs.fsw, L.FSW, "smc_slope_s"), smc["slope_s"])
    np.testing.assert_array_equal(_field(inputs.fsw, L.FSW, "smc_gain_rad_s2"), smc["gain_rad_s2"])
    np.testing.assert_array_equal(_field(inputs.fsw, L.FSW, "smc_boundary_layer_rad_s"), smc["boundary_layer_rad_s"])
    np.testing.assert_array_equal(_field(inputs.fsw, L.FSW, "inertia_kg_m2"), np.ravel(vehicle["inertia_kg_m2"]))


def test_the_smc_gains_give_001s_initial_torque_demand():
    """The file's gains, estimated (001 gives none): J G is tens of N m, 001 Fig. 22's order
    (~[-20, -75, -45] N m at the small-angle manoeuvre's start)."""
    vehicle = load_vehicle(IRASSI)
    demand = np.diag(np.asarray(vehicle["inertia_kg_m2"])) * vehicle["flight_software"]["smc"]["gain_rad_s2"]
    assert np.all((demand > 10.0) & (demand < 100.0)), demand


def test_pack_with_failed_and_detected_wheels():
    """failed_wheels mark the wheel table; detected_wheels leave the distribution and the level's limits."""
    vehicle = load_vehicle(IRASSI)
    inputs = pack(vehicle, load_mission(SMALL), failed_wheels=(2,), detected_wheels=(2,))
    assert inputs.wheels[:, L.W_FAILED].tolist() == [0.0, 1.0, 0.0, 0.0]
    np.testing.assert_array_equal(inputs.wheel_distribution[1], 0.0)
    w3 = derived.wheel_axes(vehicle)[:, [0, 2, 3]]
    np.testing.assert_allclose(inputs.wheel_distribution[[0, 2, 3]], np.linalg.inv(w3), rtol=0.0, atol=EXACT)
    # each axis: the torque at which the first used wheel reaches 0.2 N m under the distribution
    torque = 0.2 / np.abs(np.linalg.inv(w3)).max(axis=0)
    np.testing.assert_allclose(_field(inputs.levels[0], L.LEVEL, "torque_max_n_m"), torque, rtol=EXACT)
    undetected = pack(vehicle, load_mission(SMALL), failed_wheels=(2,))
    np.testing.assert_allclose(undetected.wheel_distribution, derived.wheel_distribution(vehicle), atol=0.0)


def test_pack_null_space_management():
    """The vehicle file's null_space_management reaches every row of the wheel table (1 / time
    constant, bias, deadband, cap); without the block the columns are 0: no management."""
    vehicle = load_vehicle(IRASSI)
    managed = vehicle["wheels"]["null_space_management"]
    table = pack(vehicle, load_mission(SMALL)).wheels
    np.testing.assert_array_equal(table[:, L.W_NULL_SPACE_RATE], 1.0 / managed["time_constant_s"])
    np.testing.assert_array_equal(table[:, L.W_NULL_SPACE_BIAS], 0.0)  # target zero
    np.testing.assert_array_equal(table[:, L.W_NULL_SPACE_DEADBAND], managed["deadband_n_m_s"])
    np.testing.assert_array_equal(table[:, L.W_NULL_SPACE_TORQUE_MAX], managed["torque_max_n_m"])
    np.testing.assert_array_equal(table[:, L.W_NULL_SPACE_GIVE_UP], managed["give_up_beyond_n_m_s"])
    vehicle["wheels"]["null_space_management"] = {
        "time_constant_s": 500.0,
        "target": "bias",
        "bias_n_m_s": [15.0, -15.0, 15.0, -15.0],
    }
    table = pack(vehicle, load_mission(SMALL)).wheels
    np.testing.assert_array_equal(table[:, L.W_NULL_SPACE_BIAS], [15.0, -15.0, 15.0, -15.0])
    np.testing.assert_array_equal(table[:, L.W_NULL_SPACE_DEADBAND], 0.0)
    np.testing.assert_array_equal(table[:, L.W_NULL_SPACE_TORQUE_MAX], vehicle["wheels"]["torque_max_n_m"])
    np.testing.assert_array_equal(table[:, L.W_NULL_SPACE_GIVE_UP], math.inf)  # never
    del vehicle["wheels"]["null_space_management"]
    table = pack(vehicle, load_mission(SMALL)).wheels
    for column in (
        L.W_NULL_SPACE_RATE,
        L.W_NULL_SPACE_BIAS,
        L.W_NULL_SPACE_DEADBAND,
        L.W_NULL_SPACE_TORQUE_MAX,
        L.W_NULL_SPACE_GIVE_UP,
    ):
        np.testing.assert_array_equal(table[:, column], 0.0)


@pytest.mark.parametrize(("mission", "target_deg"), [(SMALL, [13.0, 13.0, 13.0]), (LARGE, [30.0, -20.0, 1.0])])
def test_pack_irassi_missions(mission, target_deg):
    inputs = pack(load_vehicle(IRASSI), load_mission(mission))
    m = inputs.mission
    # 001 eq. 11: mu_1/r_1^3 + mu_2/r_2^3, the Sun and the Earth from L2: 1.57e-13 1/s^2
    assert _field(m, L.MISSION, "gravity_gradient_coefficient_s2") == pytest.approx(GG_COEFFICIENT, rel=EXACT)
    assert _field(m, L.MISSION, "gravity_gradient_coefficient_s2") == pytest.approx(1.57e-13, rel=0.01)
    np.testing.assert_array_equal(_field(m, L.MISSION, "gravity_gradient_direction"), [0.0, 0.0, 1.0])
    np.testing.assert_allclose(_field(m, L.MISSION, "constant_torque_n_m"), 1.18e-3 / 3, rtol=1e-4)
    assert _field(m, L.MISSION, "pointing_statistics_from_s") == 14400.0
    assert _field(m, L.MISSION, "integrator_max_step_s") == 1.0
    # the initial attitude: 001's theta_0 = [14, 14, 14] deg, extrinsic xyz as scipy reads it; the
    # core's start is from_rotation_vector(0, fpa, 0) (x) from_rotation_vector(rotvec), fpa 0 here
    rotvec = _field(m, L.MISSION, "initial_attitude_rotvec_rad")
    expected = Rotation.from_euler("xyz", [14.0, 14.0, 14.0], degrees=True)
    assert (Rotation.from_rotvec(rotvec) * expected.inv()).magnitude() < EXACT
    assert _field(m, L.MISSION, "initial_flight_path_angle_rad") == 0.0
    # the target: extrinsic xyz with 001's [phi, theta, psi] is the 3-2-1 sequence, intrinsic ZYX [psi, theta, phi]
    q = Rotation.from_quat(inputs.modes[0, L.MD_QUATERNION : L.MD_QUATERNION + 4])
    assert (q * Rotation.from_euler("ZYX", target_deg[::-1], degrees=True).inv()).magnitude() < EXACT
    assert inputs.modes.shape == (2, L.MODE_SIZE) and not inputs.modes[:, L.MD_LEVEL].any()  # manoeuvre, science


def test_missions_without_the_new_keys_pack_as_before():
    """No disturbances, no pointing window: the defaults the core reads as 'none'."""
    m = pack(load_vehicle(REFEX), load_mission(REFEX_MISSION)).mission
    assert _field(m, L.MISSION, "gravity_gradient_coefficient_s2") == 0.0
    np.testing.assert_array_equal(_field(m, L.MISSION, "constant_torque_n_m"), 0.0)
    assert _field(m, L.MISSION, "pointing_statistics_from_s") == math.inf


def _refex_with_wheels(actuation):
    """ReFEx with IRASSI's wheel assembly: a vehicle with both actuators."""
    vehicle = yaml.safe_load(REFEX.read_text())
    vehicle["wheels"] = yaml.safe_load(IRASSI.read_text())["wheels"]
    vehicle["flight_software"]["actuation"] = actuation
    if actuation == "wheels":
        vehicle["flight_software"]["gains"] = {"kp": {"wheels": [1.0, 1.0, 1.0]}, "kd": {"wheels": [2.0, 2.0, 2.0]}}
        del vehicle["flight_software"]["allocation"]
    return vehicle


def _refex_mission_without_thrust():
    """ReFEx's mission with the modes' thrust levels left out (what a vehicle flying wheels needs)."""
    mission = load_mission(REFEX_MISSION)
    for mode in mission["modes"]:
        mode.pop("thrust", None)
    return mission


def test_a_vehicle_with_rcs_and_wheels(tmp_path):
    """Thrusters and wheels: the levels follow the actuation; the other actuator is carried."""
    path = tmp_path / "v.yaml"
    path.write_text(yaml.safe_dump(_refex_with_wheels("pwpf_table"), sort_keys=False))
    vehicle = load_vehicle(path)
    inputs = pack(vehicle, load_mission(REFEX_MISSION))
    assert derived.level_names(vehicle) == ["low", "high"] and inputs.levels.shape[0] == 2
    assert inputs.thrusters.shape == (8, L.thruster_size(2)) and inputs.wheels.shape == (4, L.WHEEL_SIZE)
    assert inputs.fsw[L.F_ACTUATION] == L.ACTUATION_PWPF_TABLE

    path.write_text(yaml.safe_dump(_refex_with_wheels("wheels"), sort_keys=False))
    vehicle = load_vehicle(path)
    inputs = pack(vehicle, _refex_mission_without_thrust())
    assert derived.level_names(vehicle) == ["wheels"] and inputs.levels.shape[0] == 1
    assert inputs.thrusters.shape == (8, L.thruster_size(2))  # carried, with the rcs levels' valves
    assert (
        inputs.fsw[L.F_ACTUATION] == L.ACTUATION_WHEELS
        and inputs.fsw[L.F_CONTROLLER] == L.CONTROLLER_PD_FEEDBACK_LINEARISATION
    )
    np.testing.assert_array_equal(_field(inputs.levels[0], L.LEVEL, "kd"), [2.0, 2.0, 2.0])  # the given gains


def test_inspect_shows_the_wheels():
    result = CliRunner().invoke(main, ["inspect", str(IRASSI), "--json"])
    assert result.exit_code == 0, result.output
    info = json.loads(result.output)
    vehicle = load_vehicle(IRASSI)
    np.testing.assert_allclose(info["omega_dot_max_rad_s2"]["wheels"], derived.wheel_accel_max(vehicle))
    np.testing.assert_allclose(info["wheels"]["distribution_matrix"], derived.wheel_distribution(vehicle))
    assert "f_min_fraction" not in info  # no PWPF without thrusters
    text = CliRunner().invoke(main, ["inspect", str(IRASSI)]).output
    assert "reaction wheels: 4" in text and "null space 1" in text
    assert info["wheels"]["null_space_management"] == vehicle["wheels"]["null_space_management"]
    assert (
        "null-space momentum management: target zero, time constant 1000 s, deadband 25 N m s, "
        "at most 0.0035 N m per wheel, gives up 8 N m s beyond the deadband" in text
    )
    torque = CliRunner().invoke(main, ["inspect", str(IRASSI), "--torque", "0.1,0,0", "--json"])
    alloc = json.loads(torque.output)["allocation"]
    np.testing.assert_allclose(alloc["realised_torque_n_m"], [0.1, 0.0, 0.0], atol=EXACT)
    np.testing.assert_allclose(alloc["commands"], -0.1 * derived.wheel_distribution(vehicle)[:, 0], atol=EXACT)


# --- bad input: one message with file, line and key path ------------------------------------------

IRASSI_TEXT = IRASSI.read_text()
SMALL_TEXT = SMALL.read_text()


def _edit(text, old, new):
    assert old in text, old
    return text.replace(old, new, 1)


# (case id, "vehicle" or "mission", edited text, the line's fragment, words the message must contain)
BAD_FILES = [
    (
        "null-space-bias-without-values",
        "vehicle",
        _edit(IRASSI_TEXT, "    target: zero", "    target: bias"),
        "  null_space_management:",
        ["wheels.null_space_management", "expected bias_n_m_s with target bias"],
    ),
    (
        "null-space-bias-not-per-wheel",
        "vehicle",
        _edit(IRASSI_TEXT, "    target: zero", "    target: bias\n    bias_n_m_s: [10.0, -10.0, 10.0]"),
        "bias_n_m_s",
        ["wheels.null_space_management.bias_n_m_s", "expected one bias per wheel (4), got 3"],
    ),
    (
        "null-space-bias-beyond-the-limit",
        "vehicle",
        _edit(IRASSI_TEXT, "    target: zero", "    target: bias\n    bias_n_m_s: [70.0, -10.0, 10.0, -10.0]"),
        "bias_n_m_s",
        ["wheels.null_space_management.bias_n_m_s", "expected every |bias| below momentum_max_n_m_s (68 N m s)"],
    ),
    (
        "null-space-misspelt-key",
        "vehicle",
        _edit(IRASSI_TEXT, "    time_constant_s: 1000.0", "    time_constant: 1000.0"),
        "time_constant: 1000.0",
        ["wheels.null_space_management.time_constant", "unknown key", "did you mean 'time_constant_s'"],
    ),
    (
        "null-space-zero-time-constant",
        "vehicle",
        _edit(IRASSI_TEXT, "    time_constant_s: 1000.0", "    time_constant_s: 0.0"),
        "time_constant_s: 0.0",
        ["wheels.null_space_management.time_constant_s"],
    ),
    (
        "wheels-with-actuation-pwpf_table",
        "vehicle",
        _edit(IRASSI_TEXT, "  actuation: wheels ", "  actuation: pwpf_table "),
        "actuation: pwpf_table",
        ["flight_software.actuation", "actuation pwpf_table needs the vehicle's 'rcs'"],
    ),
    (
        "smc-without-gains",
        "vehicle",
        IRASSI_TEXT[: IRASSI_TEXT.index("  smc:\n")] + IRASSI_TEXT[IRASSI_TEXT.index("  actuation: wheels") :],
        "controller: smc",
        ["flight_software.controller", "controller smc needs its gains (flight_software.smc)"],
    ),
    (
        "axis-of-zero-length",
        "vehicle",
        _edit(IRASSI_TEXT, "axis: [1.0, 1.0, 0.0]", "axis: [0.0, 0.0, 0.0]"),
        "axis: [0.0, 0.0, 0.0]",
        ["wheels.units.1.axis", "expected a non-zero spin axis"],
    ),
    (
        "coplanar-axes",
        "vehicle",
        _edit(
            _edit(IRASSI_TEXT, "axis: [1.0, 0.0, -1.0]", "axis: [0.0, 1.0, 0.0]"), "[1.0, 0.0, 1.0]", "[1.0, 0.0, 0.0]"
        ),
        "  units:",
        ["wheels.units", "span the three body axes, got rank 2"],
    ),
    (
        "initial-momentum-beyond-the-limit",
        "vehicle",
        _edit(
            IRASSI_TEXT,
            "name: RW4, axis: [1.0, -1.0, 0.0]}",
            "name: RW4, axis: [1.0, -1.0, 0.0], initial_momentum_n_m_s: -70}",
        ),
        "initial_momentum_n_m_s: -70",
        ["wheels.units.3.initial_momentum_n_m_s", "expected |initial momentum| <= momentum_max_n_m_s (68 N m s)"],
    ),
    (
        "thruster-design-without-an-rcs",
        "vehicle",
        _edit(
            IRASSI_TEXT, "  guidance_accel_margin: 0.5", "  guidance_accel_margin: 0.5\n  thrusters_per_axis: [2, 2, 1]"
        ),
        "thrusters_per_axis",
        ["flight_software.thrusters_per_axis", "a thruster design key; the vehicle has no rcs"],
    ),
    (
        "smc-gains-with-controller-pd",
        "vehicle",
        _edit(IRASSI_TEXT, "  controller: smc ", "  controller: pd "),
        "  smc:",
        ["flight_software.smc", "'smc' is used by controller smc only; the controller is pd"],
    ),
    (
        "no-actuator",
        "vehicle",
        IRASSI_TEXT[: IRASSI_TEXT.index("wheels:\n")] + IRASSI_TEXT[IRASSI_TEXT.index("flight_software:") :],
        "name: irassi",
        ["expected an actuator: 'rcs', 'wheels' or both"],
    ),
    (
        "unknown-distribution",
        "vehicle",
        _edit(IRASSI_TEXT, "distribution: pseudo_inverse", "distribution: pseudoinverse"),
        "distribution: pseudoinverse",
        ["wheels.distribution", "expected one of pseudo_inverse"],
    ),
    (
        "both-initial-attitudes",
        "mission",
        _edit(SMALL_TEXT, "  euler_sequence: xyz", "  euler_sequence: xyz\n  attitude_rotvec_deg: [0.0, 0.0, 0.0]"),
        "initial_state:",
        ["initial_state", "expected either 'attitude_rotvec_deg' or 'attitude_euler_deg'"],
    ),
    (
        "euler-angles-without-a-sequence",
        "mission",
        _edit(SMALL_TEXT, "  euler_sequence: xyz ", "  # no sequence "),
        "attitude_euler_deg",
        ["initial_state.attitude_euler_deg", "needs 'euler_sequence'"],
    ),
    (
        "gravity-gradient-direction-zero",
        "mission",
        _edit(SMALL_TEXT, "    direction: [0.0, 0.0, 1.0]", "    direction: [0.0, 0.0, 0.0]"),
        "direction: [0.0, 0.0, 0.0]",
        ["disturbances.gravity_gradient.direction", "expected a non-zero vector"],
    ),
    (
        "pointing-window-after-the-flight",
        "mission",
        _edit(SMALL_TEXT, "pointing_statistics_from_s: 14400.0", "pointing_statistics_from_s: 90000.0"),
        "pointing_statistics_from_s",
        ["pointing_statistics_from_s", "expected a time before max_flight_time_s (80000 s), got 90000"],
    ),
    (
        "negative-pointing-window",
        "mission",
        _edit(SMALL_TEXT, "pointing_statistics_from_s: 14400.0", "pointing_statistics_from_s: -1.0"),
        "pointing_statistics_from_s",
        ["pointing_statistics_from_s", "expected a value >= 0.0"],
    ),
]


@pytest.mark.parametrize(
    ("kind", "text", "fragment", "words"), [c[1:] for c in BAD_FILES], ids=[c[0] for c in BAD_FILES]
)
def test_bad_wheel_and_mission_files_are_refused(tmp_path, kind, text, fragment, words):
    path = tmp_path / f"{kind}.yaml"
    path.write_text(text)
    result = CliRunner().invoke(main, ["validate", str(path)])
    assert result.exit_code == 2, result.output
    assert "Traceback" not in result.output
    line = next(n for n, s in enumerate(text.splitlines(), 1) if fragment in s)
    assert f"{path}:{line}:" in result.output, result.output
    for word in words:
        assert word in result.output, (word, result.output)


def _campaign(tmp_path, mission_text=SMALL_TEXT, vehicle=IRASSI, extra=""):
    (tmp_path / "mission.yaml").write_text(mission_text)
    text = f"name: irassi-test\nvehicle: {vehicle}\nmission: {tmp_path / 'mission.yaml'}\nruns: 2\nseed: 1\n{extra}"
    (tmp_path / "campaign.yaml").write_text(text)
    return tmp_path / "campaign.yaml"


def test_a_thrust_level_on_a_wheel_vehicle_is_refused_in_the_mission_file(tmp_path):
    bad = _edit(SMALL_TEXT, "    kind: hold\n", "    kind: hold\n    thrust: low\n")
    result = CliRunner().invoke(main, ["validate", str(_campaign(tmp_path, bad))])
    assert result.exit_code == 2
    line = next(n for n, s in enumerate(bad.splitlines(), 1) if "thrust: low" in s)
    assert f"{tmp_path / 'mission.yaml'}:{line}: modes.0.thrust:" in result.output, result.output
    assert "flies reaction wheels (actuation wheels); a mode takes no 'thrust'" in result.output


def test_an_actuation_the_vehicle_cannot_drive_is_refused(tmp_path):
    text = _edit(REFEX.read_text(), "actuation: pwpf_table", "actuation: wheels")
    (tmp_path / "v.yaml").write_text(text)
    with pytest.raises(ConfigError, match=r"flight_software\.actuation: actuation wheels needs the vehicle's 'wheels'"):
        load_vehicle(tmp_path / "v.yaml")


@pytest.mark.parametrize(
    ("extra", "words"),
    [
        (
            "failures: {mode: fixed, thrusters: [1]}\n",
            "failures.mode: failures mode fixed fails thrusters; the vehicle has none",
        ),
        (
            "dispersions:\n  rcs.isp_s: {dist: normal, sigma: 1.0}\n",
            "'rcs.isp_s': the vehicle file does not declare it",
        ),
        (
            "requirements: ['wheel_saturated_s.max <= 1', 'pulses_1.max <= 1']\n",
            "requirements.1: unknown metric 'pulses_1.max'",
        ),
        (
            "requirements: ['wheel_saturated_s.max <= 1', 'pulses_total.max <= 0']\n",
            "requirements.1: unknown metric 'pulses_total.max'",
        ),
    ],
    ids=["thruster-failures", "rcs-dispersion", "pulse-requirement", "pulses-total-requirement"],
)
def test_a_wheel_campaign_refuses_what_needs_thrusters(tmp_path, extra, words):
    with pytest.raises(ConfigError) as error:
        load_campaign(_campaign(tmp_path, extra=extra))
    assert words in str(error.value)


def test_rcs_dispersions_of_a_vehicle_that_flies_wheels_are_refused(tmp_path):
    (tmp_path / "v.yaml").write_text(yaml.safe_dump(_refex_with_wheels("wheels"), sort_keys=False))
    (tmp_path / "m.yaml").write_text(yaml.safe_dump(_refex_mission_without_thrust(), sort_keys=False))
    extra = "dispersions:\n  rcs.thrust_n.low: {dist: normal, sigma: 0.1}\n"
    campaign = f"name: x\nvehicle: {tmp_path / 'v.yaml'}\nmission: {tmp_path / 'm.yaml'}\nruns: 2\nseed: 1\n{extra}"
    (tmp_path / "c.yaml").write_text(campaign)
    with pytest.raises(ConfigError, match="flies reaction wheels .actuation wheels.; its thrusters never fire"):
        load_campaign(tmp_path / "c.yaml")


def test_the_euler_attitude_disperses_about_its_rotation_vector():
    """initial_state.attitude_rotvec_deg of a mission with Euler angles: nominal = their rotation vector."""
    nominal = dispersions.nominal("initial_state.attitude_rotvec_deg", load_vehicle(IRASSI), load_mission(LARGE))
    expected = Rotation.from_euler("xyz", [14.0, 14.0, 14.0], degrees=True).as_rotvec(degrees=True)
    np.testing.assert_allclose(nominal, expected, rtol=EXACT)


# --- runs columns: pointing window and wheels -------------------------------------------------------


def test_runs_columns_of_a_wheel_campaign(tmp_path):
    """The pointing and wheel columns are declared (requirements may name them), and an errored run's
    row has them (NaN); nothing is flown."""
    from refexmc.campaign import storage
    from refexmc.campaign.chunk import RunPlan

    extra = "requirements: ['pointing_rms_x_arcsec.max <= 0.1', 'wheel_momentum_peak_n_m_s.max <= 68']\n"
    campaign = load_campaign(_campaign(tmp_path, extra=extra))
    plan = RunPlan(campaign)
    assert plan.n_thrusters == 0
    assert plan.value_columns == [
        "fuel_remaining",
        "fuel_used_kg",
        "t_end_s",
        "t_manoeuvre_s",
        "t_science_s",
        "attitude_error_end_deg",
        *requirements.POINTING_COLUMNS,
        *requirements.WHEEL_COLUMNS,
    ]
    row = plan.error_row(1, "test")
    assert all(math.isnan(row[c]) for c in plan.value_columns) and not any(c.startswith("pulses_") for c in row)
    columns = storage.output_names(campaign)["columns"]["runs"]
    assert set(requirements.POINTING_COLUMNS + requirements.WHEEL_COLUMNS) <= set(columns)


def test_runs_columns_follow_the_mission_and_the_vehicle():
    """Pointing columns with a pointing window, wheel columns with wheels, neither for ReFEx."""
    refex = requirements.column_options(load_vehicle(REFEX), load_mission(REFEX_MISSION))
    assert refex == {"trajectory": "planar_drag", "pointing": False, "wheels": False}
    irassi = requirements.column_options(load_vehicle(IRASSI), load_mission(SMALL))
    assert irassi == {"trajectory": "none", "pointing": True, "wheels": True}
    with pytest.raises(ConfigError, match="unknown metric 'pointing_max_arcsec.max'"):
        requirements.parse_requirement("pointing_max_arcsec.max <= 1", requirements.runs_metric_columns(["a"], 8))


def test_runs_values_name_the_summary_fields():
    """FlightResult.runs_values maps each pointing and wheel column to its layout.SUMMARY field."""
    from refexmc.simulate import FlightResult

    summary = np.zeros(L.summary_size(1))
    fields = {
        "pointing_end_arcsec": [1.0, 2.0, 3.0],
        "pointing_rms_arcsec": [4.0, 5.0, 6.0],
        "pointing_max_arcsec": 7.0,
        "wheel_momentum_peak_n_m_s": 8.0,
        "wheel_momentum_end_n_m_s": 9.0,
        "wheel_torque_demand_peak_n_m": 10.0,
        "wheel_saturated_s": 11.0,
        "angular_momentum_residual": 12.0,
    }
    for name, value in fields.items():
        offset, size = L.SUMMARY.slices[name]
        summary[offset : offset + size] = value
    result = FlightResult(
        summary, np.zeros(0, dtype=np.int64), np.zeros((0, L.HISTORY_SIZE)), ["science"], False, True, True
    )
    row = result.runs_values()
    values = [row[c] for c in requirements.POINTING_COLUMNS + requirements.WHEEL_COLUMNS]
    assert values == [float(v) for v in range(1, 13)]
    assert list(row) == [*requirements.run_value_columns(["science"], "none", True, True), "modes_completed"]


def test_the_report_reads_every_new_column_upper_and_as_a_key_column():
    from refexmc.report.summary import KEY_COLUMNS
    from refexmc.report.tails import worse_tail

    for column in requirements.POINTING_COLUMNS + requirements.WHEEL_COLUMNS:
        # the end-of-window error per axis is signed: both ends matter (issue 25)
        expected = "both" if column.startswith("pointing_end_") else "upper"
        assert worse_tail(column) == expected, column
        assert column in KEY_COLUMNS, column


def test_a_misspelt_column_is_matched_by_its_column_not_by_its_statistic(tmp_path):
    # 'pulses_1.max' on wheels used to suggest 'fuel_used_kg.max': the shared '.max' carried the match
    with pytest.raises(ConfigError) as error:
        load_campaign(_campaign(tmp_path, extra="requirements: ['pulses_1.max <= 1']\n"))
    assert "did you mean" not in str(error.value)
    with pytest.raises(ConfigError, match=r"did you mean 'wheel_saturated_s\.p95'\?"):
        load_campaign(_campaign(tmp_path, extra="requirements: ['wheel_saturatd_s.p95 <= 1']\n"))
