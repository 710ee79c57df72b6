"""Every number of a blow-down feed (rcs.feed) can be dispersed and swept (issue 34 point 7): a
drawn value lands in the flight as if the vehicle file said it, the tank volume sets the gas and
the blow-down time constant the flight uses (002 eq. 1, 16), and its ``p.`` column is in the runs
table and the report's dispersed inputs."""

import copy
import math

import numpy as np
import pytest
from stored import ROOT, campaign_copy, read_runs

from refexmc.campaign.run import run_campaign
from refexmc.campaign.sampling import Sampler
from refexmc.campaign.sweep import run_campaign_or_sweep
from refexmc.config import dispersions, schema
from refexmc.config import sweep as sweep_config
from refexmc.config.errors import ConfigError
from refexmc.config.load import load_campaign
from refexmc.config.pack import pack
from refexmc.core import feed
from refexmc.core import layout as L
from refexmc.report import data, summary

HOP = "surveyor-hop.yaml"
FEED_NUMBERS = (*schema.FEED_TANK_KEYS, "ambient_pressure_pa")  # every number of rcs.feed
# a value of each, away from the surveyor's own (a volume, a gas, a nozzle and a pressure of their own)
OTHER_VALUE = {
    "tank_volume_m3": 0.0015,
    "gas_constant_j_kg_k": 259.8,  # oxygen
    "heat_capacity_ratio": 1.67,  # a monatomic gas (helium, argon)
    "temperature_k": 250.0,
    "initial_pressure_pa": 4.2e6,
    "throat_area_m2": 1.3e-7,
    "expansion_ratio": 80.0,
    "ambient_pressure_pa": 800.0,  # the Martian surface
}
VOLUMES_M3 = (0.0008, 0.001, 0.0015)  # the surveyor's 1 l bottle, and one smaller and one larger
# The core's gas used is the sum over valve segments of (P_start - P_end) V / (R T): against the
# closed form (P0 - P_end) V / (R T) it differs by the rounding of some thousands of segment
# differences, ~1e-13 relative; 1e-9 leaves a margin of four orders and still catches a volume
# 1e-9 off from the one the campaign says.
CLOSED_FORM_RTOL = 1e-9


def _hop(tmp_path, name, replace=(), extra="", undispersed=()):
    """The surveyor hop with 4 runs, no stuck valves (every run arrives), the dispersions of the
    paths ``undispersed`` left out and ``extra`` appended."""
    stuck = ("  mode: random\n  count_probabilities: [0.95, 0.05]", "  mode: none")
    path = campaign_copy(HOP, tmp_path, name, [("runs: 1000", "runs: 4"), stuck, *replace])
    kept = [
        line for line in path.read_text().splitlines(keepends=True) if line.split(":")[0].strip() not in undispersed
    ]
    path.write_text("".join(kept) + extra)
    return path


def _isothermal_drop_pa(runs, volume_m3, gas_constant):
    """P0 - P_end of each run from the gas it used: P V = m R T (002 eq. 1) at the run's drawn P0, T."""
    return runs["fuel_used_kg"] * gas_constant * runs["p.rcs.feed.temperature_k"] / volume_m3


