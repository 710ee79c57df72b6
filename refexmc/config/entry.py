"""The entry flight's aerodynamics and surfaces from the vehicle file (issue 24, 003).

:func:`check` holds what the schema cannot express (called by ``load.check_vehicle``): sorted
axes, tables of the axes' shape, the control derivatives of exactly the surfaces the vehicle has,
surfaces only with an atmosphere and tables, a blocked flap within its limits.
:func:`model` packs the arrays ``core.entry.EntryModel`` flies.
"""

import math

import numpy as np

from refexmc import crmath, smallmatrix
from refexmc.config import schema

# The core (numba) is imported only where arrays are packed: validating a file stays numba-free.


def coefficient_slots():
    """Vehicle-file key -> core.aerodynamics slot."""
    from refexmc.core import aerodynamics as aero

    return {
        "lift": aero.AC_LIFT,
        "drag": aero.AC_DRAG,
        "side_force_per_beta_rad": aero.AC_SIDE_BETA,
        "roll_per_beta_rad": aero.AC_ROLL_BETA,
        "pitch": aero.AC_PITCH,
        "yaw_per_beta_rad": aero.AC_YAW_BETA,
        "roll_per_aileron_rad": aero.AC_ROLL_AILERON,
        "pitch_per_elevon_rad": aero.AC_PITCH_ELEVON,
        "yaw_per_aileron_rad": aero.AC_YAW_AILERON,
        "roll_per_rudder_rad": aero.AC_ROLL_RUDDER,
        "yaw_per_rudder_rad": aero.AC_YAW_RUDDER,
    }


def _strictly_increasing(values):
    return all(b > a for a, b in zip(values, values[1:], strict=False))


def check(vehicle, fail):
    """ConfigError (through ``fail(message, *path)``) for an entry description the flight cannot use."""
    tables = vehicle.get("entry_aerodynamics")
    surfaces = vehicle.get("surfaces")
    if tables is not None:
        for axis in ("alpha_deg", "mach"):
            values = tables[axis]
            if not _strictly_increasing(values):
                k = next(i for i in range(1, len(values)) if values[i] <= values[i - 1])
                fail(
                    f"expected a strictly increasing axis, got {values[k - 1]!r} then {values[k]!r}",
                    "entry_aerodynamics",
                    axis,
                    k,
                )
        rows, columns = len(tables["alpha_deg"]), len(tables["mach"])
        for key, table in tables["coefficients"].items():
            if len(table) != rows:
                fail(
                    f"expected {rows} rows (one per alpha_deg), got {len(table)}",
                    "entry_aerodynamics",
                    "coefficients",
                    key,
                )
            for i, row in enumerate(table):
                if len(row) != columns:
                    fail(
                        f"expected {columns} values (one per mach), got {len(row)}",
                        "entry_aerodynamics",
                        "coefficients",
                        key,
                        i,
                    )
    if surfaces is None:
        if "entry_control" in vehicle:
            fail("the entry controller flies aerodynamic surfaces; the vehicle has none ('surfaces')", "entry_control")
        if tables is not None:
            for key in (*schema.ENTRY_FLAP_DERIVATIVES, *schema.ENTRY_RUDDER_DERIVATIVES):
                if key in tables["coefficients"]:
                    fail(
                        f"'{key}' is a control derivative; the vehicle has no surfaces",
                        "entry_aerodynamics",
                        "coefficients",
                        key,
                    )
        return
    if "atmosphere" not in vehicle:
        fail("aerodynamic surfaces need an atmosphere (the vehicle's 'atmosphere')", "surfaces")
    if "entry_control" not in vehicle:
        fail("aerodynamic surfaces need the entry controller's gains (the vehicle's 'entry_control')", "surfaces")
    if tables is None:
        fail("aerodynamic surfaces need the vehicle's 'entry_aerodynamics' tables", "surfaces")
    coefficients = tables["coefficients"]
    for key in schema.ENTRY_FLAP_DERIVATIVES:
        if key not in coefficients:
            fail(f"'{key}' is required: the body flaps' control derivative", "entry_aerodynamics", "coefficients")
    for key in schema.ENTRY_RUDDER_DERIVATIVES:
        if "rudders" in surfaces and key not in coefficients:
            fail(f"'{key}' is required: the rudders' control derivative", "entry_aerodynamics", "coefficients")
        if "rudders" not in surfaces and key in coefficients:
            fail(
                f"'{key}' is a rudder derivative; the vehicle has no rudders (surfaces.rudders)",
                "entry_aerodynamics",
                "coefficients",
                key,
            )
    for name in ("body_flaps", "rudders"):
        limits = surfaces.get(name)
        if limits is not None and limits["min_deg"] >= limits["max_deg"]:
            fail(
                f"expected min_deg < max_deg, got {limits['min_deg']} and {limits['max_deg']}",
                "surfaces",
                name,
                "max_deg",
            )
    flaps = surfaces["body_flaps"]
    if ("hinge_moment_max_n_m" in flaps) != ("hinge_area_arm_m3" in flaps):
        fail("expected both hinge_moment_max_n_m and hinge_area_arm_m3, or neither", "surfaces", "body_flaps")
    if "blocked" in flaps:
        deflection = flaps["blocked"]["deflection_deg"]
        if not flaps["min_deg"] <= deflection <= flaps["max_deg"]:
            fail(
                f"expected a blocked deflection within the flap limits [{flaps['min_deg']}, "
                f"{flaps['max_deg']}] deg, got {deflection}",
                "surfaces",
                "body_flaps",
                "blocked",
                "deflection_deg",
            )


