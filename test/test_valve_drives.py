"""The valve drives in the run loop: fixed_pump (the paper's circuit) and load_sensing behind
the 4/3 valve, against their own equations (docs/model.md, "Drives"), compiled and interpreted."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import run_tool

from boom_hydraulics.model import drives, physical
from boom_hydraulics.model.drives import constants as drive_constants
from boom_hydraulics.model.drives import fixed_pump
from boom_hydraulics.model.parameters import Parameters, from_mapping, with_updates
from boom_hydraulics.solve import accelerate
from boom_hydraulics.solve.commands import steps
from boom_hydraulics.solve.simulation import Simulator, simulate

JIT = [False, True] if accelerate.available() else [False]
P = Parameters()
#: Lift, hold, lower, hold: 6 s.
CYCLE = steps([0.0, 0.3, 1.8, 2.8, 4.8], [0.0, 1.0, 0.0, -0.6, 0.0])


def _run(values: dict, jit: bool, duration_s: float = 6.0, command=CYCLE):
    return simulate(from_mapping(values), duration_s, command, jit=jit)


def test_the_constants_the_drives_read_are_the_drive_constants_under_their_names():
    p = with_updates(P, drive="fixed_pump", supply_line_volume_m3=3e-4, load_sensing_margin_pa=1.5e6)
    c, d = physical.constants(p), drive_constants(p)
    assert {"p_set", "max_flow", "displacement", "speed", "pump_leak", "line_volume", "g_main"} <= set(
        physical.DRIVE_FIELDS
    )
    assert all(getattr(c, name) == getattr(d, name) for name in physical.DRIVE_FIELDS)
    # the set's drive is the fixed pump, and no other: the flag each drive's equations run under
    assert [drives.uses(c, k) for k in range(len(drives.DRIVES))] == [1.0 * (n == "fixed_pump") for n in drives.DRIVES]


@pytest.mark.parametrize("jit", JIT)
def test_todays_source_ignores_the_drive_state_and_a_changed_supply_pressure_acts_at_once(jit):
    sim = Simulator(P, jit=jit)
    sim.step(1.0, 500)
    assert sim.y[physical.DRIVE_STATE] == P.supply_pressure_pa  # p_n, standing still
    sim.set_parameters(with_updates(P, supply_pressure_pa=12e6))
    sim.step(1.0, 10)
    assert sim.outputs()["p_supply"] <= 12e6  # the pump holds the new p_n, not the state


@pytest.mark.parametrize("jit", JIT)
def test_a_fixed_pump_dead_heads_at_its_relief_and_its_line_keeps_the_energy_balance(jit):
    """Valve closed: the line stays at eq. D14's pressure; through a whole cycle the stored
    energy (the line's compression included) changes by what flowed, as the stepping checks."""
    sim = Simulator(with_updates(P, drive="fixed_pump"), jit=jit)
    sim.step(0.0, 300)
    p_ss = fixed_pump.dead_head_pressure_pa(drive_constants(sim.params))
    assert sim.outputs()["p_supply"] == pytest.approx(p_ss, rel=1e-3)
    assert p_ss > P.supply_pressure_pa  # the relief passes the pump's whole flow above p_n
    for u, n in ((1.0, 1500), (0.0, 1000), (-0.6, 2000), (0.0, 500)):
        sim.step(u, n)
    assert abs(sim.energy_residual()) < 1.0  # J, of some 30 kJ that changed hands
    assert sim.y[physical.DRIVE_STATE] == pytest.approx(p_ss, rel=1e-3)  # back at the relief


@pytest.mark.parametrize("jit", JIT)
def test_a_small_fixed_pump_limits_the_lift_to_its_flow_with_the_relief_shut(jit):
    """A pump that delivers less than the open valve would take: the line falls below p_n, the
    relief shuts, and the piston chamber takes the pump's whole delivered flow (eq. D1, D13)."""
    p = with_updates(P, drive="fixed_pump", pump_max_flow_m3_s=2.0e-4)
    run = _run({"drive": "fixed_pump", "pump_max_flow_m3_s": 2.0e-4}, jit, duration_s=1.5)
    steady = (run["t"] > 1.0) & (run["t"] < 1.5)
    assert np.all(run["p_supply"][steady] < p.supply_pressure_pa)
    d = drive_constants(p)
    delivered = d.displacement * d.speed - d.pump_leak * (run["p_supply"][steady] - p.tank_pressure_pa)  # eq. D1
    s1 = physical.constants(p).s1
    assert np.mean(run["v"][steady]) * s1 == pytest.approx(np.mean(delivered), rel=0.01)


@pytest.mark.parametrize("jit", JIT)
def test_load_sensing_holds_its_margin_over_the_lifted_load_and_idles_at_the_margin(jit):
    run = _run({"drive": "load_sensing"}, jit)
    lifting = (run["t"] > 1.0) & (run["t"] < 1.8)  # settled after the pump's lag, before the stroke's end
    margin = run["p_supply"][lifting] - run["p1"][lifting]
    assert np.all(np.abs(margin - P.load_sensing_margin_pa) < 0.05e6)
    idle = (run["t"] > 5.5) & (run["t"] <= 6.0)  # spool closed: the signal line vented to tank
    assert np.all(np.abs(run["p_supply"][idle] - (P.tank_pressure_pa + P.load_sensing_margin_pa)) < 1e3)
    # the same valve fed at the load plus 2 MPa instead of 16 MPa lifts slower
    reference = _run({}, jit)
    assert np.max(run["q1"]) < np.max(reference["q1"])


@pytest.mark.skipif(not accelerate.available(), reason="numba is switched off")
@pytest.mark.parametrize("drive", ["fixed_pump", "load_sensing", "pump_controlled"])
def test_each_drive_runs_the_same_compiled_and_interpreted(drive):
    compiled, interpreted = _run({"drive": drive}, True), _run({"drive": drive}, False)
    for name in ("q1", "p1", "p2", "p_supply", "supply_energy"):
        scale = np.max(np.abs(interpreted[name]))
        assert np.max(np.abs(compiled[name] - interpreted[name])) <= 1e-9 * scale, name


def test_a_supply_line_too_stiff_to_step_says_which_parameter_to_change(tmp_path):
    result = run_tool(
        "boom-sim", "run", "--set", "drive=fixed_pump", "--set", "supply_line_volume_m3=1e-9", "--duration", "0.1",
        "--out", tmp_path / "run.csv",
    )  # fmt: skip
    assert result.returncode == 1 and "too stiff" in result.stderr and "a larger supply_line_volume_m3" in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1 and not (tmp_path / "run.csv").exists()
