"""Attitude and rate knowledge error as a gyro-stellar estimator makes it (issue 35, reference-model
sec. 7): bias + first-order Gauss-Markov (exact discrete update) + white, in core.navigation.

- the exact update keeps the variance stationary for any step (twin: the variance recursion);
- the kernel's path is the twin's, draw for draw;
- over many seeds the path's variance and its autocorrelation at lag tau (e^-1) are within their
  sampling error;
- sigma and tau come back from a flown history (the AKE samples recorded at the control rate);
- zero Gauss-Markov error keeps the bits of the runs flown before it existed (smoke: test_generic_missions;
  IRASSI: baselines/irassi-white).
"""

import json
import math
import struct
from pathlib import Path

import numpy as np
import pytest
from naive import SplitMix64, gauss_markov_path, gauss_markov_variance

from refexmc.campaign.chunk import fly_chunk
from refexmc.config import pointing as config_pointing
from refexmc.config import renames
from refexmc.config.load import load_campaign, load_mission, load_vehicle
from refexmc.config.pack import mode_names, pack
from refexmc.core import layout as L
from refexmc.core import navigation
from refexmc.simulate import fly

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize("dt_over_tau", [1e-4, 0.1, 1.0, 30.0])
def test_the_exact_update_keeps_the_variance_stationary_over_a_million_steps(dt_over_tau):
    sigma, tau = 0.1, 10.0
    dt = dt_over_tau * tau
    a, drive = navigation.gauss_markov_coefficients(dt, tau)
    assert a == math.exp(-dt / tau) and drive == math.sqrt(1.0 - a * a)  # scalar libm in the kernel
    variance = gauss_markov_variance(sigma, dt, tau, 1_000_000)
    # each step is a contraction (a^2 < 1) of rounding errors of ~1e-16 sigma^2: they cannot add up
    assert abs(variance - sigma * sigma) <= 1e-12 * sigma * sigma


def _nav(sigma_att=0.0, tau_att=1.0, sigma_rate=0.0, tau_rate=1.0):
    nav = np.zeros(L.NAV_SIZE)
    nav[L.N_ATT_GM_SIGMA], nav[L.N_ATT_GM_TAU] = sigma_att, tau_att
    nav[L.N_RATE_GM_SIGMA], nav[L.N_RATE_GM_TAU] = sigma_rate, tau_rate
    return nav


def test_the_kernel_path_is_the_twins_draw_for_draw():
    sigma, tau, dt, steps = 2e-6, 7.0, 0.5, 200
    nav = _nav(sigma_att=sigma, tau_att=tau)
    state = np.array([987654321], dtype=np.uint64)
    knowledge = np.zeros(navigation.KNOWLEDGE_SIZE)
    navigation.start(nav, dt, state, knowledge)
    path = [knowledge[navigation.K_ATTITUDE]]
    for _ in range(steps):
        navigation.propagate(nav, state, knowledge)
        path.append(knowledge[navigation.K_ATTITUDE])
    # the twin's draws, x axis only: the kernel draws x, y, z per step, so the twin takes every third
    twin_noise = SplitMix64(987654321)

    class EveryThird:
        def normal(self):
            value = twin_noise.normal()
            twin_noise.normal()
            twin_noise.normal()
            return value

    twin = gauss_markov_path(sigma, dt, tau, steps, EveryThird())
    # the same operations on the same draws; exp and sqrt may differ by an ulp between libm and Python
    np.testing.assert_allclose(path, twin, rtol=1e-13, atol=1e-13 * sigma)


def test_zero_sigma_draws_nothing():
    state = np.array([42], dtype=np.uint64)
    knowledge = np.ones(navigation.KNOWLEDGE_SIZE)
    navigation.start(_nav(), 1.0, state, knowledge)
    navigation.propagate(_nav(), state, knowledge)
    assert int(state[0]) == 42 and not knowledge.any()


def test_variance_and_lag_tau_autocorrelation_over_many_seeds():
    """4000 seeds x 3 axes: x_0 (stationary start) and x after tau (10 steps of tau / 10)."""
    sigma, tau, dt = 1.0, 10.0, 1.0
    nav = _nav(sigma_att=sigma, tau_att=tau)
    seeds = 4000
    start, lagged = np.empty((seeds, 3)), np.empty((seeds, 3))
    knowledge = np.zeros(navigation.KNOWLEDGE_SIZE)
    for seed in range(seeds):
        state = np.array([seed * 7919 + 1], dtype=np.uint64)
        navigation.start(nav, dt, state, knowledge)
        start[seed] = knowledge[0:3]
        for _ in range(int(tau / dt)):
            navigation.propagate(nav, state, knowledge)
        lagged[seed] = knowledge[0:3]
    n = start.size
    # sample variance of n normals: standard error sigma^2 sqrt(2 / n) (1.3 % here); 4 of them
    assert np.var(start) == pytest.approx(sigma**2, abs=4 * sigma**2 * math.sqrt(2 / n))
    assert np.var(lagged) == pytest.approx(sigma**2, abs=4 * sigma**2 * math.sqrt(2 / n))
    rho = np.mean(start * lagged) / sigma**2
    # correlation e^-1 at lag tau; its standard error about (1 - rho^2) / sqrt(n) (0.008)
    assert rho == pytest.approx(math.exp(-1.0), abs=4 * (1 - math.exp(-2.0)) / math.sqrt(n))


