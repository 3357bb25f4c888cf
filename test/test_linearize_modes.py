"""linearize's hydraulic mode on an elastic boom: the oscillation that moves the boom's tip,
the payload's ringing on the oil and the boom's bending, not the boom's root on its oil."""

from __future__ import annotations

import numpy as np
import pytest
from test_elastic_boom import CRANE, _two_masses_hz

from boom_hydraulics.analysis import linear_model as lm
from boom_hydraulics.analysis.operating_point import operating_point
from boom_hydraulics.model.parameters import with_updates

#: The 1 t crane's boom elastic, without the seals' friction (the two-mass model has none).
ELASTIC = with_updates(CRANE, static_friction_n=0.0, coulomb_friction_n=0.0)
MID = 0.5 * (ELASTIC.cylinder_min_length_m + ELASTIC.cylinder_max_length_m)


def test_the_elastic_cranes_hydraulic_mode_is_the_tonne_ringing_not_the_booms_root():
    """Of the two-mass model's modes (2.66 Hz: the tonne on the oil and the bending; 125 Hz: the
    boom's root on the oil beneath it, the tip staying put), the one at the tip is the lower."""
    model = lm.linearize(operating_point(ELASTIC, MID))
    slow, fast = _two_masses_hz(ELASTIC, MID)
    assert fast > 20.0 * slow  # (the two are far apart: a choice between them is no near thing)
    mode = model.hydraulic_mode()
    assert mode.natural_frequency_hz == pytest.approx(slow, rel=3e-3)
    # a sweep's modes (every set at mid-stroke at once) choose the same
    frequency, _ = lm.mid_stroke_modes([ELASTIC])
    assert frequency[0] == pytest.approx(slow, rel=3e-3)


def test_a_rigid_boom_keeps_the_rods_mode():
    """Without the bending mode the tip moves with the rod alone: the mode is the rod's, the one
    the oil-spring formula gives, whatever the lever."""
    rigid = with_updates(ELASTIC, boom_bending_stiffness_n_m2=0.0)
    model = lm.linearize(operating_point(rigid, MID))
    ringing = [m for m in model.modes() if m.oscillatory]
    assert len(ringing) == 1
    assert model.hydraulic_mode() == ringing[0]
    alone = lm.oil_spring_frequency_rad_s(rigid, MID) / (2 * np.pi)
    assert model.hydraulic_mode().natural_frequency_hz == pytest.approx(alone, rel=0.02)
