"""How the valve drives' motor runs (motor_strategy) and fixed_pump's open-centre valve
(valve_centre), against their equations (docs/model.md, "Motor strategies", "Open-centre valve")."""

from __future__ import annotations

import math

import numpy as np
import pytest

from boom_hydraulics import jit
from boom_hydraulics.fmu import native
from boom_hydraulics.model import drives, ledger, physical
from boom_hydraulics.model.drives import DRIVES, constants, motor_speed
from boom_hydraulics.model.parameters import Parameters, with_updates
from boom_hydraulics.solve import accelerate, commands
from boom_hydraulics.solve.commands import steps
from boom_hydraulics.solve.simulation import simulate
from boom_hydraulics.solve.simulator import Simulator

P = Parameters()
VALVE_DRIVES = [name for name, module in DRIVES.items() if module.VALVE]
SPEED = physical.DRIVE_STATE + 1  # the motor's speed state (drive_state_2)
SPOOL = physical.STATE_NAMES.index("x_v")
#: The loader crane's work cycle (solve/duty_cycles), s.
LOADER_S = 18.5
#: The loader cycle's battery energy (drawn) and motor loss of each valve drive at d39ea8d, before
#: motor_strategy and valve_centre existed, J (compiled rk4; ``boom-sim run --profile loader``).
BEFORE = {
    "pressure_compensated": (29607.74146657668, 8017.4618627144655),
    "fixed_pump": (200896.88745078415, 19103.841794374708),
    "load_sensing": (12389.761343825732, 7765.475515125057),
}


def _loader(**updates) -> tuple[dict[str, float], Simulator]:
    """The ledger's integrals (J, by name) over the loader cycle with the parameters ``updates``."""
    base = with_updates(P, **updates)
    params = with_updates(base, **commands.scenario("loader", LOADER_S, base))
    sim = Simulator(params)
    sim.run(LOADER_S, commands.from_parameters(params), every=100)
    return physical.ledger_integrals(sim.y), sim


@pytest.mark.parametrize("drive", VALVE_DRIVES)
def test_the_constant_strategy_is_todays_drive_to_the_bit_and_ignores_the_new_parameters(drive):
    """The default strategy gives the loader cycle's battery energy and motor loss of d39ea8d to
    the bit, and neither the other strategies' parameters nor the open centre's act on it."""
    integrals, sim = _loader(drive=drive)
    assert (integrals["battery_drawn"], integrals["motor_loss"]) == BEFORE[drive]
    assert sim.y[SPEED] == 0.0 and sim.y[SPEED + 1] == 0.0  # the motor's states stand still
    others, _ = _loader(
        drive=drive,
        motor_min_speed_rad_s=80.0,
        motor_rotor_inertia_kg_m2=0.2,
        motor_idle_stop_s=0.5,
        open_centre_pressure_drop_pa=2e6,
        open_centre_closed_opening=0.3,
    )
    assert others == integrals


def _steady_lift(drive: str, u: float) -> tuple[Simulator, dict[str, float]]:
    sim = Simulator(with_updates(P, drive=drive, motor_strategy="speed_on_demand"))
    sim.step(0.0, 100)
    sim.step(u, 700)  # the spool's and the motor's lags have settled, the boom lifts steadily
    return sim, sim.outputs()


def test_speed_on_demand_turns_the_variable_pump_at_the_speed_that_delivers_the_flow_and_its_leakage():
    """Lifting steadily, pressure_compensated's motor turns at w = (Q + G_p dp) / D (eq. D62): Q
    the valve's P flow (into the piston chamber, the A->T and the closed P->B paths' leakage),
    dp the P port's pressure over tank; below w_n and above w_min."""
    sim, out = _steady_lift("pressure_compensated", 1.0)
    d = constants(sim.params)
    dp = out["p_supply"] - P.tank_pressure_pa
    # the P->A path feeds the piston chamber and the A->T path's leakage; P->B leaks
    q = out["q_in1"] + P.valve_leakage_m3_s_pa * (out["p1"] - P.tank_pressure_pa + out["p_supply"] - out["p2"])
    expected = (q + d.pump_leak * dp) / d.displacement  # eq. D62
    speed = sim.y[SPEED]
    sim.step(1.0, 1)
    lag = P.motor_time_constant_s * (sim.y[SPEED] - speed) / P.time_step_s  # eq. D63: w* - w = tau_m w'
    assert speed + lag == pytest.approx(expected, rel=5e-4)
    assert speed == pytest.approx(expected, rel=5e-3)  # the boom's slow acceleration: the motor keeps up
    assert P.motor_min_speed_rad_s < expected < 0.9 * P.pump_speed_rad_s
    assert out["v"] > 0.0 and out["p_supply"] == pytest.approx(P.supply_pressure_pa)  # it still holds p_n


