"""The gas-charged accumulator (issue 51, item 1; docs/model.md, "Accumulator", eq. A1-A7): its gas
spring against the closed forms, its effect on the boom's ringing against `linearize`, its energy
in the ledger and the stepping's check, off by default, a sweep axis and a re-simulated bag."""

from __future__ import annotations

import csv
import math

import numpy as np
import pytest
from conftest import CONFIG, run_tool

from boom_hydraulics.analysis import linear_model as lm
from boom_hydraulics.analysis.operating_point import operating_point
from boom_hydraulics.errors import ConfigError
from boom_hydraulics.model import accumulator, hydraulics, ledger, physical
from boom_hydraulics.model.config import load
from boom_hydraulics.model.parameters import Parameters, with_updates
from boom_hydraulics.solve import commands
from boom_hydraulics.solve.simulation import Simulator

#: The 1 t crane with its accumulator alone (its hoses and elastic boom off: the closed forms are the rigid boom's).
CRANE = with_updates(load(CONFIG / "loader_crane_1t.yaml"), hose_length_m=0.0, boom_bending_stiffness_n_m2=0.0)
#: The crane without its accumulator, and with it (the config's: 0.5 L, 8 MPa, 1.2 mm, piston line).
BARE = with_updates(CRANE, accumulator_gas_volume_m3=0.0)
FILL = physical.ACCUMULATOR_STATE


def test_the_gas_spring_is_the_polytrope_and_its_stiffness_n_p_over_v_gas():
    """p V_gas^n = p0 V0^n (eq. A1); dp/dV_oil = n p / V_gas (eq. A7) against a central difference
    and the closed form; the stored energy's slope is (p - p_t) V0 (eq. A5), isothermal and adiabatic."""
    p0, size, p_t = 6.0e6, 0.75e-3, 1.0e5
    for n in (1.0, 1.2, 1.4):
        for fill in (0.1, 0.316, 0.6):
            gas = size * (1.0 - fill)
            p = accumulator.gas_pressure_pa(fill, p0, n)
            assert p * gas**n == pytest.approx(p0 * size**n, rel=1e-12)  # eq. A1
            h = 1e-6
            dp_dv = (accumulator.gas_pressure_pa(fill + h, p0, n) - accumulator.gas_pressure_pa(fill - h, p0, n)) / (
                2 * h * size
            )
            stiffness = accumulator.gas_stiffness_pa_m3(fill, p0, n, size)
            assert stiffness == pytest.approx(n * p / gas, rel=1e-12)  # eq. A7
            assert dp_dv == pytest.approx(stiffness, rel=1e-6)
            de_dx = (
                accumulator.gas_energy_j(fill + h, p0, n, size, p_t)
                - accumulator.gas_energy_j(fill - h, p0, n, size, p_t)
            ) / (2 * h)
            assert de_dx == pytest.approx(size * (p - p_t), rel=1e-6)  # eq. A5
    # the closed forms of the polytropic work: (p V - p0 V0) / (n - 1), and p0 V0 ln(V0 / V) at n = 1
    p = accumulator.gas_pressure_pa(0.4, p0, 1.4)
    assert accumulator.gas_energy_j(0.4, p0, 1.4, size, 0.0) == pytest.approx((p * 0.6 * size - p0 * size) / 0.4)
    assert accumulator.gas_energy_j(0.4, p0, 1.0, size, 0.0) == pytest.approx(p0 * size * math.log(1 / 0.6))
    # an empty bladder: the gas stays at p0, and an outflow is shut by the poppet, an inflow passes
    assert accumulator.gas_pressure_pa(-0.01, p0, 1.4) == p0
    k = 1e-7
    assert accumulator.port_flow_m3_s(0.0, 5.0e6, p0, k, 9e10) == 0.0
    assert accumulator.port_flow_m3_s(0.0, 7.0e6, p0, k, 9e10) > 0.0
    assert (
        0.0
        > accumulator.port_flow_m3_s(0.01, 5.0e6, p0, k, 9e10)
        > accumulator.port_flow_m3_s(0.03, 5.0e6, p0, k, 9e10)
    )


