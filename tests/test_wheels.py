"""Reaction-wheel kernels (core.wheels) and the sliding-mode controller (core.control, 001 eq. 12)
against their slow twins in tests/naive.py, solve_ivp, scipy Rotation, closed forms and the
conservation of angular momentum."""

import math

import naive
import numpy as np
import pytest
import scipy.linalg
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import solve_ivp
from scipy.spatial.transform import Rotation

from refexmc.core import control, quaternion, wheels
from refexmc.core import layout as L

# 001 sec. 11.1 (IRASSI principal inertia) and Table 3 (JWST / Rockwell Collins wheel)
INERTIA = np.diag([2059.5, 5954.2, 5974.3])
SPIN_INERTIA, COULOMB, VISCOUS = 0.1295, 0.005, 2.1241e-5
COULOMB_WIDTH = 2.0 * math.pi / 60.0  # 1 rpm (estimate): I_w width / tau_e = 2.7 s, resolved by 1 s RK4 steps


def pyramid_axes(beta_deg=54.7356):
    """001 sec. 8.1's W4 with a = d = sin(beta), b = c = cos(beta): four unit spin axes."""
    a, b = math.sin(math.radians(beta_deg)), math.cos(math.radians(beta_deg))
    return np.array([[b, b, b, b], [0.0, a, 0.0, -a], [a, 0.0, -a, 0.0]])


def wheel_table(axes, torque_max=math.inf, momentum_max=math.inf, failed=(), momentum0=None):
    n = axes.shape[1]
    table = np.zeros((n, L.WHEEL_SIZE))
    for i in range(n):
        table[i, L.W_AXIS : L.W_AXIS + 3] = axes[:, i]
        table[i, L.W_SPIN_INERTIA] = SPIN_INERTIA
        table[i, L.W_TORQUE_MAX] = torque_max
        table[i, L.W_MOMENTUM_MAX] = momentum_max
        table[i, L.W_COULOMB] = COULOMB
        table[i, L.W_VISCOUS] = VISCOUS
        table[i, L.W_COULOMB_WIDTH] = COULOMB_WIDTH
        table[i, L.W_COULOMB_DESIGN] = COULOMB
        table[i, L.W_VISCOUS_DESIGN] = VISCOUS
        table[i, L.W_FAILED] = 1.0 if i in failed else 0.0
        table[i, L.W_MOMENTUM0] = 0.0 if momentum0 is None else momentum0[i]
    return table


def naive_wheels(table):
    axes = table[:, L.W_AXIS : L.W_AXIS + 3].T.copy()
    return naive.NaiveWheels(
        axes,
        table[:, L.W_SPIN_INERTIA].copy(),
        table[:, L.W_COULOMB].copy(),
        table[:, L.W_VISCOUS].copy(),
        table[:, L.W_COULOMB_WIDTH].copy(),
        table[:, L.W_TORQUE_MAX].copy(),
        table[:, L.W_MOMENTUM_MAX].copy(),
        table[:, L.W_FAILED] != 0.0,
    )


def started(table, x, gg=0.0, direction=(0.0, 0.0, 1.0), inertia=INERTIA):
    plant = wheels.plant(table)
    wheels.start(plant, np.asarray(inertia, float), x, gg, np.asarray(direction, float))
    return plant


def random_state(rng):
    q = Rotation.random(random_state=rng).as_quat()
    return np.concatenate([q, rng.normal(0.0, 0.02, 3)])


