"""Validated config dicts -> the flat arrays of ``refexmc.core.layout``.

A dispersible parameter's nominal value is packed from its row of ``config.parameters`` (the
field it lands in, its unit factor, its schema default): ``parameters.pack_nominal``, the same
write ``config.dispersions.apply`` makes for a drawn value. What is packed here by name is the rest.
"""

import functools
import json
import math

import numpy as np

from refexmc import smallmatrix
from refexmc.config import deorbit, derived, parameters, schema
from refexmc.config import feed as config_feed
from refexmc.core import layout as L
from refexmc.core import modes as core_modes
from refexmc.core.inputs import RunInputs

__all__ = ["RunInputs", "pack", "mode_names"]


def _put(array, fields, name, value):
    offset, size = fields.slices[name]
    value = np.asarray(value, dtype=float).ravel()
    if value.size != size:
        raise ValueError(f"{name}: expected {size} values, got {value.size}")
    array[offset : offset + size] = value


NO_AERODYNAMICS = {"reference_area_m2": 0.0, "reference_length_m": 0.0}  # its dispersible keys: 0 (parameters)
TRAJECTORY_MODELS = {
    "none": L.TRAJECTORY_NONE,
    "planar_drag": L.TRAJECTORY_PLANAR_DRAG,
    "orbit": L.TRAJECTORY_ORBIT,
    "local": L.TRAJECTORY_LOCAL,
}
TRANSLATION_LAWS = {
    "time_optimal": L.TRANSLATION_TIME_OPTIMAL,
    "bang_bang": L.TRANSLATION_BANG_BANG,
    "pd_pwm": L.TRANSLATION_PD_PWM,
}
NO_ENGINE = {  # its thrust: 0 (parameters)
    "isp_s": 1.0,
    "propellant_kg": 0.0,
    "direction": [1.0, 0.0, 0.0],
    "position_m": [0.0, 0.0, 0.0],
    "misalignment_deg": [0.0, 0.0, 0.0],
}
NO_BURN_GUIDANCE = {"rate_hz": 1.0, "position_gain_s2": 0.0, "velocity_gain_s": 0.0}
NO_RCS = {"derating": [1.0], "isp_s": 1.0, "propellant_kg": 0.0}  # a vehicle with reaction wheels only
NO_SMC = {"slope_s": [0.0] * 3, "gain_rad_s2": [0.0] * 3, "boundary_layer_rad_s": [0.0] * 3}
NO_PWPF = {"tau_min_fraction": 0.0, "t_on_ms": 0.0, "t_off_ms": 0.0, "correction_ms": 0.0}
CONTROLLERS = {
    "pd_feedback_linearisation": L.CONTROLLER_PD_FEEDBACK_LINEARISATION,
    "pd": L.CONTROLLER_PD,
    "smc": L.CONTROLLER_SMC,
}
GUIDANCE_LAWS = {  # flight_software.burn_guidance.law (schema enum) -> core.deorbit.steer's id
    "pd": L.GUIDANCE_LAW_PD,
    "open_loop_retrograde": L.GUIDANCE_LAW_OPEN_LOOP_RETROGRADE,
    "open_loop_planned": L.GUIDANCE_LAW_OPEN_LOOP_PLANNED,
}
ACTUATIONS = {"pwpf_table": L.ACTUATION_PWPF_TABLE, "lp_pwm": L.ACTUATION_LP_PWM, "wheels": L.ACTUATION_WHEELS}


# a level's row in the levels table is its place in thrust_n; a vehicle with actuation wheels has
# the one level "wheels"
level_names = derived.level_names


def pack_levels(vehicle, excluded_wheels=()):
    """Level table (layout.LEVEL rows): the truth thrust and the flight software's design. The
    ``wheels`` level of actuation wheels has no thrust, the torque and acceleration the wheels'
    distribution commands per body axis (without the ``excluded_wheels``), and given gains or none."""
    names = level_names(vehicle)
    out = np.zeros((len(names), L.LEVEL_SIZE))
    for row, level in zip(out, names, strict=True):
        kp, kd = derived.gains_flown(vehicle, level)
        thrust = 0.0 if derived.flies_wheels(vehicle) else vehicle["rcs"]["thrust_n"][level]
        _put(row, L.LEVEL, "thrust_n", thrust)
        _put(row, L.LEVEL, "thrust_design_n", thrust)
        _put(row, L.LEVEL, "kp", kp)
        _put(row, L.LEVEL, "kd", kd)
        _put(row, L.LEVEL, "torque_max_n_m", derived.level_torque_max(vehicle, level, excluded_wheels))
        _put(row, L.LEVEL, "accel_max_rad_s2", derived.level_accel_max(vehicle, level, excluded_wheels))
        _put(row, L.LEVEL, "regulator_pressure_pa", config_feed.set_pressure(vehicle, level))
    return out


