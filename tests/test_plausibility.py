"""Plausibility checks (config.plausibility, issue 34 point 6): one test per check.

Each slip is written as a new user would (a shipped file with one value in another unit) and must
give a warning at the file, line and key path of that value, with the value and the likely slip;
the shipped file itself gives none. ``--strict`` refusing them is tested in test_bad_input.py.
"""

import math
from pathlib import Path

import pytest

from refexmc.config import plausibility
from refexmc.config.errors import ConfigError
from refexmc.config.load import load_campaign, load_mission, load_vehicle

ROOT = Path(__file__).resolve().parents[1]
SURVEYOR = ROOT / "configs/vehicles/cold-gas-surveyor.yaml"
REFEX = ROOT / "configs/vehicles/refex.yaml"
REGULATED = ROOT / "configs/vehicles/refex-blow-down.yaml"
HOP = ROOT / "configs/missions/surveyor-hop.yaml"
X38_ENTRY = ROOT / "configs/missions/x38-entry.yaml"


def _variant(tmp_path, source, old, new, name=None):
    """``source`` with ``old`` replaced by ``new`` (once), written to tmp_path; (path, the edited line)."""
    text = source.read_text()
    assert text.count(old) == 1, old
    path = tmp_path / (name or source.name)
    path.write_text(text.replace(old, new))
    line = text[: text.index(old)].count("\n") + 1
    return path, line


def _vehicle_warnings(path):
    found = []
    load_vehicle(path, found)
    return [w for w in found if isinstance(w, plausibility.PlausibilityWarning)]


def _campaign(tmp_path, vehicle, mission=HOP, dispersions=""):
    path = tmp_path / "campaign.yaml"
    path.write_text(
        f"name: my-variant\nvehicle: {vehicle}\nmission: {mission}\nruns: 5\nseed: 1\n"
        + (f"dispersions:\n{dispersions}" if dispersions else "")
    )
    return path


def _one(warnings, path, line, key):
    assert len(warnings) == 1, [str(w) for w in warnings]
    warning = warnings[0]
    assert (warning.file, warning.line, ".".join(map(str, warning.path))) == (path, line, key), str(warning)
    return warning.message


@pytest.mark.parametrize(
    ("old", "new", "key", "words"),
    [
        ("temperature_k: 293.0", "temperature_k: 20.0", "rcs.feed.temperature_k", ["20 K", "degC"]),
        ("temperature_k: 293.0", "temperature_k: 1500.0", "rcs.feed.temperature_k", ["1500 K", "<= 1000 K"]),
        ("initial_pressure_pa: 5.0e6", "initial_pressure_pa: 50.0", "rcs.feed.initial_pressure_pa", ["50 Pa", "bar"]),
        ("gas_constant_j_kg_k: 296.8", "gas_constant_j_kg_k: 28.0", "rcs.feed.gas_constant_j_kg_k", ["molar mass"]),
        ("tank_volume_m3: 0.001", "tank_volume_m3: 20.0", "rcs.feed.tank_volume_m3", ["20 m^3", "litres"]),
        ("throat_area_m2: 1.2e-7", "throat_area_m2: 0.12", "rcs.feed.throat_area_m2", ["0.12 m^2", "mm^2"]),
        ("on_delay: 5.0", "on_delay: 0.005", "rcs.valve_time_constants_ms.low.on_delay", ["0.005 ms", "in s?"]),
        ("min_on: 10.0", "min_on: 0.01", "rcs.switching_limits_ms.min_on", ["0.01 ms", "in s?"]),
        (
            "expansion_ratio: 50.0",
            "expansion_ratio: 50.0\n    ambient_pressure_pa: 1.013",
            "rcs.feed.ambient_pressure_pa",
            ["1.013 Pa: a pressure in bar"],
        ),
        ("mass_kg: 20.0", "mass_kg: 20000.0", "mass_kg", ["a mass in g?", "denser than solid steel"]),
        ("mass_kg: 20.0", "mass_kg: 0.02", "inertia_kg_m2", ["a mass in t?"]),
    ],
    ids=[
        "temperature-in-degC",
        "temperature-too-hot",
        "pressure-in-bar",
        "gas-constant-as-molar-mass",
        "volume-in-litres",
        "throat-in-mm2",
        "ambient-in-bar",
        "valve-delay-in-s",
        "switching-limit-in-s",
        "mass-in-g",
        "mass-in-t",
    ],
)
def test_a_unit_slip_in_the_vehicle_warns_at_its_key_with_the_likely_slip(tmp_path, old, new, key, words):
    assert _vehicle_warnings(SURVEYOR) == []
    path, line = _variant(tmp_path, SURVEYOR, old, new)
    if key in ("inertia_kg_m2", "rcs.feed.ambient_pressure_pa"):
        line += 1  # the line below the edited one: the matrix below the mass, the added key
    at_key = [w for w in _vehicle_warnings(path) if ".".join(map(str, w.path)) == key]
    message = _one(at_key, path, line, key)  # 20 m^3 also holds more gas than the vehicle's mass
    for word in words:
        assert word in message, (word, message)


