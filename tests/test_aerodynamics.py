"""Coefficient tables over (alpha, Mach) (core.aerodynamics) against scipy's bilinear
interpolator; outside the axes the kernel holds the edge value (scipy given the clipped point).
Both compute the same bilinear form in another order: 1e-13 relative covers the rounding."""

import numpy as np
import pytest
from scipy.interpolate import RegularGridInterpolator

from refexmc.core import aerodynamics


def test_bilinear_with_held_edges_equals_scipy():
    rng = np.random.default_rng(3)
    alpha_axis = np.sort(rng.uniform(-0.2, 0.9, 9))
    mach_axis = np.sort(rng.uniform(1.0, 30.0, 6))
    table = rng.normal(size=(aerodynamics.AERO_COEFFICIENTS, 9, 6))
    for slot in (aerodynamics.AC_LIFT, aerodynamics.AC_YAW_RUDDER):
        reference = RegularGridInterpolator((alpha_axis, mach_axis), table[slot])
        for alpha, mach in zip(rng.uniform(-0.5, 1.2, 500), rng.uniform(0.0, 35.0, 500), strict=True):
            clipped = [[np.clip(alpha, alpha_axis[0], alpha_axis[-1]), np.clip(mach, mach_axis[0], mach_axis[-1])]]
            got = aerodynamics.coefficient(alpha_axis, mach_axis, table, slot, alpha, mach)
            assert got == pytest.approx(float(reference(clipped)[0]), rel=1e-13, abs=1e-14)


def test_a_single_mach_column_is_a_function_of_alpha_only():
    alpha_axis = np.array([0.0, 0.5, 1.0])
    table = np.zeros((aerodynamics.AERO_COEFFICIENTS, 3, 1))
    table[aerodynamics.AC_DRAG, :, 0] = [0.1, 0.4, 1.0]
    for mach in (0.5, 7.0, 40.0):
        got = aerodynamics.coefficient(alpha_axis, np.array([10.0]), table, aerodynamics.AC_DRAG, 0.75, mach)
        assert got == pytest.approx(0.7, rel=1e-15)


def test_all_coefficients_at_once_equal_each_one_alone():
    rng = np.random.default_rng(4)
    alpha_axis = np.sort(rng.uniform(-0.2, 0.9, 7))
    mach_axis = np.sort(rng.uniform(1.0, 30.0, 5))
    table = rng.normal(size=(aerodynamics.AERO_COEFFICIENTS, 7, 5))
    out = np.zeros(aerodynamics.AERO_COEFFICIENTS)
    for alpha, mach in zip(rng.uniform(-0.5, 1.2, 200), rng.uniform(0.0, 35.0, 200), strict=True):
        aerodynamics.coefficients_at(alpha_axis, mach_axis, table, alpha, mach, out)
        for slot in range(aerodynamics.AERO_COEFFICIENTS):
            assert out[slot] == aerodynamics.coefficient(alpha_axis, mach_axis, table, slot, alpha, mach)
