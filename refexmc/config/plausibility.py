"""Plausibility checks (issue 34): values the schema accepts whose size says a unit slip.

A value inside its schema range can still be off by a unit: 20 K typed for 20 degC, 50 Pa for
50 bar, a valve delay of 0.02 ms for 20 ms, a mass in grams. These checks compare each such value
with the range a GNC engineer would accept for it, and say the likely slip with the value
(docs/campaigns.md, "Plausibility checks"). They are warnings (DesignWarning, with file, line and
key path): printed by ``validate``, ``inspect`` and ``run``, recorded in ``manifest.json``;
``--strict`` refuses them. A check that fails later (a derived check: the reserve a tank cannot
hold, a regulated level the tank cannot give, an allocation a thruster position in mm turns, the
deorbit burn) is re-raised at the implausible value behind it (:func:`blamed`, only values the
check reads), so the error names the key the user set and not only the file where the check lives.

Bounds and why (SI values):
- gas temperature 100..1000 K: below ~100 K nitrogen is liquid at tank pressure (critical point
  126 K), no cold-gas tank holds gas there; above 1000 K no pressure vessel holds it (a titanium or
  composite bottle is rated to ~400 K). Below: a temperature in degC?
- tank pressure >= 1 kPa: a bottle at less than a hundredth of an atmosphere gives no thrust worth
  a valve; <= 100 MPa: flight COPVs are rated to ~70 MPa. Below: a pressure in bar or MPa?
- specific gas constant 50..4200 J/(kg K): xenon (63) to hydrogen (4124). Below: a molar mass in
  g/mol (R = 8314.46 / M), or R in kJ/(kg K)?
- tank volume <= 5 m^3: the largest flight gas bottles hold well under 1 m^3. Above: litres?
- throat area <= 1e-3 m^2 (a 36 mm throat; 2.5 kN of cold gas at 15 MPa): above, mm^2?
- stored gas (P V / (R T)) no more than the vehicle's mass_kg.
- mass and inertia: the uniform ball with the vehicle's mass and mean principal moment
  (trace / 3 = (2/5) m r^2) has a density between 0.1 and 8000 kg/m^3. A ball is the most compact
  body for a given moment: a vehicle whose ball is denser than solid steel (7850) cannot exist
  outside a steel ball; the shipped vehicles lie at 50-1900 kg/m^3, the ISS near 12, a solar
  sail near 1. A mass in grams makes it ~3e7 times denser, an inertia in g m^2 (or kg cm^2) or a
  mass in tonnes ~3e4 times less dense.
- a thruster or engine position no farther from the centre of mass than 1.5 times the vehicle's
  largest dimension (length_m, span_m; the centre of mass lies inside the vehicle), or without
  them 50 times the ball's radius: beyond, a position in mm or cm?
- valve time constants, switching limits and the modulator's pulses (ms) either 0 (ideal) or
  >= 0.1 ms (the fastest piezo valves); below: a time in s? Valve time constants <= 1000 ms.
- an ambient pressure 0 (vacuum) or >= 10 Pa (Mars' summits ~30 Pa): below, bar?
- isp_s (rcs, main engine) >= 20 s (xenon cold gas ~30 s): below, an exhaust velocity in km/s?
  propellant_kg below mass_kg (the propellant is part of it).
- a mission's fuel reserve (reserve_pressure_pa) 0 or >= 1 kPa, as the tank pressure.
- an entry mission's angle-of-attack schedule with some |alpha| >= 1.6 deg (entry vehicles fly
  15-45 deg): every node under it is an angle in rad?
- a truncnorm dispersion whose [low, high] excludes the nominal value (or its mean): every draw
  lies at or near the bound; and a dispersion of a checked key whose draws reach outside its
  plausible range. (A uniform that excludes the nominal is a deliberate range, not checked.)
"""

import contextlib
import math
from typing import NamedTuple

from refexmc.config.design_checks import DesignWarning, warning_at
from refexmc.config.errors import ConfigError

