"""The electric motor's and inverter's element laws (docs/model.md, "Electric motor and
inverter", eq. D5-D7) at operating points their equations fix: each loss coefficient from its
share of the rated loss, each term of the loss with its own power of torque or speed, the power
drawn and the efficiency motoring and generating; each also on a batch of sets (numpy arrays)."""

from __future__ import annotations

import numpy as np
import pytest

from boom_hydraulics.model import electric_motor

#: A rated point and shares of its loss where no value is a special case, N m, rad/s, -, W.
RATED_N_M, RATED_RAD_S, ETA = 23.0, 310.0, 0.91
COPPER, CURRENT, EDDY, WINDAGE, STANDBY_W = 0.45, 0.07, 0.11, 0.05, 13.0


def coefficients() -> electric_motor.MotorLosses:
    return electric_motor.loss_coefficients(RATED_N_M, RATED_RAD_S, ETA, COPPER, CURRENT, EDDY, WINDAGE, STANDBY_W)


def test_each_coefficient_is_its_share_of_the_rated_loss_at_the_rated_point():
    m = coefficients()
    rated_loss = RATED_N_M * RATED_RAD_S * (1.0 / ETA - 1.0)
    assert m.copper * RATED_N_M**2 == pytest.approx(COPPER * rated_loss, rel=1e-14)  # D6
    assert m.current * RATED_N_M == pytest.approx(CURRENT * rated_loss, rel=1e-14)
    assert m.eddy * RATED_RAD_S**2 == pytest.approx(EDDY * rated_loss, rel=1e-14)
    assert m.windage * RATED_RAD_S**3 == pytest.approx(WINDAGE * rated_loss, rel=1e-14)
    assert m.standby == STANDBY_W
    speed_share = 1.0 - COPPER - CURRENT - EDDY - WINDAGE
    assert m.iron * RATED_RAD_S == pytest.approx(speed_share * rated_loss - STANDBY_W, rel=1e-13)
    # so the rated point's losses add up to the rated loss, and its efficiency is eta
    machine = electric_motor.machine_loss_w(RATED_N_M, RATED_RAD_S, m)
    assert machine + STANDBY_W == pytest.approx(rated_loss, rel=1e-13)
    assert electric_motor.efficiency(RATED_N_M, RATED_RAD_S, m) == pytest.approx(ETA, rel=1e-13)  # D7
    assert electric_motor.efficiency(-RATED_N_M, RATED_RAD_S, m) == pytest.approx(2.0 - 1.0 / ETA, rel=1e-13)


def test_each_loss_term_grows_with_its_own_power_of_torque_or_speed_the_same_both_ways():
    m = coefficients()
    for torque, speed in ((7.0, 120.0), (-7.0, 120.0), (7.0, -120.0), (0.0, 55.0), (9.0, 0.0)):
        expected = (
            m.copper * torque**2
            + m.iron * abs(speed)
            + m.current * abs(torque)
            + m.eddy * speed**2
            + m.windage * abs(speed) ** 3
        )
        assert electric_motor.machine_loss_w(torque, speed, m) == pytest.approx(expected, rel=1e-14)  # D6
        assert electric_motor.motor_loss_w(torque, speed, m.copper, m.iron) == pytest.approx(
            m.copper * torque**2 + m.iron * abs(speed), rel=1e-14
        )
        drawn = electric_motor.input_power_w(torque, speed, m)
        assert drawn == pytest.approx(torque * speed + expected + STANDBY_W, rel=1e-14)  # D5
    # holding a torque at standstill costs the copper and switching terms alone (and the standby)
    assert electric_motor.input_power_w(9.0, 0.0, m) == pytest.approx(m.copper * 81.0 + m.current * 9.0 + STANDBY_W)
    torques, speeds = np.array([7.0, -4.0]), np.array([-120.0, 260.0])  # a batch of sets
    np.testing.assert_allclose(
        electric_motor.input_power_w(torques, speeds, m),
        [electric_motor.input_power_w(t, w, m) for t, w in zip(torques, speeds, strict=True)],
        rtol=1e-15,
    )


def test_the_efficiency_is_shaft_over_electrical_motoring_and_electrical_over_shaft_generating():
    m = coefficients()
    for torque, speed in ((11.0, 200.0), (-11.0, -200.0)):  # motoring, both directions
        assert electric_motor.efficiency(torque, speed, m) == pytest.approx(
            torque * speed / electric_motor.input_power_w(torque, speed, m), rel=1e-14
        )
    for torque, speed in ((-11.0, 200.0), (11.0, -200.0)):  # generating
        assert electric_motor.efficiency(torque, speed, m) == pytest.approx(
            electric_motor.input_power_w(torque, speed, m) / (torque * speed), rel=1e-14
        )


def test_at_the_lowest_efficiency_allowed_the_rated_loss_is_the_rated_shaft_power():
    """motor_efficiency's range starts at 0.5 (parameters): there L_r = T_r w_r (1 / 0.5 - 1) =
    T_r w_r, the rated point draws twice its shaft power, and generating returns nothing."""
    m = electric_motor.loss_coefficients(RATED_N_M, RATED_RAD_S, 0.5, COPPER, CURRENT, EDDY, WINDAGE, STANDBY_W)
    rated_shaft_w = RATED_N_M * RATED_RAD_S
    assert electric_motor.machine_loss_w(RATED_N_M, RATED_RAD_S, m) + STANDBY_W == pytest.approx(rated_shaft_w)
    assert electric_motor.efficiency(RATED_N_M, RATED_RAD_S, m) == pytest.approx(0.5, rel=1e-13)
    assert electric_motor.efficiency(-RATED_N_M, RATED_RAD_S, m) == pytest.approx(0.0, abs=1e-13)


def test_motoring_is_any_positive_shaft_power_however_small_and_generating_any_negative_one():
    m = coefficients()
    speed = 310.0
    for shaft_w in (0.5, -0.5):  # half a watt either way
        torque = shaft_w / speed
        drawn = electric_motor.input_power_w(torque, speed, m)
        expected = shaft_w / drawn if shaft_w > 0.0 else drawn / shaft_w
        assert electric_motor.efficiency(torque, speed, m) == pytest.approx(expected, rel=1e-12)
