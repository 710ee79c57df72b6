"""Blow-down and regulated cold-gas feed (002 eq. 1-20; core.feed, config.feed): against the
closed forms of eq. 16, the textbook thrust coefficient and a scipy integration of the tank."""

import copy
import math
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from refexmc.cli import main
from refexmc.config import feed as config_feed
from refexmc.config.load import load_mission, load_vehicle
from refexmc.config.pack import mode_names, pack, pack_vehicle
from refexmc.core import feed, rcs
from refexmc.core import layout as L
from refexmc.core.flight import family
from refexmc.simulate import fly
from tests import naive

ROOT = Path(__file__).resolve().parents[1]
GENERIC = ROOT / "configs/vehicles/generic-12.yaml"

# a 4 l nitrogen tank at 20 bar behind 1 mm^2 throats (illustrative numbers, not a design)
NITROGEN = {
    "model": "blow_down",
    "tank_volume_m3": 0.004,
    "gas_constant_j_kg_k": 296.8,
    "heat_capacity_ratio": 1.4,
    "temperature_k": 293.0,
    "initial_pressure_pa": 20e5,
    "throat_area_m2": 1.0e-6,
    "expansion_ratio": 50.0,
}


def _vehicle(feed_block):
    vehicle = copy.deepcopy(load_vehicle(GENERIC))
    del vehicle["rcs"]["isp_s"], vehicle["rcs"]["propellant_kg"]
    vehicle["rcs"]["feed"] = dict(feed_block)
    return vehicle


def _tank(feed_block, set_pressure=math.inf):
    """The kernel's tank at t = 0; a regulated one holding ``set_pressure`` (what the loop sets
    from the level flown, layout.LV_REGULATOR_PRESSURE)."""
    tank = feed.tank()
    feed.start(pack_vehicle(_vehicle(feed_block)), tank)
    tank.state[feed.TK_REGULATOR] = set_pressure
    return tank


NO_DERATING = pack_vehicle(_vehicle(NITROGEN))  # generic-12's derating: [1.0]


def _thrusters(scales, rise_fall_s=(0.0, 0.0)):
    """A thruster table of one thrust level: no delays, the given rise and fall times."""
    out = np.zeros((len(scales), L.thruster_size(1)))
    for i, scale in enumerate(scales):
        out[i, L.T_SCALE] = scale
        out[i, L.time_constant_column(0, L.RISE)] = rise_fall_s[0]
        out[i, L.time_constant_column(0, L.FALL)] = rise_fall_s[1]
    return out


def _fly_valves(tank, thrusters, commands, t_end, dt=0.025):
    """Drive the kernels as core.flight._integrate does: commands (t, thruster, open) at control
    steps, segments between valve breakpoints; returns the gas used (kg)."""
    n = thrusters.shape[0]
    valve_state = np.zeros((n, rcs.VALVE_STATE_SIZE))
    arms = np.ones((n, 3))
    tau0, tau1 = np.zeros(3), np.zeros(3)
    used, active, t = 0.0, 0, 0.0
    steps = round(t_end / dt)
    for k in range(steps):
        t = k * dt
        for when, i, opening in commands:
            if abs(when - t) < 1e-12:
                rcs.command(valve_state, thrusters, i, opening, t, 0)
                active |= 1 << i
        t_seg, t_stop = t, (k + 1) * dt
        while t_seg < t_stop - 1e-12:
            active = rcs.update(valve_state, thrusters, n, t_seg, 0, active)
            t_next = rcs.next_breakpoint(valve_state, n, t_seg, t_stop, active) if active else t_stop
            if active:
                used += feed.segment(valve_state, thrusters, NO_DERATING, arms, tank, t_seg, t_next, tau0, tau1, active)
            t_seg = t_next
    return used


@pytest.mark.parametrize("gamma", [1.4, 1.3, 1.67])
@pytest.mark.parametrize("expansion_ratio", [1.0, 2.0, 10.0, 50.0, 200.0])
def test_thrust_coefficient_of_eq15_equals_the_textbook_formula(gamma, expansion_ratio):
    """002 eq. 15's bracket (exit Mach from eq. 6) against Sutton eq. 3-30 with p_e/p_c from the
    pressure form of the area ratio: two independent routes to one number. 1e-12: both solve a
    smooth scalar equation to ~1 ulp, and C_F is insensitive to its root (dC_F/d(p_e/p_c) = 0
    at the optimum expansion, small elsewhere)."""
    ours = config_feed.thrust_coefficient(expansion_ratio, gamma)
    textbook = naive.textbook_thrust_coefficient(expansion_ratio, gamma)
    assert ours == pytest.approx(textbook, rel=1e-12)


