"""Layouts of the flat float64 arrays that carry run inputs and outputs into the core.

Each block (vehicle truth, thruster table, flight-software design, mission, navigation, summary,
history) is a plain array; these integer offsets name its fields. Numba reads module-level ints
as compile-time constants, so indexing by name costs nothing. ``refexmc.config`` packs the arrays
by the names in each ``Fields`` table, so a field is declared here once.
"""


class Fields:
    """An ordered table of named fields (name -> offset, size) in a flat array."""

    def __init__(self):
        self.size = 0
        self.slices = {}

    def add(self, name, size=1):
        offset = self.size
        self.slices[name] = (offset, size)
        self.size += size
        return offset

    def names(self):
        return list(self.slices)


# --- vehicle truth (dispersible) ------------------------------------------------------------
VEHICLE = Fields()
V_INERTIA = VEHICLE.add("inertia_kg_m2", 9)  # row-major 3x3, body axes about the actual CoM
V_COM_OFFSET = VEHICLE.add("com_offset_m", 3)  # actual CoM minus nominal CoM, body axes
V_MASS = VEHICLE.add("mass_kg")
V_DERATING = VEHICLE.add("derating", 8)  # factor with 1..8 valves open; more: the last
V_ISP = VEHICLE.add("isp_s")
V_PROPELLANT = VEHICLE.add("propellant_kg")
V_AERO_AREA = VEHICLE.add("aero_area_m2")
V_AERO_LENGTH = VEHICLE.add("aero_length_m")
V_MISTRIM = VEHICLE.add("aero_mistrim_cm", 3)  # torque coefficient per body axis
V_DRAG_AREA = VEHICLE.add("drag_area_m2")  # C_D S for the trajectory
V_ENGINE_THRUST = VEHICLE.add("engine_thrust_n")  # main engine, constant thrust (orbit trajectory)
V_ENGINE_ISP = VEHICLE.add("engine_isp_s")
V_ENGINE_PROPELLANT = VEHICLE.add("engine_propellant_kg")
V_ENGINE_DIRECTION = VEHICLE.add("engine_direction", 3)  # true force direction, body axes (misaligned)
V_ENGINE_POSITION = VEHICLE.add("engine_position_m", 3)  # nominal body frame
# cold-gas feed of the rcs (rcs.feed, core.feed, 002 sec. 2-3); unused with the constant feed
V_FEED_MODEL = VEHICLE.add("feed_model_id")  # FEED_*: selects the flight kernel (flight.family)
V_FEED_TANK_VOLUME = VEHICLE.add("feed_tank_volume_m3")
V_FEED_GAS_CONSTANT = VEHICLE.add("feed_gas_constant_j_kg_k")  # specific gas constant R
V_FEED_HEAT_CAPACITY_RATIO = VEHICLE.add("feed_heat_capacity_ratio")  # gamma (in C_F and Gamma below)
V_FEED_TEMPERATURE = VEHICLE.add("feed_temperature_k")  # isothermal tank (002 sec. 2.1)
V_FEED_INITIAL_PRESSURE = VEHICLE.add("feed_initial_pressure_pa")
V_FEED_THROAT_AREA = VEHICLE.add("feed_throat_area_m2")  # per thruster (times its thrust scale)
V_FEED_EXPANSION_RATIO = VEHICLE.add("feed_expansion_ratio")  # epsilon = A_e / A_t
V_FEED_AMBIENT_PRESSURE = VEHICLE.add("feed_ambient_pressure_pa")
V_FEED_THRUST_COEFFICIENT = VEHICLE.add("feed_thrust_coefficient")  # vacuum C_F, 002 eq. 15 (config.feed)
V_FEED_FLOW_FACTOR = VEHICLE.add("feed_flow_factor")  # Gamma of 002 eq. 10 (config.feed)
VEHICLE_SIZE = VEHICLE.size
DERATING_MAX_VALVES = 8

