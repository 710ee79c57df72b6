"""Design checks (issue 26): well-formed files that describe a design that cannot fly as meant.

Each case is one mistake a new user made on an own spacecraft, written into a copy of a shipped
file; errors exit 2 with file, line and key path, warnings carry their numbers, --strict makes them
errors. The shipped files validate without a warning.
"""

import json
import math
from pathlib import Path

import pytest
import yaml
from click.testing import CliRunner
from stored import campaign_copy

from refexmc.cli import main, residue_free, shown
from refexmc.config import derived
from refexmc.config.load import load_vehicle

ROOT = Path(__file__).resolve().parents[1]
GENERIC = ROOT / "configs/vehicles/generic-12.yaml"
REFEX = ROOT / "configs/vehicles/refex.yaml"


def invoke(*args):
    result = CliRunner().invoke(main, [str(a) for a in args])
    assert "Traceback" not in result.output, result.output
    assert result.exception is None or isinstance(result.exception, SystemExit), result.exception
    return result


def edited(tmp_path, source, *replacements, name="vehicle.yaml"):
    text = source.read_text()
    for old, new in replacements:
        assert old in text, old
        text = text.replace(old, new)
    path = tmp_path / name
    path.write_text(text)
    return path


def line_of(path, needle):
    """1-based line of the first line of ``path`` containing ``needle``."""
    return next(i for i, line in enumerate(Path(path).read_text().splitlines(), 1) if needle in line)


# --- errors ------------------------------------------------------------------------------------


def test_swapped_allocation_signs_are_an_error_with_file_line_and_key(tmp_path):
    """'+x' opening the -x couple turns the body the wrong way: every flight would fail."""
    path = edited(tmp_path, GENERIC, ('"+x": [1, 2]', '"+x": [3, 4]'), ('"-x": [3, 4]', '"-x": [1, 2]'))
    result = invoke("validate", path)
    assert result.exit_code == 2
    message = result.output.strip()
    line = line_of(path, '"+x": [3, 4]')
    assert message.startswith(f"error: {path}:{line}: flight_software.allocation.+x: ")
    # thrusters 3 and 4: 1 N each at 0.5 m, derated x1 -> -1 N m about x at low thrust
    assert (
        "thrusters 3, 4 give [-1, 0, 0] N m at low thrust" in message and "expected positive torque about x" in message
    )
    assert len(message.splitlines()) == 1


def test_an_entry_that_gives_no_torque_about_its_axis_is_an_error(tmp_path):
    """'+z' opening a y-couple: no torque about z at all."""
    path = edited(tmp_path, GENERIC, ('"+z": [9, 10]', '"+z": [5, 6]'))
    result = invoke("validate", path)
    assert result.exit_code == 2
    line = line_of(path, '"+z": [5, 6]')
    assert f"{path}:{line}: flight_software.allocation.+z: entry '+z' realises no torque about z" in result.output


@pytest.mark.parametrize(("direction", "norm"), [("[0.0, 2.0, 0.0]", "2"), ("[0.0, 1.0, 0.3]", "1.044")])
def test_a_thruster_direction_that_is_not_a_unit_vector_is_an_error(tmp_path, direction, norm):
    path = edited(
        tmp_path,
        GENERIC,
        (
            "position_m: [0.5, 0.0, 0.0], direction: [0.0, 1.0, 0.0]}",
            f"position_m: [0.5, 0.0, 0.0], direction: {direction}}}",
        ),
    )
    result = invoke("validate", path)
    assert result.exit_code == 2
    line = line_of(path, direction)
    assert f"error: {path}:{line}: rcs.thrusters.8.direction: expected a unit force direction" in result.output
    assert f"of norm {norm};" in result.output


def test_a_direction_rounded_to_four_digits_is_accepted_and_normalised(tmp_path):
    """[0.7071, 0.7071, 0] has norm 0.99999: rounded digits, not a mistake (within the 1e-3 tolerance)."""
    path = edited(
        tmp_path,
        GENERIC,
        (
            "position_m: [0.5, 0.0, 0.0], direction: [0.0, 1.0, 0.0]}",
            "position_m: [0.5, 0.0, 0.0], direction: [0.7071, 0.7071, 0.0]}",
        ),
    )
    assert invoke("validate", "--strict", path).exit_code == 0
    assert derived.unit_directions(load_vehicle(path))[8] == pytest.approx(
        [math.sqrt(0.5), math.sqrt(0.5), 0.0], rel=1e-12
    )


