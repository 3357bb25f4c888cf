"""pump_controlled in the run loop: the electro-hydrostatic actuator (EHA) lifts and lowers the
boom under position control and gives the boom's potential energy back to the battery
(docs/model.md, "Drives" and "Energy ledger")."""

from __future__ import annotations

import math

import numpy as np
import pytest

from boom_hydraulics.model import ledger, physical
from boom_hydraulics.model.geometry import boom_angle_rad
from boom_hydraulics.model.parameters import Parameters, with_updates
from boom_hydraulics.solve import accelerate, commands
from boom_hydraulics.solve.simulation import Simulator

JIT = [False, True] if accelerate.available() else [False]
#: Lift from 8.5 to 30 degrees under position control, hold, lower to -10 degrees and hold: 8 s.
MOVES = "angle:0=30,4=-10"


def _run(drive: str, jit: bool | None = None) -> tuple[dict[str, float], dict[str, np.ndarray], list, list, Parameters]:
    """The ledger's integrals (J, by name), the outputs, the first and last state and the
    parameters of :data:`MOVES` with ``drive``."""
    params = with_updates(Parameters(), drive=drive, **commands.scenario(MOVES, 8.0))
    sim = Simulator(params, jit=jit)
    start = list(sim.y)
    out = sim.run(8.0, commands.from_parameters(params), every=10)
    integrals = physical.ledger_integrals(sim.y)
    return integrals, out, start, list(sim.y), params


@pytest.mark.parametrize("jit", JIT, ids=lambda j: "compiled" if j else "interpreted")
def test_the_eha_follows_the_moves_and_gives_back_at_most_the_potential_energy_lowering_gives_up(jit):
    integrals, out, start, end, params = _run("pump_controlled", jit)
    alpha = np.degrees(out["alpha"])
    assert alpha.max() == pytest.approx(30.0, abs=1.0) and alpha[-1] == pytest.approx(-10.0, abs=1.5)
    assert out["p1"].max() < params.relief_pressure_pa  # the pump lifts the load, the reliefs stay shut
    c = physical.constants(params)

    def potential(y: list) -> float:
        return c.weight_coeff * math.sin(boom_angle_rad(y[0], c.a, c.b, c.h))

    given_up = integrals["lift_work"] - (potential(end) - potential(start))  # the negative part of Pi'
    assert 0.3 * given_up < integrals["battery_returned"] < given_up  # lowering generates, with losses
    assert (out["battery_power"] < 0.0).any() and out["battery_returned"][-1] == integrals["battery_returned"]
    assert ledger.energies_of(integrals)["imbalance_ratio"] < 0.005
    assert integrals["valve_loss"] >= 0.0 and integrals["leakage_loss"] == 0.0  # no 4/3 valve: only the checks


def test_on_the_same_moves_the_eha_draws_less_from_the_battery_than_every_valve_drive():
    drawn = {d: _run(d)[0] for d in ("pump_controlled", "pressure_compensated", "fixed_pump", "load_sensing")}
    net = {d: i["battery_drawn"] - i["battery_returned"] for d, i in drawn.items()}
    assert net["pump_controlled"] < min(v for d, v in net.items() if d != "pump_controlled"), net
    assert all(i["battery_returned"] == 0.0 for d, i in drawn.items() if d != "pump_controlled")


@pytest.mark.parametrize(
    ("v", "p1", "p2", "w", "u", "x_v"),
    [(0.05, 8e6, 4e5, 100.0, 1.0, 0.8), (-0.1, 6e6, 5.2e5, -60.0, -0.5, -0.4)],
    ids=["lifting", "lowering"],
)
def test_the_eha_gives_its_lines_what_the_chambers_take_losing_nothing_between_and_reports_its_opening(
    v, p1, p2, w, u, x_v
):
    """No valve between pump and chambers: the power the EHA gives its lines, (p1 - p_t) Q_A +
    (p2 - p_t) Q_B, is what the chambers take, so nothing goes to the valve's loss below the port
    reliefs; its x_v output is the opening it is handed (it has no spool)."""
    p = with_updates(Parameters(), drive="pump_controlled")
    c = physical.constants(p)
    y = list(physical.initial_state(p))
    y[0], y[1], y[2], y[3], y[4], y[physical.DRIVE_STATE] = 1.4, v, p1, p2, x_v, w
    terms = physical._terms(y, c, u, math)
    s = terms.supply
    power = (p1 - p.tank_pressure_pa) * s.q_a + (p2 - p.tank_pressure_pa) * s.q_b
    assert abs(power) > 1e3 and s.power == pytest.approx(power, rel=1e-12)
    assert terms.loss == pytest.approx(0.0, abs=1e-9 * abs(power))
    assert s.spool == x_v
