"""IRASSI's acquisition against an independent re-simulation (issue 33): the same model (001 eq. 1,
5-6, 11-12, the flight software's distribution, friction compensation and limits) flown by
scipy's DOP853 at rtol 1e-11, restarted at every control sample with the motor torques held
(zero-order hold), its flight software written from the tests' naive twins (tests/naive.py).

The torque-limited acquisition pushes every wheel through its friction's zero-speed zone (001
eq. 1 linear within +-1 rpm) several times, each in 0.07-0.14 s; refexmc's 1 s RK4 step must end
sub-steps on the zone's edges (core.wheels.step) to follow the reference."""

import math
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.spatial.transform import Rotation

from refexmc.config.load import load_mission, load_vehicle
from refexmc.config.pack import mode_names, pack
from refexmc.core import layout as L
from refexmc.simulate import fly
from tests import naive

ROOT = Path(__file__).resolve().parents[1]
ARCSEC = math.pi / (180.0 * 3600.0)
FLOWN_S = 300  # the acquisition (about 230 s) and some science; wheel_saturated_s counts within it


def _short_irassi():
    """The nominal small-angle flight of the vehicle file, its science mode ended at FLOWN_S."""
    vehicle = load_vehicle(ROOT / "configs/vehicles/irassi.yaml")
    mission = load_mission(ROOT / "configs/missions/irassi-small-angle.yaml")
    mission["modes"][1]["exit"] = [{"mission_time_s": float(FLOWN_S)}]
    mission["max_flight_time_s"] = FLOWN_S + 10.0
    mission["pointing_statistics_from_s"] = 0.0
    return mission, pack(vehicle, mission)


def _friction(speed, coulomb, viscous, width):
    """001 eq. 1, the sign linear within +-width (the model's decision, docs/irassi.md)."""
    return -coulomb * np.clip(speed / width, -1.0, 1.0) - viscous * speed


def _motor(inputs, x, h, torque_cmd):
    """The flight software's motor torques with perfect navigation: -D (u + omega x W h), the design
    friction cancelled at the tachometer speeds, null-space management (001 sec. 9.1's n), the
    vector scaled to the torque limit, a wheel at its momentum limit not driven further (the
    rules of docs/irassi.md). Returns (motor, limited)."""
    table = inputs.wheels
    n = table.shape[0]
    axes = table[:, L.W_AXIS : L.W_AXIS + 3].T
    spin = table[:, L.W_SPIN_INERTIA]
    omega = x[4:7]
    relative = h[:n] - spin * (axes.T @ omega)
    demand = -inputs.wheel_distribution @ (torque_cmd + np.cross(omega, axes @ h[:n]))
    demand -= _friction(
        relative / spin, table[:, L.W_COULOMB_DESIGN], table[:, L.W_VISCOUS_DESIGN], table[:, L.W_COULOMB_WIDTH]
    )
    demand += naive.wheel_null_space_torque(
        axes,
        np.ones(n, bool),
        relative,
        table[:, L.W_NULL_SPACE_BIAS],
        table[0, L.W_NULL_SPACE_RATE],
        table[0, L.W_NULL_SPACE_DEADBAND],
        table[0, L.W_NULL_SPACE_TORQUE_MAX],
    )
    scale = min(1.0, *(table[i, L.W_TORQUE_MAX] / abs(demand[i]) for i in range(n) if demand[i] != 0.0))
    motor = demand * scale
    at_limit = (np.abs(relative) >= table[:, L.W_MOMENTUM_MAX]) & (motor * relative > 0.0)
    return np.where(at_limit, 0.0, motor), bool(scale < 1.0 or at_limit.any())


