"""Design quantities derived from the nominal vehicle config, never typed in.

omega_dot_max (000 eq. 1), tau_max, gains (eq. 38, 34), f_min (eq. 44), the allocation table,
what the valve transients make of a pulse (000 sec. 5, Fig. 6, Table 2), and the reaction wheels'
distribution matrix (001 sec. 9.1) with the torque and acceleration it can command per body axis.
"""

import itertools

import numpy as np

from refexmc import crmath, smallmatrix
from refexmc.config import feed as config_feed
from refexmc.config.schema import DEFAULT_TRAJECTORY, WHEELS_LEVEL


def flies_wheels(vehicle):
    """True when the flight software actuates reaction wheels (``flight_software.actuation: wheels``)."""
    return vehicle["flight_software"]["actuation"] == "wheels"


def trajectory_model(vehicle):
    """The vehicle's trajectory model (its ``trajectory`` key, default ``schema.DEFAULT_TRAJECTORY``)."""
    return vehicle.get("trajectory", DEFAULT_TRAJECTORY)


def rcs_level_names(vehicle):
    """The rcs thrust levels, in the order of its ``rcs.thrust_n`` (000: low, high); none without an rcs."""
    return list(vehicle["rcs"]["thrust_n"]) if "rcs" in vehicle else []


def level_names(vehicle):
    """The rows of the levels table, the levels a mode may fly: the rcs thrust levels (000: low,
    high), or the one level ``wheels`` of a vehicle whose flight software actuates reaction wheels."""
    return [WHEELS_LEVEL] if flies_wheels(vehicle) else rcs_level_names(vehicle)


def thruster_count(vehicle):
    """Number of thrusters (0 without an rcs)."""
    return len(vehicle["rcs"]["thrusters"]) if "rcs" in vehicle else 0


def wheel_count(vehicle):
    """Number of reaction wheels (0 without a wheel assembly)."""
    return len(vehicle["wheels"]["units"]) if "wheels" in vehicle else 0


def wheel_axes(vehicle):
    """001's W: 3 x N, column i the unit spin axis of wheel i in body axes (001 sec. 8.1)."""
    axes = np.array([unit["axis"] for unit in vehicle["wheels"]["units"]], dtype=float).reshape(-1, 3)
    return smallmatrix.unit_rows(axes).T


def wheel_distribution(vehicle, excluded=()):
    """The flight software's distribution matrix D (N x 3, wheel torques = D body torque): the
    pseudo-inverse W^+ = W^T (W W^T)^-1 of the wheels it uses (001 sec. 9.1); the rows of the
    ``excluded`` wheels (1-based ids: failures it knows of) are zero. In closed form, not LAPACK's
    SVD (``smallmatrix.pseudo_inverse``): it feeds every run, the same bits on any CPU."""
    w = wheel_axes(vehicle)
    used = [i for i in range(w.shape[1]) if (i + 1) not in set(excluded)]
    out = np.zeros((w.shape[1], 3))
    if used:
        out[used] = smallmatrix.pseudo_inverse(w[:, used])
    return out


def wheel_torque_max(vehicle, excluded=()):
    """Largest body torque per axis the distribution commands with no wheel beyond its torque
    limit: tau_max / max_i |D[i, k]| (N m); 0 about an axis the used wheels cannot reach."""
    distribution = wheel_distribution(vehicle, excluded)
    largest = np.abs(distribution).max(axis=0)
    limit = vehicle["wheels"]["torque_max_n_m"]
    return np.where(largest > 0.0, limit / np.where(largest > 0.0, largest, 1.0), 0.0)


def wheel_accel_max(vehicle, excluded=()):
    """omega_dot_max per body axis of the wheels: :func:`wheel_torque_max` / J_ii (rad/s^2), the
    acceleration the slew guidance plans with (times guidance_accel_margin)."""
    inertia = np.asarray(vehicle["inertia_kg_m2"], dtype=float)
    return wheel_torque_max(vehicle, excluded) / np.diag(inertia)


def wheel_null_space(vehicle):
    """Orthonormal basis (N x (N - 3)) of the wheel torques that make no body torque (001 sec. 8.1:
    n_4), each vector's first clear entry positive (``smallmatrix.null_space``)."""
    return smallmatrix.null_space(wheel_axes(vehicle))


def wheel_problem(vehicle):
    """Why the wheel axes cannot control the attitude (they do not span three dimensions), or None."""
    rank = smallmatrix.rank(wheel_axes(vehicle))
    if rank < 3:
        return f"expected wheel axes that span the three body axes, got rank {rank}"
    return None