def test_the_gas_law_holds_its_floor_past_a_full_bladder_and_p0_below_an_empty_one():
    """A stage beyond any relief pressure (fill 1 and past it) takes the least gas share, 1e-3:
    p0 / 1e-3^n, finite (eq. A1); below an empty bladder the gas stays at p0 and its energy goes
    on along (p0 - p_t) V0 x, so that its rate stays (p_gas - p_t) V0 dx/dt (eq. A5)."""
    p0, size, p_t = 6.0e6, 0.75e-3, 1.0e5
    for n in (1.0, 1.4):
        floor = p0 * 1e-3**-n
        for fill in (0.999, 1.0, 1.5):
            assert accumulator.gas_pressure_pa(fill, p0, n) == pytest.approx(floor, rel=1e-12), (n, fill)
        assert accumulator.gas_stiffness_pa_m3(1.5, p0, n, size) == pytest.approx(n * floor / (1e-3 * size), rel=1e-12)
        for fill in (-0.01, -0.3):
            assert accumulator.gas_energy_j(fill, p0, n, size, p_t) == pytest.approx(
                size * (p0 - p_t) * fill, rel=1e-12
            )


def test_a_nearly_empty_bladders_energy_is_the_polytropic_work_to_rounding():
    """Where (n - 1) ln(V0 / V_gas) is under 1e-8 the work takes its series (eq. A5): at a fill of
    2^-26 (1 - x exact in binary) it is the closed form ((1 - x)^(1 - n) - 1) / (n - 1) p0 V0 -
    p_t V0 x, computed to 40 digits, to 1e-13."""
    from decimal import Decimal, getcontext

    getcontext().prec = 40
    p0, size, p_t, fill = 6.0e6, 0.75e-3, 1.0e5, 2.0**-26
    for n in (1.2, 1.4):
        x, m = Decimal(fill), Decimal(str(n))
        work = ((1 - x) ** (1 - m) - 1) / (m - 1)
        exact = float(Decimal(size) * (Decimal(p0) * work - Decimal(p_t) * x))
        assert accumulator.gas_energy_j(fill, p0, n, size, p_t) == pytest.approx(exact, rel=1e-13, abs=0.0), n
    exact = float(Decimal(size) * (-Decimal(p0) * (1 - Decimal(fill)).ln() - Decimal(p_t) * Decimal(fill)))
    assert accumulator.gas_energy_j(fill, p0, 1.0, size, p_t) == pytest.approx(exact, rel=1e-13, abs=0.0)  # isothermal


def test_the_poppet_throttles_only_an_outflow_and_closes_smoothly_over_the_last_2_percent():
    """An inflow passes the orifice's whole flow at any fill; an outflow passes it from a fill of
    CLOSING_FILL (2 %) on, and below it smoothstep(x / 0.02) of it: a half at 1 %, 0.15625 at
    0.5 %, none at 0 (eq. A3, A4)."""
    p0, k, transition2 = 6.0e6, 1e-7, 9e10
    assert accumulator.CLOSING_FILL == 0.02
    for line in (7.0e6, 6.5e6, 6.0e6 + 0.5, 5.0e6, 6.0e6 - 0.5):  # (and half a pascal either side)
        orifice = hydraulics.orifice_flow(k, line - p0, transition2)
        inflow = line > p0
        for fill, gate in [(0.0, 0.0), (0.005, 0.15625), (0.01, 0.5), (0.02, 1.0), (0.3, 1.0)]:
            flow = accumulator.port_flow_m3_s(fill, line, p0, k, transition2)
            assert flow == pytest.approx(orifice * (1.0 if inflow else gate), rel=1e-12, abs=0.0), (line, fill)


def test_the_start_fills_the_bladder_to_hold_the_lines_pressure_and_leaves_it_empty_below_p0():
    p0 = 8.0e6
    assert accumulator.initial_fill(16.0e6, p0, 1.0) == pytest.approx(0.5, rel=1e-15)  # p0 V0 = 2 p0 V_gas
    assert accumulator.initial_fill(p0 * 2.0**1.4, p0, 1.4) == pytest.approx(0.5, rel=1e-12)
    for line in (p0, 7.9e6, 1.0e5, 0.0):
        assert accumulator.initial_fill(line, p0, 1.4) == 0.0, line


