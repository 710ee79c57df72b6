"""Every configuration key, declared once: type, unit, range and meaning (JSON Schema).

Units are in the key names (``_m``, ``_deg_s``, ``_ms``...) and repeated in each description.
Unknown keys fail (``additionalProperties: false``).
"""

# the parameters of a dispersion that a sweep may vary (config.sweep)
SWEPT_DISTRIBUTION_PARAMETERS = (
    "value",
    "mean",
    "sigma",
    "low",
    "high",
    "median",
    "moments_sigma_fraction",
    "axes_sigma_deg",
)


def number(doc, minimum=None, maximum=None, exclusive_minimum=None, default=None):
    """A number key; ``default``: the value a file that omits it has (read by the packers)."""
    s = {"type": "number", "description": doc}
    if default is not None:
        s["default"] = default
    if minimum is not None:
        s["minimum"] = minimum
    if maximum is not None:
        s["maximum"] = maximum
    if exclusive_minimum is not None:
        s["exclusiveMinimum"] = exclusive_minimum
    return s


def integer(doc, minimum=None, maximum=None):
    s = {"type": "integer", "description": doc}
    if minimum is not None:
        s["minimum"] = minimum
    if maximum is not None:
        s["maximum"] = maximum
    return s


def vector(doc, length=3, default=None, **limits):
    item = number("component", **limits)
    s = {"type": "array", "items": item, "minItems": length, "maxItems": length, "description": doc}
    if default is not None:
        s["default"] = list(default)
    return s


def string(doc, enum=None, default=None):
    s = {"type": "string", "description": doc}
    if default is not None:
        s["default"] = default
    if enum is not None:
        s["enum"] = list(enum)
    return s


def obj(doc, properties, optional=()):
    return {
        "type": "object",
        "description": doc,
        "properties": properties,
        "required": [k for k in properties if k not in optional],
        "additionalProperties": False,
    }


POSITIVE = {"exclusive_minimum": 0.0}
LEVEL_NAME_PATTERN = "^[A-Za-z][A-Za-z0-9_]*$"
REFEX_LEVEL_NAMES = ("low", "high")  # 000's thrust levels: the levels of a call that names none
DEFAULT_TRAJECTORY = "planar_drag"  # a vehicle without a trajectory key
DEFAULT_RUN_TIME_LIMIT_S = 60.0  # a campaign without run_time_limit_s
MAX_LEVELS = 8


def per_level(doc, item):
    """A mapping thrust-level name -> ``item`` (levels are named by the vehicle's thrust_n)."""
    return {
        "type": "object",
        "description": doc,
        "propertyNames": {"pattern": LEVEL_NAME_PATTERN},
        "additionalProperties": item,
        "minProperties": 1,
        "maxProperties": MAX_LEVELS,
    }


_time_constants = obj(
    "valve time constants of one thrust level (000 Table 2)",
    {
        "on_delay": number("delay from open command to start of rise [ms]", minimum=0.0),
        "rise": number("linear rise time to full thrust [ms]", minimum=0.0),
        "off_delay": number("delay from close command to start of fall [ms]", minimum=0.0),
        "fall": number("linear fall time to zero thrust [ms]", minimum=0.0),
    },
)

THRUSTER = obj(
    "one thruster",
    {
        "id": integer("thruster number, 1..N in order", minimum=1),
        "position_m": vector("position in the nominal body frame [m]"),
        "direction": vector("force direction in body axes (normalised on load) [-]"),
        "name": {
            "type": "string",
            "pattern": "^[A-Za-z][A-Za-z0-9_-]*$",
            "description": "optional name, unique; failures may name the thruster by it",
        },
    },
    optional=("name",),
)

AXIS_COMMAND_PATTERN = "^([+-]x)?([+-]y)?([+-]z)?$"

WHEEL = obj(
    "one reaction wheel",
    {
        "id": integer("wheel number, 1..N in order", minimum=1),
        "name": {
            "type": "string",
            "pattern": "^[A-Za-z][A-Za-z0-9_-]*$",
            "description": "optional name, unique",
        },
        "axis": vector("spin axis in body axes, a column of 001's W (normalised on load) [-]"),
        "initial_momentum_n_m_s": number(
            "I_w Omega at t = 0, Omega relative to the body, along the axis; default 0 [N m s]", default=0.0
        ),
    },
    optional=("name", "initial_momentum_n_m_s"),
)
MAX_WHEELS = 16
# the distribution law of the flight software (001 sec. 9): name -> what it is
WHEEL_DISTRIBUTIONS = {
    "pseudo_inverse": "D = W^+ = W^T (W W^T)^-1 over the wheels it uses (001 sec. 9.1): least squares wheel torques",
}

WHEELS = obj(
    "reaction wheel assembly (001 sec. 4, 8, 9): identical wheels, one axis each",
    {
        "distribution": string(
            "torque distribution of the flight software: "
            + "; ".join(f"{k}: {v}" for k, v in WHEEL_DISTRIBUTIONS.items()),
            enum=list(WHEEL_DISTRIBUTIONS),
        ),
        "spin_inertia_kg_m2": number("rotor inertia about its spin axis [kg m^2]", **POSITIVE),
        "torque_max_n_m": number("motor torque limit per wheel [N m]", **POSITIVE),
        "momentum_max_n_m_s": number("momentum limit |I_w Omega| per wheel (speed limiter) [N m s]", **POSITIVE),
        "friction": obj(
            "bearing friction on each rotor, 001 eq. 1: -tau_e sign(Omega) - tau_v Omega",
            {
                "coulomb_n_m": number("Coulomb friction tau_e [N m]", minimum=0.0),
                "viscous_n_m_s": number("viscous friction tau_v [N m s/rad]", minimum=0.0),
                "coulomb_width_rpm": number(
                    "speed within which the Coulomb term is linear, -tau_e Omega / width (eq. 1's sign "
                    "regularised: 001 sec. 4.1 notes eq. 1 fails near zero speed) [rpm]",
                    **POSITIVE,
                ),
            },
        ),
        "units": {
            "type": "array",
            "description": "the wheels, ids 1..N in order; their axes must span the three body axes",
            "items": WHEEL,
            "minItems": 3,
            "maxItems": MAX_WHEELS,
        },
        "null_space_management": obj(
            "flight software, optional (absent: off): the part of the wheel momenta I_w Omega - target in the "
            "null space of the distribution's wheels (001 sec. 9.1: H_W = W^+ H_B + n) decays with a time "
            "constant, by motor torques in that null space (no body torque with the known axes); no null "
            "space with three wheels used",
            {
                "time_constant_s": number(
                    "time constant of the decay: torque = -(null-space error) / it [s]", **POSITIVE
                ),
                "target": string(
                    "zero: the null-space momentum n = 0 (the pseudo-inverse momentum law, least wheel "
                    "momenta); bias: the null-space part of bias_n_m_s (wheel speeds kept off zero)",
                    enum=["zero", "bias"],
                ),
                "bias_n_m_s": {
                    "type": "array",
                    "items": number("I_w Omega of this wheel [N m s]"),
                    "minItems": 3,
                    "maxItems": MAX_WHEELS,
                    "description": "target bias, one relative momentum per wheel in id order; only its null-space "
                    "part counts (target bias only) [N m s]",
                },
                "deadband_n_m_s": number(
                    "no torque while the null-space error's norm is within it; beyond, the error less "
                    "the deadband decays (default 0) [N m s]",
                    minimum=0.0,
                ),
                "torque_max_n_m": number(
                    "cap on the null-space torque of any wheel, the vector scaled (default: the wheels' "
                    "torque_max_n_m) [N m]",
                    **POSITIVE,
                ),
                "give_up_beyond_n_m_s": number(
                    "stop for the rest of the flight once the torque is at its cap and the null-space error, "
                    "still growing, lies this far beyond the deadband: the null space does not respond, as "
                    "with a dead wheel the flight software does not know of (default: never) [N m s]",
                    minimum=0.0,
                ),
            },
            optional=("bias_n_m_s", "deadband_n_m_s", "torque_max_n_m", "give_up_beyond_n_m_s"),
        ),
    },
    optional=("null_space_management",),
)