def unit_directions(vehicle):
    """Unit force direction of each thruster (n x 3)."""
    return smallmatrix.unit_rows(np.array([t["direction"] for t in vehicle["rcs"]["thrusters"]], dtype=float))


def torque_arms(vehicle):
    """Torque per newton of each thruster about the nominal CoM: r x F / |F| (N m / N)."""
    r = np.array([t["position_m"] for t in vehicle["rcs"]["thrusters"]], dtype=float)
    return np.array([smallmatrix.cross(p, d) for p, d in zip(r, unit_directions(vehicle), strict=True)]).reshape(-1, 3)


def lever_arms(vehicle):
    """l_i of 000 eq. 1: the largest torque arm any thruster has about body axis i (m)."""
    return np.abs(torque_arms(vehicle)).max(axis=0)


def omega_dot_max(vehicle, level):
    """000 eq. 1: l_i n_t,i F_nom / J_ii per body axis (rad/s^2)."""
    inertia = np.asarray(vehicle["inertia_kg_m2"], dtype=float)
    n_t = np.asarray(vehicle["flight_software"]["thrusters_per_axis"], dtype=float)
    thrust = vehicle["rcs"]["thrust_n"][level]
    return lever_arms(vehicle) * n_t * thrust / np.diag(inertia)


def torque_max(vehicle, level):
    """tau_max,i = J_ii omega_dot_max,i (N m), the PWPF full-scale torque (000 eq. 41)."""
    inertia = np.asarray(vehicle["inertia_kg_m2"], dtype=float)
    return np.diag(inertia) * omega_dot_max(vehicle, level)


def gains(vehicle, level):
    """Kp = |tau_min_fraction omega_dot_max / sin(phi_db / 2)| (eq. 38), Kd = 2 zeta sqrt(Kp) (eq. 34)."""
    fsw = vehicle["flight_software"]
    phi_db = np.radians(fsw["deadband_angle_deg"])
    # crmath: numpy's sin is SIMD code chosen per CPU, and the gains feed every run
    kp = np.abs(fsw["pwpf"]["tau_min_fraction"] * omega_dot_max(vehicle, level) / crmath.sin(0.5 * phi_db))
    kd = 2.0 * fsw["damping_ratio"] * np.sqrt(kp)
    return kp, kd


def gains_flown(vehicle, level):
    """(kp, kd) of a level, body x, y, z: given in the vehicle file, else :func:`gains` of an rcs
    level; the wheels level without given gains has none (the smc controller takes its own)."""
    given = vehicle["flight_software"].get("gains")
    if given is not None:
        return np.asarray(given["kp"][level], dtype=float), np.asarray(given["kd"][level], dtype=float)
    if level == WHEELS_LEVEL and flies_wheels(vehicle):
        return np.zeros(3), np.zeros(3)
    return gains(vehicle, level)


def level_torque_max(vehicle, level, excluded_wheels=()):
    """Largest body torque per axis of a level (N m): 000 eq. 41's tau_max of an rcs level, or
    what the wheels' distribution can command (:func:`wheel_torque_max`)."""
    if level == WHEELS_LEVEL and flies_wheels(vehicle):
        return wheel_torque_max(vehicle, excluded_wheels)
    return torque_max(vehicle, level)


def level_accel_max(vehicle, level, excluded_wheels=()):
    """omega_dot_max per body axis of a level (rad/s^2): 000 eq. 1, or :func:`wheel_accel_max`."""
    if level == WHEELS_LEVEL and flies_wheels(vehicle):
        return wheel_accel_max(vehicle, excluded_wheels)
    return omega_dot_max(vehicle, level)


def f_min_fraction(vehicle):
    """f_min / tau_max = t_on / (t_on + t_off) of 000 eq. 44 with the algorithm's t_on, t_off."""
    pwpf = vehicle["flight_software"]["pwpf"]
    return pwpf["t_on_ms"] / (pwpf["t_on_ms"] + pwpf["t_off_ms"])


# inspect warns when the configured PWPF correction is this far from the impulse-matching one
CORRECTION_WARNING_MS = 10.0