def pack_wheels(vehicle, failed=()):
    """Wheel table (layout.WHEEL), one row per wheel (none without wheels); ``failed`` are 1-based ids."""
    if "wheels" not in vehicle:
        return np.zeros((0, L.WHEEL_SIZE))
    wheels = vehicle["wheels"]
    axes = derived.wheel_axes(vehicle).T
    out = np.zeros((len(wheels["units"]), L.WHEEL_SIZE))
    for i, row in enumerate(out):
        _put(row, L.WHEEL, "axis", axes[i])
        _put(row, L.WHEEL, "spin_inertia_kg_m2", wheels["spin_inertia_kg_m2"])
        _put(row, L.WHEEL, "torque_max_n_m", wheels["torque_max_n_m"])
        _put(row, L.WHEEL, "momentum_max_n_m_s", wheels["momentum_max_n_m_s"])
        _put(row, L.WHEEL, "coulomb_width_rad_s", wheels["friction"]["coulomb_width_rpm"] * math.pi / 30.0)
        _put(row, L.WHEEL, "coulomb_friction_design_n_m", wheels["friction"]["coulomb_n_m"])  # never dispersed
        _put(row, L.WHEEL, "viscous_friction_design_n_m_s", wheels["friction"]["viscous_n_m_s"])
        _put(row, L.WHEEL, "failed", 1.0 if (i + 1) in set(failed) else 0.0)
    parameters.pack_nominal(out, "wheels", vehicle)  # friction, initial momentum
    managed = wheels.get("null_space_management")
    if managed is not None:  # else the columns stay 0: no management
        out[:, L.W_NULL_SPACE_RATE] = 1.0 / managed["time_constant_s"]
        out[:, L.W_NULL_SPACE_BIAS] = managed.get("bias_n_m_s", 0.0)
        out[:, L.W_NULL_SPACE_DEADBAND] = managed.get("deadband_n_m_s", 0.0)
        out[:, L.W_NULL_SPACE_TORQUE_MAX] = managed.get("torque_max_n_m", wheels["torque_max_n_m"])
        out[:, L.W_NULL_SPACE_GIVE_UP] = managed.get("give_up_beyond_n_m_s", math.inf)
    return out


def pack_wheel_distribution(vehicle, excluded=()):
    """The flight software's distribution matrix (wheels x 3, 001 sec. 9.1) without the ``excluded``
    wheels (1-based ids: failures it knows of, their rows zero); no rows without wheels."""
    if "wheels" not in vehicle:
        return np.zeros((0, 3))
    return derived.wheel_distribution(vehicle, excluded)


def pack_vehicle(vehicle):
    """Truth vehicle array (layout.VEHICLE)."""
    out = np.zeros(L.VEHICLE_SIZE)
    rcs = vehicle.get("rcs", NO_RCS)
    aero = vehicle.get("aerodynamics", NO_AERODYNAMICS)
    derating = list(rcs["derating"])
    derating += [derating[-1]] * (L.DERATING_MAX_VALVES - len(derating))
    # mass, CoM offset, mistrim, drag area, engine thrust, feed tank (zero where the vehicle has none)
    parameters.pack_nominal(out, "vehicle", vehicle)
    _put(out, L.VEHICLE, "inertia_kg_m2", vehicle["inertia_kg_m2"])
    _put(out, L.VEHICLE, "derating", derating)
    feed = rcs.get("feed", {"model": "constant"})
    if feed.get("model", "constant") == "constant":
        _put(out, L.VEHICLE, "isp_s", rcs["isp_s"])
        _put(out, L.VEHICLE, "propellant_kg", rcs["propellant_kg"])
    else:
        _pack_feed(out, feed)
    _put(out, L.VEHICLE, "aero_area_m2", aero["reference_area_m2"])
    _put(out, L.VEHICLE, "aero_length_m", aero["reference_length_m"])
    engine = vehicle.get("main_engine", NO_ENGINE)
    _put(out, L.VEHICLE, "engine_isp_s", engine["isp_s"])
    _put(out, L.VEHICLE, "engine_propellant_kg", engine["propellant_kg"])
    _put(out, L.VEHICLE, "engine_direction", derived.engine_direction(engine, engine["misalignment_deg"]))
    _put(out, L.VEHICLE, "engine_position_m", engine["position_m"])
    return out


