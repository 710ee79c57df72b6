"""Slow, obvious twins of the numba kernels, written from 000 and the reference model.

Each function here is plain Python, readable next to the equation it cites, and shares no code
with ``refexmc.core``. The unit tests compare the kernels with them.
"""

import itertools
import math
from dataclasses import dataclass

import numpy as np
import scipy.linalg
from numpy.polynomial import Polynomial
from scipy.spatial.transform import Rotation

# --------------------------------------------------------------------------------------------
# Pulse-width pulse-frequency modulation, 000 eq. 41-48
# --------------------------------------------------------------------------------------------


def pwpf_shaped_command(tau_c, tau_max, tau_min):
    """f(tau_c) of 000 eq. 43."""
    if abs(tau_c) > tau_max:
        return math.copysign(tau_max, tau_c)
    if abs(tau_c) >= tau_min:
        return tau_c
    return 0.0


def pwpf_f_min(tau_max, t_on, t_off):
    """f_min of 000 eq. 44."""
    return tau_max * t_on / (t_on + t_off)


def pwpf_pulse(f_abs, tau_max, t_on, t_off):
    """(gamma_k, T_k) of 000 eq. 45-46; gamma = T = inf at saturation (|f| = tau_max)."""
    if f_abs >= tau_max:
        return math.inf, math.inf
    if f_abs >= pwpf_f_min(tau_max, t_on, t_off):
        gamma = t_off * f_abs / (tau_max - f_abs)
    else:
        gamma = t_on
    return gamma, tau_max * gamma / f_abs


# Time comparisons as in exact arithmetic: times are step * dt in float64, so a difference of
# two of them is off the ideal value by ~1e-15 s; 1 ns is far below any control period. A pulse
# (rest) lasts while less than its duration has passed: on the sample grid it is at least as long
# as eq. 47 (48) asks, and exactly that long when the duration is a whole number of samples.
TIME_EPS = 1e-9


class NaivePWPF:
    """One axis of the Kienitz-Bals modulator with the delay correction (000 eq. 47-48).

    ``t_s_on`` / ``t_s_off`` are the times of the last pulse start / end (None: never). At
    saturation eq. 45 gives an endless pulse, started after the limiting rest t_off + delta gamma. Eq. 47-48
    keep w while less than gamma - delta gamma (T - gamma + delta gamma) has passed, compared as in
    exact arithmetic (``TIME_EPS``).
    """

    def __init__(self, tau_max, tau_min_fraction, t_on, t_off, correction):
        self.tau_max = tau_max
        self.tau_min = tau_min_fraction * tau_max
        self.t_on = t_on
        self.t_off = t_off
        self.correction = correction
        self.t_s_on = None
        self.t_s_off = None
        self.firing = False

    def step(self, t, tau_c):
        f = pwpf_shaped_command(tau_c, self.tau_max, self.tau_min)
        if f == 0.0:
            w = 0
        else:
            sign = 1 if f > 0 else -1
            gamma, period = pwpf_pulse(abs(f), self.tau_max, self.t_on, self.t_off)
            if math.isinf(gamma):  # limit |f| -> tau_max: endless pulse after a rest of t_off + delta gamma
                if self.firing or self.t_s_off is None:
                    w = sign
                else:
                    w = 0 if t - self.t_s_off < self.t_off + self.correction - TIME_EPS else sign
            elif self.firing:  # eq. 47
                w = sign if t - self.t_s_on < gamma - self.correction - TIME_EPS else 0
            elif self.t_s_off is None:  # never fired: nothing to rest from
                w = sign
            else:  # eq. 48
                w = 0 if t - self.t_s_off < period - (gamma - self.correction) - TIME_EPS else sign
        if self.firing and w == 0:
            self.firing = False
            self.t_s_off = t
        elif not self.firing and w != 0:
            self.firing = True
            self.t_s_on = t
        return w


# --------------------------------------------------------------------------------------------
# Allocation rule, 000 sec. 5 (the text that Table 3 tabulates)
# --------------------------------------------------------------------------------------------

ROLL_SET = {+1: {2, 3}, -1: {1, 4}}  # thrusters 1 and 4, 2 and 3 fire together for roll
PITCH_SET = {+1: {1, 2, 7}, -1: {3, 4, 8}}  # a pure pitch torque uses three thrusters
PITCH_ONLY = {+1: 7, -1: 8}  # the dedicated pitch thrusters
YAW_SET = {+1: {6}, -1: {5}}  # yaw only from 5 and 6


def allocate(wx, wy, wz):
    """Thruster ids (1-based) for modulator outputs, by the rule of 000 sec. 5.

    Roll and pitch together: the roll pair plus the dedicated pitch thruster (the pitch-set
    thrusters that would counteract the roll pair are left out). Yaw adds its own thruster.
    """
    ids = set()
    if wx and wy:
        ids |= ROLL_SET[wx] | {PITCH_ONLY[wy]}
    elif wx:
        ids |= ROLL_SET[wx]
    elif wy:
        ids |= PITCH_SET[wy]
    if wz:
        ids |= YAW_SET[wz]
    return ids


# --------------------------------------------------------------------------------------------
# Guidance polynomials, 000 eq. 7-9, 17-18, 22-27 (derivatives by polynomial differentiation)
# --------------------------------------------------------------------------------------------


def quintic_polynomial(t1):
    """h(t) of 000 eq. 7 as a Polynomial in t."""
    return Polynomial([0.0, 0.0, 0.0, 10.0 / t1**3, -15.0 / t1**4, 6.0 / t1**5])


def quintic(t, t1):
    """(h, h', h'') at ``t``; the final state (1, 0, 0) is held for t > t1 (000 sec. 3.1)."""
    if t >= t1:
        return 1.0, 0.0, 0.0
    p = quintic_polynomial(t1)
    return p(t), p.deriv(1)(t), p.deriv(2)(t)


def cubic_rate_polynomial(t1):
    """Rate factor of 000 eq. 17: omega(t) = factor(t) * omega_0."""
    return Polynomial([1.0, 0.0, -3.0 / t1**2, 2.0 / t1**3])


def cubic_rate(t, t1):
    """(factor, factor') of 000 eq. 17-18; (0, 0) after t1."""
    if t >= t1:
        return 0.0, 0.0
    p = cubic_rate_polynomial(t1)
    return p(t), p.deriv(1)(t)


def quartic_angle_polynomial(t1):
    """Angle factor of 000 eq. 22: phi(t) = factor(t) * omega_1."""
    return Polynomial([0.0, 0.0, 0.0, 1.0 / t1**2, -0.5 / t1**3])


def quartic_spin_up(t, t1):
    """(angle, rate, accel) factors of 000 eq. 22-24, continued by eq. 25-27 after t1."""
    p = quartic_angle_polynomial(t1)
    if t > t1:
        return p(t1) + (t - t1), 1.0, 0.0
    return p(t), p.deriv(1)(t), p.deriv(2)(t)


# --------------------------------------------------------------------------------------------
# Per-thruster switching check, 000 sec. 5
# --------------------------------------------------------------------------------------------