def coefficient_array(tables):
    """``(AERO_COEFFICIENTS, n_alpha, n_mach)`` float64; slots the file leaves out are zero."""
    slots = coefficient_slots()
    out = np.zeros((len(slots), len(tables["alpha_deg"]), len(tables["mach"])))
    for key, table in tables["coefficients"].items():
        out[slots[key]] = np.asarray(table, dtype=float)
    return out


def model(vehicle, radius_m, mu_m3_s2, rotation_rad_s):
    """The ``core.entry.EntryModel`` of ``vehicle`` over a sphere of ``radius_m`` turning at
    ``rotation_rad_s`` with gravitational parameter ``mu_m3_s2``."""
    from refexmc.config.atmosphere import standard_table
    from refexmc.core.entry import EntryModel

    atmospheres = {"ussa1976": standard_table}
    tables = vehicle["entry_aerodynamics"]
    return EntryModel(
        np.array([radius_m, mu_m3_s2, rotation_rad_s], dtype=float),
        atmospheres[vehicle["atmosphere"]](),
        np.array([math.radians(a) for a in tables["alpha_deg"]]),
        np.array(tables["mach"], dtype=float),
        coefficient_array(tables),
        np.array([tables["reference_area_m2"], tables["reference_length_m"]], dtype=float),
    )


MODE_NAMES = ("rcs", "flaps", "flaps_rudders")  # core.entry_flight's modes by HI_MODE (003's mode program)

STANDARD_GRAVITY = 9.80665  # m/s^2, for the specific impulse


def propellant_weights(vehicle):
    """w_i = b_th K_i of 003 eq. 5 (kg/s per N m about body axis i): b_th = 1 / (Isp g0) and K_i
    the least total thrust per N m of moment about axis i that the vehicle's thrusters can give
    (the LP allocation of core.lp_allocation, thrust unbounded), so that the blended allocation
    weighs each axis by what the thrusters really spend on it."""
    from refexmc.config.derived import torque_arms
    from refexmc.core import lp_allocation

    arms = np.ascontiguousarray(torque_arms(vehicle).T)
    n = arms.shape[1]
    u_max = np.full(n, 1e12)
    work = np.zeros(lp_allocation.scratch_shape(n))
    basis = np.zeros(3, dtype=np.int64)
    in_basis = np.zeros(lp_allocation.work_columns(n), dtype=np.bool_)
    u = np.zeros(n)
    weights = np.zeros(3)
    for axis in range(3):
        unit = np.zeros(3)
        unit[axis] = 1.0
        if lp_allocation.allocate(arms, u_max, unit, u, work, basis, in_basis) < 1.0:
            raise ValueError(f"the thrusters cannot give a moment about body axis {'xyz'[axis]}")
        weights[axis] = u.sum() / (vehicle["rcs"]["isp_s"] * STANDARD_GRAVITY)
    return weights