def _pack_feed(out, feed):
    """The tank and nozzle of a blow-down or regulated feed (core.feed); isp_s and propellant_kg
    from them (002 eq. 1, 15)."""
    design = config_feed.design(feed)
    _put(out, L.VEHICLE, "isp_s", design["specific_impulse_s"])
    _put(out, L.VEHICLE, "propellant_kg", design["gas_kg"])
    _put(out, L.VEHICLE, "feed_model_id", config_feed.MODELS[feed["model"]])
    for key in schema.FEED_TANK_KEYS:
        param = parameters.PARAMETERS.get(f"rcs.feed.{key}")
        if param is None or param.special:  # else packed with the parameters (pack_nominal)
            _put(out, L.VEHICLE, "feed_" + key, feed[key])
    _put(out, L.VEHICLE, "feed_thrust_coefficient", design["thrust_coefficient"])
    _put(out, L.VEHICLE, "feed_flow_factor", design["flow_factor"])


def pack_thrusters(vehicle, failed=(), known=()):
    """Thruster table (layout.THRUSTER, then the time constants per level), one row per thruster;
    ``failed`` are 1-based ids, ``known`` those of them the flight software knows (detected); no
    rows without an rcs. The time constants are those of the rcs levels (with actuation wheels the
    thrusters are carried, not fired)."""
    if "rcs" not in vehicle:
        return np.zeros((0, L.thruster_size(len(level_names(vehicle)))))
    rcs = vehicle["rcs"]
    n = len(rcs["thrusters"])
    levels = derived.rcs_level_names(vehicle)
    out = np.zeros((n, L.thruster_size(len(levels))))
    directions = derived.unit_directions(vehicle)
    for i, thruster in enumerate(rcs["thrusters"]):
        row = out[i]
        _put(row, L.THRUSTER, "position_m", thruster["position_m"])
        _put(row, L.THRUSTER, "direction", directions[i])
        for k, level in enumerate(levels):
            tc = rcs["valve_time_constants_ms"][level]
            for which, name in enumerate(L.TIME_CONSTANT_NAMES):
                row[L.time_constant_column(k, which)] = tc[name] / 1e3
        _put(row, L.THRUSTER, "failed", 1.0 if (i + 1) in set(failed) else 0.0)
        _put(row, L.THRUSTER, "failure_known", 1.0 if (i + 1) in set(failed) & set(known) else 0.0)
    parameters.pack_nominal(out, "thrusters", vehicle)  # the thrust scales, 1
    return out


def pack_allocation(vehicle, known=()):
    """The allocation table the flight software flies (``derived.allocation_table``, 000 Table 3)
    without the thrusters it knows to have failed (1-based ``known`` ids, their column zero): a
    row that needs one opens the others of its set. The table is not re-planned (000 describes no
    reconfiguration), so a known failure only stops the commands to a valve that never opens."""
    table = derived.allocation_table(vehicle)
    for tid in known:
        table[:, tid - 1] = 0
    return table


