"""Reaction-wheel failures and wheel dispersions in campaigns (issue 14): keyed draws, the sets of
each mode, what ``detected`` does to the packed inputs, the runs column end to end, bad input."""

import json
import math
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest
from click.testing import CliRunner

from refexmc.campaign.chunk import RunPlan
from refexmc.campaign.sampling import Sampler
from refexmc.cli import main
from refexmc.config import derived, dispersions
from refexmc.config.errors import ConfigError
from refexmc.config.load import apply_overrides, load_campaign
from refexmc.core import layout as L
from refexmc.simulate import fly

ROOT = Path(__file__).resolve().parents[1]
IRASSI = ROOT / "configs/vehicles/irassi.yaml"
SMALL = ROOT / "configs/missions/irassi-small-angle.yaml"
REFEX = ROOT / "configs/vehicles/refex.yaml"
REFEX_MISSION = ROOT / "configs/missions/refex-exo.yaml"
FAILED = L.WHEEL.slices["failed"][0]
# numpy's SVD-based pinv of the same 3 x 3 matrix twice: agreement to rounding
EXACT = 1e-12
# the science hold shortened from 22 h to 600 s, the pointing window to its last 300 s: a flight
# of 600 control steps, enough to exercise every wheel path and column
SHORT_MISSION = (
    SMALL.read_text()
    .replace("exit: [{mission_time_s: 79200.0}]", "exit: [{mission_time_s: 600.0}]")
    .replace("pointing_statistics_from_s: 14400.0", "pointing_statistics_from_s: 300.0")
    .replace("max_flight_time_s: 80000.0", "max_flight_time_s: 700.0")
)


def _campaign_file(tmp_path, extra, runs=6, vehicle=IRASSI, mission=None):
    if mission is None:
        mission = tmp_path / "mission.yaml"
        mission.write_text(SHORT_MISSION)
    text = f"name: wheel-failures\nvehicle: {vehicle}\nmission: {mission}\n"
    text += (f"runs: {runs}\n" if runs is not None else "") + f"seed: 7\n{extra}"
    (tmp_path / "campaign.yaml").write_text(text)
    return tmp_path / "campaign.yaml"


def _campaign(tmp_path, extra, runs=6):
    return load_campaign(_campaign_file(tmp_path, extra, runs))


RANDOM = "wheel_failures: {mode: random, count_probabilities: [0.8, 0.2]}\n"


# --- keyed draws ------------------------------------------------------------------------------------


def test_random_wheel_failures_are_keyed_by_seed_and_run_id(tmp_path):
    """The same seed and run id give the same set, whatever else the campaign has (its own stream,
    keyed by 'wheel_failures'), and the runs differ among themselves."""
    campaign = _campaign(tmp_path, RANDOM, runs=400)
    sets = [Sampler(campaign).failed_wheels(i) for i in range(400)]
    assert sets == [Sampler(campaign).failed_wheels(i) for i in range(400)]
    other = _campaign(
        tmp_path, RANDOM + "dispersions:\n  wheels.friction.coulomb_n_m: {dist: normal, sigma: 0.0005}\n", runs=400
    )
    assert sets == [Sampler(other).failed_wheels(i) for i in range(400)]
    assert sets[0] == ()  # the nominal run
    assert all(len(s) <= 1 and all(1 <= w <= 4 for w in s) for s in sets)
    assert {s for s in sets if s} == {(1,), (2,), (3,), (4,)}
    reseeded = apply_overrides(_campaign(tmp_path, RANDOM, runs=400), seed=8)
    assert sets != [Sampler(reseeded).failed_wheels(i) for i in range(400)]


