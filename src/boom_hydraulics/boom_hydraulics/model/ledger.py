"""The energy ledger, from battery to hook: every term as a power, and the balance that closes.

Every joule the battery gives ends in one term (eq. D29):

    P_batt + P_res = P_R + P_m + P_sb + P_v + P_hm + P_mr + P_valve + P_leak + P_pr
                     + P_fr + P_stop + P_amb + P_ext + P_oil + dT_rot/dt + dT/dt + dPi/dt
                     + P_acc + dE_gas/dt + P_line

- sources: the battery's chemical power P_batt = U I (negative while it takes power back)
  and the EHA's low-pressure reservoir, P_res (relative to tank pressure);
- losses, each >= 0: battery resistance, motor and inverter, standby (inverter, controller
  and auxiliaries, drawn whatever the load), pump (volumetric and
  hydro-mechanical), main relief, valve throttling (the 4/3 valve and load-holding valve,
  or the EHA's checks), leakage (the valve paths' laminar part and the load-holding
  valve's seat), port reliefs, the hoses' friction (P_line, at the end: eq. H6);
- work on the surroundings: seal friction, the end stops (and the chamber that shrinks in
  them), the ambient pressure on the rod's end (relative to tank pressure), the external
  rod force (P_ext = -F_ext v: negative where the surroundings push the rod the way it moves);
- stored: what the oil takes in (chambers, hoses and supply line: compression, and the void
  while cavitating; the hoses' flow's kinetic energy), the kinetic energy of the drive's
  rotors, the kinetic and the potential energy (weight and spring);
- the accumulator (off by default): its orifice's throttling P_acc (a loss) and the rate of
  its gas's energy dE_gas/dt (stored), eq. A6;
- the hoses (off by default): their friction P_line (a loss), eq. H6.

The hydraulic terms count pressures above tank pressure, as the model's energies do. Each
link of the chain balances on its own (eq. D26-D28); their sum is eq. D29, an identity of
the model's equations at every instant, so that the integrals of the terms balance over a
cycle to the integrator's accuracy.

Equations and conventions: docs/model.md, section "Energy ledger".
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from types import ModuleType
from typing import Any, NamedTuple

from ..jit import jitable
from .battery import battery_current_a, battery_loss_w, chemical_power_w, overloaded, state_of_charge_rate_1_s
from .drives.constants import DriveConstants, Supply
from .electric_motor import MotorLosses, machine_loss_w
from .hydraulics import pos

Num = Any  # float or numpy.ndarray

#: The ledger's terms: name, unit, kind (source, loss, work, stored) and what each is, in the
#: order of :class:`Ledger`. Each is an output signal; its integral (J) a state.
TERMS: tuple[tuple[str, str, str, str], ...] = (
    ("battery_power", "W", "source", "chemical power the battery gives (negative: takes back)"),
    ("reservoir_power", "W", "source", "power the EHA's low-pressure reservoir gives, above tank pressure"),
    ("battery_loss", "W", "loss", "battery's internal resistance, R I^2"),
    ("motor_loss", "W", "loss", "electric motor and inverter"),
    ("standby_loss", "W", "loss", "inverter, controller and auxiliaries, drawn whatever the load"),
    ("pump_volumetric_loss", "W", "loss", "pump leakage"),
    ("pump_mechanical_loss", "W", "loss", "pump friction torque"),
    ("main_relief_loss", "W", "loss", "main relief valve of the fixed pump"),
    ("valve_loss", "W", "loss", "throttling in the 4/3 valve and load-holding valve, or the EHA's checks"),
    ("leakage_loss", "W", "loss", "leakage of the valve's paths and of the load-holding valve's seat"),
    ("port_relief_loss", "W", "loss", "the chambers' relief valves"),
    ("friction_work", "W", "work", "work against the seal friction"),
    ("end_stop_work", "W", "work", "work into the end stops and the chambers they shrink"),
    ("ambient_work", "W", "work", "work against the ambient pressure on the rod's end, above tank pressure"),
    ("external_work", "W", "work", "work against the external rod force, -F_ext v (negative: it drives the rod)"),
    ("oil_work", "W", "stored", "what the oil of chambers, hoses and supply line takes in (compression, voids, flow)"),
    ("rotor_power", "W", "stored", "rate of the kinetic energy of the drive's motor and pump rotors"),
    ("kinetic_power", "W", "stored", "rate of the kinetic energy of boom and payload"),
    ("potential_power", "W", "stored", "rate of the potential energy of boom, payload and spring"),
    ("accumulator_loss", "W", "loss", "throttling in the accumulator's connecting orifice"),
    ("gas_power", "W", "stored", "rate of the accumulator gas's energy: polytropic work from its pre-charge"),
    ("line_loss", "W", "loss", "the hoses' friction between the drive's ports and the chambers (eq. H6)"),
    ("structural_loss", "W", "loss", "structural damping of the elastic boom's bending mode"),
)
TERM_NAMES = tuple(name for name, _, _, _ in TERMS)
#: The terms that supply energy; every other term takes it.
SOURCES = tuple(name for name, _, kind, _ in TERMS if kind == "source")


class Ledger(NamedTuple):
    """Every term of the energy ledger at one instant, W (see :data:`TERMS`)."""

    battery_power: Num
    reservoir_power: Num
    battery_loss: Num
    motor_loss: Num
    standby_loss: Num
    pump_volumetric_loss: Num
    pump_mechanical_loss: Num
    main_relief_loss: Num
    valve_loss: Num
    leakage_loss: Num
    port_relief_loss: Num
    friction_work: Num
    end_stop_work: Num
    ambient_work: Num
    external_work: Num
    oil_work: Num
    rotor_power: Num
    kinetic_power: Num
    potential_power: Num
    accumulator_loss: Num
    gas_power: Num
    line_loss: Num
    structural_loss: Num


assert Ledger._fields == TERM_NAMES, "TERMS and Ledger must name the same terms in one order"


class Chain(NamedTuple):
    """The electric chain from the battery to the pump's outlet at one instant (SI; eq. D26)."""

    torque: Num  # pump shaft torque, N m (eq. D2)
    shaft_power: Num  # T w, W
    motor_loss: Num  # W (eq. D6)
    electrical_power: Num  # at the battery's terminals, W (eq. D5)
    current: Num  # battery current, A, > 0 discharging (eq. D8)
    battery_loss: Num  # W (eq. D9)
    battery_power: Num  # U I, W (eq. D9)
    soc_rate: Num  # dSoC/dt, 1/s (eq. D10)
    pump_volumetric_loss: Num  # W (eq. D3)
    pump_mechanical_loss: Num  # W (eq. D3)
    hydraulic_power: Num  # dp Q at the pump's outlet, W
    overloaded: Num  # 1.0 where the battery cannot give the power asked (eq. D11)
    standby_loss: Num  # the drive's standby, the inverter's and the auxiliaries', W (eq. D5)