def pack_fsw(vehicle):
    """Flight-software design array (layout.FSW), derived from the nominal vehicle."""
    fsw_cfg = vehicle["flight_software"]
    pwpf = fsw_cfg.get("pwpf", NO_PWPF)
    limits = vehicle["rcs"]["switching_limits_ms"] if "rcs" in vehicle else {"min_on": 0.0, "min_off": 0.0}
    smc = fsw_cfg.get("smc", NO_SMC)
    out = np.zeros(L.FSW_SIZE)
    _put(out, L.FSW, "control_period_s", 1.0 / fsw_cfg["control_rate_hz"])
    _put(out, L.FSW, "inertia_kg_m2", vehicle["inertia_kg_m2"])
    _put(out, L.FSW, "accel_margin", fsw_cfg["guidance_accel_margin"])
    _put(out, L.FSW, "tau_min_fraction", pwpf["tau_min_fraction"])
    _put(out, L.FSW, "pwpf_on_s", pwpf["t_on_ms"] / 1e3)
    _put(out, L.FSW, "pwpf_off_s", pwpf["t_off_ms"] / 1e3)
    _put(out, L.FSW, "pwpf_correction_s", pwpf["correction_ms"] / 1e3)
    _put(out, L.FSW, "min_on_s", limits["min_on"] / 1e3)
    _put(out, L.FSW, "min_off_s", limits["min_off"] / 1e3)
    _put(out, L.FSW, "controller_id", CONTROLLERS[fsw_cfg["controller"]])
    _put(out, L.FSW, "actuation_id", ACTUATIONS[fsw_cfg["actuation"]])
    engine = vehicle.get("main_engine", NO_ENGINE)
    burn = fsw_cfg.get("burn_guidance", NO_BURN_GUIDANCE)
    _put(out, L.FSW, "engine_axis", derived.engine_direction(engine))
    _put(out, L.FSW, "guidance_period_s", 1.0 / burn["rate_hz"])
    _put(out, L.FSW, "guidance_position_gain_s2", burn["position_gain_s2"])
    _put(out, L.FSW, "guidance_velocity_gain_s", burn["velocity_gain_s"])
    _put(
        out,
        L.FSW,
        "guidance_law_id",
        GUIDANCE_LAWS[burn.get("law", parameters.schema_default("flight_software.burn_guidance.law"))],
    )
    _put(out, L.FSW, "smc_slope_s", smc["slope_s"])
    _put(out, L.FSW, "smc_gain_rad_s2", smc["gain_rad_s2"])
    _put(out, L.FSW, "smc_boundary_layer_rad_s", smc["boundary_layer_rad_s"])
    _put(out, L.FSW, "wheel_friction_compensation", 1.0 if fsw_cfg.get("wheel_friction_compensation") else 0.0)
    if "translation" in fsw_cfg:
        _pack_translation(out, vehicle)
    return out


def _pack_translation(out, vehicle):
    masks, force, tau = derived.translation_design(vehicle)
    feed = vehicle["rcs"]["feed"]
    gas_per_pa = feed["tank_volume_m3"] / (feed["gas_constant_j_kg_k"] * feed["temperature_k"])
    _put(out, L.FSW, "translation_law_id", TRANSLATION_LAWS[vehicle["flight_software"]["translation"]["law"]])
    _put(out, L.FSW, "translation_masks", masks)
    _put(out, L.FSW, "translation_force_per_pa", force)
    _put(out, L.FSW, "translation_tau_s", tau)
    _put(out, L.FSW, "translation_dry_mass_kg", vehicle["mass_kg"] - feed["initial_pressure_pa"] * gas_per_pa)
    _put(out, L.FSW, "translation_gas_per_pa", gas_per_pa)
    law = vehicle["flight_software"]["translation"]
    period = 1.0 / vehicle["flight_software"]["control_rate_hz"]
    _put(out, L.FSW, "translation_pd_gains", [law.get("position_gain_s2", 0.0), law.get("velocity_gain_s", 0.0)])
    _put(out, L.FSW, "translation_pwm_steps", max(1, round(law.get("pwm_period_s", period) / period)))
    _put(out, L.FSW, "translation_deadband", [law.get("deadband_position_m", 0.0), law.get("deadband_speed_m_s", 0.0)])