# --- thruster table: one row per thruster ---------------------------------------------------
THRUSTER = Fields()
T_POSITION = THRUSTER.add("position_m", 3)  # nominal body frame (origin at nominal CoM)
T_DIRECTION = THRUSTER.add("direction", 3)  # unit force direction, body axes
T_SCALE = THRUSTER.add("thrust_scale")
T_FAILED = THRUSTER.add("failed")  # 1: never opens, uses no propellant (000 sec. 5)
# 1: the flight software knows the thruster has failed (campaign failures.detected): the LP leaves
# it out of its matrix (allocation.nominal_arms), the allocation table has no entry for it (pack)
T_FAILURE_KNOWN = THRUSTER.add("failure_known")
T_TIME_CONSTANTS = THRUSTER.size  # then per thrust level: on-delay, rise, off-delay, fall (s)
TIME_CONSTANTS_PER_LEVEL = 4
ON_DELAY, RISE, OFF_DELAY, FALL = 0, 1, 2, 3
TIME_CONSTANT_NAMES = ("on_delay", "rise", "off_delay", "fall")


def thruster_size(n_levels):
    """Columns of the thruster table of a vehicle with ``n_levels`` thrust levels."""
    return T_TIME_CONSTANTS + TIME_CONSTANTS_PER_LEVEL * n_levels


def time_constant_column(level, which):
    """Column of time constant ``which`` (ON_DELAY, RISE, OFF_DELAY, FALL) of thrust level ``level``."""
    return T_TIME_CONSTANTS + TIME_CONSTANTS_PER_LEVEL * level + which


# --- thrust levels: one row per level, in the vehicle file's order ----------------------------
LEVEL = Fields()
LV_THRUST = LEVEL.add("thrust_n")  # truth, per thruster before derating and scale (dispersible)
LV_THRUST_DESIGN = LEVEL.add("thrust_design_n")  # what the flight software assumes (nominal)
LV_KP = LEVEL.add("kp", 3)  # flight software: 000 eq. 38 or given
LV_KD = LEVEL.add("kd", 3)  # 000 eq. 34 or given
LV_TORQUE_MAX = LEVEL.add("torque_max_n_m", 3)  # PWPF full scale tau_max (000 eq. 41)
LV_ACCEL_MAX = LEVEL.add("accel_max_rad_s2", 3)  # omega_dot_max (000 eq. 1)
# feed regulated: the chamber pressure the regulator holds at this level, thrust_n / (C_F A_t) (core.feed);
# inf otherwise (blow-down: the tank's pressure)
LV_REGULATOR_PRESSURE = LEVEL.add("regulator_pressure_pa")
LEVEL_SIZE = LEVEL.size

