"""The flown standard atmosphere (core.atmosphere) against the U.S. Standard Atmosphere 1976 as
the ``ussa1976`` package computes it (003's model), at 1000 random altitudes 0-150 km.

Tolerance: the core interpolates ln density and speed of sound linearly between table rows, and
every cell is smooth (the grid holds every temperature kink), so on a cell of width h the error is
at most h^2/8 max|f''| (linear interpolation's bound). The test estimates max|f''| on each cell
from the package itself (second differences on 41 points, times 1.5 for what they miss) and adds
1e-12 relative for rounding; the worst is 4e-4 relative in density (above 100 km), far below the density dispersion.
"""

import math
import sys
from pathlib import Path

import numpy as np
import pytest

from refexmc.config.atmosphere import standard_table
from refexmc.core import atmosphere

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "configs" / "atmospheres"))
ussa = pytest.importorskip("ussa1976")
import gen_ussa1976  # noqa: E402

ROUNDING_REL = 1e-12
MISSED_CURVATURE = 1.5  # second differences on 41 points underestimate max|f''| a little


def second_derivative_bounds(table, cells):
    """{cell k: max |f''| on [table[k, 0], table[k + 1, 0]] of ln density and of speed of sound},
    from the reference on 41 points of each cell (one ``ussa1976`` call for every cell: its values
    at a point do not depend on the other points asked for, and a call costs ~0.1 s)."""
    grids = {k: np.linspace(table[k, 0], table[k + 1, 0], 41) for k in cells}
    points = np.unique(np.concatenate(list(grids.values())))  # neighbouring cells share an end
    rho_all, sound_all, _ = gen_ussa1976.reference(points)
    bounds = {}
    for k, z in grids.items():
        at = np.searchsorted(points, z)
        rho, sound = rho_all[at], sound_all[at]
        step = z[1] - z[0]
        curvature = [np.abs(np.diff(np.log(f), 2)).max() / step**2 for f in (rho,)]
        curvature.append(np.abs(np.diff(sound, 2)).max() / step**2)
        bounds[k] = [MISSED_CURVATURE * c for c in curvature]
    return bounds


@pytest.fixture(scope="module")
def table():
    return standard_table()


def test_density_and_speed_of_sound_equal_ussa1976_within_the_interpolation_bound(table):
    rng = np.random.default_rng(1976)
    altitudes = np.sort(rng.uniform(0.0, 150e3, 1000))
    rho_ref, sound_ref, _ = gen_ussa1976.reference(altitudes)
    bounds = second_derivative_bounds(table, {atmosphere.cell(table, h) for h in altitudes})
    worst = 0.0
    for h, rho_expected, sound_expected in zip(altitudes, rho_ref, sound_ref, strict=True):
        k = atmosphere.cell(table, h)
        low, high = table[k, 0], table[k + 1, 0]
        assert low <= h <= high
        width2 = (high - low) ** 2 / 8.0
        ln_rho_bound = width2 * bounds[k][0]
        sound_bound = width2 * bounds[k][1]
        rho, sound, _ = atmosphere.properties(table, h)
        ln_error = abs(math.log(rho / rho_expected))
        assert ln_error <= ln_rho_bound + ROUNDING_REL, f"density at {h:.1f} m: {rho} vs {rho_expected}"
        assert abs(sound - sound_expected) <= sound_bound + ROUNDING_REL * sound_expected, f"sound at {h:.1f} m"
        worst = max(worst, ln_error)
    assert worst < 5e-4  # the stated order: the 0.5 km grid keeps density within 5e-4 relative


def test_the_table_reproduces_its_rows_and_the_sea_level_standard(table):
    rho, sound, temperature = atmosphere.properties(table, 0.0)
    # USSA 1976 sea level: 1.225 kg/m^3, 340.294 m/s, 288.15 K (NASA-TM-X-74335 Table I)
    assert rho == pytest.approx(1.225, rel=1e-6)
    assert sound == pytest.approx(340.294, rel=1e-6)
    assert temperature == pytest.approx(288.15, rel=1e-12)
    for k in (1, 100, table.shape[0] - 1):
        rho, sound, _ = atmosphere.properties(table, table[k, 0])
        assert math.log(rho) == pytest.approx(table[k, 1], rel=1e-14)
        assert sound == pytest.approx(table[k, 2], rel=1e-14)


def test_the_table_reaches_the_entry_interface_and_beyond(table):
    """003's entry starts above 120 km (400 kft = 121.9 km): the table must cover it."""
    assert table[0, 0] == 0.0 and table[-1, 0] >= 150e3
    assert np.all(np.diff(table[:, 0]) > 0.0)
    rho_120, _, _ = atmosphere.properties(table, 120e3)
    assert rho_120 == pytest.approx(2.222e-8, rel=0.01)  # USSA 1976 Table I at 120 km: 2.222e-8 kg/m^3