FEED = obj(
    "cold-gas feed behind the valves (002 sec. 2-3; core.feed, docs/cold-gas.md): constant (thrust_n "
    "until propellant_kg is used, at isp_s; the default), blow_down (nozzles on an isothermal tank: thrust "
    "and flow proportional to its pressure, 002 eq. 13-20) or regulated (each level's thrust_n while the "
    "tank is above the chamber pressure that gives it, derated with several valves open as the "
    "pressure reducers are (000 sec. 2.1), then blow-down). Not constant: isp_s and propellant_kg are "
    "derived from the tank and nozzle; blow_down: thrust_n is what the flight software assumes",
    {
        "model": string("feed model (default constant)", enum=["constant", "blow_down", "regulated"]),
        "tank_volume_m3": number("tank volume V [m^3]", **POSITIVE),
        "gas_constant_j_kg_k": number("specific gas constant R of the gas (nitrogen 296.8) [J/(kg K)]", **POSITIVE),
        "heat_capacity_ratio": number("gamma = c_p / c_v of the gas (nitrogen 1.4) [-]", exclusive_minimum=1.0),
        "temperature_k": number("tank and chamber temperature T, constant (002 sec. 2.1) [K]", **POSITIVE),
        "initial_pressure_pa": number("tank pressure at t = 0 [Pa]", **POSITIVE),
        "throat_area_m2": number("nozzle throat area A_t of each thruster (times its thrust scale) [m^2]", **POSITIVE),
        "expansion_ratio": number("nozzle area ratio epsilon = A_e / A_t (002 eq. 6) [-]", minimum=1.0),
        "ambient_pressure_pa": number(
            "ambient pressure P_a of 002 eq. 15 (default 0: vacuum) [Pa]", minimum=0.0, default=0.0
        ),
    },
    optional=(
        "tank_volume_m3",
        "gas_constant_j_kg_k",
        "heat_capacity_ratio",
        "temperature_k",
        "initial_pressure_pa",
        "throat_area_m2",
        "expansion_ratio",
        "ambient_pressure_pa",
    ),
)
# rcs.feed keys a blow-down or regulated feed needs
FEED_TANK_KEYS = (
    "tank_volume_m3",
    "gas_constant_j_kg_k",
    "heat_capacity_ratio",
    "temperature_k",
    "initial_pressure_pa",
    "throat_area_m2",
    "expansion_ratio",
)

# flight_software keys of the thruster design: required with an rcs, refused without one
RCS_DESIGN_KEYS = ("damping_ratio", "deadband_angle_deg", "thrusters_per_axis", "pwpf")
# actuation -> the vehicle block it drives
ACTUATION_HARDWARE = {"pwpf_table": "rcs", "lp_pwm": "rcs", "wheels": "wheels"}
WHEELS_LEVEL = "wheels"  # the one level of a vehicle that flies reaction wheels (levels table row 0)

# --- issue 24: entry aerodynamics and aerodynamic surfaces (003; config.entry, core.aerodynamics) ---
ENTRY_ATMOSPHERES = ("ussa1976",)


def coefficient_table(doc):
    """A coefficient over (alpha, Mach): one row per alpha_deg, one column per mach."""
    return {
        "type": "array",
        "description": doc + " [-]; rows: entry_aerodynamics.alpha_deg, columns: entry_aerodynamics.mach",
        "items": {"type": "array", "description": "one row: a value per Mach", "items": number("value"), "minItems": 1},
        "minItems": 1,
    }


# YAML key -> what it is; the core slot is config.entry.COEFFICIENT_SLOTS
ENTRY_FORCE_AND_STATIC = {
    "lift": "C_L lift coefficient (003 eq. 3)",
    "drag": "C_D drag coefficient (003 eq. 3)",
    "side_force_per_beta_rad": "C_Y_beta side force per rad of sideslip",
    "roll_per_beta_rad": "C_l_beta rolling moment per rad of sideslip",
    "pitch": "C_m pitching moment at zero flap deflection; trims at delta_trim = -C_m / C_m_delta_e (003 eq. 6)",
    "yaw_per_beta_rad": "C_n_beta yawing moment per rad of sideslip",
}
ENTRY_FLAP_DERIVATIVES = {
    "roll_per_aileron_rad": "C_l_delta_a per rad of aileron (003 eq. 6)",
    "pitch_per_elevon_rad": "C_m_delta_e per rad of elevon (003 eq. 6)",
    "yaw_per_aileron_rad": "C_n_delta_a per rad of aileron (003 eq. 6)",
}
ENTRY_RUDDER_DERIVATIVES = {
    "roll_per_rudder_rad": "C_l_delta_r per rad of rudder (003 eq. 10a)",
    "yaw_per_rudder_rad": "C_n_delta_r per rad of rudder (003 eq. 10c)",
}
ENTRY_AERODYNAMICS = obj(
    "aerodynamic coefficient tables of the entry flight over (alpha, Mach), bilinear, held at the edges "
    "(003 eq. 3, 6, 10); moments about the centre of mass with reference_length_m",
    {
        "reference_area_m2": number("reference area S [m^2]", **POSITIVE),
        "reference_length_m": number("reference length L of all three moments (003 eq. 6) [m]", **POSITIVE),
        "nose_radius_m": number("nose radius for the stagnation-point heat flux (Sutton-Graves) [m]", **POSITIVE),
        "alpha_deg": {
            "type": "array",
            "description": "angle-of-attack axis, strictly increasing [deg]",
            "items": number("alpha [deg]", minimum=-90.0, maximum=90.0),
            "minItems": 1,
        },
        "mach": {
            "type": "array",
            "description": "Mach axis, strictly increasing [-]",
            "items": number("Mach [-]", minimum=0.0),
            "minItems": 1,
        },
        "coefficients": obj(
            "coefficient tables; the control derivatives of the vehicle's surfaces are required, others refused",
            {
                key: coefficient_table(doc)
                for key, doc in {**ENTRY_FORCE_AND_STATIC, **ENTRY_FLAP_DERIVATIVES, **ENTRY_RUDDER_DERIVATIVES}.items()
            },
            optional=(*ENTRY_FLAP_DERIVATIVES, *ENTRY_RUDDER_DERIVATIVES),
        ),
    },
    optional=("nose_radius_m",),
)
SURFACES = obj(
    "aerodynamic control surfaces (003): two body flaps, elevon = symmetric, aileron = differential "
    "(eq. 7), and optionally two rudders",
    {
        "body_flaps": obj(
            "the two body flaps, each within [min_deg, max_deg] (positive: trailing edge down)",
            {
                "min_deg": number("lowest deflection of each flap [deg]", minimum=-90.0, maximum=90.0),
                "max_deg": number("highest deflection of each flap [deg]", minimum=-90.0, maximum=90.0),
                "hinge_moment_max_n_m": number(
                    "largest hinge moment a flap actuator holds (003 Table 1: 25881) [N m]", exclusive_minimum=0.0
                ),
                "hinge_area_arm_m3": number(
                    "flap area times its centre of pressure's distance behind the hinge: the hinge moment is "
                    "2 q S_f c sin^2(alpha + delta) (Newtonian), which bounds the deflection [m^3]",
                    exclusive_minimum=0.0,
                ),
                "rate_max_deg_s": number("largest deflection rate of each flap actuator [deg/s]", **POSITIVE),
                "blocked": obj(
                    "a flap blocked at a deflection (003 Hazard scenario): the other flap alone moves",
                    {
                        "flap": string("which flap is blocked", enum=["left", "right"]),
                        "deflection_deg": number(
                            "where it is blocked, within the flap limits [deg]", minimum=-90.0, maximum=90.0
                        ),
                    },
                ),
            },
            optional=("blocked", "hinge_moment_max_n_m", "hinge_area_arm_m3"),
        ),
        "rudders": obj(
            "the two fin-tip rudders, deflected together for yaw (003: usable below Mach 6, neutral above)",
            {
                "min_deg": number("lowest deflection [deg]", minimum=-90.0, maximum=90.0),
                "max_deg": number("highest deflection [deg]", minimum=-90.0, maximum=90.0),
                "usable_below_mach": number(
                    "Mach below which the rudders move; neutral above (003: 6) [-]", minimum=0.0
                ),
                "rate_max_deg_s": number("largest deflection rate of the rudder actuators [deg/s]", **POSITIVE),
            },
        ),
        "time_constant_s": number(
            "first-order lag of every surface actuator: a surface moves towards its command by "
            "1 - exp(-period / time_constant_s) of the difference each control period, within its rate (0: none) [s]",
            minimum=0.0,
        ),
    },
    optional=("rudders",),
)
ENTRY_CONTROL = obj(
    "the entry flight software's controller (core.entry_flight.control; 003: successive dynamic inversion plus "
    "feedback): outer loop on alpha, beta, bank with integral action below the RCS-only altitude, inner loop "
    "dynamic inversion of eq. 4, alignment of the free flap with a blocked one; at flight_software.control_rate_hz",
    {
        "angle_gain_1_s": vector(
            "outer loop: errors of alpha, beta, bank times these give the commanded rates of those angles [1/s]",
            exclusive_minimum=0.0,
        ),
        "rate_gain_1_s": number(
            "inner loop: body-rate error times this gives the angular acceleration the dynamic inversion "
            "commands [1/s]",
            **POSITIVE,
        ),
        "integral_gain_1_s": number(
            "outer loop: the integrals of the angle errors times this are added to the errors, below the "
            "RCS-only altitude (0: no integral action) [1/s]",
            minimum=0.0,
        ),
        "integral_limit_rad_times_s": vector(
            "anti-windup: the integrals of the alpha, beta, bank errors are clamped within +-these [rad s]",
            minimum=0.0,
        ),
        "align_gain_1_s": number(
            "a blocked flap known to the flight software: the alpha bias moves by this times the free flap's "
            "misalignment over the model's d(delta_trim)/d(alpha) per second (0: no alignment feedback) [1/s]",
            minimum=0.0,
        ),
        "align_limit_deg": number("largest |alpha bias| of the alignment feedback [deg]", minimum=0.0, maximum=90.0),
    },
)