# --- reaction wheels: one row per wheel (001 sec. 4, 8; core.wheels) -------------------------
WHEEL = Fields()
W_AXIS = WHEEL.add("axis", 3)  # unit spin axis, body frame (truth; a column of 001's W)
W_SPIN_INERTIA = WHEEL.add("spin_inertia_kg_m2")  # rotor inertia about its axis
W_TORQUE_MAX = WHEEL.add("torque_max_n_m")  # motor torque limit
W_MOMENTUM_MAX = WHEEL.add("momentum_max_n_m_s")  # |I_w Omega| limit (speed limiter), Omega relative to the body
W_COULOMB = WHEEL.add("coulomb_friction_n_m")  # 001 eq. 1: tau_e
W_VISCOUS = WHEEL.add("viscous_friction_n_m_s")  # 001 eq. 1: tau_v, N m per rad/s
W_COULOMB_WIDTH = WHEEL.add("coulomb_width_rad_s")  # Coulomb friction linear within +-this speed (0: sign)
W_COULOMB_DESIGN = WHEEL.add("coulomb_friction_design_n_m")  # what the flight software assumes (nominal)
W_VISCOUS_DESIGN = WHEEL.add("viscous_friction_design_n_m_s")
W_FAILED = WHEEL.add("failed")  # 1: the motor gives no torque (friction still acts)
W_MOMENTUM0 = WHEEL.add("initial_momentum_n_m_s")  # I_w Omega at t = 0, relative to the body
# flight software: null-space momentum management (core.wheels.null_space_torque), same in every row
W_NULL_SPACE_RATE = WHEEL.add("null_space_rate_1_s")  # 1 / time constant; 0: no management
W_NULL_SPACE_BIAS = WHEEL.add("null_space_bias_n_m_s")  # b_i: the null-space part of I_w Omega - b is driven to 0
W_NULL_SPACE_DEADBAND = WHEEL.add("null_space_deadband_n_m_s")  # no torque while |P (I_w Omega - b)| is within it
W_NULL_SPACE_TORQUE_MAX = WHEEL.add("null_space_torque_max_n_m")  # largest null-space torque on any wheel
W_NULL_SPACE_GIVE_UP = WHEEL.add("null_space_give_up_n_m_s")  # give up, capped and growing this far beyond the deadband
WHEEL_SIZE = WHEEL.size
# The flight software's wheel distribution is a separate (wheels, 3) table (RunInputs.wheel_distribution):
# motor torque commands = -D (u + omega x H_wheels), D = W^+ over the wheels it uses (001 sec. 9.1).

# --- flight software design (derived from the nominal vehicle, never dispersed) -------------
FSW = Fields()
F_CONTROL_PERIOD = FSW.add("control_period_s")
F_INERTIA = FSW.add("inertia_kg_m2", 9)  # the inertia the flight software knows (eq. 30)
F_ACCEL_MARGIN = FSW.add("accel_margin")  # guidance uses this fraction of omega_dot_max (eq. 13)
F_TAU_MIN_FRACTION = FSW.add("tau_min_fraction")  # PWPF deadband tau_min / tau_max (eq. 43)
F_PWPF_ON = FSW.add("pwpf_on_s")  # algorithm t_on (000 sec. 5: 75 ms)
F_PWPF_OFF = FSW.add("pwpf_off_s")  # algorithm t_off (125 ms)
F_PWPF_CORRECTION = FSW.add("pwpf_correction_s")  # delta gamma (50 ms, eq. 47-48)
F_MIN_ON = FSW.add("min_on_s")  # per-thruster hardware minimum pulse (25 ms)
F_MIN_OFF = FSW.add("min_off_s")  # per-thruster hardware minimum rest (175 ms)
F_CONTROLLER = FSW.add("controller_id")
F_ACTUATION = FSW.add("actuation_id")
F_ENGINE_AXIS = FSW.add("engine_axis", 3)  # the main engine's nominal force direction, body axes
F_GUIDANCE_PERIOD = FSW.add("guidance_period_s")  # deorbit burn guidance (004 sec. III: 1 Hz)
F_GUIDANCE_POSITION_GAIN = FSW.add("guidance_position_gain_s2")  # k_r (1/s^2)
F_GUIDANCE_VELOCITY_GAIN = FSW.add("guidance_velocity_gain_s")  # k_v (1/s)
F_GUIDANCE_LAW = FSW.add("guidance_law_id")  # GUIDANCE_LAW_* (core.deorbit.steer)
F_SMC_SLOPE = FSW.add("smc_slope_s", 3)  # 001 eq. 12: Lambda, sliding-surface slope (1/s)
F_SMC_GAIN = FSW.add("smc_gain_rad_s2", 3)  # G (rad/s^2)
F_SMC_LAYER = FSW.add("smc_boundary_layer_rad_s", 3)  # epsilon of sat(sigma, epsilon) (rad/s)
F_WHEEL_FRICTION_COMPENSATION = FSW.add("wheel_friction_compensation")  # 1: motor commands add the design friction
# translation law of translate modes (trajectory local; core.local_flight, core.time_optimal)
F_TRANSLATION_LAW = FSW.add("translation_law_id")  # TRANSLATION_*
F_TRANSLATION_MASKS = FSW.add("translation_masks", 6)  # thruster bit masks pushing +x, -x, +y, -y, +z, -z
F_TRANSLATION_FORCE_PER_PA = FSW.add("translation_force_per_pa", 3)  # n C_F A_t per body axis (N/Pa)
F_TRANSLATION_DRY_MASS = FSW.add("translation_dry_mass_kg")  # mass_kg - P0 V/(R T): mass = this + P V/(R T)
F_TRANSLATION_GAS_PER_PA = FSW.add("translation_gas_per_pa")  # V / (R T) (kg/Pa)
F_TRANSLATION_PD_GAINS = FSW.add("translation_pd_gains", 2)  # pd_pwm: a = -kp e - kd v, kp (1/s^2), kd (1/s)
F_TRANSLATION_PWM_STEPS = FSW.add("translation_pwm_steps")  # pd_pwm: control periods per modulation period
F_TRANSLATION_DEADBAND = FSW.add("translation_deadband", 2)  # |e| (m) and |v| (m/s) per axis within which u = 0
F_TRANSLATION_TAU = FSW.add("translation_tau_s", 3)  # blow-down time constant with the axis's n thrusters open
FSW_SIZE = FSW.size