class Cylinder(NamedTuple):
    """The ledger's terms from the cylinder lines to the hook at one instant, W (eq. D28)."""

    port_relief_loss: Num
    oil_work: Num
    friction_work: Num
    end_stop_work: Num
    ambient_work: Num
    external_work: Num
    kinetic_power: Num
    potential_power: Num


@jitable
def electric_chain(s: Supply, d: DriveConstants, xp: ModuleType = math) -> Chain:
    """The drive's motor at its operating point ``s`` through the inverter to the battery
    (eq. D26): U I = R I^2 + P_m + P_sb + T w, the shaft power T w being the pump's
    (P_v + P_hm + dp Q) and its rotors' (dT_rot/dt). The motor's and inverter's loss P_m is
    one function of the torque and speed for every drive (eq. D6); the standby P_sb is the
    drive's own (``s.standby_loss``), the enabled inverter's P_0 and the auxiliaries' P_aux,
    drawn while the machine is on, whatever its load (eq. D5)."""
    m = MotorLosses(d.motor_copper, d.motor_iron, d.motor_current, d.motor_eddy, d.motor_windage, d.inverter_standby)
    shaft = s.torque * s.speed
    loss = machine_loss_w(s.torque, s.speed, m)  # eq. D6
    standby = s.standby_loss + d.inverter_standby + d.auxiliary_power
    electrical = shaft + loss + standby  # eq. D5
    current = battery_current_a(electrical, d.battery_voltage, d.battery_resistance, xp)  # eq. D8
    return Chain(
        s.torque,
        shaft,
        loss,
        electrical,
        current,
        battery_loss_w(current, d.battery_resistance),  # eq. D9
        chemical_power_w(current, d.battery_voltage),  # eq. D9
        state_of_charge_rate_1_s(current, d.battery_voltage, d.battery_capacity),  # eq. D10
        s.volumetric_loss,  # eq. D3
        s.mechanical_loss,  # eq. D3
        s.hydraulic_power,
        overloaded(electrical, d.battery_voltage, d.battery_resistance),  # eq. D11
        standby,
    )


