"""The input tables of one flight, as the core takes them (``refexmc.config.pack`` fills them)."""

from typing import NamedTuple

import numpy as np


class RunInputs(NamedTuple):
    """Float64 tables with the column offsets of ``refexmc.core.layout``."""

    vehicle: np.ndarray  # layout.VEHICLE, the dispersed truth
    thrusters: np.ndarray  # one layout.THRUSTER row per thruster, then its time constants per level
    levels: np.ndarray  # one layout.LEVEL row per thrust level
    fsw: np.ndarray  # layout.FSW, the flight software's design
    mission: np.ndarray  # layout.MISSION
    modes: np.ndarray  # one layout.MODE row per mode, in flight order
    exits: np.ndarray  # layout.EXIT rows of every mode's exit conditions
    nav: np.ndarray  # layout.NAV
    atmosphere: np.ndarray  # rows [base altitude m, density kg/m^3, scale height m]
    allocation: np.ndarray  # 27 rows x thrusters: thrusters opened per axis-command combination
    nominal: np.ndarray  # layout.NOMINAL rows of the nominal deorbit burn (orbit missions; else no rows)
    wheels: np.ndarray  # one layout.WHEEL row per reaction wheel (no rows: no wheels)
    wheel_distribution: np.ndarray  # (wheels, 3): the flight software's distribution matrix (001 sec. 9.1)