TRANSLATION_NONE = 0
TRANSLATION_TIME_OPTIMAL = 1  # 002 eq. 44
TRANSLATION_BANG_BANG = 2  # -sign(sigma2), 002 Fig. 8's comparison
TRANSLATION_PD_PWM = 3  # PD on position and velocity, pulse-width modulated over whole control periods

CONTROLLER_PD_FEEDBACK_LINEARISATION = 0  # 000 eq. 30, 35
CONTROLLER_PD = 1  # 004 eq. 1: torque gains, no feedforward
CONTROLLER_SMC = 2  # 001 eq. 12: sliding mode with boundary layer
ACTUATION_PWPF_TABLE = 0  # PWPF per axis (eq. 41-48) + allocation table (Table 3)
ACTUATION_LP_PWM = 1  # LP allocation (004 eq. 2-5) + pulse-width modulation in the control period
ACTUATION_WHEELS = 2  # reaction wheels: RunInputs.wheel_distribution (001 sec. 9.1), held over the period
GUIDANCE_LAW_PD = 0  # deorbit burn: a_nom - k_r dr - k_v dv on the GPS errors (004 sec. III)
GUIDANCE_LAW_OPEN_LOOP_RETROGRADE = 1  # open loop: along -v_gps (004 sec. III "opposite to velocity")
GUIDANCE_LAW_OPEN_LOOP_PLANNED = 2  # open loop: the plan's thrust direction at t (hohmann_direction: fixed)

