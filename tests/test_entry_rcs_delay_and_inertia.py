"""The entry's RCS delay and its true-against-flight-software inertia (issue 24, point 8: "mass
and inertia ..., RCS delays"): core.entry_flight.advance against the closed form of a delayed
moment step, the delay changes the flight and is bit-for-bit absent at 0, the drawn inertia is
the truth's and not the flight software's."""

import copy
import math
from pathlib import Path

import numpy as np
import pytest
from test_entry_flight import prepare

from refexmc import simulate
from refexmc.campaign.entry_plan import EntryRunPlan
from refexmc.config import entry as config_entry
from refexmc.config.load import load_campaign, load_mission, load_vehicle
from refexmc.core import entry_flight as ef

ROOT = Path(__file__).resolve().parents[1]
VEHICLE = ROOT / "configs/vehicles/x38.yaml"
BLOCKED_MISSION = ROOT / "configs/missions/x38-entry-right-flap-blocked.yaml"
Q = ef.ENTRY_STATE_SIZE  # the quaternion's first slot; body rates at Q + 4 .. Q + 6


def _airless():
    """The test entry with every true aerodynamic coefficient zero: only the thrusters turn it."""
    flown, initial = prepare()
    model = flown.model._replace(coefficients=np.zeros_like(flown.model.coefficients))
    return flown._replace(model=model), initial


@pytest.mark.parametrize("delay_s", [0.0, 0.01, 0.025, 0.06, 0.099])
def test_a_delayed_moment_step_turns_the_vehicle_as_the_closed_form(delay_s):
    """Pitch moment tau0 until the delay, tau1 after it, from rest, about the principal y axis
    (I_xy = I_yz = 0 in x38.yaml, so omega x J omega = 0 and the axis stays fixed): the rate is
    q = (tau0 d + tau1 (T - d)) / I_yy and the angle
    theta = (tau0 d^2 / 2 + tau0 d (T - d) + tau1 (T - d)^2 / 2) / I_yy at the period's end T.
    RK4 is exact for a piecewise-constant moment on each side of the switch, so the rate agrees to
    rounding (1e-12 relative); the angle comes through the quaternion kinematics (RK4 truncation
    ~(omega T)^5 ~ 1e-20 here) and a 2e-4-rad vector part read back to double precision: 1e-9."""
    flown, initial = _airless()
    wk = ef.work()
    wk.state[:] = initial
    tau0, tau1, period = 1500.0, -2500.0, 0.1
    wk.thruster_previous[:] = [0.0, tau0, 0.0]
    wk.thruster[:] = [0.0, tau1, 0.0]
    ef.advance(flown, wk, 0.0, period, delay_s)
    i_yy = flown.inertia[1, 1]
    late = period - delay_s
    if delay_s == 0.0:  # no delay: this period's moment from the control instant
        tau0 = tau1
    q_expected = (tau0 * delay_s + tau1 * late) / i_yy
    theta_expected = (0.5 * tau0 * delay_s**2 + tau0 * delay_s * late + 0.5 * tau1 * late**2) / i_yy
    rates = wk.state[Q + 4 : Q + 7]
    assert rates[1] == pytest.approx(q_expected, rel=1e-12)
    assert abs(rates[0]) < 1e-15 and abs(rates[2]) < 1e-15
    q0, q1 = initial[Q : Q + 4], wk.state[Q : Q + 4]  # scalar-last quaternions (core.quaternion)
    # q0^-1 (x) q1, the rotation between them: its scalar and vector parts, then its angle
    w = q0 @ q1
    v = q0[3] * q1[:3] - q1[3] * q0[:3] - np.cross(q0[:3], q1[:3])
    assert 2.0 * math.atan2(np.linalg.norm(v), w) == pytest.approx(abs(theta_expected), rel=1e-9)
    assert abs(v[0]) < 1e-14 and abs(v[2]) < 1e-14  # about body y alone
    # afterwards both slots hold this period's moment, the next period's "previous"
    assert list(wk.thruster) == list(wk.thruster_previous) == [0.0, -2500.0, 0.0]


def _blocked_flight(**changes):
    vehicle = load_vehicle(VEHICLE)
    mission = load_mission(BLOCKED_MISSION)
    mission["entry_flight"].update(changes)
    return simulate.fly_entry(*config_entry.entry_flight_from_mission(vehicle, mission))


