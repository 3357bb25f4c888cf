"""What every drive reads, derived once from the parameters, and what every drive returns.

:class:`DriveConstants` holds the pump, motor, battery, valve and drive values (floats, or
arrays for a batch), with the few values of the chambers a drive needs beside them, so that
each drive function takes one constants argument; ``drive`` is the index of the set's drive
in the registry (parameters.DRIVES). :class:`Supply` is one drive at one instant: the rates
of its states, what it gives the cylinder's lines and rod, the motor's operating point and
the drive's terms of the energy ledger. The model (model/physical.py) reads nothing else of
a drive, so that a drive is one module (docs/model.md, "Drives").

Equations and conventions: docs/model.md, section "Drives".
"""

from __future__ import annotations

import math
from types import ModuleType
from typing import Any, NamedTuple

from ...jit import jitable
from .. import electric_motor, pump, valve
from ..battery import J_PER_KWH
from ..geometry import piston_area_m2
from ..hydraulics import orifice_coefficient
from ..parameters import DRIVES, Parameters

Num = Any  # float or numpy.ndarray


class DriveConstants(NamedTuple):
    """Derived constants of the drives (SI; pressures absolute)."""

    drive: Num  # the set's drive: its index in parameters.DRIVES (the registry's order)
    p_tank: Num  # Pa
    p_cav: Num  # cavitation floor, Pa
    bulk_modulus: Num  # E, Pa
    p_set: Num  # p_n: supply pressure (pressure_compensated), main relief (fixed_pump), cap (load_sensing), Pa
    k_valve: Num  # K of a fully open valve path, m^3/(s Pa^0.5) (eq. 14, 17)
    transition2: Num  # p_tr^2 of the orifices, Pa^2
    k_laminar: Num  # K / sqrt(p_tr): the steepest dQ/dp of a fully open path, m^3/(s Pa)
    leak: Num  # laminar leakage of each closed valve path, m^3/(s Pa)
    holding: Num  # 1.0 with a load-holding valve on the piston side, 0.0 without
    seat_leak: Num  # seat leakage of the closed load-holding valve, m^3/(s Pa)
    max_flow: Num  # Q_max: the pump's geometric flow at speed, m^3/s
    speed: Num  # w_n: constant pump speed; the EHA's top speed, rad/s
    displacement: Num  # D = Q_max / w_n, m^3/rad (eq. D4)
    pump_leak: Num  # G_p, m^3/(s Pa) (eq. D1)
    torque_loss: Num  # c_f (eq. D2)
    motor_copper: Num  # k_c, W/(N m)^2 (eq. D6)
    motor_iron: Num  # k_s, W/(rad/s) (eq. D6)
    motor_lag: Num  # 1.0 with a speed lag, 0.0 without
    motor_inv_tau: Num  # 1 / motor time constant (0 without lag), 1/s
    battery_voltage: Num  # U, V
    battery_resistance: Num  # R, ohm
    battery_capacity: Num  # E_usable, J
    line_volume: Num  # V_s of fixed_pump, m^3
    g_main: Num  # main relief conductance Q_max / range, m^3/(s Pa) (eq. D12)
    ls_margin: Num  # load-sensing margin, Pa
    ls_inv_tau: Num  # 1 / load-sensing pump time constant, 1/s
    p_reservoir: Num  # EHA low-pressure reservoir, Pa
    k_check: Num  # K of a pilot-operated check, m^3/(s Pa^0.5)
    pilot_full: Num  # pilot pressure above the reservoir's that opens a check fully, Pa
    # how the valve drives' motor runs, and the open-centre valve (docs/model.md, "Motor strategies",
    # "Open-centre valve")
    motor_strategy: Num  # index in motor_speed.STRATEGIES: 0 constant, 1 idle_stop, 2 speed_on_demand
    min_speed: Num  # w_min of speed_on_demand, rad/s (eq. D32)
    rotor_inertia: Num  # J of the motor's and pump's rotors, kg m^2 (eq. D33)
    idle_stop_s: Num  # T_idle of idle_stop, s (eq. D31)
    open_centre: Num  # 1.0 with fixed_pump's valve open-centre, 0.0 closed-centre
    k_centre: Num  # K_c of the fully open centre path, m^3/(s Pa^0.5) (eq. D35)
    centre_closed: Num  # x_c: the spool opening at which the centre path has closed (eq. D35)