class NaiveSwitching:
    """Each valve keeps a state for at least its hardware minimum (``min_on`` open, ``min_off``
    closed) and follows the wanted state as soon as that minimum has passed (000 sec. 5).
    ``slack`` absorbs the roundoff of times computed as step * dt."""

    def __init__(self, n, min_on, min_off, slack=1e-9):
        self.is_open = [False] * n
        self.last_change = [-math.inf] * n
        self.min_on, self.min_off, self.slack = min_on, min_off, slack

    def step(self, wanted, t):
        """``wanted``: the set of thrusters to be open; returns (opened, closed) as sets."""
        opened, closed = set(), set()
        for i, was_open in enumerate(self.is_open):
            if (i in wanted) == was_open:
                continue
            minimum = self.min_on if was_open else self.min_off
            if t - self.last_change[i] >= minimum - self.slack:
                self.is_open[i] = not was_open
                self.last_change[i] = t
                (closed if was_open else opened).add(i)
        return opened, closed


# --------------------------------------------------------------------------------------------
# Valve thrust profile (000 Fig. 6, Table 2; reference-model sec. 2) and its exact integral
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class ValveTimes:
    """Delays and full-swing ramp times of one valve (s)."""

    on_delay: float
    rise: float
    off_delay: float
    fall: float


def valve_reactions(commands, times):
    """Times at which the valve starts to react, from ``[(t_command, is_open), ...]``.

    Each command reacts after its delay. A command whose reaction comes before a pending one
    of an earlier command cancels that one (the later command wins).
    """
    reactions = []
    for t, is_open in sorted(commands, key=lambda c: c[0]):
        t_react = t + (times.on_delay if is_open else times.off_delay)
        reactions = [r for r in reactions if r[0] <= t_react]
        reactions.append((t_react, is_open))
    return reactions


def valve_knots(commands, times):
    """Knots ``[(t, level), ...]`` of the piecewise-linear normalised thrust level.

    Zero before the first knot; constant after the last. Every reaction starts a ramp from the
    level at that instant toward 1 (open) or 0 (close) at the full-swing slope.
    """
    knots = []
    level, t_level, slope = 0.0, -math.inf, 0.0

    def level_at(t):
        if slope == 0.0:
            return level
        return min(1.0, max(0.0, level + slope * (t - t_level)))

    reactions = valve_reactions(commands, times)
    for k, (t_react, is_open) in enumerate(reactions):
        start = level_at(t_react)
        knots.append((t_react, start))
        target = 1.0 if is_open else 0.0
        ramp = times.rise if is_open else times.fall
        level, t_level, slope = start, t_react, (1.0 if is_open else -1.0) / ramp
        t_done = t_react + abs(target - start) * ramp
        t_following = reactions[k + 1][0] if k + 1 < len(reactions) else math.inf
        if t_done < t_following:
            knots.append((t_done, target))
    return knots


def level(knots, t):
    """Normalised thrust level at ``t`` from the knots."""
    if not knots or t <= knots[0][0]:
        return 0.0
    ts = [k[0] for k in knots]
    ls = [k[1] for k in knots]
    return float(np.interp(t, ts, ls))


def thrust_impulse(knots_per_thruster, nominal_thrust, derating, t_start, t_end, arms=None):
    """Exact impulse (N s) and angular impulse (N m s) of several valves over [t_start, t_end].

    Thrust of valve i: nominal * derating[n - 1] * level_i, with n the number of valves whose
    level is above zero (more than len(derating) valves: the last factor). Between consecutive
    knots of all valves every level is linear and n is constant, so the trapezoid rule is exact.
    """
    times = {t_start, t_end}
    for knots in knots_per_thruster:
        times |= {t for t, _ in knots if t_start < t < t_end}
    times = sorted(times)
    impulse = 0.0
    angular = np.zeros(3)
    for a, b in zip(times[:-1], times[1:], strict=True):
        mid = 0.5 * (a + b)
        n_open = sum(level(k, mid) > 0.0 for k in knots_per_thruster)
        factor = derating[min(n_open, len(derating)) - 1] if n_open else 1.0
        for i, knots in enumerate(knots_per_thruster):
            area = 0.5 * (level(knots, a) + level(knots, b)) * (b - a)
            impulse += nominal_thrust * factor * area
            if arms is not None:
                angular += nominal_thrust * factor * area * np.asarray(arms[i])
    return impulse, angular


# --- mode program: exit conditions read straight from the mission file (refexmc.core.modes) ---
def exit_holds(mode_config, time_in_mode, t1, rates, rate_error, angle_error, altitude, climb, qbar):
    """A mode's exit conditions as the mission file states them, in its own units (deg, m, Pa):
    any group whose predicates all hold. Rates in deg/s, angles in deg."""
    tests = {
        "time_in_mode_s": lambda v: time_in_mode >= v,
        "guidance_finished": lambda v: time_in_mode > t1,
        "rates_below_deg_s": lambda v: all(abs(r) < v for r in rates),
        "rate_error_below_deg_s": lambda v: rate_error < v,
        "angle_error_below_deg": lambda v: angle_error < v,
        "altitude_below_m": lambda v: altitude < v,
        "descending": lambda v: climb < 0.0,
        "dynamic_pressure_above_pa": lambda v: qbar >= v,
    }
    return any(all(tests[name](value) for name, value in group.items()) for group in mode_config["exit"])


# --- LP thruster allocation (refexmc.core.lp_allocation), by enumerating the vertices ---------
def lp_allocation_vertices(arms, u_max, torque, tolerance=1e-9):
    """min sum(u) s.t. arms u = torque, 0 <= u <= u_max, by brute force over the polytope's vertices.

    A vertex has at most 3 thrusters strictly between their bounds: for every choice of 3
    (the basis) and every assignment of the others to 0 or u_max, solve for the 3 and keep the
    feasible assignment of least total thrust. Exponential; for a handful of thrusters only.
    Returns (least total thrust, u), or (inf, None) when the torque is not attainable.
    """
    import itertools

    import numpy as np

    n = arms.shape[1]
    best, best_u = np.inf, None
    for trio in itertools.combinations(range(n), 3):
        b = arms[:, trio]
        if abs(np.linalg.det(b)) < 1e-12:
            continue
        others = [j for j in range(n) if j not in trio]
        for at_max in itertools.product((0.0, 1.0), repeat=len(others)):
            u = np.zeros(n)
            u[others] = np.asarray(at_max) * u_max[others]
            u[list(trio)] = np.linalg.solve(b, torque - arms[:, others] @ u[others])
            if np.all(u >= -tolerance) and np.all(u <= u_max + tolerance) and u.sum() < best:
                best, best_u = u.sum(), u
    return best, best_u


# --- orbit translation with a constant-thrust engine (refexmc.core.orbit), one RK4 step ------
def orbit_rk4_step(state, h, mu, thrust, mass_flow, d0, d1, f0, f1):
    """One classical RK4 step of ``[r, v, m]`` under two-body gravity and ``thrust`` along the
    unit vector of ``d0 + (d1 - d0) f``, with ``f`` going linearly from ``f0`` to ``f1`` over the
    step (the stages at f0, the midpoint and f1); returns the new state as a list."""

    def direction(f):
        d = [a + (b - a) * f for a, b in zip(d0, d1, strict=True)]
        norm = math.sqrt(sum(c * c for c in d))
        return [c / norm for c in d]

    def rate(y, d):
        r, v, m = y[0:3], y[3:6], y[6]
        r_norm = math.sqrt(sum(c * c for c in r))
        gravity = [-mu / r_norm**3 * c for c in r]
        return [*v, *(g + thrust / m * c for g, c in zip(gravity, d, strict=True)), -mass_flow]

    def shifted(y, k, scale):
        return [a + scale * b for a, b in zip(y, k, strict=True)]

    y = [float(c) for c in state]
    k1 = rate(y, direction(f0))
    k2 = rate(shifted(y, k1, 0.5 * h), direction(0.5 * (f0 + f1)))
    k3 = rate(shifted(y, k2, 0.5 * h), direction(0.5 * (f0 + f1)))
    k4 = rate(shifted(y, k3, h), direction(f1))
    return [a + h / 6.0 * (b1 + 2.0 * b2 + 2.0 * b3 + b4) for a, b1, b2, b3, b4 in zip(y, k1, k2, k3, k4, strict=True)]