# --- warnings ----------------------------------------------------------------------------------


def single_thruster_entries(tmp_path):
    """generic-12 whose single-axis entries on x and y open one thruster, n_t still [2, 2, 2]."""
    return edited(
        tmp_path,
        GENERIC,
        ('"+x": [1, 2]', '"+x": [1]'),
        ('"-x": [3, 4]', '"-x": [3]'),
        ('"+y": [5, 6]', '"+y": [5]'),
        ('"-y": [7, 8]', '"-y": [7]'),
    )


WARNING_CASES = {
    "thrusters-per-axis": (
        single_thruster_entries,
        "thrusters_per_axis: [2, 2, 2]",
        "flight_software.thrusters_per_axis.0: thrusters_per_axis x is 2, but the allocation's '+x' entry realises "
        "1.00 thrusters' torque about x (derated, at the lever arm 0.5 m): omega_dot_max, tau_max and derived "
        "gains on x (000 eq. 1, 38) assume 2.00 x what the thrusters give",
    ),
    "t-on-below-min-on": (
        lambda tmp: edited(tmp, GENERIC, ("t_on_ms: 30.0", "t_on_ms: 5.0")),
        "t_on_ms: 5.0",
        "flight_software.pwpf.t_on_ms: the modulator's shortest pulse t_on - correction = 5 - 2.5 = 2.5 ms is "
        "below the hardware min_on 25 ms",
    ),
    "min-on-below-the-period": (
        lambda tmp: edited(tmp, GENERIC, ("min_on: 25.0", "min_on: 10.0"), ("t_on_ms: 30.0", "t_on_ms: 12.5")),
        "min_on: 10.0",
        "rcs.switching_limits_ms.min_on: min_on 10 ms is shorter than the 25 ms control period: valves switch on "
        "the control grid, so the shortest pulse is 25 ms",
    ),
    "min-off-between-periods": (
        lambda tmp: edited(tmp, GENERIC, ("min_off: 50.0", "min_off: 60.0")),
        "min_off: 60.0",
        "rcs.switching_limits_ms.min_off: min_off 60 ms is not a whole number of 25 ms control periods: valves "
        "switch on the control grid, so the shortest rest is 75 ms",
    ),
}


@pytest.mark.parametrize("case", list(WARNING_CASES))
def test_vehicle_design_warnings_carry_their_numbers_and_strict_makes_them_errors(tmp_path, case):
    make, needle, expected = WARNING_CASES[case]
    path = make(tmp_path)
    where = f"{path}:{line_of(path, needle)}: "
    loose = invoke("validate", path)
    assert loose.exit_code == 0, loose.output
    assert f"warning: {where}{expected}" in loose.output, loose.output
    assert "valid vehicle, 1 design warning" in loose.output or "design warnings" in loose.output
    strict = invoke("validate", "--strict", path)
    assert strict.exit_code == 2 and f"error: {where}{expected}" in strict.output
    inspected = invoke("inspect", path)
    assert inspected.exit_code == 0 and f"warning: {where}{expected}" in inspected.output
    assert invoke("inspect", "--strict", path).exit_code == 2


def deadband_campaign(tmp_path, threshold):
    """generic-slew with its detumble exit at ``threshold`` deg/s (the file: 0.15)."""
    mission = edited(
        tmp_path,
        ROOT / "configs/missions/generic-slew.yaml",
        ("rates_below_deg_s: 0.15", f"rates_below_deg_s: {threshold}"),
        name="mission.yaml",
    )
    original = str(ROOT / "configs/missions/generic-slew.yaml")
    return campaign_copy("generic-slew.yaml", tmp_path, replace=[(original, str(mission))]), mission