def pulse_impulse_ms(width_ms, on_delay, rise, off_delay, fall):
    """Equivalent full-thrust width (ms) of a ``width_ms`` command: the integral of the normalised
    thrust of the valve model (000 Fig. 6; refexmc.core.rcs), zero for on_delay, a linear rise over
    ``rise``; after the close command full for off_delay, then a linear fall over ``fall``. A close
    that takes effect mid-rise falls from the level reached; one before the open reaction cancels it.
    """
    t_open = on_delay
    t_close = width_ms + off_delay
    if t_close <= t_open:
        return 0.0
    peak = 1.0 if rise <= 0.0 else min(1.0, (t_close - t_open) / rise)
    t_peak = t_open + peak * rise
    return 0.5 * peak * peak * (rise + fall) + peak * (t_close - t_peak)


def valve_constants(vehicle, level):
    """(on_delay, rise, off_delay, fall) in ms at a thrust level (000 Table 2)."""
    c = vehicle["rcs"]["valve_time_constants_ms"][level]
    return c["on_delay"], c["rise"], c["off_delay"], c["fall"]


def pulse_equivalent_ms(vehicle, level):
    """Equivalent full-thrust width of the shortest hardware pulse (000 sec. 5: 25 ms)."""
    return pulse_impulse_ms(vehicle["rcs"]["switching_limits_ms"]["min_on"], *valve_constants(vehicle, level))


def pulse_correction_matching_ms(vehicle, level):
    """The correction delta gamma that gives a command the impulse of an ideal pulse of its
    width plus delta gamma (000 sec. 5, eq. 47-48): (off_delay + fall/2) - (on_delay + rise/2),
    the same for any pulse long enough to reach full thrust."""
    on_delay, rise, off_delay, fall = valve_constants(vehicle, level)
    return (off_delay + 0.5 * fall) - (on_delay + 0.5 * rise)


def axis_command_key(w):
    """'+x-y' style key for modulator outputs w in {-1, 0, 1}^3 ('' when all zero)."""
    return "".join(("+" if v > 0 else "-") + axis for v, axis in zip(w, "xyz", strict=True) if v != 0)


def allocation_table(vehicle):
    """27 x N matrix of 0/1: thrusters opened for each (wx, wy, wz), row (wx+1)*9+(wy+1)*3+(wz+1).

    Entries come from the config (000 Table 3). A three-axis command opens the roll-pitch set
    of its x-y entry plus its yaw thrusters (000 sec. 5: yaw has its own thrusters), unless the
    config lists it. Raises KeyError naming a missing single- or two-axis entry.
    """
    n = thruster_count(vehicle)
    table = np.zeros((27, n), dtype=np.int64)
    if "allocation" not in vehicle["flight_software"]:
        return table  # actuation lp_pwm or wheels: no table
    entries = vehicle["flight_software"]["allocation"]
    for w in itertools.product((-1, 0, 1), repeat=3):
        key = axis_command_key(w)
        if not key:
            continue
        if key in entries:
            ids = entries[key]
        elif all(w):
            ids = set(entries[axis_command_key((w[0], w[1], 0))]) | set(entries[axis_command_key((0, 0, w[2]))])
        else:
            raise KeyError(key)
        row = (w[0] + 1) * 9 + (w[1] + 1) * 3 + (w[2] + 1)
        for tid in ids:
            table[row, tid - 1] = 1
    return table


def derating_factor(vehicle, valves_open):
    """Thrust factor of every thruster with ``valves_open`` valves producing thrust (000 sec. 2.1):
    the vehicle's ``rcs.derating`` entry for that count, its last entry beyond the list."""
    derating = vehicle["rcs"]["derating"]
    return float(derating[min(valves_open, len(derating)) - 1]) if valves_open > 0 else 1.0


def entry_torque_per_newton(vehicle, ids):
    """Body torque (N m per N of nominal thrust) of the thrusters ``ids`` (1-based) open together,
    each derated for their number: sum of r x d over them, times the derating factor."""
    arms = torque_arms(vehicle)
    return arms[[i - 1 for i in ids]].sum(axis=0) * derating_factor(vehicle, len(ids))


def allocation_torques(vehicle, level):
    """{axis command: realised body torque (N m)} of each row of the allocation table at a thrust
    level, derating included: what the table's thrusters give when they all fire."""
    thrust = vehicle["rcs"]["thrust_n"][level]
    table = allocation_table(vehicle)
    out = {}
    for w in itertools.product((-1, 0, 1), repeat=3):
        key = axis_command_key(w)
        if key:
            ids = [int(i) + 1 for i in np.flatnonzero(table[(w[0] + 1) * 9 + (w[1] + 1) * 3 + (w[2] + 1)])]
            out[key] = (entry_torque_per_newton(vehicle, ids) * thrust).tolist()
    return out