def test_one_thruster_open_continuously_follows_eq16():
    """One ideal valve open for 3 tau: P(t) = P0 exp(-t/tau) (002 eq. 16), impulse
    C_F A_t P0 tau (1 - exp(-t/tau)) and gas used P0 tau A_t Gamma/sqrt(RT) (1 - exp(-t/tau)),
    with tau = V / (A_t Gamma sqrt(R T)) from the textbook flow (naive.choked_mass_flow).
    1e-9: the kernel's pressure is the closed form per segment; the product of 1000 segment
    factors exp(-h/tau) drifts by ~1000 ulp at most."""
    f = NITROGEN
    rt = f["gas_constant_j_kg_k"] * f["temperature_k"]
    mdot_per_pa = naive.choked_mass_flow(
        f["throat_area_m2"], 1.0, f["heat_capacity_ratio"], f["gas_constant_j_kg_k"], f["temperature_k"]
    )
    tau = f["tank_volume_m3"] / (rt * mdot_per_pa)
    tank = _tank(f)
    thrusters = _thrusters([1.0])
    t_end = round(3.0 * tau / 0.025) * 0.025
    used = _fly_valves(tank, thrusters, [(0.0, 0, True)], t_end)
    p0 = f["initial_pressure_pa"]
    decay = math.exp(-t_end / tau)
    c_f = naive.textbook_thrust_coefficient(f["expansion_ratio"], f["heat_capacity_ratio"])
    assert tank.state[feed.TK_PRESSURE] == pytest.approx(p0 * decay, rel=1e-9)
    assert used == pytest.approx(p0 * tau * mdot_per_pa * (1.0 - decay), rel=1e-9)
    assert tank.state[feed.TK_IMPULSE] == pytest.approx(c_f * f["throat_area_m2"] * p0 * tau * (1.0 - decay), rel=1e-9)
    # gas used = delta P V / (R T) (002 eq. 1)
    assert used == pytest.approx((p0 - tank.state[feed.TK_PRESSURE]) * f["tank_volume_m3"] / rt, rel=1e-12)
    assert feed.gas(tank) == pytest.approx(tank.state[feed.TK_PRESSURE] * f["tank_volume_m3"] / rt, rel=1e-15)


@pytest.mark.parametrize("model", ["blow_down", "regulated"])
def test_ramped_pulses_of_two_thrusters_match_the_integrated_tank(model):
    """Two thrusters (scales 1 and 0.7) pulsing with 20 ms rises and 30 ms falls, overlapping:
    pressure, gas and impulse against scipy's DOP853 of the tank ODE (naive.tank_history, rtol
    1e-13, split at every valve kink). 1e-9: the kernel is exact per segment, the reference
    integrates to ~1e-12."""
    f = dict(NITROGEN, model=model)
    set_pressure = math.inf
    if model == "regulated":
        set_pressure = 8e5
        f["tank_volume_m3"] = 0.0005  # small enough to fall below the set pressure in the run
    tank = _tank(f, set_pressure)
    thrusters = _thrusters([1.0, 0.7], rise_fall_s=(0.02, 0.03))
    commands = []
    for k in range(40):
        start = round(k * 0.5, 3)
        commands += [(start, 0, True), (round(start + 0.3, 3), 0, False)]
        commands += [(round(start + 0.1, 3), 1, True), (round(start + 0.45, 3), 1, False)]
    t_end = 20.0
    used = _fly_valves(tank, thrusters, commands, t_end)

    def level(t, on, off, rise=0.02, fall=0.03):
        if t <= on:
            return 0.0
        up = min((t - on) / rise, 1.0)
        if t <= off:
            return up
        start = min((off - on) / rise, 1.0)
        return max(start - (t - off) / fall, 0.0)

    def open_sum(t):
        total = 0.0
        for k in range(40):
            s = k * 0.5
            total += level(t, s, s + 0.3) + 0.7 * level(t, s + 0.1, s + 0.45)
        return total

    kinks = sorted({round(k * 0.5 + d, 6) for k in range(40) for d in (0, 0.02, 0.3, 0.33, 0.1, 0.12, 0.45, 0.48)})
    reference = naive.tank_history(
        open_sum,
        [*kinks, t_end],
        _naive_tank(f, set_pressure),
    )
    if model == "regulated":  # it starts above the set pressure and ends below: both regimes flown
        assert reference[0] < set_pressure < f["initial_pressure_pa"]
    assert tank.state[feed.TK_PRESSURE] == pytest.approx(reference[0], rel=1e-9)
    assert used == pytest.approx(reference[1], rel=1e-9)
    assert tank.state[feed.TK_IMPULSE] == pytest.approx(reference[2], rel=1e-9)