def test_an_exit_threshold_inside_the_rate_deadband_warns_with_the_deadband(tmp_path):
    """generic-12 at low thrust: tau_min = 0.05 * 2 N * 0.5 m = 0.05 N m, Kd = [36, 48, 54] N m s
    (pd: no J), so rates below 0.05 / Kd = [0.0796, 0.0597, 0.0531] deg/s fire no valve."""
    kd = [36.0, 48.0, 54.0]
    band = [math.degrees(0.05 / k) for k in kd]
    campaign, mission = deadband_campaign(tmp_path, 0.07)
    result = invoke("validate", campaign)
    assert result.exit_code == 0, result.output
    line = line_of(mission, "rates_below_deg_s: 0.07")
    expected = (
        f"warning: {mission}:{line}: modes.0.exit.0.rates_below_deg_s: rates_below_deg_s 0.07 lies inside the "
        f"controller's rate deadband at low thrust [{band[0]:.3g}, {band[1]:.3g}, {band[2]:.3g}] deg/s"
    )
    assert expected in result.output, result.output
    assert "on x, no valve fires" in result.output  # 0.07 is inside x's band only
    assert invoke("validate", "--strict", campaign).exit_code == 2
    # just outside every axis' band: no warning
    (tmp_path / "ok").mkdir()
    clean, _ = deadband_campaign(tmp_path / "ok", 0.08)
    assert invoke("validate", "--strict", clean).exit_code == 0


def test_an_angle_exit_inside_the_angle_deadband_warns(tmp_path):
    """ReFEx SAM at low thrust: the angle deadband is the design's phi_db = 0.4156 deg (000 eq. 38)."""
    mission = edited(
        tmp_path,
        ROOT / "configs/missions/refex-exo.yaml",
        ("angle_error_below_deg: 1.0", "angle_error_below_deg: 0.3"),
        name="mission.yaml",
    )
    campaign = campaign_copy(
        "smoke.yaml", tmp_path, replace=[(str(ROOT / "configs/missions/refex-exo.yaml"), str(mission))]
    )
    result = invoke("validate", campaign)
    assert result.exit_code == 0, result.output
    assert (
        "modes.2.exit.0.angle_error_below_deg: angle_error_below_deg 0.3 lies inside the controller's angle "
        "deadband at low thrust [0.416, 0.416, 0.416] deg" in result.output
    )


def test_run_prints_the_warnings_records_them_in_the_manifest_and_strict_writes_nothing(tmp_path):
    campaign, _ = deadband_campaign(tmp_path, 0.07)
    refused = tmp_path / "refused"
    strict = invoke("run", campaign, "-o", refused, "--runs", "1", "-j", "1", "--no-progress", "--strict")
    assert strict.exit_code == 2 and "--strict: design warnings are errors" in strict.output
    assert not refused.exists()
    out = tmp_path / "out"
    flown = invoke("run", campaign, "-o", out, "--runs", "1", "-j", "1", "--no-progress")
    assert flown.exit_code == 0, flown.output
    assert "warning: " in flown.output and "rates_below_deg_s 0.07 lies inside" in flown.output
    # the warning was real: the nominal flight's rates freeze inside the deadband, the detumble
    # times out; the summary speaks of the flight stopping, not of a hand-over it does not have
    assert "flight: FAILED (detumble_timeout), flight stopped at t = 120.0 s" in flown.output
    assert "hand-over" not in flown.output
    manifest = json.loads((out / "manifest.json").read_text())
    assert len(manifest["design_warnings"]) == 1 and "rates_below_deg_s 0.07" in manifest["design_warnings"][0]


# their design and plausibility warnings (config.plausibility, issue 34): none
SHIPPED = sorted(ROOT.glob("campaigns/**/*.yaml")) + sorted(ROOT.glob("configs/*/*.yaml"))


@pytest.mark.parametrize("path", SHIPPED, ids=[str(p.relative_to(ROOT)) for p in SHIPPED])
def test_shipped_files_validate_without_design_warnings(path):
    result = invoke("validate", "--strict", path)
    assert result.exit_code == 0 and "warning" not in result.output, result.output


# --- inspect -----------------------------------------------------------------------------------


def printed_numbers(text, label):
    """The comma-separated numbers printed after ``label`` (up to a ';' or the line's end)."""
    line = next(line for line in text.splitlines() if label in line)
    return [float(v) for v in line.split(label, 1)[1].split(";")[0].split(",")]