def _reference_flight(mission, inputs):
    """The flight sampled at 1 Hz: (the error rotation vectors before each sample's command (rad,
    rows), t_manoeuvre_s, wheel_saturated_s)."""
    table = inputs.wheels
    wheels = naive.NaiveWheels(
        table[:, L.W_AXIS : L.W_AXIS + 3].T.copy(),
        table[:, L.W_SPIN_INERTIA].copy(),
        table[:, L.W_COULOMB].copy(),
        table[:, L.W_VISCOUS].copy(),
        table[:, L.W_COULOMB_WIDTH].copy(),
        table[:, L.W_TORQUE_MAX].copy(),
        table[:, L.W_MOMENTUM_MAX].copy(),
        table[:, L.W_FAILED] != 0.0,
    )
    inertia = inputs.vehicle[L.V_INERTIA : L.V_INERTIA + 9].reshape(3, 3)
    fsw_inertia = inputs.fsw[L.F_INERTIA : L.F_INERTIA + 9].reshape(3, 3)
    smc = [inputs.fsw[k : k + 3] for k in (L.F_SMC_SLOPE, L.F_SMC_GAIN, L.F_SMC_LAYER)]
    gg = inputs.mission[L.M_GG_COEFFICIENT]
    direction = inputs.mission[L.M_GG_DIRECTION : L.M_GG_DIRECTION + 3]
    u_const = np.asarray(mission["disturbances"]["constant_torque_n_m"], float)
    euler = mission["initial_state"]["attitude_euler_deg"]
    target = Rotation.from_euler("xyz", mission["modes"][0]["target"]["euler_deg"], degrees=True)
    x = np.concatenate([Rotation.from_euler("xyz", euler, degrees=True).as_quat(), np.zeros(3)])
    h = np.concatenate([table[:, L.W_MOMENTUM0], np.zeros(3)])  # omega_0 = 0: h = I_w Omega
    angle_below = math.radians(mission["modes"][0]["exit"][0]["angle_error_below_deg"])
    rate_below = math.radians(mission["modes"][0]["exit"][0]["rate_error_below_deg_s"])

    def rate(_t, y, motor):
        dx, dh = naive.wheel_state_rate(y[:7], y[7:], motor, u_const, wheels, inertia, gg, direction)
        return np.concatenate([dx, dh])

    errors, t_manoeuvre, saturated = [], None, 0.0
    for k in range(FLOWN_S):
        error = target.inv() * Rotation.from_quat(x[:4])
        q_error = error.as_quat()
        q_error = -q_error if q_error[3] < 0.0 else q_error
        errors.append(error.as_rotvec())
        if t_manoeuvre is None and error.magnitude() < angle_below and np.linalg.norm(x[4:7]) < rate_below:
            t_manoeuvre = float(k)
        u = naive.sliding_mode_torque(q_error, x[4:7], x[4:7], np.zeros(3), *smc, fsw_inertia)
        motor, limited = _motor(inputs, x, h, u)
        saturated += float(limited)
        # rtol 1e-11: halving it moves the attitude by < 1e-6 arcsec (measured); DOP853's error
        # control rejects the steps across the zone's edges until each meets it
        solution = solve_ivp(
            rate, (k, k + 1.0), np.concatenate([x, h]), method="DOP853", rtol=1e-11, atol=1e-14, args=(motor,)
        )
        x, h = solution.y[:7, -1].copy(), solution.y[7:, -1].copy()
        x[:4] /= np.linalg.norm(x[:4])
    return np.asarray(errors), t_manoeuvre, saturated


@pytest.mark.slow
def test_acquisition_follows_the_reference_within_an_arcsec_and_its_mode_times_within_a_period():
    """Over the acquisition (t <= t_manoeuvre_s) the controller's attitude error agrees with the
    reference within 1 arcsec at every sample (issue 33; main's 1 s RK4 across the zone's edges
    was 151 arcsec off at t = 208 s), and t_manoeuvre_s and wheel_saturated_s within one control
    period (main: 228 s and 218 s, the reference 230 s and 223 s)."""
    mission, inputs = _short_irassi()
    result = fly(inputs, 0, 1.0, mode_names(mission))
    values = result.runs_values()
    flown = np.radians(result.column("theta_e_deg"))
    reference, t_manoeuvre, saturated = _reference_flight(mission, inputs)
    assert t_manoeuvre is not None
    assert abs(values["t_manoeuvre_s"] - t_manoeuvre) <= 1.0, (values["t_manoeuvre_s"], t_manoeuvre)
    assert abs(values["wheel_saturated_s"] - saturated) <= 1.0, (values["wheel_saturated_s"], saturated)
    acquisition = int(min(values["t_manoeuvre_s"], t_manoeuvre)) + 1
    difference = np.abs(flown[:acquisition] - reference[:acquisition]).max() / ARCSEC
    assert difference < 1.0, difference
