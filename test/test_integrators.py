"""Integrators: measured orders of convergence and the adaptive method's accuracy."""

from __future__ import annotations

import math

import pytest
from conftest import CONFIG

from boom_hydraulics.model import config
from boom_hydraulics.model.parameters import Parameters, with_updates
from boom_hydraulics.solve.commands import steps
from boom_hydraulics.solve.simulation import Simulator, simulate

PAPER = config.load(CONFIG / "paper_fig8.yaml")


def _final(params, duration=1.0, command=None):
    tr = simulate(params, duration, command, every=10**9, jit=False)
    return tr["q1"][-1], tr["p1"][-1]


def _orders(method, steps_s):
    reference = _final(with_updates(PAPER, method="rk4", time_step_s=1.25e-4))[0]
    errors = [abs(_final(with_updates(PAPER, method=method, time_step_s=h))[0] - reference) for h in steps_s]
    return [math.log2(errors[i] / errors[i + 1]) for i in range(len(errors) - 1)]


def test_euler_converges_with_order_one():
    for order in _orders("euler", [4e-4, 2e-4, 1e-4]):
        assert order == pytest.approx(1.0, abs=0.1)


def test_rk4_converges_with_order_four():
    for order in _orders("rk4", [1e-2, 5e-3, 2.5e-3]):
        assert order == pytest.approx(4.0, abs=0.25)


def test_substeps_equal_a_smaller_step():
    fine = _final(with_updates(PAPER, time_step_s=2.5e-4))
    split = _final(with_updates(PAPER, time_step_s=1e-3, substeps=4))
    assert split[0] == pytest.approx(fine[0], rel=1e-12)


def test_rk45_meets_its_tolerance_with_coarse_output_steps():
    """With 20 ms between outputs, rk45 subdivides and still lands within its tolerance."""
    reference = _final(with_updates(PAPER, time_step_s=1.25e-4))
    params = with_updates(PAPER, method="rk45", time_step_s=0.02, rtol=1e-8, atol_scale=1e-10)
    sim = Simulator(params)
    sim.run(1.0, lambda t: 1.0, every=10**9)
    assert sim.integrator.accepted > 50  # more internal steps than the 50 outputs
    assert sim.y[0] == pytest.approx(reference[0], rel=1e-6)
    assert sim.y[2] == pytest.approx(reference[1], rel=1e-6)


def test_rk45_agrees_with_rk4_in_physical_mode():
    command = steps([0.0, 0.8], [1.0, -0.6])
    rk4 = _final(with_updates(Parameters(), time_step_s=2.5e-4), 1.5, command)
    rk45 = _final(with_updates(Parameters(), method="rk45", rtol=1e-9, atol_scale=1e-11), 1.5, command)
    assert rk45[0] == pytest.approx(rk4[0], rel=1e-6)
    assert rk45[1] == pytest.approx(rk4[1], rel=1e-5)


def test_the_parameter_schema_offers_the_registered_methods():
    """The methods a params file may name are the solver's (model/ names them without importing it)."""
    from boom_hydraulics.model import parameters
    from boom_hydraulics.solve import integrators

    assert tuple(getattr(parameters, "METHOD_NAMES", parameters.METHODS)) == tuple(integrators.METHODS)