VEHICLE = obj(
    "vehicle: mass properties, actuators (rcs, wheels or both) and flight-software design",
    {
        "name": string("vehicle name"),
        "trajectory": string(
            "trajectory model: planar_drag (point mass, gravity and drag; altitude and dynamic pressure), "
            "orbit (3D two-body orbit with a main engine, 004 sec. III; the mission's orbit block) "
            "local (position near a small body, uniform gravity, thrust through the attitude; the mission's "
            "local block, translate modes, docs/cold-gas.md) or none (attitude only); default " + DEFAULT_TRAJECTORY,
            enum=["planar_drag", "orbit", "none", "local"],
        )
        | {"default": DEFAULT_TRAJECTORY},
        "mass_kg": number("vehicle mass [kg]", **POSITIVE),
        "length_m": number("vehicle length (documentation) [m]", **POSITIVE),
        "span_m": number("wing span (documentation) [m]", **POSITIVE),
        "inertia_kg_m2": {
            "type": "array",
            "description": "inertia tensor about the CoM, body axes [kg m^2]",
            "items": vector("row"),
            "minItems": 3,
            "maxItems": 3,
        },
        "com_offset_m": vector("actual minus nominal centre of mass, body axes [m]"),
        "aerodynamics": obj(
            "aerodynamic reference data",
            {
                "reference_area_m2": number("reference area S [m^2]", **POSITIVE),
                "reference_length_m": number("reference length L [m]", **POSITIVE),
                "drag_area_m2": number("drag area C_D S for the trajectory [m^2]", minimum=0.0),
                "mistrim_cm": vector("mistrim moment coefficient per body axis [-]"),
            },
        ),
        "main_engine": obj(
            "constant-thrust main engine (orbit trajectory; 004 sec. III)",
            {
                "thrust_n": number("thrust [N]", **POSITIVE),
                "isp_s": number("specific impulse [s]", **POSITIVE),
                "propellant_kg": number("main-engine propellant, part of mass_kg [kg]", **POSITIVE),
                "direction": vector("nominal force direction in body axes (normalised on load) [-]"),
                "position_m": vector("thrust application point, nominal body frame [m]"),
                "misalignment_deg": vector("true minus nominal force direction, rotation vector [deg]"),
            },
        ),
        "rcs": obj(
            "reaction control system",
            {
                "thrust_n": per_level(
                    "thrust levels by name, in order (e.g. low, high): nominal thrust per thruster",
                    number("thrust of the level [N]", **POSITIVE),
                ),
                "derating": {
                    "type": "array",
                    "description": "thrust factor with 1, 2, ... valves open; more valves: the last [-]",
                    "items": number("factor", exclusive_minimum=0.0, maximum=1.0),
                    "minItems": 1,
                    "maxItems": 8,
                },
                "isp_s": number("specific impulse [s]", **POSITIVE),
                "propellant_kg": number("propellant mass at t = 0 [kg]", **POSITIVE),
                "valve_time_constants_ms": per_level(
                    "mean valve time constants per thrust level (the levels of thrust_n)", _time_constants
                ),
                "switching_limits_ms": obj(
                    "hardware switching limits per thruster (000 sec. 5)",
                    {
                        "min_on": number("minimum pulse duration [ms]", minimum=0.0),
                        "min_off": number("minimum rest between pulses [ms]", minimum=0.0),
                    },
                ),
                "thrusters": {
                    "type": "array",
                    "description": "thruster geometry",
                    "items": THRUSTER,
                    "minItems": 1,
                    "maxItems": 63,
                },
                "feed": FEED,
            },
            optional=("isp_s", "propellant_kg", "feed"),
        ),
        "wheels": WHEELS,
        "flight_software": obj(
            "flight-software design parameters",
            {
                "control_rate_hz": number("controller and modulator rate [Hz]", **POSITIVE),
                "controller": string(
                    "control law: pd_feedback_linearisation (000 eq. 30, 35), pd (004 eq. 1) or smc (sliding "
                    "mode with a boundary layer, 001 eq. 12; flight_software.smc)",
                    enum=["pd_feedback_linearisation", "pd", "smc"],
                ),
                "smc": obj(
                    "sliding-mode controller (001 eq. 12): sigma = omega_e + Lambda q_e,vec, "
                    "u = J (-Lambda q_e,vec_dot + omega_d_dot) + omega x J omega - J G sat(sigma, epsilon)",
                    {
                        "slope_s": vector("Lambda, slope of the sliding surface per body axis [1/s]", **POSITIVE),
                        "gain_rad_s2": vector("G, switching gain per body axis [rad/s^2]", **POSITIVE),
                        "boundary_layer_rad_s": vector(
                            "epsilon, boundary-layer width of sat(sigma, epsilon) per body axis [rad/s]", **POSITIVE
                        ),
                    },
                ),
                "gains": obj(
                    "given gains per thrust level (with actuation wheels: the level 'wheels'), body x, y, z "
                    "(default: derived from the rcs, 000 eq. 38 and 34). "
                    "pd: kp [N m], kd [N m s/rad]; pd_feedback_linearisation: kp [1/s^2], kd [1/s]",
                    {
                        "kp": per_level("proportional gain per thrust level", vector("body x, y, z [-]", minimum=0.0)),
                        "kd": per_level("derivative gain per thrust level", vector("body x, y, z [-]", minimum=0.0)),
                    },
                ),
                "actuation": string(
                    "torque-to-actuator chain: pwpf_table (PWPF per axis and the allocation table, 000 eq. 41-48, "
                    "Table 3) or lp_pwm (fuel-optimal LP allocation, 004 eq. 2-5, realised by pulse-width "
                    "modulation in the control period), both with the rcs; wheels (motor torques -D (u + omega x "
                    "H_wheels) with the wheels' distribution D, 001 sec. 9.1, held over the control period)",
                    enum=["pwpf_table", "lp_pwm", "wheels"],
                ),
                "translation": obj(
                    "translation law of translate modes (trajectory local; 002 sec. 4, core.time_optimal)",
                    {
                        "law": string(
                            "time_optimal (002 eq. 41-44, bang-off-bang with the fuel reserve), bang_bang "
                            "(sigma2 alone, 002 Fig. 8's comparison) or pd_pwm (a = -kp e - kd v per body axis, "
                            "pulse-width modulated over whole control periods)",
                            enum=["time_optimal", "bang_bang", "pd_pwm"],
                        ),
                        "deadband_position_m": number(
                            "an axis within this position error and deadband_speed_m_s coasts (default 0) [m]",
                            minimum=0.0,
                        ),
                        "deadband_speed_m_s": number(
                            "an axis within this speed and deadband_position_m coasts (default 0) [m/s]", minimum=0.0
                        ),
                        "position_gain_s2": number("pd_pwm: kp [1/s^2]", **POSITIVE),
                        "velocity_gain_s": number("pd_pwm: kd [1/s]", **POSITIVE),
                        "pwm_period_s": number("pd_pwm: modulation period, whole control periods [s]", **POSITIVE),
                    },
                    optional=(
                        "position_gain_s2",
                        "velocity_gain_s",
                        "pwm_period_s",
                        "deadband_position_m",
                        "deadband_speed_m_s",
                    ),
                ),
                "wheel_friction_compensation": {
                    "type": "boolean",
                    "description": "actuation wheels: each motor command also cancels the friction of 001 eq. 1 "
                    "with the vehicle file's (design) coefficients at the wheel's measured speed "
                    "(default false)",
                },
                "damping_ratio": number("zeta of 000 eq. 34 (derived rcs gains) [-]", **POSITIVE),
                "deadband_angle_deg": number(
                    "phi_e,db of 000 eq. 38 (derived rcs gains) [deg]", exclusive_minimum=0.0, maximum=10.0
                ),
                "thrusters_per_axis": vector("n_t of 000 eq. 1 (rcs) [-]", minimum=1),
                "guidance_accel_margin": number(
                    "fraction of omega_dot_max the guidance uses (000 eq. 13) [-]", exclusive_minimum=0.0, maximum=1.0
                ),
                "pwpf": obj(
                    "pulse modulator (000 eq. 41-48; rcs)",
                    {
                        "tau_min_fraction": number("tau_min / tau_max [-]", minimum=0.0, maximum=1.0),
                        "t_on_ms": number("algorithm minimum pulse [ms]", **POSITIVE),
                        "t_off_ms": number("algorithm minimum rest [ms]", **POSITIVE),
                        "correction_ms": number("delay correction delta gamma [ms]", minimum=0.0),
                    },
                ),
                "burn_guidance": obj(
                    "deorbit burn guidance (004 sec. III; core.deorbit): a_cmd = a_nom - k_r dr - k_v dv",
                    {
                        "rate_hz": number("guidance rate [Hz]", **POSITIVE),
                        "position_gain_s2": number("k_r [1/s^2]", minimum=0.0),
                        "velocity_gain_s": number("k_v [1/s]", minimum=0.0),
                        "law": string(
                            "pd (default: the law above on the GPS errors), open_loop_retrograde (along -v_gps, "
                            "no feedback) or open_loop_planned (the nominal's thrust direction at t, no feedback); "
                            "the burn time is the plan's in each",
                            enum=["pd", "open_loop_retrograde", "open_loop_planned"],
                            default="pd",
                        ),
                    },
                    optional=("law",),
                ),
                "allocation": {
                    "type": "object",
                    "description": "thrusters opened per axis-command combination, e.g. '+x-y' (000 Table 3)",
                    "propertyNames": {"pattern": AXIS_COMMAND_PATTERN, "minLength": 2},
                    "additionalProperties": {
                        "type": "array",
                        "items": integer("thruster id", minimum=1),
                        "description": "thruster ids",
                    },
                },
            },
            optional=(
                "gains",
                "allocation",
                "burn_guidance",
                "smc",
                "wheel_friction_compensation",
                "translation",
                *RCS_DESIGN_KEYS,
            ),
        ),
        # issue 24 (003, X-38): the entry flight's air, aerodynamic tables and surfaces (config.entry)
        "atmosphere": string(
            "standard atmosphere of the entry flight: ussa1976 (U.S. Standard Atmosphere 1976, 0-150 km, "
            "configs/atmospheres/ussa1976.csv)",
            enum=list(ENTRY_ATMOSPHERES),
        ),
        "entry_aerodynamics": ENTRY_AERODYNAMICS,
        "surfaces": SURFACES,
        "entry_control": ENTRY_CONTROL,
    },
    optional=(
        "trajectory",
        "length_m",
        "span_m",
        "aerodynamics",
        "main_engine",
        "rcs",
        "wheels",
        "atmosphere",
        "entry_aerodynamics",
        "surfaces",
        "entry_control",
    ),
)