FEED_TEMPERATURE_K = (100.0, 1000.0)
TANK_PRESSURE_PA = (1.0e3, 1.0e8)
GAS_CONSTANT_J_KG_K = (50.0, 4200.0)
UNIVERSAL_GAS_CONSTANT_J_KMOL_K = 8314.46
AMBIENT_MIN_PA = 10.0  # Mars' surface ~600 Pa, its highest summits ~30 Pa; sea level in bar is 1.013
TANK_VOLUME_MAX_M3 = 5.0
THROAT_AREA_MAX_M2 = 1.0e-3
BALL_DENSITY_KG_M3 = (0.1, 8000.0)
POSITION_SIZE_FACTOR = 1.5  # times the largest of length_m, span_m
POSITION_BALL_FACTOR = 50.0  # times the equivalent ball's radius, without length_m or span_m
ISP_MIN_S = 20.0  # xenon cold gas ~30 s, the lowest specific impulse that flies
SHORTEST_TIME_MS = 0.1
LONGEST_VALVE_TIME_MS = 1000.0
ALPHA_RAD_SUSPECT_DEG = 1.6  # a schedule whose every |alpha| is below pi/2 rad reads as radians


class PlausibilityWarning(DesignWarning):
    """A value whose size says a unit slip: ``str()`` is ``file:line: key.path: message``."""


def _warning_at(fail):
    """A warn(message, *path) that builds the PlausibilityWarning where ``fail`` would raise."""
    return warning_at(fail, PlausibilityWarning)


class Range(NamedTuple):
    """A plausible range of a key with the slips a value below or above it suggests."""

    low: float
    high: float
    unit: str
    below: str  # the likely slip of a value below low ("" when none is likely)
    above: str

    def problem(self, value, zero_ok=False):
        """The message for ``value`` outside the range, or None."""
        if zero_ok and value == 0.0:
            return None
        if value < self.low:
            slip, expected = self.below, f">= {self.low:g}"
        elif value > self.high:
            slip, expected = self.above, f"<= {self.high:g}"
        else:
            return None
        return f"{value:g} {self.unit}{': ' + slip if slip else ''} (expected {expected} {self.unit})"


def _temperature_range():
    return Range(
        *FEED_TEMPERATURE_K, "K", "a temperature in degC? (K = degC + 273.15)", "hotter than any gas tank holds"
    )


def _pressure_range():
    return Range(
        *TANK_PRESSURE_PA,
        "Pa",
        "a pressure in bar (x 1e5 Pa) or MPa (x 1e6 Pa)?",
        "above any flight tank's rating (COPVs ~70 MPa)",
    )


def _gas_constant_range():
    return Range(
        *GAS_CONSTANT_J_KG_K,
        "J/(kg K)",
        f"a molar mass in g/mol (R = {UNIVERSAL_GAS_CONSTANT_J_KMOL_K:g} / M; nitrogen 296.8) or R in kJ/(kg K)?",
        "lighter than hydrogen (4124)",
    )


# rcs.feed keys -> their range (the dispersion paths rcs.feed.<key> share them)
FEED_RANGES = {
    "temperature_k": _temperature_range(),
    "initial_pressure_pa": _pressure_range(),
    "gas_constant_j_kg_k": _gas_constant_range(),
    "tank_volume_m3": Range(0.0, TANK_VOLUME_MAX_M3, "m^3", "", "a volume in litres? (1 l = 0.001 m^3)"),
    "throat_area_m2": Range(0.0, THROAT_AREA_MAX_M2, "m^2", "", "an area in mm^2? (1 mm^2 = 1e-6 m^2)"),
}
TIME_MS_RANGE = Range(SHORTEST_TIME_MS, math.inf, "ms", "a time in s? (1 s = 1000 ms)", "")
VALVE_TIME_MS_RANGE = Range(
    SHORTEST_TIME_MS, LONGEST_VALVE_TIME_MS, "ms", "a time in s? (1 s = 1000 ms)", "a time in us?"
)