def _stiffness_closed_form(p: Parameters, point) -> tuple[float, float]:
    """(k_eff, m_eff) of the boom on its oil springs with the gas's compliance beside the piston
    chamber's oil (docs/model.md, "Accumulator": C1 = V1 / E + V_gas / (n p_gas), in parallel),
    k_eff = S1^2 / C1 + E S2^2 / V2 + F_s / z_ba."""
    c = physical.constants(p)
    v1, v2, _, _ = physical.chamber_volumes(point.q1_m, c)
    compliance = v1 / c.bulk_modulus
    if p.accumulator_gas_volume_m3 > 0.0:
        fill = point.state[FILL]
        compliance += 1.0 / accumulator.gas_stiffness_pa_m3(fill, c.acc_precharge, c.acc_exponent, c.acc_size)
    stiffness = c.s1**2 / compliance + c.bulk_modulus * c.s2**2 / v2 + c.static / c.presliding
    return stiffness, lm.effective_mass_at(p, point.q1_m)


def test_linearize_drops_the_hydraulic_mode_as_the_gas_spring_in_parallel_with_the_oil_says():
    """With a wide orifice the gas joins the piston chamber's oil: omega = sqrt(k_eff / m_eff) with
    the two compliances in parallel; without the accumulator the oil alone (the closed form of
    test_linearize)."""
    wide = with_updates(CRANE, accumulator_orifice_diameter_m=0.02)
    for p in (BARE, wide):
        point = operating_point(p, p.initial_length_m)
        mode = lm.linearize(point).hydraulic_mode()
        k_eff, m_eff = _stiffness_closed_form(p, point)
        assert mode.natural_frequency_hz == pytest.approx(math.sqrt(k_eff / m_eff) / (2 * math.pi), rel=5e-3)
    # the gas holds the piston chamber's pressure at the operating point (eq. A1: its fill settled)
    gas = accumulator.gas_pressure_pa(
        point.state[FILL], wide.accumulator_precharge_pa, wide.accumulator_polytropic_exponent
    )
    assert gas == pytest.approx(point.state[2], rel=1e-9)
    bare = lm.linearize(operating_point(BARE, BARE.initial_length_m)).hydraulic_mode()
    assert mode.natural_frequency_hz < 0.65 * bare.natural_frequency_hz  # 4.0 Hz -> 2.3 Hz


def _reduced_eigenvalue(p: Parameters, point) -> complex:
    """The hydraulic pair of the closed-form linear model (docs/model.md, "Accumulator"): the
    mass on the seals' presliding spring and damping, the rod chamber's oil spring (its closed
    valve paths leaking), the piston chamber's oil (its load-holding seat leaking) behind the
    orifice's laminar conductance G from the gas spring (eq. A3, A7)."""
    c = physical.constants(p)
    v1, v2, _, _ = physical.chamber_volumes(point.q1_m, c)
    m = lm.effective_mass_at(p, point.q1_m)
    g = c.acc_slope  # dQ/dp of the orifice at dp = 0: K / sqrt(p_tr)
    k_gas = accumulator.gas_stiffness_pa_m3(point.state[FILL], c.acc_precharge, c.acc_exponent, c.acc_size)
    e1, e2 = c.bulk_modulus / v1, c.bulk_modulus / v2
    damping = c.presliding_damping + c.viscous
    # x, v, p1, p2, p_gas
    a = np.array(
        [
            [0.0, 1.0, 0.0, 0.0, 0.0],
            [-c.static / c.presliding / m, -damping / m, c.s1 / m, -c.s2 / m, 0.0],
            [0.0, -e1 * c.s1, -e1 * (g + c.holding * c.seat_leak), 0.0, e1 * g],
            [0.0, e2 * c.s2, 0.0, -e2 * 2.0 * c.leak, 0.0],  # the closed valve's P->B and B->T leak
            [0.0, 0.0, k_gas * g, 0.0, -k_gas * g],
        ]
    )
    values = np.linalg.eigvals(a)
    return values[np.argmax(np.abs(values.imag))]


