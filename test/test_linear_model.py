"""The linear model's readings as a user takes them (analysis.linear_model, boom-sim linearize):
modes against the closed form of a second-order system, static gains with their signs, the
quasi-static gains against the fast modes' residues, the position loop's gain against its
definition, and margins at a known crossover."""

from __future__ import annotations

import dataclasses
import math
import subprocess
import sys

import numpy as np
import pytest
from test_linearize_modes import ELASTIC, MID

from boom_hydraulics.analysis import linear_model as lm
from boom_hydraulics.analysis.operating_point import operating_point
from boom_hydraulics.model.geometry import lever_rad_per_m
from boom_hydraulics.model.parameters import Parameters, with_updates

control = pytest.importorskip("control")

AT = {name: i for i, name in enumerate(lm.STATE_NAMES)}


@pytest.fixture(scope="module")
def model() -> lm.LinearModel:
    return lm.linearize(operating_point(Parameters(), 1.4))


def _with(model: lm.LinearModel, a: np.ndarray, b: np.ndarray) -> lm.LinearModel:
    """The linear model's point, outputs and states with another A and B."""
    return lm.LinearModel(
        model.point, np.asarray(a, dtype=float), np.asarray(b, dtype=float).reshape(-1, 1), model.C, model.D
    )


def _oscillator(wn: float, zeta: float, gain: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """q1'' + 2 zeta wn q1' + wn^2 q1 = wn^2 gain u, in the states q1, v; the others each a
    first-order lag of their own, slow to fast (p1 at 3/s, p2 at 7/s, x_v at 11/s, bristle at 13/s)."""
    a = np.diag([0.0, 0.0, -3.0, -7.0, -11.0, -13.0])
    a[AT["q1"], AT["v"]] = 1.0
    a[AT["v"], AT["q1"]] = -wn * wn
    a[AT["v"], AT["v"]] = -2.0 * zeta * wn
    b = np.array([0.0, wn * wn * gain, 3.0, 14.0, 0.0, 0.0])
    return a, b


def test_the_modes_of_a_second_order_system_are_its_natural_frequency_and_damping(model):
    """Eigenvalues -zeta wn +- j wn sqrt(1 - zeta^2): |lambda| = wn, -Re/|lambda| = zeta; the
    pair counts once, a real mode has damping 1, and they come slowest first."""
    wn, zeta = 2 * math.pi * 5.0, 0.2
    a, b = _oscillator(wn, zeta)
    modes = _with(model, a, b).modes()
    assert len(modes) == 5  # six states, one pair
    assert [m.natural_frequency_hz for m in modes] == sorted(m.natural_frequency_hz for m in modes)
    ringing = [m for m in modes if m.oscillatory]
    assert len(ringing) == 1
    assert ringing[0].natural_frequency_hz == pytest.approx(5.0, rel=1e-12)
    assert ringing[0].damping_ratio == pytest.approx(zeta, rel=1e-12)
    assert ringing[0].eigenvalue.imag == pytest.approx(wn * math.sqrt(1 - zeta * zeta), rel=1e-12)
    real = [m for m in modes if not m.oscillatory]
    assert [m.natural_frequency_hz for m in real] == pytest.approx([r / (2 * math.pi) for r in (3, 7, 11, 13)])
    assert all(m.damping_ratio == 1.0 and m.eigenvalue.imag == 0.0 for m in real)


def test_a_slow_ringing_counts_once_rings_and_is_the_hydraulic_mode(model):
    """A ringing at 0.1 Hz (eigenvalues -0.13 +- 0.62j: imaginary parts within 1/s of 0) is one
    oscillating mode, and the boom's hydraulic one."""
    wn, zeta = 2 * math.pi * 0.1, 0.2
    slow = _with(model, *_oscillator(wn, zeta))
    ringing = [m for m in slow.modes() if m.oscillatory]
    assert len(slow.modes()) == 5 and len(ringing) == 1
    assert ringing[0].natural_frequency_hz == pytest.approx(0.1, rel=1e-12)
    assert slow.hydraulic_mode().natural_frequency_hz == pytest.approx(0.1, rel=1e-12)


def test_a_mode_at_rest_has_no_frequency_and_counts_as_damped(model):
    """An integrator (eigenvalue 0) reads 0 Hz and damping 1, not 0/0."""
    a = np.diag([0.0, -1.0, -2.0, -3.0, -4.0, -5.0])
    first = _with(model, a, np.ones(6)).modes()[0]
    assert first.natural_frequency_hz == 0.0 and first.damping_ratio == 1.0 and not first.oscillatory


def test_the_hydraulic_mode_is_the_ringing_of_the_rod_and_none_where_nothing_rings(model):
    wn, zeta = 2 * math.pi * 5.0, 0.2
    mode = _with(model, *_oscillator(wn, zeta)).hydraulic_mode()
    assert mode.natural_frequency_hz == pytest.approx(5.0, rel=1e-12)
    assert mode.damping_ratio == pytest.approx(zeta, rel=1e-12) and mode.oscillatory
    assert mode.eigenvalue.imag > 0.0  # of the pair, the one with the positive imaginary part
    real = _with(model, np.diag([-1.0, -2.0, -3.0, -4.0, -5.0, -6.0]), np.ones(6))
    assert real.hydraulic_mode() is None
    # one matrix, not a stack of them, gives its one eigenvalue
    a, _ = _oscillator(wn, zeta)
    alone = lm.hydraulic_eigenvalue(a, model.point.params)
    assert alone.shape == () and complex(alone) == pytest.approx(mode.eigenvalue, rel=1e-12)
    # the drive's own model rings at 8 Hz, lightly damped
    assert 5.0 < model.hydraulic_mode().natural_frequency_hz < 12.0 and 0.0 < model.hydraulic_mode().damping_ratio < 0.3


def test_static_gains_are_each_outputs_own_with_its_sign_and_an_integrator_is_infinite(model):
    """G(0) = -C A^-1 B per output: a lag b/(s + a) settles at b/a; a second-order system at
    its gain; where q1 integrates the command (no spring) its static gain is infinite."""
    a, b = _oscillator(2 * math.pi * 5.0, 0.2, gain=-0.04)  # a command closing the rod in by 4 cm per unit
    gains = _with(model, a, b).dc_gains()
    assert gains == pytest.approx([-0.04, 0.0, 3.0 / 3.0, 14.0 / 7.0], abs=1e-12)
    a[AT["v"], AT["q1"]] = 0.0  # no spring: q1 integrates the rod's velocity
    gains = _with(model, a, b).dc_gains()
    assert math.isinf(gains[0])
    # the drive itself: its trapped oil's mode at s = 0 leaves G(0) undetermined
    assert np.isnan(model.dc_gains()).all()


def test_the_quasi_static_gains_are_the_fast_modes_residues_and_the_drive_lifts_for_a_positive_command(model):
    """With the slow modes (leakage, creep, q1's integrator) held, each output's gain is the sum
    over the fast modes of its residue over -lambda (modal truncation, by eigenvectors here); on
    the drive a positive command lifts: the rod's velocity gain is positive, m/s per unit."""
    values, vectors = np.linalg.eig(model.A)
    limit = abs(model.hydraulic_mode().eigenvalue) / lm.SLOW_RATIO
    fast = np.abs(values) >= limit
    left = np.linalg.inv(vectors)
    residues = (model.C @ vectors[:, fast]) * (left[fast] @ model.B)[:, 0]
    expected = np.real(np.sum(residues / -values[fast], axis=1))
    gains = model.quasi_static_gains()
    assert gains == pytest.approx(expected, rel=1e-6)
    assert gains[lm.OUTPUT_NAMES.index("v")] > 0.01
    # a hand-made drive: the lags are fast, the oscillator too, and a slow creep on q1 is held
    a, b = _oscillator(2 * math.pi * 5.0, 0.2, gain=-0.04)
    assert _with(model, a, b).quasi_static_gains() == pytest.approx([-0.04, 0.0, 1.0, 2.0], abs=1e-9)
    # nothing rings: the limit is then the fastest mode's over SLOW_RATIO; a mode just slower
    # than that is held (its gain not counted), one exactly SLOW_RATIO times slower is not
    lags = np.diag([-3.97, -100.0, -400.0, -4.0, -8.0, -200.0])
    gains = _with(model, lags, [3.97, 100.0, 400.0, 4.0, 0.0, 0.0]).quasi_static_gains()
    assert gains == pytest.approx([0.0, 1.0, 1.0, 1.0], abs=1e-9)


def test_the_loop_gain_is_the_pi_controller_times_the_lever_times_the_rods_response(model):
    """L(j w) = (Kp + Ki / (j w)) k C_q1 (j w I - A)^-1 B, rad of boom angle per rad of error."""
    p = model.point.params
    k = lm.angle_gain(model.point)
    loop = lm.loop_gain(model)
    n = model.A.shape[0]
    for hz in (0.1, 1.0, 8.0, 40.0):
        w = 2 * math.pi * hz
        rod = (model.C[0] @ np.linalg.solve(1j * w * np.eye(n) - model.A, model.B))[0]
        expected = (p.control_position_gain_1_rad + p.control_integral_gain_1_rad_s / (1j * w)) * k * rod
        assert complex(control.evalfr(loop, 1j * w)) == pytest.approx(expected, rel=1e-6)
    # the controller's gains are its own: a stiffer proportional gain raises L where it dominates
    stiffer = with_updates(p, control_position_gain_1_rad=2 * p.control_position_gain_1_rad)
    doubled = lm.loop_gain(lm.linearize(operating_point(stiffer, 1.4)))
    w = 2 * math.pi * 40.0
    assert abs(control.evalfr(doubled, 1j * w)) > 1.9 * abs(control.evalfr(loop, 1j * w))


def test_the_margins_of_a_known_loop_are_its_crossovers(model):
    """L(s) = 2 / (s (s + 1) (s + 2)): its phase is -180 deg at w = sqrt(2), where |L| = 2/6, so
    the gain margin is 3 (9.54 dB); its gain crossover solves w^2 (w^2 + 1) (w^2 + 4) = 4."""
    margins = lm.margins(control.tf([2.0], [1.0, 3.0, 2.0, 0.0]))
    assert margins.gain_margin == pytest.approx(3.0, rel=1e-6)
    assert margins.gain_margin_db == pytest.approx(20 * math.log10(3.0), rel=1e-6)
    assert margins.phase_crossover_hz == pytest.approx(math.sqrt(2.0) / (2 * math.pi), rel=1e-6)
    w2 = np.roots([1.0, 5.0, 4.0, -4.0])  # w^2 (w^2 + 1) (w^2 + 4) = 4 in w^2
    wc = math.sqrt(float(np.real(w2[(np.abs(w2.imag) < 1e-12) & (w2.real > 0)][0])))
    assert margins.crossover_hz == pytest.approx(wc / (2 * math.pi), rel=1e-6)
    phase = -90.0 - math.degrees(math.atan(wc)) - math.degrees(math.atan(wc / 2.0))
    assert margins.phase_margin_deg == pytest.approx(180.0 + phase, rel=1e-6)
    # a first-order loop never crosses -180 deg: no gain margin to speak of, and no phase crossover
    # six times the gain: past the margin, the loop is unstable and the margin below one (-6 dB)
    unstable = lm.margins(control.tf([12.0], [1.0, 3.0, 2.0, 0.0]))
    assert unstable.gain_margin == pytest.approx(0.5, rel=1e-6)
    assert unstable.gain_margin_db == pytest.approx(20 * math.log10(0.5), rel=1e-6)
    first = lm.margins(control.tf([1.0], [1.0, 1.0]))
    assert math.isinf(first.gain_margin) and math.isnan(first.phase_crossover_hz)
    assert lm.Margins(0.0, 30.0, 1.0, 2.0).gain_margin_db != lm.Margins(0.0, 30.0, 1.0, 2.0).gain_margin_db  # nan


@pytest.mark.parametrize("hose_length_m", [0.0, 1.0])
def test_the_oil_spring_frequency_goes_with_the_root_of_the_oil_stiffness_and_the_seals_add_theirs(hose_length_m):
    """omega^2 = E (S1^2/V1 + S2^2/V2) / m: a quarter of the bulk modulus halves it, however
    soft; with hoses, each chamber's oil beside its hose's at K_eff (1/K_eff = 1/E + 1/K_wall),
    a quarter of both moduli does too; the seals add F_s / z_ba over m to omega^2."""
    p = with_updates(Parameters(), hose_length_m=hose_length_m)
    for q1_m in (1.15, 1.4, 1.65):
        for modulus in (4.0e6, 1.4e9):
            stiff = lm.oil_spring_frequency_rad_s(
                with_updates(p, bulk_modulus_pa=modulus, hose_wall_modulus_pa=2 * modulus), q1_m
            )
            soft = with_updates(p, bulk_modulus_pa=modulus / 4.0, hose_wall_modulus_pa=modulus / 2.0)
            assert lm.oil_spring_frequency_rad_s(soft, q1_m) == pytest.approx(stiff / 2.0, rel=1e-12)
        seals = with_updates(p, static_friction_n=173.0, friction_presliding_m=3e-4)  # 576667 N/m
        sealed = lm.oil_spring_frequency_rad_s(seals, q1_m, seals=True) ** 2
        added = 173.0 / 3e-4 / lm.effective_mass_at(p, q1_m)
        assert sealed - lm.oil_spring_frequency_rad_s(seals, q1_m) ** 2 == pytest.approx(added, rel=1e-9)


def test_the_sweeps_modes_come_of_a_mode_named_in_a_file_as_of_the_default():
    """A sweep's parameters read from YAML name their mode with a string of their own, not the
    interpreter's literal: the mid-stroke mode is found all the same."""
    read = with_updates(Parameters(), mode="".join(["phys", "ical"]))
    frequency, damping = lm.mid_stroke_modes([read])
    default = lm.linearize(operating_point(Parameters(), 1.4)).hydraulic_mode()
    assert frequency[0] == pytest.approx(default.natural_frequency_hz, rel=1e-9)
    assert damping[0] == pytest.approx(default.damping_ratio, rel=1e-6)


@pytest.mark.parametrize("case", ["tip still, little oil", "tip nearly still, much oil"])
def test_of_two_ringing_modes_the_one_that_moves_the_booms_tip_is_the_hydraulic_mode(case):
    """An elastic boom's two oscillations, made by hand: the boom's root rings with the rod and
    the bending rate (nearly) cancelling at the tip (L1 k v + eta' = 0, or a hundredth of the
    rod's), the tonne's with the bending adding to the rod's motion there. The tonne's is the
    hydraulic mode, whether it moves much more oil than the root's or much less."""
    point = operating_point(ELASTIC, MID)
    model = lm.linearize(point)
    names = model.state_names
    at = {name: i for i, name in enumerate(names)}
    assert len(names) == 8 and names[-2:] == ("boom_deflection", "boom_deflection_rate")
    tip = ELASTIC.boom_length_m * lever_rad_per_m(MID, ELASTIC.a_m, ELASTIC.b_m)

    def vector(**parts: float) -> np.ndarray:
        out = np.zeros(len(names))
        for name, value in parts.items():
            out[at[name]] = value
        return out

    if case == "tip still, little oil":
        root = (vector(v=1e-3, boom_deflection=0.5, boom_deflection_rate=-tip * 1e-3), vector(q1=1e-3))
        tonne = (vector(v=1e-3, boom_deflection_rate=tip * 1e-3, p1=1.0), vector(p2=1.0))
    else:
        root = (vector(v=1e-3, boom_deflection_rate=-0.99 * tip * 1e-3, p1=1.0), vector(p2=1.0))
        tonne = (vector(v=1e-3, boom_deflection=0.5, boom_deflection_rate=tip * 1e-3), vector(q1=1e-3))
    others = [vector(x_v=1.0), vector(bristle=1.0), vector(boom_deflection=1.0), vector(p1=1.0)]
    columns = np.column_stack([*root, *tonne, *others])
    blocks = np.zeros((len(names), len(names)))
    for k, (sigma, omega) in enumerate([(-20.0, 2 * math.pi * 125.0), (-1.0, 2 * math.pi * 2.66)]):
        blocks[2 * k : 2 * k + 2, 2 * k : 2 * k + 2] = [[sigma, omega], [-omega, sigma]]
    blocks[4:, 4:] = np.diag([-3.0, -7.0, -11.0, -13.0])
    a = columns @ blocks @ np.linalg.inv(columns)
    mode = lm.LinearModel(point, a, np.zeros((len(names), 1)), model.C, model.D).hydraulic_mode()
    assert mode.natural_frequency_hz == pytest.approx(math.hypot(1.0, 2 * math.pi * 2.66) / (2 * math.pi), rel=1e-9)


@pytest.mark.parametrize("drive", ["pump_controlled", "fixed_pump"])
def test_a_drive_with_its_own_states_and_hoses_is_linearised_over_them_all(drive):
    """The drive's own states and the hoses' together (8 + 16 and more): each has its name and
    unit, and the boom rings a little below the same drive's without hoses (their oil beside
    the chambers' is softer)."""
    bare = with_updates(Parameters(), drive=drive)
    hosed = with_updates(bare, hose_length_m=1.0)
    model = lm.linearize(operating_point(hosed, 1.4))
    n = len(lm.states_of(hosed))
    assert n >= 24 and model.A.shape == (n, n) and len(model.state_names) == len(model.state_units) == n
    assert model.state_units[-16:] == (("Pa",) * 4 + ("m^3/s",) * 4) * 2
    assert model.state_names[-16:] == tuple(
        f"hose_{s}_{x}" for s in "ab" for x in ("p0", "p1", "p2", "p3", "q1", "q2", "q3", "q4")
    )
    alone = lm.linearize(operating_point(bare, 1.4)).hydraulic_mode().natural_frequency_hz
    assert 0.75 * alone < model.hydraulic_mode().natural_frequency_hz < alone


def test_modes_and_margins_are_values():
    """A mode or a margin is a value: equal ones are one in a set, and none can be changed; nor
    can a linear model's matrices be swapped under it."""
    first = lm.Mode(complex(-1.0, 6.0), 1.0, 0.2, True)
    assert {first, lm.Mode(complex(-1.0, 6.0), 1.0, 0.2, True)} == {first}
    with pytest.raises(dataclasses.FrozenInstanceError):
        first.damping_ratio = 0.5  # type: ignore[misc]
    with pytest.raises(dataclasses.FrozenInstanceError):
        lm.linearize(operating_point(Parameters(), 1.4)).A = np.zeros((6, 6))  # type: ignore[misc]
    margins = lm.Margins(3.0, 30.0, 1.0, 2.0)
    assert len({margins, lm.Margins(3.0, 30.0, 1.0, 2.0)}) == 1
    with pytest.raises(dataclasses.FrozenInstanceError):
        margins.gain_margin = 1.0  # type: ignore[misc]


def test_a_sweep_takes_its_modes_without_loading_python_control():
    """python-control takes seconds to load and a sweep's modes need none of it: importing the
    linear model (as boom-sweep does) leaves it unloaded."""
    code = "import sys, boom_hydraulics.analysis.linear_model; print('control' in sys.modules)"
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == "False"


def test_the_hydraulic_mode_weighs_each_state_in_units_of_its_size():
    """Two ringing modes made by hand over (q1 in m, v in m/s, p1 in Pa, x): the first moves
    q1 and v by their whole sizes (1 m, 0.1 m/s) and x by half of its, the second v by a tenth
    of its size and p1 by a hundredth (1e5 of 1e7 Pa). In units of each state's size the second
    moves the tip most against the rest (0.1 of 0.11, against 1 of 2.5): it is the hydraulic mode.
    Weighed by the sizes instead of in their units, the pascals would swamp it and the first,
    which moves no oil, would be taken."""
    names, sizes = ("q1", "v", "p1", "x"), (1.0, 0.1, 1e7, 1.0)
    first, second = -1.0 + 10.0j, -2.0 + 20.0j
    w1 = np.array([1.0, 0.1j, 0.0, 0.5j])
    w2 = np.array([0.0, 0.01, 1e5j, 0.0])
    vectors = np.column_stack([w1, w1.conj(), w2, w2.conj()])
    a = np.real(vectors @ np.diag([first, first.conjugate(), second, second.conjugate()]) @ np.linalg.inv(vectors))
    got = lm.hydraulic_eigenvalue(a, Parameters(), names, sizes)
    assert got == pytest.approx(second, rel=1e-9)
