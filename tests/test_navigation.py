"""navigation.measure (reference-model sec. 5; 000 sec. 2.2, 6.2) against its twin and closed forms.

The attitude bias b decays as b e^(-t/tau) over the time spent in calibrating modes (the sun scan)
and keeps its decayed value afterwards; white noise on attitude and rate; a constant rate bias.
"""

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from naive import SplitMix64, navigation_measure

from refexmc.config.load import load_mission, load_vehicle
from refexmc.config.pack import mode_names, pack
from refexmc.core import dynamics, layout, navigation
from refexmc.simulate import fly

ROOT = Path(__file__).resolve().parents[1]

# Both sides build the measured quaternion from the same float64 inputs through different
# formulas (Hamilton product vs scipy's rotation composition): they agree to a few ulp of 1.
QUATERNION_TOL = 1e-14
ANGLE_TOL = 1e-12  # rad: a rotation vector of ~1e-2 rad recovered through scipy, good to ~1e-17 rad


def nav_table(attitude_bias=(0, 0, 0), attitude_noise=0.0, rate_bias=(0, 0, 0), rate_noise=0.0, calibration_time=0.0):
    nav = np.zeros(layout.NAV.size)
    nav[layout.N_ATT_BIAS : layout.N_ATT_BIAS + 3] = attitude_bias
    nav[layout.N_ATT_NOISE] = attitude_noise
    nav[layout.N_RATE_BIAS : layout.N_RATE_BIAS + 3] = rate_bias
    nav[layout.N_RATE_NOISE] = rate_noise
    nav[layout.N_CALIBRATION_TIME] = calibration_time
    return nav


def state(q=(0.0, 0.0, 0.0, 1.0), rate=(0.0, 0.0, 0.0)):
    x = np.zeros(dynamics.STATE_SIZE)
    x[0:4] = q
    x[4:7] = rate
    return x


def measure(x, nav, time_calibrating, seed=12345):
    rng_state = np.array([seed], dtype=np.uint64)
    q_out, rate_out, work4 = np.empty(4), np.empty(3), np.empty(4)
    navigation.measure(x, nav, time_calibrating, rng_state, np.zeros(navigation.KNOWLEDGE_SIZE), q_out, rate_out, work4)
    return q_out, rate_out, int(rng_state[0])


def error_vector(q_truth, q_meas):
    """Body-axes rotation vector from truth to measurement: 2 atan2(|v|, w) v / |v| of conj(q) (x) q_m."""
    from scipy.spatial.transform import Rotation

    return (Rotation.from_quat(q_truth).inv() * Rotation.from_quat(q_meas)).as_rotvec()


BIAS = np.radians([0.5, -0.3, 0.2])  # rad, well inside the small-angle range the model is meant for
TAU = 40.0  # s


@pytest.mark.parametrize("t_cal", [0.0, 0.5, 10.0, 40.0, 120.0])
def test_attitude_bias_decays_as_exp_minus_t_over_tau_while_calibrating(t_cal):
    """Closed form: the attitude error is b e^(-t_cal / tau) exactly (no noise): t = tau leaves b / e."""
    q_truth = np.array([0.1, -0.2, 0.3, 0.9]) / np.linalg.norm([0.1, -0.2, 0.3, 0.9])
    q_meas, _, _ = measure(state(q_truth), nav_table(attitude_bias=BIAS, calibration_time=TAU), t_cal)
    expected = BIAS * math.exp(-t_cal / TAU)
    assert np.allclose(error_vector(q_truth, q_meas), expected, rtol=0, atol=ANGLE_TOL), (t_cal, expected)


def test_the_bias_stays_where_calibration_left_it():
    """After the calibrating modes ``time_calibrating`` stops growing (flight.py adds dt only in
    modes flagged navigation_calibration): the same time gives the same measurement at any later
    step, and without a time constant the bias never decays."""
    nav = nav_table(attitude_bias=BIAS, calibration_time=TAU)
    x = state(rate=(0.01, 0.02, -0.03))
    first, _, _ = measure(x, nav, 30.0)
    again, _, _ = measure(x, nav, 30.0)
    assert np.array_equal(first, again)
    never, _, _ = measure(x, nav_table(attitude_bias=BIAS, calibration_time=0.0), 500.0)
    assert np.allclose(error_vector(x[0:4], never), BIAS, atol=ANGLE_TOL)


@pytest.mark.parametrize("axis", [0, 1, 2])
def test_a_bias_about_one_axis_alone_is_measured(axis):
    """A bias on one axis (the others exactly 0) still turns the measured attitude: the kernel's
    no-error shortcut must need all three components to be zero."""
    bias = np.zeros(3)
    bias[axis] = 0.01
    q_truth = np.array([0.2, 0.1, -0.3, 0.9]) / np.linalg.norm([0.2, 0.1, -0.3, 0.9])
    q_meas, _, _ = measure(state(q_truth), nav_table(attitude_bias=bias), 0.0)
    assert np.allclose(error_vector(q_truth, q_meas), bias, rtol=0, atol=ANGLE_TOL)