def test_a_rounding_residue_prints_as_zero():
    """A component below the printed rounding of the vector's largest is 0, not 1.10093e-16 (the
    residue an AVX-512 BLAS left in the realised torque, issue 32), and -0.0000 has no sign; a
    small component above the rounding is kept."""
    assert shown([1.10093e-16, 20.5115, 0.0], ".6g") == "0, 20.5115, 0"
    assert shown([-3e-17, 0.25, -4e-5], "8.4f", " ") == "  0.0000   0.2500   0.0000"
    assert residue_free([1.0, 4.9e-6, 5.1e-6, -2e-7], ".6g") == [1.0, 0.0, 5.1e-6, 0.0]
    assert residue_free([2e-4, 1e-21, None], "10.4g") == [2e-4, 0.0, None]
    assert residue_free([0.0, 1e-300], ".6g") == [0.0, 1e-300]  # alone, a small value is no residue


def test_inspect_torque_derates_the_open_valves():
    """refex high thrust, +y: 000 Table 3 opens thrusters 1, 2, 7, each 8.92 N at 1.05 m from the
    CoM along x, derated to 0.73 with three valves open (000 sec. 2.1): 3 x 8.92 x 1.05 x 0.73 =
    20.51 N m, not the 28.098 N m of full thrust."""
    vehicle = yaml.safe_load(REFEX.read_text())
    ids = vehicle["flight_software"]["allocation"]["+y"]
    thrust, derating = vehicle["rcs"]["thrust_n"]["high"], vehicle["rcs"]["derating"][len(ids) - 1]
    arm = -vehicle["rcs"]["thrusters"][ids[0] - 1]["position_m"][0]  # r x F about y for a +z force at x = -1.05
    hand = len(ids) * thrust * arm * derating
    assert hand == pytest.approx(20.51, abs=0.005)
    result = invoke("inspect", REFEX, "--torque", "0,1,0", "--level", "high")
    assert result.exit_code == 0
    assert "3 valves open, thrust derated x0.73" in result.output
    # numbers, not strings of floats: 6 significant digits printed, so within 5e-6 relative
    assert printed_numbers(result.output, "realised torque [N m]:") == pytest.approx([0.0, hand, 0.0], rel=5e-6, abs=0)
    as_json = json.loads(invoke("inspect", REFEX, "--torque", "0,1,0", "--level", "high", "--json").output)
    assert as_json["allocation"]["realised_torque_n_m"][1] == pytest.approx(hand, rel=1e-12)
    assert as_json["allocation"]["derating"] == derating


def test_inspect_prints_the_deadbands_of_000_eq_38_per_axis_and_level():
    """With derived gains the angle deadband is the design's phi_db (000 eq. 38 solved for the
    angle), and the rate deadband is tau_min / (J Kd) = 0.35 omega_dot_max / (2 sqrt(Kp)) (eq. 34),
    computed here from the vehicle file alone."""
    vehicle = yaml.safe_load(REFEX.read_text())
    info = json.loads(invoke("inspect", REFEX, "--json").output)
    fsw = vehicle["flight_software"]
    inertia = [vehicle["inertia_kg_m2"][i][i] for i in range(3)]
    arms = [0.171, 1.05, 1.05]  # largest |r x d| per axis of the thruster table: y of 2/3, x of all
    for level, thrust in vehicle["rcs"]["thrust_n"].items():
        accel = [arms[i] * fsw["thrusters_per_axis"][i] * thrust / inertia[i] for i in range(3)]
        kp = [0.35 * a / math.sin(math.radians(fsw["deadband_angle_deg"]) / 2) for a in accel]
        rate = [math.degrees(0.35 * a / (2 * math.sqrt(k))) for a, k in zip(accel, kp, strict=True)]
        assert info["deadbands"][level]["rate_deg_s"] == pytest.approx(rate, rel=1e-12)
        assert info["deadbands"][level]["angle_deg"] == pytest.approx([fsw["deadband_angle_deg"]] * 3, rel=1e-12)
    text = invoke("inspect", REFEX).output
    assert "rate deadband [deg/s]         0.1958    0.1391    0.0976   tau_min / (J Kd)" in text
    assert "angle deadband [deg]          0.4156    0.4156    0.4156" in text


