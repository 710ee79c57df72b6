"""The time-optimal law of 002 (eq. 41-46) on its normalised plant eq. 21 and, through the
scaling of core.time_optimal, on the physical direct-feed plant eq. 18-20."""

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import brentq, minimize_scalar

from refexmc.config import feed as config_feed
from refexmc.core import time_optimal as to
from tests import naive

FIG8 = (0.6, 0.5, 2.5)  # 002 sec. 5
X3_MIN = 0.5  # Fig. 8 does not state its reserve; 0.5 is inside eq. 45 (0 <= x3_min < 2.0)
DT = 1e-3  # 1 kHz: arrival needs a sample with |x2| <= 1e-3 while braking at x3 ~ 0.7 per unit time
TOLERANCE = 1e-3  # 002 Fig. 8's target: |x1|, |x2| <= 1e-3


def _legs(x0, t_accelerate):
    """(total, coast, brake, x3 at the end) after accelerating towards the origin for
    ``t_accelerate``: 002 eq. 33 into eq. 31 and 32 (= eq. 34-36), for x1 > 0."""
    x10, x20, x30 = x0
    decay = math.exp(-t_accelerate)
    x11 = x10 + x20 * t_accelerate - x30 * (decay + t_accelerate - 1.0)
    x21 = x20 + x30 * (decay - 1.0)
    x31 = x30 * decay
    brake = math.log(x31 / (x31 + x21))
    coast = -(x11 + x21 + (x31 + x21) * brake) / x21
    return t_accelerate + coast + brake, coast, brake, x31 * math.exp(-brake)


def _accelerate_bounds(x0):
    """Accelerating times with a coast formula: moving towards the origin (x2 < 0) and the
    origin still reachable (x3 + x2 > 0, eq. 46)."""
    _, x20, x30 = x0
    return math.log(x30 / (x30 - x20)) + 1e-9, math.log(2.0 * x30 / (x30 - x20)) - 1e-9


def optimum(x0):
    """Minimum of eq. 36 over the one free parameter Delta t_+ (scipy, independent of the law)."""
    low, high = _accelerate_bounds(x0)
    no_coast = brentq(lambda tp: _legs(x0, tp)[1], low, high, xtol=1e-15)  # past it the coast is negative
    best = minimize_scalar(
        lambda tp: _legs(x0, tp)[0], bounds=(low, no_coast), method="bounded", options={"xatol": 1e-12}
    )
    return best.x, _legs(x0, best.x)


def bang_bang_exact(x0):
    """Bang-bang: accelerate until the state is on sigma2 = 0 (no coast), then brake (eq. 29)."""
    low, high = _accelerate_bounds(x0)
    switch = brentq(lambda tp: _legs(x0, tp)[1], low, high, xtol=1e-15)
    return switch, _legs(x0, switch)


def _fly(x0, x3_min=X3_MIN, dt=DT, bang_bang=False):
    history = np.zeros((200_000, to.TO_HISTORY_SIZE))
    steps, arrived = to.fly_normalised(*x0, x3_min, dt, bang_bang, TOLERANCE, history.shape[0], history)
    return history[: steps + 1], arrived


def _phases(history):
    """(u, start time) of each run of equal commands, the final hold (u = 0 at arrival) left out."""
    u = history[:-1, to.TO_U]
    changes = np.flatnonzero(np.diff(u) != 0.0) + 1
    starts = np.concatenate([[0], changes])
    return [(float(u[i]) + 0.0, float(history[i, to.TO_T])) for i in starts]


def test_fig8_law_reaches_the_origin_with_one_acceleration_coast_and_brake():
    """002 Fig. 8: from [0.6, 0.5, 2.5] the law accelerates, coasts and brakes once each, arrives
    within 1e-3 with x3 >= x3_min, and its time is within 0.5 % of the optimum of eq. 34-36
    (the issue's acceptance; measured 0.0 %: 1.776 against 1.77643). The switch to coasting is
    the optimal Delta t_+ to within two control periods."""
    history, arrived = _fly(FIG8)
    assert arrived
    end = history[-1]
    assert abs(end[to.TO_X1]) <= TOLERANCE and abs(end[to.TO_X2]) <= TOLERANCE
    assert end[to.TO_X3] >= X3_MIN
    phases = _phases(history)
    assert [u for u, _ in phases] == [-1.0, 0.0, 1.0]
    t_accelerate, (t_optimal, coast, brake, x3_end) = optimum(FIG8)
    assert end[to.TO_T] == pytest.approx(t_optimal, rel=5e-3)
    assert phases[1][1] == pytest.approx(t_accelerate, abs=2 * DT)
    assert phases[2][1] == pytest.approx(t_accelerate + coast, abs=2 * DT)
    assert end[to.TO_X3] == pytest.approx(x3_end, rel=1e-2)