# --- the mode program (refexmc.core.modes): kinds, targets and exit predicates by name -------
# A kind: what it is, the targets it can use (None: it takes no target), the mode keys only it
# takes (required, optional) and what its guidance provides to the exit predicates
# ("profile": a transition time t1; "rate_reference"; "attitude_reference").
MODE_KINDS = {
    "locked": {
        "doc": "no reference, actuators off (000 sec. 2.2, NCM)",
        "targets": None,
        "keys": ((), ()),
        "provides": (),
    },
    "rate_damping": {
        "doc": "cubic rate profile to zero from the measured rates (000 eq. 15-19)",
        "targets": None,
        "keys": ((), ()),
        "provides": ("profile", "rate_reference"),
    },
    "slew": {
        "doc": "SLERP paced by a quintic to the target, t1 from 000 eq. 13-14",
        "targets": ("sun_horizontal", "entry_predicted", "entry_velocity", "inertial", "burn_start"),
        "keys": ((), ("t1_design_s",)),
        "provides": ("profile", "rate_reference", "attitude_reference"),
    },
    "spin_up": {
        "doc": "quartic spin-up to a body rate from the last target attitude (000 eq. 20-27)",
        "targets": None,
        "keys": (("rate_deg_s",), ()),
        "provides": ("profile", "rate_reference", "attitude_reference"),
    },
    "hold": {
        "doc": "the target attitude at zero rate",
        "targets": ("sun_horizontal", "entry_predicted", "entry_velocity", "inertial", "previous", "burn_start"),
        "keys": ((), ()),
        "provides": ("rate_reference", "attitude_reference"),
    },
    "track": {
        "doc": "a moving target, recomputed every control period",
        "targets": ("entry_velocity",),
        "keys": ((), ()),
        "provides": ("rate_reference", "attitude_reference"),
    },
    "burn": {
        "doc": "main engine on from the planned ignition to cut-off, the engine axis steered by the burn "
        "guidance (004 sec. III); t1: the cut-off",
        "targets": None,
        "keys": ((), ()),
        "provides": ("profile", "rate_reference", "attitude_reference"),
    },
    "translate": {
        "doc": "trajectory local: to the mode's target_position_m (default the mission's "
        "local.target_position_m) and stop, the valves driven by flight_software.translation (002 eq. 44 "
        "per body axis); no attitude reference",
        "targets": None,
        "keys": ((), ("target_position_m",)),
        "provides": ("position",),
    },
}
# kinds of the local trajectory only
GAUSS_MARKOV_KEYS = ("attitude_gm_sigma_deg", "attitude_gm_tau_s", "rate_gm_sigma_deg_s", "rate_gm_tau_s")
LOCAL_NAVIGATION_KEYS = ("local_position_noise_m", "local_velocity_noise_m_s", "tank_pressure_noise_pa")
LOCAL_KINDS = ("translate",)
# targets computed from the trajectory (a vehicle without one cannot use them)
TRAJECTORY_TARGETS = ("sun_horizontal", "entry_predicted", "entry_velocity")
# kinds and targets of the orbit trajectory only (the deorbit plan)
ORBIT_KINDS = ("burn",)
ORBIT_TARGETS = ("burn_start",)
_ENTRY_ANGLES = {
    "alpha_deg": number("angle of attack [deg]", minimum=-90.0, maximum=90.0),
    "beta_deg": number("sideslip [deg]", minimum=-90.0, maximum=90.0),
    "bank_deg": number("bank angle [deg]", minimum=-180.0, maximum=180.0),
}
TARGET_TYPES = {
    "sun_horizontal": obj("body +y at the sun, body x nearest the local horizontal", {}),
    "entry_predicted": obj(
        "alpha, beta, bank to the velocity predicted (two-body conic) at an altitude",
        {**_ENTRY_ANGLES, "predicted_at_altitude_m": number("altitude of the prediction [m]", **POSITIVE)},
    ),
    "entry_velocity": obj("alpha, beta, bank to the current velocity", dict(_ENTRY_ANGLES)),
    "inertial": obj(
        "a fixed inertial attitude, as a quaternion or as Euler angles",
        {
            "quaternion": vector("body-to-inertial quaternion, scalar last (normalised on load) [-]", length=4),
            "euler_deg": vector("Euler angles [deg]"),
            "sequence": {
                "type": "string",
                "pattern": "^([XYZ]{3}|[xyz]{3})$",
                "description": "Euler sequence, scipy Rotation convention: XYZ intrinsic, xyz extrinsic",
            },
        },
        optional=("quaternion", "euler_deg", "sequence"),
    ),
    "previous": obj("the attitude the previous mode targeted (the measured one if none did)", {}),
    "burn_start": obj("the attitude of the nominal burn at ignition: the engine along the planned thrust", {}),
}
_TARGET_TYPE = string("target type", enum=list(TARGET_TYPES))
TARGET = {
    "type": "object",
    "description": "target attitude: {type: NAME, ...the keys of that type}",
    "properties": {"type": _TARGET_TYPE},
    "required": ["type"],
    "allOf": [
        {
            "if": {"properties": {"type": {"const": name}}},
            "then": {**spec, "properties": {"type": _TARGET_TYPE, **spec["properties"]}},
        }
        for name, spec in TARGET_TYPES.items()
    ],
}
# predicate -> (schema of its value, cost rank: cheaper predicates are evaluated first, what it
# needs: None, "trajectory", or what the mode's kind must provide)
EXIT_PREDICATES = {
    "time_in_mode_s": (number("time in mode at least [s]", minimum=0.0), 0, None),
    "mission_time_s": (number("time since t = 0 at least [s]", minimum=0.0), 0, None),
    "guidance_finished": ({"const": True, "description": "time in mode beyond the profile's t1"}, 1, "profile"),
    "descending": ({"const": True, "description": "navigated climb rate negative"}, 2, "trajectory"),
    "altitude_below_m": (number("navigated altitude below [m]"), 3, "trajectory"),
    "dynamic_pressure_above_pa": (number("dynamic pressure at least [Pa]", minimum=0.0), 4, "trajectory"),
    "rates_below_deg_s": (number("every measured body rate below [deg/s]", **POSITIVE), 5, None),
    "rate_error_below_deg_s": (
        number("measured minus reference rate, norm below [deg/s]", **POSITIVE),
        6,
        "rate_reference",
    ),
    "angle_error_below_deg": (
        number("angle measured attitude to target below [deg]", **POSITIVE),
        7,
        "attitude_reference",
    ),
    "position_error_below_m": (number("|position - local target| at most [m]", **POSITIVE), 8, "position"),
    "speed_below_m_s": (number("|velocity| in the local frame at most [m/s]", **POSITIVE), 8, "position"),
}
EXIT_GROUP = {
    "type": "object",
    "description": "predicates that must all hold",
    "properties": {name: value for name, (value, _, _) in EXIT_PREDICATES.items()},
    "additionalProperties": False,
    "minProperties": 1,
}
MAX_MODES = 32
MODE_NAME_PATTERN = "^[A-Za-z][A-Za-z0-9_]*$"
MODE = obj(
    "one mode of the program",
    {
        "name": {
            "type": "string",
            "pattern": MODE_NAME_PATTERN,
            "description": "mode name (letters, digits, _); output columns t_<name>_s",
        },
        "kind": string(
            "guidance kind: " + "; ".join(f"{k}: {v['doc']}" for k, v in MODE_KINDS.items()), enum=list(MODE_KINDS)
        ),
        "target": TARGET,
        "thrust": {
            "type": "string",
            "pattern": LEVEL_NAME_PATTERN,
            "description": "thrust level flown in the mode, a level of the vehicle's thrust_n (default: its "
            "first); not with actuation wheels",
        },
        "t1_design_s": number("shortest slew duration t1,dsgn (000 eq. 14) [s]", minimum=0.0),
        "rate_deg_s": vector("spin-up: final body rate [deg/s]"),
        "target_position_m": vector("translate: where this mode goes and stops, local frame [m]"),
        "navigation_calibration": {
            "type": "boolean",
            "description": "the attitude bias decays while this mode runs (navigation.ssm_calibration_time_s)",
        },
        "exit": {
            "type": "array",
            "description": "the mode ends when one group holds (OR of ANDs)",
            "items": EXIT_GROUP,
            "minItems": 1,
        },
        "timeout_s": number("the run fails when the mode lasts longer [s]", **POSITIVE),
    },
    optional=(
        "target",
        "thrust",
        "t1_design_s",
        "rate_deg_s",
        "navigation_calibration",
        "timeout_s",
        "target_position_m",
    ),
)


