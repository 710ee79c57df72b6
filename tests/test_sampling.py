"""Dispersions and failures: keyed seeding, distributions, and every path reaching the flight."""

import copy
import itertools
import math
import pickle
from pathlib import Path

import naive
import numpy as np
import pandas as pd
import pytest
from scipy import stats
from scipy.spatial.transform import Rotation

from refexmc.campaign import sampling
from refexmc.campaign.chunk import RunPlan, fly_chunk, plan_for
from refexmc.campaign.sampling import Sampler, dims, keyed_rng
from refexmc.config import dispersions
from refexmc.config.derived import inertia_problem, unphysical_inertias
from refexmc.config.load import failure_sets, load_campaign
from refexmc.core import layout as L
from refexmc.distributions import transform, truncated_normal_ppf
from refexmc.simulate import fly

ROOT = Path(__file__).resolve().parents[1]
NOMINAL = ROOT / "campaigns/nominal.yaml"

# KS tests below run at significance 1e-3 with fixed seeds: they are deterministic, and a
# wrong transform (wrong sigma, missing truncation, a biased rotation) fails them by orders of
# magnitude at these sample sizes.
P_MIN = 1e-3
# The sampler's inertia tensor and naive.dispersed_inertia (LAPACK's eigh, scipy's rotation, BLAS
# products with FMA) round ~15 operations differently: a few ulp of the largest component, not more.
INERTIA_TWIN_RTOL = 1e-14


@pytest.fixture(scope="module")
def base():
    """The nominal campaign as a dict, to be deep-copied and given dispersions."""
    return load_campaign(NOMINAL)


def campaign_with(base, dispersions_map, runs=10, sampling="random", nominal_first=False, failures=None):
    campaign = copy.deepcopy(base)
    campaign.update(
        dispersions=dispersions_map,
        runs=runs,
        sampling=sampling,
        nominal_first=nominal_first,
        failures=failures or {"mode": "none"},
    )
    return campaign


def draws(campaign, path, run_ids):
    sampler = Sampler(campaign)
    return np.array([sampler.values(i)[path] for i in run_ids])


MIXED = {
    "initial_state.rates_deg_s": {"dist": "normal", "mean": [0, 0, 0], "sigma": [1, 2, 3]},
    "rcs.thrust_scale": {"dist": "truncnorm", "mean": 1.0, "sigma": 0.05, "low": 0.9, "high": 1.1},
    "inertia_kg_m2": {"dist": "inertia", "moments_sigma_fraction": 0.05, "axes_sigma_deg": 1.0},
}


@pytest.mark.parametrize("sampling", ["random", "lhs", "sobol"])
def test_draws_do_not_depend_on_the_other_dispersions_or_on_chunking(base, sampling):
    full = campaign_with(base, MIXED, runs=40, sampling=sampling)
    alone = campaign_with(base, {"rcs.thrust_scale": MIXED["rcs.thrust_scale"]}, runs=40, sampling=sampling)
    a = draws(full, "rcs.thrust_scale", range(40))
    b = draws(alone, "rcs.thrust_scale", range(40))
    assert np.array_equal(a, b)
    # one sampler per chunk, in any order: the same values
    chunks = [draws(full, "rcs.thrust_scale", ids) for ids in (range(20, 40), range(0, 20))]
    assert np.array_equal(np.concatenate(chunks[::-1]), a)
    # distinct runs get distinct draws, distinct thrusters independent draws
    assert len({tuple(row) for row in a}) == 40
    assert np.abs(np.corrcoef(a.T)[np.triu_indices(8, 1)]).max() < 0.7


def test_fly_chunk_rows_are_independent_of_chunking(base):
    campaign = campaign_with(base, MIXED, runs=6, nominal_first=True, failures={"mode": "enumerate", "sizes": [1]})
    campaign["runs"] = 6
    whole, _ = fly_chunk(campaign, range(6))
    parts = fly_chunk(campaign, [4, 5])[0] + fly_chunk(campaign, [0, 1, 2, 3])[0]
    pd.testing.assert_frame_equal(
        pd.DataFrame(whole), pd.DataFrame(parts).sort_values("run_id").reset_index(drop=True), check_exact=True
    )
    assert [r["failed_thrusters"] for r in whole] == ["", "1", "2", "3", "4", "5"]
    assert whole[0]["p.initial_state.rates_deg_s.x"] == 3.0  # run 0: the nominal value