def ball(mass, inertia):
    """(radius m, density kg/m^3) of the uniform ball with ``mass`` and the mean principal moment
    of ``inertia`` (trace / 3 = (2/5) m r^2)."""
    mean_moment = (inertia[0][0] + inertia[1][1] + inertia[2][2]) / 3.0
    radius = math.sqrt(2.5 * mean_moment / mass)
    return radius, mass / (4.0 / 3.0 * math.pi * radius**3)


def check_vehicle(vehicle, fail):
    """Plausibility warnings of a vehicle (``fail(message, *path)`` raises at a key path of it)."""
    warn = _warning_at(fail)
    out = []
    out += _mass_and_inertia(vehicle, warn)
    out += _propellant(vehicle, warn)
    rcs = vehicle.get("rcs")
    if rcs is not None:
        out += _feed(vehicle, warn)
        for level, constants in rcs["valve_time_constants_ms"].items():
            for name, value in constants.items():
                message = VALVE_TIME_MS_RANGE.problem(value, zero_ok=True)
                if message:
                    out.append(warn(message, "rcs", "valve_time_constants_ms", level, name))
        for key, value in rcs["switching_limits_ms"].items():
            message = TIME_MS_RANGE.problem(value, zero_ok=True)
            if message:
                out.append(warn(message, "rcs", "switching_limits_ms", key))
        pwpf = vehicle["flight_software"].get("pwpf", {})
        for key in ("t_on_ms", "t_off_ms"):
            message = TIME_MS_RANGE.problem(pwpf[key]) if key in pwpf else None
            if message:
                out.append(warn(message, "flight_software", "pwpf", key))
    out += _positions(vehicle, warn)
    return out


def _mass_and_inertia(vehicle, warn):
    mass, inertia = vehicle["mass_kg"], vehicle["inertia_kg_m2"]
    if min(inertia[k][k] for k in range(3)) <= 0.0:
        return []  # not physical: load.inertia_problem refuses it
    radius, density = ball(mass, inertia)
    low, high = BALL_DENSITY_KG_M3
    what = (
        f"mass {mass:g} kg with inertia trace/3 {(inertia[0][0] + inertia[1][1] + inertia[2][2]) / 3.0:.4g} kg m^2 "
        f"is a uniform ball of {density:.3g} kg/m^3 (radius {radius:.3g} m)"
    )
    if density > high:
        return [warn(f"{what}, denser than solid steel: a mass in g? (expected {low:g}..{high:g} kg/m^3)", "mass_kg")]
    if density < low:
        return [
            warn(
                f"{what}: an inertia in g m^2 or kg cm^2, or a mass in t? (expected {low:g}..{high:g} kg/m^3)",
                "inertia_kg_m2",
            )
        ]
    return []


def _propellant(vehicle, warn):
    """isp_s and propellant_kg of the rcs (constant feed) and the main engine."""
    out = []
    for root in ("rcs", "main_engine"):
        part = vehicle.get(root, {})
        isp = part.get("isp_s")
        if isp is not None and isp < ISP_MIN_S:
            out.append(
                warn(
                    f"{isp:g} s: an exhaust velocity in km/s? (Isp = c / 9.80665 m/s^2; expected >= {ISP_MIN_S:g} s)",
                    root,
                    "isp_s",
                )
            )
        propellant = part.get("propellant_kg")
        if propellant is not None and propellant >= vehicle["mass_kg"]:
            out.append(
                warn(
                    f"{propellant:g} kg of propellant in a vehicle of mass_kg {vehicle['mass_kg']:g} (the propellant "
                    "is part of it): a mass in g, or the mass in t?",
                    root,
                    "propellant_kg",
                )
            )
    return out


