"""Navigation noise of the local trajectory (core.local_flight.measure, docs/cold-gas.md sec. 2):
position, velocity and tank pressure measured with white noise, against its twin, the drawn sigma
from the kernel's own sample sequence, and in flight: zero noise is the pre-noise surveyor hop bit
for bit, each noise changes the hop, and the same seed flies the same noise."""

import math
from pathlib import Path

import numpy as np
import pyarrow as pa
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from naive import SplitMix64, local_measure
from scipy.stats import chi2
from stored import campaign_copy

from refexmc.campaign import storage
from refexmc.campaign.chunk import fly_chunk
from refexmc.config.load import load_campaign, load_mission, load_vehicle
from refexmc.config.pack import mode_names, pack
from refexmc.core import layout, local_flight
from refexmc.simulate import fly

ROOT = Path(__file__).resolve().parents[1]
NOISE_PATHS = (
    "navigation.local_position_noise_m",
    "navigation.local_velocity_noise_m_s",
    "navigation.tank_pressure_noise_pa",
)


def nav_table(position_noise=0.0, velocity_noise=0.0, pressure_noise=0.0):
    nav = np.zeros(layout.NAV_SIZE)
    nav[layout.N_LOCAL_POSITION_NOISE] = position_noise
    nav[layout.N_LOCAL_VELOCITY_NOISE] = velocity_noise
    nav[layout.N_TANK_PRESSURE_NOISE] = pressure_noise
    return nav


def measure(state, pressure, nav, seed):
    rng_state = np.array([seed], dtype=np.uint64)
    out = np.empty(7)
    local_flight.measure(nav, np.asarray(state, float), pressure, rng_state, out)
    return out, int(rng_state[0])


def test_without_noise_the_measurement_is_the_truth_and_draws_nothing():
    state = [3.0, -1.0, 0.25, 0.1, -0.2, 1e-3]
    out, rng_after = measure(state, 4.2e6, nav_table(), 12345)
    assert np.array_equal(out, [*state, 4.2e6])
    assert rng_after == 12345


@settings(deadline=None, max_examples=100)
@given(
    state=st.lists(st.floats(-10.0, 10.0), min_size=6, max_size=6),
    pressure=st.floats(0.0, 6e6),
    position_noise=st.sampled_from([0.0, 1e-3, 0.05]),
    velocity_noise=st.sampled_from([0.0, 1e-4, 0.01]),
    pressure_noise=st.sampled_from([0.0, 1e3, 1e7]),  # 1e7 Pa: readings below zero happen (they read 0)
    seed=st.integers(0, 2**64 - 1),
)
def test_measure_matches_its_twin(state, pressure, position_noise, velocity_noise, pressure_noise, seed):
    """The same draws in the same order: equal to the last ulp of the sums (rtol 1e-15)."""
    out, rng_after = measure(state, pressure, nav_table(position_noise, velocity_noise, pressure_noise), seed)
    noise = SplitMix64(seed)
    position, velocity, p = local_measure(
        state[:3], state[3:], pressure, position_noise, velocity_noise, pressure_noise, noise
    )
    assert np.allclose(out[:3], position, rtol=1e-15, atol=1e-15)
    assert np.allclose(out[3:6], velocity, rtol=1e-15, atol=1e-15)
    assert out[6] == pytest.approx(p, rel=1e-15, abs=1e-15)
    assert out[6] >= 0.0
    assert rng_after == noise.state


def test_noise_has_the_drawn_sigma():
    """The kernel's sample sequence, 5,000 periods: each axis's sample sigma within 5 % (its standard
    error is sigma / sqrt(2 n) = 1 %) and its mean within 5 standard errors of the truth."""
    sigmas, n = (0.01, 2e-3, 2.5e4), 5000
    nav = nav_table(*sigmas)
    truth = np.array([3.0, 1.0, 0.0, 0.1, -0.05, 0.0])
    pressure = 4.0e6
    rng_state = np.array([20170701], dtype=np.uint64)
    samples, out = np.empty((n, 7)), np.empty(7)
    for k in range(n):
        local_flight.measure(nav, truth, pressure, rng_state, out)
        samples[k] = out
    errors = samples - np.array([*truth, pressure])
    expected = np.repeat(sigmas, [3, 3, 1])
    assert np.allclose(errors.std(axis=0), expected, rtol=0.05)
    assert np.all(np.abs(errors.mean(axis=0)) < 5 * expected / math.sqrt(n))


def _bits(column):
    column = column.combine_chunks() if isinstance(column, pa.ChunkedArray) else column
    if pa.types.is_floating(column.type):
        return column.to_numpy(zero_copy_only=False).view(np.uint64).tolist()
    return column.to_pylist()