def effective_thrusters_per_axis(vehicle):
    """{'+x': n, '-x': n, ...}: the thrusters' worth of torque the single-axis entries of the
    allocation table realise about their axis, derated, in units of one thruster at the lever arm
    l_i (000 eq. 1's n_t: ReFEx's '+y' opens 3 valves derated to 0.73, worth 2.19)."""
    arms = lever_arms(vehicle)
    entries = vehicle["flight_software"]["allocation"]
    out = {}
    for axis, name in enumerate("xyz"):
        for sign in "+-":
            ids = entries.get(sign + name, [])
            torque = entry_torque_per_newton(vehicle, ids)[axis] if ids else 0.0
            out[sign + name] = float(abs(torque) / arms[axis]) if arms[axis] > 0.0 else 0.0
    return out


def deadbands(vehicle, level):
    """(rate deadband [rad/s], angle deadband [rad]) per body axis of a thrust level: the largest
    single-axis error the controller answers with less than the PWPF threshold tau_min =
    tau_min_fraction tau_max (000 sec. 5), so no valve fires. At rest with one error alone
    (000 eq. 36-37): pd_feedback_linearisation |J_ii Kd_i omega_e| < tau_min, |J_ii Kp_i sin(phi/2)|
    < tau_min; pd (gains in N m, N m s) the same without J. None where there is no such threshold
    (actuation other than pwpf_table, controller smc)."""
    fsw = vehicle["flight_software"]
    if fsw["actuation"] != "pwpf_table" or fsw["controller"] == "smc":
        return None
    tau_min = fsw["pwpf"]["tau_min_fraction"] * torque_max(vehicle, level)
    kp, kd = gains_flown(vehicle, level)
    scale = np.ones(3) if fsw["controller"] == "pd" else np.diag(np.asarray(vehicle["inertia_kg_m2"], dtype=float))
    with np.errstate(divide="ignore", invalid="ignore"):  # 0 / 0 where a gain and the torque are 0
        rate = np.where(kd > 0.0, tau_min / (scale * kd), np.inf)
        ratio = np.where(kp > 0.0, tau_min / (scale * kp), np.inf)
    angle = np.where(ratio < 1.0, 2.0 * crmath.asin(np.minimum(ratio, 1.0)), np.pi)  # beyond 1: never fires
    return rate, np.where(kp > 0.0, angle, np.inf)  # inf: no gain, the error is never acted on


def minimum_impulse_bit(vehicle, level):
    """(impulse [N m s], rate change [rad/s]) per body axis of the shortest hardware pulse
    (switching_limits_ms.min_on, at least one control period) of the '+' single-axis entry at a
    thrust level: its realised torque about the axis times the pulse's full-thrust width through
    the valve transients (:func:`pulse_impulse_ms`), and that over J_ii."""
    period_ms = 1e3 / vehicle["flight_software"]["control_rate_hz"]
    width_ms = max(vehicle["rcs"]["switching_limits_ms"]["min_on"], period_ms)
    full_ms = pulse_impulse_ms(width_ms, *valve_constants(vehicle, level))
    thrust = vehicle["rcs"]["thrust_n"][level]
    entries = vehicle["flight_software"]["allocation"]
    impulse = np.array(
        [abs(entry_torque_per_newton(vehicle, entries.get("+" + a, []))[k]) * thrust for k, a in enumerate("xyz")]
    ) * (full_ms / 1e3)
    return impulse, impulse / np.diag(np.asarray(vehicle["inertia_kg_m2"], dtype=float))


def design(vehicle):
    """Everything ``refexmc inspect`` shows, as plain Python types."""
    fsw = vehicle["flight_software"]
    out = {
        "controller": fsw["controller"],
        "actuation": fsw["actuation"],
        "levels": level_names(vehicle),
        "omega_dot_max_rad_s2": {},
        "torque_max_n_m": {},
        "gains": {},
    }
    if fsw["controller"] == "smc":
        out["gains_source"] = "smc (001 eq. 12)"
        out["smc"] = {key: list(value) for key, value in fsw["smc"].items()}
    else:
        out["gains_source"] = "given" if "gains" in fsw else "derived (000 eq. 38, 34)"
    for level in level_names(vehicle):
        out["omega_dot_max_rad_s2"][level] = level_accel_max(vehicle, level).tolist()
        out["torque_max_n_m"][level] = level_torque_max(vehicle, level).tolist()
        kp, kd = gains_flown(vehicle, level)
        out["gains"][level] = {"kp": kp.tolist(), "kd": kd.tolist()}
    if "wheels" in vehicle:
        out["wheels"] = _wheel_design(vehicle)
    if "translation" in fsw:
        out["translation"] = _translation_design(vehicle)
        # a hop's vehicle: no torque to control (gains all zero), the translation law drives the valves
        out["attitude_controlled"] = any(any(out["gains"][level][k]) for level in out["gains"] for k in ("kp", "kd"))
    if "rcs" in vehicle:
        out.update(_rcs_design(vehicle))
        feed = vehicle["rcs"].get("feed", {})
        if feed.get("model", "constant") != "constant":
            out["feed"] = {"model": feed["model"], **config_feed.design(feed)}
            if feed["model"] == "regulated":
                out["feed"]["set_pressure_pa"] = {
                    level: config_feed.set_pressure(vehicle, level) for level in vehicle["rcs"]["thrust_n"]
                }
    return out