def test_an_rcs_delay_changes_the_flight_and_zero_is_the_flight_without_one():
    """0 ms (x38-entry-right-flap-blocked.yaml declares it) flies bit for bit the mission without
    the key; 30 ms (the valves' on-delay plus rise) changes the propellant and the tracking but the
    entry still reaches Mach 2 within the bounds of tests/test_entry_flight.py."""
    zero = _blocked_flight()
    mission = load_mission(BLOCKED_MISSION)
    del mission["entry_flight"]["rcs_delay_ms"]
    absent = simulate.fly_entry(*config_entry.entry_flight_from_mission(load_vehicle(VEHICLE), mission))
    np.testing.assert_array_equal(zero.summary, absent.summary)
    np.testing.assert_array_equal(zero.history, absent.history)
    late = _blocked_flight(rcs_delay_ms=30.0)
    assert late.success
    assert late.summary[ef.SU_PROPELLANT] != zero.summary[ef.SU_PROPELLANT]
    assert late.summary[ef.SU_ALPHA_ERROR] != zero.summary[ef.SU_ALPHA_ERROR]
    assert math.degrees(late.summary[ef.SU_ALPHA_ERROR]) < 1.0
    assert math.degrees(late.summary[ef.SU_BANK_ERROR]) < 5.0


def test_an_rcs_delay_of_a_control_period_or_more_is_refused():
    vehicle, mission = load_vehicle(VEHICLE), load_mission(BLOCKED_MISSION)
    mission["entry_flight"]["rcs_delay_ms"] = 100.0  # x38 controls at 10 Hz
    with pytest.raises(ValueError, match=r"RCS delay in \[0, 100\) ms"):
        config_entry.entry_flight_from_mission(vehicle, mission)


INERTIA = np.array([[16000.0, 0.0, -2500.0], [0.0, 42000.0, 0.0], [-2500.0, 0.0, 59000.0]])  # not x38's


def test_the_drawn_inertia_flies_the_truth_and_the_flight_software_keeps_the_nominal():
    """EntryRunPlan.flight with an inertia_kg_m2 draw: the dynamics' inertia (and its inverse) is
    the drawn tensor, the dynamic inversion's is the vehicle file's."""
    plan = EntryRunPlan(load_campaign(ROOT / "campaigns/x38-blocked-flap.yaml"))
    nominal = np.asarray(plan.vehicle["inertia_kg_m2"], dtype=float)
    values = plan.sampler.values(0)  # the nominal run's values, the inertia replaced
    values["inertia_kg_m2"] = np.array([INERTIA[a, b] for a, b in ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2))])
    flown, _ = plan.flight(values)
    np.testing.assert_array_equal(flown.inertia, INERTIA)
    np.testing.assert_allclose(flown.inertia_inv @ INERTIA, np.eye(3), atol=1e-15)
    np.testing.assert_array_equal(flown.fsw_inertia, nominal)
    undispersed, _ = plan.flight(plan.sampler.values(0))
    np.testing.assert_array_equal(undispersed.inertia, nominal)
    np.testing.assert_array_equal(undispersed.fsw_inertia, nominal)


def test_the_controller_uses_the_flight_softwares_inertia_and_the_dynamics_the_true_one():
    """One control period from the same state: another true inertia leaves the commands
    unchanged, another flight-software inertia changes them; the rotational derivative follows the
    true inertia."""
    flown, initial = prepare(blocked=("right", 14.0))
    initial = initial.copy()
    initial[Q + 4 : Q + 7] = [0.01, -0.02, 0.015]  # rates, so that omega x J omega matters too
    truth_changed = flown._replace(inertia=INERTIA, inertia_inv=np.linalg.inv(INERTIA))
    fsw_changed = flown._replace(fsw_inertia=INERTIA)

    def period(vehicle):
        wk = ef.work()
        wk.state[:] = initial
        rate = ef.control(vehicle, wk, 0.0, math.radians(45.0), math.radians(60.0))[0]
        derivative = np.zeros(ef.FLIGHT_STATE_SIZE)
        ef.derivative(vehicle, wk, initial, 0.0, derivative)
        return rate, wk.thruster.copy(), wk.command.copy(), derivative

    base, truth, fsw = period(flown), period(truth_changed), period(fsw_changed)
    assert truth[0] == base[0]
    np.testing.assert_array_equal(truth[1], base[1])
    np.testing.assert_array_equal(truth[2], base[2])
    assert not np.array_equal(fsw[1], base[1])  # the dynamic inversion's moment moved
    assert not np.array_equal(truth[3][Q + 4 :], base[3][Q + 4 :])  # the true rotation did
    np.testing.assert_array_equal(truth[3][:Q], base[3][:Q])  # the translation did not


def test_a_dispersed_inertia_changes_the_flight():
    vehicle, mission = load_vehicle(VEHICLE), load_mission(BLOCKED_MISSION)
    nominal = simulate.fly_entry(*config_entry.entry_flight_from_mission(vehicle, copy.deepcopy(mission)))
    dispersed = simulate.fly_entry(*config_entry.entry_flight_from_mission(vehicle, mission, inertia=INERTIA))
    assert dispersed.success
    assert dispersed.summary[ef.SU_PROPELLANT] != nominal.summary[ef.SU_PROPELLANT]