@jitable
def cylinder_side(
    v: Num,
    acc: Num,
    p1_pa: Num,
    p2_pa: Num,
    q_in1: Num,
    q_in2: Num,
    dvol1_m2: Num,
    dvol2_m2: Num,
    q_relief1: Num,
    q_relief2: Num,
    f_friction_n: Num,
    f_stop_n: Num,
    f_spring_n: Num,
    lever: Num,
    lever_slope: Num,
    cos_alpha: Num,
    inertia: Num,
    weight_coeff: Num,
    s1: Num,
    s2: Num,
    p_tank_pa: Num,
    p_ambient_pa: Num,
    f_external_n: Num,
) -> Cylinder:
    """The ledger from the cylinder lines to the hook, W (eq. D28).

    ``q_in1``, ``q_in2`` are the net flows into the chambers (after the port reliefs, which
    take ``q_relief1``, ``q_relief2``), ``dvol1_m2``, ``dvol2_m2`` the chambers' dV/dq1, the
    forces those on the rod (friction opposing, the stops' pushing it out, the spring's
    pulling it in, the external force ``f_external_n`` extending it), and the rest the boom's
    lever, inertia and weight (physical.Constants). What the lines take,
    sum (p - p_t)(Q_in + Q_relief), equals the sum of the terms."""
    g1, g2 = p1_pa - p_tank_pa, p2_pa - p_tank_pa
    displaced = (g1 * dvol1_m2 + g2 * dvol2_m2) * v  # (p - p_t) dV/dt of both chambers
    rod = (g1 * s1 - g2 * s2) * v  # the same on the rod's areas: what turns into rod force
    return Cylinder(
        g1 * q_relief1 + g2 * q_relief2,
        g1 * q_in1 + g2 * q_in2 - displaced,  # eq. D28: (p - p_t)(Q_in - dV/dt)
        f_friction_n * v,
        displaced - rod - f_stop_n * v,  # the stops' work, and the chamber that shrinks in them
        (p_ambient_pa - p_tank_pa) * (s1 - s2) * v,
        -f_external_n * v,  # eq. D28: P_ext, the drive's work against F_ext (eq. 11)
        inertia * lever * v * (lever * acc + lever_slope * v * v),  # d/dt (J k^2 v^2 / 2) (eq. 8)
        weight_coeff * cos_alpha * lever * v + f_spring_n * v,  # d/dt of Pi (eq. 9) and the spring's energy
    )