MISSION = obj(
    "mission: trajectory, environment, modes, navigation",
    {
        "name": string("mission name"),
        "earth": obj(
            "spherical non-rotating Earth",
            {
                "radius_m": number("radius [m]", **POSITIVE),
                "mu_m3_s2": number("gravitational parameter [m^3/s^2]", **POSITIVE),
                "rotation_rate_rad_s": number("spin rate (orbit trajectory: entry-state angles) [rad/s]", minimum=0.0),
            },
            optional=("rotation_rate_rad_s",),
        ),
        "orbit": obj(
            "initial orbit and deorbit target (orbit trajectory; config.deorbit)",
            {
                "altitude_m": number("altitude of the initial circular orbit [m]", **POSITIVE),
                "inclination_deg": number("inclination [deg]", exclusive_minimum=0.0, maximum=180.0),
                "entry_interface_altitude_m": number("entry interface altitude (004: 125 km) [m]", **POSITIVE),
                "deorbit": obj(
                    "the nominal burn: ignition, steering and the entry it targets",
                    {
                        "approach": string(
                            "opposite_velocity (thrust along -v) or hohmann_direction (the ignition's "
                            "tangential -v, fixed inertial), 004 Fig. 7",
                            enum=["opposite_velocity", "hohmann_direction"],
                        ),
                        "burn_start_s": number("ignition time [s]", **POSITIVE),
                        "entry_flight_path_angle_deg": number(
                            "target entry flight-path angle (burn time by bisection) [deg]",
                            exclusive_minimum=-90.0,
                            maximum=0.0,
                        ),
                        "entry_longitude_deg": number("target entry longitude [deg E]", minimum=-180.0, maximum=360.0),
                        "entry_latitude_deg": number("target entry latitude [deg N]", minimum=-90.0, maximum=90.0),
                        "pass": string(
                            "entry on the ascending (northbound) or descending pass", enum=["ascending", "descending"]
                        ),
                    },
                ),
            },
        ),
        "initial_state": obj(
            "the state at t = 0 (was 'separation'): absolute rates and attitude, not errors from a target",
            {
                "altitude_m": number("altitude (planar_drag trajectory) [m]", **POSITIVE),
                "speed_m_s": number("inertial speed (planar_drag trajectory) [m/s]", **POSITIVE),
                "flight_path_angle_deg": number(
                    "flight-path angle (planar_drag trajectory) [deg]", minimum=-90.0, maximum=90.0
                ),
                "rates_deg_s": vector("body rates, inertial (absolute) [deg/s]", minimum=-90.0, maximum=90.0),
                "attitude_rotvec_deg": vector(
                    "the attitude (absolute, not an error): rotation vector from the reference axes, body x "
                    "along velocity and wings level (no trajectory: the inertial axes) [deg]; or attitude_euler_deg"
                ),
                "attitude_euler_deg": vector(
                    "the same attitude as Euler angles in euler_sequence, instead of attitude_rotvec_deg [deg]"
                ),
                "euler_sequence": {
                    "type": "string",
                    "pattern": "^([XYZ]{3}|[xyz]{3})$",
                    "description": "sequence of attitude_euler_deg, scipy Rotation convention: XYZ intrinsic, "
                    "xyz extrinsic",
                },
            },
            optional=(
                "altitude_m",
                "speed_m_s",
                "flight_path_angle_deg",
                "attitude_rotvec_deg",
                "attitude_euler_deg",
                "euler_sequence",
            ),
        ),
        "sun_direction": vector("sun direction, inertial frame (normalised on load) [-]"),
        "atmosphere": {
            "type": "array",
            "description": "piecewise-exponential density table, ascending base altitude",
            "minItems": 1,
            "items": obj(
                "one layer",
                {
                    "base_altitude_km": number("layer base altitude [km]"),
                    "density_kg_m3": number("density at the base [kg/m^3]", **POSITIVE),
                    "scale_height_km": number("scale height [km]", **POSITIVE),
                },
            ),
        },
        "modes": {
            "type": "array",
            "description": "the mode program, flown in order (docs/missions.md)",
            "items": MODE,
            "minItems": 1,
            "maxItems": MAX_MODES,
        },
        "attitude_error_end_max_deg": number(
            "success: the total attitude error when the last mode ends (attitude_error_end_deg) below [deg]; "
            "default: no check",
            **POSITIVE,
        ),
        "max_flight_time_s": number("a run still flying then fails [s]", **POSITIVE),
        "navigation": obj(
            "navigation errors (the project's reference model, sec. 5)",
            {
                "attitude_bias_deg": vector("attitude bias rotation vector [deg]"),
                "attitude_noise_deg": number("attitude white noise, 1 sigma per axis [deg]", minimum=0.0),
                "rate_bias_deg_s": vector("rate bias [deg/s]"),
                "rate_noise_deg_s": number("rate white noise, 1 sigma per axis [deg/s]", minimum=0.0),
                "ssm_calibration_time_s": number(
                    "attitude-bias decay time constant in modes with navigation_calibration; 0: none [s]", minimum=0.0
                ),
                "gps_position_bias_m": vector(
                    "GPS position bias, ECI axes (orbit trajectory) [m]", default=[0.0, 0.0, 0.0]
                ),
                "gps_position_noise_m": number(
                    "GPS position white noise, 1 sigma per axis and sample [m]", minimum=0.0, default=0.0
                ),
                "gps_velocity_bias_m_s": vector("GPS velocity bias, ECI axes [m/s]", default=[0.0, 0.0, 0.0]),
                "gps_velocity_noise_m_s": number(
                    "GPS velocity white noise, 1 sigma per axis and sample [m/s]", minimum=0.0, default=0.0
                ),
                "local_position_noise_m": number(
                    "local trajectory: position white noise, 1 sigma per axis and control period [m]",
                    minimum=0.0,
                    default=0.0,
                ),
                "local_velocity_noise_m_s": number(
                    "local trajectory: velocity white noise, 1 sigma per axis and control period [m/s]",
                    minimum=0.0,
                    default=0.0,
                ),
                "tank_pressure_noise_pa": number(
                    "local trajectory: the translation law's tank-pressure transducer, white noise 1 sigma [Pa]",
                    minimum=0.0,
                    default=0.0,
                ),
                "attitude_gm_sigma_deg": number(
                    "attitude knowledge error, first-order Gauss-Markov: stationary 1 sigma per axis; 0: none [deg]",
                    minimum=0.0,
                    default=0.0,
                ),
                "attitude_gm_tau_s": number(
                    "its correlation time, sqrt(N) / sigma_v of a gyro-stellar estimator (Farrenkopf) [s]",
                    exclusive_minimum=0.0,
                    default=1.0,
                ),
                "rate_gm_sigma_deg_s": number(
                    "rate knowledge error, first-order Gauss-Markov: stationary 1 sigma per axis; 0: none [deg/s]",
                    minimum=0.0,
                    default=0.0,
                ),
                "rate_gm_tau_s": number("its correlation time [s]", exclusive_minimum=0.0, default=1.0),
            },
            optional=(
                "gps_position_bias_m",
                "gps_position_noise_m",
                "gps_velocity_bias_m_s",
                "gps_velocity_noise_m_s",
                *LOCAL_NAVIGATION_KEYS,
                *GAUSS_MARKOV_KEYS,
            ),
        ),
        "disturbances": obj(
            "external disturbance torques (001 sec. 10.2, eq. 10-11)",
            {
                "gravity_gradient": obj(
                    "gravity gradient of distant bodies on one line (001 eq. 11): 3 (sum mu/r^3) "
                    "n x J n, n the line's direction in body axes (physical sign; docs/irassi.md)",
                    {
                        "bodies": {
                            "type": "array",
                            "description": "the attracting bodies; the coefficient is sum mu/r^3",
                            "minItems": 1,
                            "items": obj(
                                "one body",
                                {
                                    "name": string("body name (documentation)"),
                                    "mu_m3_s2": number("gravitational parameter [m^3/s^2]", **POSITIVE),
                                    "distance_m": number("distance from the spacecraft [m]", **POSITIVE),
                                },
                            ),
                        },
                        "direction": vector(
                            "direction of the bodies from the spacecraft, inertial frame (normalised on load) [-]"
                        ),
                    },
                ),
                "constant_torque_n_m": vector("constant torque u_const in body axes (001 eq. 10) [N m]"),
            },
            optional=("gravity_gradient", "constant_torque_n_m"),
        ),
        "pointing_statistics_from_s": number(
            "pointing RMS and largest error over t >= this (runs columns pointing_*_arcsec) [s]", minimum=0.0
        ),
        "local": obj(
            "trajectory local: the vehicle near a small body, local frame = the attitude's inertial frame "
            "(core.local_flight)",
            {
                "position_m": vector("position at t = 0 [m]"),
                "velocity_m_s": vector("velocity at t = 0 [m/s]"),
                "target_position_m": vector("where translate modes go and stop [m]"),
                "gravity_m_s2": vector("uniform gravity (default zero) [m/s^2]"),
                "reserve_pressure_pa": number(
                    "tank pressure to keep at arrival: x3_min of 002 eq. 42 (default 0), inside eq. 45 [Pa]",
                    minimum=0.0,
                ),
            },
            optional=("gravity_m_s2", "reserve_pressure_pa"),
        ),
        "integrator": obj(
            "numerical integration",
            {
                "max_step_s": number(
                    "largest attitude RK4 step between thrust breakpoints [s]", exclusive_minimum=0.0, maximum=1.0
                ),
                "trajectory_step_s": number(
                    "trajectory RK4 node spacing; cubic Hermite in between [s]", exclusive_minimum=0.0, maximum=5.0
                ),
            },
        ),
    },
    optional=(
        "attitude_error_end_max_deg",
        "earth",
        "sun_direction",
        "atmosphere",
        "orbit",
        "disturbances",
        "pointing_statistics_from_s",
        "local",
    ),
)