def test_rate_bias_is_added_to_the_true_rate():
    rate = np.array([0.1, -0.05, 0.02])
    bias = np.array([1e-3, -2e-3, 5e-4])
    q_meas, rate_meas, rng_after = measure(state(rate=rate), nav_table(rate_bias=bias), 0.0)
    assert np.array_equal(rate_meas, rate + bias)
    assert np.array_equal(q_meas, [0, 0, 0, 1])  # no attitude error: the truth
    assert rng_after == 12345  # no noise configured: no draws


def test_noise_has_the_configured_sigma():
    """1 sigma per axis: 4,000 draws per axis give the sample sigma within 5 % (its standard error
    is sigma / sqrt(2 n) = 1.1 %) and a mean within 5 standard errors of 0."""
    sigma_att, sigma_rate, n = 1e-3, 2e-4, 4000
    nav = nav_table(attitude_noise=sigma_att, rate_noise=sigma_rate)
    rng_state = np.array([7], dtype=np.uint64)
    q_out, rate_out, work4 = np.empty(4), np.empty(3), np.empty(4)
    att, rates = np.empty((n, 3)), np.empty((n, 3))
    x = state()
    for k in range(n):
        navigation.measure(x, nav, 0.0, rng_state, np.zeros(navigation.KNOWLEDGE_SIZE), q_out, rate_out, work4)
        att[k] = error_vector(x[0:4], q_out)
        rates[k] = rate_out
    for samples, sigma in ((att, sigma_att), (rates, sigma_rate)):
        assert np.allclose(samples.std(axis=0), sigma, rtol=0.05)
        assert np.all(np.abs(samples.mean(axis=0)) < 5 * sigma / math.sqrt(n))


finite = st.floats(-1.0, 1.0)
small_angle = st.floats(-0.02, 0.02)


@settings(deadline=None, max_examples=150)
@given(
    q=st.tuples(finite, finite, finite, finite).filter(lambda q: np.linalg.norm(q) > 0.1),
    rate=st.tuples(finite, finite, finite),
    bias=st.tuples(small_angle, small_angle, small_angle),
    attitude_noise=st.sampled_from([0.0, 1e-4, 3e-3]),
    rate_bias=st.tuples(small_angle, small_angle, small_angle),
    rate_noise=st.sampled_from([0.0, 1e-5, 1e-3]),
    calibration_time=st.sampled_from([0.0, 0.5, 5.0, 60.0]),  # 0.5: a time constant under 1 s decays too
    time_calibrating=st.floats(0.0, 300.0),
    seed=st.integers(0, 2**64 - 1),
)
def test_measure_matches_its_twin(
    q, rate, bias, attitude_noise, rate_bias, rate_noise, calibration_time, time_calibrating, seed
):
    q = np.array(q) / np.linalg.norm(q)
    nav = nav_table(bias, attitude_noise, rate_bias, rate_noise, calibration_time)
    q_meas, rate_meas, rng_after = measure(state(q, rate), nav, time_calibrating, seed)
    noise = SplitMix64(seed)
    q_twin, rate_twin = navigation_measure(
        q, rate, bias, attitude_noise, rate_bias, rate_noise, calibration_time, time_calibrating, noise
    )
    sign = 1.0 if np.dot(q_meas, q_twin) >= 0 else -1.0
    assert np.allclose(sign * q_meas, q_twin, rtol=0, atol=QUATERNION_TOL), (q_meas, q_twin)
    assert np.allclose(rate_meas, rate_twin, rtol=1e-15, atol=1e-15)
    assert rng_after == noise.state  # the same number of draws, in the same order


def test_in_flight_the_bias_decays_only_while_a_calibrating_mode_runs(tmp_path):
    """generic-slew with an 8 deg attitude bias about z, tau = 5 s, and only the detumble flagged
    navigation_calibration: the flight software then steers the *measured* attitude onto the
    target, so the true error at the end is the bias left when the detumble ended, b e^(-T/tau)
    with T the detumble's duration (frozen through the slew and the 60 s hold, where it would have
    decayed to ~0). The hold keeps the measured attitude within the angle deadband, at most
    0.531 deg on any axis for generic-12 at low thrust (`refexmc inspect`): the tolerance."""
    text = (ROOT / "configs/missions/generic-slew.yaml").read_text()
    for old, new in (
        ("    kind: rate_damping\n", "    kind: rate_damping\n    navigation_calibration: true\n"),
        ("attitude_bias_deg: [0.0, 0.0, 0.0]", "attitude_bias_deg: [0.0, 0.0, 8.0]"),
        ("ssm_calibration_time_s: 0.0", "ssm_calibration_time_s: 5.0"),
    ):
        assert old in text
        text = text.replace(old, new)
    (tmp_path / "mission.yaml").write_text(text)
    mission = load_mission(tmp_path / "mission.yaml")
    vehicle = load_vehicle(ROOT / "configs/vehicles/generic-12.yaml")
    result = fly(pack(vehicle, mission), history_rate_hz=2.0, mode_names=mode_names(mission))
    detumble_s = result.value("t_mode_s")[0]
    left = 8.0 * math.exp(-detumble_s / 5.0)  # ~1.93 deg; 2 tau would leave ~3.9, no freeze ~0
    assert result.value("attitude_error_end_deg") == pytest.approx(left, abs=0.531)
