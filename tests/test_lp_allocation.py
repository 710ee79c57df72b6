"""LP thruster allocation (core.lp_allocation, 004 eq. 2-5) against scipy's HiGHS and a vertex
enumeration (tests/naive.py).

Tolerances: the kernel and HiGHS both return vertices of the same polytope, so the optimal totals
agree to rounding; 1e-9 relative (issue 13) leaves six orders for HiGHS's own tolerances. The
kernel recomputes its basic thrusts from the nonbasic ones, so H u reproduces the torque to
rounding of a 3 x 3 solve: 1e-12 N m for torques of order 1 N m.
"""

from pathlib import Path

import naive
import numpy as np
import pytest
from lp_reference import highs_minima
from scipy.optimize import linprog

from refexmc.config import derived
from refexmc.config.load import load_vehicle
from refexmc.core import lp_allocation as lp

ROOT = Path(__file__).resolve().parents[1]
OBJECTIVE_REL = 1e-9
RESIDUAL_N_M = 1e-12


class Solver:
    def __init__(self, arms, u_max):
        n = arms.shape[1]
        self.arms, self.u_max = np.ascontiguousarray(arms, dtype=float), np.asarray(u_max, dtype=float)
        self.work = np.zeros(lp.scratch_shape(n))
        self.basis = np.zeros(3, dtype=np.int64)
        self.in_basis = np.zeros(lp.work_columns(n), dtype=np.bool_)
        self.u = np.zeros(n)

    def __call__(self, torque):
        scale = lp.allocate(
            self.arms, self.u_max, np.asarray(torque, dtype=float), self.u, self.work, self.basis, self.in_basis
        )
        return scale, self.u.copy()


def bounds(u_max):
    return [(0.0, float(top)) for top in u_max]


def random_geometry(seed, n=12):
    rng = np.random.default_rng(seed)
    positions = rng.uniform(-1.0, 1.0, (n, 3))
    directions = rng.normal(size=(n, 3))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    return np.cross(positions, directions).T, rng.uniform(0.5, 2.0, n)


def generic_12():
    vehicle = load_vehicle(ROOT / "configs/vehicles/generic-12.yaml")
    return derived.torque_arms(vehicle).T, np.full(12, vehicle["rcs"]["thrust_n"]["low"])


GEOMETRIES = {"generic-12": generic_12, "random-12": lambda: random_geometry(7)}


def attainable_torques(arms, u_max, count, seed):
    """Torques of random thrust vectors, about half the thrusters firing: inside the polytope."""
    rng = np.random.default_rng(seed)
    n = arms.shape[1]
    thrusts = rng.uniform(0.0, 1.0, (count, n)) * (rng.random((count, n)) < 0.5) * u_max
    return thrusts @ arms.T


def assert_equal_to_highs(arms, u_max, count, seed):
    """The kernel's total equals HiGHS's on ``count`` attainable torques; H u = tau; bounds held."""
    solve = Solver(arms, u_max)
    torques = attainable_torques(arms, u_max, count, seed=seed)
    n = arms.shape[1]
    minima = highs_minima(np.ones((count, n)), np.broadcast_to(arms, (count, *arms.shape)), torques, 0.0, u_max)
    for torque, minimum in zip(torques, minima, strict=True):
        scale, u = solve(torque)
        assert scale == 1.0
        assert u.sum() == pytest.approx(minimum, rel=OBJECTIVE_REL, abs=1e-15)
        assert np.abs(arms @ u - torque).max() <= RESIDUAL_N_M
        assert np.all(u >= 0.0) and np.all(u <= u_max)


@pytest.mark.slow
@pytest.mark.parametrize("name", GEOMETRIES)
def test_ten_thousand_torques_equal_highs(name):
    """Issue 13: 10,000 attainable torques; objective equal to linprog, H u = tau, bounds held."""
    assert_equal_to_highs(*GEOMETRIES[name](), count=10_000, seed=1)


@pytest.mark.parametrize("name", GEOMETRIES)
def test_equal_to_highs_on_a_few_hundred_torques(name):
    assert_equal_to_highs(*GEOMETRIES[name](), count=300, seed=2)


def test_the_stacked_reference_is_each_lp_solved_alone():
    """HiGHS on the stacked LP gives each torque the minimum of its own LP (to HiGHS's rounding)."""
    arms, u_max = random_geometry(8)
    torques = attainable_torques(arms, u_max, 60, seed=3)
    minima = highs_minima(np.ones((60, 12)), np.broadcast_to(arms, (60, 3, 12)), torques, 0.0, u_max)
    for torque, minimum in zip(torques, minima, strict=True):
        alone = linprog(np.ones(12), A_eq=arms, b_eq=torque, bounds=bounds(u_max), method="highs")
        assert alone.status == 0 and minimum == pytest.approx(alone.fun, rel=1e-12, abs=1e-15)