def test_a_worker_reuses_its_plan_for_every_copy_of_the_same_campaign(base):
    """Each task brings a new unpickled copy of the campaign: the plan is kept by content, and a
    campaign that differs (here the seed, also when changed in place) gets its own plan."""
    campaign = campaign_with(base, MIXED)
    plan = plan_for(campaign)
    assert plan_for(pickle.loads(pickle.dumps(campaign))) is plan
    campaign["seed"] += 1
    changed = plan_for(campaign)
    assert changed is not plan and changed.sampler.seed == campaign["seed"]


def test_seed_changes_the_draws(base):
    a = campaign_with(base, MIXED, runs=5)
    b = copy.deepcopy(a)
    b["seed"] += 1
    path = "initial_state.rates_deg_s"
    assert not np.array_equal(draws(a, path, range(5)), draws(b, path, range(5)))


# --- distributions against scipy.stats ------------------------------------------------------------


def _ks(values, cdf):
    return stats.kstest(values, cdf).pvalue


def test_normal_truncnorm_uniform_lognormal_match_scipy(base):
    n = 2000
    spec = {
        "initial_state.rates_deg_s": {"dist": "normal", "mean": [1.0, 0.0, -2.0], "sigma": [0.5, 2.0, 1.0]},
        "rcs.isp_s": {"dist": "truncnorm", "mean": 70.0, "sigma": 3.0, "low": 68.0, "high": 80.0},
        "initial_state.altitude_m": {"dist": "uniform", "low": 84000.0, "high": 86000.0},
        "atmosphere.density_scale": {"dist": "lognormal", "median": 1.2, "sigma": 0.3},
    }
    campaign = campaign_with(base, spec, runs=n)
    sampler = Sampler(campaign)
    values = [sampler.values(i) for i in range(n)]
    rates = np.array([v["initial_state.rates_deg_s"] for v in values])
    for k, (mean, sigma) in enumerate([(1.0, 0.5), (0.0, 2.0), (-2.0, 1.0)]):
        assert _ks(rates[:, k], stats.norm(mean, sigma).cdf) > P_MIN
    isp = np.array([v["rcs.isp_s"][0] for v in values])
    assert isp.min() >= 68.0 and isp.max() <= 80.0
    assert _ks(isp, stats.truncnorm((68 - 70) / 3, (80 - 70) / 3, loc=70, scale=3).cdf) > P_MIN
    altitude = np.array([v["initial_state.altitude_m"][0] for v in values])
    assert _ks(altitude, stats.uniform(84000.0, 2000.0).cdf) > P_MIN
    density = np.array([v["atmosphere.density_scale"][0] for v in values])
    assert _ks(density, stats.lognorm(s=0.3, scale=1.2).cdf) > P_MIN
    # components of one vector are independent of each other
    assert abs(np.corrcoef(rates.T)[0, 1]) < 0.1


def test_truncated_normal_ppf_equals_scipy():
    u = np.linspace(1e-6, 1 - 1e-6, 501)
    for a, b in [(-2.0, 3.0), (-np.inf, 0.5), (1.0, np.inf), (4.0, 6.0), (-7.0, -5.0), (-0.1, 0.1)]:
        # scipy evaluates the same inverse with its own algorithm; they agree to round-off of
        # ndtr/ndtri near the tails (1e-9 relative is far below any dispersion's meaning)
        expected = stats.truncnorm.ppf(u, a, b)
        assert np.allclose(truncated_normal_ppf(u, a, b), expected, rtol=1e-9, atol=1e-9), (a, b)