def test_the_share_of_runs_with_a_failed_wheel_is_the_probability(tmp_path):
    """Over n = 4000 dispersed runs with P(1 failed) = 0.2 the count is binomial: within 5 standard
    deviations (sqrt(n p (1 - p)) = 25 runs) of n p = 800 (a false alarm once in 1.7 million)."""
    n, p = 4000, 0.2
    campaign = _campaign(tmp_path, "nominal_first: false\n" + RANDOM, runs=n)
    sampler = Sampler(campaign)
    count = sum(1 for i in range(n) if sampler.failed_wheels(i))
    assert abs(count - n * p) <= 5.0 * math.sqrt(n * p * (1 - p)), f"{count} of {n} runs, expected about {n * p}"


def test_wheel_and_thruster_failures_use_their_own_streams():
    """Thruster failures of a vehicle without wheels are drawn as before (key 'failures')."""
    refex = load_campaign(ROOT / "campaigns/refex-mc100.yaml")
    refex["failures"] = {"mode": "random", "count_probabilities": [0.5, 0.5]}
    sampler = Sampler(refex)
    assert sampler.failed_wheels(3) == () and len({sampler.failed(i) for i in range(1, 40)}) > 2


# --- fixed and enumerate -----------------------------------------------------------------------------


def test_fixed_wheel_failures_by_name_or_id_fail_every_run_including_the_nominal(tmp_path):
    campaign = _campaign(tmp_path, "wheel_failures: {mode: fixed, wheels: [RW3, 1]}\n")
    assert campaign["wheel_failures"]["wheels"] == [3, 1]  # names resolved to ids on load
    sampler = Sampler(campaign)
    assert [sampler.failed_wheels(i) for i in range(6)] == [(1, 3)] * 6


def test_enumerated_wheel_failures_derive_the_run_count(tmp_path):
    campaign = _campaign(tmp_path, "wheel_failures: {mode: enumerate, sizes: [1, 2]}\n", runs=None)
    assert campaign["runs"] == 1 + 4 + 6
    sampler = Sampler(campaign)
    sets = [sampler.failed_wheels(i) for i in range(campaign["runs"])]
    assert sets == [(), (1,), (2,), (3,), (4,), (1, 2), (1, 3), (1, 4), (2, 3), (2, 4), (3, 4)]
    with pytest.raises(ConfigError, match="--runs cannot be used with wheel_failures mode enumerate"):
        apply_overrides(campaign, runs=3)


# --- what reaches the packed inputs ------------------------------------------------------------------


def _run_with_failure(plan, n=50):
    return next(i for i in range(n) if plan.sampler.failed_wheels(i))


@pytest.mark.parametrize("detected", [False, True])
def test_a_failed_wheel_reaches_the_wheel_table_and_a_detected_one_the_distribution(tmp_path, detected):
    """Undetected: the wheel's failed column is set, the flight software's distribution is the
    nominal one. Detected: besides, the failed wheel's row is zero and the others are numpy's
    pinv of the other three axes (001 sec. 9.1), and the levels' limits are those of three wheels."""
    extra = f"wheel_failures: {{mode: random, count_probabilities: [0.5, 0.5], detected: {str(detected).lower()}}}\n"
    plan = RunPlan(_campaign(tmp_path, extra, runs=50))
    run_id = _run_with_failure(plan)
    (wheel,) = plan.sampler.failed_wheels(run_id)
    _, failed, _, inputs = plan.prepare(run_id)
    assert failed.wheels == (wheel,) and failed.thrusters == ()
    assert inputs.wheels[:, FAILED].tolist() == [1.0 if w == wheel else 0.0 for w in (1, 2, 3, 4)]
    assert plan.nominal_inputs.wheels[:, FAILED].tolist() == [0.0] * 4  # the run's own copy
    nominal = plan.nominal_inputs
    if not detected:
        assert np.array_equal(inputs.wheel_distribution, nominal.wheel_distribution)
        assert np.array_equal(inputs.levels, nominal.levels)
        return
    others = [w - 1 for w in (1, 2, 3, 4) if w != wheel]
    axes = derived.wheel_axes(plan.campaign["vehicle"])
    assert np.all(inputs.wheel_distribution[wheel - 1] == 0.0)
    np.testing.assert_allclose(inputs.wheel_distribution[others], np.linalg.pinv(axes[:, others]), atol=EXACT)
    assert not np.array_equal(inputs.levels, nominal.levels)