def test_equal_to_the_vertex_enumeration():
    """The slow twin: every vertex of a 7-thruster polytope, no LP solver involved."""
    arms, u_max = random_geometry(3, n=7)
    solve = Solver(arms, u_max)
    for torque in attainable_torques(arms, u_max, 20, seed=4):
        best, _ = naive.lp_allocation_vertices(arms, u_max, torque)
        scale, u = solve(torque)
        assert scale == 1.0 and u.sum() == pytest.approx(best, rel=1e-9)


def test_unattainable_torque_gets_the_largest_share_with_the_least_propellant():
    """Policy: s* = max s with H u = s tau attainable (an LP of its own for linprog), then min sum(u)."""
    arms, u_max = random_geometry(11)
    solve = Solver(arms, u_max)
    rng = np.random.default_rng(5)
    n = arms.shape[1]
    for _ in range(50):
        torque = rng.normal(size=3) * 50.0  # far outside the polytope
        scale, u = solve(torque)
        a_eq = np.c_[arms, -torque]
        widest = linprog(np.r_[np.zeros(n), -1.0], A_eq=a_eq, b_eq=np.zeros(3), bounds=[*bounds(u_max), (0, 1)])
        assert 0.0 < scale < 1.0 and scale == pytest.approx(-widest.fun, rel=1e-9)
        cheapest = linprog(np.ones(n), A_eq=arms, b_eq=scale * torque, bounds=bounds(u_max))
        assert u.sum() == pytest.approx(cheapest.fun, rel=1e-7)
        assert np.abs(arms @ u - scale * torque).max() <= RESIDUAL_N_M * 50


def test_a_direction_no_thruster_can_produce_gives_nothing():
    """generic-12 with every +x thruster unavailable (u_max 0): a +x torque gets s* = 0, u = 0."""
    arms, u_max = generic_12()
    u_max = u_max.copy()
    u_max[[0, 1]] = 0.0
    scale, u = Solver(arms, u_max)(np.array([0.3, 0.0, 0.0]))
    assert scale == 0.0 and not u.any()


def test_never_more_propellant_than_any_allocation_that_realises_the_torque():
    """The thrusts that generated each torque realise it: the LP's total is never larger. The
    clipped pseudo-inverse, clip(pinv(H) tau, 0, u_max), is such an allocation only where it
    realises the torque; with thrusters that push one way it mostly does not (it loses the
    negative entries): on generic-12's couples it never does, which the last assertion records."""
    arms, u_max = generic_12()
    solve = Solver(arms, u_max)
    pinv = np.linalg.pinv(arms)
    rng = np.random.default_rng(6)
    realised_by_pinv = 0
    for _ in range(2000):
        thrusts = rng.uniform(0.0, 1.0, 12) * (rng.random(12) < 0.5) * u_max
        torque = arms @ thrusts
        _, u = solve(torque)
        assert u.sum() <= thrusts.sum() + 1e-12
        clipped = np.clip(pinv @ torque, 0.0, u_max)
        if np.abs(arms @ clipped - torque).max() <= 1e-9:
            realised_by_pinv += 1
            assert u.sum() <= clipped.sum() + 1e-12
    # couples: pinv splits each axis over both senses, clipping drops one: it realises no torque here
    assert realised_by_pinv == 0


def _inspect(args):
    import json

    from click.testing import CliRunner

    from refexmc.cli import main

    result = CliRunner().invoke(main, ["inspect", *args])
    return result.exit_code, (
        json.loads(result.output) if "--json" in args and result.exit_code == 0 else result.output
    )


def test_inspect_torque_shows_the_lp_allocation(tmp_path):
    """`inspect --torque` on an lp_pwm vehicle: HiGHS's total, the torque realised, the JSON contract."""
    text = (ROOT / "configs/vehicles/generic-12.yaml").read_text().replace("actuation: pwpf_table", "actuation: lp_pwm")
    text = text.replace("min_off: 50.0", "min_off: 0.0")
    (tmp_path / "v.yaml").write_text(text)
    code, out = _inspect([str(tmp_path / "v.yaml"), "--torque", "0.3,-0.2,0.1", "--json"])
    assert code == 0
    arms, u_max = generic_12()
    commands = np.array(out["allocation"]["commands"])
    reference = linprog(np.ones(12), A_eq=arms, b_eq=[0.3, -0.2, 0.1], bounds=bounds(u_max))
    assert out["allocation"]["method"] == "lp" and commands.sum() == pytest.approx(reference.fun, rel=1e-9)
    assert np.allclose(out["allocation"]["realised_torque_n_m"], [0.3, -0.2, 0.1], atol=RESIDUAL_N_M)
    assert [t["max_thrust_n"] for t in out["thrusters"]] == [1.0] * 12
    assert out["thrusters"][0]["position_m"] == [0.0, 0.5, 0.0]