def test_the_ball_density_is_that_of_a_uniform_ball():
    """A uniform ball of radius r and density rho: m = (4/3) pi r^3 rho, J = (2/5) m r^2 about any
    axis (closed form): ball() recovers r and rho to rounding."""
    radius, density = 0.7, 2700.0
    mass = 4.0 / 3.0 * math.pi * radius**3 * density
    moment = 0.4 * mass * radius**2
    got = plausibility.ball(mass, [[moment, 0, 0], [0, moment, 0], [0, 0, moment]])
    assert got == pytest.approx((radius, density), rel=1e-12)


def test_the_gas_a_tank_holds_beyond_the_vehicle_mass_warns(tmp_path):
    """P V / (R T) = 5e6 * 2 / (296.8 * 293) = 115 kg of nitrogen in a 20 kg vehicle (2 m^3 is
    below the volume bound, so only the gas mass says it)."""
    path, line = _variant(tmp_path, SURVEYOR, "tank_volume_m3: 0.001", "tank_volume_m3: 2.0")
    message = _one(_vehicle_warnings(path), path, line - 2, "rcs.feed")  # the feed block's line
    assert "115 kg of gas" in message and "mass_kg 20" in message


def test_thruster_positions_in_mm_warn(tmp_path):
    """Every ReFEx position in mm: the geometry's signs hold; one warning names the first and counts the rest."""
    text = REFEX.read_text()
    for metres, mm in (("-1.05", "-1050.0"), ("-0.171", "-171.0"), ("0.171", "171.0")):
        text = text.replace(f"{metres},", f"{mm},")
    path = tmp_path / "refex.yaml"
    path.write_text(text)
    assert _vehicle_warnings(REFEX) == []
    warnings = _vehicle_warnings(path)
    assert [w.path for w in warnings] == [("rcs", "thrusters", 0, "position_m")]  # one, the first
    message = warnings[0].message
    assert "1064 m from the centre of mass (and 7 more positions)" in message
    assert "2.7 m" in message and "in mm or cm?" in message


def test_one_position_in_mm_that_breaks_the_allocation_is_refused_at_the_position(tmp_path):
    """One thruster in mm turns an allocation entry's torque (a derived error): refused at the
    position the user typed, the allocation's error after it."""
    path, line = _variant(
        tmp_path,
        REFEX,
        "position_m: [-1.05, -0.171, 0.0], direction: [0.0, 0.0, 1.0]",
        "position_m: [-1050.0, -171.0, 0.0], direction: [0.0, 0.0, 1.0]",
    )
    with pytest.raises(ConfigError) as caught:
        load_vehicle(path)
    error = caught.value
    assert (error.file, error.line, error.path) == (path, line, ("rcs", "thrusters", 0, "position_m"))
    assert "in mm or cm?" in error.message and "flight_software.allocation" in error.message


@pytest.mark.parametrize(
    ("old", "new", "key", "words"),
    [
        ("  isp_s: 70.0", "  isp_s: 0.69", "rcs.isp_s", ["0.69 s: an exhaust velocity in km/s?"]),
        ("  propellant_kg: 0.76", "  propellant_kg: 760.0", "rcs.propellant_kg", ["760 kg of propellant", "in g"]),
    ],
    ids=["isp-as-km-per-s", "propellant-in-g"],
)
def test_a_propellant_slip_warns(tmp_path, old, new, key, words):
    path, line = _variant(tmp_path, REFEX, old, new)
    message = _one(_vehicle_warnings(path), path, line, key)
    for word in words:
        assert word in message, (word, message)


def test_a_reserve_in_bar_warns_in_the_mission(tmp_path):
    found = []
    load_mission(HOP, found)
    assert found == []
    path, line = _variant(tmp_path, HOP, "reserve_pressure_pa: 1.0e6", "reserve_pressure_pa: 10.0")
    load_mission(path, found)
    assert "10 Pa: a pressure in bar" in _one(found, path, line, "local.reserve_pressure_pa")