def test_inspect_prints_the_minimum_impulse_bit():
    """generic-12, low thrust: a 25 ms pulse through 5 ms delays, a 2 ms rise and a 5 ms fall gives
    (25 + 5 - 7) + (2 + 5) / 2 = 26.5 ms of full thrust; '+x' is a 1 N couple at 0.5 m (1 N m):
    0.0265 N m s, over J_xx = 60 kg m^2."""
    info = json.loads(invoke("inspect", GENERIC, "--json").output)
    bit = info["minimum_impulse_bit"]["low"]
    assert bit["n_m_s"] == pytest.approx([0.0265] * 3, rel=1e-12)
    assert bit["rate_deg_s"] == pytest.approx([math.degrees(0.0265 / j) for j in (60.0, 80.0, 90.0)], rel=1e-12)
    assert info["allocation_torque_n_m"]["high"]["-z"] == pytest.approx([0.0, 0.0, -4.0])


# --- messages ----------------------------------------------------------------------------------


def test_dispersing_an_undeclared_thrust_level_lists_the_declared_ones(tmp_path):
    """A vehicle whose one level is 'nominal': dispersing rcs.thrust_n.low names what it has."""
    vehicle = edited(
        tmp_path,
        GENERIC,
        ("thrust_n: {low: 1.0, high: 4.0}", "thrust_n: {nominal: 1.0}"),
        (
            "    low: {on_delay: 5.0, rise: 2.0, off_delay: 5.0, fall: 5.0}\n",
            "    nominal: {on_delay: 5.0, rise: 2.0, off_delay: 5.0, fall: 5.0}\n",
        ),
        ("    high: {on_delay: 5.0, rise: 2.0, off_delay: 5.0, fall: 5.0}\n", ""),
        ("kp: {low: [10.8, 14.4, 16.2], high: [10.8, 14.4, 16.2]}", "kp: {nominal: [10.8, 14.4, 16.2]}"),
        ("kd: {low: [36.0, 48.0, 54.0], high: [36.0, 48.0, 54.0]}", "kd: {nominal: [36.0, 48.0, 54.0]}"),
    )
    campaign = campaign_copy(
        "generic-slew.yaml",
        tmp_path,
        replace=[
            (str(GENERIC), str(vehicle)),
            ("dispersions:\n", "dispersions:\n  rcs.thrust_n.low: {dist: normal, sigma: 0.01}\n"),
        ],
    )
    result = invoke("validate", campaign)
    assert result.exit_code == 2
    line = line_of(campaign, "rcs.thrust_n.low")
    assert result.output.strip() == (
        f"error: {campaign}:{line}: dispersions.rcs.thrust_n.low: 'rcs.thrust_n.low': the vehicle file does not "
        "declare it; rcs.thrust_n declares: nominal"
    )


def test_a_vehicle_without_torque_about_its_axes_validates_clean(tmp_path):
    """Thrusters through the centre of mass (a translation-only lander): every allocation entry
    empty and no gains. Empty entries are no sign error, n_t describes no torque, and a rate exit
    threshold has no deadband to lie in (the controller never acts): no error, no warning."""
    text = GENERIC.read_text()
    start, end = text.index("  allocation:"), len(text)
    keys = ["+x", "-x", "+y", "-y", "+z", "-z", "+x+y", "+x-y", "-x+y", "-x-y", "+x+z", "+x-z", "-x+z", "-x-z"]
    keys += ["+y+z", "+y-z", "-y+z", "-y-z"]
    empty = "  allocation: {" + ", ".join(f'"{k}": []' for k in keys) + "}\n"
    vehicle = tmp_path / "vehicle.yaml"
    vehicle.write_text(
        (text[:start] + empty + text[end:])
        .replace("kp: {low: [10.8, 14.4, 16.2], high: [10.8, 14.4, 16.2]}", "kp: {low: [0, 0, 0], high: [0, 0, 0]}")
        .replace("kd: {low: [36.0, 48.0, 54.0], high: [36.0, 48.0, 54.0]}", "kd: {low: [0, 0, 0], high: [0, 0, 0]}")
    )
    campaign = campaign_copy("generic-slew.yaml", tmp_path, replace=[(str(GENERIC), str(vehicle))])
    result = invoke("validate", "--strict", vehicle, campaign)
    assert result.exit_code == 0 and "warning" not in result.output, result.output
    inspected = json.loads(invoke("inspect", vehicle, "--json").output)
    assert inspected["deadbands"]["low"] == {"rate_deg_s": [None] * 3, "angle_deg": [None] * 3}
    assert invoke("inspect", vehicle).exit_code == 0