@pytest.mark.parametrize("key", FEED_NUMBERS)
def test_every_feed_number_drawn_is_the_flight_of_a_file_that_says_it(tmp_path, key):
    """A constant dispersion of ``rcs.feed.KEY`` gives the packed vehicle (the truth) of the vehicle
    file with that value, bit for bit, and the same tank at t = 0 in the core (pressure, tau,
    exhaust velocity, force per pascal, gas): the nozzle's C_F and Gamma follow a drawn gamma or
    area ratio. The translation law keeps
    the file's (the flight software table is the nominal one). Each is also a sweep axis."""
    path = f"rcs.feed.{key}"
    campaign = load_campaign(ROOT / "campaigns" / HOP)
    campaign["dispersions"] = {path: {"dist": "constant", "value": OTHER_VALUE[key]}}
    sampler = Sampler(campaign)
    nominal = pack(campaign["vehicle"], campaign["mission"])
    drawn = sampler.inputs(nominal, sampler.values(1), ())
    said = copy.deepcopy(campaign["vehicle"])
    said["rcs"]["feed"][key] = OTHER_VALUE[key]
    truth = pack(said, campaign["mission"])
    # isp_s and propellant_kg are packed from the file's tank, and not read by a blow-down flight
    # (its tank gives the gas and the exhaust velocity at t = 0: core.feed.start, core.flight)
    derived = [L.VEHICLE.slices[name][0] for name in ("isp_s", "propellant_kg")]
    flown = np.ones(L.VEHICLE_SIZE, dtype=bool)
    flown[derived] = False
    assert drawn.vehicle[flown].tobytes() == truth.vehicle[flown].tobytes()
    assert drawn.vehicle[flown].tobytes() != nominal.vehicle[flown].tobytes()
    tanks = [feed.tank(), feed.tank()]
    feed.start(drawn.vehicle, tanks[0])
    feed.start(truth.vehicle, tanks[1])
    assert tanks[0].state.tobytes() == tanks[1].state.tobytes()
    assert drawn.fsw.tobytes() == nominal.fsw.tobytes()
    assert sampler.columns(sampler.values(1)) == {f"p.{path}": OTHER_VALUE[key]}
    param = dispersions.parameter(path)
    assert param is not None and param.shape == "scalar"
    # a sweep axis too (ambient_pressure_pa: the file omits it, its schema default 0 is the value)
    axis = f"sweep:\n  axes:\n    - parameter: {path}\n      values: [{OTHER_VALUE[key]!r}]\n"
    swept = load_campaign(_hop(tmp_path, "sweep.yaml", extra=axis, undispersed=(path,)))
    assert sweep_config.file_value(swept, path) == dispersions.nominal(path, swept["vehicle"], swept["mission"])[0]
    (point,) = sweep_config.points(swept)
    flown = sweep_config.point_campaign(swept, 0, point)
    assert flown["vehicle"]["rcs"]["feed"][key] == OTHER_VALUE[key]
    assert flown["dispersions"][path] == {"dist": "constant", "value": OTHER_VALUE[key]}


def test_the_feed_of_a_constant_feed_vehicle_is_refused_by_name(tmp_path):
    """ReFEx flies the constant feed: there is no tank to disperse or sweep (not 'the file does not
    declare it')."""
    campaign = load_campaign(ROOT / "campaigns/nominal.yaml")
    with pytest.raises(ConfigError, match="has the constant feed"):
        dispersions.check(
            {"rcs.feed.tank_volume_m3": {"dist": "uniform", "low": 0.001, "high": 0.002}},
            campaign["vehicle"],
            campaign["mission"],
            None,
            {},
        )
    axis = "sweep:\n  axes:\n    - parameter: rcs.feed.tank_volume_m3\n      values: [0.001, 0.002]\n"
    path = campaign_copy("nominal.yaml", tmp_path)
    path.write_text(path.read_text() + axis)
    with pytest.raises(ConfigError, match=r"sweep\.axes\.0\.parameter: .* has the constant feed"):
        load_campaign(path)


def test_the_tank_volume_sets_the_blow_down_time_constant():
    """tau = V / (A_t Gamma sqrt(R T)) (002 eq. 16), Gamma = sqrt(gamma (2/(gamma+1))^((gamma+1)/(gamma-1)))
    (eq. 10), written out here from the vehicle file: the core's tank at t = 0 of a drawn volume.
    The same operations in another order: a few ulps, 1e-14 relative."""
    campaign = load_campaign(ROOT / "campaigns" / HOP)
    tank_file = campaign["vehicle"]["rcs"]["feed"]
    campaign["dispersions"] = {"rcs.feed.tank_volume_m3": {"dist": "uniform", "low": 5e-4, "high": 2e-3}}
    sampler = Sampler(campaign)
    nominal = pack(campaign["vehicle"], campaign["mission"])
    gamma, rt = tank_file["heat_capacity_ratio"], tank_file["gas_constant_j_kg_k"] * tank_file["temperature_k"]
    flow_factor = math.sqrt(gamma * (2.0 / (gamma + 1.0)) ** ((gamma + 1.0) / (gamma - 1.0)))
    volumes = []
    for run_id in range(1, 6):
        values = sampler.values(run_id)
        tank = feed.tank()
        feed.start(sampler.inputs(nominal, values, ()).vehicle, tank)
        volume = float(values["rcs.feed.tank_volume_m3"][0])
        expected = volume / (tank_file["throat_area_m2"] * flow_factor * math.sqrt(rt))
        assert tank.state[feed.TK_TAU] == pytest.approx(expected, rel=1e-14)
        assert feed.gas(tank) == pytest.approx(tank_file["initial_pressure_pa"] * volume / rt, rel=1e-14)
        volumes.append(volume)
    assert len(set(volumes)) == 5 and min(volumes) >= 5e-4 and max(volumes) <= 2e-3