def test_speed_on_demand_turns_the_fixed_pump_with_the_spool_and_spills_less_over_the_relief():
    """fixed_pump's motor follows the spool, |x| w_n (eq. D62): half open, half speed. The default
    valve passes the pump's full flow only at 28 MPa, so the open path takes less than |x| Q_max
    at p_n and the relief still spills, but less than half what it spills at constant speed."""
    sim, out = _steady_lift("fixed_pump", 0.5)
    assert sim.y[SPEED] == pytest.approx(0.5 * P.pump_speed_rad_s, rel=1e-3)
    constant = Simulator(with_updates(P, drive="fixed_pump"))
    constant.step(0.0, 100)
    constant.step(0.5, 700)
    before = constant.outputs()
    assert out["v"] == pytest.approx(before["v"], rel=0.05)  # the line at the relief either way
    assert out["main_relief_loss_j"] < 0.5 * before["main_relief_loss_j"]
    assert out["battery_drawn"] < 0.6 * before["battery_drawn"]


def test_speed_on_demand_cuts_load_sensings_battery_energy_over_the_loader_cycle():
    """Most of what load sensing draws at constant speed is the motor's speed loss k_s w (about
    420 W idling): following the valves' demand, the motor turns at w_min while the boom holds."""
    constant, _ = _loader(drive="load_sensing")
    on_demand, sim = _loader(drive="load_sensing", motor_strategy="speed_on_demand")
    assert on_demand["battery_drawn"] < 0.7 * constant["battery_drawn"], (on_demand, constant)  # measured: 0.59
    assert on_demand["motor_loss"] < 0.5 * constant["motor_loss"]
    assert abs(sim.energy_residual()) < 1.0  # J: the rotors' energy is in the stored energy


def _idle_run(**updates) -> tuple[list[tuple[float, float, float, float]], Simulator]:
    """(t, spool, speed, rotor energy integral) every 10 ms of a run with the spool closed for 3 s,
    then opening to lift, under idle_stop with pressure_compensated."""
    sim = Simulator(with_updates(P, drive="pressure_compensated", motor_strategy="idle_stop", **updates))
    rotor = ledger.INTEGRALS.index("rotor_power") + physical.LEDGER_STATES
    drawn = physical.BATTERY_DRAWN
    rows = []
    for k in range(350):
        sim.step(0.0 if k < 300 else 1.0, 10)
        rows.append(((k + 1) * 10 * P.time_step_s, sim.y[SPOOL], sim.y[SPEED], sim.y[rotor], sim.y[drawn]))
    return rows, sim


def _first(rows, condition, after: float = 0.0) -> tuple:
    return next(r for r in rows if r[0] > after and condition(r))


def test_idle_stop_stops_the_motor_after_the_set_time_and_restarts_it_through_its_inertia():
    """Without demand the motor runs on for motor_idle_stop_s, then stops (eq. D61); the next
    demand restarts it, the speed rising with the motor's time constant (eq. D63), and the
    restart puts J w_n^2 / 2 into the rotors and draws that plus the motor's losses."""
    rows, sim = _idle_run()
    w_n, j = P.pump_speed_rad_s, P.motor_rotor_inertia_kg_m2
    stopping = _first(rows, lambda r: r[2] < 0.5 * w_n)[0]
    assert 0.95 * P.motor_idle_stop_s < stopping < 1.1 * P.motor_idle_stop_s
    stopped = _first(rows, lambda r: r[0] >= 2.9)
    assert stopped[2] < 1e-3 * w_n
    demand = _first(rows, lambda r: abs(r[1]) >= motor_speed.DEMAND_OPENING, after=3.0)
    running = _first(rows, lambda r: r[2] >= 0.9 * w_n, after=3.0)
    # 90 % of the way takes ln(10) tau_m after the target steps up
    assert running[0] - demand[0] >= 2.0 * P.motor_time_constant_s
    assert running[0] - demand[0] < 0.3
    end = rows[-1]
    assert end[3] - stopped[3] == pytest.approx(0.5 * j * (end[2] ** 2 - stopped[2] ** 2), rel=1e-3)
    assert abs(sim.energy_residual()) < 1.0
    # against the same run without rotor inertia, the restart draws J w_n^2 / 2 plus the losses of
    # the accelerating torque J w': its copper loss k_c (J w')^2 (~10 J), its cross term with the
    # pump's torque 2 k_c T_pump J w' (< 50 J) and the battery's R I^2 on the extra current
    # (~40 J): measured 1.31 J w_n^2 / 2
    light, _ = _idle_run(motor_rotor_inertia_kg_m2=0.0)
    extra = (end[4] - stopped[4]) - (light[-1][4] - _first(light, lambda r: r[0] >= 2.9)[4])
    assert 1.0 < extra / (0.5 * j * w_n * w_n) < 1.5