def _naive_tank(f, set_pressure):
    """The feed ``f`` as naive.tank_history's parameters (the textbook C_F, set pressure or inf)."""
    return {
        "volume": f["tank_volume_m3"],
        "gas_constant": f["gas_constant_j_kg_k"],
        "gamma": f["heat_capacity_ratio"],
        "temperature": f["temperature_k"],
        "pressure": f["initial_pressure_pa"],
        "throat_area": f["throat_area_m2"],
        "thrust_coefficient": naive.textbook_thrust_coefficient(f["expansion_ratio"], f["heat_capacity_ratio"]),
        "regulator": set_pressure,
    }


@pytest.mark.parametrize("model", ["blow_down", "regulated"])
def test_pressure_within_a_ramp_segment_is_the_integrated_tanks_and_ends_where_segment_does(model):
    """core.feed.pressure_within (the local trajectory's midpoint, issue 33): over a valve's 20 ms
    rise, at its midpoint against scipy's DOP853 of the tank ODE (naive.tank_history, rtol 1e-13;
    1e-12: the closed form is exact), and at the segment's end the very pressure feed.segment
    leaves (the same closed form, to the bit)."""
    f = dict(NITROGEN, model=model)
    set_pressure = 0.8 * f["initial_pressure_pa"] if model == "regulated" else math.inf
    tank = _tank(f, set_pressure)
    thrusters = _thrusters([0.7], rise_fall_s=(0.02, 0.03))
    valve_state = np.zeros((1, rcs.VALVE_STATE_SIZE))
    rcs.command(valve_state, thrusters, 0, True, 0.0, 0)
    active = rcs.update(valve_state, thrusters, 1, 0.0, 0, 1)
    t_end = rcs.next_breakpoint(valve_state, 1, 0.0, 1.0, active)
    assert t_end == pytest.approx(0.02)  # the rise: the level linear from 0 to 1
    p0 = tank.state[feed.TK_PRESSURE]
    middle = feed.pressure_within(valve_state, thrusters, NO_DERATING, tank, p0, 0.0, t_end, 0.5 * t_end, active)
    end = feed.pressure_within(valve_state, thrusters, NO_DERATING, tank, p0, 0.0, t_end, t_end, active)
    feed.segment(valve_state, thrusters, NO_DERATING, np.ones((1, 3)), tank, 0.0, t_end, np.zeros(3), np.zeros(3), 1)
    assert end == tank.state[feed.TK_PRESSURE]
    reference = naive.tank_history(
        lambda t: 0.7 * min(t / 0.02, 1.0),
        [0.5 * t_end],
        _naive_tank(f, set_pressure),
    )
    assert middle == pytest.approx(reference[0], rel=1e-12)
    assert middle < p0


def test_regulated_tank_falls_linearly_above_the_set_pressure():
    """Above P_reg the chamber is at P_reg: the tank falls by P_reg t / tau, a straight line."""
    p_reg = 5e5
    tank = _tank(dict(NITROGEN, model="regulated"), p_reg)
    tau = tank.state[feed.TK_TAU]
    p0 = NITROGEN["initial_pressure_pa"]
    assert feed.pressure_after(p0, 10.0, tau, p_reg) == pytest.approx(p0 - p_reg * 10.0 / tau, rel=1e-15)
    # just past the set pressure: the rest blows down from P_reg
    t_cross = (p0 - p_reg) * tau / p_reg
    assert feed.pressure_after(p0, t_cross + 5.0, tau, p_reg) == pytest.approx(p_reg * math.exp(-5.0 / tau), rel=1e-12)
    assert feed.thrust_per_level(tank, p0) == pytest.approx(feed.thrust_per_level(tank, p_reg), rel=1e-15)


