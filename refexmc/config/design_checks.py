"""Design checks: files that are well formed but describe a design that cannot fly as meant (issue 26).

Run by ``validate``, ``inspect`` and ``run`` (through :mod:`refexmc.config.load`). Errors raise
ConfigError (file, line, key path; exit 2); warnings are :class:`DesignWarning` objects, printed
by the commands and recorded in ``manifest.json``; ``--strict`` makes them errors.

Errors:
- an allocation entry whose thrusters realise no torque, or torque of the other sign, about an
  axis the entry is listed for (from the thruster geometry, derating included);
- a thruster direction that is not a unit vector (norm off 1 by more than
  ``DIRECTION_NORM_TOLERANCE``): ``[0, 2, 0]`` or ``[0, 1, 0.3]`` is a typo, not a direction;
  within the tolerance (rounded digits) it is normalised as before.

Warnings (docs/missions.md, "Design checks"):
- ``thrusters_per_axis`` (000 eq. 1's n_t) differs by half a thruster or more from what the
  table's single-axis entries realise: omega_dot_max, tau_max and derived gains are then off;
- the modulator's shortest pulse t_on - correction is below the hardware ``min_on``;
- a switching limit that is not a whole number of control periods (pulses and rests are whole
  periods with pwpf_table): it becomes the next whole number of periods;
- an exit threshold on rates (rate damping) or on the angle error (attitude-controlled modes)
  inside the controller's deadband at the mode's thrust level: the errors can stay there without
  a valve firing, and the mode may never exit.
"""

import math

import numpy as np

from refexmc import smallmatrix
from refexmc.config import derived
from refexmc.config.errors import ConfigError

DIRECTION_NORM_TOLERANCE = 1e-3  # a unit vector written with ~4 significant digits is within it
THRUSTER_COUNT_TOLERANCE = 0.5  # n_t is a count: half a thruster's torque apart is a different count
TIME_EPS_MS = 1e-6  # switching limits compared with whole control periods as in exact arithmetic
# attitude-controlled kinds: the controller's Kp term acts (modes.reference); rate damping: rates only
ATTITUDE_KINDS = ("slew", "spin_up", "hold", "track", "burn")


class DesignWarning(ConfigError):
    """A design finding: ``str()`` is ``file:line: key.path: message``, as for errors."""


def strict_error(warnings):
    """The ConfigError that ``--strict`` makes of design warnings: the first, and how many there are."""
    first = warnings[0]
    more = f" (and {len(warnings) - 1} more)" if len(warnings) > 1 else ""
    return ConfigError(
        f"{first.message} [--strict: design warnings are errors{more}]",
        file=first.file,
        line=first.line,
        path=first.path,
    )


def warning_at(fail, kind=DesignWarning):
    """A warn(message, *path) that builds a ``kind`` warning where ``fail`` would raise the error."""

    def warn(message, *path):
        try:
            fail(message, *path)
        except ConfigError as exc:
            return kind(exc.message, file=exc.file, line=exc.line, path=exc.path)
        raise AssertionError("fail() must raise")  # pragma: no cover

    return warn


def _fmt(values, digits=4):
    return "[" + ", ".join(f"{v:.{digits}g}" for v in values) + "]"


def check_vehicle(vehicle, fail):
    """Errors of a vehicle's thruster design (raised through ``fail(message, *key_path)``) and its
    warnings (returned as a list of DesignWarning)."""
    if "rcs" not in vehicle:
        return []
    _check_directions(vehicle, fail)
    fsw = vehicle["flight_software"]
    if fsw["actuation"] != "pwpf_table" or "allocation" not in fsw:
        return []
    _check_allocation_signs(vehicle, fail)
    warn = warning_at(fail)
    return [*_thrusters_per_axis(vehicle, warn), *_pulse_limits(vehicle, warn)]


def _check_directions(vehicle, fail):
    for i, thruster in enumerate(vehicle["rcs"]["thrusters"]):
        direction = np.asarray(thruster["direction"], dtype=float)
        norm = float(smallmatrix.norm(direction))
        if norm > 0.0 and abs(norm - 1.0) > DIRECTION_NORM_TOLERANCE:
            fail(
                f"expected a unit force direction (norm 1 within {DIRECTION_NORM_TOLERANCE:g}), got "
                f"{_fmt(direction)} of norm {norm:.4g}; the unit vector along it is {_fmt(direction / norm)}",
                "rcs",
                "thrusters",
                i,
                "direction",
            )


def _check_allocation_signs(vehicle, fail):
    """Each listed entry turns the body the way its key says about every axis the key names."""
    for key, ids in vehicle["flight_software"]["allocation"].items():
        if not ids:  # opens nothing: the vehicle declares no torque for this command (thrusters through the CoM)
            continue
        per_newton = derived.entry_torque_per_newton(vehicle, ids)
        scale = max(float(np.abs(derived.torque_arms(vehicle)).max()), 1e-12)
        for sign, axis in zip(key[::2], key[1::2], strict=True):
            k = "xyz".index(axis)
            value = per_newton[k] * (1.0 if sign == "+" else -1.0)
            if value <= 1e-9 * scale:
                level = derived.rcs_level_names(vehicle)[0]
                thrust = vehicle["rcs"]["thrust_n"][level]
                torque = per_newton * thrust
                factor = derived.derating_factor(vehicle, len(ids))
                what = "no torque" if abs(value) <= 1e-9 * scale else "a torque of the opposite sign"
                fail(
                    f"entry '{key}' realises {what} about {axis}: thrusters {', '.join(map(str, ids))} give "
                    f"{_fmt(torque)} N m at {level} thrust ({thrust:g} N, derated x{factor:g}); expected "
                    f"{'positive' if sign == '+' else 'negative'} torque about {axis} (thruster positions, "
                    "directions or the entry are wrong)",
                    "flight_software",
                    "allocation",
                    key,
                )


