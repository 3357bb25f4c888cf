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

import numpy as np

from ...jit import compiled_as, jitable
from .. import electric_motor, pump, valve
from ..battery import J_PER_KWH
from ..geometry import annulus_area_m2, piston_area_m2
from ..hydraulics import orifice_coefficient
from ..parameters import DRIVES, Parameters

Num = Any  # float or numpy.ndarray


def in_use(flag: Num) -> bool:
    """Whether a 0/1 flag (a float, or an array of a batch's sets) is set for any set: the
    model skips the equations of a drive no set uses."""
    if isinstance(flag, float):
        return flag != 0.0
    return bool(np.any(flag != 0.0))


@compiled_as(in_use)
def _in_use_compiled(flag: Any) -> Any:
    """:func:`in_use` as compiled code runs it: a branch on the flag of the set (the
    implementation's annotations are those of this typing function, as numba asks)."""

    def of_set(flag: Any) -> Any:
        return np.any(flag != 0.0)

    return of_set


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
    command_rod_speed: Num  # rod speed at full command where the command sets a motor's speed, m/s (0: valve)
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
    # motor and inverter losses, auxiliary power
    motor_current: Num  # k_i: inverter switching, W/(N m) (eq. D6)
    motor_eddy: Num  # k_e: eddy currents, W/(rad/s)^2 (eq. D6)
    motor_windage: Num  # k_w: windage, W/(rad/s)^3 (eq. D6)
    inverter_standby: Num  # P_0: the enabled inverter's standby, W (eq. D5)
    auxiliary_power: Num  # P_aux: the machine's auxiliaries while it is on, W (eq. D5)
    # electro_mechanical (docs/model.md, "Drives", eq. D30-D36)
    ema_ratio: Num  # r = l / (2 pi N): rod travel per motor radian, m/rad (eq. D30)
    ema_friction_mean: Num  # m = (1/eta_f - eta_b) / 2 of the gearing and screw (eq. D32)
    ema_friction_skew: Num  # d = (1/eta_f + eta_b) / 2 - 1 (eq. D32)
    ema_stiffness: Num  # k_s, N/m (eq. D31)
    ema_damping: Num  # c_s, N s/m (eq. D31)
    ema_inertia: Num  # J_m, kg m^2 (eq. D33)
    ema_torque_limit: Num  # T_max, N m (eq. D34)
    ema_speed_gain: Num  # K_w = J_m w_c, N m s/rad (eq. D34)
    ema_brake_torque: Num  # T_b, N m (eq. D35)
    ema_brake_threshold: Num  # u_b: |u| below which the brake engages (eq. D35)
    ema_piston_area: Num  # S1, m^2: the chambers breathe (eq. D36)
    ema_annulus_area: Num  # S2, m^2
    # the EHA as built (docs/model.md, "The EHA as built", eq. D50-D56): each off at its default
    eha_torque_model: Num  # 1.0: the motor's speed is a state under a torque-limited speed loop; 0.0: the lag
    eha_torque_max: Num  # T_max = min(torque limit, k_t I_max), N m (eq. D50)
    eha_inertia: Num  # J of the rotors, kg m^2 (0 with the lag) (eq. D51)
    eha_inv_inertia: Num  # 1 / J (0 with the lag), 1/(kg m^2)
    eha_speed_gain: Num  # K_w, N m s/rad (eq. D50)
    eha_inv_integral_time: Num  # 1 / T_i of the speed loop (0: proportional), 1/s (eq. D52)
    eha_holding: Num  # 1.0 with the load-holding valve between pump and piston chamber, 0.0 without
    eha_holding_command: Num  # u_h: share of top speed at which it is fully open (eq. D53)
    # how the valve drives' motor runs, and the open-centre valve (docs/model.md, "Motor strategies",
    # "Open-centre valve")
    motor_strategy: Num  # index in motor_speed.STRATEGIES: 0 constant, 1 idle_stop, 2 speed_on_demand
    min_speed: Num  # w_min of speed_on_demand, rad/s (eq. D62)
    rotor_inertia: Num  # J of the motor's and pump's rotors, kg m^2 (eq. D63)
    idle_stop_s: Num  # T_idle of idle_stop, s (eq. D61)
    open_centre: Num  # 1.0 with fixed_pump's valve open-centre, 0.0 closed-centre
    k_centre: Num  # K_c of the fully open centre path, m^3/(s Pa^0.5) (eq. D65)
    centre_closed: Num  # x_c: the spool opening at which the centre path has closed (eq. D65)


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
    motor = electric_motor.loss_coefficients(
        p.motor_rated_torque_n_m, p.pump_speed_rad_s, p.motor_efficiency, p.motor_copper_loss_fraction,
        p.motor_switching_loss_fraction, p.motor_eddy_loss_fraction, p.motor_windage_loss_fraction,
        p.inverter_standby_power_w,
    )  # fmt: skip
    lag = 1.0 if p.motor_time_constant_s > 0.0 else 0.0
    inv_tau = lag / p.motor_time_constant_s if lag else 0.0  # here: numba compiles no keyword argument that branches
    holding = 1.0 if p.load_holding_valve == "piston_side" else 0.0
    k_valve = orifice_coefficient(p.discharge_coefficient, piston_area_m2(p.orifice_diameter_m), p.density_kg_m3)
    # the EHA as built: the torque-limited speed loop is on with a torque limit (eq. D50)
    torque_model = 1.0 if p.eha_torque_limit_n_m > 0.0 else 0.0
    eha_integral = 1.0 if torque_model * p.eha_speed_integral_time_s > 0.0 else 0.0
    eha_inv_integral_time = eha_integral / p.eha_speed_integral_time_s if eha_integral else 0.0
    eha_holding = 1.0 if p.eha_holding_valve == "piston_side" else 0.0
    # the drives without the 4/3 valve set the motor's speed by the command, and so the rod's speed
    # at full command (control.full_opening_rate, the feedforward's plant model; 0: the valve's law)
    command_rod_speed = 0.0
    if p.drive == "pump_controlled":
        command_rod_speed = p.pump_max_flow_m3_s / piston_area_m2(p.piston_diameter_m)  # D w_max / S1 (eq. D20)
    if p.drive == "electro_mechanical":
        command_rod_speed = p.ema_screw_lead_m / (2.0 * math.pi * p.ema_gear_ratio) * p.pump_speed_rad_s  # eq. D30
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
        command_rod_speed=command_rod_speed,
        max_flow=p.pump_max_flow_m3_s,
        speed=p.pump_speed_rad_s,
        displacement=p.pump_max_flow_m3_s / p.pump_speed_rad_s,
        pump_leak=pump.leakage_conductance(
            p.pump_volumetric_efficiency, p.pump_max_flow_m3_s, p.supply_pressure_pa - p.tank_pressure_pa
        ),
        torque_loss=pump.torque_loss_ratio(p.pump_hydromechanical_efficiency),
        motor_copper=motor.copper,
        motor_iron=motor.iron,
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
        # motor and inverter losses, auxiliary power
        motor_current=motor.current,
        motor_eddy=motor.eddy,
        motor_windage=motor.windage,
        inverter_standby=motor.standby,
        auxiliary_power=p.auxiliary_power_w,
        # electro_mechanical (eq. D30-D36)
        ema_ratio=p.ema_screw_lead_m / (2.0 * math.pi * p.ema_gear_ratio),
        ema_friction_mean=0.5 * (1.0 / p.ema_forward_efficiency - p.ema_backdrive_efficiency),
        ema_friction_skew=0.5 * (1.0 / p.ema_forward_efficiency + p.ema_backdrive_efficiency) - 1.0,
        ema_stiffness=p.ema_screw_stiffness_n_m,
        ema_damping=p.ema_screw_damping_n_s_m,
        ema_inertia=p.ema_inertia_kg_m2,
        ema_torque_limit=p.ema_torque_limit_n_m,
        ema_speed_gain=p.ema_inertia_kg_m2 * p.ema_speed_bandwidth_rad_s,
        ema_brake_torque=p.ema_brake_torque_n_m,
        ema_brake_threshold=p.ema_brake_threshold,
        ema_piston_area=piston_area_m2(p.piston_diameter_m),
        ema_annulus_area=annulus_area_m2(p.piston_diameter_m, p.rod_diameter_m),
        eha_torque_model=torque_model,
        eha_torque_max=torque_model * min(p.eha_torque_limit_n_m, p.eha_torque_constant_n_m_a * p.eha_current_limit_a),
        eha_inertia=torque_model * p.eha_motor_inertia_kg_m2,
        eha_inv_inertia=torque_model / p.eha_motor_inertia_kg_m2,
        eha_speed_gain=p.eha_speed_gain_n_m_s_rad,
        eha_inv_integral_time=eha_inv_integral_time,
        eha_holding=eha_holding,
        eha_holding_command=p.eha_holding_command,
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


def chosen(a: Supply, b: Supply, w: Num) -> Supply:
    """The set's drive ``b`` where its flag ``w`` is 1: for one set (a float flag, 1 wherever a
    drive's equations run) ``b`` itself, without :func:`blend`'s arithmetic; for a batch, the blend."""
    return b if isinstance(w, float) else blend(a, b, w)


@compiled_as(chosen)
def _chosen_compiled(a: Any, b: Any, w: Any) -> Any:
    """:func:`chosen` as compiled code runs it: one set's float flag picks ``b`` (the implementation's
    annotations are those of this typing function, as numba asks)."""
    import numba

    if isinstance(w, numba.types.Float):

        def of_set(a: Any, b: Any, w: Any) -> Any:
            return b

        return of_set

    def of_batch(a: Any, b: Any, w: Any) -> Any:
        return blend(a, b, w)

    return of_batch


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