def test_inspect_torque_on_a_table_vehicle_shows_the_table_row_at_full_thrust():
    """refex, high thrust, torque (+, -, +): 000 Table 3's +x-y row plus -z... every thruster of the
    row at 8.92 N, and the realised torque is the sum of their arms times thrust."""
    code, out = _inspect(
        [str(ROOT / "configs/vehicles/refex.yaml"), "--torque", "0.3,-0.2,0.1", "--level", "high", "--json"]
    )
    assert code == 0
    vehicle = load_vehicle(ROOT / "configs/vehicles/refex.yaml")
    fired = [i + 1 for i, u in enumerate(out["allocation"]["commands"]) if u > 0]
    expected = sorted(
        set(vehicle["flight_software"]["allocation"]["+x-y"]) | set(vehicle["flight_software"]["allocation"]["+z"])
    )
    assert fired == expected
    realised = derived.torque_arms(vehicle).T @ np.array(out["allocation"]["commands"])
    assert np.allclose(out["allocation"]["realised_torque_n_m"], realised, rtol=1e-15)


@pytest.mark.parametrize(
    ("args", "words"),
    [
        (["--torque", "1,2"], "three finite numbers"),
        (["--torque", "1,2,3", "--level", "max"], "thrust levels low, high"),
    ],
)
def test_inspect_torque_bad_options_are_bad_input(args, words):
    code, out = _inspect([str(ROOT / "configs/vehicles/refex.yaml"), *args])
    assert code == 2 and words in out


@pytest.mark.parametrize(
    ("u", "u_max", "min_on", "expected"),
    [
        (0.5, 1.0, 0.0, 0.0125),  # half thrust: half the 25 ms period
        (2.0, 1.0, 0.0, 0.025),  # saturated: the whole period
        (0.3, 1.0, 0.010, 0.010),  # 7.5 ms: at least min_on / 2, rounded up to the 10 ms minimum
        (0.1, 1.0, 0.010, 0.0),  # 2.5 ms < 5 ms: nothing
        (0.0, 1.0, 0.0, 0.0),
        (0.5, 0.0, 0.0, 0.0),  # a thruster with no thrust never fires
        (0.5, 2.0, 0.0, 0.00625),  # a quarter of the thruster's thrust: a quarter of the period
        (0.2, 1.0, 2.0 * (0.025 * 0.2), 2.0 * (0.025 * 0.2)),  # exactly min_on / 2: rounded up
    ],
)
def test_pulse_width_is_the_thrust_share_of_the_period(u, u_max, min_on, expected):
    from refexmc.core import allocation

    on = allocation.pwm_on_time(u, u_max, 0.025, min_on)
    assert on == pytest.approx(expected, abs=1e-15)


def test_nominal_arms_are_r_cross_d_for_any_geometry():
    """core.allocation.nominal_arms against numpy's cross product for random positions and
    directions (the vehicles' thrusters sit on axes, where half the products vanish); 1e-15
    absolute for arms of order 1 m."""
    from refexmc.core import allocation
    from refexmc.core import layout as L

    rng = np.random.default_rng(26)
    thrusters = np.zeros((7, L.T_TIME_CONSTANTS))
    thrusters[:, L.T_POSITION : L.T_POSITION + 3] = rng.uniform(-1.0, 1.0, (7, 3))
    thrusters[:, L.T_DIRECTION : L.T_DIRECTION + 3] = rng.uniform(-1.0, 1.0, (7, 3))
    out = np.full((3, 7), np.nan)
    allocation.nominal_arms(thrusters, out)
    expected = np.cross(thrusters[:, L.T_POSITION : L.T_POSITION + 3], thrusters[:, L.T_DIRECTION : L.T_DIRECTION + 3])
    np.testing.assert_allclose(out, expected.T, rtol=0, atol=1e-15)