def translation_design(vehicle):
    """Per body axis: the thruster bit masks pushing + and - (unit direction within 1e-6 of the
    axis), and for the + set the law's constants (core.time_optimal.scale): force per pascal
    n C_F A_t and blow-down time constant tau / n, n thrusters open (vacuum, nominal); the
    acceleration per pascal at t = 0 is the force per pascal over mass_kg."""
    design = config_feed.design(vehicle["rcs"]["feed"])
    directions = unit_directions(vehicle)
    masks, accel, tau = [], [], []
    for axis in range(3):
        counts = []
        for sense in (1.0, -1.0):
            ids = [i for i, d in enumerate(directions) if abs(d[axis] - sense) < 1e-6]
            masks.append(sum(1 << i for i in ids))
            counts.append(len(ids))
        n = counts[0]
        accel.append(n * design["thrust_coefficient"] * vehicle["rcs"]["feed"]["throat_area_m2"])
        tau.append(design["blow_down_time_constant_s"] / n if n else 0.0)
    return masks, accel, tau


def _translation_design(vehicle):
    """The translation law of translate modes (trajectory local; 002 sec. 4, config.pack): per body
    axis the thrusters pushing + and -, n C_F A_t, the blow-down time constant with the + set open
    and the acceleration at the initial tank pressure (vacuum, nominal mass)."""
    law = vehicle["flight_software"]["translation"]
    masks, force_per_pa, tau = translation_design(vehicle)
    pressure0 = vehicle["rcs"]["feed"]["initial_pressure_pa"]
    out = {
        "law": law["law"],
        "deadband_position_m": law.get("deadband_position_m", 0.0),
        "deadband_speed_m_s": law.get("deadband_speed_m_s", 0.0),
        "thrusters": [
            {sense: [i + 1 for i in range(64) if (masks[2 * axis + k] >> i) & 1] for k, sense in enumerate("+-")}
            for axis in range(3)
        ],
        "force_per_pa_n_pa": list(force_per_pa),
        "time_constant_s": list(tau),
        "initial_accel_m_s2": [f * pressure0 / vehicle["mass_kg"] for f in force_per_pa],
    }
    if law["law"] == "pd_pwm":
        for key in ("position_gain_s2", "velocity_gain_s", "pwm_period_s"):
            if key in law:
                out[key] = law[key]
    return out


def _wheel_design(vehicle):
    wheels = vehicle["wheels"]
    return {
        "distribution": wheels["distribution"],
        "axes": wheel_axes(vehicle).T.tolist(),
        "distribution_matrix": wheel_distribution(vehicle).tolist(),
        "null_space": wheel_null_space(vehicle).tolist(),
        "torque_max_n_m": wheel_torque_max(vehicle).tolist(),
        "accel_max_rad_s2": wheel_accel_max(vehicle).tolist(),
        "wheel_torque_max_n_m": wheels["torque_max_n_m"],
        "wheel_momentum_max_n_m_s": wheels["momentum_max_n_m_s"],
        "speed_max_rpm": wheels["momentum_max_n_m_s"] / wheels["spin_inertia_kg_m2"] * 30.0 / np.pi,
        "null_space_management": wheels.get("null_space_management"),  # None: off
    }


def _finite(values):
    """A list for JSON: None where a value is not finite (a deadband without a gain)."""
    return [float(v) if np.isfinite(v) else None for v in values]