def test_fig8_bang_bang_is_slower_and_uses_more_fuel():
    """sigma2 alone: two phases, the time within 0.5 % of bang-bang's exact time (measured
    1.998 against 1.99892), and it ends with less fuel than the law (002 Fig. 8, sec. 6)."""
    history, arrived = _fly(FIG8, bang_bang=True)
    assert arrived
    phases = _phases(history)
    assert [u for u, _ in phases] == [-1.0, 1.0]
    switch, (t_exact, coast, _, x3_end) = bang_bang_exact(FIG8)
    assert coast == pytest.approx(0.0, abs=1e-9)
    assert history[-1, to.TO_T] == pytest.approx(t_exact, rel=5e-3)
    assert phases[1][1] == pytest.approx(switch, abs=2 * DT)
    law, _ = _fly(FIG8)
    assert history[-1, to.TO_X3] < law[-1, to.TO_X3]  # more fuel used
    assert history[-1, to.TO_T] > law[-1, to.TO_T]


def test_the_reserve_surface_keeps_the_fuel_above_x3_min():
    """x3_min = 1.0 binds (the unconstrained optimum ends at x3 = 0.712): the law coasts earlier
    (sigma1 = 0), arrives later and keeps x3 >= x3_min up to the braking of one control period."""
    history, arrived = _fly(FIG8, x3_min=1.0)
    assert arrived
    assert history[-1, to.TO_X3] >= 1.0 - 3 * DT * 2.5
    assert history[-1, to.TO_T] > optimum(FIG8)[1][0]
    assert [u for u, _ in _phases(history)] == [-1.0, 0.0, 1.0]


@pytest.mark.parametrize("sign", [1.0, -1.0])
@pytest.mark.parametrize("t_brake", [0.05, 0.4, 1.3])
@pytest.mark.parametrize("x33", [0.3, 2.0])
def test_sigma2_vanishes_on_the_braking_curve_of_eq27(sign, t_brake, x33):
    """eq. 27 (and its mirror, eq. 41-43's transformation) parametrises sigma2 = 0; 1e-12
    absolute for terms of order 1."""
    x1 = sign * x33 * (math.exp(t_brake) - 1.0 - t_brake)
    x2 = sign * x33 * (1.0 - math.exp(t_brake))
    x3 = x33 * math.exp(t_brake)
    assert to.sigma2(x1, x2, x3) == pytest.approx(0.0, abs=1e-12)


def test_law_matches_the_naive_twin_on_a_grid():
    """The kernel's u against tests/naive.py's eq. 44 written out, over a grid of states that
    straddles every surface (x3 from 0.2 to 3, both signs of x1 and x2, reserve 0 and 0.5)."""
    grid = np.linspace(-1.5, 1.5, 13)
    for x1 in grid:
        for x2 in grid:
            for x3 in (0.2, 1.0, 2.5, 3.0):
                for x3_min in (0.0, 0.5):
                    for bang_bang in (False, True):
                        assert to.command(x1, x2, x3, x3_min, bang_bang) == naive.time_optimal_u(
                            x1, x2, x3, x3_min, bang_bang
                        ), (x1, x2, x3, x3_min, bang_bang)


def test_the_physical_plant_through_the_scaling_switches_at_the_same_scaled_times():
    """A 2 kg vehicle, 0.5 l nitrogen tank at 3 bar, 0.2 mm^2 throat (tau 9.8 s, a0 0.05 m/s^2):
    eq. 18-20 (vacuum) integrated by scipy with the law applied every tau * DT to the scaled state
    (core.time_optimal.scale, L = 1 m), against the normalised law from the scaled initial state.
    Same sampled commands, and switching times / tau equal to 1e-9 (the plants agree to the
    integrator's 1e-12; a command would differ only if a surface were within that of a sample)."""
    tank = {
        "tank_volume_m3": 0.0005,
        "gas_constant_j_kg_k": 296.8,
        "heat_capacity_ratio": 1.4,
        "temperature_k": 293.0,
        "initial_pressure_pa": 3e5,
        "throat_area_m2": 0.2e-6,
        "expansion_ratio": 20.0,
    }
    mass = 2.0
    design = config_feed.design(tank)
    tau = design["blow_down_time_constant_s"]
    accel_per_pa = design["thrust_coefficient"] * tank["throat_area_m2"] / mass  # f1 / (m x3), eq. 19
    p0 = tank["initial_pressure_pa"]
    x0_physical = (0.6 * 1.0 / 1.0, 0.5 / tau, p0)  # chosen to scale onto Fig. 8's x1, x2
    scaled0 = to.scale(x0_physical[0], x0_physical[1], accel_per_pa, p0, tau, 1.0)
    assert tau > 1.0 and scaled0[2] > 0.0
    normalised, arrived = _fly(scaled0)
    assert arrived

    def rhs(_t, y, u):  # eq. 18 with eq. 19, 20 in vacuum
        return [y[1], u * accel_per_pa * y[2], -abs(u) * y[2] / tau]

    y = np.array(x0_physical, dtype=float)
    commands = []
    for _ in range(normalised.shape[0] - 1):
        x1, x2, x3 = to.scale(y[0], y[1], accel_per_pa, y[2], tau, 1.0)
        u = to.command(x1, x2, x3, X3_MIN, False)
        commands.append(u)
        h = tau * DT
        y = solve_ivp(rhs, (0.0, h), y, args=(u,), method="DOP853", rtol=1e-13, atol=1e-15).y[:, -1]
    np.testing.assert_array_equal(commands, normalised[:-1, to.TO_U])
    x1, x2, x3 = to.scale(y[0], y[1], accel_per_pa, y[2], tau, 1.0)
    assert (x1, x2, x3) == pytest.approx(tuple(normalised[-1, 1:4]), rel=1e-9, abs=1e-9)