@jitable
def drive_index(name: str) -> float:
    """The index of drive ``name`` in parameters.DRIVES (the registry's order), as a float."""
    index = 0.0
    for i in range(len(DRIVES)):
        if DRIVES[i] == name:
            index = float(i)
    return index


@jitable
def constants(p: Parameters) -> DriveConstants:
    """The drive constants of one parameter set (compiled code calls it too: the native FMU)."""
    copper, iron = electric_motor.loss_coefficients(
        p.motor_rated_torque_n_m, p.pump_speed_rad_s, p.motor_efficiency, p.motor_copper_loss_fraction
    )
    lag = 1.0 if p.motor_time_constant_s > 0.0 else 0.0
    inv_tau = lag / p.motor_time_constant_s if lag else 0.0  # here: numba compiles no keyword argument that branches
    holding = 1.0 if p.load_holding_valve == "piston_side" else 0.0
    k_valve = orifice_coefficient(p.discharge_coefficient, piston_area_m2(p.orifice_diameter_m), p.density_kg_m3)
    return DriveConstants(
        drive=drive_index(p.drive),
        p_tank=p.tank_pressure_pa,
        p_cav=p.cavitation_pressure_pa,
        bulk_modulus=p.bulk_modulus_pa,
        p_set=p.supply_pressure_pa,
        k_valve=k_valve,
        transition2=p.transition_pressure_pa**2,
        k_laminar=k_valve / math.sqrt(p.transition_pressure_pa),
        leak=p.valve_leakage_m3_s_pa,
        holding=holding,
        seat_leak=p.load_holding_leakage_m3_s_pa,
        max_flow=p.pump_max_flow_m3_s,
        speed=p.pump_speed_rad_s,
        displacement=p.pump_max_flow_m3_s / p.pump_speed_rad_s,
        pump_leak=pump.leakage_conductance(
            p.pump_volumetric_efficiency, p.pump_max_flow_m3_s, p.supply_pressure_pa - p.tank_pressure_pa
        ),
        torque_loss=pump.torque_loss_ratio(p.pump_hydromechanical_efficiency),
        motor_copper=copper,
        motor_iron=iron,
        motor_lag=lag,
        motor_inv_tau=inv_tau,
        battery_voltage=p.battery_voltage_v,
        battery_resistance=p.battery_resistance_ohm,
        battery_capacity=p.battery_capacity_kwh * J_PER_KWH,
        line_volume=p.supply_line_volume_m3,
        g_main=p.pump_max_flow_m3_s / p.main_relief_range_pa,
        ls_margin=p.load_sensing_margin_pa,
        ls_inv_tau=1.0 / p.load_sensing_time_constant_s,
        p_reservoir=p.reservoir_pressure_pa,
        k_check=orifice_coefficient(p.discharge_coefficient, piston_area_m2(p.pilot_check_diameter_m), p.density_kg_m3),
        pilot_full=p.pilot_check_opening_pa,
        motor_strategy=1.0 * (p.motor_strategy == "idle_stop") + 2.0 * (p.motor_strategy == "speed_on_demand"),
        min_speed=p.motor_min_speed_rad_s,
        rotor_inertia=p.motor_rotor_inertia_kg_m2,
        idle_stop_s=p.motor_idle_stop_s,
        open_centre=1.0 * (p.valve_centre == "open"),  # arithmetic: numba compiles no keyword argument that branches
        k_centre=valve.centre_coefficient(
            p.pump_max_flow_m3_s, p.open_centre_pressure_drop_pa, p.transition_pressure_pa
        ),
        centre_closed=p.open_centre_closed_opening,
    )


