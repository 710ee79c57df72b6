"""The X-38 vehicle file (configs/vehicles/x38.yaml, issue 24): its tables are what their
generator prints, they pack into the arrays core.entry flies, and bad entry input is exit 2 with
file, line and key path."""

import json
import math
import re
import sys
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from refexmc.cli import main
from refexmc.config import entry
from refexmc.config.load import load_vehicle
from refexmc.core import aerodynamics

ROOT = Path(__file__).resolve().parents[1]
X38 = ROOT / "configs/vehicles/x38.yaml"
TEXT = X38.read_text()
sys.path.insert(0, str(ROOT / "configs/vehicles"))
import gen_x38_aero  # noqa: E402


def test_the_vehicle_file_holds_what_its_generator_prints():
    vehicle = load_vehicle(X38)
    tables = vehicle["entry_aerodynamics"]
    assert tables["alpha_deg"] == gen_x38_aero.ALPHA_DEG and tables["mach"] == gen_x38_aero.MACH
    assert tables["coefficients"] == gen_x38_aero.tables()


def test_the_packed_model_interpolates_the_files_tables():
    vehicle = load_vehicle(X38)
    model = entry.model(vehicle, 6_371_000.0, 3.986e14, 7.29e-5)
    tables = vehicle["entry_aerodynamics"]
    slots = entry.coefficient_slots()
    for key, table in tables["coefficients"].items():
        for i, alpha_deg in enumerate(tables["alpha_deg"]):
            for j, mach in enumerate(tables["mach"]):
                got = aerodynamics.coefficient(
                    model.alpha_axis, model.mach_axis, model.coefficients, slots[key], math.radians(alpha_deg), mach
                )
                assert got == pytest.approx(table[i][j], rel=1e-14, abs=1e-16), (key, alpha_deg, mach)
    assert model.reference[0] == 22.7  # 003 Table 1
    assert model.atmosphere.shape[1] == 4
    # the trim deflection of 003 eq. 6, -C_m / C_m_delta_e, is the generator's 14 deg at alpha 40
    alpha = math.radians(40.0)
    c_m = aerodynamics.coefficient(
        model.alpha_axis, model.mach_axis, model.coefficients, aerodynamics.AC_PITCH, alpha, 20.0
    )
    c_m_de = aerodynamics.coefficient(
        model.alpha_axis, model.mach_axis, model.coefficients, aerodynamics.AC_PITCH_ELEVON, alpha, 20.0
    )
    assert math.degrees(-c_m / c_m_de) == pytest.approx(gen_x38_aero.trim_deflection_deg(40.0), abs=1e-3)


def test_lift_to_drag_is_about_0_9_in_the_hypersonic_phase():
    """003: "a lifting body with a lift-to-drag ratio of about 0.9 during the hypersonic phase"."""
    tables = gen_x38_aero.tables()
    i = gen_x38_aero.ALPHA_DEG.index(40.0)
    for j, mach in enumerate(gen_x38_aero.MACH):
        if mach >= 6.0:
            assert 0.85 <= tables["lift"][i][j] / tables["drag"][i][j] <= 0.95


def _line_of(text, needle):
    return next(n for n, line in enumerate(text.splitlines(), 1) if needle in line)


def _first_row(key):
    """The first table row of coefficient ``key`` in the file's text."""
    start = TEXT.index(f"    {key}:\n")
    row_start = TEXT.index("      - [", start)
    return row_start, TEXT.index("\n", row_start)


def _drop_block(text, key):
    start = text.index(f"    {key}:\n")
    end = start + len(f"    {key}:\n")
    while text[end:].startswith("      - "):
        end = text.index("\n", end) + 1
    return text[:start] + text[end:]


def _without_rudders():
    text = _drop_block(_drop_block(TEXT, "roll_per_rudder_rad"), "yaw_per_rudder_rad")
    return re.sub(r"\n  rudders: .*", "", text)


