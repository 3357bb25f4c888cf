"""Paper mode: the Fig. 7 listing, integrated as the paper did, and what the paper reports."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import CONFIG
from scipy.integrate import solve_ivp

from boom_hydraulics.errors import SimulationError
from boom_hydraulics.model import config, paper
from boom_hydraulics.model.parameters import with_updates
from boom_hydraulics.solve import commands
from boom_hydraulics.solve.simulation import Simulator, simulate

CONFIGS = ("paper_fig8", "paper_fig9", "paper_fig10")


def _run(name: str, duration: float = 1.5):
    return simulate(config.load(CONFIG / f"{name}.yaml"), duration)


@pytest.mark.parametrize("name", CONFIGS)
def test_rk4_at_1ms_matches_a_tight_reference_solution(name):
    """RK4 at dt = 1 ms agrees with DOP853 at rtol 1e-12 to 1e-6 relative on q1 and p1."""
    params = config.load(CONFIG / f"{name}.yaml")
    c = paper.constants(params)
    trajectory = simulate(params, 1.5)
    reference = solve_ivp(
        lambda t, y: paper.derivative(t, list(y), c, 1.0),
        (0.0, trajectory["t"][-1]),
        paper.initial_state(params),
        method="DOP853",
        t_eval=trajectory["t"],
        rtol=1e-12,
        atol=[1e-12, 1e-12, 1e-4, 1e-6, 1e-6],
    )
    assert reference.success
    for i, name_ in ((0, "q1"), (2, "p1")):
        ref = reference.y[i]
        err = np.max(np.abs(trajectory[name_] - ref)) / np.max(np.abs(ref))
        assert err < 1e-6, f"{name_}: relative error {err:.2e}"


def test_initial_pressure_is_the_listing_static_pressure():
    params = config.load(CONFIG / "paper_fig8.yaml")
    # p0 = g L1 cos(alpha0) / (a sin(phi0) S1) (0.5 m1 + mb), worked by hand for q0 = 1.37 m
    xi = (0.4**2 + 1.4**2 - 1.37**2) / (2 * 0.4 * 1.4)
    alpha0 = np.arccos(xi) - np.pi / 2 + np.arccos(1.307 / 1.4)
    phi0 = np.arccos((0.4**2 - 1.4**2 + 1.37**2) / (2 * 0.4 * 1.37))
    s1 = np.pi * 0.04**2 / 4
    expected = 9.81 * 2.0 * np.cos(alpha0) / (0.4 * np.sin(phi0) * s1) * (0.5 * 100 + 50)
    assert paper.initial_state(params)[2] == pytest.approx(expected, rel=1e-12)
    assert expected == pytest.approx(3.870e6, rel=1e-3)


def test_an_external_rod_force_acts_beside_the_piston_force_of_eq_16():
    """F_ext (positive extending) enters eq. 16 where p S1 does: the listing's p0 drops by
    F_ext / S1, and at that pressure the acceleration is the one without the force."""
    params = config.load(CONFIG / "paper_fig8.yaml")
    pushed = with_updates(params, external_rod_force_n=2000.0)
    s1 = np.pi * 0.04**2 / 4
    y0, y = paper.initial_state(params), paper.initial_state(pushed)
    assert y0[2] - y[2] == pytest.approx(2000.0 / s1, rel=1e-12)
    c0, c = paper.constants(params), paper.constants(pushed)
    assert paper.derivative(0.0, y, c, 0.0)[1] == pytest.approx(paper.derivative(0.0, y0, c0, 0.0)[1], rel=1e-9)
    assert paper.derivative(0.0, y0, c, 0.0)[1] > paper.derivative(0.0, y0, c0, 0.0)[1]  # pushing out: it extends


def test_40mm_first_moves_backwards_then_extends_fast():
    tr = _run("paper_fig8")
    early = tr["t"] < 0.3
    assert tr["v"][early].min() < -0.01  # the rod first retracts ...
    assert tr["q1"][-1] - tr["q1"][0] > 0.25  # ... then extends more than 0.25 m in 1.5 s


def test_80mm_extends_slower_and_oscillates():
    small, large = _run("paper_fig8"), _run("paper_fig9")
    assert large["q1"][-1] - large["q1"][0] < 0.5 * (small["q1"][-1] - small["q1"][0])
    # wave process: the acceleration changes sign again and again (8 times or more in 1.5 s)
    crossings = np.count_nonzero(np.diff(np.sign(large["a"])) != 0)
    assert crossings >= 8
    # and still rings at the end: late swings of the acceleration of a quarter of the peak
    late = large["t"] > 1.0
    assert np.ptp(large["a"][late]) > 0.25 * np.max(np.abs(large["a"]))


def _settling_time(tr, fraction: float = 0.05) -> float:
    a = np.abs(tr["a"])
    above = np.nonzero(a > fraction * a.max())[0]
    return float(tr["t"][above[-1]])


def test_stiffer_oil_oscillations_die_out_sooner_within_one_second():
    soft, stiff = _run("paper_fig9"), _run("paper_fig10")
    assert _settling_time(stiff) < 1.0  # Fig. 10: attenuated within about 1 s
    assert _settling_time(stiff) < 0.75 * _settling_time(soft)


def test_80mm_stiff_oil_drives_piston_chamber_below_zero():
    """The listing knows no cavitation: p1 falls below the drain pressure (flagged)."""
    tr = _run("paper_fig10")
    assert tr["p1"].min() < 0.0
    assert tr["cavitation"].any()


def _listing(q: float, v: float, p: float, params) -> tuple[float, float]:
    """acceleration[q, v, p] and dpdt[q, v, p] of the Fig. 7 listing, transcribed as printed."""
    a, b, h, g = params.a_m, params.b_m, params.support_height_m, params.gravity_m_s2
    m1, mb, L1 = params.boom_mass_kg, params.payload_mass_kg, params.boom_length_m
    J1 = m1 * L1**2 / 3 + mb * L1**2  # eq. 8
    S1 = math.pi * params.piston_diameter_m**2 / 4
    fdr = math.pi * params.orifice_diameter_m**2 / 4  # eq. 17
    c_pr, b_pr, F_mp = params.spring_stiffness_n_m, params.viscous_friction_n_s_m, params.coulomb_friction_n
    xi = (a**2 + b**2 - q**2) / (2 * a * b)
    Theta = math.acos(h / b) + math.acos(xi)
    acceleration = (
        (a**2 * b**2 * (1 - xi**2))
        / (2 * J1 * q**2)
        * (
            p * S1
            - F_mp
            - (c_pr + ((0.5 * m1 + mb) * g * L1 * math.sin(Theta)) / (a * b * math.sqrt(1 - xi**2))) * q
            - (1 - (xi * q**2) / (a * b * (1 - xi**2))) * (J1 * q) / (a**2 * b**2 * (1 - xi**2)) * v**2
            - b_pr * v
        )
    )
    pn, rho, mu = params.supply_pressure_pa, params.density_kg_m3, params.discharge_coefficient
    Q = mu * fdr * math.sqrt(2 / rho * abs(pn - p)) * math.copysign(1.0, pn - p)
    dpdt = params.bulk_modulus_pa / params.piston_dead_volume_m3 * (Q - S1 * v)
    return acceleration, dpdt


@pytest.mark.parametrize("name", CONFIGS)
@pytest.mark.parametrize(("q", "v", "p"), [(1.37, 0.0, 4e6), (1.5, 0.2, 9e6), (1.2, -0.1, 15.5e6), (1.7, 0.05, 2e6)])
def test_the_derivative_is_the_listing_as_printed(name, q, v, p):
    params = config.load(CONFIG / f"{name}.yaml")
    dq, dv, dp, _, _ = paper.derivative(0.0, [q, v, p, 0.0, 0.0], paper.constants(params), 1.0)
    acceleration, dpdt = _listing(q, v, p, params)
    assert dq == v
    assert dv == pytest.approx(acceleration, rel=1e-12)
    assert dp == pytest.approx(dpdt, rel=1e-12)


@pytest.mark.parametrize("jit", [False, True], ids=["interpreted", "compiled"])
def test_a_run_that_leaves_the_geometry_stops_at_its_last_good_step_however_it_is_stepped(jit):
    """From q1 = 1.7 m the open valve runs the rod out of (1, 1.8) m after 1 s: a whole run and
    the node's steps (one at a time, or a tick of many held steps) keep the state of the last
    step inside and say so with the same line."""
    params = with_updates(config.load(CONFIG / "paper_fig8.yaml"), initial_length_m=1.7)
    whole = Simulator(params, jit=jit)
    with pytest.raises(SimulationError) as run_error:
        whole.run(3.0, commands.constant(1.0), every=100)
    assert str(run_error.value).startswith("rod left the valid geometry after t = 1 s (q1 = 1.79997")
    for steps in (1, 7, 3000):
        sim = Simulator(params, jit=jit)
        with pytest.raises(SimulationError) as step_error:
            for _ in range(3000):
                sim.step(1.0, steps)
        assert str(step_error.value) == str(run_error.value)
        assert (sim.t, sim.step_count, sim.y) == (whole.t, whole.step_count, whole.y)
