"""Each mission's columns show their worse tail (refexmc/report/tails.py, docs/report.md's table):
propellant used of any kind is upper-tail, non-negative magnitudes (an entry's largest sideslip, a
hop's speed at the end) upper-tail, what is left lower-tail; a quantity with two bad ends (an
entry state, a signed error) keeps both."""

import pytest

from refexmc.report.tails import worse_tail


@pytest.mark.parametrize(
    ("column", "tail"),
    [
        ("rcs_propellant_kg", "upper"),  # RCS propellant used (README: propellant used is upper-tail)
        ("engine_propellant_used_kg", "upper"),
        ("fuel_used_kg", "upper"),
        ("beta_max_deg", "upper"),  # the largest |beta| after the transients (core.entry_flight)
        ("alpha_error_max_deg", "upper"),
        ("bank_error_max_deg", "upper"),
        ("peak_qbar_pa", "upper"),
        ("peak_load_g", "upper"),
        ("peak_heat_flux_w_m2", "upper"),
        ("speed_end_m_s", "upper"),  # the hop: a speed magnitude, it must stop
        ("position_error_end_m", "upper"),
        ("switches_x", "upper"),
        ("tank_pressure_end_pa", "lower"),
        ("fuel_remaining", "lower"),
        ("pointing_end_x_arcsec", "both"),  # signed
        ("down_range_m", None),  # an entry state: no rule, both ends unless a requirement says
        ("terminal_mach", None),
    ],
)
def test_each_column_has_its_worse_tail(column, tail):
    assert worse_tail(column) == tail