def _rcs_design(vehicle):
    """The thruster design (000): lever arms, omega_dot_max and gains per thrust level, PWPF, switching
    limits, the allocation table."""
    fsw = vehicle["flight_software"]
    out = {
        "lever_arms_m": lever_arms(vehicle).tolist(),
        "thrusters_per_axis": list(fsw["thrusters_per_axis"]),
        "rcs_levels": rcs_level_names(vehicle),
        "pulse_equivalent_ms": {},
        "pulse_correction_matching_ms": {},
    }
    for level in rcs_level_names(vehicle):
        out["pulse_equivalent_ms"][level] = pulse_equivalent_ms(vehicle, level)
        out["pulse_correction_matching_ms"][level] = pulse_correction_matching_ms(vehicle, level)
        if flies_wheels(vehicle):  # the thrusters are not flown; their design is still shown
            out.setdefault("rcs_omega_dot_max_rad_s2", {})[level] = omega_dot_max(vehicle, level).tolist()
    if deadbands(vehicle, rcs_level_names(vehicle)[0]) is not None:
        out["deadbands"], out["minimum_impulse_bit"] = {}, {}
        for level in rcs_level_names(vehicle):
            rate, angle = deadbands(vehicle, level)
            out["deadbands"][level] = {"rate_deg_s": _finite(np.degrees(rate)), "angle_deg": _finite(np.degrees(angle))}
            impulse, rate_change = minimum_impulse_bit(vehicle, level)
            out["minimum_impulse_bit"][level] = {
                "n_m_s": impulse.tolist(),
                "rate_deg_s": np.degrees(rate_change).tolist(),
            }
    pwpf = fsw["pwpf"]
    limits = vehicle["rcs"]["switching_limits_ms"]
    out["f_min_fraction"] = f_min_fraction(vehicle)
    out["tau_min_fraction"] = pwpf["tau_min_fraction"]
    out["pwpf_t_on_ms"] = pwpf["t_on_ms"]
    out["pwpf_t_off_ms"] = pwpf["t_off_ms"]
    out["pwpf_correction_ms"] = pwpf["correction_ms"]
    out["hardware_min_on_ms"] = limits["min_on"]
    out["hardware_min_off_ms"] = limits["min_off"]
    if "allocation" not in fsw:
        return out
    table = allocation_table(vehicle)
    out["allocation"] = {}
    combos = sorted(
        itertools.product((-1, 0, 1), repeat=3), key=lambda w: (sum(map(abs, w)), [-abs(v) for v in w], [-v for v in w])
    )
    for w in combos:
        key = axis_command_key(w)
        if key:
            row = (w[0] + 1) * 9 + (w[1] + 1) * 3 + (w[2] + 1)
            out["allocation"][key] = [int(i) + 1 for i in np.flatnonzero(table[row])]
    out["allocation_torque_n_m"] = {level: allocation_torques(vehicle, level) for level in rcs_level_names(vehicle)}
    return out


def _inertia_checks(tensors):
    """(symmetric, eigenvalues ascending) of each tensor of an n x 3 x 3 stack; a tensor that is not
    symmetric (or not finite) gets the identity's eigenvalues (they are not looked at)."""
    j = np.asarray(tensors, dtype=float)
    finite = np.isfinite(j).all(axis=(1, 2))  # NaN or infinite entries: reported as not symmetric
    j = np.where(finite[:, None, None], j, np.eye(3))
    atol = 1e-9 * np.maximum(1.0, np.abs(j).max(axis=(1, 2)))
    symmetric = finite & np.isclose(j, np.swapaxes(j, 1, 2), rtol=0.0, atol=atol[:, None, None]).all(axis=(1, 2))
    tensors = np.where(symmetric[:, None, None], j, np.eye(3))
    tensors = np.tril(tensors) + np.swapaxes(np.tril(tensors, -1), 1, 2)  # the lower triangle, as eigvalsh
    # Jacobi, not LAPACK's eigvalsh: the verdict decides a campaign's redraws, the same on any CPU
    return symmetric, smallmatrix.symmetric_eigenvalues(tensors)


def _triangle_violated(eig):
    return eig[..., 0] + eig[..., 1] < eig[..., 2] * (1.0 - 1e-12)


def inertia_problem(inertia):
    """Why an inertia tensor is not physical, or None."""
    symmetric, eig = _inertia_checks(np.asarray(inertia, dtype=float)[np.newaxis])
    if not symmetric[0]:
        return "expected a symmetric inertia tensor"
    if eig[0].min() <= 0.0:
        return f"expected a positive definite inertia tensor, eigenvalues {eig[0].round(6).tolist()}"
    if _triangle_violated(eig[0]):
        return f"principal moments {eig[0].round(6).tolist()} violate the triangle inequality"
    return None