# --- reaction wheels (refexmc.core.wheels, 001 eq. 1, 5-6, 11, 12; sec. 9.1) -----------------
@dataclass
class NaiveWheels:
    """A wheel set in plain numpy: spin axes as the columns of ``axes`` (001's W), rotor inertia,
    001 eq. 1's friction coefficients, limits; ``failed`` a boolean per wheel."""

    axes: np.ndarray  # (3, n)
    spin_inertia: np.ndarray  # (n,)
    coulomb: np.ndarray
    viscous: np.ndarray
    coulomb_width: np.ndarray  # rad/s: sign(Omega) made Omega / width inside it
    torque_max: np.ndarray
    momentum_max: np.ndarray
    failed: np.ndarray


def quaternion_matrix(q):
    """Body-to-inertial rotation matrix of a scalar-last unit quaternion, written out."""
    x, y, z, w = q
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def wheel_state_rate(x, h, motor, torque, wheels, inertia, gg_coefficient=0.0, gg_direction=(0.0, 0.0, 1.0)):
    """d/dt of [q, omega] and [h (inertial axial momenta), p (inertial external impulse)].

    L = J_b omega + W h with J_b = J - sum I_w a a^T; dh/dt = motor + friction(Omega), Omega =
    h / I_w - a . omega (001 eq. 1, its sign linear within the Coulomb width); J_b domega/dt =
    tau - omega x L - W dh/dt (001 eq. 5-6);
    tau = torque + 3 k c x J c, c = R^T d (gravity gradient, physical sign); dp/dt = R tau.
    """
    q, omega = np.asarray(x[:4], float), np.asarray(x[4:7], float)
    n = wheels.axes.shape[1]
    h_w = np.asarray(h[:n], float)
    inertia = np.asarray(inertia, float)
    inertia_b = inertia - sum(wheels.spin_inertia[i] * np.outer(wheels.axes[:, i], wheels.axes[:, i]) for i in range(n))
    rotation = quaternion_matrix(q)
    c = rotation.T @ np.asarray(gg_direction, float)
    tau = np.asarray(torque, float) + 3.0 * gg_coefficient * np.cross(c, inertia @ c)
    speed = h_w / wheels.spin_inertia - wheels.axes.T @ omega
    friction = -wheels.coulomb * np.clip(speed / wheels.coulomb_width, -1.0, 1.0) - wheels.viscous * speed
    h_dot = np.asarray(motor, float) + friction
    total = inertia_b @ omega + wheels.axes @ h_w
    omega_dot = np.linalg.solve(inertia_b, tau - np.cross(omega, total) - wheels.axes @ h_dot)
    w_x, w_y, w_z = omega
    omega_matrix = np.array([[0, w_z, -w_y, w_x], [-w_z, 0, w_x, w_y], [w_y, -w_x, 0, w_z], [-w_x, -w_y, -w_z, 0]])
    q_dot = 0.5 * omega_matrix @ q  # 001 eq. 4: Omega(omega) q / 2, scalar last
    return np.concatenate([q_dot, omega_dot]), np.concatenate([h_dot, rotation @ tau])


def wheel_total_momentum(x, h, wheels, inertia):
    """Inertial total angular momentum R(q) (J_b omega + W h)."""
    n = wheels.axes.shape[1]
    inertia_b = np.asarray(inertia, float) - sum(
        wheels.spin_inertia[i] * np.outer(wheels.axes[:, i], wheels.axes[:, i]) for i in range(n)
    )
    return quaternion_matrix(x[:4]) @ (inertia_b @ np.asarray(x[4:7]) + wheels.axes @ np.asarray(h[:n]))


def wheel_commands(distribution, wheels, h, rate_meas, omega, torque_cmd):
    """Motor torques: demand = -D (u + omega x W h) (001 eq. 6, sec. 9.1), scaled as one vector to
    the working wheels' torque limit, a wheel at its momentum limit not driven further, failed
    wheels zero. Returns (motor, demand)."""
    n = wheels.axes.shape[1]
    h_w = np.asarray(h[:n], float)
    demand = -np.asarray(distribution) @ (np.asarray(torque_cmd) + np.cross(rate_meas, wheels.axes @ h_w))
    working = ~wheels.failed
    ratios = [wheels.torque_max[i] / abs(demand[i]) for i in range(n) if working[i] and abs(demand[i]) > 0]
    scale = min([1.0, *ratios])
    motor = np.where(working, demand * scale, 0.0)
    relative = h_w - wheels.spin_inertia * (wheels.axes.T @ np.asarray(omega))
    at_limit = (np.abs(relative) >= wheels.momentum_max) & (motor * relative > 0)
    return np.where(at_limit, 0.0, motor), demand


def wheel_null_space_torque(axes, used, h_relative, bias, rate, deadband=0.0, cap=math.inf):
    """Null-space momentum management, from scipy: N an orthonormal basis of the null space of the
    used wheels' axes (scipy.linalg.null_space), the error e_n = N N^T (h_relative - bias) on the
    used wheels; torque -rate (1 - deadband / |e_n|) e_n beyond the deadband, else 0, scaled down
    so that no wheel's exceeds ``cap``; 0 on the other wheels (and everywhere with three: N is empty)."""
    used = np.asarray(used, bool)
    out = np.zeros(len(used))
    basis = scipy.linalg.null_space(np.asarray(axes)[:, used])
    error = basis @ (basis.T @ (np.asarray(h_relative, float) - np.asarray(bias, float))[used])
    size = np.linalg.norm(error)
    if size <= deadband:
        return out
    out[used] = -rate * (1.0 - deadband / size) * error
    peak = np.abs(out).max()
    return out * (cap / peak) if peak > cap else out


def sliding_mode_torque(q_error, rate_error, rate_meas, accel_ref, slope, gain, layer, inertia):
    """001 eq. 12 in vector form: sigma = omega_e + Lambda q_e,vec (q_e4 >= 0); dq_e,vec/dt =
    (q_e4 omega_e + q_e,vec x omega_e) / 2; u = J (-Lambda dq_e + omega_dot_d) + omega x J omega
    - J G sat(sigma / epsilon)."""
    e, e4 = np.asarray(q_error[:3], float), float(q_error[3])
    w_e = np.asarray(rate_error, float)
    sigma = w_e + np.asarray(slope) * e
    q_dot = 0.5 * (e4 * w_e + np.cross(e, w_e))
    saturated = np.clip(sigma / np.asarray(layer), -1.0, 1.0)
    inertia = np.asarray(inertia, float)
    accel = -np.asarray(slope) * q_dot + np.asarray(accel_ref) - np.asarray(gain) * saturated
    return inertia @ accel + np.cross(rate_meas, inertia @ np.asarray(rate_meas))