class Supply(NamedTuple):
    """One drive at one instant (SI): the rates of its states, what it gives the cylinder's
    lines and rod, the motor's operating point (what the electric chain turns into battery
    power, see ledger.electric_chain) and the drive's terms of the energy ledger. Every
    drive's ``supply`` returns one; the model reads nothing else of a drive."""

    rate: Num  # d/dt of the drive's first state (its STATE_NAMES[0]): Pa/s, rad/s, ...
    rate2: Num  # d/dt of its second state (0 for a drive with fewer)
    rate3: Num  # d/dt of its third state
    q_a: Num  # flow into the piston-chamber line, before the port relief, m^3/s (eq. 12)
    q_b: Num  # flow into the rod-chamber line, before the port relief, m^3/s (eq. 13: -Q_2)
    cylinder: Num  # 1.0: the chambers' pressures push the rod; 0.0: they do not (a drive without oil)
    force: Num  # the force the drive puts on the rod itself, extending positive, N (0: through the oil)
    spool: Num  # the valve's spool position its paths see, -1..1 (the command, without a valve)
    p_supply: Num  # the supply pressure: the valve's P port, or an EHA's higher line, Pa
    saturated: Num  # 1.0 where the pump is at its flow limit (the port below the pump's pressure)
    power: Num  # hydraulic power the drive gives the lines, above tank pressure, W
    torque: Num  # the motor's shaft torque, N m (eq. D2)
    speed: Num  # the motor's shaft speed, rad/s
    hydraulic_power: Num  # dp Q: what the pump gives the oil at its outlet, W
    volumetric_loss: Num  # pump leakage, W (eq. D3)
    mechanical_loss: Num  # pump friction torque, W (eq. D3)
    main_relief_loss: Num  # W
    valve_loss: Num  # throttling in the 4/3 valve and load-holding valve, or the EHA's checks, W
    leakage_loss: Num  # leakage of the valve's paths and the load-holding valve's seat, W
    line_oil_work: Num  # power into the supply line's oil, W
    reservoir_power: Num  # power the low-pressure reservoir gives, relative to tank pressure, W
    rotor_power: Num  # rate of the kinetic energy of the motor's and pump's rotors, W
    standby_loss: Num  # inverter, controller and auxiliary power drawn whatever the load, W


@jitable
def blend(a: Supply, b: Supply, w: Num) -> Supply:
    """The drive ``a``, or ``b`` where the flag ``w`` is 1 (a batch of sets with several drives)."""
    return Supply(
        a.rate + w * (b.rate - a.rate),
        a.rate2 + w * (b.rate2 - a.rate2),
        a.rate3 + w * (b.rate3 - a.rate3),
        a.q_a + w * (b.q_a - a.q_a),
        a.q_b + w * (b.q_b - a.q_b),
        a.cylinder + w * (b.cylinder - a.cylinder),
        a.force + w * (b.force - a.force),
        a.spool + w * (b.spool - a.spool),
        a.p_supply + w * (b.p_supply - a.p_supply),
        a.saturated + w * (b.saturated - a.saturated),
        a.power + w * (b.power - a.power),
        a.torque + w * (b.torque - a.torque),
        a.speed + w * (b.speed - a.speed),
        a.hydraulic_power + w * (b.hydraulic_power - a.hydraulic_power),
        a.volumetric_loss + w * (b.volumetric_loss - a.volumetric_loss),
        a.mechanical_loss + w * (b.mechanical_loss - a.mechanical_loss),
        a.main_relief_loss + w * (b.main_relief_loss - a.main_relief_loss),
        a.valve_loss + w * (b.valve_loss - a.valve_loss),
        a.leakage_loss + w * (b.leakage_loss - a.leakage_loss),
        a.line_oil_work + w * (b.line_oil_work - a.line_oil_work),
        a.reservoir_power + w * (b.reservoir_power - a.reservoir_power),
        a.rotor_power + w * (b.rotor_power - a.rotor_power),
        a.standby_loss + w * (b.standby_loss - a.standby_loss),
    )


class PumpPoint(NamedTuple):
    """A displacement pump at one operating point (eq. D1-D3), W and N m."""

    torque: Num  # shaft torque, N m (eq. D2)
    hydraulic_power: Num  # dp Q, W
    volumetric_loss: Num  # G_p dp^2, W (eq. D3)
    mechanical_loss: Num  # friction torque times speed, W (eq. D3)


@jitable
def pump_point(
    displacement: Num, speed: Num, dp: Num, q_pump: Num, d: DriveConstants, xp: ModuleType = math
) -> PumpPoint:
    """The pump of displacement D at speed w across dp delivering Q (eq. D1-D3)."""
    return PumpPoint(
        pump.shaft_torque_n_m(displacement, speed, dp, d.torque_loss, xp),  # eq. D2
        dp * q_pump,
        pump.volumetric_loss_w(dp, d.pump_leak),  # eq. D3
        pump.mechanical_loss_w(displacement, speed, dp, d.torque_loss, xp),  # eq. D3
    )
