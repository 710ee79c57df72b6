"""Which end of each runs column is the bad one: the one place the report declares it.

``upper``: larger is worse (durations, angle errors, valve pulses, propellant used of any kind, wheel
momentum and torque, peaks, non-negative magnitudes such as the largest sideslip or the speed at the
end); the statistics tables show upper percentiles and upper bounds. ``lower``: smaller is worse
(propellant remaining, modes completed, tank pressure left); they show lower percentiles and lower bounds. ``both``: a
signed quantity (a pointing error per axis at the end), whose statistics tables show both ends.
The first rule whose pattern (``fnmatch``) matches a column decides; docs/report.md lists them.
"""

from fnmatch import fnmatchcase

TAIL_RULES = (  # (column pattern, worse tail, what the column is)
    ("fuel_remaining", "lower", "propellant remaining (fraction of the load)"),
    ("modes_completed", "lower", "modes completed"),
    ("fuel_used_kg", "upper", "propellant used"),
    ("attitude_error_end_deg", "upper", "total attitude error when the last mode ends"),
    ("burn_pointing_*_deg", "upper", "engine pointing error during a burn (RMS, largest)"),
    ("engine_propellant_used_kg", "upper", "main-engine propellant used"),
    ("rcs_propellant_kg", "upper", "RCS propellant used"),
    ("*propellant*_kg", "upper", "propellant used (a mass in kg; what is left is fuel_remaining)"),
    ("pointing_end_*_arcsec", "both", "pointing error per axis at the end of the pointing window (signed)"),
    ("pointing_*_arcsec", "upper", "pointing error in the pointing window (RMS per axis, largest)"),
    ("wheel_momentum_*_n_m_s", "upper", "largest wheel momentum (over the flight, at its end)"),
    ("wheel_torque_demand_peak_n_m", "upper", "largest wheel motor torque asked for"),
    ("wheel_saturated_s", "upper", "time some wheel was held at its torque or momentum limit"),
    ("angular_momentum_residual", "upper", "relative angular momentum residual (integration check)"),
    ("*_error_max_deg", "upper", "largest tracking error after the transients (an entry's α, bank; a magnitude)"),
    ("beta_max_deg", "upper", "largest sideslip angle after the transients (a magnitude, commanded 0)"),
    ("peak_*", "upper", "peak of a load (dynamic pressure, load factor, heat flux)"),
    ("position_error_end_m", "upper", "distance to the target at the end (a magnitude)"),
    ("speed_end_m_s", "upper", "speed at the end (a magnitude: the hop must stop)"),
    ("tank_pressure_end_pa", "lower", "tank pressure left at the end"),
    ("switches_*", "upper", "command changes per body axis (valve cycles)"),
    ("t_end_s", "upper", "flight duration"),
    ("t_*_s", "upper", "time spent in a mode"),
    ("pulses_*", "upper", "valve pulses (per thruster, and pulses_total)"),
)


def worse_tail(column):
    """ "upper", "lower" or "both" for a column of ``TAIL_RULES``; None for any other (e.g. ``p.`` inputs)."""
    for pattern, tail, _ in TAIL_RULES:
        if fnmatchcase(column, pattern):
            return tail
    return None