# --- keyed uniforms (refexmc.core.keyed_random): numpy's SeedSequence + PCG64 in Python ints ---
_MASK32, _MASK64, _MASK128 = (1 << 32) - 1, (1 << 64) - 1, (1 << 128) - 1
_PCG64_MULTIPLIER = (2549297995355413924 << 64) + 4865540595714422341


def seed_sequence_pool(entropy):
    """numpy's SeedSequence pool (4 words) of non-negative integers: hashmix, then mix every word
    into every other, then the words beyond the pool (numpy/random/bit_generator.pyx)."""
    words = []
    for value in entropy:
        words += [0] if value == 0 else [(value >> (32 * k)) & _MASK32 for k in range((value.bit_length() + 31) // 32)]
    constant = [0x43B0D7E5]

    def hashmix(value):
        value = (value ^ constant[0]) & _MASK32
        constant[0] = (constant[0] * 0x931E8875) & _MASK32
        value = (value * constant[0]) & _MASK32
        return value ^ (value >> 16)

    def mix(x, y):
        result = (0xCA01F9DD * x - 0x4973F715 * y) & _MASK32
        return result ^ (result >> 16)

    pool = [hashmix(words[i] if i < len(words) else 0) for i in range(4)]
    for source in range(4):
        for target in range(4):
            if source != target:
                pool[target] = mix(pool[target], hashmix(pool[source]))
    for source in range(4, len(words)):
        for target in range(4):
            pool[target] = mix(pool[target], hashmix(words[source]))
    return pool


def keyed_doubles(entropy, n):
    """``default_rng(SeedSequence(entropy)).random(n)``: generate_state(4, uint64) seeds PCG64
    (srandom_r), each double is one 128-bit LCG step, its XSL-RR output, and (x >> 11) 2^-53."""
    pool, constant, halves = seed_sequence_pool(entropy), 0x8B51F9DD, []
    for i in range(8):
        value = (pool[i % 4] ^ constant) & _MASK32
        constant = (constant * 0x58F38DED) & _MASK32
        value = (value * constant) & _MASK32
        halves.append(value ^ (value >> 16))
    seed = [halves[2 * k] | (halves[2 * k + 1] << 32) for k in range(4)]
    increment = ((((seed[2] << 64) | seed[3]) << 1) | 1) & _MASK128
    state = increment  # 0 * multiplier + increment
    state = (state + ((seed[0] << 64) | seed[1])) & _MASK128
    state = (state * _PCG64_MULTIPLIER + increment) & _MASK128
    out = []
    for _ in range(n):
        state = (state * _PCG64_MULTIPLIER + increment) & _MASK128
        x, rotation = ((state >> 64) ^ state) & _MASK64, state >> 122
        x = ((x >> rotation) | (x << ((64 - rotation) % 64))) & _MASK64
        out.append((x >> 11) * 2.0**-53)
    return out


def dispersed_inertia(nominal_components, moments_sigma_fraction, axes_sigma_deg, u):
    """One inertia draw, one tensor at a time (refexmc.distributions.dispersed_inertia_rows):
    principal moments of the nominal tensor scaled by (1 + sigma z), its principal axes turned by
    the rotation vector axes_sigma z; z the standard normal quantiles of the 6 uniforms ``u``."""
    from scipy import special
    from scipy.spatial.transform import Rotation

    xx, yy, zz, xy, xz, yz = nominal_components
    moments, axes = np.linalg.eigh(np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]]))
    z = special.ndtri(u)
    moments = moments * (1.0 + moments_sigma_fraction * z[:3])
    turn = Rotation.from_rotvec(axes_sigma_deg * z[3:], degrees=True).as_matrix() @ axes
    j = turn @ np.diag(moments) @ turn.T
    j = 0.5 * (j + j.T)
    return np.array([j[0, 0], j[1, 1], j[2, 2], j[0, 1], j[0, 2], j[1, 2]])


# --------------------------------------------------------------------------------------------
# Deorbit burn guidance laws (004 sec. III; core.deorbit.steer)
# --------------------------------------------------------------------------------------------


def burn_direction(law, r_gps, v_gps, r_nom, v_nom, a_nom, position_gain, velocity_gain):
    """Unit thrust direction of a burn-guidance law: "pd" a_nom - k_r dr - k_v dv,
    "open_loop_retrograde" -v_gps, "open_loop_planned" a_nom (numpy vectors)."""
    if law == "pd":
        a = (
            np.asarray(a_nom)
            - position_gain * (np.asarray(r_gps) - r_nom)
            - velocity_gain * (np.asarray(v_gps) - v_nom)
        )
    elif law == "open_loop_retrograde":
        a = -np.asarray(v_gps, dtype=float)
    elif law == "open_loop_planned":
        a = np.asarray(a_nom, dtype=float)
    else:
        raise ValueError(law)
    return a / np.linalg.norm(a)


# --------------------------------------------------------------------------------------------
# Navigation errors (reference-model sec. 5; 000 sec. 2.2, 6.2) and their noise source
# --------------------------------------------------------------------------------------------


class SplitMix64:
    """SplitMix64 (Steele, Lea, Flood 2014) in Python ints, with Box-Muller normals (one of the pair)."""

    GOLDEN, MIX1, MIX2 = 0x9E3779B97F4A7C15, 0xBF58476D1CE4E5B9, 0x94D049BB133111EB

    def __init__(self, state):
        self.state = int(state) & _MASK64

    def uniform(self):
        self.state = (self.state + self.GOLDEN) & _MASK64
        z = self.state
        z = ((z ^ (z >> 30)) * self.MIX1) & _MASK64
        z = ((z ^ (z >> 27)) * self.MIX2) & _MASK64
        z ^= z >> 31
        return ((z >> 11) + 0.5) / 2.0**53  # in (0, 1)

    def normal(self):
        u1, u2 = self.uniform(), self.uniform()
        return math.sqrt(-2.0 * math.log(u1)) * math.cos(2.0 * math.pi * u2)


def navigation_measure(
    q, rate, attitude_bias, attitude_noise, rate_bias, rate_noise, calibration_time, time_calibrating, noise
):
    """(measured quaternion [x, y, z, w], measured rate) of the reference model sec. 5.

    The attitude error is the body-axes rotation vector b e^(-t_cal / tau) + n (n ~ N(0, sigma^2)
    per axis): the bias decays only over ``time_calibrating``, the time spent in calibrating modes
    (frozen once they end), and not at all without a time constant. Measured rate = truth + bias +
    noise. ``noise``: a SplitMix64 drawn in the kernel's order (attitude x, y, z, then rate x, y, z),
    a draw only where the sigma is positive.
    """
    decay = math.exp(-time_calibrating / calibration_time) if calibration_time > 0 and time_calibrating > 0 else 1.0
    error = decay * np.asarray(attitude_bias, float)
    if attitude_noise > 0:
        error = error + attitude_noise * np.array([noise.normal() for _ in range(3)])
    measured = (Rotation.from_quat(q) * Rotation.from_rotvec(error)).as_quat()
    if np.dot(measured, q) < 0:  # the same rotation; the sign closest to the truth
        measured = -measured
    rates = np.asarray(rate, float) + np.asarray(rate_bias, float)
    if rate_noise > 0:
        rates = rates + rate_noise * np.array([noise.normal() for _ in range(3)])
    return measured, rates


