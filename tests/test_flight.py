"""Whole-flight acceptance tests for the nominal ReFEx case (000 sec. 6.1, 6.3).

The reference flight uses configs/vehicles/refex.yaml and configs/missions/refex-exo.yaml with
a full-rate (40 Hz) history so every control step is visible.
"""

from pathlib import Path

import numpy as np
import pytest

from refexmc.config.load import load_mission, load_vehicle
from refexmc.config.pack import mode_names, pack
from refexmc.core import layout as L
from refexmc.simulate import fly

ROOT = Path(__file__).resolve().parents[1]
HANDOVER_LIMIT_DEG = 5.0  # reference-model sec. 4: success needs < 5 deg at hand-over
MODES = ("NCM", "RDM1", "SAM", "SSM", "RDM2", "EAM", "GEEM")  # 000 sec. 2.2, in flight order
NCM, RDM1, SAM, SSM, RDM2, EAM, GEEM = range(len(MODES))


@pytest.fixture(scope="module")
def vehicle():
    return load_vehicle(ROOT / "configs/vehicles/refex.yaml")


@pytest.fixture(scope="module")
def mission():
    mission = load_mission(ROOT / "configs/missions/refex-exo.yaml")
    assert tuple(mode_names(mission)) == MODES
    return mission


def mode_config(mission, name):
    return next(mode for mode in mission["modes"] if mode["name"] == name)


@pytest.fixture(scope="module")
def nominal(vehicle, mission):
    return fly(pack(vehicle, mission), history_rate_hz=40.0)


def test_nominal_flight_succeeds_through_every_mode(nominal):
    assert nominal.success, nominal.failure_reason
    assert nominal.failure_reason is None
    # NCM..GEEM each left by its own exit condition: 7 transitions, the last one the hand-over
    assert nominal.value("modes_completed") == len(MODES)
    modes = nominal.column("mode")
    visited = [int(m) for m in modes[np.r_[True, np.diff(modes) != 0]]]
    assert visited == list(range(len(MODES))), "modes must come in order NCM, RDM1, SAM, SSM, RDM2, EAM, GEEM"
    assert np.all(nominal.value("t_mode_s") > 0.0)


def test_nominal_mode_timing_matches_the_trajectory(nominal, mission):
    """Mode exits land where the trajectory puts them (reference-model sec. 5 scipy check)."""
    t_mode = nominal.value("t_mode_s")
    ssm_end = t_mode[:RDM2].sum()
    assert t_mode[NCM] == pytest.approx(mode_config(mission, "NCM")["exit"][0]["time_in_mode_s"], abs=0.025)
    assert t_mode[RDM2] == pytest.approx(mode_config(mission, "RDM2")["exit"][0]["time_in_mode_s"], abs=0.025)
    assert ssm_end == pytest.approx(168.0, abs=2.0)  # 110 km descending at t ~ 168 s
    eam_end = t_mode[:GEEM].sum()
    assert eam_end == pytest.approx(215.0, abs=2.0)  # 70 km at t ~ 215 s
    assert nominal.value("t_end_s") == pytest.approx(230.0, abs=2.0)  # q = 1 kPa at ~53 km, t ~ 230 s
    assert nominal.value("qbar_end_pa") >= mode_config(mission, "GEEM")["exit"][0]["dynamic_pressure_above_pa"]


def test_nominal_handover_error_and_propellant(nominal, vehicle):
    assert nominal.value("attitude_error_end_deg") < HANDOVER_LIMIT_DEG
    # 000 Fig. 9: roughly half the propellant left; the config's propellant mass is tuned for it
    assert 0.45 <= nominal.value("fuel_remaining") <= 0.55
    used = nominal.value("fuel_used_kg")
    assert used == pytest.approx(vehicle["rcs"]["propellant_kg"] * (1.0 - nominal.value("fuel_remaining")))