@pytest.mark.parametrize("orifice_m", [0.0012, 0.003, 0.006])
def test_the_orifice_damps_the_ringing_as_the_closed_form_model_says(orifice_m):
    """The hydraulic mode's frequency and damping at three orifices against the closed-form
    five-state model; the crane's 1.2 mm damps it 15 times more than no accumulator does."""
    p = with_updates(CRANE, accumulator_orifice_diameter_m=orifice_m)
    point = operating_point(p, p.initial_length_m)
    mode = lm.linearize(point).hydraulic_mode()
    lam = _reduced_eigenvalue(p, point)
    assert mode.natural_frequency_hz == pytest.approx(abs(lam) / (2 * math.pi), rel=2e-3)
    assert mode.damping_ratio == pytest.approx(-lam.real / abs(lam), rel=5e-3)
    bare = lm.linearize(operating_point(BARE, BARE.initial_length_m)).hydraulic_mode()
    if orifice_m == CRANE.accumulator_orifice_diameter_m:
        assert mode.damping_ratio > 15.0 * bare.damping_ratio


def _loader(p: Parameters, seconds: float = 18.5) -> tuple[dict[str, float], Simulator, list]:
    params = with_updates(p, **commands.scenario("loader", seconds, p))
    sim = Simulator(params)
    fills = []
    for _ in range(round(seconds)):
        sim.run(1.0, commands.from_parameters(params), every=100)
        fills.append(float(sim.y[FILL]))
    return physical.ledger_integrals(sim.y), sim, fills


@pytest.mark.parametrize(
    "updates",
    [
        {},  # the crane's: on the piston line
        {"drive": "fixed_pump", "valve_centre": "closed", "accumulator_position": "supply",
         "accumulator_precharge_pa": 1.8e7, "accumulator_gas_volume_m3": 1e-3, "accumulator_orifice_diameter_m": 0.006},
    ],
)  # fmt: skip
def test_over_the_loader_cycle_the_ledger_closes_and_the_stored_energy_holds_the_gas(updates):
    """The crane's loader cycle with the accumulator on the piston line, and on fixed_pump's supply
    line (charged to 0.9 of the 20 MPa dead-heading pressure, it gives oil when the valve opens):
    the ledger closes within 0.5 %, the stepping's energy check within 1e-4 of what the battery
    gave, and the accumulator throttled and stored energy the whole time."""
    p = with_updates(CRANE, **updates)
    integrals, sim, fills = _loader(p)
    energies = ledger.energies_of(integrals)
    assert energies["imbalance_ratio"] < 0.005, energies
    assert abs(sim.energy_residual()) < 1e-4 * integrals["battery_drawn"]
    assert integrals["accumulator_loss"] > 1e-4 * integrals["battery_drawn"]
    c = physical.constants(p)
    start = physical.initial_state(p)[FILL]
    gas = [
        accumulator.gas_energy_j(x, c.acc_precharge, c.acc_exponent, c.acc_size, c.p_tank) for x in (start, sim.y[FILL])
    ]
    assert integrals["gas_power"] == pytest.approx(gas[1] - gas[0], abs=1e-5 * integrals["battery_drawn"])
    assert max(fills) - min(fills) > 0.02  # the oil went in and out
    assert min(integrals[n] for n, _, kind, _ in ledger.TERMS if kind == "loss") >= 0.0


def test_off_by_default_its_state_and_terms_stay_zero_and_its_other_parameters_do_not_act():
    """Default parameters: no accumulator; its fill and ledger terms stay exactly 0, and its
    other parameters change nothing to the bit."""
    assert Parameters().accumulator_gas_volume_m3 == 0.0
    runs = []
    for updates in ({}, {"accumulator_precharge_pa": 2e6, "accumulator_orifice_diameter_m": 0.01}):
        p = with_updates(Parameters(), **updates)
        integrals, sim, fills = _loader(p, 4.0)
        assert fills == [0.0] * 4 and integrals["accumulator_loss"] == 0.0 and integrals["gas_power"] == 0.0
        runs.append(list(sim.y))
    assert runs[0] == runs[1]


def test_a_supply_accumulator_needs_a_drive_with_a_supply_line():
    with pytest.raises(ConfigError, match="needs a drive with a supply line") as refused:
        with_updates(CRANE, accumulator_position="supply")
    assert "\n" not in str(refused.value)
    with_updates(CRANE, accumulator_position="supply", drive="fixed_pump")  # the drive that has one
    with_updates(CRANE, accumulator_position="supply", accumulator_gas_volume_m3=0.0)  # none: nothing to place