def local_measure(position, velocity, pressure, position_noise, velocity_noise, pressure_noise, noise):
    """(measured position, velocity, tank pressure) of the local trajectory (docs/cold-gas.md):
    truth + sigma n per axis, drawn in the kernel's order (position x, y, z, velocity x, y, z,
    pressure), a draw only where the sigma is positive; a pressure reading below zero reads zero."""
    measured_position = [p + (position_noise * noise.normal() if position_noise > 0 else 0.0) for p in position]
    measured_velocity = [v + (velocity_noise * noise.normal() if velocity_noise > 0 else 0.0) for v in velocity]
    measured_pressure = pressure
    if pressure_noise > 0:
        measured_pressure = max(pressure + pressure_noise * noise.normal(), 0.0)
    return np.array(measured_position), np.array(measured_velocity), measured_pressure


# --------------------------------------------------------------------------------------------
# PD control with partial feedback linearisation, 000 eq. 30 and 35
# --------------------------------------------------------------------------------------------


def pd_feedback_linearisation_torque(q_error, rate_error, rate_meas, accel_ref, kp, kd, inertia, attitude_controlled):
    """u = J v + omega x J omega (eq. 30), v = omega_dot_g - Kd omega_e - Kp q_e,vec (eq. 35);
    in rate damping (attitude not controlled, 000 sec. 3.2) v has no Kp term."""
    inertia = np.asarray(inertia, float)
    omega = np.asarray(rate_meas, float)
    v = np.asarray(accel_ref, float) - np.asarray(kd, float) * np.asarray(rate_error, float)
    if attitude_controlled:
        v = v - np.asarray(kp, float) * np.asarray(q_error[:3], float)
    return inertia @ v + np.cross(omega, inertia @ omega)


# Entry flight over a rotating spherical Earth, 003 eq. 3 (longitude/latitude rates and the
# centripetal sign in gamma-dot as for a heading from north: core.entry's docstring)
# --------------------------------------------------------------------------------------------


def entry_derivative(state, radius, mu, omega, air, forces, mass, bank):
    """d/dt [h, lon, lat, V, gamma, chi]; ``air(h) -> (rho, sound)``, ``forces(rho, V, sound) ->
    (L, D, Y)`` in N."""
    h, _lon, lat, v, gamma, chi = state
    r = radius + h
    g = mu / r**2
    rho, sound = air(h)
    lift, drag, side = forces(rho, v, sound)
    w = omega
    return [
        v * math.sin(gamma),
        v * math.cos(gamma) * math.sin(chi) / (r * math.cos(lat)),
        v * math.cos(gamma) * math.cos(chi) / r,
        -drag / mass
        - g * math.sin(gamma)
        + w**2
        * r
        * math.cos(lat)
        * (math.sin(gamma) * math.cos(lat) - math.cos(gamma) * math.sin(lat) * math.cos(chi)),
        (lift * math.cos(bank) - side * math.sin(bank)) / (mass * v)
        + math.cos(gamma) * (v / r - g / v)
        + 2 * w * math.cos(lat) * math.sin(chi)
        + w**2
        * r
        / v
        * math.cos(lat)
        * (math.cos(gamma) * math.cos(lat) + math.sin(gamma) * math.sin(lat) * math.cos(chi)),
        (lift * math.sin(bank) + side * math.cos(bank)) / (mass * v * math.cos(gamma))
        + v * math.cos(gamma) * math.sin(chi) * math.tan(lat) / r
        - 2 * w * (math.tan(gamma) * math.cos(lat) * math.cos(chi) - math.sin(lat))
        + w**2 * r / (v * math.cos(gamma)) * math.sin(lat) * math.cos(lat) * math.sin(chi),
    ]


# --------------------------------------------------------------------------------------------
# Blending thrusters with surfaces, 003 eq. 5-10: vertex enumeration, no LP solver
# --------------------------------------------------------------------------------------------


def blend_rate(effectiveness, offset, torque, weights, d):
    """003 eq. 8: sum_i w_i |tau_i - (B d + offset)_i|."""
    t = np.asarray(torque) - np.asarray(effectiveness) @ np.asarray(d) - np.asarray(offset)
    return float(np.sum(np.asarray(weights) * np.abs(t)))


def blend_candidates(effectiveness, offset, torque, lower, upper):
    """Every point where the minimum of eq. 8 over the box can lie: the vertices of the
    arrangement of the zero-thruster-moment planes (eq. 9a-c, 10a-c) and the box faces, in the
    free surfaces (lower < upper; the fixed ones, such as a blocked flap, stay at their bound)."""
    b = np.asarray(effectiveness, dtype=float)
    lo, hi = np.asarray(lower, dtype=float), np.asarray(upper, dtype=float)
    free = [j for j in range(len(lo)) if hi[j] > lo[j]]
    fixed = [j for j in range(len(lo)) if hi[j] <= lo[j]]
    c = np.asarray(torque, dtype=float) - np.asarray(offset, dtype=float) - b[:, fixed] @ lo[fixed]
    n = len(free)
    planes = [(b[i, free], c[i]) for i in range(3)]
    for k in range(n):
        unit = np.eye(n)[k]
        planes += [(unit, lo[free[k]]), (unit, hi[free[k]])]
    points = []
    for combination in itertools.combinations(planes, n):
        m = np.array([normal for normal, _ in combination])
        if n and abs(np.linalg.det(m)) < 1e-300:
            continue
        x = np.linalg.solve(m, [value for _, value in combination]) if n else np.zeros(0)
        slack = 1e-12 * (1.0 + np.abs(x))
        if np.all(x >= lo[free] - slack) and np.all(x <= hi[free] + slack):
            point = lo.copy()
            point[free] = np.clip(x, lo[free], hi[free])
            points.append(point)
    return points


def triangle_vertices(effectiveness, offset, torque, lower, upper):
    """The three vertices of the triangle of eq. 10a-c in the two free surfaces (the free flap and
    the rudder): pairwise intersections of the lines where one thruster moment is zero."""
    b = np.asarray(effectiveness, dtype=float)
    lo, hi = np.asarray(lower, dtype=float), np.asarray(upper, dtype=float)
    free = [j for j in range(len(lo)) if hi[j] > lo[j]]
    fixed = [j for j in range(len(lo)) if hi[j] <= lo[j]]
    c = np.asarray(torque, dtype=float) - np.asarray(offset, dtype=float) - b[:, fixed] @ lo[fixed]
    vertices = []
    for i, j in ((0, 1), (1, 2), (0, 2)):
        point = lo.copy()
        point[free] = np.linalg.solve(b[[i, j]][:, free], c[[i, j]])
        vertices.append(point)
    return vertices


def entry_aero_moment(coefficients, qsl, beta, deflection):
    """Body moments of the entry flight (core.entry_flight): ``coefficients`` a dict of the
    vehicle-file names at the flight condition; deflection (left, right, rudder) in rad."""
    elevon = (deflection[0] + deflection[1]) / 2
    aileron = (deflection[0] - deflection[1]) / 2
    c = coefficients
    return qsl * np.array(
        [
            c["roll_per_beta_rad"] * beta
            + c["roll_per_aileron_rad"] * aileron
            + c["roll_per_rudder_rad"] * deflection[2],
            c["pitch"] + c["pitch_per_elevon_rad"] * elevon,
            c["yaw_per_beta_rad"] * beta + c["yaw_per_aileron_rad"] * aileron + c["yaw_per_rudder_rad"] * deflection[2],
        ]
    )


# Cold-gas tank and nozzle, 002 eq. 1-20 (textbook forms: Sutton and Biblarz, ch. 3)
# --------------------------------------------------------------------------------------------