def test_choice_frequencies_and_whole_vector_choice(base):
    n = 3000
    spec = {
        "rcs.propellant_kg": {"dist": "choice", "values": [1.0, 2.0, 3.0], "probabilities": [0.2, 0.5, 0.3]},
        "com_offset_m": {"dist": "choice", "values": [[0, 0, 0], [0.01, 0.02, 0.03]]},
    }
    sampler = Sampler(campaign_with(base, spec, runs=n))
    values = [sampler.values(i) for i in range(n)]
    prop = np.array([v["rcs.propellant_kg"][0] for v in values])
    for value, p in [(1.0, 0.2), (2.0, 0.5), (3.0, 0.3)]:
        share = np.mean(prop == value)
        # binomial standard error at n = 3000 is <= 0.0091; 4 sigma
        assert abs(share - p) < 4 * math.sqrt(p * (1 - p) / n), (value, share)
    com = np.array([v["com_offset_m"] for v in values])
    assert {tuple(row) for row in com} == {(0.0, 0.0, 0.0), (0.01, 0.02, 0.03)}


def test_uniform_so3_is_haar_distributed(base):
    n = 3000
    spec = {"initial_state.attitude_rotvec_deg": {"dist": "uniform_so3"}}
    rotvec = draws(campaign_with(base, spec, runs=n), "initial_state.attitude_rotvec_deg", range(n))
    angle = np.radians(np.linalg.norm(rotvec, axis=1))
    # Haar measure on SO(3): rotation angle density (1 - cos t) / pi on [0, pi]
    assert _ks(angle, lambda t: (np.asarray(t) - np.sin(t)) / np.pi) > P_MIN
    # and a uniformly distributed rotation axis: each axis component uniform on [-1, 1]
    axis = rotvec / np.linalg.norm(rotvec, axis=1, keepdims=True)
    for k in range(3):
        assert _ks(axis[:, k], stats.uniform(-1, 2).cdf) > P_MIN
    # the rotated body x axis is uniform on the sphere: its mean is near zero (3 / sqrt(n) bound)
    x_axis = Rotation.from_rotvec(rotvec, degrees=True).apply([1.0, 0.0, 0.0])
    assert np.all(np.abs(x_axis.mean(axis=0)) < 3.0 / math.sqrt(n))


# every distribution at once, a large inertia dispersion among them (some first draws are redrawn)
EVERY_DISTRIBUTION = {
    "initial_state.rates_deg_s": {"dist": "normal", "mean": [1.0, 0.0, -2.0], "sigma": [0.5, 2.0, 1.0]},
    "rcs.isp_s": {"dist": "truncnorm", "mean": 70.0, "sigma": 3.0, "low": 68.0, "high": 80.0},
    "initial_state.altitude_m": {"dist": "uniform", "low": 84000.0, "high": 86000.0},
    "atmosphere.density_scale": {"dist": "lognormal", "median": 1.2, "sigma": 0.3},
    "rcs.propellant_kg": {"dist": "choice", "values": [1.0, 2.0, 3.0], "probabilities": [0.2, 0.5, 0.3]},
    "com_offset_m": {"dist": "choice", "values": [[0, 0, 0], [0.01, 0.02, 0.03]]},
    "initial_state.attitude_rotvec_deg": {"dist": "uniform_so3"},
    "inertia_kg_m2": {"dist": "inertia", "moments_sigma_fraction": 0.3, "axes_sigma_deg": 20},
    "mass_kg": {"dist": "constant", "value": 80.0},
}


