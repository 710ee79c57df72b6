"""The run loop's scalars (one float64 array) and thruster bit masks (one int64 array).

Shared by the loop (core.flight) and each vehicle family's steps (core.orbit_flight,
core.wheels, core.lp_allocation), so that those import no loop module.
"""

# --- flight status: the loop's scalars, one float64 array ------------------------------------
ST_MODE = 0  # index of the mode flown; n_modes when the program is done
ST_MODE_START = 1  # time the mode began (s)
ST_FAILURE = 2  # layout.FAIL_*
ST_FAILURE_MODE = 3
ST_FUEL = 4  # propellant left (kg)
ST_CALIBRATING = 5  # time spent in calibrating modes (s)
ST_HAS_FINAL = 6  # 1: guidance has a target attitude (Guide.q_final)
ST_MODES_COMPLETED = 7
ST_RK4_STEPS = 8
ST_NODE_INDEX = 9  # trajectory node a is at node_index * trajectory_step_s
ST_STARTED = 10  # 1 once the first mode has started
ST_GUIDANCE_TICK = 11  # orbit: time of the last burn-guidance step
ST_POINTING_SUM2 = 12  # sum of squared pointing errors (rad^2) over control steps with the engine on
ST_POINTING_COUNT = 13
ST_POINTING_MAX = 14
ST_ENTERED = 15  # 1 once the entry interface was crossed
ST_ENGINE_ON = 16  # engine on-time in the coming control period: start, end (s)
ST_ENGINE_OFF = 17
ST_POINTING_WINDOW_SUM2 = 18  # per body axis: sum of squared pointing errors (rad^2) in the pointing window
ST_POINTING_WINDOW_COUNT = 21
ST_POINTING_WINDOW_MAX = 22  # largest total angle there (rad)
ST_WHEEL_MOMENTUM_PEAK = 23  # largest |I_w Omega| of any wheel (N m s)
ST_WHEEL_TORQUE_PEAK = 24  # largest motor torque demand before limits (N m)
ST_WHEEL_SATURATED = 25  # time with a wheel limit acting (s)
STATUS_SIZE = 26
# --- thruster bit masks (bit i for thruster i), one int64 array --------------------------------
MASK_OPEN = 0  # commanded open (switching.enforce)
MASK_ACTIVE = 1  # not closed and settled (rcs.update)