def nozzle_pressure_ratio(expansion_ratio, gamma):
    """p_e / p_c of an ideal nozzle with area ratio A_e / A_t (Sutton eq. 3-25, supersonic branch),
    from the pressure form of the area ratio rather than the Mach form of 002 eq. 6."""
    from scipy.optimize import brentq

    def inverse_area_ratio(ratio):  # A_t / A_e as a function of p_e / p_c
        g = gamma
        return (
            ((g + 1.0) / 2.0) ** (1.0 / (g - 1.0))
            * ratio ** (1.0 / g)
            * math.sqrt((g + 1.0) / (g - 1.0) * (1.0 - ratio ** ((g - 1.0) / g)))
        )

    critical = (2.0 / (gamma + 1.0)) ** (gamma / (gamma - 1.0))  # the throat's p / p_c
    if expansion_ratio == 1.0:
        return critical
    return brentq(lambda r: inverse_area_ratio(r) - 1.0 / expansion_ratio, 1e-300, critical, xtol=1e-300, rtol=1e-15)


def textbook_thrust_coefficient(expansion_ratio, gamma, ambient_over_chamber=0.0):
    """C_F = F / (A_t p_c) (Sutton eq. 3-30)."""
    g = gamma
    ratio = nozzle_pressure_ratio(expansion_ratio, gamma)
    momentum = math.sqrt(
        2.0 * g * g / (g - 1.0) * (2.0 / (g + 1.0)) ** ((g + 1.0) / (g - 1.0)) * (1.0 - ratio ** ((g - 1.0) / g))
    )
    return momentum + (ratio - ambient_over_chamber) * expansion_ratio


def choked_mass_flow(throat_area, chamber_pressure, gamma, gas_constant, temperature):
    """mdot through a choked throat (Sutton eq. 3-24; 002 eq. 10)."""
    g = gamma
    return (
        throat_area
        * chamber_pressure
        * g
        * math.sqrt((2.0 / (g + 1.0)) ** ((g + 1.0) / (g - 1.0)))
        / math.sqrt(g * gas_constant * temperature)
    )


def tank_history(open_sum, t_end, tank, rtol=1e-13):
    """Integrate the isothermal tank (002 eq. 2, 3, 10, 15) with scipy at tight tolerance:
    y = [tank pressure, gas used, impulse] at ``t_end``. ``open_sum(t)``: sum of valve level times
    thrust scale; ``tank``: dict of volume, gas_constant, gamma, temperature, pressure, throat_area,
    thrust_coefficient (vacuum), regulator (inf for blow-down). ``t_end``: a list of breakpoints,
    integrated piece by piece so the solver never steps over a kink."""
    from scipy.integrate import solve_ivp

    rt = tank["gas_constant"] * tank["temperature"]

    def rhs(t, y):
        chamber = min(y[0], tank["regulator"])
        flow = open_sum(t) * choked_mass_flow(
            tank["throat_area"], chamber, tank["gamma"], tank["gas_constant"], tank["temperature"]
        )
        thrust = open_sum(t) * tank["thrust_coefficient"] * tank["throat_area"] * chamber
        return [-rt / tank["volume"] * flow, flow, thrust]

    y = [tank["pressure"], 0.0, 0.0]
    t0 = 0.0
    for t1 in t_end:
        if t1 > t0:
            sol = solve_ivp(rhs, (t0, t1), y, method="DOP853", rtol=rtol, atol=1e-30)
            y = list(sol.y[:, -1])
        t0 = t1
    return y


# --------------------------------------------------------------------------------------------
# Time-optimal law of 002 eq. 41-44 and its plant eq. 21
# --------------------------------------------------------------------------------------------


def time_optimal_u(x1, x2, x3, x3_min, bang_bang=False):
    """u of 002 eq. 44 (or -sign(sigma2), bang-bang), written out from eq. 41-43 as printed."""
    sign = np.sign
    a = abs(x2)
    if x3 <= a:  # eq. 46: outside the reachable region the logarithms are undefined: brake
        return -float(sign(x2))
    log = math.log(x3 / (x3 - a))
    s2 = x1 + x2 - sign(x2) * (x3 - a) * log
    if bang_bang:
        return -float(sign(s2))
    s1 = x3 - x3_min - a
    if s1 > 0.0:
        if x2 == 0.0:
            s0 = sign(x1)  # x3 / x2^2 -> +inf times the bracket x1
        else:
            s0 = x3 / x2**2 * (x1 + (x3 + a) / (x3 - a) * x2 - sign(x2) * (x3 + a) * log)
        return -0.5 * float(sign(s0) + sign(s2))
    return -0.5 * float(sign(x2) + sign(s2))


# --------------------------------------------------------------------------------------------
# Entry attitude, guidance alignment and control (core.entry_attitude, core.entry_flight):
# 003 eq. 4 and its "successive dynamic inversion ... additional feedback control provides
# tracking of the commands alpha_c, beta_c and mu_c"; the free flap aligned with the blocked one
# ("the commanded angle of attack has to be increased"); the surfaces' moments of eq. 6 and 10.
# Written from the textbook frames (trajectory axes from gamma and chi, wind axes by the bank
# about the velocity, body axes by alpha and beta), with matrices, a linear solve for the
# kinematics and scipy's interpolator for the tables; nothing shared with refexmc.core.
# --------------------------------------------------------------------------------------------


def entry_trajectory_axes(state, t, rotation):
    """Columns: the trajectory axes x_k (along the Earth-relative velocity), y_k (horizontal, to
    the right), z_k = x_k x y_k in inertial axes, the Earth turned by ``rotation`` t."""
    _h, lon, lat, _v, gamma, chi = state
    lon = lon + rotation * t
    north = np.array([-math.sin(lat) * math.cos(lon), -math.sin(lat) * math.sin(lon), math.cos(lat)])
    east = np.array([-math.sin(lon), math.cos(lon), 0.0])
    down = np.array([-math.cos(lat) * math.cos(lon), -math.cos(lat) * math.sin(lon), -math.sin(lat)])
    ned = np.column_stack([north, east, down])
    x_k = ned @ [math.cos(gamma) * math.cos(chi), math.cos(gamma) * math.sin(chi), -math.sin(gamma)]
    y_k = ned @ [-math.sin(chi), math.cos(chi), 0.0]
    return np.column_stack([x_k, y_k, np.cross(x_k, y_k)])


def body_from_wind(alpha, beta):
    """Matrix taking wind-axis components to body-axis components (rotate by -beta about z_w, then
    by alpha about y_b)."""
    ca, sa, cb, sb = math.cos(alpha), math.sin(alpha), math.cos(beta), math.sin(beta)
    return np.array([[ca * cb, -ca * sb, -sa], [sb, cb, 0.0], [sa * cb, -sa * sb, ca]])


def entry_aerodynamic_angles(state, t, rotation, quaternion):
    """(alpha, beta, bank) of the body attitude (scalar-last body-to-inertial quaternion): the
    velocity in body axes gives alpha and beta; the bank turns the wind z axis about the velocity
    from z_k, positive with the lift (-z_w) to the right: z_w = -sin(mu) y_k + cos(mu) z_k."""
    axes = entry_trajectory_axes(state, t, rotation)
    body = quaternion_matrix(quaternion)
    u, v, w = body.T @ axes[:, 0]
    alpha, beta = math.atan2(w, u), math.asin(max(-1.0, min(1.0, v)))
    z_wind = body @ body_from_wind(alpha, beta)[:, 2]
    return alpha, beta, math.atan2(-z_wind @ axes[:, 1], z_wind @ axes[:, 2])