def test_a_blow_down_vehicle_flies_its_own_family_and_uses_the_tank_gas():
    """The generic 12-thruster slew with a blow-down tank: its kernel is the blow-down family,
    the gas used is the tank's P0 V/(RT) times (1 - P_end/P0), and the thrusters deliver less
    thrust than at the start as the tank empties (fuel_remaining = P_end / P0, isothermal)."""
    vehicle = _vehicle(NITROGEN)
    mission = load_mission(ROOT / "configs/missions/generic-slew.yaml")
    inputs = pack(vehicle, mission)
    assert family(inputs)[3] == L.FEED_BLOW_DOWN
    design = config_feed.design(NITROGEN)
    assert inputs.vehicle[L.V_PROPELLANT] == pytest.approx(design["gas_kg"], rel=1e-15)
    result = fly(inputs, mode_names=mode_names(mission))
    assert result.success
    used, remaining = result.value("fuel_used_kg"), result.value("fuel_remaining")
    assert 0.0 < used < design["gas_kg"]
    assert used == pytest.approx(design["gas_kg"] * (1.0 - remaining), rel=1e-12)


def test_constant_feed_family_is_unchanged():
    """Without rcs.feed the family's feed id is constant (the ReFEx kernel compiles no core.feed)."""
    inputs = pack(
        load_vehicle(ROOT / "configs/vehicles/refex.yaml"), load_mission(ROOT / "configs/missions/refex-exo.yaml")
    )
    assert family(inputs)[3] == L.FEED_CONSTANT


def _bad_vehicle(tmp_path, old, new, drop_propellant=True):
    text = GENERIC.read_text()
    if drop_propellant:
        text = text.replace("  isp_s: 65.0\n  propellant_kg: 2.0\n", "")
    feed_block = "".join(f"    {k}: {v}\n" for k, v in NITROGEN.items())
    text = text.replace("  switching_limits_ms:", "  feed:\n" + feed_block + "  switching_limits_ms:")
    assert old in text, old
    path = tmp_path / "vehicle.yaml"
    path.write_text(text.replace(old, new))
    line = (
        next(n for n, row in enumerate(path.read_text().splitlines(), 1) if new.strip().split("\n")[0] in row)
        if new
        else None
    )
    return path, line


@pytest.mark.parametrize(
    ("old", "new", "words"),
    [
        ("tank_volume_m3: 0.004", "tank_volume_m3: 0.0", ["rcs.feed.tank_volume_m3", "expected a value > 0.0"]),
        ("initial_pressure_pa: 2000000.0", "initial_pressure_pa: -1.0", ["rcs.feed.initial_pressure_pa"]),
        ("temperature_k: 293.0", "temperature_k: 0", ["rcs.feed.temperature_k"]),
        ("expansion_ratio: 50.0", "expansion_ratio: 0.9", ["rcs.feed.expansion_ratio"]),
        (
            "heat_capacity_ratio: 1.4",
            "heat_capacity_ratio: 1.0",
            ["rcs.feed.heat_capacity_ratio", "expected a value > 1.0"],
        ),
        ("model: blow_down", "model: blowdown", ["rcs.feed.model"]),
        ("    throat_area_m2: 1e-06\n", "", ["throat_area_m2", "required with feed blow_down"]),
    ],
)
def test_bad_feed_input_exits_2_with_file_line_and_key_path(tmp_path, old, new, words):
    path, line = _bad_vehicle(tmp_path, old, new)
    result = CliRunner().invoke(main, ["validate", str(path)])
    assert result.exit_code == 2, result.output
    assert "Traceback" not in result.output
    assert str(path) in result.output
    for word in words:
        assert word in result.output, result.output
    if new:
        assert f":{line}:" in result.output, result.output


def test_isp_and_propellant_with_a_tank_exit_2(tmp_path):
    path, _ = _bad_vehicle(tmp_path, "model: blow_down", "model: blow_down", drop_propellant=False)
    result = CliRunner().invoke(main, ["validate", str(path)])
    assert result.exit_code == 2
    assert "rcs.isp_s" in result.output and "derived from the tank" in result.output, result.output