def test_an_alpha_schedule_in_radians_warns(tmp_path):
    text = X38_ENTRY.read_text()
    for deg, rad in (("20.0", "0.35"), ("30.0", "0.52"), ("40.0", "0.7")):
        text = text.replace(f"alpha_deg: {deg}}}", f"alpha_deg: {rad}}}")
    path = tmp_path / "x38-entry.yaml"
    path.write_text(text)
    found = []
    load_mission(X38_ENTRY, found)
    assert found == []
    load_mission(path, found)
    line = text[: text.index("alpha_schedule:")].count("\n") + 1
    assert "angles in rad?" in _one(found, path, line, "entry_flight.alpha_schedule")


@pytest.mark.parametrize(
    ("spec", "bound", "words"),
    [
        ("{dist: truncnorm, sigma: 0.4, low: 25.0, high: 30.0}", "low", ["exclude the nominal 20", "near the bound"]),
        ("{dist: truncnorm, mean: 10.0, sigma: 0.4, high: 15.0}", "high", ["exclude the nominal 20"]),
        ("{dist: truncnorm, mean: 30.0, sigma: 0.4, low: 18.0, high: 22.0}", "high", ["exclude its mean 30"]),
    ],
    ids=["nominal-below-low", "nominal-above-high", "mean-above-high"],
)
def test_a_truncnorm_whose_bounds_exclude_the_nominal_warns(tmp_path, spec, bound, words):
    campaign = _campaign(tmp_path, SURVEYOR, dispersions=f"  mass_kg: {spec}\n")
    found = []
    load_campaign(campaign, found)
    message = _one(found, campaign, 7, f"dispersions.mass_kg.{bound}")
    for word in words:
        assert word in message, (word, message)


def test_a_truncnorm_about_the_nominal_and_a_uniform_band_do_not_warn(tmp_path):
    """The shipped hop's truncnorms hold their nominal; a uniform band above a placeholder nominal
    (IRASSI's noise levels over the mission's 0) is a deliberate range."""
    dispersions = (
        "  mass_kg: {dist: truncnorm, sigma: 0.4, low: 18.0}\n"
        "  navigation.attitude_noise_deg: {dist: uniform, low: 0.01, high: 0.1}\n"
    )
    found = []
    load_campaign(_campaign(tmp_path, SURVEYOR, dispersions=dispersions), found)
    assert found == []


def test_a_dispersion_that_reaches_an_implausible_value_warns(tmp_path):
    campaign = _campaign(tmp_path, SURVEYOR, dispersions="  rcs.feed.temperature_k: {dist: constant, value: 20.0}\n")
    found = []
    load_campaign(campaign, found)
    message = _one(found, campaign, 7, "dispersions.rcs.feed.temperature_k.value")
    assert "20 K: a temperature in degC?" in message


def test_a_pressure_in_bar_that_fails_the_shipped_missions_reserve_check_names_the_users_key(tmp_path):
    """The issue's slip: the reserve check lives in the shipped mission, the user edited the vehicle."""
    vehicle, line = _variant(tmp_path, SURVEYOR, "initial_pressure_pa: 5.0e6", "initial_pressure_pa: 50.0")
    with pytest.raises(ConfigError) as caught:
        load_campaign(_campaign(tmp_path, vehicle))
    error = caught.value
    assert (error.file, error.line, error.path) == (vehicle, line, ("rcs", "feed", "initial_pressure_pa"))
    assert "50 Pa: a pressure in bar" in error.message
    assert f"{HOP}:" in error.message and "local.reserve_pressure_pa" in error.message  # the check that failed


def test_an_unrelated_implausible_value_does_not_take_the_blame(tmp_path):
    """Valve delays in s (a warning) and a plausible 3 bar tank below the shipped 10 bar reserve:
    the reserve's error stays in the mission file (the delays play no part in 002 eq. 45)."""
    text = SURVEYOR.read_text().replace("initial_pressure_pa: 5.0e6", "initial_pressure_pa: 3.0e5")
    vehicle = tmp_path / "vehicle.yaml"
    vehicle.write_text(text.replace("on_delay: 5.0", "on_delay: 0.005"))
    found = []
    load_vehicle(vehicle, found)
    assert [w.path[-1] for w in found] == ["on_delay"]
    with pytest.raises(ConfigError) as caught:
        load_campaign(_campaign(tmp_path, vehicle))
    assert (caught.value.file, caught.value.path) == (HOP, ("local", "reserve_pressure_pa"))