def entry_body_axes(state, t, rotation, alpha, beta, bank):
    """Body-to-inertial matrix flying ``state`` at (alpha, beta, bank): wind axes = trajectory
    axes turned by the bank about x_k, body axes from them by alpha and beta."""
    axes = entry_trajectory_axes(state, t, rotation)
    cm, sm = math.cos(bank), math.sin(bank)
    wind = np.column_stack([axes[:, 0], cm * axes[:, 1] + sm * axes[:, 2], -sm * axes[:, 1] + cm * axes[:, 2]])
    return wind @ body_from_wind(alpha, beta).T


def entry_coefficient(model, slot, alpha, mach):
    """A coefficient table of ``model`` (core.entry.EntryModel) at (alpha rad, Mach): scipy's
    bilinear interpolation, held at the table's edges."""
    from scipy.interpolate import RegularGridInterpolator

    alphas, machs = np.asarray(model.alpha_axis), np.asarray(model.mach_axis)
    table = RegularGridInterpolator((alphas, machs), np.asarray(model.coefficients[slot]), method="linear")
    point = [min(max(alpha, alphas[0]), alphas[-1]), min(max(mach, machs[0]), machs[-1])]
    return float(table([point])[0])


def entry_trim_alpha(model, slots, mach, deflection, fallback):
    """The lowest alpha on the table's axis where the flaps trim at ``deflection``:
    C_m + deflection C_m_delta_e = 0 (003 eq. 6, delta_trim = -C_m / C_m_delta_e), by brentq on
    the first cell of the alpha axis where it changes sign; ``fallback`` where none does.
    ``slots``: (pitch, pitch per elevon) table indices."""
    from scipy.optimize import brentq

    def moment(alpha):
        return entry_coefficient(model, slots[0], alpha, mach) + deflection * entry_coefficient(
            model, slots[1], alpha, mach
        )

    axis = np.asarray(model.alpha_axis)
    for a, b in zip(axis[:-1], axis[1:], strict=True):
        if moment(a) == 0.0:
            return float(a)
        if moment(a) * moment(b) < 0.0:
            return brentq(moment, a, b, xtol=1e-15, rtol=1e-15)
    return float(axis[-1]) if moment(axis[-1]) == 0.0 else fallback


def entry_alignment_bias(model, slots, mach, alpha, free_deflection, blocked_deflection, bias, gain, period, limit):
    """The next alpha bias of the alignment feedback: alpha moves towards where the free flap's
    trim deflection equals the blocked one, at ``gain`` per second of the misalignment divided
    by d(delta_trim)/d(alpha) (central difference over +-0.01 rad), within +-``limit``."""

    def trim(a):
        return -entry_coefficient(model, slots[0], a, mach) / entry_coefficient(model, slots[1], a, mach)

    slope = (trim(alpha + 0.01) - trim(alpha - 0.01)) / 0.02
    if slope == 0.0:
        return bias
    return min(max(bias - gain * period * (free_deflection - blocked_deflection) / slope, -limit), limit)


def entry_hinge_limit(qbar, alpha, hinge_moment_max, area_arm):
    """Largest flap deflection whose Newtonian hinge moment 2 q S_f c sin^2(alpha + delta) is within
    the limit (003 Table 1), found by brentq; pi/2 - alpha where every deflection is."""
    from scipy.optimize import brentq

    top = 0.5 * math.pi - alpha
    if hinge_moment_max <= 0.0 or qbar <= 0.0 or 2.0 * qbar * area_arm <= hinge_moment_max:
        return top
    return brentq(
        lambda d: 2.0 * qbar * area_arm * math.sin(alpha + d) ** 2 - hinge_moment_max, -alpha, top, xtol=1e-15
    )


def angle_rates_to_body_rates(alpha, beta, rates):
    """Body rates (p, q, r) giving the rates of (alpha, beta, bank), flight-path terms neglected:
    alpha' = q - tan(b)(p cos a + r sin a), beta' = p sin a - r cos a, mu' = (p cos a + r sin a) / cos b,
    solved as a linear system."""
    ca, sa, tb, cb = math.cos(alpha), math.sin(alpha), math.tan(beta), math.cos(beta)
    kinematics = np.array([[-tb * ca, 1.0, -tb * sa], [sa, 0.0, -ca], [ca / cb, 0.0, sa / cb]])
    return np.linalg.solve(kinematics, rates)


def entry_control(vehicle, state, t, deflection, integral, alpha_cmd, bank_cmd, qbar, mach, slots):
    """One control period of the entry flight software, from 003 (see the block comment):

    - outer loop: errors of alpha, beta (commanded 0) and bank, plus ``integral_gain`` times their
      integrals (accumulated below the RCS-only altitude, clamped), times the angle gains, are the
      commanded angle rates, turned into body rates by :func:`angle_rates_to_body_rates`;
    - inner loop, eq. 4 inverted: M_c = J k (omega_c - omega) + omega x J omega, less the static
      sideslip moments q S L (C_l_beta beta, 0, C_n_beta beta) (the pitch moment goes to the
      allocation through delta_trim, eq. 6);
    - the mode program and the surfaces' bounds; the surfaces' moments B d + offset of eq. 6 and 10.

    ``qbar``, ``mach``: the flight software's air data (core.atmosphere, tested on its own);
    ``slots``: dict of the coefficient table indices. Returns a dict."""
    from refexmc.core import entry_flight as ef

    ct, sf, model = vehicle.control, vehicle.surfaces, vehicle.fsw_model
    rotation = model.planet[2]
    translation, quaternion, omega = state[:6], state[6:10], np.asarray(state[10:13], dtype=float)
    alpha, beta, bank = entry_aerodynamic_angles(translation, t, rotation, quaternion)
    qsl = qbar * model.reference[0] * model.reference[1]

    def c(name):
        return entry_coefficient(model, slots[name], alpha, mach)

    errors = np.array([alpha_cmd - alpha, -beta, (bank_cmd - bank + math.pi) % (2 * math.pi) - math.pi])
    integral = np.array(integral, dtype=float)
    aero_mode = translation[0] < ct[ef.CT_RCS_ONLY_ABOVE_M]
    if aero_mode and ct[ef.CT_INTEGRAL_GAIN] > 0.0:
        limits = ct[ef.CT_INTEGRAL_LIMIT : ef.CT_INTEGRAL_LIMIT + 3]
        integral = np.clip(integral + errors * ct[ef.CT_PERIOD], -limits, limits)
    angle_rates = ct[ef.CT_ANGLE_GAIN : ef.CT_ANGLE_GAIN + 3] * (errors + ct[ef.CT_INTEGRAL_GAIN] * integral)
    omega_cmd = angle_rates_to_body_rates(alpha, beta, angle_rates)
    inertia = np.asarray(vehicle.inertia)
    moment = inertia @ (ct[ef.CT_RATE_GAIN] * (omega_cmd - omega)) + np.cross(omega, inertia @ omega)
    moment -= qsl * beta * np.array([c("roll_per_beta_rad"), 0.0, c("yaw_per_beta_rad")])
    rudders = sf[ef.SF_HAS_RUDDERS] > 0.0 and mach < sf[ef.SF_RUDDER_MACH]
    flap_top = min(
        sf[ef.SF_FLAP_MAX], entry_hinge_limit(qbar, alpha, sf[ef.SF_HINGE_MOMENT_MAX], sf[ef.SF_HINGE_AREA_ARM])
    )
    lower, upper = np.zeros(3), np.zeros(3)
    for i in range(2):
        lower[i], upper[i] = (
            (sf[ef.SF_FLAP_MIN], max(flap_top, sf[ef.SF_FLAP_MIN])) if aero_mode else (deflection[i],) * 2
        )
    blocked = int(sf[ef.SF_BLOCKED_FLAP])
    if blocked >= 0 and sf[ef.SF_BLOCKED_KNOWN] > 0.0:
        lower[blocked] = upper[blocked] = sf[ef.SF_BLOCKED_DEFLECTION]
    if rudders and aero_mode:
        lower[2], upper[2] = sf[ef.SF_RUDDER_MIN], sf[ef.SF_RUDDER_MAX]
    roll_a, pitch_e, yaw_a = c("roll_per_aileron_rad"), c("pitch_per_elevon_rad"), c("yaw_per_aileron_rad")
    roll_r, yaw_r = c("roll_per_rudder_rad"), c("yaw_per_rudder_rad")
    effectiveness = qsl * np.array(
        [[roll_a / 2, -roll_a / 2, roll_r], [pitch_e / 2, pitch_e / 2, 0.0], [yaw_a / 2, -yaw_a / 2, yaw_r]]
    )
    trim = -c("pitch") / pitch_e if pitch_e != 0.0 else 0.0
    offset = np.array([0.0, -qsl * pitch_e * trim, 0.0])  # C_m_de (delta_e - delta_trim), eq. 6
    return {
        "angles": (alpha, beta, bank),
        "integral": integral,
        "body_rates_cmd": omega_cmd,
        "moment": moment,
        "lower": lower,
        "upper": upper,
        "mode": 0 if not aero_mode else (2 if rudders else 1),
        "effectiveness": effectiveness,
        "offset": offset,
    }