def test_derivative_equals_the_naive_twin():
    """Every component of d/dt [q, omega, h, p] on random states, motors and torques; the two share
    no code (closed-form matrix algebra vs the kernel's unrolled sums). 1e-12 relative: rounding."""
    rng = np.random.default_rng(14)
    table = wheel_table(pyramid_axes())
    for _ in range(50):
        x = random_state(rng)
        plant = started(
            table, x, gg=1.57e-13 * rng.uniform(1, 1e6), direction=Rotation.random(random_state=rng).as_matrix()[:, 0]
        )
        plant.h[:4] = rng.normal(0.0, 20.0, 4)
        plant.motor[:] = rng.normal(0.0, 0.1, 4)
        torque = rng.normal(0.0, 1e-3, 3)
        dx, dh = np.zeros(7), np.zeros(7)
        wheels.derivative(x, plant.h, torque, plant, dx, dh)
        ndx, ndh = naive.wheel_state_rate(
            x, plant.h, plant.motor, torque, naive_wheels(table), INERTIA, plant.gravity[0], plant.gravity[1:4]
        )
        np.testing.assert_allclose(dx, ndx, rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(dh, ndh, rtol=1e-12, atol=1e-15)


def test_rk4_follows_solve_ivp():
    """200 s of a tumbling body with friction, held motor torques, a body torque and a strong
    gravity gradient: kernel RK4 at 0.05 s against DOP853 at rtol 1e-12 on the naive derivative.
    RK4's global error ~ (omega h)^4 ~ (0.05 * 0.05)^4: 1e-9 covers it with margin."""
    table = wheel_table(pyramid_axes(), momentum0=[5.0, -3.0, 8.0, 1.0])
    x = np.concatenate([Rotation.from_rotvec([0.3, -0.2, 0.5]).as_quat(), [0.01, -0.02, 0.015]])
    gg, direction = 1e-6, np.array([0.6, 0.0, 0.8])
    plant = started(table, x, gg, direction)
    plant.motor[:] = [0.05, -0.02, 0.01, 0.03]
    torque = np.array([1e-3, -2e-3, 5e-4])
    y0 = np.concatenate([x, plant.h])
    ref = naive_wheels(table)

    def rhs(_, y):
        dx, dh = naive.wheel_state_rate(y[:7], y[7:], plant.motor, torque, ref, INERTIA, gg, direction)
        return np.concatenate([dx, dh])

    solution = solve_ivp(rhs, (0.0, 200.0), y0, method="DOP853", rtol=1e-12, atol=1e-14)
    for _ in range(4000):
        wheels.rk4_step(x, 0.05, torque, torque, plant)
    end = solution.y[:, -1]
    assert quaternion.angle_between(x[:4], end[:4] / np.linalg.norm(end[:4])) < 1e-9
    np.testing.assert_allclose(x[4:7], end[4:7], atol=1e-9 * np.abs(end[4:7]).max())
    np.testing.assert_allclose(plant.h, end[7:], rtol=1e-9, atol=1e-9)


def _one_second(table, x, h, motor, torque):
    """solve_ivp's DOP853 at rtol 1e-12 over 1 s on the naive derivative (its error control
    rejects steps across the zone's edges until each meets the tolerance)."""
    ref = naive_wheels(table)

    def rhs(_, y):
        dx, dh = naive.wheel_state_rate(y[:7], y[7:], motor, torque, ref, INERTIA)
        return np.concatenate([dx, dh])

    return solve_ivp(rhs, (0.0, 1.0), np.concatenate([x, h]), method="DOP853", rtol=1e-12, atol=1e-15).y[:, -1]


@pytest.mark.parametrize("through", [False, True])
def test_step_ends_sub_steps_on_the_zero_speed_zone_and_follows_solve_ivp(through):
    """A 1 s step in which the motors push wheel 1 across the friction's +-1 rpm zone (from +2 rpm
    into it, or ``through`` it from +3 to -8 rpm, as IRASSI's torque-limited acquisition does:
    issue 33): core.wheels.step against solve_ivp (which agrees with an event-split solve_ivp to
    3e-14 N m s). Within the zone the friction is linear with time constant I_w w / tau_e = 2.7 s;
    RK4 over the 0.46 s left there errs by about tau_e h (h / 2.7 s)^4 / 120 = 2e-8 N m s
    (measured 7.5e-8 into the zone, 1.3e-9 through it), hence 2e-7 N m s on the momenta and 1e-10
    rad/s on the body rate (measured 2e-11). The plain RK4 step across the kinks is off by
    2e-4 to 3e-4 N m s: more than 1e-5 here. It takes more than one RK4 step."""
    rpm = 2.0 * math.pi / 60.0
    table = wheel_table(pyramid_axes())
    x = np.concatenate([Rotation.from_rotvec([0.1, 0.2, -0.1]).as_quat(), [1e-4, -2e-4, 5e-5]])
    plant = started(table, x)
    speeds0 = np.array([3.0 if through else 2.0, 40.0, -30.0, 60.0]) * rpm
    axes = table[:, L.W_AXIS : L.W_AXIS + 3]
    plant.h[:4] = SPIN_INERTIA * (speeds0 + axes @ x[4:7])
    plant.motor[:] = [-0.2 if through else -0.02, 0.01, -0.01, 0.02]
    torque = np.array([1e-3, -2e-3, 5e-4])
    end = _one_second(table, x, plant.h, plant.motor, torque)
    speed_end = end[7] / SPIN_INERTIA - axes[0] @ end[4:7]
    assert speed_end < -rpm if through else abs(speed_end) < rpm  # through the zone, or into it
    plain_x, plain_h = x.copy(), plant.h.copy()
    taken = wheels.step(x, 1.0, torque, torque, plant)
    assert taken > 1
    np.testing.assert_allclose(x[4:7], end[4:7], rtol=0, atol=1e-10)
    np.testing.assert_allclose(plant.h, end[7:], rtol=0, atol=2e-7)
    plant.h[:] = plain_h
    wheels.rk4_step(plain_x, 1.0, torque, torque, plant)
    assert np.abs(plant.h - end[7:]).max() > 1e-5


def test_step_away_from_the_zone_is_the_plain_rk4_step_to_the_bit():
    """Wheels that stay outside the zone (or inside it) cross no edge: one RK4 step, the same bits."""
    rng = np.random.default_rng(33)
    table = wheel_table(pyramid_axes())
    axes = table[:, L.W_AXIS : L.W_AXIS + 3]
    for inside in (False, True):
        x = random_state(rng) * np.r_[np.ones(4), 1e-2 * np.ones(3)]
        x[:4] /= np.linalg.norm(x[:4])
        plant = started(table, x)
        speeds = rng.uniform(0.1, 0.5, 4) * COULOMB_WIDTH if inside else rng.uniform(50.0, 100.0, 4)
        plant.h[:4] = SPIN_INERTIA * (speeds + axes @ x[4:7])
        plant.motor[:] = rng.normal(0.0, 1e-3 if inside else 0.1, 4)
        torque_start, torque_end = rng.normal(0.0, 1e-3, 3), rng.normal(0.0, 1e-3, 3)
        h0, x_plain = plant.h.copy(), x.copy()
        assert wheels.step(x, 1.0, torque_start, torque_end, plant) == 1
        h_step = plant.h.copy()
        plant.h[:] = h0
        wheels.rk4_step(x_plain, 1.0, torque_start, torque_end, plant)
        assert np.array_equal(x, x_plain) and np.array_equal(h_step, plant.h)


def test_angular_momentum_is_conserved_without_external_torque():
    """No external torque: the inertial total angular momentum (computed here with scipy's
    Rotation, not the kernel) stays put through 22 h of wheel commands changing every second and
    Coulomb friction switching signs; 1e-9 relative (RK4 at 1 s, rates ~1e-3 rad/s)."""
    rng = np.random.default_rng(7)
    table = wheel_table(pyramid_axes())
    x = np.concatenate([Rotation.from_euler("ZYX", [14, 14, 14], degrees=True).as_quat(), [1e-4, -2e-4, 5e-5]])
    plant = started(table, x)
    ref = naive_wheels(table)

    def total():
        n = ref.axes.shape[1]
        inertia_b = INERTIA - sum(SPIN_INERTIA * np.outer(ref.axes[:, i], ref.axes[:, i]) for i in range(n))
        body = inertia_b @ x[4:7] + ref.axes @ plant.h[:n]
        return Rotation.from_quat(x[:4]).apply(body)

    start = total()
    zero = np.zeros(3)
    for step in range(79200):
        if step % 60 == 0:
            plant.motor[:] = rng.normal(0.0, 2e-3, 4)  # 0.5 N m s per wheel per minute at most
        wheels.rk4_step(x, 1.0, zero, zero, plant)
    end = total()
    assert np.linalg.norm(end - start) <= 1e-9 * max(np.linalg.norm(start), np.linalg.norm(end))
    assert np.abs(plant.h[4:]).max() == 0.0
    assert wheels.momentum_residual(x, plant) <= 1e-9


def test_external_impulse_accounts_for_the_change_of_angular_momentum():
    """With 001's constant torque and a gravity gradient the inertial momentum changes by the
    impulse the integrator accumulates; the impulse itself matches DOP853 on the naive equations
    (2 h at 1 s steps; rates stay below ~1e-2 rad/s, so RK4's error is far below 1e-9 relative)."""
    table = wheel_table(pyramid_axes())
    x = np.concatenate([Rotation.from_euler("ZYX", [30, -20, 1], degrees=True).as_quat(), [2e-3, -1e-3, 1e-3]])
    gg, direction = 1e-8, np.array([0.0, 0.0, 1.0])  # exaggerated (the L2 value is 1.6e-13 s^-2): ~1e-4 N m
    torque = np.full(3, 1.18e-3)  # 001 eq. 10: u_const
    plant = started(table, x, gg, direction)
    plant.motor[:] = [1e-3, -2e-3, 0.5e-3, 1e-3]
    y0 = np.concatenate([x, plant.h])
    ref = naive_wheels(table)

    def rhs(_, y):
        return np.concatenate(naive.wheel_state_rate(y[:7], y[7:], plant.motor, torque, ref, INERTIA, gg, direction))

    solution = solve_ivp(rhs, (0.0, 7200.0), y0, method="DOP853", rtol=1e-12, atol=1e-15)
    for _ in range(7200):
        wheels.rk4_step(x, 1.0, torque, torque, plant)
    impulse = plant.h[4:]
    assert np.linalg.norm(impulse) > 5.0  # the test is not about nothing: u_const over 2 h is 14.7 N m s
    np.testing.assert_allclose(impulse, solution.y[11:, -1], rtol=1e-9)
    assert wheels.momentum_residual(x, plant) <= 1e-9


def test_gravity_gradient_closed_form_and_sign():
    """Along a principal axis there is no torque; at 45 deg between x and y it is 3 k (J_yy - J_xx)
    / 2 about z (the physical sign: the torque turns the minimum axis toward the line to the
    bodies; 001 eq. 11 prints the opposite sign)."""
    k = 1.57e-13
    out = np.zeros(3)
    scratch = np.zeros((2, 3))
    identity = np.array([0.0, 0.0, 0.0, 1.0])
    for axis in np.eye(3):
        out[:] = 0.0
        wheels.gravity_gradient(identity, k, axis, INERTIA, scratch, out)
        assert np.abs(out).max() == 0.0
    out[:] = 0.0
    wheels.gravity_gradient(identity, k, np.array([1.0, 1.0, 0.0]) / math.sqrt(2.0), INERTIA, scratch, out)
    assert out[2] == pytest.approx(3.0 * k * (INERTIA[1, 1] - INERTIA[0, 0]) / 2.0, rel=1e-14)
    # rotated: c = R^T d with scipy's rotation
    rotation = Rotation.from_rotvec([0.2, -0.4, 0.7])
    d = np.array([0.3, -0.5, 0.81]) / np.linalg.norm([0.3, -0.5, 0.81])
    c = rotation.inv().apply(d)
    out[:] = 0.0
    wheels.gravity_gradient(rotation.as_quat(), k, d, INERTIA, scratch, out)
    np.testing.assert_allclose(out, 3.0 * k * np.cross(c, INERTIA @ c), rtol=1e-12)


def _command(table, distribution, h, rate_meas, omega, torque_cmd, compensate=False):
    plant = wheels.plant(table)
    plant.h[: table.shape[0]] = h
    peak, limited = wheels.command(distribution, plant, rate_meas, omega, torque_cmd, compensate)
    return plant.motor.copy(), plant.demand.copy(), peak, limited


def test_unlimited_wheels_realise_the_commanded_body_torque():
    """-W tau_m - omega x W h = u (001 eq. 6): the wheels apply the controller's torque."""
    rng = np.random.default_rng(3)
    axes = pyramid_axes()
    table = wheel_table(axes)
    distribution = np.linalg.pinv(axes)
    for _ in range(20):
        h, omega, u = rng.normal(0, 30, 4), rng.normal(0, 1e-3, 3), rng.normal(0, 0.1, 3)
        motor, demand, peak, limited = _command(table, distribution, h, omega, omega, u)
        np.testing.assert_allclose(-axes @ motor - np.cross(omega, axes @ h), u, atol=1e-15)
        assert not limited and peak == pytest.approx(np.abs(demand).max())
        nmotor, ndemand = naive.wheel_commands(distribution, naive_wheels(table), h, omega, omega, u)
        np.testing.assert_allclose(motor, nmotor, rtol=1e-14, atol=1e-18)


def test_limits_scale_the_vector_stop_a_full_wheel_and_a_failed_one():
    rng = np.random.default_rng(4)
    axes = pyramid_axes()
    distribution = np.linalg.pinv(axes)
    u = np.array([3.0, -1.0, 2.0])  # far beyond 0.2 N m wheels
    table = wheel_table(axes, torque_max=0.2, momentum_max=68.0)
    motor, demand, peak, limited = _command(table, distribution, np.zeros(4), np.zeros(3), np.zeros(3), u)
    assert limited and np.abs(motor).max() == pytest.approx(0.2, rel=1e-14)
    np.testing.assert_allclose(motor / np.abs(motor).max(), demand / np.abs(demand).max(), rtol=1e-13)
    body = -axes @ motor  # the body torque keeps its direction
    assert np.dot(body, u) / (np.linalg.norm(body) * np.linalg.norm(u)) == pytest.approx(1.0, abs=1e-14)
    # wheel 0 at +68 N m s relative: not driven further up, still allowed down
    h = np.array([68.0, 0.0, 0.0, 0.0])
    for sign in (1.0, -1.0):
        motor, demand, _, _ = _command(table, distribution, h, np.zeros(3), np.zeros(3), -sign * axes[:, 0] * 0.01)
        if sign > 0:
            assert demand[0] > 0.0 and motor[0] == 0.0
        else:
            assert demand[0] < 0.0 and motor[0] == pytest.approx(demand[0])
    # a failed wheel gives nothing; the others are as commanded (undetected: D unchanged)
    failed = wheel_table(axes, failed=(2,))
    for _ in range(5):
        u = rng.normal(0, 0.05, 3)
        motor, demand, _, _ = _command(failed, distribution, np.zeros(4), np.zeros(3), np.zeros(3), u)
        assert motor[2] == 0.0 and demand[2] != 0.0
        np.testing.assert_allclose(motor[[0, 1, 3]], demand[[0, 1, 3]])
        nmotor, _ = naive.wheel_commands(distribution, naive_wheels(failed), np.zeros(4), np.zeros(3), np.zeros(3), u)
        np.testing.assert_allclose(motor, nmotor, rtol=1e-14, atol=1e-18)


def test_sliding_mode_equals_the_naive_twin_and_saturates():
    """001 eq. 12 on random errors, inside and outside the boundary layer."""
    rng = np.random.default_rng(12)
    smc = np.array([[0.05, 0.05, 0.05], [0.002, 0.002, 0.002], [1e-4, 1e-4, 1e-4]])
    out = np.zeros(3)
    for scale in (1e-7, 1e-5, 1e-2):
        for _ in range(20):
            q_error = Rotation.from_rotvec(rng.normal(0, scale, 3)).as_quat()
            q_error *= np.sign(q_error[3])
            rate_error = rng.normal(0, scale, 3)
            rate_meas = rate_error + rng.normal(0, 1e-3, 3)
            accel = rng.normal(0, 1e-5, 3)
            control.torque_command(
                L.CONTROLLER_SMC,
                q_error,
                rate_error,
                rate_meas,
                accel,
                np.zeros(3),
                np.zeros(3),
                smc,
                INERTIA,
                True,
                out,
            )
            expected = naive.sliding_mode_torque(q_error, rate_error, rate_meas, accel, *smc, INERTIA)
            np.testing.assert_allclose(out, expected, rtol=1e-12, atol=1e-15)
    # far outside the layer the switching term is J G per axis: no attitude error, a unit rate error
    signs, zero, no_error = np.array([1.0, -1.0, 1.0]), np.zeros(3), np.array([0.0, 0.0, 0.0, 1.0])
    control.torque_command(L.CONTROLLER_SMC, no_error, signs, zero, zero, zero, zero, smc, INERTIA, True, out)
    expected = -np.diag(INERTIA) * smc[1] * signs - INERTIA @ (smc[0] * 0.5 * signs)  # -J G sign - J Lambda dq_e
    np.testing.assert_allclose(out, expected, rtol=1e-12)


def test_friction_compensation_cancels_the_design_friction():
    """With compensation the motor adds -friction(design coefficients, measured speed): with the
    truth equal to the design the net wheel torque is the uncompensated command (dh/dt of the
    naive twin), on both sides of zero speed and inside the linear zone."""
    rng = np.random.default_rng(9)
    axes = pyramid_axes()
    table = wheel_table(axes)
    distribution = np.linalg.pinv(axes)
    for relative in ([30.0, -20.0, 0.005, -0.001], [0.0, 0.0, 0.0, 0.0], rng.normal(0, 10, 4)):
        omega, u = rng.normal(0, 1e-3, 3), rng.normal(0, 0.05, 3)
        h = np.asarray(relative) + SPIN_INERTIA * (axes.T @ omega)
        plain, _, _, _ = _command(table, distribution, h, omega, omega, u)
        compensated, _, _, _ = _command(table, distribution, h, omega, omega, u, compensate=True)
        x = np.concatenate([[0.0, 0.0, 0.0, 1.0], omega])
        _, dh = naive.wheel_state_rate(
            x, np.concatenate([h, np.zeros(3)]), compensated, np.zeros(3), naive_wheels(table), INERTIA
        )
        np.testing.assert_allclose(dh[:4], plain, rtol=1e-12, atol=1e-15)
        # dispersed truth: the compensation uses the design columns, not the truth
        truth = table.copy()
        truth[:, L.W_COULOMB] *= 1.5
        again, _, _, _ = _command(truth, distribution, h, omega, omega, u, compensate=True)
        np.testing.assert_array_equal(again, compensated)


# --- null-space momentum management (001 sec. 9.1: H_W = W^+ H_B + n) ------------------------
def _managed(table, rate, bias=0.0, deadband=0.0, cap=math.inf, give_up=math.inf):
    table = table.copy()
    table[:, L.W_NULL_SPACE_GIVE_UP] = give_up
    table[:, L.W_NULL_SPACE_RATE] = rate
    table[:, L.W_NULL_SPACE_BIAS] = bias
    table[:, L.W_NULL_SPACE_DEADBAND] = deadband
    table[:, L.W_NULL_SPACE_TORQUE_MAX] = cap
    return table


def _spanning_axes(rng, n):
    """``n`` random unit axes whose W W^T is well conditioned (cond < 100), as any usable wheel set."""
    while True:
        axes = rng.normal(size=(3, n))
        axes /= np.linalg.norm(axes, axis=0)
        if np.linalg.cond(axes @ axes.T) < 100.0:
            return axes


@settings(deadline=None, max_examples=60)
@given(
    seed=st.integers(0, 2**32 - 1),
    n=st.integers(3, 7),
    excluded=st.sampled_from([None, 0, 2]),
    rate=st.floats(1e-5, 1.0),
    deadband=st.sampled_from([0.0, 10.0, 1e6]),
    cap=st.sampled_from([math.inf, 1e-3]),
)
def test_null_space_torque_is_scipys_null_space_projection_and_makes_no_body_torque(
    seed, n, excluded, rate, deadband, cap
):
    """The kernel's projector, built from D alone, against scipy.linalg.null_space of the used axes
    (tests/naive.py). Both are orthogonal projections of the same error in double precision: with
    cond(W W^T) < 100 they agree to ~1e3 eps relative, so 1e-12 of rate |e|. W_u tau is zero to the
    same relative rounding: the body feels nothing from the axes the flight software knows. The
    deadband and the cap only scale the vector, so both hold with them."""
    rng = np.random.default_rng(seed)
    axes = _spanning_axes(rng, n)
    used = np.ones(n, bool)
    if excluded is not None and excluded < n and n > 3:
        used[excluded] = False
        while np.linalg.cond(axes[:, used] @ axes[:, used].T) >= 100.0:
            axes = _spanning_axes(rng, n)
    distribution = np.zeros((n, 3))
    distribution[used] = np.linalg.pinv(axes[:, used])
    bias = rng.normal(0.0, 20.0, n)
    table = _managed(wheel_table(axes), rate, bias, deadband, cap)
    omega = rng.normal(0.0, 1e-3, 3)
    relative = rng.normal(0.0, 30.0, n)
    h = relative + SPIN_INERTIA * (axes.T @ omega)
    out = np.full(n, np.nan)
    count, size, capped = wheels.null_space_torque(distribution, table, h, omega, out)
    assert count == used.sum()
    expected = naive.wheel_null_space_torque(axes, used, relative, bias, rate, deadband, cap)
    scale = rate * np.linalg.norm(relative - bias)
    np.testing.assert_allclose(out, expected, rtol=0.0, atol=1e-12 * scale)
    np.testing.assert_allclose(axes @ out, 0.0, rtol=0.0, atol=1e-12 * scale)
    assert np.all(out[~used] == 0.0)
    assert np.abs(out).max() <= cap * (1.0 + 1e-15)
    if used.sum() > 3:  # |e_n| as the flight software measures it, and whether the cap acted
        basis = scipy.linalg.null_space(axes[:, used])
        error = basis.T @ (relative - bias)[used]
        assert size == pytest.approx(np.linalg.norm(error), rel=1e-12)
        uncapped = naive.wheel_null_space_torque(axes, used, relative, bias, rate, deadband)
        assert capped == (np.abs(uncapped).max() > cap)
    if used.sum() == 3:  # no null space: nothing at all, not rounding
        assert np.all(out == 0.0)
    elif deadband == 0.0 and cap == math.inf:  # it takes the null-space error back: d/dt (N^T e) = -rate N^T e
        basis = scipy.linalg.null_space(axes[:, used])
        np.testing.assert_allclose(
            basis.T @ out[used], -rate * basis.T @ (relative - bias)[used], rtol=0.0, atol=1e-12 * scale
        )
    elif deadband == 1e6:  # no error that large: nothing
        assert np.all(out == 0.0)


def test_null_space_torque_of_001s_pyramid_is_along_n4():
    """001 sec. 8.1: n_4 = [c, -b, c, -b] / sqrt(2 (b^2 + c^2)) spans the null space of W_4; a momentum
    error along n_4 is taken back along n_4 at the rate, one orthogonal to it gives nothing."""
    axes = pyramid_axes(45.0)
    b = c = math.cos(math.radians(45.0))
    n4 = np.array([c, -b, c, -b]) / math.sqrt(2.0 * (b * b + c * c))
    table = _managed(wheel_table(axes), 1e-3)
    distribution = np.linalg.pinv(axes)
    out = np.zeros(4)
    wheels.null_space_torque(distribution, table, 7.0 * n4, np.zeros(3), out)
    np.testing.assert_allclose(out, -7e-3 * n4, rtol=1e-14, atol=1e-18)
    wheels.null_space_torque(distribution, table, distribution @ np.array([1.0, -2.0, 3.0]), np.zeros(3), out)
    np.testing.assert_allclose(out, 0.0, rtol=0.0, atol=1e-17)  # W^+ H_B has no part along n_4
    # a 4 N m s deadband: 7 along n_4 leaves 3 to take back; a 1 mN m cap scales that to 1 mN m
    wheels.null_space_torque(distribution, _managed(wheel_table(axes), 1e-3, deadband=4.0), 7.0 * n4, np.zeros(3), out)
    np.testing.assert_allclose(out, -3e-3 * n4, rtol=1e-14, atol=1e-18)
    capped = _managed(wheel_table(axes), 1e-3, deadband=4.0, cap=1e-3)
    wheels.null_space_torque(distribution, capped, 7.0 * n4, np.zeros(3), out)
    np.testing.assert_allclose(out, -2e-3 * n4, rtol=1e-14, atol=1e-18)  # |n_4 component| = 1/2: 1e-3 per wheel


def test_null_space_torque_of_wheels_that_do_not_span_three_axes_is_zero():
    """Five wheels of which four are used but lie in one plane (D of rank 2): no projector, no torque."""
    axes = np.array([[1.0, 0.0, 1.0, 1.0, 0.0], [0.0, 1.0, 1.0, -1.0, 0.0], [0.0, 0.0, 0.0, 0.0, 1.0]])
    axes /= np.linalg.norm(axes, axis=0)
    distribution = np.zeros((5, 3))
    distribution[:4] = np.linalg.pinv(axes[:, :4])  # wheel 5 (the only one off the plane) left out
    out = np.full(5, np.nan)
    used, size, capped = wheels.null_space_torque(
        distribution, _managed(wheel_table(axes), 1e-3), np.arange(5.0), np.zeros(3), out
    )
    assert used == 4 and size == 0.0 and not capped and np.all(out == 0.0)


def test_managed_commands_add_the_null_space_torque_and_keep_the_body_torque():
    """command() with management = the naive command plus the naive null-space torque; unlimited
    wheels still realise u exactly (-W tau_m - omega x W h = u), with or without the bias."""
    rng = np.random.default_rng(23)
    axes = pyramid_axes()
    distribution = np.linalg.pinv(axes)
    for bias in (0.0, np.array([15.0, -15.0, 15.0, -15.0])):
        table = _managed(wheel_table(axes), 1e-3, bias)
        for _ in range(10):
            h, omega, u = rng.normal(0, 30, 4), rng.normal(0, 1e-3, 3), rng.normal(0, 0.1, 3)
            motor, demand, _, limited = _command(table, distribution, h, omega, omega, u)
            np.testing.assert_allclose(-axes @ motor - np.cross(omega, axes @ h), u, atol=1e-15)
            nmotor, _ = naive.wheel_commands(distribution, naive_wheels(table), h, omega, omega, u)
            relative = h - SPIN_INERTIA * (axes.T @ omega)
            null = naive.wheel_null_space_torque(axes, np.ones(4, bool), relative, np.broadcast_to(bias, 4), 1e-3)
            np.testing.assert_allclose(motor, nmotor + null, rtol=1e-12, atol=1e-15)
            assert not limited


def test_management_gives_up_when_the_capped_error_still_grows():
    """Give-up: at the cap, beyond deadband + margin and growing since the last period (a dead wheel
    the flight software does not know of makes n grow whatever it commands). Then the command is the
    plain one for the rest of the flight. Shrinking at the cap (a healthy set catching up) or
    growing below the cap does not count, nor does the first period."""
    axes = pyramid_axes(45.0)
    n4 = np.array([0.5, -0.5, 0.5, -0.5])
    distribution = np.linalg.pinv(axes)
    table = _managed(wheel_table(axes), 1e-3, deadband=20.0, cap=3e-3, give_up=8.0)
    plain_table = wheel_table(axes)
    u, zero = np.array([1e-4, -2e-4, 3e-4]), np.zeros(3)

    def step(plant, n):
        plant.h[:4] = n * n4
        wheels.command(distribution, plant, zero, zero, u, False)
        return plant.motor.copy()

    def plain(n):
        return _command(plain_table, distribution, n * n4, zero, zero, u)[0]

    plant = started(table, np.array([0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0]))
    assert plant.null_space[0] == 0.0
    np.testing.assert_allclose(step(plant, 40.0), plain(40.0) - 3e-3 * n4 / 0.5, rtol=1e-12)  # first: capped
    step(plant, 39.0)  # shrinking at the cap: goes on
    assert plant.null_space[0] == 0.0
    step(plant, 27.0)  # capped (3.5 mN m asked) and growing, but only 7 and 7.5 beyond the deadband
    step(plant, 27.5)
    assert plant.null_space[0] == 0.0
    np.testing.assert_array_equal(step(plant, 29.0), plain(29.0))  # capped, 9 > 8 beyond, growing
    assert plant.null_space[0] == 1.0
    np.testing.assert_array_equal(step(plant, 21.0), plain(21.0))  # for good


def test_management_off_commands_the_same_bits():
    """Rate 0 (no null_space_management in the vehicle file) leaves the command bit for bit."""
    rng = np.random.default_rng(24)
    axes = pyramid_axes()
    distribution = np.linalg.pinv(axes)
    table = wheel_table(axes, torque_max=0.2, momentum_max=68.0)
    for _ in range(10):
        h, omega, u = rng.normal(0, 30, 4), rng.normal(0, 1e-3, 3), rng.normal(0, 0.1, 3)
        off = _command(_managed(table, 0.0, 5.0), distribution, h, omega, omega, u, compensate=True)
        plain = _command(table, distribution, h, omega, omega, u, compensate=True)
        np.testing.assert_array_equal(off[0], plain[0])
        np.testing.assert_array_equal(off[1], plain[1])