def _propellant_per_mode(result):
    """Fraction of the tank used in each mode, from the history (a mode's first sample to the next
    mode's first sample)."""
    fuel = result.column("fuel_remaining")
    modes = result.column("mode")
    starts = [int(np.flatnonzero(modes == m)[0]) for m in range(len(MODES))] + [len(fuel) - 1]
    return np.array([fuel[a] - fuel[b] for a, b in zip(starts[:-1], starts[1:], strict=True)])


def test_nominal_sun_scanning_uses_less_than_the_manoeuvres(nominal):
    """000 sec. 6.1: sun scanning uses less propellant than rate damping, sun acquisition and
    entry attitude acquisition (the short GEEM: see the expected failure below)."""
    used = _propellant_per_mode(nominal)
    assert used[SSM] < min(used[RDM1], used[SAM], used[EAM])


@pytest.mark.xfail(
    strict=True,
    reason="000 sec. 6.1 / Fig. 9: most propellant in EAM and GEEM, the least in SSM (RDM2 aside). With the "
    "45 ms valve fall, no nominal aerodynamic mistrim and GEEM starting on its reference, this model spends "
    "~36 % in EAM + GEEM, most in SAM, and less in GEEM than in SSM (docs/model.md, Findings)",
)
def test_nominal_propellant_goes_mostly_to_eam_and_geem(nominal):
    """000 sec. 6.1: most propellant is used in EAM and GEEM (high thrust), the least in SSM."""
    used = _propellant_per_mode(nominal)
    assert used[EAM] + used[GEEM] > 0.5 * used.sum()
    assert used[SSM] < used[GEEM]


def test_geem_starts_without_a_step_in_its_reference(nominal):
    """EAM aims at the velocity predicted at its exit altitude (reference-model sec. 4), so GEEM's
    reference, to the current velocity, starts within 2 deg of the EAM target. The step is at most
    the sum of the true attitude's angles to both (the last EAM and first GEEM samples, 40 Hz)."""
    modes = nominal.column("mode")
    theta = nominal.column("theta_t_deg")
    first_geem = int(np.flatnonzero(modes == GEEM)[0])
    assert modes[first_geem - 1] == EAM
    assert theta[first_geem - 1] + theta[first_geem] < 2.0


def _sam_transition(nominal):
    t = nominal.column("t_s")
    modes = nominal.column("mode")
    sam = modes == SAM
    t_start = t[sam][0]
    t1 = nominal.value("t1_mode_s")[SAM]
    assert t1 > 0.0
    return sam & (t <= t_start + t1), t_start + t1


def test_sam_has_no_overshoot(nominal):
    """zeta = 1: the total angle error falls without growing again until the limit cycle (000 Fig. 7a).

    The limit cycle starts when the guidance transition ends (t > t1): from then on the
    reference is fixed and only deadband corrections remain.
    """
    during, _ = _sam_transition(nominal)
    theta = nominal.column("theta_t_deg")[during]
    assert theta[0] > 10.0  # a real reorientation
    growth = np.diff(theta)
    # 1e-9 deg: round-off of the angle computation, far below any physical growth
    assert growth.max() <= 1e-9, f"theta_t grew by {growth.max():.3g} deg during the SAM transition"
    assert theta[-1] < 0.05 * theta[0]  # the reorientation is essentially done at t1


def test_sam_pitch_and_yaw_pulses_change_sign_at_most_once(nominal):
    """000 Fig. 8: pitch and yaw pulse commands show one sign change before the limit cycle."""
    during, _ = _sam_transition(nominal)
    pulses = nominal.column("pulse_command")[during]
    for axis, name in ((1, "pitch"), (2, "yaw")):
        fired = pulses[:, axis][pulses[:, axis] != 0.0]
        changes = int(np.count_nonzero(np.diff(np.sign(fired))))
        assert len(fired) > 0, f"{name} never fired during the SAM transition"
        assert changes <= 1, f"{name} pulse commands changed sign {changes} times before the limit cycle"