def test_the_accumulators_size_is_a_sweep_axis(tmp_path):
    """boom-sweep --vary accumulator_gas_volume_m3: the linear model's mode at mid-stroke goes
    down in frequency and up in damping with the crane's accumulator."""
    out = tmp_path / "sweep"
    result = run_tool(
        "boom-sweep", "--config", CONFIG / "loader_crane_1t.yaml", "--vary", "accumulator_gas_volume_m3=0,0.0005",
        "--set", "hose_length_m=0", "--set", "boom_bending_stiffness_n_m2=0",
        "--duration", "1.5", "--lift-angle-deg", "8", "--no-plots", "--out", out,
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    with (out / "results.csv").open() as handle:
        rows = list(csv.DictReader(handle))
    assert [float(r["accumulator_gas_volume_m3"]) for r in rows] == [0.0, 0.0005]
    assert {r["status"] for r in rows} == {"ok"}
    bare, fitted = rows
    assert float(fitted["natural_frequency_hz"]) < 0.9 * float(bare["natural_frequency_hz"])
    assert float(fitted["linear_damping_ratio"]) > 5.0 * float(bare["linear_damping_ratio"])
    assert float(fitted["accumulator_loss_j"]) > 0.0 == float(bare["accumulator_loss_j"])


def test_a_bag_recorded_with_the_accumulator_on_resimulates_exactly(tmp_path):
    """A bag as the node records it (states each 10 ms, commands as taken; the pattern of
    test_resim_timing) of the crane with its accumulator lifting and stopping: boom-resim
    rebuilds the accumulator from the bag's parameters and reproduces the rod and p1 to the bit."""
    from machine_bags import EPOCH_NS, valve_command

    from boom_hydraulics.bags.encoding import DRIVE_STATE, drive_state_cdr
    from boom_hydraulics.bags.reading import read_drive_states
    from boom_hydraulics.bags.recording import BagRecorder, Topic, run_description
    from boom_hydraulics.solve.command_queue import CommandedDrive

    tick_s, timeout_s = 0.01, 1.0
    sim = Simulator(CRANE)
    drive = CommandedDrive(sim, timeout_s)
    opened = {20: 0.8, 120: 0.0, 150: -0.5, 220: 0.0}  # tick: opening (a lift, a stop that rings, a lowering)
    topics = [Topic("/drive_state", DRIVE_STATE), Topic("/valve_command", "boom_hydraulics_msgs/msg/ValveCommand")]
    custom = run_description(CRANE, EPOCH_NS, 1 / tick_s, timeout_s, node="/boom_sim")
    bag = tmp_path / "accumulator"
    fills = []
    with BagRecorder(bag, topics, custom_data=custom) as rec:
        for k in range(1, 300):
            if k in opened:
                rec.write("/valve_command", EPOCH_NS + round((k * tick_s - 5e-4) * 1e9), valve_command(0, opened[k]))
                drive.push(sim.t, opened[k])
            drive.advance(round(k * tick_s / CRANE.time_step_s) - sim.step_count)
            fills.append(float(sim.y[FILL]))
            stamp_ns = EPOCH_NS + round(sim.t * 1e9)
            rec.write("/drive_state", stamp_ns + 700_000, drive_state_cdr(sim.outputs(), stamp_ns))
    assert max(fills) - min(fills) > 0.01  # the accumulator took oil and gave it back
    result = run_tool("boom-resim", bag, "--out", tmp_path / "again")
    assert result.returncode == 0, result.stderr
    recorded, again = read_drive_states(bag), read_drive_states(tmp_path / "again")
    assert len(again["q1"]) == len(recorded["q1"]) == 299
    assert np.max(np.abs(again["q1"] - recorded["q1"])) < 1e-12
    assert np.max(np.abs(again["p1"] - recorded["p1"])) < 1e-6
    bare = run_tool("boom-resim", bag, "--set", "accumulator_gas_volume_m3=0", "--out", tmp_path / "bare")
    assert bare.returncode == 0, bare.stderr
    assert np.max(np.abs(read_drive_states(tmp_path / "bare")["p1"] - recorded["p1"])) > 1e5  # it acts