def test_sigma_and_tau_come_back_from_a_flown_history():
    """IRASSI's 22 h at 1 Hz with only a Gauss-Markov attitude knowledge error (0.1 arcsec, 10 s);
    the AKE samples (estimated - true, recorded every control step) give sigma and tau back."""
    sigma_arcsec, tau = 0.1, 10.0
    vehicle = load_vehicle(ROOT / "configs/vehicles/irassi.yaml")
    mission = load_mission(ROOT / "configs/missions/irassi-small-angle.yaml")
    mission["navigation"]["attitude_gm_sigma_deg"] = sigma_arcsec / 3600.0
    mission["navigation"]["attitude_gm_tau_s"] = tau
    record = {"index": "AKE", "error": "total", "bound_arcsec": 1.0, "p_c": 0.9973, "interpretation": "ensemble",
              "window": {"modes": ["science"]}}  # fmt: skip
    # and the largest true error over the mission's pointing window: the runs column pointing_max_arcsec
    largest = dict(record, index="APE", window={"from_s": mission["pointing_statistics_from_s"]})
    plan = config_pointing.plan(config_pointing.parse([record, largest], mission), mission)
    result = fly(pack(vehicle, mission), 3, 1 / 600, mode_names(mission), requirements=plan)
    values = result.runs_values()
    assert values["ape_total_ensemble_arcsec"] == values["pointing_max_arcsec"]  # the same samples, two codes
    rec = result.pointing_record
    n = int(rec.counts[0])
    e = rec.samples[0, :n, 0:3] * (180.0 / math.pi * 3600.0)  # arcsec, per body axis
    assert n > 70000 and np.all(np.diff(rec.samples[0, :n, 3]) == 1.0)
    variance = np.mean(e * e)  # the mean is zero
    a = math.exp(-1.0 / tau)
    # AR(1) sample variance of N samples: standard error sigma^2 sqrt(2 (1 + a^2) / ((1 - a^2) N)) (1.1 % here)
    se_variance = sigma_arcsec**2 * math.sqrt(2 * (1 + a * a) / ((1 - a * a) * e.size))
    assert variance == pytest.approx(sigma_arcsec**2, abs=4 * se_variance)
    rho = np.mean(e[1:] * e[:-1]) / variance
    # lag-1 correlation: standard error sqrt((1 - a^2) / N); tau = -dt / ln(rho) moves by |d tau / d rho|
    se_tau = math.sqrt((1 - a * a) / e.size) / (a * math.log(a) ** 2)
    assert -1.0 / math.log(rho) == pytest.approx(tau, abs=4 * se_tau)


def _hex_rows(rows):
    return [{k: (struct.pack("<d", v).hex() if isinstance(v, float) else v) for k, v in r.items()} for r in rows]


def test_irassi_runs_without_gauss_markov_error_keep_their_bits():
    """baselines/irassi-white: 5 runs of the IRASSI campaign as it was before issue 35, flown by
    the code just before issue 35 merged (white estimator noise, one undetected failed wheel in run 3),
    re-flown by issue 37 (core/elementary.py moved every flight's last bits; a pin since).
    Its files keep the names of before issue 34 (``separation.*``, ``theta_t_handover_deg``): the old
    campaign still loads, and its rows are the same bits under the new names (config.renames)."""
    folder = ROOT / "baselines/irassi-white"
    campaign = load_campaign(folder / "campaign.yaml")
    rows, _ = fly_chunk(campaign, range(campaign["runs"]))
    stored = json.loads((folder / "rows.json").read_text())
    assert "theta_t_handover_deg" in stored[0] and "p.separation.attitude_error_deg.x" in stored[0]
    assert _hex_rows(rows) == [{renames.new_column(k): v for k, v in row.items()} for row in stored]


def test_the_measurement_adds_the_processes_then_advances_them():
    """Measured attitude = truth (x) rot(x_att), measured rate = truth + x_rate, with the processes'
    values before the call; afterwards they have taken one exact step."""
    nav = _nav(sigma_att=3e-6, tau_att=20.0, sigma_rate=2e-7, tau_rate=5.0)
    state = np.array([7], dtype=np.uint64)
    knowledge = np.zeros(navigation.KNOWLEDGE_SIZE)
    navigation.start(nav, 0.5, state, knowledge)
    before = knowledge.copy()
    x = np.zeros(7)
    x[3] = 1.0
    x[4:7] = [1e-3, -2e-3, 5e-4]
    q_out, rate_out = np.empty(4), np.empty(3)
    navigation.measure(x, nav, 0.0, state, knowledge, q_out, rate_out, np.empty(4))
    from scipy.spatial.transform import Rotation

    # rotation vector of ~5e-6 rad through a quaternion: 1e-17 rad
    np.testing.assert_allclose(Rotation.from_quat(q_out).as_rotvec(), before[0:3], rtol=0, atol=1e-17)
    np.testing.assert_array_equal(rate_out, x[4:7] + before[3:6])
    a_att, a_rate = math.exp(-0.5 / 20.0), math.exp(-0.5 / 5.0)
    assert knowledge[navigation.K_ATT_DECAY] == a_att and knowledge[navigation.K_RATE_DECAY] == a_rate
    assert not np.array_equal(knowledge[0:6], before[0:6])