def test_wheel_dispersions_reach_the_runs_own_wheel_table(tmp_path):
    """Friction: every wheel the one drawn value; initial momentum: one value per wheel. The nominal
    inputs (shared by the runs of a chunk) are not written."""
    extra = (
        "dispersions:\n"
        "  wheels.friction.coulomb_n_m: {dist: uniform, low: 0.001, high: 0.002}\n"
        "  wheels.friction.viscous_n_m_s: {dist: uniform, low: 1.0e-5, high: 2.0e-5}\n"
        "  wheels.initial_momentum_n_m_s: {dist: normal, sigma: 1.0}\n"
    )
    plan = RunPlan(_campaign(tmp_path, extra))
    before = plan.nominal_inputs.wheels.copy()
    _, _, params, inputs = plan.prepare(2)
    assert np.array_equal(plan.nominal_inputs.wheels, before)

    def column(name):
        return inputs.wheels[:, L.WHEEL.slices[name][0]]

    assert np.all(column("coulomb_friction_n_m") == params["p.wheels.friction.coulomb_n_m"])
    assert 0.001 <= params["p.wheels.friction.coulomb_n_m"] <= 0.002
    assert np.all(column("viscous_friction_n_m_s") == params["p.wheels.friction.viscous_n_m_s"])
    momenta = [params[f"p.wheels.initial_momentum_n_m_s.{w}"] for w in (1, 2, 3, 4)]
    assert column("initial_momentum_n_m_s").tolist() == momenta and len(set(momenta)) == 4


@pytest.mark.slow
def test_every_wheel_path_and_component_changes_the_flight(tmp_path):
    """No wheel dispersion is silently ignored: each path, each component alone, changes the flight."""
    plan = RunPlan(_campaign(tmp_path, ""))
    campaign = plan.campaign

    def flight(inputs):
        result = fly(inputs, nav_seed=1, history_rate_hz=1.0)
        return np.concatenate([result.summary, result.history.ravel()])

    reference = flight(plan.nominal_inputs)
    paths = [p for p in dispersions.PARAMETERS if p.startswith("wheels.")]
    checked = 0
    for path in paths:
        nominal = dispersions.nominal(path, campaign["vehicle"], campaign["mission"])
        for k in range(dispersions.size(path, campaign["vehicle"])):
            value = nominal.copy()
            value[k] = value[k] * 0.5 if value[k] else 2.0
            inputs = plan.sampler.inputs(plan.nominal_inputs, {path: value}, ())
            assert not np.array_equal(flight(inputs), reference), f"{path} component {k} ignored"
            checked += 1
    assert checked == 1 + 1 + 4


# --- end to end ----------------------------------------------------------------------------------------


