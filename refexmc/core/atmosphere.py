"""Tabulated standard atmosphere for the entry flight (003: U.S. Standard Atmosphere 1976).

The table is ``(n, 4)`` rows ``[altitude m, ln density, speed of sound m/s, temperature K]``
with strictly increasing altitudes (``refexmc.config.atmosphere.standard_table``). Between rows,
ln density, speed of sound and temperature are linear in altitude (density exponential); below
the first and above the last row the end cell is extended the same way.
"""

from refexmc._jit import jit_noalloc
from refexmc.core import elementary

ATM_ALTITUDE = 0
ATM_LN_DENSITY = 1
ATM_SPEED_OF_SOUND = 2
ATM_TEMPERATURE = 3
ATMOSPHERE_COLUMNS = 4


@jit_noalloc
def cell(table, altitude):
    """Index k of the cell [table[k], table[k + 1]] holding ``altitude`` (bisection; end cells
    extend outwards)."""
    low = 0
    high = table.shape[0] - 1
    if altitude <= table[0, ATM_ALTITUDE]:
        return 0
    if altitude >= table[high, ATM_ALTITUDE]:
        return high - 1
    while high - low > 1:
        middle = (low + high) // 2
        if table[middle, ATM_ALTITUDE] <= altitude:
            low = middle
        else:
            high = middle
    return low


@jit_noalloc
def properties(table, altitude):
    """Density (kg/m^3), speed of sound (m/s) and temperature (K) at ``altitude`` (m)."""
    k = cell(table, altitude)
    h0 = table[k, ATM_ALTITUDE]
    f = (altitude - h0) / (table[k + 1, ATM_ALTITUDE] - h0)
    ln_rho = table[k, ATM_LN_DENSITY] + f * (table[k + 1, ATM_LN_DENSITY] - table[k, ATM_LN_DENSITY])
    sound = table[k, ATM_SPEED_OF_SOUND] + f * (table[k + 1, ATM_SPEED_OF_SOUND] - table[k, ATM_SPEED_OF_SOUND])
    temperature = table[k, ATM_TEMPERATURE] + f * (table[k + 1, ATM_TEMPERATURE] - table[k, ATM_TEMPERATURE])
    return elementary.exp(ln_rho), sound, temperature