def test_the_reserve_check_names_the_vehicle_key_of_p0(tmp_path):
    """A plausible pressure (3 bar) below the shipped reserve (10 bar): no plausibility warning to
    blame, and the mission's error still names P0's file, line and key in the vehicle."""
    vehicle, line = _variant(tmp_path, SURVEYOR, "initial_pressure_pa: 5.0e6", "initial_pressure_pa: 3.0e5")
    with pytest.raises(ConfigError) as caught:
        load_campaign(_campaign(tmp_path, vehicle))
    assert caught.value.file == HOP
    assert f"P0 = 300000 Pa at {vehicle}:{line}: rcs.feed.initial_pressure_pa" in caught.value.message


def test_a_regulated_tank_in_bar_fails_its_level_check_at_the_pressure(tmp_path):
    """ReFEx's regulated feed with 20 (bar) for 2.0e6 Pa: the full tank cannot give a level's
    thrust (a derived check), refused at the pressure the user typed."""
    path, line = _variant(tmp_path, REGULATED, "initial_pressure_pa: 2.0e6", "initial_pressure_pa: 20.0")
    with pytest.raises(ConfigError) as caught:
        load_vehicle(path)
    assert (caught.value.file, caught.value.line) == (path, line)
    assert "20 Pa: a pressure in bar" in caught.value.message and "regulated level" in caught.value.message


def test_a_missing_vehicle_file_names_the_campaign_line(tmp_path):
    campaign = _campaign(tmp_path, "no-such-vehicle.yaml")
    with pytest.raises(ConfigError) as caught:
        load_campaign(campaign)
    assert (caught.value.file, caught.value.line, caught.value.path) == (campaign, 2, ("vehicle",))
    assert "no-such-vehicle.yaml" in caught.value.message and "file not found" in caught.value.message


# every shipped campaign, vehicle and mission passes validate --strict, plausibility included:
# test_design_checks.test_shipped_files_validate_without_design_warnings


def test_a_swept_feed_value_in_another_unit_warns_at_the_axis(tmp_path):
    """A tank temperature swept to 20 (degC typed into kelvin) flies that point as the file's value:
    the same slip as in the vehicle file, named at the sweep axis' line; plausible points are silent."""
    axis = "sweep:\n  axes:\n    - parameter: rcs.feed.temperature_k\n      values: [{}]\n"
    good = _campaign(tmp_path, SURVEYOR)
    good.write_text(good.read_text() + axis.format("250.0, 293.0"))
    found = []
    load_campaign(good, found)
    assert not [w for w in found if isinstance(w, plausibility.PlausibilityWarning)]
    slip = _campaign(tmp_path, SURVEYOR)
    slip.write_text(slip.read_text() + axis.format("20.0, 293.0"))
    line = slip.read_text().splitlines().index("      values: [20.0, 293.0]") + 1
    found = []
    load_campaign(slip, found)
    message = _one(
        [w for w in found if isinstance(w, plausibility.PlausibilityWarning)], slip, line, "sweep.axes.0.values"
    )
    assert "rcs.feed.temperature_k swept to 20 K" in message and "degC" in message


def test_a_metric_named_for_another_missions_mode_suggests_this_ones(tmp_path):
    """A sweep metric 't_hop_s' on a mission whose mode is 'cross': its columns carry the mode's
    name, so the message offers 't_cross_s' (a new user's slip, copied from the hop's campaign)."""
    mission, _ = _variant(tmp_path, HOP, "  - name: hop\n", "  - name: cross\n", "my-mission.yaml")
    campaign = _campaign(tmp_path, SURVEYOR, mission)
    campaign.write_text(
        campaign.read_text()
        + "sweep:\n  axes:\n    - parameter: rcs.feed.tank_volume_m3\n      values: [0.0008, 0.0012]\n"
        + "  metrics: [t_hop_s]\n"
    )
    with pytest.raises(ConfigError, match=r"got 't_hop_s'; did you mean 't_cross_s'\?") as caught:
        load_campaign(campaign)
    assert caught.value.path == ("sweep", "metrics", 0)


def test_a_requirement_written_as_a_mapping_says_how_a_requirement_is_written(tmp_path):
    """A requirement written as a mapping of made-up keys is neither a pointing record nor a
    string: the message shows both forms, not a pointing record's key list."""
    campaign = _campaign(tmp_path, SURVEYOR)
    campaign.write_text(
        campaign.read_text() + 'requirements:\n  - {metric: position_error_end_m, stat: max, op: "<=", value: 0.05}\n'
    )
    with pytest.raises(ConfigError, match=r"'COLUMN\.STAT OP VALUE' .* or a pointing record") as caught:
        load_campaign(campaign)
    assert (caught.value.line, caught.value.path) == (7, ("requirements", 0))