# --- mission ----------------------------------------------------------------------------------
MISSION = Fields()
M_SEP_ALTITUDE = MISSION.add("initial_altitude_m")
M_SEP_SPEED = MISSION.add("initial_speed_m_s")
M_SEP_FLIGHT_PATH = MISSION.add("initial_flight_path_angle_rad")
M_SEP_RATES = MISSION.add("initial_rates_rad_s", 3)
M_SEP_ATTITUDE = MISSION.add("initial_attitude_rotvec_rad", 3)  # from body x along velocity
M_SUN_DIRECTION = MISSION.add("sun_direction", 3)  # unit vector, inertial frame
M_EARTH_RADIUS = MISSION.add("earth_radius_m")
M_EARTH_MU = MISSION.add("earth_mu_m3_s2")
M_HANDOVER_ANGLE = MISSION.add("attitude_error_end_max_rad")  # after the last mode; inf: no check
M_MAX_TIME = MISSION.add("max_flight_time_s")
M_MAX_STEP = MISSION.add("integrator_max_step_s")
M_TRAJECTORY_STEP = MISSION.add("trajectory_step_s")  # RK4 node spacing, Hermite in between
M_TRAJECTORY_MODEL = MISSION.add("trajectory_model_id")  # TRAJECTORY_*
M_ORBIT_STATE = MISSION.add("orbit_state", 6)  # orbit trajectory: ECI position (m), velocity (m/s) at t = 0
M_EARTH_RATE = MISSION.add("earth_rotation_rate_rad_s")
M_ENTRY_ALTITUDE = MISSION.add("entry_interface_altitude_m")
M_BURN_START = MISSION.add("burn_start_s")  # main engine ignition (the nominal plan's)
M_BURN_DURATION = MISSION.add("burn_duration_s")  # from the bisection on the entry flight-path angle
M_GG_COEFFICIENT = MISSION.add("gravity_gradient_coefficient_s2")  # 001 eq. 11: mu1/r1^3 + mu2/r2^3; 0: none
M_GG_DIRECTION = MISSION.add("gravity_gradient_direction", 3)  # unit, inertial: the line to the attracting bodies
M_CONSTANT_TORQUE = MISSION.add("constant_torque_n_m", 3)  # 001 eq. 10: u_const, body axes
M_POINTING_FROM = MISSION.add("pointing_statistics_from_s")  # pointing RMS/max over t >= this; inf: none
M_LOCAL_POSITION = MISSION.add("local_position_m", 3)  # trajectory local: at t = 0, local frame
M_LOCAL_VELOCITY = MISSION.add("local_velocity_m_s", 3)
M_LOCAL_TARGET = MISSION.add("local_target_m", 3)  # where translate modes go and stop
M_LOCAL_GRAVITY = MISSION.add("local_gravity_m_s2", 3)  # uniform
M_LOCAL_RESERVE = MISSION.add("local_reserve_pressure_pa")  # the tank pressure to keep: x3_min of 002 eq. 42
MISSION_SIZE = MISSION.size

FEED_CONSTANT = 0  # thrust_n until the propellant is gone (core.rcs.segment_thrust)
FEED_BLOW_DOWN = 1  # nozzles on the tank: thrust and flow follow its pressure (002 eq. 13-20; core.feed)
FEED_REGULATED = 2  # constant chamber pressure above the regulator's set pressure, then blow-down

TRAJECTORY_NONE = 0  # attitude only: no altitude, no dynamic pressure, no aerodynamic torque
TRAJECTORY_PLANAR_DRAG = 1  # point mass in the x-z plane, spherical gravity and drag (core.environment)
TRAJECTORY_ORBIT = 2  # point mass in 3D, two-body gravity and a main engine (core.orbit, 004 sec. III)
TRAJECTORY_LOCAL = 3  # position near a small body, uniform gravity, thrust through the attitude (core.local_flight)

# --- mode program: one row per mode, flown in order (refexmc.core.modes) ---------------------
MODE = Fields()
MD_KIND = MODE.add("kind_id")  # guidance kind (modes.KIND_*)
MD_TARGET = MODE.add("target_id")  # target attitude (modes.TARGET_*)
MD_LEVEL = MODE.add("thrust_level")  # index of the thrust level
MD_CALIBRATION = MODE.add("navigation_calibration")  # 1: the attitude bias decays in this mode
MD_TIMEOUT = MODE.add("timeout_s")  # the run fails when the mode lasts longer; inf: never
MD_T1_DESIGN = MODE.add("t1_design_s")  # shortest transition t1,dsgn (000 eq. 14)
MD_ANGLES = MODE.add("aerodynamic_angles_rad", 3)  # alpha, beta, bank of an entry target
MD_QUATERNION = MODE.add("target_quaternion", 4)  # inertial target, scalar last
MD_RATE = MODE.add("rate_rad_s", 3)  # spin-up body rate
MD_PREDICT_ALTITUDE = MODE.add("predicted_at_altitude_m")  # entry target: velocity predicted there
MD_EXIT_FIRST = MODE.add("exit_first_row")  # the mode's rows of the exit table
MD_EXIT_ROWS = MODE.add("exit_rows")
MD_LOCAL_TARGET = MODE.add("local_target_m", 3)  # translate: its target (default the mission's local target)
MODE_SIZE = MODE.size