def _cases():
    row_start, row_end = _first_row("drag")
    yield (
        "unsorted-alpha",
        TEXT.replace("alpha_deg: [0.0, 10.0, 20.0,", "alpha_deg: [0.0, 20.0, 10.0,"),
        ["entry_aerodynamics.alpha_deg.2", "strictly increasing", f":{_line_of(TEXT, 'alpha_deg: [')}:"],
    )
    yield (
        "mismatched-rows",
        TEXT[:row_start] + TEXT[row_end + 1 :],
        ["entry_aerodynamics.coefficients.drag", "expected 8 rows (one per alpha_deg), got 7"],
    )
    yield (
        "mismatched-columns",
        TEXT[:row_start] + TEXT[row_start:row_end].replace(", 0.08400]", "]") + TEXT[row_end:],
        ["entry_aerodynamics.coefficients.drag.0", "expected 9 values (one per mach), got 8"],
    )
    yield (
        "missing-derivative",
        _drop_block(TEXT, "pitch_per_elevon_rad"),
        ["entry_aerodynamics.coefficients", "'pitch_per_elevon_rad' is required"],
    )
    yield (
        "blocked-outside-limits",
        TEXT.replace("    max_deg: 40.0 ", "    blocked: {flap: left, deflection_deg: 45.0}\n    max_deg: 40.0 "),
        ["surfaces.body_flaps.blocked.deflection_deg", "within the flap limits [-10.0, 40.0] deg, got 45.0"],
    )
    yield (
        "rudders-without-rudders",
        re.sub(r"\n  rudders: .*", "", TEXT),
        ["entry_aerodynamics.coefficients.roll_per_rudder_rad", "the vehicle has no rudders"],
    )
    yield (
        "surfaces-without-atmosphere",
        TEXT.replace("atmosphere: ussa1976 ", "# no atmosphere "),
        ["surfaces", "need an atmosphere", f":{_line_of(TEXT, 'surfaces:')}:"],
    )
    yield (
        "hinge-half-given",
        re.sub(r"\n    hinge_area_arm_m3: .*", "", TEXT),
        ["surfaces.body_flaps", "both hinge_moment_max_n_m and hinge_area_arm_m3, or neither"],
    )
    # the surfaces' actuators and the entry controller (vehicle-file keys, not code defaults)
    yield (
        "flap-rate-missing",
        TEXT.replace("    rate_max_deg_s: 20.0\n", ""),
        ["surfaces.body_flaps", "rate_max_deg_s", f":{_line_of(TEXT, '  body_flaps:')}:"],
    )
    yield (
        "rudder-rate-zero",
        TEXT.replace("usable_below_mach: 6.0, rate_max_deg_s: 20.0}", "usable_below_mach: 6.0, rate_max_deg_s: 0.0}"),
        ["surfaces.rudders.rate_max_deg_s", f":{_line_of(TEXT, '  rudders: {')}:"],
    )
    yield (
        "negative-lag",
        TEXT.replace("  time_constant_s: 0.1", "  time_constant_s: -0.1"),
        ["surfaces.time_constant_s", f":{_line_of(TEXT, '  time_constant_s:')}:"],
    )
    yield (
        "angle-gains-of-two-axes",
        TEXT.replace("angle_gain_1_s: [1.0, 1.0, 1.0]", "angle_gain_1_s: [1.0, 1.0]"),
        ["entry_control.angle_gain_1_s", f":{_line_of(TEXT, '  angle_gain_1_s:')}:"],
    )
    yield (
        "negative-integral-gain",
        TEXT.replace("integral_gain_1_s: 0.2", "integral_gain_1_s: -0.2"),
        ["entry_control.integral_gain_1_s", f":{_line_of(TEXT, '  integral_gain_1_s:')}:"],
    )
    yield (
        "misspelt-controller-key",
        TEXT.replace("align_limit_deg: 10.0", "align_limit_degs: 10.0"),
        ["entry_control", "align_limit_degs"],
    )
    yield (
        "surfaces-without-controller",
        TEXT[: TEXT.index("entry_control:")],
        ["surfaces", "need the entry controller's gains", f":{_line_of(TEXT, 'surfaces:')}:"],
    )
    no_surfaces = TEXT[: TEXT.index("surfaces:")] + TEXT[TEXT.index("entry_control:") :]
    yield (
        "controller-without-surfaces",
        no_surfaces,
        ["entry_control", "the vehicle has none", f":{_line_of(no_surfaces, 'entry_control:')}:"],
    )
    yield (
        "unknown-atmosphere",
        TEXT.replace("atmosphere: ussa1976 ", "atmosphere: mars "),
        ["atmosphere", "expected one of ussa1976"],
    )


CASES = list(_cases())


@pytest.mark.parametrize("case", CASES, ids=[c[0] for c in CASES])
def test_bad_entry_input_is_exit_2_with_file_line_and_key_path(case, tmp_path):
    _, text, words = case
    path = tmp_path / "x38-bad.yaml"
    path.write_text(text)
    result = CliRunner().invoke(main, ["validate", str(path)])
    assert result.exit_code == 2, result.output
    assert "Traceback" not in result.output
    message = result.output.strip()
    assert re.search(rf"{re.escape(str(path))}:\d+: ", message), message
    for word in words:
        assert word in message, f"{word!r} not in {message!r}"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["x38-bad.yaml"]