def _feed(vehicle, warn):
    feed = vehicle["rcs"].get("feed", {})
    out = []
    for key, limits in FEED_RANGES.items():
        if key in feed:
            message = limits.problem(feed[key])
            if message:
                out.append(warn(message, "rcs", "feed", key))
    ambient = feed.get("ambient_pressure_pa", 0.0)
    if 0.0 < ambient < AMBIENT_MIN_PA:
        out.append(
            warn(
                f"{ambient:g} Pa: a pressure in bar (x 1e5 Pa)? (expected 0 for vacuum or >= {AMBIENT_MIN_PA:g} Pa)",
                "rcs",
                "feed",
                "ambient_pressure_pa",
            )
        )
    if all(key in feed for key in ("initial_pressure_pa", "tank_volume_m3", "gas_constant_j_kg_k", "temperature_k")):
        gas = (
            feed["initial_pressure_pa"] * feed["tank_volume_m3"] / (feed["gas_constant_j_kg_k"] * feed["temperature_k"])
        )
        if gas > vehicle["mass_kg"]:
            out.append(
                warn(
                    f"the tank holds {gas:.4g} kg of gas (P V / (R T)), more than the vehicle's mass_kg "
                    f"{vehicle['mass_kg']:g}: a pressure, volume or temperature in another unit?",
                    "rcs",
                    "feed",
                )
            )
    return out


def _positions(vehicle, warn):
    size = max(vehicle.get("length_m", 0.0), vehicle.get("span_m", 0.0))
    inertia = vehicle["inertia_kg_m2"]
    if size > 0.0:
        limit, why = (
            POSITION_SIZE_FACTOR * size,
            f"{POSITION_SIZE_FACTOR:g} x the vehicle's largest dimension {size:g} m",
        )
    elif min(inertia[k][k] for k in range(3)) > 0.0:
        radius = ball(vehicle["mass_kg"], inertia)[0]
        limit, why = (
            POSITION_BALL_FACTOR * radius,
            f"{POSITION_BALL_FACTOR:g} x the radius {radius:.3g} m of the ball of its mass and inertia",
        )
    else:
        return []
    places = [
        (("rcs", "thrusters", i, "position_m"), t["position_m"])
        for i, t in enumerate(vehicle.get("rcs", {}).get("thrusters", []))
    ]
    if "position_m" in vehicle.get("main_engine", {}):
        places.append((("main_engine", "position_m"), vehicle["main_engine"]["position_m"]))
    far = [(path, math.sqrt(sum(x * x for x in position))) for path, position in places]
    far = [(path, distance) for path, distance in far if distance > limit]
    if not far:
        return []
    (path, distance), more = far[0], len(far) - 1  # one warning: the first, and how many more
    also = f" (and {more} more position{'s' if more > 1 else ''})" if more else ""
    return [warn(f"{distance:.4g} m from the centre of mass{also}, beyond {why}: a position in mm or cm?", *path)]


def check_mission(mission, fail):
    """Plausibility warnings of a mission (``fail(message, *path)`` raises at a key path of it)."""
    warn = _warning_at(fail)
    out = []
    reserve = mission.get("local", {}).get("reserve_pressure_pa")
    if reserve is not None:
        message = _pressure_range().problem(reserve, zero_ok=True)
        if message:
            out.append(warn(message, "local", "reserve_pressure_pa"))
    schedule = mission.get("entry_flight", {}).get("alpha_schedule", [])
    if schedule and max(abs(node["alpha_deg"]) for node in schedule) < ALPHA_RAD_SUSPECT_DEG:
        largest = max(abs(node["alpha_deg"]) for node in schedule)
        out.append(
            warn(
                f"every angle of attack is under {ALPHA_RAD_SUSPECT_DEG:g} deg (largest {largest:g}): angles in rad? "
                f"({largest:g} rad = {math.degrees(largest):.3g} deg; entry vehicles fly 15-45 deg)",
                "entry_flight",
                "alpha_schedule",
            )
        )
    return out


# dispersion paths whose draws have a plausible range (rcs.feed.<key> as the vehicle's key)
DISPERSION_RANGES = {f"rcs.feed.{key}": limits for key, limits in FEED_RANGES.items()}