def unphysical_inertias(tensors):
    """Whether each tensor of an n x 3 x 3 stack is not physical: :func:`inertia_problem` is not
    None for it (the same checks, batched: a campaign's draws are checked a chunk at a time)."""
    symmetric, eig = _inertia_checks(tensors)
    return ~symmetric | (eig.min(axis=1) <= 0.0) | _triangle_violated(eig)


def allocate_torque(vehicle, torque, level=None):
    """What fires for a body torque (N m): per-thruster thrust (N) and the torque it realises.

    ``lp_pwm``: the LP allocation of the flight software (core.lp_allocation, 004 eq. 2-5), each
    thruster limited to the level's thrust; ``pwpf_table``: the allocation table's row for the
    signs of the torque's components, its thrusters at the level's full thrust derated for their
    number (what the table opens when the PWPF commands every axis the torque has; ``derating``:
    the factor, 1 for the LP).
    """
    from refexmc.core import lp_allocation

    if flies_wheels(vehicle):
        return _distribute_torque(vehicle, torque)
    level = level or level_names(vehicle)[0]
    thrust = vehicle["rcs"]["thrust_n"][level]
    arms = torque_arms(vehicle)  # n x 3, N m per N
    n = arms.shape[0]
    torque = np.asarray(torque, dtype=float)
    method = vehicle["flight_software"]["actuation"]
    share = None
    factor = 1.0
    if method == "lp_pwm":
        u = np.zeros(n)
        work = np.zeros(lp_allocation.scratch_shape(n))
        basis, in_basis = np.zeros(3, dtype=np.int64), np.zeros(lp_allocation.work_columns(n), dtype=np.bool_)
        share = lp_allocation.allocate(
            np.ascontiguousarray(arms.T), np.full(n, thrust), torque, u, work, basis, in_basis
        )
    else:
        signs = tuple(int(v) for v in np.sign(torque))
        row = (signs[0] + 1) * 9 + (signs[1] + 1) * 3 + (signs[2] + 1)
        opened = allocation_table(vehicle)[row]
        factor = derating_factor(vehicle, int(opened.sum()))  # every open valve derated (000 sec. 2.1)
        u = opened * float(thrust) * factor
    return {
        "allocation": {
            "method": "lp" if method == "lp_pwm" else "table",
            "level": level,
            "torque_n_m": torque.tolist(),
            "commands": u.tolist(),
            "realised_torque_n_m": smallmatrix.matmul(arms.T, u).tolist(),
            "attained_share": share,
            "derating": factor,
        },
        "thrusters": [
            {"position_m": list(t["position_m"]), "direction": d.tolist(), "max_thrust_n": thrust}
            for t, d in zip(vehicle["rcs"]["thrusters"], unit_directions(vehicle), strict=True)
        ],
    }


def _distribute_torque(vehicle, torque):
    """The wheels' share of a body torque (N m): motor torque commands -D torque (each wheel's
    torque on its rotor, the body taking the reaction; 001 sec. 9.1, the gyroscopic term left
    out), each limited to the wheels' torque limit, and the body torque that realises."""
    torque = np.asarray(torque, dtype=float)
    limit = vehicle["wheels"]["torque_max_n_m"]
    commands = -smallmatrix.matmul(wheel_distribution(vehicle), torque)
    limited = np.clip(commands, -limit, limit)
    return {
        "allocation": {
            "method": vehicle["wheels"]["distribution"],
            "level": WHEELS_LEVEL,
            "torque_n_m": torque.tolist(),
            "commands": commands.tolist(),
            "limited_commands": limited.tolist(),
            "realised_torque_n_m": (-smallmatrix.matmul(wheel_axes(vehicle), limited)).tolist(),
        },
        "wheels": [
            {"axis": axis.tolist(), "max_torque_n_m": limit, "name": unit.get("name")}
            for axis, unit in zip(wheel_axes(vehicle).T, vehicle["wheels"]["units"], strict=True)
        ],
    }


def gravity_gradient_coefficient(bodies):
    """sum mu_k / r_k^3 over the bodies (1/s^2) of 001 eq. 11 (the Sun and the Earth seen from L2)."""
    total = 0.0
    for body in bodies:
        r = body["distance_m"]
        total += body["mu_m3_s2"] / (r * r * r)  # not r ** 3: glibc's pow, whose variant depends on the CPU
    return float(total)


