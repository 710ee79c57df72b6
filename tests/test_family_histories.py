"""Each vehicle family records its own quantities in the histories and no others (issue 34 point 3,
docs/interface.md ``histories``): a hop its position, velocity, distance to the target, speed,
tank pressure and the translation law's command; reaction wheels their momenta and torques;
ReFEx its attitude errors, altitude and dynamic pressure. Each recorded quantity is checked
against something it must agree with: the kinematics, the runs table's end values, the tank's
isothermal mass, the wheels' limits."""

from pathlib import Path

import numpy as np
import pytest

from refexmc.campaign.storage import history_table
from refexmc.config.load import load_mission, load_vehicle
from refexmc.config.pack import mode_names, pack
from refexmc.simulate import fly

ROOT = Path(__file__).resolve().parents[1]
COMMON = {"run_id", "t_s", "mode"}
PROPELLANT = {"fuel_remaining", "valves_open"}
ATTITUDE = {"theta_t_deg", "omega_m_deg_s"} | {
    f"{q}_{a}_{u}" for q, u in (("theta_e", "deg"), ("omega_e", "deg_s")) for a in "xyz"
}
PULSES = {f"pulse_{a}" for a in "xyz"}
HOP = (
    {"tank_pressure_pa", "position_error_m", "speed_m_s"}
    | {f"position_{a}_m" for a in "xyz"}
    | {f"velocity_{a}_m_s" for a in "xyz"}
    | {f"translation_command_{a}" for a in "xyz"}
)


def _fly(vehicle_file, mission_file, rate_hz):
    vehicle = load_vehicle(ROOT / "configs/vehicles" / vehicle_file)
    mission = load_mission(ROOT / "configs/missions" / mission_file)
    result = fly(pack(vehicle, mission), history_rate_hz=rate_hz, mode_names=mode_names(mission))
    return vehicle, mission, result, history_table(0, result).to_pandas()


@pytest.fixture(scope="module")
def hop():
    """The nominal hop with a history row every control step (100 Hz)."""
    return _fly("cold-gas-surveyor.yaml", "surveyor-hop.yaml", 100.0)


def test_a_hop_records_its_translation_and_no_attitude(hop):
    vehicle, mission, result, history = hop
    assert set(history.columns) == COMMON | PROPELLANT | HOP  # no attitude, altitude_m or qbar_pa
    for column in set(history.columns) - {"mode"}:
        assert np.isfinite(history[column].to_numpy(dtype=float)).all(), column
    position = history[[f"position_{a}_m" for a in "xyz"]].to_numpy(dtype=float)
    velocity = history[[f"velocity_{a}_m_s" for a in "xyz"]].to_numpy(dtype=float)
    target = np.asarray(mission["local"]["target_position_m"])
    # float32 columns: 7 digits
    np.testing.assert_allclose(history["speed_m_s"], np.linalg.norm(velocity, axis=1), rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(history["position_error_m"], np.linalg.norm(position - target, axis=1), atol=1e-6)
    # kinematics: each step's displacement is the trapezoid of its velocities; exact for a linear
    # velocity, off by at most a h^2 / 4 where the thrust steps within the step (a <= 0.052 m/s^2
    # at the initial tank pressure, h = 10 ms: 1.3e-6 m), plus the float32 rounding of two
    # positions near 3 m (2 x 2.4e-7 m)
    t = history["t_s"].to_numpy()
    step = np.diff(t)[:, None]
    trapezoid = 0.5 * (velocity[1:] + velocity[:-1]) * step
    assert np.abs(np.diff(position, axis=0) - trapezoid).max() < 2e-6
    # the end values are the runs table's
    row = result.runs_values()
    assert history["position_error_m"].iloc[-1] == np.float32(row["position_error_end_m"])
    assert history["speed_m_s"].iloc[-1] == np.float32(row["speed_end_m_s"])
    assert history["tank_pressure_pa"].iloc[-1] == np.float32(row["tank_pressure_end_pa"])
    # an isothermal blow-down tank (002 eq. 1): the gas left, P V / (R T), is the pressure's fraction
    pressure = history["tank_pressure_pa"].to_numpy(dtype=float)
    assert (np.diff(pressure) <= 0.0).all() and pressure[0] == vehicle["rcs"]["feed"]["initial_pressure_pa"]
    np.testing.assert_allclose(history["fuel_remaining"], pressure / pressure[0], rtol=2e-7)
    # every command the law gave is in a row (one per control step): its changes are the runs
    # table's switches, the first opening counting
    for axis in "xyz":
        command = history[f"translation_command_{axis}"].to_numpy()
        assert set(np.unique(command)) <= {-1, 0, 1}
        changes = int((np.diff(np.concatenate([[0], command])) != 0).sum())
        assert changes == row[f"switches_{axis}"], axis
    # the law's +1 on x opens XP (thruster 1, bit 0) within the step (5 ms on-delay, 2 ms rise)
    # and never XN (bit 1)
    valves = history["valves_open"].to_numpy()
    pushing = history["translation_command_x"].to_numpy() == 1
    pushing[-1] = False
    assert pushing.any()
    assert ((valves[1:][pushing[:-1]] & 0b01) != 0).all() and ((valves[1:][pushing[:-1]] & 0b10) == 0).all()


def test_wheels_record_their_momenta_and_torques_within_their_limits():
    vehicle, _, result, history = _fly("irassi.yaml", "irassi-small-angle.yaml", 1.0 / 60.0)
    wheels = len(vehicle["wheels"]["units"])
    momenta = [f"wheel_momentum_{i}_n_m_s" for i in range(1, wheels + 1)]
    torques = [f"wheel_torque_{i}_n_m" for i in range(1, wheels + 1)]
    # no thruster fires: no propellant, valve or pulse columns; no trajectory: no altitude
    assert set(history.columns) == COMMON | ATTITUDE | set(momenta) | set(torques)
    row = result.runs_values()
    h = np.abs(history[momenta].to_numpy(dtype=float))
    assert h[-1].max() == pytest.approx(row["wheel_momentum_end_n_m_s"], rel=1e-6)  # float32
    assert h.max() <= row["wheel_momentum_peak_n_m_s"] * (1 + 1e-6)  # the peak is over every step
    assert h.max() > 1.0  # the wheels carry the constant torque's momentum over the flight
    tau = np.abs(history[torques].to_numpy(dtype=float))
    assert tau.max() <= vehicle["wheels"]["torque_max_n_m"] * (1 + 1e-6) and tau.max() > 0.0


@pytest.mark.parametrize(
    ("vehicle", "mission", "expected"),
    [
        ("refex.yaml", "refex-exo.yaml", COMMON | PROPELLANT | ATTITUDE | PULSES | {"altitude_m", "qbar_pa"}),
        ("generic-12.yaml", "generic-slew.yaml", COMMON | PROPELLANT | ATTITUDE | PULSES),
        (
            "refex-blow-down.yaml",
            "refex-exo.yaml",
            COMMON | PROPELLANT | ATTITUDE | PULSES | {"altitude_m", "qbar_pa", "tank_pressure_pa"},
        ),
    ],
)
def test_attitude_families_keep_their_columns_and_only_theirs(vehicle, mission, expected):
    _, _, _, history = _fly(vehicle, mission, 1.0)
    assert set(history.columns) == expected
    for column in expected - {"mode", "theta_t_deg"} - {c for c in ATTITUDE if c.startswith("theta_e")}:
        assert np.isfinite(history[column].to_numpy(dtype=float)).all(), column  # no mode without reference: NaN
