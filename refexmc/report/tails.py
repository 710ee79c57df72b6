"""Which end of each runs column is the bad one: the one place the report declares it.

``upper``: larger is worse (durations, angle errors, valve pulses, propellant used, wheel momentum
and torque); the statistics tables show upper percentiles and upper bounds. ``lower``: smaller is worse
(propellant remaining, modes completed); they show lower percentiles and lower bounds. ``both``: a
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
    ("pointing_end_*_arcsec", "both", "pointing error per axis at the end of the pointing window (signed)"),
    ("pointing_*_arcsec", "upper", "pointing error in the pointing window (RMS per axis, largest)"),
    ("wheel_momentum_*_n_m_s", "upper", "largest wheel momentum (over the flight, at its end)"),
    ("wheel_torque_demand_peak_n_m", "upper", "largest wheel motor torque asked for"),
    ("wheel_saturated_s", "upper", "time some wheel was held at its torque or momentum limit"),
    ("angular_momentum_residual", "upper", "relative angular momentum residual (integration check)"),
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