def pack_mission(mission, trajectory=schema.DEFAULT_TRAJECTORY, plan=None):
    """Mission array (layout.MISSION); ``trajectory`` is the vehicle's trajectory model, ``plan``
    an orbit mission's nominal deorbit plan (``config.deorbit.plan``)."""
    out = np.zeros(L.MISSION_SIZE)
    initial = mission["initial_state"]
    sun = np.asarray(mission.get("sun_direction", [1.0, 0.0, 0.0]), dtype=float)
    earth = mission.get("earth", {"radius_m": 0.0, "mu_m3_s2": 0.0})
    rad = np.radians
    end_max = mission.get("attitude_error_end_max_deg")
    disturbances = mission.get("disturbances", {})
    gravity = disturbances.get("gravity_gradient", {"bodies": [], "direction": [0.0, 0.0, 1.0]})
    gravity_direction = np.asarray(gravity["direction"], dtype=float)
    # the initial state, the local trajectory's position and velocity (zero where the mission has none)
    parameters.pack_nominal(out, "mission", mission)
    values = {
        "initial_attitude_rotvec_rad": derived.initial_rotation_vector(initial),  # or from Euler angles
        "sun_direction": smallmatrix.unit(sun),
        "earth_radius_m": earth["radius_m"],
        "earth_mu_m3_s2": earth["mu_m3_s2"],
        "attitude_error_end_max_rad": math.inf if end_max is None else rad(end_max),
        "max_flight_time_s": mission["max_flight_time_s"],
        "integrator_max_step_s": mission["integrator"]["max_step_s"],
        "trajectory_step_s": mission["integrator"]["trajectory_step_s"],
        "trajectory_model_id": TRAJECTORY_MODELS[trajectory],
        "earth_rotation_rate_rad_s": earth.get("rotation_rate_rad_s", 0.0),
        "gravity_gradient_coefficient_s2": derived.gravity_gradient_coefficient(gravity["bodies"]),
        "gravity_gradient_direction": smallmatrix.unit(gravity_direction),
        "constant_torque_n_m": disturbances.get("constant_torque_n_m", [0.0, 0.0, 0.0]),
        "pointing_statistics_from_s": mission.get("pointing_statistics_from_s", math.inf),
    }
    if plan is not None:
        values["orbit_state"] = plan.state0[:6]
        values["entry_interface_altitude_m"] = mission["orbit"]["entry_interface_altitude_m"]
        values["burn_start_s"] = plan.ignition_s
        values["burn_duration_s"] = plan.burn_duration_s
    local = mission.get("local")
    if local is not None:
        values["local_target_m"] = local["target_position_m"]
        values["local_gravity_m_s2"] = local.get("gravity_m_s2", [0.0, 0.0, 0.0])
        values["local_reserve_pressure_pa"] = local.get("reserve_pressure_pa", 0.0)
    for name, value in values.items():
        _put(out, L.MISSION, name, value)
    return out


def mode_names(mission):
    """The mission's mode names in flight order."""
    return [mode["name"] for mode in mission["modes"]]


def target_quaternion(target):
    """Inertial target quaternion (scalar last, unit) of an ``inertial`` target."""
    if "quaternion" in target:
        q = np.asarray(target["quaternion"], dtype=float)
        return smallmatrix.unit(q)
    return derived.euler_quaternion(target["sequence"], target["euler_deg"])


def _predicate_value(name, value):
    """A threshold in SI units: degrees (``_deg``, ``_deg_s``) to radians; flags to 1."""
    if value is True:
        return 1.0
    return math.radians(value) if name.endswith(("_deg", "_deg_s")) else float(value)


def pack_modes(mission, levels=schema.REFEX_LEVEL_NAMES, burn_attitude=None):
    """Mode table (layout.MODE rows) and exit table (layout.EXIT rows) of the mode program;
    ``levels``: the vehicle's thrust-level names (:func:`level_names`); ``burn_attitude``: the
    inertial attitude of a ``burn_start`` target (``derived.burn_start_attitude``)."""
    levels = {name: k for k, name in enumerate(levels)}
    program = mission["modes"]
    table = np.zeros((len(program), L.MODE_SIZE))
    exit_rows = []
    for m, mode in enumerate(program):
        row = table[m]
        target = mode.get("target", {"type": "none"})
        _put(row, L.MODE, "kind_id", core_modes.KINDS[mode["kind"]])
        # a burn_start target is an inertial one, computed from the nominal plan
        target_type = "inertial" if target["type"] == "burn_start" else target["type"]
        _put(row, L.MODE, "target_id", core_modes.TARGETS[target_type])
        _put(row, L.MODE, "thrust_level", levels[mode["thrust"]] if "thrust" in mode else 0)
        _put(row, L.MODE, "navigation_calibration", 1.0 if mode.get("navigation_calibration") else 0.0)
        _put(row, L.MODE, "timeout_s", mode.get("timeout_s", math.inf))
        _put(row, L.MODE, "t1_design_s", mode.get("t1_design_s", 0.0))
        angles = [target.get(k, 0.0) for k in ("alpha_deg", "beta_deg", "bank_deg")]
        _put(row, L.MODE, "aerodynamic_angles_rad", np.radians(angles))
        quaternion = target_quaternion(target) if target["type"] == "inertial" else [0.0, 0.0, 0.0, 1.0]
        if target["type"] == "burn_start":
            quaternion = burn_attitude
        _put(row, L.MODE, "target_quaternion", quaternion)
        _put(row, L.MODE, "rate_rad_s", np.radians(mode.get("rate_deg_s", [0.0, 0.0, 0.0])))
        _put(row, L.MODE, "predicted_at_altitude_m", target.get("predicted_at_altitude_m", 0.0))
        local_target = mode.get("target_position_m", mission.get("local", {}).get("target_position_m", [0.0] * 3))
        _put(row, L.MODE, "local_target_m", local_target)
        _put(row, L.MODE, "exit_first_row", len(exit_rows))
        for group, predicates in enumerate(mode["exit"]):
            ranked = sorted(predicates, key=lambda name: schema.EXIT_PREDICATES[name][1])  # cheap first
            for name in ranked:
                value = _predicate_value(name, predicates[name])
                exit_rows.append([group, core_modes.PREDICATES[name], value])
        _put(row, L.MODE, "exit_rows", len(exit_rows) - row[L.MD_EXIT_FIRST])
    exits = np.zeros((len(exit_rows), L.EXIT_SIZE))
    for k, (group, predicate, value) in enumerate(exit_rows):
        exits[k, L.E_GROUP] = group
        exits[k, L.E_PREDICATE] = predicate
        exits[k, L.E_VALUE] = value
    return table, exits


