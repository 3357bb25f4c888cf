"""boom-sim linearize: the linear model at an operating point holds to analytic derivatives, to
the natural-frequency formula and to the simulated ringing of a small step."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import CONFIG

from boom_hydraulics.analysis import linear_model as lm
from boom_hydraulics.analysis.jacobian import BACKWARD, CENTRAL, FORWARD, jacobian
from boom_hydraulics.analysis.operating_point import MODEL, operating_point, rod_length_at_angle
from boom_hydraulics.analysis.ringing import ringing
from boom_hydraulics.cli import sim as cli
from boom_hydraulics.model.geometry import boom_angle_rad
from boom_hydraulics.model.parameters import Parameters, with_updates
from boom_hydraulics.model.physical import chamber_volumes
from boom_hydraulics.sweeps import sweep


def test_differences_are_exact_to_rounding_and_take_a_kink_from_the_side_asked():
    def f(x):
        return [math.sin(x[0]) * x[1], math.exp(x[1]) + x[0] ** 3]

    x = [0.7, -1.3]
    exact = np.array([[math.cos(0.7) * -1.3, math.sin(0.7)], [3 * 0.7**2, math.exp(-1.3)]])
    for side in (CENTRAL, FORWARD, BACKWARD):
        np.testing.assert_allclose(jacobian(f, x, [1.0, 1.0], [side, side]), exact, rtol=1e-9)
    # at the kink of max(x, 0) each side has its own slope; a central difference would average them
    kink = [0.0]
    relu = lambda x: [0.5 * (x[0] + abs(x[0]))]  # noqa: E731
    assert jacobian(relu, kink, [1.0], [FORWARD])[0, 0] == pytest.approx(1.0)
    assert jacobian(relu, kink, [1.0], [BACKWARD])[0, 0] == pytest.approx(0.0, abs=1e-12)
    assert jacobian(relu, kink, [1.0], [CENTRAL])[0, 0] == pytest.approx(0.5)


def test_the_jacobian_holds_the_model_equations_own_derivatives():
    """At rest the entries that eq. 11-13 give in closed form: d(acc)/dp = +-S/m, d(dp/dt)/dv =
    -+E S/V, the spool's lag; and the energy states the linear model leaves out act on nothing."""
    p = Parameters()
    point = operating_point(p, 1.4)
    model = lm.linearize(point)
    c = MODEL.constants(p)
    k = lm.angle_gain(point)
    mass = c.inertia * k * k
    v1, v2, _, _ = chamber_volumes(1.4, c)
    at = {name: i for i, name in enumerate(lm.STATE_NAMES)}
    a = model.A
    assert a[at["q1"], at["v"]] == pytest.approx(1.0, rel=1e-9)
    assert a[at["v"], at["p1"]] == pytest.approx(c.s1 / mass, rel=1e-7)
    assert a[at["v"], at["p2"]] == pytest.approx(-c.s2 / mass, rel=1e-7)
    assert a[at["p1"], at["v"]] == pytest.approx(-c.bulk_modulus * c.s1 / v1, rel=1e-7)
    assert a[at["p2"], at["v"]] == pytest.approx(c.bulk_modulus * c.s2 / v2, rel=1e-7)
    assert a[at["x_v"], at["x_v"]] == pytest.approx(-1.0 / p.spool_time_constant_s, rel=1e-9)
    assert model.B[at["x_v"], 0] == pytest.approx(1.0 / p.spool_time_constant_s, rel=1e-9)
    # the rod at rest and the boom held: the operating point is an equilibrium of the mechanics
    d = MODEL.derivative(0.0, point.state, c, 0.0)
    assert d[1] == pytest.approx(0.0, abs=1e-9) and d[3] == pytest.approx(0.0, abs=1e-3)
    assert point.drift < 0.0  # p1 creeps down through the load-holding valve's seat
    assert set(lm.STATE_NAMES) == {"q1", "v", "p1", "p2", "x_v", "bristle"}


@pytest.mark.parametrize("q1_m", [1.15, 1.4, 1.65])
@pytest.mark.parametrize("payload_kg", [0.0, 150.0])
def test_the_hydraulic_mode_is_the_natural_frequency_formula(q1_m, payload_kg):
    """sqrt(E S1^2/(m V1) + E S2^2/(m V2)): exactly the oil springs without seal friction, and
    with the seals' presliding stiffness F_s/z_ba added where they have it."""
    frictionless = with_updates(Parameters(), payload_mass_kg=payload_kg, static_friction_n=0.0, coulomb_friction_n=0.0)
    mode = lm.linearize(operating_point(frictionless, q1_m)).hydraulic_mode()
    formula = lm.oil_spring_frequency_rad_s(frictionless, q1_m) / (2 * math.pi)
    assert mode.natural_frequency_hz == pytest.approx(formula, rel=5e-3)
    sealed = with_updates(Parameters(), payload_mass_kg=payload_kg)
    mode = lm.linearize(operating_point(sealed, q1_m)).hydraulic_mode()
    with_seals = lm.oil_spring_frequency_rad_s(sealed, q1_m, seals=True) / (2 * math.pi)
    assert mode.natural_frequency_hz == pytest.approx(with_seals, rel=5e-3)
    assert mode.natural_frequency_hz > formula * 1.01  # the seals do stiffen it