def entry_vehicle(
    vehicle,
    alpha_schedule,
    bank_schedule,
    *,
    blocked=None,
    planet=(6_371_000.0, 3.986004418e14, 7.2921159e-5),
    rcs_only_above_m=90_000.0,
    terminal_mach=2.0,
    floor_altitude_m=15_000.0,
    max_time_s=3_000.0,
    transient_s=30.0,
    rcs_delay_ms=0.0,
    blocked_known=True,
    density_factor=1.0,
    coefficient_factors=None,
    inertia=None,
):
    """``core.entry_flight.EntryVehicle`` for ``vehicle`` (validated) flying the schedules
    ``alpha_schedule`` [(Mach, alpha deg), ...] and ``bank_schedule`` [(speed m/s, bank deg), ...].

    ``blocked``: None or (flap 'left'|'right', deflection deg); default the vehicle file's
    ``surfaces.body_flaps.blocked``. The surfaces' rates and lag, the controller's gains
    (``entry_control``) and the control rate come from the vehicle file; the mode program and the
    terminal condition are keywords (an entry mission's keys: :func:`entry_flight_from_mission`),
    by default 003's mode program (RCS alone above 90 km) and a terminal Mach of 2.

    ``rcs_delay_ms``: the thrusters' moment acts this long after each control instant (below
    the control period; ValueError otherwise).

    Truth against the flight software: ``blocked_known`` False commands the blocked flap as if
    free (it does not move); ``density_factor`` scales the true density, ``coefficient_factors``
    ({vehicle-file coefficient name: factor}) the true coefficients and ``inertia`` (3 x 3 kg m^2)
    is the true inertia, while the flight software keeps the vehicle file's.
    """
    from refexmc.core import entry_flight as ef

    surfaces = vehicle["surfaces"]
    flaps = surfaces["body_flaps"]
    if blocked is None and "blocked" in flaps:
        blocked = (flaps["blocked"]["flap"], flaps["blocked"]["deflection_deg"])
    sf = np.zeros(ef.SURFACE_PARAMETERS)
    sf[ef.SF_FLAP_MIN], sf[ef.SF_FLAP_MAX] = math.radians(flaps["min_deg"]), math.radians(flaps["max_deg"])
    rudders = surfaces.get("rudders")
    if rudders is not None:
        sf[ef.SF_RUDDER_MIN], sf[ef.SF_RUDDER_MAX] = math.radians(rudders["min_deg"]), math.radians(rudders["max_deg"])
        sf[ef.SF_RUDDER_MACH] = rudders["usable_below_mach"]
        sf[ef.SF_HAS_RUDDERS] = 1.0
        sf[ef.SF_RUDDER_RATE] = math.radians(rudders["rate_max_deg_s"])
    sf[ef.SF_FLAP_RATE] = math.radians(flaps["rate_max_deg_s"])
    sf[ef.SF_TIME_CONSTANT] = surfaces["time_constant_s"]
    sf[ef.SF_BLOCKED_FLAP] = -1.0 if blocked is None else {"left": 0.0, "right": 1.0}[blocked[0]]
    sf[ef.SF_BLOCKED_DEFLECTION] = 0.0 if blocked is None else math.radians(blocked[1])
    sf[ef.SF_HINGE_MOMENT_MAX] = flaps.get("hinge_moment_max_n_m", 0.0)
    sf[ef.SF_HINGE_AREA_ARM] = flaps.get("hinge_area_arm_m3", 0.0)
    sf[ef.SF_BLOCKED_KNOWN] = 1.0 if blocked_known else 0.0
    ct = np.zeros(ef.CONTROL_PARAMETERS)
    gains = vehicle["entry_control"]
    ct[ef.CT_PERIOD] = 1.0 / vehicle["flight_software"]["control_rate_hz"]
    ct[ef.CT_RCS_DELAY_S] = rcs_delay_ms / 1000.0
    if not 0.0 <= ct[ef.CT_RCS_DELAY_S] < ct[ef.CT_PERIOD]:
        raise ValueError(
            f"expected an RCS delay in [0, {1000.0 * ct[ef.CT_PERIOD]:g}) ms (the control period), got {rcs_delay_ms:g}"
        )
    ct[ef.CT_ANGLE_GAIN : ef.CT_ANGLE_GAIN + 3] = gains["angle_gain_1_s"]
    ct[ef.CT_RATE_GAIN] = gains["rate_gain_1_s"]
    ct[ef.CT_INTEGRAL_GAIN] = gains["integral_gain_1_s"]
    ct[ef.CT_INTEGRAL_LIMIT : ef.CT_INTEGRAL_LIMIT + 3] = gains["integral_limit_rad_times_s"]
    ct[ef.CT_ALIGN_GAIN] = gains["align_gain_1_s"]
    ct[ef.CT_ALIGN_LIMIT] = math.radians(gains["align_limit_deg"])
    ct[ef.CT_RCS_ONLY_ABOVE_M] = rcs_only_above_m
    ct[ef.CT_TERMINAL_MACH] = terminal_mach
    ct[ef.CT_FLOOR_ALTITUDE_M] = floor_altitude_m
    ct[ef.CT_MAX_TIME_S] = max_time_s
    ct[ef.CT_RCS_CAPACITY : ef.CT_RCS_CAPACITY + 3] = rcs_capacity(vehicle)
    ct[ef.CT_WEIGHTS : ef.CT_WEIGHTS + 3] = propellant_weights(vehicle)
    ct[ef.CT_TRANSIENT_S] = transient_s
    ct[ef.CT_MASS] = vehicle["mass_kg"]
    ct[ef.CT_NOSE_RADIUS_M] = vehicle["entry_aerodynamics"].get("nose_radius_m", 0.0)
    fsw_inertia = np.asarray(vehicle["inertia_kg_m2"], dtype=float)
    inertia = fsw_inertia if inertia is None else np.asarray(inertia, dtype=float)
    alpha = np.array([[m for m, _ in alpha_schedule], [math.radians(a) for _, a in alpha_schedule]])
    bank = np.array([[v for v, _ in bank_schedule], [math.radians(b) for _, b in bank_schedule]])
    nominal = model(vehicle, *planet)
    truth = nominal
    if density_factor != 1.0 or coefficient_factors:
        atmosphere = nominal.atmosphere.copy()
        atmosphere[:, 1] += float(crmath.log(density_factor))  # correctly rounded: any CPU's bits
        coefficients = nominal.coefficients.copy()
        slots = coefficient_slots()
        for key, factor in (coefficient_factors or {}).items():
            coefficients[slots[key]] *= factor
        truth = nominal._replace(atmosphere=atmosphere, coefficients=coefficients)
    return ef.EntryVehicle(truth, inertia, smallmatrix.inverse(inertia), sf, ct, alpha, bank, nominal, fsw_inertia)