def test_failed_thrusters_1_and_8_are_compensated(vehicle, mission, nominal):
    """000 sec. 6.3 / Table 4: [1, 8] is compensable; the coupled roll/pitch torques cost
    propellant in the first rate damping, where the paper locates the extra consumption."""
    failed = fly(pack(vehicle, mission, (1, 8)), history_rate_hz=40.0)
    assert failed.success, failed.failure_reason
    assert failed.value("attitude_error_end_deg") < HANDOVER_LIMIT_DEG
    assert failed.pulse_counts[0] > 0 and failed.pulse_counts[7] > 0  # commanded, never opened

    def rdm1_use(result):
        fuel = result.column("fuel_remaining")
        rdm1 = np.flatnonzero(result.column("mode") == RDM1)
        return fuel[rdm1[0]] - fuel[rdm1[-1] + 1]

    assert rdm1_use(failed) > rdm1_use(nominal)
    # slower rate damping with less authority (000 sec. 6.3)
    assert failed.value("t_mode_s")[RDM1] >= nominal.value("t_mode_s")[RDM1]


def test_failed_thrusters_1_and_8_cost_propellant(vehicle, mission, nominal):
    """000 sec. 6.3: "the overall fuel consumption should be a bit higher for the failure case".

    The nominal case, and 20 cases with the separation rates perturbed by up to 0.05 deg/s per
    axis (uniform, seeded): [1, 8] must use more in the nominal case and in at least 15 of 20."""
    failed = fly(pack(vehicle, mission, (1, 8)))
    assert failed.success
    assert failed.value("fuel_used_kg") > nominal.value("fuel_used_kg")
    rng = np.random.default_rng(0)
    more = 0
    for _ in range(20):
        rates = np.array(mission["initial_state"]["rates_deg_s"]) + rng.uniform(-0.05, 0.05, 3)
        perturbed = dict(mission, initial_state=dict(mission["initial_state"], rates_deg_s=rates.tolist()))
        used = [fly(pack(vehicle, perturbed, f)).value("fuel_used_kg") for f in ((), (1, 8))]
        more += used[1] > used[0]
    assert more >= 15, f"[1, 8] used more propellant in only {more} of 20 perturbed cases"


def test_failed_yaw_thruster_5_loses_the_flight(vehicle, mission):
    """Thrusters 5/6 are the only yaw thrusters: losing 5 cannot be compensated (000 sec. 5)."""
    result = fly(pack(vehicle, mission, (5,)), mode_names=MODES)
    assert not result.success
    assert result.failure_reason == "rdm1_timeout"  # positive yaw rate cannot be damped
    assert result.pulse_counts[4] > 0


def test_failed_thrusters_use_no_propellant(vehicle, mission):
    """With every thruster failed nothing is consumed, and the flight fails."""
    result = fly(pack(vehicle, mission, tuple(range(1, 9))))
    assert result.value("fuel_used_kg") == 0.0
    assert not result.success


def test_running_out_of_propellant_fails_the_run(vehicle, mission):
    starved = dict(vehicle, rcs=dict(vehicle["rcs"], propellant_kg=0.05))
    result = fly(pack(starved, mission))
    assert not result.success
    assert result.failure_reason == "propellant_exhausted"
    assert result.value("fuel_remaining") == 0.0
    assert result.value("t_end_s") < 100.0


def test_flight_is_deterministic(vehicle, mission):
    """Same inputs and seed: bit-identical summary and history, including navigation noise."""
    noisy = dict(mission, navigation=dict(mission["navigation"], attitude_noise_deg=0.02, rate_noise_deg_s=0.01))
    a = fly(pack(vehicle, noisy), nav_seed=7)
    b = fly(pack(vehicle, noisy), nav_seed=7)
    c = fly(pack(vehicle, noisy), nav_seed=8)
    assert np.array_equal(a.summary, b.summary, equal_nan=True)
    assert np.array_equal(a.history, b.history, equal_nan=True)
    assert not np.array_equal(a.history, c.history, equal_nan=True)