def entry_actuate(command, deflection, blocked, blocked_deflection, rates, time_constant, dt):
    """Surfaces after one period: each moves by the first-order lag's share 1 - exp(-dt / T) of
    its command error, at most rate dt; the blocked flap stays where it is."""
    share = 1.0 - math.exp(-dt / time_constant) if time_constant > 0.0 else 1.0
    out = []
    for i in range(3):
        if i == blocked:
            out.append(blocked_deflection)
            continue
        step = (command[i] - deflection[i]) * share
        out.append(deflection[i] + max(-rates[i] * dt, min(rates[i] * dt, step)))
    return np.array(out)


# --------------------------------------------------------------------------------------------
# First-order Gauss-Markov knowledge error (core.navigation; Farrenkopf, Markley NASA 20000086664)
# --------------------------------------------------------------------------------------------


def gauss_markov_variance(sigma, dt, tau, steps):
    """The variance of x_k after ``steps`` exact updates x_{k+1} = a x_k + sqrt(1 - a^2) sigma w_k
    from the stationary start Var x_0 = sigma^2: v_{k+1} = a^2 v_k + (1 - a^2) sigma^2, a = e^(-dt/tau)."""
    a = math.exp(-dt / tau)
    variance = sigma * sigma
    for _ in range(steps):
        variance = a * a * variance + (1.0 - a * a) * sigma * sigma
    return variance


def gauss_markov_path(sigma, dt, tau, steps, noise):
    """A Gauss-Markov path of ``steps + 1`` samples from the stationary start (x_0 = sigma n_0), each
    next x = a x + sqrt(1 - a^2) sigma n; ``noise``: a SplitMix64 in the kernel's order."""
    a = math.exp(-dt / tau)
    drive = math.sqrt(1.0 - a * a)
    x = sigma * noise.normal()
    path = [x]
    for _ in range(steps):
        x = a * x + drive * sigma * noise.normal()
        path.append(x)
    return np.array(path)


# --------------------------------------------------------------------------------------------
# A drawn dispersion written into one run's inputs (config.dispersions.apply_rows does a chunk's
# runs at once): run by run, field by field, from the layout's offsets
# --------------------------------------------------------------------------------------------


def apply_dispersion(inputs, path, values, nominal_atmosphere, levels):
    """Write ``values`` (user units) of ``path`` into one run's own input tables, as the packer
    puts a nominal value: a field of its table, times the path's unit scale (a thruster or wheel
    table: that column of every row), or by name for the special paths. The per-run functions it
    calls (the nozzle constants, the misalignment's rotation) are those of the config: what is
    twinned is writing a chunk's values at once."""
    from refexmc.config import derived
    from refexmc.config import feed as config_feed
    from refexmc.config.parameters import NOZZLE_CONSTANTS, TABLES, parameter
    from refexmc.core import layout as L

    def field(table, fields, name, new):
        offset, count = fields.slices[name]
        new = [float(v) for v in np.ravel(new)]
        assert len(new) == count
        for i, v in enumerate(new):
            table[offset + i] = v

    values = [float(v) for v in np.ravel(values)]
    param = parameter(path)
    if param.table is not None:
        table = getattr(inputs, param.table)
        offset, count = TABLES[param.table].slices[param.field]
        scaled = [v * param.scale for v in values]
        if table.ndim == 2:
            for row in range(table.shape[0]):
                table[row, offset] = scaled[row] if len(scaled) > 1 else scaled[0]
        else:
            field(table, TABLES[param.table], param.field, scaled)
        if param.special == NOZZLE_CONSTANTS:
            vehicle = inputs.vehicle
            vehicle[L.V_FEED_THRUST_COEFFICIENT], vehicle[L.V_FEED_FLOW_FACTOR] = config_feed.nozzle_constants(
                float(vehicle[L.V_FEED_HEAT_CAPACITY_RATIO]), float(vehicle[L.V_FEED_EXPANSION_RATIO])
            )
    elif path.startswith("rcs.thrust_n."):
        row = inputs.levels[list(levels).index(path.split(".")[2])]
        row[L.LV_REGULATOR_PRESSURE] = row[L.LV_REGULATOR_PRESSURE] * (values[0] / row[L.LV_THRUST])
        row[L.LV_THRUST] = values[0]
    elif path == "main_engine.misalignment_deg":
        axis = inputs.fsw[L.F_ENGINE_AXIS : L.F_ENGINE_AXIS + 3]
        field(inputs.vehicle, L.VEHICLE, "engine_direction", derived.rotate_by_rotation_vector(axis, values))
    elif path == "inertia_kg_m2":
        xx, yy, zz, xy, xz, yz = values
        field(inputs.vehicle, L.VEHICLE, "inertia_kg_m2", [xx, xy, xz, xy, yy, yz, xz, yz, zz])
    elif path == "rcs.derating":
        field(inputs.vehicle, L.VEHICLE, "derating", values + [values[-1]] * (L.DERATING_MAX_VALVES - len(values)))
    elif path.startswith("rcs.valve_time_constants_ms."):
        _, _, level, name = path.split(".")
        column = L.time_constant_column(list(levels).index(level), L.TIME_CONSTANT_NAMES.index(name))
        for row in range(inputs.thrusters.shape[0]):
            inputs.thrusters[row, column] = values[row] / 1e3
    elif path == "atmosphere.density_scale":
        for row in range(inputs.atmosphere.shape[0]):
            inputs.atmosphere[row, 1] = nominal_atmosphere[row, 1] * values[0]
    else:
        raise KeyError(path)