def check_dispersions(specs, nominal, file, lines):
    """Plausibility warnings of a campaign's checked dispersions ``specs`` (config.dispersions.check):
    a truncnorm whose bounds exclude the nominal value (``nominal(path)``: an array per component)
    or its mean; an rcs.feed key's constant, truncnorm or uniform that reaches outside its range."""
    out = []
    for path, spec in specs.items():
        where = ("dispersions", path)

        def warn(message, *sub, _where=where):
            key = _where + sub
            line = lines.get(key) or lines.get(_where) or lines.get(("dispersions",))
            return PlausibilityWarning(message, file=file, line=line, path=key)

        dist = spec["dist"]
        if dist == "truncnorm":
            out += _bounds_exclude(spec, list(nominal(path)), warn)
        limits = DISPERSION_RANGES.get(path)
        if limits is not None and dist in ("constant", "truncnorm", "uniform"):
            values = spec["value"] if dist == "constant" else [*spec["low"], *spec["high"]]
            for value in values:
                message = limits.problem(float(value)) if math.isfinite(value) else None
                if message:
                    out.append(warn(f"draws reach {message}", "value" if dist == "constant" else "dist"))
                    break
    return out


def check_sweep(axes, file, lines):
    """Plausibility warnings of a sweep's ``axes`` (config.sweep, checked): a swept rcs.feed key's
    value outside its range (each point flies it as the file's value: the same slips as in the file)."""
    from refexmc.config.sweep import axis_values  # the sweep's own arithmetic; no cycle at import

    out = []
    for i, axis in enumerate(axes):
        limits = DISPERSION_RANGES.get(axis["parameter"])
        if limits is None or "dispersion" in axis:
            continue
        key = ("sweep", "axes", i, "values" if "values" in axis else "range")
        for value in axis_values(axis):
            message = limits.problem(value) if math.isfinite(value) else None
            if message:
                line = lines.get(key) or lines.get(("sweep", "axes", i))
                message = f"{axis['parameter']} swept to {message}"
                out.append(PlausibilityWarning(message, file=file, line=line, path=key))
                break
    return out


def _bounds_exclude(spec, nominal, warn):
    """A truncnorm whose [low, high] excludes its mean (the nominal by default): its draws pile up
    at the bound; or excludes the nominal (its mean given inside): no draw is the value the nominal
    run flies. (A uniform that excludes the nominal is a deliberate range: IRASSI's noise levels
    are drawn from a band above the mission's placeholder 0.)"""
    for k, (low, high) in enumerate(zip(spec["low"], spec["high"], strict=True)):
        which = f" (component {k + 1})" if len(nominal) > 1 else ""
        mean, given = float(spec["mean"][k]), spec["mean"][k] != nominal[k]
        for centre, consequence in (
            (mean, "every draw lies near the bound"),
            (nominal[k], "no draw is the value the nominal run flies"),
        ):
            if low <= centre <= high:
                continue
            name = "its mean" if given and centre == mean else "the nominal"
            key = "low" if centre < low else "high"
            return [
                warn(
                    f"truncnorm bounds [{low:g}, {high:g}]{which} exclude {name} {centre:g}: {consequence} "
                    "(a bound on the wrong side, or a value in another unit?)",
                    key,
                )
            ]
    return []


@contextlib.contextmanager
def blamed(found, *inputs):
    """Re-raise a ConfigError raised inside at the first plausibility warning of the list ``found``
    (of those whose key path holds one of the keys ``inputs``, when given): a derived check that
    fails on an implausible value names the key the user set."""
    try:
        yield
    except ConfigError as error:
        suspects = [
            w
            for w in found
            if isinstance(w, PlausibilityWarning) and (not inputs or any(key in w.path for key in inputs))
        ]
        if not suspects or isinstance(error, DesignWarning):
            raise
        first = suspects[0]
        raise ConfigError(
            f"{first.message}; with it: {error}", file=first.file, line=first.line, path=first.path
        ) from None