def test_a_vehicle_without_rudders_and_their_derivatives_is_valid(tmp_path):
    path = tmp_path / "x38-no-rudders.yaml"
    path.write_text(_without_rudders())
    vehicle = load_vehicle(path)
    packed = entry.coefficient_array(vehicle["entry_aerodynamics"])
    assert np.all(packed[aerodynamics.AC_YAW_RUDDER] == 0.0)


def test_propellant_weights_are_the_least_thrust_per_moment_over_isp_g0():
    """003 eq. 5's b_th K_i: HiGHS's least total thrust for a unit moment about each axis, over
    Isp g0 (both solve the same LP: 1e-9 relative)."""
    from scipy.optimize import linprog

    from refexmc.config.derived import torque_arms

    vehicle = load_vehicle(X38)
    arms = torque_arms(vehicle).T
    weights = entry.propellant_weights(vehicle)
    for axis in range(3):
        unit = np.eye(3)[axis]
        least = linprog(np.ones(arms.shape[1]), A_eq=arms, b_eq=unit, bounds=[(0.0, None)] * arms.shape[1]).fun
        assert weights[axis] == pytest.approx(least / (220.0 * 9.80665), rel=1e-9)
    # pitch: a down-firing pair 4 m aft gives 8 N m for 2 N, rolls cancelling: 1/4 N per N m
    assert weights[1] * 220.0 * 9.80665 == pytest.approx(0.25, rel=1e-12)


def test_inspect_shows_what_the_entry_flies():
    """``refexmc inspect`` of an entry vehicle prints its entry part: the RCS's pure moment and the
    propellant per N m that the blending weighs, checked against scipy's linprog on the thrusters
    written out here (HiGHS optimum: 1e-9 relative), and the flap's hinge-limited reach, checked
    against the hinge moment 2 q S_f c sin^2(alpha + delta) of 003 Table 1's limit (1e-9)."""
    from scipy.optimize import linprog

    result = CliRunner().invoke(main, ["inspect", str(X38), "--json"])
    assert result.exit_code == 0, result.output
    shown = json.loads(result.output)["entry"]
    vehicle = load_vehicle(X38)
    rcs = vehicle["rcs"]
    moments = (
        np.array(
            [
                np.cross(t["position_m"], np.asarray(t["direction"]) / np.linalg.norm(t["direction"]))
                for t in rcs["thrusters"]
            ]
        ).T
        - np.cross(vehicle["com_offset_m"], np.zeros(3))[:, None]
    )
    thrust = max(rcs["thrust_n"].values())
    for axis in range(3):
        others = [k for k in range(3) if k != axis]
        most = linprog(-moments[axis], A_eq=moments[others], b_eq=[0.0, 0.0], bounds=[(0.0, thrust)] * moments.shape[1])
        assert shown["rcs_capacity_n_m"][axis] == pytest.approx(-most.fun, rel=1e-9)
        unit = np.eye(3)[axis]
        least = linprog(np.ones(moments.shape[1]), A_eq=moments, b_eq=unit, bounds=[(0.0, None)] * moments.shape[1])
        assert shown["propellant_kg_s_per_n_m"][axis] == pytest.approx(least.fun / (rcs["isp_s"] * 9.80665), rel=1e-9)
    flaps = vehicle["surfaces"]["body_flaps"]
    reach = shown["flap_hinge_reach_deg"]
    alpha = math.radians(reach["alpha_deg"])

    def hinge_moment(q, deflection_deg):
        return 2.0 * q * flaps["hinge_area_arm_m3"] * math.sin(alpha + math.radians(deflection_deg)) ** 2

    q_bind = reach["binds_above_qbar_pa"]
    assert hinge_moment(q_bind, flaps["max_deg"]) == pytest.approx(flaps["hinge_moment_max_n_m"], rel=1e-9)
    for q, deflection in zip(reach["qbar_pa"], reach["deflection_deg"], strict=True):
        if q <= q_bind:
            assert deflection == flaps["max_deg"]
        else:
            assert deflection < flaps["max_deg"]
            assert hinge_moment(q, deflection) == pytest.approx(flaps["hinge_moment_max_n_m"], rel=1e-9)
    text = CliRunner().invoke(main, ["inspect", str(X38)]).output
    assert "entry flight" in text
    printed = re.search(r"limits the flap above q ([0-9.]+) kPa", text)
    assert float(printed[1]) == pytest.approx(q_bind / 1e3, abs=0.05)  # printed to 0.1 kPa
    assert "entry flight" not in CliRunner().invoke(main, ["inspect", "configs/vehicles/refex.yaml"]).output