# --- issue 24: an entry mission (003, X-38): config.entry.entry_flight_from_mission flies it ---
ENTRY_MISSION = obj(
    "an entry mission: the closed-loop entry of core.entry_flight from the entry interface to a terminal "
    "condition (docs/x38.md)",
    {
        "name": string("mission name"),
        # the mission's Earth (declared once, in MISSION), its spin rate required: 003 eq. 3 turns with it
        "earth": {**MISSION["properties"]["earth"], "required": ["radius_m", "mu_m3_s2", "rotation_rate_rad_s"]},
        "entry_flight": obj(
            "the entry: state at the entry interface, guidance, mode program, terminal condition",
            {
                "state": obj(
                    "state of 003 eq. 3 at t = 0",
                    {
                        "altitude_m": number("altitude [m]", minimum=15_000.0, maximum=150_000.0),
                        "longitude_deg": number("longitude [deg E]", minimum=-180.0, maximum=360.0),
                        "latitude_deg": number("geocentric latitude [deg N]", minimum=-90.0, maximum=90.0),
                        "speed_m_s": number("Earth-relative speed [m/s]", **POSITIVE),
                        "flight_path_angle_deg": number("Earth-relative flight-path angle [deg]", -90.0, 90.0),
                        "heading_deg": number("heading from north towards east [deg]", -360.0, 360.0),
                        "alpha_deg": number("angle of attack of the initial attitude [deg]", -90.0, 90.0),
                        "bank_deg": number("bank of the initial attitude (sideslip 0) [deg]", -180.0, 180.0),
                    },
                ),
                "alpha_schedule": {
                    "type": "array",
                    "minItems": 1,
                    "description": "guidance: commanded angle of attack over Mach, piecewise linear, held at the "
                    "ends; Mach strictly increasing",
                    "items": obj(
                        "one node",
                        {
                            "mach": number("Mach number [-]", minimum=0.0),
                            "alpha_deg": number("commanded angle of attack [deg]", -90.0, 90.0),
                        },
                    ),
                },
                "bank_schedule": {
                    "type": "array",
                    "minItems": 1,
                    "description": "guidance: commanded bank over Earth-relative speed, piecewise linear, held at "
                    "the ends; speed strictly increasing",
                    "items": obj(
                        "one node",
                        {
                            "speed_m_s": number("Earth-relative speed [m/s]", minimum=0.0),
                            "bank_deg": number("commanded bank, positive turns the lift right [deg]", -180.0, 180.0),
                        },
                    ),
                },
                "rcs_only_above_m": number("mode program (003): RCS alone above this altitude [m]", minimum=0.0),
                "terminal_mach": number("the flight ends below this Mach (success) [-]", **POSITIVE),
                "floor_altitude_m": number("the flight ends below this altitude (failure) [m]", minimum=0.0),
                "max_time_s": number("the flight ends at this time (failure) [s]", **POSITIVE),
                "transient_s": number(
                    "tracking errors count this long after the start and after each mode change [s]", minimum=0.0
                ),
                "rcs_delay_ms": number(
                    "the thrusters' moment acts this long after each control instant, the previous period's "
                    "until then (valve opening and closing the flight software does not allow for); below the "
                    "vehicle's control period (absent: 0) [ms]",
                    minimum=0.0,
                ),
                "blocked_flap": obj(
                    "a body flap blocked from t = 0 (003; a failure; the vehicle file's surfaces.body_flaps.blocked "
                    "is replaced)",
                    {
                        "flap": string("which flap", enum=["left", "right"]),
                        "deflection_deg": number("where it is blocked, within the flap limits [deg]", -90.0, 90.0),
                        "known_to_flight_software": {
                            "type": "boolean",
                            "description": "true: the blending holds it at its deflection and the guidance flies "
                            "the alpha where it trims; false: the flight software commands it as if free",
                        },
                    },
                ),
            },
            optional=("blocked_flap", "rcs_delay_ms"),
        ),
    },
)