@pytest.mark.parametrize("sampling", ["random", "lhs", "sobol"])
def test_a_chunk_draws_each_run_as_it_would_be_drawn_alone(base, sampling):
    """values_for_runs transforms a chunk's uniforms path by path in one go; every run's values
    are, bit for bit, those of its own uniforms (numpy's keyed generator for random sampling, its
    design row otherwise) transformed alone; the inertia is also the one-tensor twin's (tests/naive.py:
    scipy's rotation, LAPACK's eigh and BLAS products) to rounding."""
    campaign = campaign_with(base, EVERY_DISTRIBUTION, runs=80, sampling=sampling, nominal_first=True)
    sampler = Sampler(campaign)
    run_ids, bounds = list(range(80)), [0, 13, 45, 80]  # chunks of 13, 32 and 35 runs
    chunked = [v for a, b in itertools.pairwise(bounds) for v in sampler.values_for_runs(run_ids[a:b])]
    redrawn = 0
    for run_id, values in zip(run_ids, chunked, strict=True):
        if run_id == 0:
            assert all(np.array_equal(values[p], sampler.nominal[p]) for p in EVERY_DISTRIBUTION)
            continue
        for path, spec in sampler.specs.items():
            n = dims(spec, dispersions.size(path, campaign["vehicle"]))
            if sampling == "random":
                u = keyed_rng(campaign["seed"], run_id, path).random(n)
            else:
                u = sampler.uniforms(path, run_id, n)
            u = np.clip(u, dispersions.UNIFORM_EPS, 1.0 - dispersions.UNIFORM_EPS)
            alone = transform(spec, u, sampler.nominal[path])
            if spec["dist"] == "inertia":
                twin = naive.dispersed_inertia(sampler.nominal[path], 0.3, 20.0, u)
                np.testing.assert_allclose(alone, twin, rtol=0, atol=INERTIA_TWIN_RTOL * np.abs(twin).max())
                if inertia_problem(dispersions.inertia_matrix(alone)) is not None:
                    redrawn += 1
                    continue  # drawn again with attempt 1, 2, ...: checked by the test below
            np.testing.assert_array_equal(values[path], alone, err_msg=f"{path} of run {run_id}")
    assert redrawn > 0  # the large inertia sigma makes some first draws unphysical


def test_inertia_is_redrawn_alone_until_physical(base):
    """A run whose first inertia draw is not physical gets the first physical one of attempts
    1, 2, ... of its own keyed stream, whatever chunk it is drawn in."""
    spec = {"inertia_kg_m2": EVERY_DISTRIBUTION["inertia_kg_m2"]}
    sampler = Sampler(campaign_with(base, spec, runs=60))
    nominal = sampler.nominal["inertia_kg_m2"]
    drawn = sampler.values_for_runs(list(range(60)))
    for run_id, values in enumerate(drawn):
        for attempt in range(1000):
            u = np.clip(keyed_rng(sampler.seed, run_id, "inertia_kg_m2", attempt).random(6), 2.0**-53, 1.0 - 2.0**-53)
            expected = transform(sampler.specs["inertia_kg_m2"], u, nominal)
            twin = naive.dispersed_inertia(nominal, 0.3, 20.0, u)
            np.testing.assert_allclose(expected, twin, rtol=0, atol=INERTIA_TWIN_RTOL * np.abs(twin).max())
            if inertia_problem(dispersions.inertia_matrix(expected)) is None:
                break
        np.testing.assert_array_equal(values["inertia_kg_m2"], expected, err_msg=f"run {run_id}")


def test_a_run_without_a_physical_draw_is_an_error_row_beside_the_others(base, monkeypatch):
    """Drawn in one chunk, a run whose inertia cannot be drawn (no redraws allowed here) fails
    alone: an error row naming the reason, while every other run of the chunk flies."""
    monkeypatch.setattr(sampling, "INERTIA_MAX_ATTEMPTS", 0)
    campaign = campaign_with(base, {"inertia_kg_m2": EVERY_DISTRIBUTION["inertia_kg_m2"]}, runs=24)
    prepared = RunPlan(campaign).prepare_runs(list(range(24)))
    failed = [i for i, p in enumerate(prepared) if isinstance(p, Exception)]
    assert 0 < len(failed) < 24
    rows, history = fly_chunk(campaign, range(24))
    assert [r["run_id"] for r in rows if r["status"] == "error"] == failed
    assert all("no physical inertia" in rows[i]["failure_reason"] for i in failed)
    assert set(history.column("run_id").to_pylist()) == set(range(24)) - set(failed)