def _thrusters_per_axis(vehicle, warn):
    n_t = vehicle["flight_software"]["thrusters_per_axis"]
    effective = derived.effective_thrusters_per_axis(vehicle)
    entries = vehicle["flight_software"]["allocation"]
    arms = derived.lever_arms(vehicle)
    out = []
    for k, axis in enumerate("xyz"):
        if arms[k] == 0.0 or not (entries.get("+" + axis) or entries.get("-" + axis)):
            continue  # no torque about this axis at all: nothing for n_t to describe
        worth = {sign: effective[sign + axis] for sign in "+-"}
        off = {sign: n for sign, n in worth.items() if abs(n - n_t[k]) >= THRUSTER_COUNT_TOLERANCE}
        if off:
            sign, n = max(off.items(), key=lambda item: abs(item[1] - n_t[k]))
            ratio = f"{n_t[k] / n:.2f} x" if n > 0 else "infinitely"
            out.append(
                warn(
                    f"thrusters_per_axis {axis} is {n_t[k]}, but the allocation's '{sign}{axis}' entry realises "
                    f"{n:.2f} thrusters' torque about {axis} (derated, at the lever arm "
                    f"{derived.lever_arms(vehicle)[k]:.4g} m): omega_dot_max, tau_max and derived gains on {axis} "
                    f"(000 eq. 1, 38) assume {ratio} what the thrusters give",
                    "flight_software",
                    "thrusters_per_axis",
                    k,
                )
            )
    return out


def _pulse_limits(vehicle, warn):
    fsw = vehicle["flight_software"]
    pwpf = fsw["pwpf"]
    limits = vehicle["rcs"]["switching_limits_ms"]
    period_ms = 1e3 / fsw["control_rate_hz"]
    out = []
    shortest = pwpf["t_on_ms"] - pwpf["correction_ms"]
    if shortest < limits["min_on"] - TIME_EPS_MS:
        out.append(
            warn(
                f"the modulator's shortest pulse t_on - correction = {pwpf['t_on_ms']:g} - {pwpf['correction_ms']:g} = "
                f"{shortest:g} ms is below the hardware min_on {limits['min_on']:g} ms: the switching check "
                "stretches it, and f_min (000 eq. 44) no longer is the smallest torque the modulator commands",
                "flight_software",
                "pwpf",
                "t_on_ms",
            )
        )
    for key, what in (("min_on", "pulse"), ("min_off", "rest")):
        value = limits[key]
        periods = value / period_ms
        whole = math.ceil(periods - TIME_EPS_MS / period_ms)
        if value > 0.0 and abs(periods - round(periods)) * period_ms > TIME_EPS_MS:
            becomes = max(whole, 1) * period_ms
            short = "shorter than the" if value < period_ms else "not a whole number of"
            plural = "" if value < period_ms else "s"
            out.append(
                warn(
                    f"{key} {value:g} ms is {short} {period_ms:g} ms control period{plural}: "
                    f"valves switch on the control grid, so the shortest {what} is {becomes:g} ms",
                    "rcs",
                    "switching_limits_ms",
                    key,
                )
            )
    return out


def check_flight(vehicle, mission, warn_fail):
    """Warnings of a mission flown by a vehicle: exit thresholds inside the controller's deadband.
    ``warn_fail(message, *key_path)`` raises ConfigError at a key path of the mission file."""
    if "rcs" not in vehicle or derived.deadbands(vehicle, derived.rcs_level_names(vehicle)[0]) is None:
        return []
    warn = warning_at(warn_fail)
    levels = derived.level_names(vehicle)
    out = []
    for m, mode in enumerate(mission["modes"]):
        level = mode.get("thrust", levels[0])
        rate_db, angle_db = derived.deadbands(vehicle, level)
        for g, group in enumerate(mode.get("exit", [])):
            for key, value in group.items():
                if mode["kind"] == "rate_damping" and key in ("rates_below_deg_s", "rate_error_below_deg_s"):
                    band, what = np.degrees(rate_db), "rate"
                    unit = "deg/s"
                    why = "rates below it are not damped"
                elif mode["kind"] in ATTITUDE_KINDS and key == "angle_error_below_deg":
                    band, what = np.degrees(angle_db), "angle"
                    unit = "deg"
                    why = "angle errors below it are not corrected"
                else:
                    continue
                # an axis with no torque or no gain has no deadband to speak of (never controlled)
                inside = [axis for axis, b in zip("xyz", band, strict=True) if math.isfinite(b) and value < b]
                if inside:
                    out.append(
                        warn(
                            f"{key} {value:g} lies inside the controller's {what} deadband at {level} thrust "
                            f"{_fmt(band, 3)} {unit} (x, y, z; tau_min/(J K{'d' if what == 'rate' else 'p'})): "
                            f"{why} on {', '.join(inside)}, no valve fires, and the mode may never exit "
                            "(`refexmc inspect` prints the deadbands)",
                            "modes",
                            m,
                            "exit",
                            g,
                            key,
                        )
                    )
    return out