POINTING_INDICES = ("APE", "MPE", "RPE", "PDE", "PRE")  # ECSS-E-ST-60-10C performance error indices
KNOWLEDGE_INDICES = ("AKE", "MKE", "RKE", "KDE", "KRE")  # the same on the knowledge error, in that order
POINTING_ERRORS = ("total", "los", "x", "y", "z")
INTERPRETATIONS = ("temporal", "ensemble", "mixed")
PROBABILITY = {"exclusiveMinimum": 0.0, "exclusiveMaximum": 1.0}

# a pointing requirement of a campaign's `requirements` (config.pointing, docs/pointing.md)
POINTING_REQUIREMENT = obj(
    "a pointing requirement as ECSS-E-ST-60-10C states one: index, error, bound, P_C, interpretation, window",
    {
        "index": string("the error index", enum=POINTING_INDICES + KNOWLEDGE_INDICES),
        "error": string(
            "what |e| is: total (3-axis rotation angle), los (boresight to where the reference points it) "
            "or the component about body axis x, y or z",
            enum=POINTING_ERRORS,
        ),
        "boresight": vector("error los: the line of sight, body axes (normalised) [-]"),
        "bound_arcsec": number("the bound on the index [arcsec]", exclusive_minimum=0.0),
        "bound_deg": number("the bound on the index [deg]", exclusive_minimum=0.0),
        "p_c": {**number("the probability P_C the bound is met with [-]"), **PROBABILITY},
        "interpretation": string("the statistical interpretation", enum=INTERPRETATIONS),
        "window": obj(
            "the observation window: control steps in one of these modes and from_s <= t <= to_s",
            {
                "modes": {
                    "type": "array",
                    "items": string("a mode name of the mission"),
                    "minItems": 1,
                    "description": "the modes that count; default all",
                },
                "from_s": number("window start [s]", minimum=0.0),
                "to_s": number("window end [s]", minimum=0.0),
            },
            optional=("modes", "from_s", "to_s"),
        ),
        "delta_t_s": number(
            "MPE, RPE, PDE (and MKE, RKE, KDE): the averaging interval; default the observation period [s]",
            exclusive_minimum=0.0,
        ),
        "confidence": {**number("the verdict's confidence level [-]", default=0.95), **PROBABILITY},
        "runs": string("the runs judged: all, or failure_free (no injected failure)", enum=["all", "failure_free"]),
        "runs_fraction": {
            **number("temporal: the fraction of runs that must meet the bound [-]", default=0.99),
            "exclusiveMinimum": 0.0,
            "maximum": 1.0,
        },
        "name": string("a suffix that tells apart two requirements of the same index, error and interpretation"),
    },
    optional=("boresight", "bound_arcsec", "bound_deg", "delta_t_s", "confidence", "runs", "runs_fraction", "name"),
)


_reference = {
    "oneOf": [{"type": "string"}, {"type": "object"}],
    "description": "path relative to the campaign file, or an inline mapping",
}