def rcs_capacity(vehicle):
    """Largest pure moment about each body axis the thrusters give at their highest level (N m):
    the LP allocation's scale s* for a very large moment (core.lp_allocation)."""
    from refexmc.config.derived import torque_arms
    from refexmc.core import lp_allocation

    arms = np.ascontiguousarray(torque_arms(vehicle).T)
    n = arms.shape[1]
    u_max = np.full(n, max(vehicle["rcs"]["thrust_n"].values()))
    work = np.zeros(lp_allocation.scratch_shape(n))
    basis = np.zeros(3, dtype=np.int64)
    in_basis = np.zeros(lp_allocation.work_columns(n), dtype=np.bool_)
    u = np.zeros(n)
    big = 1e9
    capacity = np.zeros(3)
    for axis in range(3):
        unit = np.zeros(3)
        unit[axis] = big
        capacity[axis] = lp_allocation.allocate(arms, u_max, unit, u, work, basis, in_basis) * big
    return capacity


def entry_flight_from_mission(vehicle, mission, *, blocked=None, **keywords):
    """(``core.entry_flight.EntryVehicle``, initial flight state) of an entry mission
    (``schema.ENTRY_MISSION``, validated) flown by ``vehicle``: its Earth, guidance schedules, mode
    program and terminal condition. ``blocked`` and ``keywords`` as :func:`entry_vehicle` (the
    blocked flap, the truth apart from the flight software's model)."""
    from refexmc.core import entry_attitude
    from refexmc.core import entry_flight as ef

    flight = mission["entry_flight"]
    if blocked is None and "blocked_flap" in flight:
        failure = flight["blocked_flap"]
        blocked = (failure["flap"], failure["deflection_deg"])
        keywords.setdefault("blocked_known", failure["known_to_flight_software"])
    earth = mission["earth"]
    planet = (earth["radius_m"], earth["mu_m3_s2"], earth["rotation_rate_rad_s"])
    flown = entry_vehicle(
        vehicle,
        [(node["mach"], node["alpha_deg"]) for node in flight["alpha_schedule"]],
        [(node["speed_m_s"], node["bank_deg"]) for node in flight["bank_schedule"]],
        blocked=blocked,
        planet=planet,
        rcs_only_above_m=flight["rcs_only_above_m"],
        terminal_mach=flight["terminal_mach"],
        floor_altitude_m=flight["floor_altitude_m"],
        max_time_s=flight["max_time_s"],
        transient_s=flight["transient_s"],
        rcs_delay_ms=flight.get("rcs_delay_ms", 0.0),
        **keywords,
    )
    state = flight["state"]
    initial = np.zeros(ef.FLIGHT_STATE_SIZE)
    initial[: ef.ENTRY_STATE_SIZE] = [
        state["altitude_m"],
        math.radians(state["longitude_deg"]),
        math.radians(state["latitude_deg"]),
        state["speed_m_s"],
        math.radians(state["flight_path_angle_deg"]),
        math.radians(state["heading_deg"]),
    ]
    scratch = np.zeros(entry_attitude.AXES_SCRATCH)
    entry_attitude.attitude_from_angles(
        initial[: ef.ENTRY_STATE_SIZE],
        0.0,
        planet[2],
        math.radians(state["alpha_deg"]),
        0.0,
        math.radians(state["bank_deg"]),
        scratch,
        initial[ef.ENTRY_STATE_SIZE : ef.ENTRY_STATE_SIZE + 4],
    )
    return flown, initial