def initial_rotation_vector(initial):
    """The initial attitude's rotation vector (rad): ``attitude_error_deg``, or the rotation of
    ``attitude_euler_deg`` in ``euler_sequence`` (:func:`euler_quaternion`, as the inertial target). Both are
    from body x along the velocity, wings level (no trajectory: from the inertial axes)."""
    if "attitude_euler_deg" not in initial:
        return np.radians(initial["attitude_rotvec_deg"])
    return rotation_vector(euler_quaternion(initial["euler_sequence"], initial["attitude_euler_deg"]))


def euler_quaternion(sequence, angles_deg):
    """The unit quaternion (scalar last) of Euler angles ``angles_deg`` about the axes of
    ``sequence`` ('xyz': extrinsic, fixed axes; 'XYZ': intrinsic, moving axes), as scipy's
    ``Rotation.from_euler(sequence, angles, degrees=True).as_quat()`` composes it, with correctly
    rounded sin and cos and the products in a fixed order: it feeds runs, so no libm (the same
    bits on every CPU; tests/test_derived.py compares with scipy)."""
    intrinsic = sequence.isupper()
    quaternion = None
    for axis, angle in zip(sequence.lower(), np.radians(np.asarray(angles_deg, dtype=float)), strict=True):
        elementary = np.zeros(4)
        half = 0.5 * float(angle)
        elementary["xyz".index(axis)] = float(crmath.sin(half))
        elementary[3] = float(crmath.cos(half))
        if quaternion is None:
            quaternion = elementary
        elif intrinsic:
            quaternion = _compose(quaternion, elementary)
        else:
            quaternion = _compose(elementary, quaternion)
    return quaternion


def _compose(p, q):
    """The quaternion product p q (scalar last), in scipy's order of operations."""
    cross = smallmatrix.cross(p[:3], q[:3])
    vector = [p[3] * q[i] + q[3] * p[i] + cross[i] for i in range(3)]
    return np.array([*vector, p[3] * q[3] - (p[0] * q[0] + p[1] * q[1] + p[2] * q[2])])


def rotation_vector(quaternion):
    """The rotation vector (rad) of a unit quaternion (scalar last), the shorter way round, as
    scipy's ``as_rotvec`` computes it, with correctly rounded atan2 and sin."""
    q = -np.asarray(quaternion, dtype=float) if quaternion[3] < 0.0 else np.asarray(quaternion, dtype=float)
    angle = 2.0 * float(crmath.atan2(smallmatrix.norm(q[:3]), q[3]))
    if angle <= 1e-3:  # angle / sin(angle / 2) by its series (scipy's threshold and terms)
        angle2 = angle * angle
        scale = 2.0 + angle2 / 12.0 + 7.0 * angle2 * angle2 / 2880.0
    else:
        scale = angle / float(crmath.sin(0.5 * angle))
    return scale * q[:3]


def rotate_by_rotation_vector(vector, rotvec_deg):
    """``vector`` rotated by the rotation vector ``rotvec_deg`` (deg; Rodrigues' formula); it
    feeds runs (an engine's misalignment, drawn per run): no BLAS, correctly rounded sin and cos."""
    v = np.asarray(vector, dtype=float)
    r = np.radians(np.asarray(rotvec_deg, dtype=float))
    angle = smallmatrix.norm(r)
    if angle == 0.0:
        return v.copy()
    k = r / angle
    cos, sin = float(crmath.cos(angle)), float(crmath.sin(angle))
    return v * cos + smallmatrix.cross(k, v) * sin + k * (smallmatrix.dot(k, v) * (1.0 - cos))


def engine_direction(engine, misalignment_deg=(0.0, 0.0, 0.0)):
    """The main engine's unit force direction in body axes, turned by a misalignment rotation vector."""
    direction = np.asarray(engine["direction"], dtype=float)
    return rotate_by_rotation_vector(smallmatrix.unit(direction), misalignment_deg)


def burn_start_attitude(vehicle, plan):
    """Inertial attitude (quaternion, scalar last) that points the main engine's nominal axis
    along the nominal thrust at ignition (``core.deorbit.thrust_attitude``): the ``burn_start`` target."""
    from refexmc.core import deorbit
    from refexmc.core import layout as L

    row = plan.table[0]
    accel = row[L.NM_THRUST_ACCEL : L.NM_THRUST_ACCEL + 3]
    q = np.zeros(4)
    deorbit.thrust_attitude(
        smallmatrix.unit(accel),
        row[L.NM_POSITION : L.NM_POSITION + 3].copy(),
        row[L.NM_VELOCITY : L.NM_VELOCITY + 3].copy(),
        engine_direction(vehicle["main_engine"]),
        q,
        np.zeros((9, 3)),
    )
    return q
