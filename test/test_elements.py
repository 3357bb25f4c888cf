"""The accumulator, the hoses and the elastic boom together (docs/model.md): the 1 t crane as it
ships has all three on, and its loader cycle keeps its energy balance with each of them
taking its share; with a drive without oil (the electro-mechanical actuator) the two that sit
on oil lines are left out. Each element's own closed-form checks are in test_accumulator.py,
test_hoses.py and test_elastic_boom.py."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import CONFIG

from boom_hydraulics.model import config, ledger, physical
from boom_hydraulics.model.parameters import with_updates
from boom_hydraulics.solve import commands
from boom_hydraulics.solve.simulator import Simulator

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
    integrals = dict(zip(ledger.INTEGRALS, list(sim.y)[physical.LEDGER_STATES :], strict=True))
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