# --- exit conditions: one row per predicate; a mode ends when every predicate of one of its
# groups holds (OR of ANDs); rows of a mode are contiguous, grouped, cheap predicates first
EXIT = Fields()
E_GROUP = EXIT.add("group")
E_PREDICATE = EXIT.add("predicate_id")  # modes.PREDICATE_*
E_VALUE = EXIT.add("value")  # threshold, SI units
EXIT_SIZE = EXIT.size

# --- navigation errors ------------------------------------------------------------------------
NAV = Fields()
N_ATT_BIAS = NAV.add("attitude_bias_rad", 3)
N_ATT_NOISE = NAV.add("attitude_noise_rad")
N_RATE_BIAS = NAV.add("rate_bias_rad_s", 3)
N_RATE_NOISE = NAV.add("rate_noise_rad_s")
N_CALIBRATION_TIME = NAV.add("ssm_calibration_time_s")  # attitude bias decay in calibrating modes
N_GPS_POSITION_BIAS = NAV.add("gps_position_bias_m", 3)  # ECI axes
N_GPS_POSITION_NOISE = NAV.add("gps_position_noise_m")  # 1 sigma per axis and sample
N_GPS_VELOCITY_BIAS = NAV.add("gps_velocity_bias_m_s", 3)
N_GPS_VELOCITY_NOISE = NAV.add("gps_velocity_noise_m_s")
N_LOCAL_POSITION_NOISE = NAV.add("local_position_noise_m")  # local trajectory: 1 sigma per axis and period
N_LOCAL_VELOCITY_NOISE = NAV.add("local_velocity_noise_m_s")
N_TANK_PRESSURE_NOISE = NAV.add("tank_pressure_noise_pa")  # the translation law's pressure transducer
# first-order Gauss-Markov knowledge error (core.navigation; Farrenkopf, Markley NASA 20000086664):
# per axis x_{k+1} = a x_k + sqrt(1 - a^2) sigma w_k, a = exp(-dt / tau); sigma 0: none (no draws)
N_ATT_GM_SIGMA = NAV.add("attitude_gm_sigma_rad")
N_ATT_GM_TAU = NAV.add("attitude_gm_tau_s")
N_RATE_GM_SIGMA = NAV.add("rate_gm_sigma_rad_s")
N_RATE_GM_TAU = NAV.add("rate_gm_tau_s")
NAV_SIZE = NAV.size

# --- pointing requirements: one row per requirement (core.pointing, config.pointing) ---------
POINTING = Fields()
P_INDEX = POINTING.add("index_id")  # POINTING_INDEX_*: what is computed from e(t)
P_KNOWLEDGE = POINTING.add("knowledge")  # 1: e = estimated - true attitude (AKE, ...); 0: true - reference
P_ERROR = POINTING.add("error_id")  # ERROR_*: what |e| is
P_AXIS = POINTING.add("axis", 3)  # ERROR_AXIS: the unit body axis; ERROR_LOS: the boresight, body axes
P_WINDOW_FROM = POINTING.add("window_from_s")  # the window: from <= t <= to, in a mode of the mask
P_WINDOW_TO = POINTING.add("window_to_s")
P_MODE_MASK = POINTING.add("mode_mask")  # bit m: mode m counts (the mode flown); all bits: any mode
P_DELTA_T = POINTING.add("delta_t_s")  # MPE, RPE, PDE: the averaging interval; inf: the observation period
P_INTERPRETATION = POINTING.add("interpretation_id")  # INTERPRETATION_*
P_PROBABILITY = POINTING.add("p_c")  # the temporal quantile's probability
P_BOUND = POINTING.add("bound_rad")  # mixed: the bound the fraction of time above is counted against
POINTING_SIZE = POINTING.size

