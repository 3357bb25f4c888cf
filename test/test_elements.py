"""The accumulator, the hoses and the elastic boom together (docs/model.md): the 1 t crane as it
ships has all three on, and its loader cycle keeps its energy balance with each of them
taking its share; with a drive without oil (the electro-mechanical actuator) the two that sit
on oil lines are left out. Each element's own closed-form checks are in test_accumulator.py,
test_hoses.py and test_elastic_boom.py."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import CONFIG

from boom_hydraulics.analysis.jacobian import jacobian
from boom_hydraulics.model import config, ledger, physical
from boom_hydraulics.model.parameters import with_updates
from boom_hydraulics.solve import commands, integrators
from boom_hydraulics.solve.simulator import Simulator, scale_sizes

CRANE = config.load(CONFIG / "loader_crane_1t.yaml")


def test_the_1t_crane_ships_with_all_three_on():
    assert CRANE.accumulator_gas_volume_m3 > 0.0
    assert CRANE.hose_length_m > 0.0
    assert CRANE.boom_bending_stiffness_n_m2 > 0.0
    assert physical.element_states(CRANE) == (
        physical.ACCUMULATOR_STATE,
        *physical.HOSE_STATES,
        *physical.BOOM_STATES,
    )


def test_the_loader_cycle_with_all_three_on_keeps_its_energy_balance():
    """The loader cycle with the tonne on the crane as it ships: the ledger's integrals balance
    to 0.5 % of the battery's energy (as with none of them), the stepping's energy check held
    (W against the stored energy, which holds the gas's, the hoses' oil and the boom's mode),
    and each element took its share: the accumulator's orifice, the hoses' friction and the
    boom's structural damping each dissipated energy, and the tip rang."""
    params = with_updates(CRANE, **commands.scenario("loader", 0.0, CRANE))
    sim = Simulator(params)
    out = sim.run(18.5, commands.from_parameters(params), every=10)
    integrals = physical.ledger_integrals(sim.y)
    energies = ledger.energies_of(integrals)
    assert energies["imbalance_ratio"] < 0.005, energies
    assert abs(sim.energy_residual()) < 1e-3 * integrals["battery_drawn"]
    for term in ("accumulator_loss", "line_loss", "structural_loss"):
        assert integrals[term] > 1e-5 * integrals["battery_drawn"], term  # at least 1 J in 100 kJ
    assert np.ptp(out["boom_deflection"]) > 1e-3  # the tip moved by millimetres over the cycle


@pytest.mark.parametrize("drive", ["electro_mechanical"])
def test_a_drive_without_oil_leaves_the_accumulator_and_hoses_out(drive):
    """The actuator has no oil lines: on the crane as it ships its linear model and its states
    keep the elastic boom alone, and its accumulator and hose states stand still."""
    params = with_updates(CRANE, drive=drive)
    assert physical.element_states(params) == physical.BOOM_STATES
    c = physical.constants(params)
    assert c.acc_on == 0.0 and c.hose_on == 0.0
    y = physical.initial_state(params)
    rates = physical.derivative(0.0, y, c, 0.5)
    assert all(rates[i] == 0.0 for i in (physical.ACCUMULATOR_STATE, *physical.HOSE_STATES))


@pytest.mark.parametrize("opening", [0.6, 0.0])
def test_the_stability_bound_with_all_three_on_covers_the_fastest_mode_and_its_substeps_keep_rk4_stable(opening):
    """The stepping's bound (physical.stiffness_rate) with the three on, against the Jacobian's
    eigenvalues at the crane's start (by differences of the model's derivative): at least the
    largest |lambda| (the hoses' highest wave, about 3700 1/s), and rk4 in the substeps it asks
    for keeps every decaying mode inside its stability region (|R(h lambda)| <= 1): a tighter
    bound that let a mode out would make the run ring up and stop on its energy balance."""
    c = physical.constants(CRANE)
    y = physical.initial_state(CRANE)
    dt = CRANE.time_step_s
    # the energy integrals feed back into nothing: the states that move the model
    moving = [i for i, kind in enumerate(physical.STATE_SCALES) if kind != "energy"]
    sizes = scale_sizes(CRANE)

    def rates(x):
        z = list(y)
        for i, value in zip(moving, x, strict=True):
            z[i] = value
        d = physical.derivative(0.0, z, c, opening)
        return [d[i] for i in moving]

    lam = np.linalg.eigvals(jacobian(rates, [y[i] for i in moving], [sizes[physical.STATE_SCALES[i]] for i in moving]))
    bound = physical.stiffness_rate(y, c, opening, dt)
    assert bound >= np.max(np.abs(lam)) > 3000.0  # the waves are there, and the bound covers them
    substeps = math.ceil(dt * bound / integrators.METHODS["rk4"].stability_limit)
    z = lam[lam.real < 0.0] * dt / substeps
    assert np.max(np.abs(1.0 + z + z**2 / 2.0 + z**3 / 6.0 + z**4 / 24.0)) <= 1.0


def test_a_batch_steps_the_elements_states_where_one_of_its_sets_has_one_on():
    """Compiled, the kernels step the state without the elements' states where every set has
    them off (they stand still), and the whole state where one set of a batch has one on: that
    set's hose flows move as they do interpreted, and the set beside it without hoses runs as
    it does alone."""
    from boom_hydraulics.solve.batch import run_sets

    plain = config.load(CONFIG / "default.yaml")
    hosed = with_updates(plain, hose_length_m=1.0)
    lift = commands.constant(0.6)
    together = run_sets([plain, hosed], 0.2, lift)
    alone = run_sets([plain], 0.2, lift)
    interpreted = run_sets([hosed], 0.2, lift, jit=False)
    assert np.array_equal(together.states[0], alone.states[0])
    flow_a = physical.HOSE_STATE + 4  # line A's first flow (hoses.STATE_NAMES)
    assert physical.initial_state(hosed)[flow_a] == 0.0 < together.states[1][flow_a]
    np.testing.assert_allclose(together.states[1], interpreted.states[0], rtol=1e-9, atol=1e-12)