def test_a_swept_tank_volume_blows_down_by_the_isothermal_closed_form(tmp_path):
    """Three tank volumes swept on the hop: each point's runs record the volume, and every run's
    tank ends where P V = m R T (002 eq. 1) puts it after the gas it used, with the point's V; the
    nominal hop needs about the same gas from any bottle, so its end pressure rises with V."""
    values = ", ".join(f"{v:g}" for v in VOLUMES_M3)
    extra = (
        "sweep:\n  axes:\n    - parameter: rcs.feed.tank_volume_m3\n"
        f"      values: [{values}]\n  metrics: [tank_pressure_end_pa]\n"
    )
    result = run_campaign_or_sweep(_hop(tmp_path, "sweep.yaml", extra=extra), tmp_path / "sweep", jobs=1)
    runs = result["runs"]
    gas_constant = load_campaign(ROOT / "campaigns" / HOP)["vehicle"]["rcs"]["feed"]["gas_constant_j_kg_k"]
    end_pressures = []
    for point, volume in enumerate(VOLUMES_M3):
        flown = runs[runs["point"] == point]
        assert len(flown) == 4 and (flown["status"] == "ok").all()
        assert (flown["p.rcs.feed.tank_volume_m3"] == volume).all()
        drop = flown["p.rcs.feed.initial_pressure_pa"] - flown["tank_pressure_end_pa"]
        np.testing.assert_allclose(drop, _isothermal_drop_pa(flown, volume, gas_constant), rtol=CLOSED_FORM_RTOL)
        end_pressures.append(float(flown.loc[flown["run_id"] == 0, "tank_pressure_end_pa"].iloc[0]))
    assert end_pressures == sorted(end_pressures) and len(set(end_pressures)) == 3


def test_a_dispersed_tank_volume_is_an_input_column_and_changes_the_flights(tmp_path):
    """The tank volume drawn per run: a p. column within its bounds, a row of the report's dispersed
    inputs, the closed form per run, and flights that differ from the same campaign (same seeds)
    without it in every dispersed run (run 0, the nominal, the same)."""
    dispersion = "  rcs.feed.tank_volume_m3: {dist: truncnorm, sigma: 1.0e-4, low: 8.0e-4, high: 1.2e-3}\n"
    anchor = "dispersions:\n"
    volume_file = _hop(tmp_path, "volume.yaml", replace=[(anchor, anchor + dispersion)])
    with_volume = run_campaign(volume_file, tmp_path / "v", jobs=1)
    plain = run_campaign(_hop(tmp_path, "plain.yaml"), tmp_path / "plain", jobs=1)["runs"]
    runs = with_volume["runs"].sort_values("run_id", ignore_index=True)
    plain = plain.sort_values("run_id", ignore_index=True)
    column = runs["p.rcs.feed.tank_volume_m3"]
    assert column.iloc[0] == 0.001 and column.iloc[1:].between(8.0e-4, 1.2e-3).all() and column.iloc[1:].nunique() == 3
    gas_constant = load_campaign(ROOT / "campaigns" / HOP)["vehicle"]["rcs"]["feed"]["gas_constant_j_kg_k"]
    drop = runs["p.rcs.feed.initial_pressure_pa"] - runs["tank_pressure_end_pa"]
    np.testing.assert_allclose(drop, _isothermal_drop_pa(runs, column, gas_constant), rtol=CLOSED_FORM_RTOL)
    assert runs.loc[0, "tank_pressure_end_pa"] == plain.loc[0, "tank_pressure_end_pa"]
    assert (runs["tank_pressure_end_pa"].iloc[1:] != plain["tank_pressure_end_pa"].iloc[1:]).all()
    shared = [c for c in plain.columns if c.startswith("p.")]
    assert runs[shared].equals(plain[shared])  # keyed seeding: every other draw the same
    inputs = {row["parameter"]: row for row in summary.inputs_section(data.load(tmp_path / "v"))["rows"]}
    drawn = inputs["rcs.feed.tank_volume_m3"]["drawn"][0]
    assert drawn["column"] == "p.rcs.feed.tank_volume_m3" and 8.0e-4 <= drawn["min"] < drawn["max"] <= 1.2e-3
    assert read_runs(tmp_path / "v")["p.rcs.feed.tank_volume_m3"].tolist() == column.tolist()