def test_a_feed_on_a_wheel_vehicle_exits_2(tmp_path):
    """ReFEx with wheels flying (tests/test_wheels_config.py): its thrusters never fire, so a tank
    behind them is refused."""
    import yaml

    from tests.test_wheels_config import _refex_with_wheels

    vehicle = _refex_with_wheels("wheels")
    del vehicle["rcs"]["isp_s"], vehicle["rcs"]["propellant_kg"]
    vehicle["rcs"]["feed"] = dict(NITROGEN)
    path = tmp_path / "wheels.yaml"
    path.write_text(yaml.safe_dump(vehicle, sort_keys=False))
    result = CliRunner().invoke(main, ["validate", str(path)])
    assert result.exit_code == 2, result.output
    assert "rcs.feed" in result.output and "actuation wheels" in result.output, result.output


def test_inspect_shows_the_feed_design(tmp_path):
    """`refexmc inspect --json`: C_F (textbook), exhaust velocity c = C_F sqrt(RT)/Gamma (so that
    c mdot = C_F A_t P, 002 eq. 10, 15), initial thrust C_F A_t P0, half of it at half tank, and
    the total impulse c P0 V/(R T)."""
    import json

    path, _ = _bad_vehicle(tmp_path, "model: blow_down", "model: blow_down")
    result = CliRunner().invoke(main, ["inspect", str(path), "--json"])
    assert result.exit_code == 0, result.output
    info = json.loads(result.output)["feed"]
    f = NITROGEN
    c_f = naive.textbook_thrust_coefficient(f["expansion_ratio"], f["heat_capacity_ratio"])
    mdot_per_pa = naive.choked_mass_flow(
        f["throat_area_m2"], 1.0, f["heat_capacity_ratio"], f["gas_constant_j_kg_k"], f["temperature_k"]
    )
    gas = f["initial_pressure_pa"] * f["tank_volume_m3"] / (f["gas_constant_j_kg_k"] * f["temperature_k"])
    assert info["thrust_coefficient"] == pytest.approx(c_f, rel=1e-12)
    assert info["exhaust_velocity_m_s"] == pytest.approx(c_f * f["throat_area_m2"] / mdot_per_pa, rel=1e-12)
    assert info["initial_thrust_n"] == pytest.approx(c_f * f["throat_area_m2"] * f["initial_pressure_pa"], rel=1e-12)
    assert info["thrust_at_half_tank_n"] == pytest.approx(0.5 * info["initial_thrust_n"], rel=1e-12)
    assert info["total_impulse_n_s"] == pytest.approx(info["exhaust_velocity_m_s"] * gas, rel=1e-12)
    text = CliRunner().invoke(main, ["inspect", str(path)]).output
    assert "thrust coefficient C_F" in text and "total impulse" in text


def test_a_regulated_level_holds_its_thrust_derated_as_the_pressure_reducers():
    """Feed regulated: each level's set pressure gives its thrust_n (C_F A_t P_set = thrust_n, in
    the levels table), and with two valves open the set pressure is derated like 000 sec. 2.1's
    reducers: each thruster's torque is the derated thrust while the tank is above it."""
    vehicle = _vehicle(dict(NITROGEN, model="regulated", initial_pressure_pa=20e6))  # 34.6 N full
    vehicle["rcs"]["derating"] = [1.0, 0.91]
    inputs = pack(vehicle, load_mission(ROOT / "configs/missions/generic-slew.yaml"))
    c_f = naive.textbook_thrust_coefficient(NITROGEN["expansion_ratio"], NITROGEN["heat_capacity_ratio"])
    for k, level in enumerate(("low", "high")):
        set_pressure = inputs.levels[k, L.LV_REGULATOR_PRESSURE]
        assert c_f * NITROGEN["throat_area_m2"] * set_pressure == pytest.approx(
            vehicle["rcs"]["thrust_n"][level], rel=1e-12
        )
    tank = feed.tank()
    feed.start(inputs.vehicle, tank)
    tank.state[feed.TK_REGULATOR] = inputs.levels[1, L.LV_REGULATOR_PRESSURE]  # high: 4 N
    thrusters = _thrusters([1.0, 1.0])
    valve_state = np.zeros((2, rcs.VALVE_STATE_SIZE))
    for i in range(2):
        rcs.command(valve_state, thrusters, i, True, 0.0, 0)
    active = rcs.update(valve_state, thrusters, 2, 0.0, 0, 0b11)
    arms = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    tau0, tau1 = np.zeros(3), np.zeros(3)
    feed.segment(valve_state, thrusters, inputs.vehicle, arms, tank, 0.0, 0.1, tau0, tau1, active)
    np.testing.assert_allclose(tau0[:2], [4.0 * 0.91, 4.0 * 0.91], rtol=1e-12)
    np.testing.assert_allclose(tau1[:2], tau0[:2], rtol=1e-15)  # still regulated at the end