HINGE_CHECK_QBAR_PA = (10_000.0, 20_000.0, 40_000.0, 80_000.0)  # inspect: the flap's reach at these q
HINGE_CHECK_ALPHA_DEG = 40.0  # 003's hypersonic angle of attack


def design(vehicle):
    """What ``refexmc inspect`` shows of an entry vehicle (one with ``entry_control``): the RCS's
    pure moment per axis, the propellant rate per N m that the blending weighs (003 eq. 5), the
    surfaces' limits and the flap's hinge-limited reach (003 Table 1), and the entry controller."""
    from refexmc.core import entry_flight as ef

    flaps = vehicle["surfaces"]["body_flaps"]
    out = {
        "rcs_capacity_n_m": rcs_capacity(vehicle).tolist(),
        "propellant_kg_s_per_n_m": propellant_weights(vehicle).tolist(),
        "flaps": {key: flaps[key] for key in ("min_deg", "max_deg", "rate_max_deg_s") if key in flaps},
        "time_constant_s": vehicle["surfaces"]["time_constant_s"],
        "control": dict(vehicle["entry_control"]),
        "control_rate_hz": vehicle["flight_software"]["control_rate_hz"],
    }
    if "hinge_moment_max_n_m" in flaps:
        alpha = math.radians(HINGE_CHECK_ALPHA_DEG)
        reach = [
            math.degrees(ef.hinge_limit(q, alpha, flaps["hinge_moment_max_n_m"], flaps["hinge_area_arm_m3"]))
            for q in HINGE_CHECK_QBAR_PA
        ]
        # the hinge moment 2 q S_f c sin^2(alpha + delta) reaches its limit at the largest deflection
        # (or at alpha + delta = 90 deg) from this q on
        worst = min(alpha + math.radians(flaps["max_deg"]), 0.5 * math.pi)
        out["flap_hinge_reach_deg"] = {
            "alpha_deg": HINGE_CHECK_ALPHA_DEG,
            "qbar_pa": list(HINGE_CHECK_QBAR_PA),
            "deflection_deg": [min(r, flaps["max_deg"]) for r in reach],
            "binds_above_qbar_pa": flaps["hinge_moment_max_n_m"]
            / (2.0 * flaps["hinge_area_arm_m3"] * float(crmath.sin(worst) * crmath.sin(worst))),
        }
    if "blocked" in flaps:
        out["flaps"]["blocked"] = dict(flaps["blocked"])
    rudders = vehicle["surfaces"].get("rudders")
    if rudders is not None:
        out["rudders"] = dict(rudders)
    return out