POINTING_INDEX_ABSOLUTE = 0  # APE / AKE: |e(t)|
POINTING_INDEX_MEAN = 1  # MPE / MKE: |mean of e over each interval delta_t|
POINTING_INDEX_RELATIVE = 2  # RPE / RKE: |e(t) - mean of e over the interval containing t|
POINTING_INDEX_DRIFT = 3  # PDE / KDE: |difference of consecutive interval means| in one observation period
POINTING_INDEX_REPRODUCIBILITY = 4  # PRE / KRE: |difference of consecutive observation periods' means|
ERROR_TOTAL = 0  # the rotation vector of the error (3-axis angle)
ERROR_AXIS = 1  # its component about one body axis
ERROR_LOS = 2  # the angle between the boresight and where the reference points it
INTERPRETATION_TEMPORAL = 0  # the P_C time quantile of the per-sample values
INTERPRETATION_ENSEMBLE = 1  # their largest
INTERPRETATION_MIXED = 2  # the fraction of them above the bound

# --- nominal deorbit burn: one row per guidance period, ignition to cut-off (core.deorbit) ---
NOMINAL = Fields()
NM_T = NOMINAL.add("t_s")
NM_POSITION = NOMINAL.add("position_m", 3)  # ECI
NM_VELOCITY = NOMINAL.add("velocity_m_s", 3)
NM_THRUST_ACCEL = NOMINAL.add("thrust_accel_m_s2", 3)  # nominal thrust / mass along the nominal direction
NOMINAL_SIZE = NOMINAL.size

# --- why a run failed ------------------------------------------------------------------------
FAIL_NONE = 0
FAIL_MODE_TIMEOUT = 1  # the mode in summary[S_FAILURE_MODE] lasted longer than its timeout
FAIL_PROPELLANT = 2
FAIL_HANDOVER_ANGLE = 3
FAIL_TIME_LIMIT = 4
FAIL_NON_FINITE = 5
FAILURE_NAMES = (
    None,
    "{mode}_timeout",  # with the mode's name, lower case
    "propellant_exhausted",
    "attitude_error_end_above_max",
    "flight_time_limit",
    "non_finite_state",
)