@pytest.mark.slow
def test_a_small_irassi_campaign_with_wheel_failures_runs_and_reruns(tmp_path):
    extra = (
        "wheel_failures: {mode: random, count_probabilities: [0.5, 0.5], detected: true}\n"
        "dispersions:\n  wheels.friction.coulomb_n_m: {dist: normal, sigma: 0.0005}\n"
        "output: {history_rate_hz: 0.01}\n"
    )
    path = _campaign_file(tmp_path, extra)
    out = tmp_path / "out"
    result = CliRunner().invoke(main, ["run", str(path), "-o", str(out), "-j", "1"])
    assert result.exit_code == 0, result.output
    runs = pq.read_table(out / "runs").to_pandas().sort_values("run_id")
    sampler = Sampler(load_campaign(path))
    expected = [",".join(str(w) for w in sampler.failed_wheels(i)) for i in range(6)]
    assert runs["failed_wheels"].tolist() == expected
    assert any(expected) and runs["success"].all()
    assert runs["failed_thrusters"].tolist() == [""] * 6
    run_id = next(i for i, s in enumerate(expected) if s)
    rerun = CliRunner().invoke(main, ["rerun", str(out), str(run_id)])
    assert rerun.exit_code == 0, rerun.output
    assert f"failed wheels [{expected[run_id]}]" in rerun.output
    assert "summary row identical to the stored one" in rerun.output
    # the report groups the runs by failed-wheel set: its statistics are those of each group
    report = CliRunner().invoke(main, ["report", str(out)])
    assert report.exit_code in (0, 1), report.output
    assert "failed wheels (detected (redistributed)), per set:" in report.output
    summary = json.loads((out / "report" / "summary.json").read_text())
    sets = summary["wheel_failure_sets"]
    assert sets["detected"] is True
    for row in sets["sets"]:
        group = runs[runs["failed_wheels"] == row["failed_wheels"]]
        assert row["runs"] == len(group) and row["successes"] == int(group["success"].sum())
        assert row["wheel_momentum_peak_n_m_s.max"] == group["wheel_momentum_peak_n_m_s"].max()
        median = np.median(group["pointing_rms_x_arcsec"])
        assert row["pointing_rms_x_arcsec.median"] == pytest.approx(median, rel=1e-12)
    assert sorted(r["failed_wheels"] for r in sets["sets"]) == sorted(set(expected))


# --- bad input ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("vehicle", "extra", "fragment", "words"),
    [
        (
            REFEX,
            "wheel_failures: {mode: fixed, wheels: [1]}\n",
            "wheel_failures",
            "wheel_failures.mode: wheel_failures mode fixed fails wheels; the vehicle has none",
        ),
        (
            IRASSI,
            "wheel_failures:\n  mode: fixed\n  wheels: [5]\n",
            "wheels: [5]",
            "wheel_failures.wheels.0: expected a wheel id 1..4, got 5",
        ),
        (
            IRASSI,
            "wheel_failures:\n  mode: fixed\n  wheels: [RW5]\n",
            "wheels: [RW5]",
            "wheel_failures.wheels.0: unknown wheel 'RW5'; did you mean",
        ),
        (
            IRASSI,
            "wheel_failures:\n  mode: random\n  count_probabilities: [0.2, 0.2, 0.2, 0.2, 0.1, 0.1]\n",
            "count_probabilities",
            "expected at most 5 probabilities (0..4 failed)",
        ),
        (
            IRASSI,
            "wheel_failures:\n  mode: random\n  sizes: [1]\n  count_probabilities: [1.0]\n",
            "sizes",
            "wheel_failures.sizes: 'sizes' is not used with mode random",
        ),
        (
            REFEX,
            "dispersions:\n  wheels.friction.coulomb_n_m: {dist: normal, sigma: 0.001}\n",
            "wheels.friction",
            "'wheels.friction.coulomb_n_m': the vehicle file does not declare it",
        ),
        (
            IRASSI,
            "wheel_failures:\n  mode: none\n  detected: true\n",
            "  detected: true",
            "wheel_failures.detected: 'detected' is not used with mode none (no wheel fails)",
        ),
    ],
    ids=[
        "no-wheels",
        "unknown-id",
        "unknown-name",
        "too-many-probabilities",
        "unused-key",
        "wheel-path-on-refex",
        "detected-without-failures",
    ],
)
def test_bad_wheel_failures_exit_2_with_file_line_and_key(tmp_path, vehicle, extra, fragment, words):
    mission = REFEX_MISSION if vehicle == REFEX else None
    path = _campaign_file(tmp_path, extra, vehicle=vehicle, mission=mission)
    result = CliRunner().invoke(main, ["validate", str(path)])
    assert result.exit_code == 2, result.output
    assert "Traceback" not in result.output
    line = next(n for n, s in enumerate(path.read_text().splitlines(), 1) if fragment in s)
    assert f"{path}:{line}:" in result.output, result.output
    assert words in result.output, result.output