@pytest.mark.parametrize("drive", VALVE_DRIVES)
def test_a_motor_stopped_for_a_long_hold_or_started_from_standstill_runs_again(drive):
    """idle_stop: through a minute's hold the stopped motor's speed decays to a denormal, the
    pump holding no pressure, and the next demand starts it. speed_on_demand with no minimum
    speed starts at standstill; holding, a variable pump turns only as fast as its leakage at
    its pressure asks ((G_p dp + Q_leak) / D), the fixed pump not at all; lifting starts it."""
    sim = Simulator(with_updates(P, drive=drive, motor_strategy="idle_stop"))
    sim.step(0.0, 60_000)
    assert sim.y[SPEED] < 1e-200
    sim.step(1.0, 500)
    assert sim.y[SPEED] > 0.9 * P.pump_speed_rad_s and sim.outputs()["v"] > 0.0
    sim = Simulator(with_updates(P, drive=drive, motor_strategy="speed_on_demand", motor_min_speed_rad_s=0.0))
    assert sim.y[SPEED] == 0.0
    sim.step(0.0, 2000)
    d = constants(sim.params)
    out = sim.outputs()
    # the pump's leakage and the closed P->B path's, and P->A's where it exceeds A->T's (the
    # load-holding valve checks a net outflow of line A)
    ps, p1, p2 = out["p_supply"], out["p1"], out["p2"]
    p_to_a = d.leak * (ps - p1) * (ps - p1 > p1 - P.tank_pressure_pa)
    leakage = (d.pump_leak * (ps - P.tank_pressure_pa) + d.leak * (ps - p2) + p_to_a) / d.displacement
    assert sim.y[SPEED] == pytest.approx(0.0 if drive == "fixed_pump" else leakage, rel=0.02, abs=1e-9)
    sim.step(1.0, 500)
    assert sim.y[SPEED] > 0.2 * P.pump_speed_rad_s and sim.outputs()["v"] > 0.0


@pytest.mark.parametrize("strategy", motor_speed.STRATEGIES)
@pytest.mark.parametrize("drive", [*VALVE_DRIVES, "fixed_pump open"])
def test_the_ledger_closes_over_the_loader_cycle_for_every_strategy(drive, strategy):
    """Battery energy less every loss, work and stored term (the rotors' energy among them) is
    under 0.5 % of what the battery gave, and the stepping's energy check holds."""
    name, _, centre = drive.partition(" ")
    integrals, sim = _loader(drive=name, motor_strategy=strategy, valve_centre=centre or "closed")
    energies = ledger.energies_of(integrals)
    assert energies["imbalance_ratio"] < 0.005, energies
    assert abs(sim.energy_residual()) < 1e-4 * integrals["battery_drawn"]
    assert min(integrals[n] for n, _, kind, _ in ledger.TERMS if kind == "loss") >= 0.0


def _orifice_flow(k: float, dp: float) -> float:
    """The laminar-turbulent orifice ("Orifices and the 4/3 valve")."""
    return k * dp / (dp * dp + P.transition_pressure_pa**2) ** 0.25