# --- run summary: these fields, then per mode its time and its t1 ------------------------------
SUMMARY = Fields()
S_SUCCESS = SUMMARY.add("success")
S_FAILURE = SUMMARY.add("failure_code")
S_FAILURE_MODE = SUMMARY.add("failure_mode")  # index of the mode a timeout failed
S_FUEL_REMAINING = SUMMARY.add("fuel_remaining")
S_FUEL_USED = SUMMARY.add("fuel_used_kg")
S_T_END = SUMMARY.add("t_end_s")
S_THETA_HANDOVER = SUMMARY.add("attitude_error_end_deg")
S_MODES_COMPLETED = SUMMARY.add("modes_completed")
S_ALTITUDE_END = SUMMARY.add("altitude_end_m")
S_QBAR_END = SUMMARY.add("qbar_end_pa")
S_RK4_STEPS = SUMMARY.add("rk4_steps")
S_HISTORY_ROWS = SUMMARY.add("history_rows")
S_ENTRY = SUMMARY.add("entry_state", 5)  # orbit: longitude, latitude (deg), speed (m/s), fpa, heading (deg)
S_ENTRY_TIME = SUMMARY.add("entry_time_s")
S_BURN_POINTING_RMS = SUMMARY.add("burn_pointing_rms_deg")  # thrust vs commanded direction, engine on
S_BURN_POINTING_MAX = SUMMARY.add("burn_pointing_max_deg")
S_ENGINE_PROPELLANT_USED = SUMMARY.add("engine_propellant_used_kg")
S_POINTING_END = SUMMARY.add("pointing_end_arcsec", 3)  # true attitude vs reference at the end, per body axis
S_POINTING_RMS = SUMMARY.add("pointing_rms_arcsec", 3)  # per axis over t >= pointing_statistics_from_s
S_POINTING_MAX = SUMMARY.add("pointing_max_arcsec")  # largest total angle there
S_WHEEL_MOMENTUM_PEAK = SUMMARY.add("wheel_momentum_peak_n_m_s")  # largest |I_w Omega| of any wheel
S_WHEEL_MOMENTUM_END = SUMMARY.add("wheel_momentum_end_n_m_s")  # largest |I_w Omega| at the end
S_WHEEL_TORQUE_PEAK = SUMMARY.add("wheel_torque_demand_peak_n_m")  # largest motor torque asked for, before limits
S_WHEEL_SATURATED_TIME = SUMMARY.add("wheel_saturated_s")  # time some wheel was held at a torque or momentum limit
S_MOMENTUM_RESIDUAL = SUMMARY.add("angular_momentum_residual")  # |L(T) - L(0) - external impulse| / |L|, inertial
S_LOCAL_POSITION_ERROR = SUMMARY.add("position_error_end_m")  # trajectory local: |position - target| at the end
S_LOCAL_SPEED = SUMMARY.add("speed_end_m_s")
S_TANK_PRESSURE_END = SUMMARY.add("tank_pressure_end_pa")
S_SWITCHES = SUMMARY.add("switches", 3)  # translation command changes per body axis (the first opening counts)
S_PER_MODE = SUMMARY.size  # summary[S_PER_MODE + m]: time in mode m; + n_modes + m: its t1


def summary_size(n_modes):
    """Length of the summary array of a mission with ``n_modes`` modes."""
    return S_PER_MODE + 2 * n_modes


# --- history (one row per sample) ------------------------------------------------------------
HISTORY = Fields()
H_T = HISTORY.add("t_s")
H_MODE = HISTORY.add("mode")
H_THETA_T = HISTORY.add("theta_t_deg")
H_OMEGA_M = HISTORY.add("omega_m_deg_s")
H_THETA_E = HISTORY.add("theta_e_deg", 3)
H_OMEGA_E = HISTORY.add("omega_e_deg_s", 3)
H_FUEL = HISTORY.add("fuel_remaining")
H_VALVES = HISTORY.add("valves_open", 2)  # thrusters producing thrust: mask bits 0-31, then 32-62 (exact)
H_PULSE = HISTORY.add("pulse_command", 3)
H_ALTITUDE = HISTORY.add("altitude_m")  # planar and orbit trajectories
H_QBAR = HISTORY.add("qbar_pa")  # planar trajectory
H_TANK_PRESSURE = HISTORY.add("tank_pressure_pa")  # a blow-down or regulated feed (core.feed)
H_POSITION = HISTORY.add("position_m", 3)  # trajectory local: truth, local frame
H_VELOCITY = HISTORY.add("velocity_m_s", 3)
H_POSITION_ERROR = HISTORY.add("position_error_m")  # |position - the mode's target|, truth
H_SPEED = HISTORY.add("speed_m_s")
H_TRANSLATION_COMMAND = HISTORY.add("translation_command", 3)  # the law's u per body axis: -1, 0, +1
HISTORY_SIZE = HISTORY.size  # then per reaction wheel: HISTORY_PER_WHEEL columns (history_size)
HW_MOMENTUM = 0  # I_w Omega, relative to the body (N m s): what the speed limit bounds
HW_TORQUE = 1  # motor torque held over the control period (N m)
HISTORY_PER_WHEEL = 2


def history_size(n_wheels):
    """Columns of a history row of a vehicle with ``n_wheels`` reaction wheels."""
    return HISTORY_SIZE + HISTORY_PER_WHEEL * n_wheels