@jitable
def assemble(
    chain: Chain,
    s: Supply,
    cylinder: Cylinder,
    accumulator_loss: Num,
    gas_power: Num,
    hose_oil_work: Num,
    hose_loss: Num,
    structural_loss: Num,
) -> Ledger:
    """The whole ledger from its links (eq. D29): the electric chain, the drive (its pump,
    valve or checks, relief and line), the hoses (what their oil takes in and their friction,
    eq. H6; 0 without hoses), the cylinder, the accumulator (its orifice's throttling and
    its gas's rate, eq. A6; 0 without one) and the elastic boom's structural damping
    (docs/model.md, "Elastic boom"; 0 for a rigid boom)."""
    return Ledger(
        chain.battery_power,
        s.reservoir_power,
        chain.battery_loss,
        chain.motor_loss,
        chain.standby_loss,
        chain.pump_volumetric_loss,
        chain.pump_mechanical_loss,
        s.main_relief_loss,
        s.valve_loss,
        s.leakage_loss,
        cylinder.port_relief_loss,
        cylinder.friction_work,
        cylinder.end_stop_work,
        cylinder.ambient_work,
        cylinder.external_work,
        cylinder.oil_work + s.line_oil_work + hose_oil_work,
        s.rotor_power,
        cylinder.kinetic_power,
        cylinder.potential_power,
        accumulator_loss,
        gas_power,
        hose_loss,
        structural_loss,
    )


@jitable
def residual_w(ledger: Ledger) -> Num:
    """Sources less every other term, W: zero but for rounding where the ledger's terms come
    from one evaluation of the model (eq. D29)."""
    return (
        ledger.battery_power
        + ledger.reservoir_power
        - ledger.battery_loss
        - ledger.motor_loss
        - ledger.standby_loss
        - ledger.pump_volumetric_loss
        - ledger.pump_mechanical_loss
        - ledger.main_relief_loss
        - ledger.valve_loss
        - ledger.leakage_loss
        - ledger.port_relief_loss
        - ledger.friction_work
        - ledger.end_stop_work
        - ledger.ambient_work
        - ledger.external_work
        - ledger.oil_work
        - ledger.rotor_power
        - ledger.kinetic_power
        - ledger.potential_power
        - ledger.accumulator_loss
        - ledger.gas_power
        - ledger.line_loss
        - ledger.structural_loss
    )


#: The ledger over a run, J, each the integral of a term (a state of the physical model, see
#: :func:`integral_rates`): the battery's chemical energy split into what it gave
#: (``battery_drawn``) and what it took back (``battery_returned``), both >= 0, every other
#: term's integral under the term's name, and ``lift_work``: the potential energy raised, the
#: integral of the positive part of ``potential_power`` (the useful work of a cycle that ends
#: where it began).
INTEGRALS = ("battery_drawn", "battery_returned", *TERM_NAMES[1:], "lift_work")


@jitable
def integral_rates(ledger: Ledger) -> tuple:
    """The rates of :data:`INTEGRALS` at one instant, W, in its order."""
    return (
        pos(ledger.battery_power),
        pos(-ledger.battery_power),
        ledger.reservoir_power,
        ledger.battery_loss,
        ledger.motor_loss,
        ledger.standby_loss,
        ledger.pump_volumetric_loss,
        ledger.pump_mechanical_loss,
        ledger.main_relief_loss,
        ledger.valve_loss,
        ledger.leakage_loss,
        ledger.port_relief_loss,
        ledger.friction_work,
        ledger.end_stop_work,
        ledger.ambient_work,
        ledger.external_work,
        ledger.oil_work,
        ledger.rotor_power,
        ledger.kinetic_power,
        ledger.potential_power,
        ledger.accumulator_loss,
        ledger.gas_power,
        ledger.line_loss,
        ledger.structural_loss,
        pos(ledger.potential_power),
    )


def energies_of(integrals: Mapping[str, float]) -> dict[str, float]:
    """The ledger over a run, J, from the integrals of its terms (``integrals``: by term name,
    with the battery's split into ``battery_drawn`` and ``battery_returned``, the integrals of
    its positive and negative parts, both >= 0) plus ``imbalance``: the sources less the other
    terms, and ``imbalance_ratio``: that over the energy drawn (0.005 is 0.5 %)."""
    energies = dict(integrals)
    sources = energies["battery_drawn"] - energies["battery_returned"] + energies["reservoir_power"]
    taken = sum(energies[name] for name in TERM_NAMES if name not in SOURCES)
    energies["imbalance"] = sources - taken
    drawn = energies["battery_drawn"] + abs(energies["reservoir_power"])
    energies["imbalance_ratio"] = abs(sources - taken) / drawn if drawn > 0.0 else 0.0
    return energies