def failures_schema(description, units_key, unit_item, units_description, **extra):
    """The schema of a campaign's failure settings (``failures``: thrusters, ``wheel_failures``:
    wheels): a mode, the failed units of mode fixed (under ``units_key``), the count
    probabilities of mode random, the set sizes of mode enumerate, and ``extra`` properties."""
    word = units_key.rstrip("s")
    return {
        "type": "object",
        "description": description,
        "properties": {
            "mode": string(
                "none | fixed (the same set every run) | random (count drawn per run) | "
                "enumerate (one run per combination of the given sizes)",
                enum=["none", "fixed", "random", "enumerate"],
            ),
            units_key: {
                "type": "array",
                "items": unit_item,
                "uniqueItems": True,
                "description": units_description,
            },
            "count_probabilities": {
                "type": "array",
                "items": number("probability", minimum=0.0, maximum=1.0),
                "minItems": 1,
                "description": "P(0 failed), P(1 failed), ... (mode random; sum 1)",
            },
            "sizes": {
                "type": "array",
                "items": integer(f"number of failed {word}s", minimum=1),
                "minItems": 1,
                "uniqueItems": True,
                "description": "sizes of the failure sets enumerated (mode enumerate)",
            },
            **extra,
        },
        "required": ["mode"],
        "additionalProperties": False,
    }


CAMPAIGN = obj(
    "a campaign",
    {
        "name": string("campaign name (default output directory runs/<name>)"),
        "vehicle": dict(_reference),
        "mission": dict(_reference),
        "runs": integer(
            "number of runs (with failures mode enumerate: derived, may be omitted)", minimum=1, maximum=10_000_000
        ),
        "seed": integer("campaign seed", minimum=0, maximum=2**63 - 1),
        "nominal_first": {"type": "boolean", "description": "run 0 is the undispersed nominal case"},
        "sampling": string(
            "sampling of the dispersions (saltelli: SALib's design for Sobol' indices, docs/studies.md)",
            enum=["random", "lhs", "sobol", "saltelli"],
        ),
        "dispersions": {
            "type": "object",
            "description": "parameter path -> distribution {dist: ..., parameters}; paths and "
            "distributions: refexmc.config.dispersions, docs/campaigns.md",
            "additionalProperties": {"type": "object", "description": "a distribution"},
        },
        "failures": failures_schema(
            "thrusters that never open and use no propellant (000 sec. 5)",
            "thrusters",
            {"type": ["integer", "string"], "minimum": 1, "description": "thruster id or name"},
            "failed thrusters by id or name (mode fixed)",
            detected={
                "type": "boolean",
                "description": "the flight software knows the failed thrusters: its LP allocation leaves them "
                "out (004 eq. 2-5) and its allocation table no longer commands them; default false (undetected)",
            },
        ),
        "wheel_failures": failures_schema(
            "reaction wheels whose motor gives no torque (friction still acts); vehicles with wheels only",
            "wheels",
            {"type": ["integer", "string"], "minimum": 1, "description": "wheel id or name"},
            "failed wheels by id or name (mode fixed)",
            detected={
                "type": "boolean",
                "description": "the flight software knows the failed wheels and leaves them out of its "
                "distribution matrix and torque limits (001 sec. 9.1); default false (undetected)",
            },
        ),
        "run_time_limit_s": number(
            "wall-clock limit of one run [s]; a run that exceeds it is recorded as an error",
            exclusive_minimum=0.0,
            default=DEFAULT_RUN_TIME_LIMIT_S,
        ),
        "output": obj(
            "what is stored",
            {"history_rate_hz": number("history sample rate [Hz]", exclusive_minimum=0.0, maximum=1000.0)},
        ),
        "requirements": {
            "type": "array",
            "items": {
                "type": ["string", "object"],
                "description": "'METRIC OP VALUE', or a pointing requirement (POINTING_REQUIREMENT)",
            },
            "description": "requirement verdicts for the report (docs/report.md, docs/pointing.md)",
        },
        "published": {
            "type": "array",
            "description": "values a source reports for this campaign, shown by the report beside ours "
            "(refexmc.config.published)",
            "items": obj(
                "one source's values of one statistic",
                {
                    "source": string("where the values come from (document, table, column)"),
                    "statistic": string(
                        "the statistic the values are, a requirement statistic (three_sigma: 3 std, std, mean, "
                        "p<q>, ...; refexmc.config.requirements), computed over the flown runs"
                    ),
                    "values": {
                        "type": "object",
                        "description": "runs column -> the source's value",
                        "additionalProperties": number("the source's value [the column's unit]"),
                        "minProperties": 1,
                    },
                },
            ),
        },
        "rare_event": obj(
            "estimate the probability of a rare event by subset simulation (Au & Beck 2001; "
            "refexmc.config.rare_event, docs/rare-events.md); needs sampling random, nominal_first false, no runs",
            {
                "event": string("the event on one run, 'METRIC OP VALUE' (a runs column; OP <= < >= >)"),
                "method": string("the estimator", enum=["subset"], default="subset"),
                "per_level": {**integer("flights per level; level 0 is an ordinary random draw", 20), "default": 1000},
                "p0": number("conditional probability of each level, 0 < p0 <= 0.5 [-]", None, 0.5, 0.0, 0.1),
                "max_levels": {**integer("most levels (level 0 included); P down to about p0^max_levels", 1, 40)},
                "proposal": string(
                    "the Markov-chain move in the standard-normal space of the inputs: pcn (preconditioned "
                    "Crank-Nicolson) or mma (component-wise modified Metropolis, Au & Beck sec. 3)",
                    enum=["pcn", "mma"],
                    default="pcn",
                ),
            },
            optional=("method", "per_level", "p0", "max_levels", "proposal"),
        ),
        "sweep": obj(
            "parameters varied over a grid, each point a full campaign (refexmc.config.sweep, docs/studies.md)",
            {
                "axes": {
                    "type": "array",
                    "minItems": 1,
                    "maxItems": 2,
                    "description": "one axis, or two for a grid",
                    "items": obj(
                        "one swept parameter",
                        {
                            "parameter": string(
                                "a scalar parameter path of docs/campaigns.md sec. 2 [its unit]; with "
                                "'dispersion', any dispersed path"
                            ),
                            "dispersion": string(
                                "sweep this parameter of the path's distribution instead of the file value "
                                "[the parameter's unit]",
                                enum=list(SWEPT_DISTRIBUTION_PARAMETERS),
                            ),
                            "values": {
                                "type": "array",
                                "minItems": 1,
                                "items": number("a value of the parameter [its unit]"),
                                "description": "the values (or range)",
                            },
                            "range": obj(
                                "count evenly spaced values from start to stop",
                                {
                                    "start": number("first value [the parameter's unit]"),
                                    "stop": number("last value [the parameter's unit]"),
                                    "count": integer("number of values", minimum=2, maximum=1000),
                                },
                            ),
                        },
                        optional=("values", "range", "dispersion"),
                    ),
                },
                "metrics": {
                    "type": "array",
                    "items": string("a runs column"),
                    "description": "columns whose percentiles the report draws against the swept value",
                },
            },
            optional=("metrics",),
        ),
        "sobol": obj(
            "the Sobol' indices of a 'sampling: saltelli' campaign (docs/studies.md sec. 3)",
            {
                "metrics": {
                    "type": "array",
                    "minItems": 1,
                    "uniqueItems": True,
                    "items": string("'success' or a runs column the mission produces"),
                    "description": "the metrics whose indices the report estimates [default: success when a "
                    "flight failed, the requirements' columns, then the mission's other outputs]",
                },
            },
        ),
    },
    optional=(
        "runs",
        "nominal_first",
        "sampling",
        "dispersions",
        "failures",
        "wheel_failures",
        "run_time_limit_s",
        "output",
        "requirements",
        "published",
        "sweep",
        "sobol",
        "rare_event",
    ),
)
