"""The standard atmosphere table the entry flight flies (core.atmosphere).

``configs/atmospheres/ussa1976.csv`` holds the U.S. Standard Atmosphere 1976 (003's model) on a
0.5 km grid plus every temperature kink, 0-150 km, written by ``gen_ussa1976.py`` beside it from
the ``ussa1976`` package; ``tests/test_atmosphere.py`` checks the flown interpolation against
that package at 1000 altitudes.
"""

import functools
from pathlib import Path

import numpy as np

from refexmc import crmath
from refexmc.core.atmosphere import ATMOSPHERE_COLUMNS

USSA1976_CSV = Path(__file__).resolve().parents[2] / "configs" / "atmospheres" / "ussa1976.csv"


@functools.cache
def _read(path):
    data = np.loadtxt(path, delimiter=",", comments="#", skiprows=2)
    if data.ndim != 2 or data.shape[1] != 4 or np.any(np.diff(data[:, 0]) <= 0.0) or np.any(data[:, 1:] <= 0.0):
        raise ValueError(f"{path}: expected rows altitude_m,density,speed_of_sound,temperature, altitude increasing")
    table = np.empty((data.shape[0], ATMOSPHERE_COLUMNS))
    table[:, 0] = data[:, 0]
    table[:, 1] = crmath.log(data[:, 1])  # correctly rounded: the same bits on every CPU
    table[:, 2] = data[:, 2]
    table[:, 3] = data[:, 3]
    table.setflags(write=False)
    return table


def standard_table(path=USSA1976_CSV):
    """``(n, 4)`` rows ``[altitude m, ln density, speed of sound m/s, temperature K]`` (read-only)."""
    return _read(Path(path))
