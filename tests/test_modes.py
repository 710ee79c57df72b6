"""Mode exit predicates (reference-model sec. 4) just either side of their thresholds.

Thresholds come from configs/missions/refex-exo.yaml via the packed mission array; ``NUDGE``
is a relative step far above float64 rounding (1e-16) and far below any physical margin.
"""

import math

import numpy as np
import pytest

from refexmc.core import layout as L
from refexmc.core import modes, rcs

NUDGE = 1e-9  # relative; see module docstring


def below(x):
    return x * (1 - NUDGE) if x > 0 else x - NUDGE


def above(x):
    return x * (1 + NUDGE) if x > 0 else x + NUDGE


def test_thresholds_are_the_configured_ones(inputs, mission_config):
    m = inputs.mission
    cfg = mission_config["modes"]
    assert m[L.M_NCM_DURATION] == cfg["ncm"]["duration_s"] == 5.0  # 000 sec. 2.2
    assert m[L.M_RDM2_DURATION] == cfg["rdm2"]["duration_s"] == 8.0  # 000 sec. 2.2
    assert m[L.M_RDM1_RATE] == pytest.approx(math.radians(cfg["rdm1"]["rate_threshold_deg_s"]), rel=1e-15)
    assert m[L.M_SAM_ANGLE] == pytest.approx(math.radians(cfg["sam"]["angle_threshold_deg"]), rel=1e-15)
    assert m[L.M_SAM_RATE] == pytest.approx(math.radians(cfg["sam"]["rate_threshold_deg_s"]), rel=1e-15)
    assert m[L.M_SSM_EXIT_ALTITUDE] == cfg["ssm"]["exit_altitude_m"]
    assert m[L.M_EAM_EXIT_ALTITUDE] == cfg["eam"]["exit_altitude_m"]
    assert m[L.M_GEEM_QBAR] == cfg["geem"]["handover_qbar_pa"]
    assert m[L.M_GEEM_EXIT_ALTITUDE] == cfg["geem"]["exit_altitude_m"]


def test_ncm_ends_at_its_duration(inputs):
    d = inputs.mission[L.M_NCM_DURATION]
    assert not modes.ncm_done(inputs.mission, below(d))
    assert modes.ncm_done(inputs.mission, d)
    assert modes.ncm_done(inputs.mission, above(d))


def test_rdm2_ends_at_its_duration(inputs):
    d = inputs.mission[L.M_RDM2_DURATION]
    assert not modes.rdm2_done(inputs.mission, below(d))
    assert modes.rdm2_done(inputs.mission, d)


def test_rdm1_needs_profile_finished_and_every_rate_below_threshold(inputs):
    m = inputs.mission
    limit = m[L.M_RDM1_RATE]
    t1 = 12.0
    small = np.full(3, below(limit))
    assert modes.rdm1_done(m, above(t1), t1, small)
    assert not modes.rdm1_done(m, t1, t1, small), "t > t1 is required"
    assert not modes.rdm1_done(m, below(t1), t1, small)
    for axis in range(3):
        for sign in (1.0, -1.0):
            rates = small.copy()
            rates[axis] = sign * above(limit)
            assert not modes.rdm1_done(m, above(t1), t1, rates), f"axis {axis}, sign {sign}"
            rates[axis] = sign * limit
            assert not modes.rdm1_done(m, above(t1), t1, rates), "strictly below the threshold"
            rates[axis] = sign * below(limit)
            assert modes.rdm1_done(m, above(t1), t1, rates)


def test_sam_needs_both_angle_and_rate_below_thresholds(inputs):
    m = inputs.mission
    angle, rate = m[L.M_SAM_ANGLE], m[L.M_SAM_RATE]
    assert modes.sam_done(m, below(angle), below(rate))
    assert not modes.sam_done(m, above(angle), below(rate))
    assert not modes.sam_done(m, below(angle), above(rate))
    assert not modes.sam_done(m, angle, below(rate))
    assert not modes.sam_done(m, below(angle), rate)


def test_ssm_ends_below_its_altitude_only_when_descending(inputs):
    m = inputs.mission
    h = m[L.M_SSM_EXIT_ALTITUDE]
    assert modes.ssm_done(m, below(h), -1.0)
    assert not modes.ssm_done(m, above(h), -1.0)
    assert not modes.ssm_done(m, h, -1.0)
    assert not modes.ssm_done(m, below(h), +1.0), "the ascending crossing must not end SSM"
    assert not modes.ssm_done(m, below(h), 0.0)


def test_eam_ends_below_its_altitude(inputs):
    m = inputs.mission
    h = m[L.M_EAM_EXIT_ALTITUDE]
    assert modes.eam_done(m, below(h))
    assert not modes.eam_done(m, h)
    assert not modes.eam_done(m, above(h))


def test_geem_hands_over_at_qbar_or_floor_altitude(inputs):
    m = inputs.mission
    q, floor = m[L.M_GEEM_QBAR], m[L.M_GEEM_EXIT_ALTITUDE]
    high = above(floor)
    assert modes.geem_done(m, high, q), "q-bar >= threshold hands over"
    assert modes.geem_done(m, high, above(q))
    assert not modes.geem_done(m, high, below(q))
    assert modes.geem_done(m, below(floor), below(q)), "floor altitude hands over"
    assert not modes.geem_done(m, floor, below(q))


@pytest.mark.parametrize("mode", range(L.N_MODES))
def test_thrust_level_per_mode(mode):
    """Low thrust NCM..RDM2, high thrust in EAM and GEEM (000 sec. 2.2)."""
    expected = rcs.LEVEL_HIGH if mode in (L.MODE_EAM, L.MODE_GEEM) else rcs.LEVEL_LOW
    assert modes.thrust_level(mode) == expected
