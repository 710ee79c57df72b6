"""Cold-gas feed design quantities from the vehicle file's ``rcs.feed`` (002 sec. 2-3).

The nozzle constants the core takes (``core.feed``): the exit Mach number from the area ratio
(002 eq. 6 corrected, supersonic root: see :func:`area_ratio`), the vacuum thrust coefficient
C_F (eq. 15's bracket) and the flow factor Gamma (eq. 10), and for ``refexmc inspect`` the
exhaust velocity, blow-down time constant, thrusts and total impulse.
"""

import math

from refexmc import crmath
from refexmc.config import schema

MODELS = {"constant": 0, "blow_down": 1, "regulated": 2}
AMBIENT_PRESSURE_DEFAULT_PA = schema.FEED["properties"]["ambient_pressure_pa"]["default"]  # declared in the schema


def _pow(x, y):
    """x**y correctly rounded (refexmc.crmath): Python's ``**`` is glibc's pow, whose variant and
    last bit depend on the CPU (docs/campaigns.md); these feed every cold-gas run."""
    return float(crmath.pow(x, y))


def area_ratio(mach, gamma):
    """A_e / A_t at exit Mach number ``mach``: (1/M) [(2/(gamma+1)) (1 + (gamma-1)/2 M^2)]^((gamma+1)/(2(gamma-1)))
    (Sutton eq. 3-14). 002 eq. 6 as printed leaves 2/(gamma+1) outside the power, which gives
    1.58 instead of 1 at the throat (M = 1, gamma = 1.4): a misprint, not used."""
    base = (2.0 / (gamma + 1.0)) * (1.0 + 0.5 * (gamma - 1.0) * mach * mach)
    return _pow(base, (gamma + 1.0) / (2.0 * (gamma - 1.0))) / mach


def exit_mach(expansion_ratio, gamma):
    """Supersonic exit Mach number of a nozzle with area ratio ``expansion_ratio`` >= 1 (002 eq. 6,
    corrected): bisection on M > 1, where the area ratio increases, to the last bit (no scipy:
    ``pack`` imports this module for every campaign)."""
    if expansion_ratio == 1.0:
        return 1.0
    low, high = 1.0, 2.0
    while area_ratio(high, gamma) < expansion_ratio:
        low, high = high, 2.0 * high
    while True:
        middle = 0.5 * (low + high)
        if middle <= low or middle >= high:
            return high if area_ratio(high, gamma) - expansion_ratio < expansion_ratio - area_ratio(low, gamma) else low
        if area_ratio(middle, gamma) < expansion_ratio:
            low = middle
        else:
            high = middle


def thrust_coefficient(expansion_ratio, gamma):
    """Vacuum thrust coefficient C_F = F / (A_t P_c) at P_a = 0: the bracket of 002 eq. 15."""
    mach = exit_mach(expansion_ratio, gamma)
    base = 1.0 + 0.5 * (gamma - 1.0) * mach * mach
    momentum = gamma * mach * _pow(2.0 / (gamma + 1.0), (gamma + 1.0) / (2.0 * (gamma - 1.0))) / math.sqrt(base)
    return momentum + expansion_ratio * _pow(base, -gamma / (gamma - 1.0))


def flow_factor(gamma):
    """Gamma of 002 eq. 10: mdot = A_t P_c Gamma / sqrt(R T)."""
    return math.sqrt(gamma * _pow(2.0 / (gamma + 1.0), (gamma + 1.0) / (gamma - 1.0)))


def nozzle_constants(heat_capacity_ratio, expansion_ratio):
    """(C_F, Gamma) the core takes from the gas's gamma and the nozzle's area ratio: the vacuum
    thrust coefficient (002 eq. 15) and the flow factor (eq. 10)."""
    return thrust_coefficient(expansion_ratio, heat_capacity_ratio), flow_factor(heat_capacity_ratio)


def design(feed):
    """Derived quantities of a ``rcs.feed`` block that is not ``constant``, SI units."""
    gamma, eps = feed["heat_capacity_ratio"], feed["expansion_ratio"]
    rt = feed["gas_constant_j_kg_k"] * feed["temperature_k"]
    area, volume = feed["throat_area_m2"], feed["tank_volume_m3"]
    p0, ambient = feed["initial_pressure_pa"], feed.get("ambient_pressure_pa", AMBIENT_PRESSURE_DEFAULT_PA)
    c_f = thrust_coefficient(eps, gamma)
    factor = flow_factor(gamma)
    exhaust = c_f * math.sqrt(rt) / factor
    gas = p0 * volume / rt
    tau = volume / (area * factor * math.sqrt(rt))

    def thrust(pressure):
        return max(area * (c_f * pressure - eps * ambient), 0.0)

    return {
        "exit_mach": exit_mach(eps, gamma),
        "thrust_coefficient": c_f,
        "flow_factor": factor,
        "exhaust_velocity_m_s": exhaust,
        "specific_impulse_s": exhaust / 9.80665,
        "gas_kg": gas,
        "blow_down_time_constant_s": tau,
        "initial_thrust_n": thrust(p0),
        "thrust_at_half_tank_n": thrust(0.5 * p0),
        # vacuum: all gas through the nozzles, c * m (the ambient term reduces it)
        "total_impulse_n_s": exhaust * gas,
    }


def set_pressure(vehicle, level):
    """Feed regulated: the chamber pressure the regulator holds at thrust ``level``, the one that
    gives its thrust_n (002 eq. 15 solved for P_c); inf for any other feed or level (no rcs)."""
    rcs = vehicle.get("rcs", {})
    feed = rcs.get("feed", {})
    if feed.get("model") != "regulated" or level not in rcs.get("thrust_n", {}):
        return math.inf
    area = feed["throat_area_m2"]
    ambient_force = feed["expansion_ratio"] * feed.get("ambient_pressure_pa", AMBIENT_PRESSURE_DEFAULT_PA) * area
    return (rcs["thrust_n"][level] + ambient_force) / (
        thrust_coefficient(feed["expansion_ratio"], feed["heat_capacity_ratio"]) * area
    )