def test_batched_inertia_check_agrees_with_inertia_problem():
    """unphysical_inertias (a chunk's tensors at once) says what inertia_problem says of each:
    physical, not positive definite, triangle violated, not symmetric, NaN."""
    rng = np.random.default_rng(4)
    tensors = []
    for _ in range(3000):
        axes = Rotation.random(random_state=rng).as_matrix()
        tensors.append(axes @ np.diag(rng.uniform(-0.2, 2.0, 3)) @ axes.T)
    tensors += [np.diag([1.0, 1.0, 2.0]), np.diag([1.0, 1.0, 2.0 + 1e-9]), np.diag([0.0, 1.0, 1.0])]
    tensors += [np.array([[1.0, 0.1, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]), np.full((3, 3), np.nan)]
    tensors = np.array(tensors)
    expected = [inertia_problem(t) is not None for t in tensors]
    assert 100 < sum(expected) < len(tensors) - 100  # both verdicts well represented
    assert unphysical_inertias(tensors).tolist() == expected


def test_inertia_draws_are_physical_and_disperse_the_principal_moments(base):
    n = 1500
    spec = {"inertia_kg_m2": {"dist": "inertia", "moments_sigma_fraction": [0.05, 0.01, 0.01], "axes_sigma_deg": 0}}
    values = draws(campaign_with(base, spec, runs=n), "inertia_kg_m2", range(n))
    j0 = dispersions.inertia_matrix(dispersions.nominal("inertia_kg_m2", base["vehicle"], {}))
    nominal, axes = np.linalg.eigh(j0)
    assert all(inertia_problem(dispersions.inertia_matrix(v)) is None for v in values)
    # without axis misalignment the principal axes stay those of the nominal tensor
    moments = np.array([np.diag(axes.T @ dispersions.inertia_matrix(v) @ axes) for v in values])
    off_diagonal = np.array([axes.T @ dispersions.inertia_matrix(v) @ axes for v in values]) * (1 - np.eye(3))
    assert np.abs(off_diagonal).max() < 1e-9 * nominal.max()
    relative = moments / nominal - 1.0
    # sample standard deviation of n = 1500 normal draws: relative standard error 1.8 %; 10 % bound.
    # These sigmas keep the triangle inequality (margin 16 kg m^2 against a 3.5 kg m^2 sigma of
    # J_z - J_y) from cutting the tails
    assert np.allclose(relative.std(axis=0), [0.05, 0.01, 0.01], rtol=0.10)
    assert np.all(np.abs(relative.mean(axis=0)) < 4 * np.array([0.05, 0.01, 0.01]) / math.sqrt(n))


def test_axis_misalignment_turns_the_principal_axes(base):
    spec = {"inertia_kg_m2": {"dist": "inertia", "moments_sigma_fraction": 0.0, "axes_sigma_deg": [0.0, 2.0, 0.0]}}
    values = draws(campaign_with(base, spec, runs=400), "inertia_kg_m2", range(400))
    j0 = dispersions.inertia_matrix(dispersions.nominal("inertia_kg_m2", base["vehicle"], {}))
    _, axes0 = np.linalg.eigh(j0)
    angles = []
    for v in values:
        j = dispersions.inertia_matrix(v)
        assert np.allclose(np.linalg.eigvalsh(j), np.linalg.eigvalsh(j0), rtol=1e-12)  # same moments
        _, axes = np.linalg.eigh(j)
        # a turn about body y tilts the minor (roll) principal axis by the turn angle
        angles.append(np.degrees(np.arccos(min(1.0, abs(axes[:, 0] @ axes0[:, 0])))))
    # RMS of |N(0, 2 deg)| is 2 deg; standard error at n = 400 is 3.5 %, bound 12 %
    assert math.sqrt(np.mean(np.square(angles))) == pytest.approx(2.0, rel=0.12)


def test_large_inertia_dispersions_are_redrawn_until_physical(base):
    spec = {"inertia_kg_m2": {"dist": "inertia", "moments_sigma_fraction": 0.3, "axes_sigma_deg": 20}}
    values = draws(campaign_with(base, spec, runs=300), "inertia_kg_m2", range(300))
    assert all(inertia_problem(dispersions.inertia_matrix(v)) is None for v in values)
    # unconditioned, a 30 % sigma on J_z = 248 against J_x + J_y = 264 would break the triangle
    # inequality in ~40 % of draws: check that such draws happened and were replaced
    j0 = np.linalg.eigvalsh(dispersions.inertia_matrix(dispersions.nominal("inertia_kg_m2", base["vehicle"], {})))
    assert np.ptp(np.array([np.linalg.eigvalsh(dispersions.inertia_matrix(v)) for v in values])[:, 2]) > 0.5 * j0[2]


# --- LHS and Sobol designs ---------------------------------------------------------------------------


def test_lhs_has_one_point_per_stratum_in_every_component(base):
    n = 50
    campaign = campaign_with(base, {"rcs.thrust_scale": {"dist": "uniform", "low": 0.0, "high": 1.0}}, runs=n + 1)
    campaign.update(sampling="lhs", nominal_first=True)
    sampler = Sampler(campaign)
    u = np.array([sampler.values(i)["rcs.thrust_scale"] for i in range(1, n + 1)])
    for k in range(8):
        assert sorted(np.floor(u[:, k] * n).astype(int)) == list(range(n))


def test_sobol_points_are_balanced(base):
    n = 64
    campaign = campaign_with(base, {"initial_state.rates_deg_s": {"dist": "uniform", "low": 0, "high": 1}}, runs=n)
    campaign["sampling"] = "sobol"
    u = draws(campaign, "initial_state.rates_deg_s", range(n))
    for k in range(3):  # a scrambled Sobol net: one point in each of the 64 elementary intervals
        assert sorted(np.floor(u[:, k] * n).astype(int)) == list(range(n))
    for a, b in [(0, 1), (0, 2), (1, 2)]:  # (t, m, s)-net property in 2-D: every 8x8 cell has one point
        cells = np.floor(u[:, a] * 8).astype(int) * 8 + np.floor(u[:, b] * 8).astype(int)
        assert sorted(cells) == list(range(64))


# --- failures ---------------------------------------------------------------------------------------


def test_random_failure_counts_follow_the_probabilities(base):
    n = 3000
    probabilities = [0.7, 0.2, 0.1]
    campaign = campaign_with(base, {}, runs=n, failures={"mode": "random", "count_probabilities": probabilities})
    sampler = Sampler(campaign)
    sets = [sampler.failed(i) for i in range(n)]
    counts = np.bincount([len(s) for s in sets], minlength=3)
    for k, p in enumerate(probabilities):
        assert abs(counts[k] / n - p) < 4 * math.sqrt(p * (1 - p) / n)
    assert all(len(set(s)) == len(s) and list(s) == sorted(s) and all(1 <= t <= 8 for t in s) for s in sets)
    singles = np.bincount([s[0] for s in sets if len(s) == 1], minlength=9)[1:]
    assert stats.chisquare(singles).pvalue > P_MIN  # each thruster equally likely


def test_enumerate_gives_every_set_once_after_the_nominal_run(base):
    campaign = campaign_with(base, {}, runs=37, nominal_first=True, failures={"mode": "enumerate", "sizes": [2, 1]})
    sampler = Sampler(campaign)
    sets = [sampler.failed(i) for i in range(37)]
    assert sets[0] == ()
    assert sets[1:9] == [(t,) for t in range(1, 9)]
    assert len(set(sets[9:])) == 28 and all(len(s) == 2 for s in sets[9:])
    assert failure_sets([1, 2], 8) == sets[1:]


def test_nominal_run_keeps_fixed_failures_and_has_no_dispersion(base):
    campaign = campaign_with(base, MIXED, runs=3, nominal_first=True, failures={"mode": "fixed", "thrusters": [8, 1]})
    plan = RunPlan(campaign)
    _, failed, params, inputs = plan.prepare(0)
    assert failed.thrusters == (1, 8) and failed.wheels == ()
    assert inputs.thrusters[:, L.THRUSTER.slices["failed"][0]].tolist() == [1, 0, 0, 0, 0, 0, 0, 1]
    for name, array in plan.nominal_inputs._asdict().items():
        if name != "thrusters":
            assert np.array_equal(getattr(inputs, name), array), name
    assert params["p.rcs.thrust_scale.3"] == 1.0


# --- every path reaches the flight -------------------------------------------------------------------


def _perturbed(value):
    return np.where(value == 0.0, 0.3, value * 0.8)  # inside every physical range


def _flight_arrays(inputs, seed):
    result = fly(inputs, nav_seed=seed, history_rate_hz=40.0)
    return np.concatenate([result.summary, result.pulse_counts, result.history.ravel()])


ORBIT_PATHS = ("main_engine.", "navigation.gps_")  # quantities of an orbit vehicle and mission only
WHEEL_PATHS = ("wheels.",)  # quantities of a vehicle with reaction wheels only (tests/test_wheel_failures.py)
LOCAL_PATHS = ("rcs.feed.", "local.", "navigation.local_", "navigation.tank_pressure")  # a tank, a local trajectory


def _paths_change_the_flight(campaign, paths):
    """Fly each component of each path perturbed alone; the count of those checked."""
    campaign["nominal_first"] = False
    reference_plan = RunPlan(campaign)
    seed, _, _, reference_inputs = reference_plan.prepare(0)
    reference = _flight_arrays(reference_inputs, seed)
    checked = 0
    for path in paths:
        param = dispersions.PARAMETERS[path]
        nominal = dispersions.nominal(path, campaign["vehicle"], campaign["mission"])
        for k, component in enumerate(dispersions.components(path, campaign["vehicle"]) or ("",)):
            if path == "main_engine.misalignment_deg" and component == "z":
                continue  # a turn about the engine's own axis (body z) leaves its direction unchanged
            value = nominal.copy()
            if param.shape == "inertia" and k >= 3:
                value[k] += 2.0  # a product of inertia (still physical)
            elif param.shape == "attitude":
                value[k] += 20.0
            elif path == "initial_state.flight_path_angle_deg":
                value[k] += 2.0
            elif path == "navigation.tank_pressure_noise_pa":
                value[k] = 2.5e4  # 0.3 Pa on a 50 bar tank changes no decision of the law
            else:
                value[k] = _perturbed(value[k])
            inputs = reference_plan.sampler.inputs(reference_plan.nominal_inputs, {path: value}, ())
            assert not np.array_equal(_flight_arrays(inputs, seed), reference), f"{path} {component} ignored"
            checked += 1
    return checked


def test_every_dispersion_path_and_component_changes_the_flight(base):
    """No dispersion is silently ignored: each path, each component alone, changes the flight."""
    campaign = copy.deepcopy(base)
    # calibration time only acts on an attitude bias, noise only with a non-zero seed
    campaign["mission"]["navigation"]["attitude_bias_deg"] = [0.5, -0.4, 0.3]
    # a correlation time only acts with a Gauss-Markov sigma (issue 35)
    campaign["mission"]["navigation"].update(
        attitude_gm_sigma_deg=0.01, attitude_gm_tau_s=5.0, rate_gm_sigma_deg_s=0.001, rate_gm_tau_s=5.0
    )
    # the entry paths (an entry mission only): tests/test_x38_campaign.py
    others = ORBIT_PATHS + WHEEL_PATHS + LOCAL_PATHS + ("entry_flight.",)
    paths = [p for p in dispersions.PARAMETERS if not p.startswith(others)]
    assert _paths_change_the_flight(campaign, paths) >= 100


def test_every_tank_and_local_dispersion_path_changes_the_surveyor_hop():
    """The feed's and the local trajectory's paths, on the cold-gas surveyor's hop (issue 23)."""
    campaign = load_campaign(ROOT / "campaigns/surveyor-hop.yaml")
    campaign["dispersions"] = {}
    paths = [p for p in dispersions.PARAMETERS if p.startswith(LOCAL_PATHS)]
    # 3 navigation noises, every number of the feed (8: tank volume, gas constant, gamma, P0, T,
    # throat, expansion ratio, ambient pressure; issue 34 point 7), position and velocity (3 each)
    assert _paths_change_the_flight(campaign, paths) == 3 + 8 + 3 + 3


def test_every_orbit_dispersion_path_changes_the_deorbit_flight():
    """The orbit-only paths, on the SPORE campaign (the GPS noise acts through the burn guidance)."""
    campaign = load_campaign(ROOT / "campaigns/spore-deorbit-iss.yaml")
    campaign["dispersions"] = {}
    paths = [p for p in dispersions.PARAMETERS if p.startswith(ORBIT_PATHS)]
    assert _paths_change_the_flight(campaign, paths) == 1 + 2 + 3 + 1 + 3 + 1