def test_dispersible_inputs_reach_the_model_without_recompiling(vehicle, mission):
    """Every quantity a campaign disperses is an array value: changing it changes the flight
    and compiles nothing new (one signature of the run kernel)."""
    from refexmc.core import flight

    base_inputs = pack(vehicle, mission)
    base = fly(base_inputs)

    def perturbed(edit):
        inputs = pack(vehicle, mission)
        edit(inputs)
        return fly(inputs)

    edits = {
        "inertia": lambda p: p.vehicle.__setitem__(L.V_INERTIA + 4, 260.0),
        "com_offset": lambda p: p.vehicle.__setitem__(L.V_COM_OFFSET + 2, 0.01),
        "isp": lambda p: p.vehicle.__setitem__(L.V_ISP, 60.0),
        "derating": lambda p: p.vehicle.__setitem__(L.V_DERATING + 1, 0.8),
        "mistrim": lambda p: p.vehicle.__setitem__(L.V_MISTRIM + 1, 2e-3),
        "thrust_scale": lambda p: p.thrusters.__setitem__((6, L.T_SCALE), 0.9),
        "off_delay": lambda p: p.thrusters.__setitem__((2, L.time_constant_column(0, L.OFF_DELAY)), 0.06),
        "separation_rates": lambda p: p.mission.__setitem__(L.M_SEP_RATES, 0.06),
        "separation_attitude": lambda p: p.mission.__setitem__(L.M_SEP_ATTITUDE + 2, 0.1),
        "rate_bias": lambda p: p.nav.__setitem__(L.N_RATE_BIAS, 1e-4),
    }
    for name, edit in edits.items():
        result = perturbed(edit)
        assert not np.array_equal(result.history, base.history, equal_nan=True), f"{name} had no effect"
    run_flight = flight.kernel(*flight.family(base_inputs))
    if hasattr(run_flight, "signatures"):  # absent when REFEXMC_DISABLE_JIT=1
        assert len(run_flight.signatures) == 1


def test_trajectory_in_the_flight_matches_solve_ivp(nominal, mission, vehicle):
    """The altitude the mode logic sees (RK4 nodes + Hermite interpolation) vs scipy DOP853.

    1 m: the interpolation error is O(span^4) (sub-millimetre at 0.2 s); 1 m is still 25x
    smaller than the 25 m the vehicle descends in one control period near hand-over.
    """
    from scipy.integrate import solve_ivp

    earth = mission["earth"]
    sep = mission["initial_state"]
    rows = mission["atmosphere"]
    base = np.array([r["base_altitude_km"] * 1e3 for r in rows])
    rho0 = np.array([r["density_kg_m3"] for r in rows])
    scale = np.array([r["scale_height_km"] * 1e3 for r in rows])
    k_drag = vehicle["aerodynamics"]["drag_area_m2"] / vehicle["mass_kg"]
    centre = earth["radius_m"] + sep["altitude_m"]

    def rhs(_, y):
        rx, rz = y[0], y[1] - centre
        r = np.hypot(rx, rz)
        h = r - earth["radius_m"]
        i = max(0, np.searchsorted(base, h, side="right") - 1)
        rho = rho0[i] * np.exp(-(h - base[i]) / scale[i])
        speed = np.hypot(y[2], y[3])
        g = -earth["mu_m3_s2"] / r**3
        return [y[2], y[3], g * rx - 0.5 * rho * speed * k_drag * y[2], g * rz - 0.5 * rho * speed * k_drag * y[3]]

    gamma = np.radians(sep["flight_path_angle_deg"])
    y0 = [0.0, 0.0, sep["speed_m_s"] * np.cos(gamma), -sep["speed_m_s"] * np.sin(gamma)]
    t = nominal.column("t_s")
    ref = solve_ivp(rhs, (0.0, t[-1]), y0, method="DOP853", rtol=1e-12, atol=1e-9, t_eval=t)
    altitude_ref = np.hypot(ref.y[0], ref.y[1] - centre) - earth["radius_m"]
    assert np.max(np.abs(nominal.column("altitude_m") - altitude_ref)) < 1.0
    assert altitude_ref.max() == pytest.approx(131e3, abs=1e3)  # apogee ~131 km (reference-model sec. 5)
