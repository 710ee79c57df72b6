"""Aerodynamic coefficient tables over (angle of attack, Mach) (issue 24, 003 eq. 6).

A vehicle's coefficients are one array ``(AERO_COEFFICIENTS, n_alpha, n_mach)`` on strictly
increasing axes ``alpha_axis`` (rad) and ``mach_axis``; each is interpolated bilinearly and held
at the edge value outside the axes (refexmc.config validates the tables before flight). Slots:
force coefficients, the static moment coefficients and the control derivatives of 003 eq. 6 and
eq. 10 (per radian of deflection). Moment coefficients use the reference length.
"""

from refexmc._jit import jit_noalloc

AC_LIFT = 0  # C_L
AC_DRAG = 1  # C_D
AC_SIDE_BETA = 2  # C_Y_beta, side force per rad of sideslip
AC_ROLL_BETA = 3  # C_l_beta
AC_PITCH = 4  # C_m at zero deflection (trim term: 003 eq. 6 uses C_m_delta_e (delta_e - delta_trim))
AC_YAW_BETA = 5  # C_n_beta
AC_ROLL_AILERON = 6  # C_l_delta_a, 003 eq. 6
AC_PITCH_ELEVON = 7  # C_m_delta_e, 003 eq. 6
AC_YAW_AILERON = 8  # C_n_delta_a, 003 eq. 6
AC_ROLL_RUDDER = 9  # C_l_delta_r, 003 eq. 10a
AC_YAW_RUDDER = 10  # C_n_delta_r, 003 eq. 10c
AERO_COEFFICIENTS = 11


@jit_noalloc
def axis_cell(axis, x):
    """(k, f): ``x`` lies a fraction f in [0, 1] of the way from axis[k] to axis[k + 1], clamped."""
    n = axis.shape[0]
    if n == 1 or x <= axis[0]:
        return 0, 0.0
    if x >= axis[n - 1]:
        return n - 2, 1.0
    low = 0
    high = n - 1
    while high - low > 1:
        middle = (low + high) // 2
        if axis[middle] <= x:
            low = middle
        else:
            high = middle
    return low, (x - axis[low]) / (axis[low + 1] - axis[low])


@jit_noalloc
def coefficient(alpha_axis, mach_axis, table, slot, alpha, mach):
    """Coefficient ``slot`` at (alpha rad, mach), bilinear in the table, held at its edges."""
    i, fa = axis_cell(alpha_axis, alpha)
    j, fm = axis_cell(mach_axis, mach)
    if alpha_axis.shape[0] == 1:
        i1 = i
    else:
        i1 = i + 1
    if mach_axis.shape[0] == 1:
        j1 = j
    else:
        j1 = j + 1
    low = table[slot, i, j] + fm * (table[slot, i, j1] - table[slot, i, j])
    high = table[slot, i1, j] + fm * (table[slot, i1, j1] - table[slot, i1, j])
    return low + fa * (high - low)


@jit_noalloc
def coefficients_at(alpha_axis, mach_axis, table, alpha, mach, out):
    """Every slot of ``table`` at (alpha rad, mach) into ``out`` (AERO_COEFFICIENTS): what
    :func:`coefficient` gives slot by slot, with one search of each axis."""
    i, fa = axis_cell(alpha_axis, alpha)
    j, fm = axis_cell(mach_axis, mach)
    i1 = i if alpha_axis.shape[0] == 1 else i + 1
    j1 = j if mach_axis.shape[0] == 1 else j + 1
    for slot in range(table.shape[0]):
        low = table[slot, i, j] + fm * (table[slot, i, j1] - table[slot, i, j])
        high = table[slot, i1, j] + fm * (table[slot, i1, j1] - table[slot, i1, j])
        out[slot] = low + fa * (high - low)
