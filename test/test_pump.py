"""The displacement pump's element laws (docs/model.md, "Pump", eq. D1-D4) at operating points
their equations fix: leakage and friction from the datasheet's efficiencies, the flow, the shaft
torque pumping and driven by the oil, the losses in both directions and the stroke a variable
pump sets; each also on a batch (xp=numpy)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from boom_hydraulics.model import pump

#: 10 cm^3/rev, 20 MPa rated, eta_v 0.93 at 30 L/min, eta_hm 0.88 (no value a special case).
DISPLACEMENT_M3_RAD = 10e-6 / (2.0 * math.pi)
MAX_FLOW_M3_S, RATED_DP_PA, ETA_V, ETA_HM = 30e-3 / 60.0, 20e6, 0.93, 0.88


def test_leakage_and_friction_give_the_datasheets_efficiencies_at_the_rated_point():
    leakage = pump.leakage_conductance(ETA_V, MAX_FLOW_M3_S, RATED_DP_PA)
    assert leakage == pytest.approx((1.0 - ETA_V) * MAX_FLOW_M3_S / RATED_DP_PA, rel=1e-15)  # D1
    assert leakage * RATED_DP_PA == pytest.approx((1.0 - ETA_V) * MAX_FLOW_M3_S, rel=1e-14)  # eta_v at p_n
    c_f = pump.torque_loss_ratio(ETA_HM)
    assert c_f == pytest.approx(1.0 / ETA_HM - 1.0, rel=1e-15)  # D2
    assert pump.torque_loss_ratio(1.0) == 0.0  # a lossless pump has no friction torque


def test_flow_torque_and_losses_pumping_and_driven_by_the_oil():
    leakage = pump.leakage_conductance(ETA_V, MAX_FLOW_M3_S, RATED_DP_PA)
    c_f = pump.torque_loss_ratio(ETA_HM)
    dp = 12e6
    for w in (157.0, -157.0, 0.4, 0.0):
        flow = pump.delivered_flow_m3_s(DISPLACEMENT_M3_RAD, w, dp, leakage)
        assert flow == pytest.approx(DISPLACEMENT_M3_RAD * w - leakage * dp, rel=1e-14)  # D1
        ideal = DISPLACEMENT_M3_RAD * dp
        direction = w / math.sqrt(w * w + pump.FRICTION_SPEED_RAD_S**2)
        torque = pump.shaft_torque_n_m(DISPLACEMENT_M3_RAD, w, dp, c_f)
        assert torque == pytest.approx(ideal + c_f * abs(ideal) * direction, rel=1e-14)  # D2
        friction_w = pump.mechanical_loss_w(DISPLACEMENT_M3_RAD, w, dp, c_f)
        assert friction_w == pytest.approx(c_f * ideal * w * direction, rel=1e-13, abs=1e-300)  # D3
        assert friction_w >= 0.0  # a loss both ways
        leak_w = pump.volumetric_loss_w(dp, leakage)
        assert leak_w == pytest.approx(leakage * dp * dp, rel=1e-15)  # D3
        assert torque * w == pytest.approx(dp * flow + leak_w + friction_w, rel=1e-12, abs=1e-9)  # the balance
    assert pump.FRICTION_SPEED_RAD_S == 1.0
    # pumping fast the torque is D dp (1 + c_f), driven by the oil D dp (1 - c_f)
    assert pump.shaft_torque_n_m(DISPLACEMENT_M3_RAD, 1e4, dp, c_f) == pytest.approx(
        DISPLACEMENT_M3_RAD * dp * (1.0 + c_f), rel=1e-8
    )
    assert pump.shaft_torque_n_m(DISPLACEMENT_M3_RAD, -1e4, dp, c_f) == pytest.approx(
        DISPLACEMENT_M3_RAD * dp * (1.0 - c_f), rel=1e-8
    )
    speeds = np.array([157.0, -3.0])  # a batch of sets
    np.testing.assert_allclose(
        pump.mechanical_loss_w(DISPLACEMENT_M3_RAD, speeds, dp, c_f, np),
        [pump.mechanical_loss_w(DISPLACEMENT_M3_RAD, w, dp, c_f) for w in (157.0, -3.0)],
        rtol=1e-15,
    )


def test_a_variable_pump_strokes_to_deliver_the_flow_and_cover_its_leakage():
    leakage = pump.leakage_conductance(ETA_V, MAX_FLOW_M3_S, RATED_DP_PA)
    dp, w, flow = 9e6, 150.0, 2.1e-4
    stroke = pump.stroke_for_flow_m3_rad(flow, w, dp, leakage)
    assert stroke == pytest.approx((flow + leakage * dp) / w, rel=1e-15)  # D4
    assert pump.delivered_flow_m3_s(stroke, w, dp, leakage) == pytest.approx(flow, rel=1e-13)


def test_efficiencies_at_the_low_ends_of_their_ranges_give_their_leakage_and_friction():
    """A worn pump: eta_v 0.4 leaks 60 % of its full flow at the rated pressure rise; eta_hm at
    its range's end, 0.5, needs a friction torque as large as the ideal one, c_f = 1."""
    assert pump.leakage_conductance(0.4, MAX_FLOW_M3_S, RATED_DP_PA) * RATED_DP_PA == pytest.approx(
        0.6 * MAX_FLOW_M3_S, rel=1e-14
    )
    assert pump.torque_loss_ratio(0.5) == 1.0