def test_a_regulated_tank_far_above_its_set_pressures_flies_like_the_constant_feed():
    """While the regulator holds, the thrusts are thrust_n: the generic slew flies as with the
    constant feed at the tank's Isp (c / g0) and gas. Same modes and times; the gas used equal to
    1e-6 (the two thrust paths differ in the last bits: C_F A_t P_set against thrust_n)."""
    mission = load_mission(ROOT / "configs/missions/generic-slew.yaml")
    regulated = _vehicle(dict(NITROGEN, model="regulated", initial_pressure_pa=20e6))
    design = config_feed.design(regulated["rcs"]["feed"])
    constant = load_vehicle(GENERIC)
    constant["rcs"]["isp_s"] = design["specific_impulse_s"]
    constant["rcs"]["propellant_kg"] = design["gas_kg"]
    a = fly(pack(regulated, mission), mode_names=mode_names(mission)).runs_values()
    b = fly(pack(constant, mission), mode_names=mode_names(mission)).runs_values()
    assert a["t_end_s"] == b["t_end_s"]
    assert [a[k] for k in a if k.startswith("pulses_")] == [b[k] for k in b if k.startswith("pulses_")]
    assert a["fuel_used_kg"] == pytest.approx(b["fuel_used_kg"], rel=1e-6)


def test_refex_on_its_estimated_tank_runs_below_the_high_set_pressure():
    """configs/vehicles/refex-blow-down.yaml, nominal: the flight succeeds and ends with the tank
    below the high level's set pressure (docs/cold-gas.md sec. 5: 5.3 bar against 9.9 bar)."""
    vehicle = load_vehicle(ROOT / "configs/vehicles/refex-blow-down.yaml")
    mission = load_mission(ROOT / "configs/missions/refex-exo.yaml")
    inputs = pack(vehicle, mission)
    high = inputs.levels[1, L.LV_REGULATOR_PRESSURE]
    assert high == pytest.approx(9.92e5, rel=1e-3)
    result = fly(inputs, mode_names=mode_names(mission))
    assert result.success
    end_pressure = result.value("fuel_remaining") * vehicle["rcs"]["feed"]["initial_pressure_pa"]
    assert end_pressure < high


def test_dispersing_a_regulated_level_scales_its_set_pressure():
    """rcs.thrust_n.high drawn 5 % high: the regulated level's set pressure follows (the thrust it
    delivers is C_F A_t P_set); with a blow-down tank the path is refused."""
    from refexmc.config import dispersions

    vehicle = load_vehicle(ROOT / "configs/vehicles/refex-blow-down.yaml")
    mission = load_mission(ROOT / "configs/missions/refex-exo.yaml")
    inputs = pack(vehicle, mission)
    nominal = inputs.levels[1, L.LV_REGULATOR_PRESSURE]
    dispersions.apply(inputs, "rcs.thrust_n.high", [8.92 * 1.05], None)
    assert inputs.levels[1, L.LV_REGULATOR_PRESSURE] == pytest.approx(1.05 * nominal, rel=1e-12)
    blow_down = _vehicle(NITROGEN)
    assert "blow-down tank" in dispersions.undeclared(
        "rcs.thrust_n.high", blow_down, load_mission(ROOT / "configs/missions/generic-slew.yaml")
    )