def test_zero_noise_flies_the_surveyor_hop_of_before_bit_for_bit(tmp_path):
    """baselines/surveyor-hop-40: runs 0-39 of campaigns/surveyor-hop.yaml flown by main before the
    navigation noise (commit bc41557, 3 of them with a stuck valve), regenerated on purpose by
    issue 33 (each segment's thrust over the mass at its points, Simpson's rule: every run moved
    by micrometres, four changed a valve decision) and by issue 37 (core/elementary.py: every
    flight's last bits; a pin since). With every new sigma a constant 0 the table
    is the same, bit for bit, apart from the constant columns of the new paths."""
    text = (ROOT / "campaigns/surveyor-hop.yaml").read_text()
    replace = []
    for path in NOISE_PATHS:
        line = next(line for line in text.splitlines() if line.startswith(f"  {path}:"))
        replace.append((line, f"  {path}: {{dist: constant, value: 0.0}}"))
    campaign = load_campaign(campaign_copy("surveyor-hop.yaml", tmp_path, replace=replace))
    rows, _ = fly_chunk(campaign, range(40))
    flown = storage.runs_table(rows)
    baseline = storage.read_runs_part(ROOT / "baselines/surveyor-hop-40/runs").sort_by("run_id")  # names of now
    assert baseline.column("success").to_pylist().count(False) == 3
    for name in baseline.column_names:
        assert _bits(flown[name]) == _bits(baseline[name]), name


@pytest.fixture(scope="module")
def hop():
    vehicle = load_vehicle(ROOT / "configs/vehicles/cold-gas-surveyor.yaml")
    mission = load_mission(ROOT / "configs/missions/surveyor-hop.yaml")

    def fly_with(seed=7, **noise):
        m = dict(mission, navigation=dict(mission["navigation"], **noise))
        return fly(pack(vehicle, m), history_rate_hz=1.0, mode_names=mode_names(m), nav_seed=seed).runs_values()

    return fly_with


@pytest.mark.parametrize(
    "noise",
    [{"local_position_noise_m": 0.01}, {"local_velocity_noise_m_s": 2e-3}, {"tank_pressure_noise_pa": 2.5e4}],
)
def test_each_noise_reaches_the_law_and_the_same_seed_flies_the_same_noise(hop, noise):
    """The nominal hop with one sigma set: a different flight (the law reads the measurement),
    the same one again with the same navigation seed, another with another seed."""
    quiet, noisy, again, other = hop(), hop(**noise), hop(**noise), hop(seed=8, **noise)
    keys = ("t_end_s", "fuel_used_kg", "position_error_end_m", "speed_end_m_s", "switches_x", "switches_y")
    assert [noisy[k] for k in keys] == [again[k] for k in keys]
    assert noisy["t_end_s"] != quiet["t_end_s"] or noisy["fuel_used_kg"] != quiet["fuel_used_kg"]
    assert other["fuel_used_kg"] != noisy["fuel_used_kg"]


@pytest.mark.parametrize(
    ("noise_key", "predicate"),
    [("local_position_noise_m", "position_error_below_m"), ("local_velocity_noise_m_s", "speed_below_m_s")],
)
def test_in_flight_the_exit_predicates_see_the_drawn_sigma(tmp_path, noise_key, predicate):
    """From flights: the surveyor at rest on its target, its law held off by a deadband of 10 m and
    10 m/s, in a translate mode that ends when the measured position error (speed) is below
    r = sigma. A measurement is inside with p = P(chi2_3 < 1) = 0.199 per control period, so the
    periods flown until the mode ends (t_end / dt + 1) are geometric with mean 1/p = 5.03 (sd 4.5).
    400 navigation seeds: the sample mean within 4 standard errors (0.9) of it, where a sigma 10 %
    off would put it 6 standard errors away (flown with 1.1 sigma: 0.93 off, the test fails)."""
    sigma = 0.01
    text = (ROOT / "configs/missions/surveyor-hop.yaml").read_text()
    text = text.replace(
        "    kind: translate\n    exit: [{position_error_below_m: 0.05, speed_below_m_s: 0.01}]",
        f"    kind: translate\n    exit: [{{{predicate}: {sigma}}}]",
    )
    text = text.replace("  position_m: [0.0, 0.0, 0.0]", "  position_m: [3.0, 1.0, 0.0]")
    text = text.replace(f"  {noise_key}: 0.0", f"  {noise_key}: {sigma}")
    (tmp_path / "mission.yaml").write_text(text)
    mission = load_mission(tmp_path / "mission.yaml")
    vehicle = load_vehicle(ROOT / "configs/vehicles/cold-gas-surveyor.yaml")
    vehicle["flight_software"]["translation"].update(deadband_position_m=10.0, deadband_speed_m_s=10.0)
    inputs = pack(vehicle, mission)
    dt = inputs.fsw[layout.F_CONTROL_PERIOD]
    periods = []
    for seed in range(1, 401):
        result = fly(inputs, nav_seed=seed, history_rate_hz=1.0, mode_names=mode_names(mission))
        assert result.success
        periods.append(round(result.runs_values()["t_end_s"] / dt) + 1)
    p = chi2.cdf(1.0, 3)
    standard_error = math.sqrt(1.0 - p) / p / math.sqrt(len(periods))
    assert abs(np.mean(periods) - 1.0 / p) < 4.0 * standard_error, (np.mean(periods), 1.0 / p)
