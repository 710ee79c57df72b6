"""Mode logic of the exoatmospheric phase (reference-model sec. 4, 000 sec. 2.2).

NCM -> RDM1 -> SAM -> SSM -> RDM2 -> EAM -> GEEM -> hand-over. Each predicate below is one
mode's exit condition on what the flight software knows (measured state, navigation altitude).
"""

from refexmc._jit import jit_noalloc
from refexmc.core.layout import (
    M_EAM_EXIT_ALTITUDE,
    M_GEEM_EXIT_ALTITUDE,
    M_GEEM_QBAR,
    M_NCM_DURATION,
    M_RDM1_RATE,
    M_RDM2_DURATION,
    M_SAM_ANGLE,
    M_SAM_RATE,
    M_SSM_EXIT_ALTITUDE,
    MODE_EAM,
    MODE_GEEM,
)
from refexmc.core.rcs import LEVEL_HIGH, LEVEL_LOW


@jit_noalloc
def thrust_level(mode):
    """Low thrust for precision in NCM..RDM2, high thrust in EAM and GEEM (000 sec. 2.2)."""
    return LEVEL_HIGH if mode == MODE_EAM or mode == MODE_GEEM else LEVEL_LOW


@jit_noalloc
def ncm_done(mission, time_in_mode):
    """Actuators unlocked a fixed time after separation."""
    return time_in_mode >= mission[M_NCM_DURATION]


@jit_noalloc
def rdm1_done(mission, time_in_mode, t1, rate_meas):
    """Rate profile finished and every measured body rate below the threshold."""
    if time_in_mode <= t1:
        return False
    limit = mission[M_RDM1_RATE]
    return abs(rate_meas[0]) < limit and abs(rate_meas[1]) < limit and abs(rate_meas[2]) < limit


@jit_noalloc
def sam_done(mission, total_angle_error, rate_error_norm):
    """Total angle error and rate error norm both below their thresholds (000 sec. 2.2)."""
    return total_angle_error < mission[M_SAM_ANGLE] and rate_error_norm < mission[M_SAM_RATE]


@jit_noalloc
def ssm_done(mission, altitude, climb_rate):
    """Below the SSM exit altitude on the descending branch."""
    return altitude < mission[M_SSM_EXIT_ALTITUDE] and climb_rate < 0.0


@jit_noalloc
def rdm2_done(mission, time_in_mode):
    """Second rate damping lasts a fixed time (000 sec. 2.2: 8 s)."""
    return time_in_mode >= mission[M_RDM2_DURATION]


@jit_noalloc
def eam_done(mission, altitude):
    """Entry attitude held until the EAM exit altitude."""
    return altitude < mission[M_EAM_EXIT_ALTITUDE]


@jit_noalloc
def geem_done(mission, altitude, qbar):
    """Hand-over to aerodynamic control: enough dynamic pressure, or the floor altitude."""
    return qbar >= mission[M_GEEM_QBAR] or altitude < mission[M_GEEM_EXIT_ALTITUDE]