def test_segment_torque_and_impulse_with_ambient_pressure_and_thrust_scales_eq15():
    """Two ideal valves (thrust scales 1 and 0.7, distinct arms) open on a blow-down tank in an
    ambient pressure: each thruster's force is s_i (C_F A_t P - epsilon P_a A_t) (002 eq. 15) at
    both ends of a segment, the tank falls as P0 exp(-1.7 h / tau) (eq. 16 with S = 1.7), and
    the impulse is C_F A_t P0 tau (1 - exp(-1.7 h / tau)) - 1.7 epsilon P_a A_t h, the integral
    of the sum. Below C_F P = epsilon P_a a nozzle gives no thrust (not a negative one).
    1e-12: one closed-form segment against the closed forms written out here."""
    f = dict(NITROGEN, ambient_pressure_pa=0.3e5)
    area, p0, eps, p_a = f["throat_area_m2"], f["initial_pressure_pa"], f["expansion_ratio"], 0.3e5
    c_f = naive.textbook_thrust_coefficient(eps, f["heat_capacity_ratio"])
    rt = f["gas_constant_j_kg_k"] * f["temperature_k"]
    mdot_per_pa = naive.choked_mass_flow(
        area, 1.0, f["heat_capacity_ratio"], f["gas_constant_j_kg_k"], f["temperature_k"]
    )
    tau = f["tank_volume_m3"] / (rt * mdot_per_pa)
    tank = _tank(f)
    thrusters = _thrusters([1.0, 0.7])
    valve_state = np.zeros((2, rcs.VALVE_STATE_SIZE))
    for i in range(2):
        rcs.command(valve_state, thrusters, i, True, 0.0, 0)
    active = rcs.update(valve_state, thrusters, 2, 0.0, 0, 0b11)
    arms = np.array([[0.3, -0.2, 0.5], [-0.1, 0.4, 0.25]])
    tau0, tau1 = np.zeros(3), np.zeros(3)
    h = 2.0
    feed.segment(valve_state, thrusters, NO_DERATING, arms, tank, 0.0, h, tau0, tau1, active)
    p1 = p0 * math.exp(-1.7 * h / tau)
    assert tank.state[feed.TK_PRESSURE] == pytest.approx(p1, rel=1e-12)

    def force(pressure):  # eq. 15 per unit of level and thrust scale
        return c_f * area * pressure - eps * p_a * area

    for torque, pressure in ((tau0, p0), (tau1, p1)):
        expected = force(pressure) * (1.0 * arms[0] + 0.7 * arms[1])
        np.testing.assert_allclose(torque, expected, rtol=1e-12, atol=0.0)
    impulse = c_f * area * p0 * tau * (1.0 - math.exp(-1.7 * h / tau)) - 1.7 * eps * p_a * area * h
    assert tank.state[feed.TK_IMPULSE] == pytest.approx(impulse, rel=1e-12)
    assert feed.thrust_per_level(tank, p0) == pytest.approx(force(p0), rel=1e-12)
    assert feed.thrust_per_level(tank, 0.5 * eps * p_a / c_f) == 0.0


@pytest.mark.parametrize("opening", [True, False])
def test_a_regulated_segment_derates_by_the_valves_open_within_it(opening):
    """A regulated tank far above its derated set pressure, valve 0 open and valve 1 ramping
    (rising 20 ms after it opens at 5 s, or falling 30 ms after it closes at 5 s): within the
    segment [5, 5.01] s both valves are open, so the set pressure is derated for two
    (000 sec. 2.1, 0.91) at both ends; the torque is each thruster's level (rcs ramps, written
    out here) times the derated 4 N. 1e-12: one segment, closed forms."""
    vehicle = _vehicle(dict(NITROGEN, model="regulated", initial_pressure_pa=20e6))
    vehicle["rcs"]["derating"] = [1.0, 0.91]
    inputs = pack(vehicle, load_mission(ROOT / "configs/missions/generic-slew.yaml"))
    tank = feed.tank()
    feed.start(inputs.vehicle, tank)
    tank.state[feed.TK_REGULATOR] = inputs.levels[1, L.LV_REGULATOR_PRESSURE]  # high: 4 N
    thrusters = _thrusters([1.0, 1.0], rise_fall_s=(0.02, 0.03))
    valve_state = np.zeros((2, rcs.VALVE_STATE_SIZE))
    rcs.command(valve_state, thrusters, 0, True, 0.0, 0)
    if not opening:
        rcs.command(valve_state, thrusters, 1, True, 0.0, 0)
    active = rcs.update(valve_state, thrusters, 2, 0.0, 0, 0b11 if not opening else 0b01)
    rcs.command(valve_state, thrusters, 1, opening, 5.0, 0)
    active = rcs.update(valve_state, thrusters, 2, 5.0, 0, active | 0b10)
    arms = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    tau0, tau1 = np.zeros(3), np.zeros(3)
    feed.segment(valve_state, thrusters, inputs.vehicle, arms, tank, 5.0, 5.01, tau0, tau1, active)
    level1 = (0.0, 0.5) if opening else (1.0, 1.0 - 0.01 / 0.03)
    np.testing.assert_allclose(tau0[:2], [4.0 * 0.91, 4.0 * 0.91 * level1[0]], rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(tau1[:2], [4.0 * 0.91, 4.0 * 0.91 * level1[1]], rtol=1e-12, atol=1e-15)