def pack_navigation(mission):
    """Navigation-error array (layout.NAV)."""
    out = np.zeros(L.NAV_SIZE)
    parameters.pack_nominal(out, "nav", mission)  # every field is a dispersible parameter
    return out


def pack_atmosphere(mission):
    """Atmosphere table rows [base altitude m, density kg/m^3, scale height m]."""
    rows = [
        [r["base_altitude_km"] * 1e3, r["density_kg_m3"], r["scale_height_km"] * 1e3]
        for r in mission.get("atmosphere", [])
    ]
    return np.array(rows, dtype=float).reshape(-1, 3)


def deorbit_plan(vehicle, mission):
    """The nominal deorbit plan of an orbit mission (``config.deorbit``), or None. Computed once
    per process for the same vehicle and mission (a bisection of ~0.5 s; every chunk packs)."""
    if vehicle.get("trajectory") != "orbit":
        return None
    return _cached_plan(json.dumps([vehicle, mission], sort_keys=True))


@functools.lru_cache(maxsize=8)
def _cached_plan(key):
    vehicle, mission = json.loads(key)
    fsw = vehicle["flight_software"]
    return deorbit.plan(vehicle, mission, 1.0 / fsw["control_rate_hz"], 1.0 / fsw["burn_guidance"]["rate_hz"])


def pack(vehicle, mission, failed_thrusters=(), plan=None, failed_wheels=(), detected_wheels=(), detected_thrusters=()):
    """All run inputs for the nominal (undispersed) vehicle and mission; ``plan``: the deorbit
    plan when already computed (:func:`deorbit_plan`). ``failed_thrusters``, ``failed_wheels``:
    1-based ids of what does not work; ``detected_wheels``: 1-based ids of wheels the flight
    software knows to have failed and leaves out of its distribution (and of the levels' limits);
    ``detected_thrusters``: failed thrusters it knows, left out of its LP and allocation table."""
    detected_thrusters = tuple(t for t in detected_thrusters if t in set(failed_thrusters))
    plan = plan or deorbit_plan(vehicle, mission)
    burn_attitude = None if plan is None else derived.burn_start_attitude(vehicle, plan)
    mode_table, exit_table = pack_modes(mission, level_names(vehicle), burn_attitude)
    nominal = np.zeros((0, L.NOMINAL_SIZE)) if plan is None else plan.table
    return RunInputs(
        vehicle=pack_vehicle(vehicle),
        thrusters=pack_thrusters(vehicle, failed_thrusters, detected_thrusters),
        levels=pack_levels(vehicle, detected_wheels),
        fsw=pack_fsw(vehicle),
        mission=pack_mission(mission, derived.trajectory_model(vehicle), plan),
        modes=mode_table,
        exits=exit_table,
        nav=pack_navigation(mission),
        atmosphere=pack_atmosphere(mission),
        allocation=pack_allocation(vehicle, detected_thrusters),
        nominal=nominal,
        wheels=pack_wheels(vehicle, failed_wheels),
        wheel_distribution=pack_wheel_distribution(vehicle, detected_wheels),
    )
