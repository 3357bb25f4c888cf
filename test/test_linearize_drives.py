"""boom-sim linearize of every drive: a drive whose supply does not stand still adds its own
states to the linear model, and their modes are the closed forms of its equations (docs/model.md,
"Drives"; analysis/linear_model.states_of)."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import CONFIG

from boom_hydraulics.analysis import linear_model as lm
from boom_hydraulics.analysis.operating_point import operating_point
from boom_hydraulics.cli import sim as cli
from boom_hydraulics.model import config
from boom_hydraulics.model.drives import DRIVES, constants
from boom_hydraulics.model.parameters import with_updates

P = config.load(CONFIG / "default.yaml")


def _model(drive: str, opening: float = 0.0) -> lm.LinearModel:
    p = with_updates(P, drive=drive)
    return lm.linearize(operating_point(p, p.initial_length_m, opening))


def _real_eigenvalues(model: lm.LinearModel) -> np.ndarray:
    values = np.linalg.eigvals(model.A)
    return np.sort(values[np.abs(values.imag) < 1e-9].real)


@pytest.mark.parametrize("drive", list(DRIVES))
def test_each_drive_keeps_its_own_states_unless_its_supply_stands_still(drive):
    model = _model(drive)
    own = DRIVES[drive].STATE_NAMES
    expected = lm.STATE_NAMES + (() if DRIVES[drive].STEADY_SUPPLY else own)
    assert model.state_names == expected and model.A.shape == (len(expected), len(expected))
    assert len(model.state_units) == len(expected)
    # the hydraulic mode is still found among the drive's modes (the boom on its oil springs)
    assert model.hydraulic_mode() is not None


def test_the_fixed_pumps_line_mode_is_its_oil_spring_against_relief_and_leakage():
    """With the valve closed the line's pressure relaxes at (E / V_s)(G_mr + G_p + 2 G_leak):
    its relief (open: the pump dead-heads over it), the pump's leakage and the closed spool's
    two leaking paths (eq. D12-D14)."""
    p = with_updates(P, drive="fixed_pump")
    d = constants(p)
    expected = -(d.bulk_modulus / d.line_volume) * (d.g_main + d.pump_leak + 2.0 * d.leak)
    fastest = _real_eigenvalues(_model("fixed_pump"))[0]
    assert fastest == pytest.approx(expected, rel=1e-3)


def test_the_load_sensing_pumps_mode_is_its_lag_and_the_ehas_its_motors():
    ls = with_updates(P, drive="load_sensing")
    assert np.min(np.abs(_real_eigenvalues(_model("load_sensing")) + 1.0 / ls.load_sensing_time_constant_s)) < 1e-6
    eha = with_updates(P, drive="pump_controlled")
    assert np.min(np.abs(_real_eigenvalues(_model("pump_controlled")) + 1.0 / eha.motor_time_constant_s)) < 1e-6


def test_the_ehas_command_acts_through_its_motor_alone():
    """No valve: the command drives the motor's speed (B has one entry, its lag's gain w_max / tau),
    and the motor's speed drives the lines' pressures."""
    model = _model("pump_controlled")
    p = model.point.params
    speed = model.state_names.index("motor_speed")
    assert model.B[speed, 0] == pytest.approx(p.pump_speed_rad_s / p.motor_time_constant_s, rel=1e-6)
    others = [i for i, name in enumerate(model.state_names) if name not in ("motor_speed", "x_v")]
    # (differences of rates of order 1e9 Pa/s leave rounding of order 1e-4 Pa/s: nothing acts there)
    assert np.all(np.abs(model.B[others, 0]) < 1e-2)
    p1 = model.state_names.index("p1")
    assert model.A[p1, speed] > 0.0  # lifting speed fills the piston chamber


def test_boom_sim_linearize_of_the_eha_saves_its_motor_state_with_its_unit(tmp_path):
    out = tmp_path / "eha"
    args = ["linearize", "--config", str(CONFIG / "default.yaml"), "--set", "drive=pump_controlled", "--out", str(out)]
    assert cli.main(args) == 0
    saved = np.load(out / "linear_model.npz")
    names, units = list(saved["state_names"]), list(saved["state_units"])
    assert names[-2:] == ["motor_speed", "speed_loop_integral"] and units[-2:] == ["rad/s", "rad/s"]
    assert saved["A"].shape == (8, 8) and len(saved["operating_state"]) == 8


def test_the_actuator_held_on_its_brake_rings_on_its_screw_in_series_with_the_brake():
    """At rest the electro-mechanical actuator holds on its brake: the boom's mass at the rod
    rings on the screw's stiffness k_s in series with the brake's presliding stiffness, its
    torque T_b over the presliding angle theta seen at the rod through the ratio r
    (docs/model.md, eq. D30-D35): f = sqrt(k / m) / (2 pi), 1/k = 1/k_s + r^2 theta / T_b."""
    from boom_hydraulics.model.drives import electro_mechanical

    model = _model("electro_mechanical")
    p = model.point.params
    assert model.state_names[-3:] == ("screw_force", "motor_speed", "friction_state")
    r = p.ema_screw_lead_m / (2.0 * np.pi * p.ema_gear_ratio)
    brake = p.ema_brake_torque_n_m / electro_mechanical.PRESLIDING_RAD / r**2
    stiffness = 1.0 / (1.0 / p.ema_screw_stiffness_n_m + 1.0 / brake)
    frequency = np.sqrt(stiffness / lm.effective_mass_at(p, model.point.q1_m)) / (2.0 * np.pi)
    assert model.hydraulic_mode().natural_frequency_hz == pytest.approx(frequency, rel=0.05)
