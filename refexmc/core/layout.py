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
V_THRUST_LOW = VEHICLE.add("thrust_low_n")
V_THRUST_HIGH = VEHICLE.add("thrust_high_n")
V_DERATING = VEHICLE.add("derating", 8)  # factor with 1..8 valves open; more: the last
V_ISP = VEHICLE.add("isp_s")
V_PROPELLANT = VEHICLE.add("propellant_kg")
V_AERO_AREA = VEHICLE.add("aero_area_m2")
V_AERO_LENGTH = VEHICLE.add("aero_length_m")
V_MISTRIM = VEHICLE.add("aero_mistrim_cm", 3)  # torque coefficient per body axis
V_DRAG_AREA = VEHICLE.add("drag_area_m2")  # C_D S for the trajectory
VEHICLE_SIZE = VEHICLE.size
DERATING_MAX_VALVES = 8

# --- thruster table: one row per thruster ---------------------------------------------------
THRUSTER = Fields()
T_POSITION = THRUSTER.add("position_m", 3)  # nominal body frame (origin at nominal CoM)
T_DIRECTION = THRUSTER.add("direction", 3)  # unit force direction, body axes
T_SCALE = THRUSTER.add("thrust_scale")
T_ON_DELAY_LOW = THRUSTER.add("on_delay_low_s")
T_RISE_LOW = THRUSTER.add("rise_low_s")
T_OFF_DELAY_LOW = THRUSTER.add("off_delay_low_s")
T_FALL_LOW = THRUSTER.add("fall_low_s")
T_ON_DELAY_HIGH = THRUSTER.add("on_delay_high_s")
T_RISE_HIGH = THRUSTER.add("rise_high_s")
T_OFF_DELAY_HIGH = THRUSTER.add("off_delay_high_s")
T_FALL_HIGH = THRUSTER.add("fall_high_s")
T_FAILED = THRUSTER.add("failed")  # 1: never opens, uses no propellant (000 sec. 5)
THRUSTER_SIZE = THRUSTER.size
# offset of the time constants of a thrust level: T_ON_DELAY_LOW + 4 * level
TIME_CONSTANTS_PER_LEVEL = 4
ON_DELAY, RISE, OFF_DELAY, FALL = 0, 1, 2, 3

# --- flight software design (derived from the nominal vehicle, never dispersed) -------------
FSW = Fields()
F_CONTROL_PERIOD = FSW.add("control_period_s")
F_INERTIA = FSW.add("inertia_kg_m2", 9)  # the inertia the flight software knows (eq. 30)
F_KP = FSW.add("kp", 6)  # low x,y,z then high x,y,z (000 eq. 38)
F_KD = FSW.add("kd", 6)  # (000 eq. 34)
F_TORQUE_MAX = FSW.add("torque_max_n_m", 6)  # tau_max per axis, low then high (000 eq. 41)
F_ACCEL_MAX = FSW.add("accel_max_rad_s2", 6)  # omega_dot_max, low then high (000 eq. 1-3)
F_ACCEL_MARGIN = FSW.add("accel_margin")  # guidance uses this fraction of omega_dot_max (eq. 13)
F_TAU_MIN_FRACTION = FSW.add("tau_min_fraction")  # PWPF deadband tau_min / tau_max (eq. 43)
F_PWPF_ON = FSW.add("pwpf_on_s")  # algorithm t_on (000 sec. 5: 75 ms)
F_PWPF_OFF = FSW.add("pwpf_off_s")  # algorithm t_off (125 ms)
F_PWPF_CORRECTION = FSW.add("pwpf_correction_s")  # delta gamma (50 ms, eq. 47-48)
F_MIN_ON = FSW.add("min_on_s")  # per-thruster hardware minimum pulse (25 ms)
F_MIN_OFF = FSW.add("min_off_s")  # per-thruster hardware minimum rest (175 ms)
F_CONTROLLER = FSW.add("controller_id")
F_ACTUATION = FSW.add("actuation_id")
FSW_SIZE = FSW.size

CONTROLLER_PD_FEEDBACK_LINEARISATION = 0  # 000 eq. 30, 35
ACTUATION_PWPF_TABLE = 0  # PWPF per axis (eq. 41-48) + allocation table (Table 3)