@pytest.mark.parametrize("length", [0.01, 1.0, 7.3])
@pytest.mark.parametrize("u", [-1.0, 0.0, 1.0])
def test_scaling_maps_the_physical_plant_onto_eq21_for_any_length(length, u):
    """core.time_optimal.scale (module doc): X1 = x1 / L, X2 = x2 tau / L, X3 = k P tau^2 / L
    carries eq. 18-20 in vacuum onto eq. 21 for any L. The physical plant integrated by scipy
    over 0.3 tau, scaled at both ends, against eq. 21's closed form over 0.3 (advance): 1e-9
    relative (DOP853 at rtol 1e-13; terms of order 1). L = 1 alone would not see an L put on
    the wrong side of any of the three."""
    tau, accel_per_pa = 9.8, 1.7e-7  # s, m/s^2 per Pa: the 2 kg vehicle of the test above
    y0 = [0.4, -0.03, 2.5e5]  # m, m/s, Pa

    def rhs(_t, y):  # eq. 18 with eq. 19, 20 in vacuum
        return [y[1], u * accel_per_pa * y[2], -abs(u) * y[2] / tau]

    y1 = solve_ivp(rhs, (0.0, 0.3 * tau), y0, method="DOP853", rtol=1e-13, atol=1e-15).y[:, -1]
    start = to.scale(y0[0], y0[1], accel_per_pa, y0[2], tau, length)
    end = to.scale(y1[0], y1[1], accel_per_pa, y1[2], tau, length)
    assert to.advance(*start, u, 0.3) == pytest.approx(end, rel=1e-9, abs=1e-12 / length)
    # and the law, homogeneous in the scaled state, gives the same command at every L
    assert to.command(*start, 0.1 * start[2], False) == to.command(
        *to.scale(y0[0], y0[1], accel_per_pa, y0[2], tau, 1.0), 0.1 * (start[2] * length), False
    )


@pytest.mark.parametrize("x2", [0.5, -0.5, 2.0, -2.0])
@pytest.mark.parametrize("x3_over_speed", [1.0, 0.5])
def test_each_surface_says_brake_where_the_origin_is_out_of_reach_eq46(x2, x3_over_speed):
    """002 eq. 46: with x3 <= |x2| the thrust left cannot stop the vehicle; sigma0 and sigma2
    then have the sign of x2, so eq. 44 and bang-bang brake (u = -sign x2), x3 = |x2| included
    (there the logarithms of eq. 41, 43 are undefined). The naive twin says the same."""
    x3 = x3_over_speed * abs(x2)
    for x1 in (-1.0, 0.0, 1.0):
        assert to._sign(to.sigma0(x1, x2, x3)) == math.copysign(1.0, x2)
        assert to._sign(to.sigma2(x1, x2, x3)) == math.copysign(1.0, x2)
        for bang_bang in (False, True):
            u = to.command(x1, x2, x3, 0.0, bang_bang)
            assert u == -math.copysign(1.0, x2) == naive.time_optimal_u(x1, x2, x3, 0.0, bang_bang)


def test_fly_normalised_records_every_step_and_stops_the_law_on_arrival():
    """fly_normalised's contract: row k is the state at t = k dt (the time as k * dt, no sum of
    steps) with the command then held; the row at arrival has u = 0; a history shorter than the
    flight keeps its first rows and changes nothing else; a flight cut at max_steps reports that
    it did not arrive."""
    full, arrived = _fly(FIG8)
    assert arrived
    steps = full.shape[0] - 1
    np.testing.assert_array_equal(full[:, to.TO_T], np.arange(steps + 1) * DT)
    assert full[-1, to.TO_U] == 0.0 and full[-2, to.TO_U] != 0.0
    short = np.full((10, to.TO_HISTORY_SIZE), np.nan)
    assert to.fly_normalised(*FIG8, X3_MIN, DT, False, TOLERANCE, 200_000, short) == (steps, True)
    np.testing.assert_array_equal(short, full[:10])
    cut = np.zeros((200_000, to.TO_HISTORY_SIZE))
    assert to.fly_normalised(*FIG8, X3_MIN, DT, False, TOLERANCE, steps // 2, cut) == (steps // 2, False)
    np.testing.assert_array_equal(cut[: steps // 2], full[: steps // 2])
