"""What every drive reads, derived once from the parameters, and what every drive returns.

:class:`DriveConstants` holds the pump, motor, battery and drive values (floats, or arrays
for a batch), with the few values of the valve and chambers a drive needs beside them, so
that each drive function takes one constants argument. :class:`Supply` is one drive's
supply side at one instant: the rate of its state, the pump's operating point and the
supply-side terms of the energy ledger.

Equations and conventions: docs/model.md, section "Drives".
"""

from __future__ import annotations

from typing import Any, NamedTuple

from ...jit import jitable
from .. import electric_motor, pump
from ..battery import J_PER_KWH
from ..geometry import piston_area_m2
from ..hydraulics import orifice_coefficient
from ..parameters import Parameters

Num = Any  # float or numpy.ndarray


class DriveConstants(NamedTuple):
    """Derived constants of the drives (SI; pressures absolute)."""

    p_tank: Num  # Pa
    p_cav: Num  # cavitation floor, Pa
    bulk_modulus: Num  # E, Pa
    p_set: Num  # p_n: supply pressure (pressure_compensated), main relief (fixed_pump), cap (load_sensing), Pa
    k_valve: Num  # K of a fully open valve path, m^3/(s Pa^0.5) (eq. 14, 17)
    transition2: Num  # p_tr^2 of the orifices, Pa^2
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


@jitable
def constants(p: Parameters) -> DriveConstants:
    """The drive constants of one parameter set (compiled code calls it too: the native FMU)."""
    copper, iron = electric_motor.loss_coefficients(
        p.motor_rated_torque_n_m, p.pump_speed_rad_s, p.motor_efficiency, p.motor_copper_loss_fraction
    )
    lag = 1.0 if p.motor_time_constant_s > 0.0 else 0.0
    inv_tau = lag / p.motor_time_constant_s if lag else 0.0  # here: numba compiles no keyword argument that branches
    return DriveConstants(
        p_tank=p.tank_pressure_pa,
        p_cav=p.cavitation_pressure_pa,
        bulk_modulus=p.bulk_modulus_pa,
        p_set=p.supply_pressure_pa,
        k_valve=orifice_coefficient(p.discharge_coefficient, piston_area_m2(p.orifice_diameter_m), p.density_kg_m3),
        transition2=p.transition_pressure_pa**2,
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
    )


class Supply(NamedTuple):
    """One drive's supply side at one instant (SI): the rate of its state, the pump's operating
    point (what the electric chain turns into battery power, see ledger.electric_chain) and
    the supply-side terms of the energy ledger."""

    rate: Num  # d/dt of the drive's state: Pa/s (a pressure state) or rad/s (a motor speed)
    displacement: Num  # pump displacement in use, m^3/rad
    speed: Num  # pump shaft speed, rad/s
    dp: Num  # pump pressure rise, outlet minus inlet, Pa
    q_pump: Num  # flow the pump delivers, m^3/s (eq. D1)
    main_relief_loss: Num  # W
    line_oil_work: Num  # power into the supply line's oil, W
    check_loss: Num  # throttling in the EHA's pilot-operated checks, W
    reservoir_power: Num  # power the low-pressure reservoir gives, relative to tank pressure, W