def test_an_open_centre_passes_the_fixed_pumps_flow_to_tank_at_its_pressure_drop_in_neutral():
    """Spool closed, the line sits where the open centre passes what the pump delivers (eq. D67):
    K_c f(dp) = D w_n - G_p dp, K_c such that the centre passes Q_max at its stated drop; the
    battery gives a few hundred W where the closed centre spills ~8 kW over the relief."""
    sim = Simulator(with_updates(P, drive="fixed_pump", valve_centre="open"))
    sim.step(0.0, 500)
    d = constants(sim.params)
    drop, p_tr = P.open_centre_pressure_drop_pa, P.transition_pressure_pa
    k_c = P.pump_max_flow_m3_s * (drop * drop + p_tr * p_tr) ** 0.25 / drop
    lo, hi = 0.0, 2.0 * drop
    for _ in range(100):  # bisection on the balance of eq. D67
        mid = 0.5 * (lo + hi)
        surplus = d.displacement * d.speed - d.pump_leak * mid - _orifice_flow(k_c, mid)
        lo, hi = (mid, hi) if surplus > 0.0 else (lo, mid)
    out = sim.outputs()
    assert out["p_supply"] - P.tank_pressure_pa == pytest.approx(lo, rel=1e-3)
    assert out["battery_power"] < 1000.0
    closed = Simulator(with_updates(P, drive="fixed_pump"))
    closed.step(0.0, 500)
    assert closed.outputs()["battery_power"] > 10e3


def test_opening_the_spool_closes_the_centre_and_lifts_as_the_closed_centre_does_beyond_it():
    """Slightly open, the open centre keeps the line below the load and the boom does not lift
    (the flow goes to tank); fully open, the centre is closed and the boom lifts as fast as with
    a closed centre."""
    speeds = {}
    for centre in ("closed", "open"):
        sim = Simulator(with_updates(P, drive="fixed_pump", valve_centre=centre))
        sim.step(0.0, 100)
        sim.step(0.05, 500)
        speeds[centre, 0.05] = sim.outputs()["v"]
        sim.step(1.0, 300)
        speeds[centre, 1.0] = sim.outputs()["v"]
    assert speeds["closed", 0.05] > 1e-3 and abs(speeds["open", 0.05]) < 1e-4, speeds
    assert speeds["open", 1.0] == pytest.approx(speeds["closed", 1.0], rel=0.02)
    assert math.isfinite(speeds["open", 1.0])


@pytest.mark.skipif(not accelerate.available(), reason="numba is switched off")
@pytest.mark.parametrize(
    "updates",
    [
        {"drive": "load_sensing", "motor_strategy": "speed_on_demand"},
        {"drive": "fixed_pump", "motor_strategy": "idle_stop", "valve_centre": "open", "motor_idle_stop_s": 0.5},
        {"drive": "pressure_compensated", "motor_strategy": "idle_stop", "motor_idle_stop_s": 0.5},
    ],
)
def test_each_strategy_runs_the_same_compiled_and_interpreted(updates):
    """Lift, hold long enough for idle_stop to stop the motor, lower, hold: the compiled model
    and the interpreted one agree (numba nopython and Python give one model)."""
    command = steps([0.0, 0.1, 0.6, 1.6, 2.2], [0.0, 1.0, 0.0, -0.6, 0.0])
    params = with_updates(P, **updates)
    compiled, interpreted = simulate(params, 2.5, command, jit=True), simulate(params, 2.5, command, jit=False)
    for name in ("q1", "p1", "p2", "p_supply", "battery_drawn", "rotor_power_j"):
        scale = max(np.max(np.abs(interpreted[name])), 1.0)
        assert np.max(np.abs(compiled[name] - interpreted[name])) <= 1e-9 * scale, name


@jit.kernel(native.cache_sources())  # (cached beside the FMU's object file: compiled once, not every run)
def _compiled_drive_derivations(row: np.ndarray) -> tuple:
    """The drive's constants and state at rest as the native FMU's code derives them from a row."""
    p = native.surrogate_of(row)
    d = drives.constants(p)
    return d, drives.initial_state(p.drive, d)


@pytest.mark.skipif(not accelerate.available(), reason="numba is switched off")
@pytest.mark.parametrize(
    "changes",
    [
        {"drive": "fixed_pump", "valve_centre": "open", "motor_strategy": "idle_stop"},
        {"drive": "load_sensing", "motor_strategy": "speed_on_demand", "motor_min_speed_rad_s": 30.0},
    ],
)
def test_the_native_fmu_derives_the_strategies_constants_and_initial_state_to_the_bit(changes):
    """Compiled code (the native FMU) derives the drive's constants, the strategy's and the open
    centre's among them, and its initial state from the parameters as Python does."""
    params = with_updates(P, **changes)
    d, z = _compiled_drive_derivations(np.array(native.row_of(params)))
    assert tuple(d) == tuple(constants(params))
    assert z == drives.initial_state(params.drive, constants(params))