@pytest.mark.parametrize(("q1_m", "payload_kg", "opening"), [(1.37, 50.0, 0.0), (1.6, 150.0, 0.05)])
def test_a_simulated_small_step_rings_as_the_linear_model_says(q1_m, payload_kg, opening):
    point = operating_point(with_updates(Parameters(), payload_mass_kg=payload_kg), q1_m, opening)
    mode = lm.linearize(point).hydraulic_mode()
    rung = ringing(point)
    assert rung.natural_frequency_hz == pytest.approx(mode.natural_frequency_hz, rel=0.01)
    assert rung.damping_ratio == pytest.approx(mode.damping_ratio, rel=0.05)


def test_an_angle_gives_its_rod_length_and_a_moving_point_stands_still_but_for_q1():
    p = Parameters()
    q1 = rod_length_at_angle(p, math.radians(20.0))
    assert math.degrees(boom_angle_rad(q1, p.a_m, p.b_m, p.support_height_m)) == pytest.approx(20.0, abs=1e-9)
    point = operating_point(p, q1, 0.1)
    d = MODEL.derivative(0.0, point.state, MODEL.constants(p), 0.1)
    assert point.state[1] > 0.01  # lifting
    assert max(abs(d[1]), abs(d[2]) / 1e7, abs(d[3]) / 1e7, abs(d[7])) < 1e-9


def test_the_sweep_metrics_are_the_linear_model_at_mid_stroke():
    sets = [with_updates(Parameters(), piston_diameter_m=d, payload_mass_kg=m) for d in (0.04, 0.063) for m in (0, 150)]
    frequency, damping = lm.mid_stroke_modes([*sets, with_updates(Parameters(), mode="paper")])
    for k, p in enumerate(sets):
        mode = lm.linearize(operating_point(p, 1.4)).hydraulic_mode()
        assert frequency[k] == pytest.approx(mode.natural_frequency_hz, rel=1e-9)
        assert damping[k] == pytest.approx(mode.damping_ratio, rel=1e-6)
    assert np.isnan(frequency[-1]) and np.isnan(damping[-1])  # paper mode has no such model
    assert frequency[1] < frequency[0]  # more payload, softer
    assert {"natural_frequency_hz", "linear_damping_ratio"} <= set(sweep.METRIC_NAMES)


def test_boom_sim_linearize_writes_what_it_says(tmp_path, capsys):
    control = pytest.importorskip("control")
    out = tmp_path / "lin"
    args = [
        "linearize",
        "--config",
        str(CONFIG / "default.yaml"),
        "--angle-deg",
        "15",
        "--payload-kg",
        "100",
        "--controller",
    ]
    assert cli.main([*args, "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "hydraulic mode:" in printed and "phase margin" in printed and "gain margin" in printed
    # the trapped oil's mode at s = 0 leaves G(0) without a value: said in words, never nan or inf
    assert "no static gain over all time" in printed and not {"nan", "inf"} & set(printed.replace(",", " ").split())
    assert sorted(f.name for f in out.iterdir()) == ["bode.csv", "bode.png", "linear_model.npz"]
    saved = np.load(out / "linear_model.npz")
    system = control.ss(saved["A"], saved["B"], saved["C"], saved["D"])
    assert list(saved["output_names"]) == ["q1", "v", "p1", "p2"] and system.nstates == 6
    header = (out / "bode.csv").read_text().splitlines()[0]
    assert header.startswith("frequency [Hz],q1 magnitude [m per unit]") and "loop phase [deg]" in header
    assert len((out / "bode.csv").read_text().splitlines()) == 401


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--rod-length-m", "1.9"], "lies outside the stroke"),
        # past the stroke's ends the law of cosines gives a mirrored angle's length (170 deg
        # was taken as 52, -170 as 32): refused, naming the angles the stroke reaches
        (["--angle-deg", "170"], "--angle-deg 2.9671 rad (170.00 deg) lies outside the stroke's"),
        (["--angle-deg", "-170"], "(-170.00 deg) lies outside the stroke's"),
        (["--angle-deg", "400"], "(400.00 deg) lies outside the stroke's"),
        (["--opening", "2"], "--opening must be a valve opening in [-1, 1]"),
        (["--set", "mode=paper"], "a linear model is taken of the physical drive"),
        (["--set", "drive=load_sensing"], "drive 'load_sensing' adds states of its own that it does not hold yet"),
    ],
)
def test_what_cannot_be_linearised_is_one_line_and_nothing_written(tmp_path, capsys, args, message):
    out = tmp_path / "never"
    assert cli.main(["linearize", "--config", str(CONFIG / "default.yaml"), *args, "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and message in err and "Traceback" not in err
    assert not out.exists()