# --- mission ----------------------------------------------------------------------------------
MISSION = Fields()
M_SEP_ALTITUDE = MISSION.add("separation_altitude_m")
M_SEP_SPEED = MISSION.add("separation_speed_m_s")
M_SEP_FLIGHT_PATH = MISSION.add("separation_flight_path_angle_rad")
M_SEP_RATES = MISSION.add("separation_rates_rad_s", 3)
M_SEP_ATTITUDE = MISSION.add("separation_attitude_rotvec_rad", 3)  # from body x along velocity
M_SUN_DIRECTION = MISSION.add("sun_direction", 3)  # unit vector, inertial frame
M_EARTH_RADIUS = MISSION.add("earth_radius_m")
M_EARTH_MU = MISSION.add("earth_mu_m3_s2")
M_NCM_DURATION = MISSION.add("ncm_duration_s")
M_RDM1_RATE = MISSION.add("rdm1_rate_threshold_rad_s")
M_RDM1_TIMEOUT = MISSION.add("rdm1_timeout_s")
M_SAM_ANGLE = MISSION.add("sam_angle_threshold_rad")
M_SAM_RATE = MISSION.add("sam_rate_threshold_rad_s")
M_SAM_TIMEOUT = MISSION.add("sam_timeout_s")
M_SSM_RATE = MISSION.add("ssm_roll_rate_rad_s")
M_SSM_EXIT_ALTITUDE = MISSION.add("ssm_exit_altitude_m")
M_RDM2_DURATION = MISSION.add("rdm2_duration_s")
M_EAM_ALPHA = MISSION.add("eam_alpha_rad")
M_EAM_BETA = MISSION.add("eam_beta_rad")
M_EAM_BANK = MISSION.add("eam_bank_rad")
M_EAM_T1_DESIGN = MISSION.add("eam_t1_design_s")
M_EAM_EXIT_ALTITUDE = MISSION.add("eam_exit_altitude_m")
M_GEEM_QBAR = MISSION.add("geem_handover_qbar_pa")
M_GEEM_EXIT_ALTITUDE = MISSION.add("geem_exit_altitude_m")
M_HANDOVER_ANGLE = MISSION.add("handover_max_angle_rad")
M_MAX_TIME = MISSION.add("max_flight_time_s")
M_MAX_STEP = MISSION.add("integrator_max_step_s")
M_TRAJECTORY_STEP = MISSION.add("trajectory_step_s")  # RK4 node spacing, Hermite in between
MISSION_SIZE = MISSION.size

# --- navigation errors ------------------------------------------------------------------------
NAV = Fields()
N_ATT_BIAS = NAV.add("attitude_bias_rad", 3)
N_ATT_NOISE = NAV.add("attitude_noise_rad")
N_RATE_BIAS = NAV.add("rate_bias_rad_s", 3)
N_RATE_NOISE = NAV.add("rate_noise_rad_s")
N_CALIBRATION_TIME = NAV.add("ssm_calibration_time_s")  # attitude bias decay in SSM
NAV_SIZE = NAV.size

# --- modes -----------------------------------------------------------------------------------
MODE_NCM, MODE_RDM1, MODE_SAM, MODE_SSM, MODE_RDM2, MODE_EAM, MODE_GEEM, MODE_DONE = range(8)
MODE_NAMES = ("NCM", "RDM1", "SAM", "SSM", "RDM2", "EAM", "GEEM")
N_MODES = 7

# --- why a run failed ------------------------------------------------------------------------
FAIL_NONE = 0
FAIL_RDM1_TIMEOUT = 1
FAIL_SAM_TIMEOUT = 2
FAIL_PROPELLANT = 3
FAIL_HANDOVER_ANGLE = 4
FAIL_TIME_LIMIT = 5
FAIL_NON_FINITE = 6
FAILURE_NAMES = (
    None,
    "rdm1_timeout",
    "sam_timeout",
    "propellant_exhausted",
    "handover_angle_error",
    "flight_time_limit",
    "non_finite_state",
)

# --- run summary -----------------------------------------------------------------------------
SUMMARY = Fields()
S_SUCCESS = SUMMARY.add("success")
S_FAILURE = SUMMARY.add("failure_code")
S_FUEL_REMAINING = SUMMARY.add("fuel_remaining")
S_FUEL_USED = SUMMARY.add("fuel_used_kg")
S_T_END = SUMMARY.add("t_end_s")
S_T_MODE = SUMMARY.add("t_mode_s", N_MODES)
S_T1_MODE = SUMMARY.add("t1_mode_s", N_MODES)  # guidance transition time t1 per mode (0: none)
S_THETA_HANDOVER = SUMMARY.add("theta_t_handover_deg")
S_MODES_COMPLETED = SUMMARY.add("modes_completed")
S_ALTITUDE_END = SUMMARY.add("altitude_end_m")
S_QBAR_END = SUMMARY.add("qbar_end_pa")
S_RK4_STEPS = SUMMARY.add("rk4_steps")
S_HISTORY_ROWS = SUMMARY.add("history_rows")
SUMMARY_SIZE = SUMMARY.size

# --- history (one row per sample) ------------------------------------------------------------
HISTORY = Fields()
H_T = HISTORY.add("t_s")
H_MODE = HISTORY.add("mode")
H_THETA_T = HISTORY.add("theta_t_deg")
H_OMEGA_M = HISTORY.add("omega_m_deg_s")
H_THETA_E = HISTORY.add("theta_e_deg", 3)
H_OMEGA_E = HISTORY.add("omega_e_deg_s", 3)
H_FUEL = HISTORY.add("fuel_remaining")
H_VALVES = HISTORY.add("valves_open")
H_PULSE = HISTORY.add("pulse_command", 3)
H_ALTITUDE = HISTORY.add("altitude_m")
H_QBAR = HISTORY.add("qbar_pa")
HISTORY_SIZE = HISTORY.size