def test_lp_pwm_flies_the_generic_mission(tmp_path):
    """generic-12 with actuation lp_pwm (2 ms minimum pulse, no rest limit) detumbles, slews and
    holds; it fires more, shorter pulses than the PWPF and the table, for about the same propellant."""
    import copy

    from refexmc.config.load import load_mission
    from refexmc.config.pack import mode_names, pack
    from refexmc.simulate import fly

    vehicle = load_vehicle(ROOT / "configs/vehicles/generic-12.yaml")
    mission = load_mission(ROOT / "configs/missions/generic-slew.yaml")
    lp_vehicle = copy.deepcopy(vehicle)
    lp_vehicle["flight_software"]["actuation"] = "lp_pwm"
    lp_vehicle["rcs"]["switching_limits_ms"] = {"min_on": 2.0, "min_off": 0.0}
    table = fly(pack(vehicle, mission), mode_names=mode_names(mission))
    result = fly(pack(lp_vehicle, mission), mode_names=mode_names(mission))
    assert result.success, result.failure_reason
    assert result.value("attitude_error_end_deg") < mission["attitude_error_end_max_deg"]
    assert result.pulse_counts.sum() > table.pulse_counts.sum()
    assert result.value("fuel_used_kg") == pytest.approx(table.value("fuel_used_kg"), rel=0.5)


def test_lp_pwm_refuses_a_rest_limit_it_cannot_honour(tmp_path):
    from click.testing import CliRunner

    from refexmc.cli import main

    text = (ROOT / "configs/vehicles/generic-12.yaml").read_text().replace("actuation: pwpf_table", "actuation: lp_pwm")
    (tmp_path / "v.yaml").write_text(text)
    result = CliRunner().invoke(main, ["validate", str(tmp_path / "v.yaml")])
    assert result.exit_code == 2
    assert "rcs.switching_limits_ms.min_off: actuation lp_pwm pulses inside each control period" in result.output


# --- detected failures: a zero column is the LP without that thruster --------------------------


@pytest.mark.parametrize("name", GEOMETRIES)
def test_a_zeroed_column_gives_exactly_the_lp_without_that_thruster(name):
    """A thruster the flight software knows to have failed has a zero column in H
    (allocation.nominal_arms). It never enters the basis, so every pivot is that of the LP with the
    column removed: the thrusts are bit-identical, the failed one gets none, and the total equals
    linprog's on the reduced problem (the tolerances of the module's docstring). Torques both
    attainable and far outside, so phase A's scale is exercised too."""
    arms, u_max = GEOMETRIES[name]()
    rng = np.random.default_rng(21)
    for failed in ([0], [3], [0, 5], [2, 7, 11]):
        keep = [j for j in range(arms.shape[1]) if j not in failed]
        zeroed = arms.copy()
        zeroed[:, failed] = 0.0
        with_zeros, reduced = Solver(zeroed, u_max), Solver(arms[:, keep], u_max[keep])
        inside = attainable_torques(arms[:, keep], u_max[keep], 30, seed=len(failed))
        for torque in [*inside, *(rng.normal(size=(10, 3)) * 50.0)]:
            scale, u = with_zeros(torque)
            scale_reduced, u_reduced = reduced(torque)
            assert scale == scale_reduced
            assert np.array_equal(u[keep], u_reduced) and not u[failed].any()
            if scale == 1.0:
                reference = linprog(
                    np.ones(len(keep)), A_eq=arms[:, keep], b_eq=torque, bounds=bounds(u_max[keep]), method="highs"
                )
                assert reference.status == 0
                assert u.sum() == pytest.approx(reference.fun, rel=OBJECTIVE_REL, abs=1e-15)


def test_nominal_arms_zero_the_thrusters_whose_failure_is_known():
    """core.allocation.nominal_arms: the column of a thruster marked failure_known is zero, every
    other is r x d (derived.torque_arms, numpy's cross product); a failure not known keeps its
    column (undetected: the flight software does not know)."""
    from refexmc.config.pack import pack_thrusters
    from refexmc.core import allocation

    vehicle = load_vehicle(ROOT / "configs/vehicles/spore-sm.yaml")
    expected = derived.torque_arms(vehicle).T
    for failed, known in (((), ()), ((1, 8), ()), ((1, 8), (8,)), ((3, 4, 12), (3, 4, 12))):
        thrusters = pack_thrusters(vehicle, failed, known)
        out = np.full((3, 12), np.nan)
        allocation.nominal_arms(thrusters, out)
        columns = [t - 1 for t in known]
        assert not out[:, columns].any()
        others = [j for j in range(12) if j not in columns]
        np.testing.assert_allclose(out[:, others], expected[:, others], rtol=0, atol=1e-15)
