"""Every parameter of the boom drive, with unit, description, range and validation.

The defaults are the paper's printed values where the paper gives one (its symbol is named
in the description) and realistic components for what only the physical mode adds. The
shipped ``config/default.yaml`` spells out the same values; a test keeps the two equal.

Each parameter belongs to one group, by what it configures (:data:`GROUPS`): the plant
(the crane and its hydraulics, and which model of them), the solver (how the equations
are integrated), the controller (the position loop's gains) and the scenario (the valve
command of a headless run: boom-sim and boom-sweep; the node takes its commands from
topics). The group is in each field's metadata; :func:`group_of` and :func:`names_in`
tell them. The names stay flat, as the ROS parameters and the params files spell them.

One :class:`Parameters` instance is immutable and always valid: :func:`from_mapping` and
:func:`with_updates` build a new one or raise :class:`ConfigError`, so an error never
leaves a set half-applied.
"""

from __future__ import annotations

import dataclasses
import difflib
import itertools
import math
from collections.abc import Collection, Mapping
from dataclasses import dataclass, field
from typing import Any

from ..errors import ConfigError
from ..jit import jitable
from .geometry import outside_stroke, triangle_bounds_m
from .hoses import NODE_SEGMENTS, SEGMENTS

MODES = ("physical", "paper")
#: The integration methods, by name, with what each is. The solver's registry
#: (solve.integrators.METHODS) implements exactly these, in this order; a test keeps them equal.
METHOD_NAMES: dict[str, str] = {
    "euler": "explicit Euler, first order",
    "rk4": "classic Runge-Kutta, fourth order (the paper's)",
    "rk45": "Dormand-Prince 5(4), adaptive with error control",
    "ros2": "Rosenbrock ROS2, second order, L-stable (stiff settings)",
}
METHODS = tuple(METHOD_NAMES)
#: The drives that feed the cylinder, by name, with what each is (docs/model.md, "Drives").
#: model.drives.DRIVES implements exactly these, in this order; a test keeps them equal.
DRIVE_NAMES: dict[str, str] = {
    "pressure_compensated": "a variable pump that holds the supply pressure and delivers on demand (the reference)",
    "fixed_pump": "a fixed pump at constant speed into a supply line with a main relief at p_n (the paper's Fig. 6)",
    "load_sensing": "a variable pump at the fed port's pressure plus a margin, with its own lag",
    "pump_controlled": "a variable-speed motor and a bidirectional pump on the two chambers (EHA), regenerating",
    "electro_mechanical": "a variable-speed motor, a gearing and a ball screw in place of the oil (EMA), with a "
    "holding brake, regenerating",
}
DRIVES = tuple(DRIVE_NAMES)
#: The drives with a supply line (an oil volume between pump and valve, a node of its own) that
#: an accumulator can sit on (accumulator_position: supply); model.drives checks their SUPPLY_NODE.
SUPPLY_LINE_DRIVES = ("fixed_pump",)
#: The drives the solvers run. The others are model elements (model/drives/) that the run
#: kernels do not call yet: a run that asks for one is refused.
COMMAND_PROFILES = ("constant", "steps", "ramp", "sine", "angle")

#: Clearance the stroke ends keep from the degenerate triangle (q1 = b - a or a + b), m.
#: End stops are spring-dampers; the rod may press a little into them.
GEOMETRY_CLEARANCE_M = 0.005


#: What a parameter configures: the plant (crane, cylinder, oil, valve, supply; the model of
#: them), the solver (integration), the controller (position loop) and the scenario (the
#: headless run's valve command, ``command_*``).
GROUPS = ("plant", "solver", "controller", "scenario")


def _param(
    group: str,
    default: Any,
    unit: str,
    description: str,
    *,
    low: float | None = None,
    high: float | None = None,
    low_inclusive: bool = False,
    choices: tuple[str, ...] | None = None,
    start_only: bool = False,
    solved: bool = True,
) -> Any:
    """A dataclass field that carries its group, unit, description and allowed range.

    ``start_only``: a running node cannot change it (its descriptor is read_only).
    ``solved``: the solvers read it; False for the drives' parameters, which only the drive
    elements read until the run kernels call them (see :data:`UNSOLVED`)."""
    meta = {
        "group": group,
        "unit": unit,
        "description": description,
        "low": low,
        "high": high,
        "low_inclusive": low_inclusive,
        "choices": choices,
        "start_only": start_only,
        "solved": solved,
    }
    if isinstance(default, list):
        return field(default_factory=lambda: list(default), metadata=meta)
    return field(default=default, metadata=meta)


def _plant(default: Any, unit: str, description: str, **limits: Any) -> Any:
    return _param("plant", default, unit, description, **limits)


def _drive(default: Any, unit: str, description: str, **limits: Any) -> Any:
    """A plant parameter of the drives, their electric supply or the battery that the solvers
    read (docs/model.md, "Drives")."""
    return _param("plant", default, unit, description, **limits)


def _solver(default: Any, unit: str, description: str, **limits: Any) -> Any:
    return _param("solver", default, unit, description, **limits)


def _controller(default: Any, unit: str, description: str, **limits: Any) -> Any:
    return _param("controller", default, unit, description, **limits)


def _scenario(default: Any, unit: str, description: str, **limits: Any) -> Any:
    return _param("scenario", default, unit, description, **limits)


@dataclass(frozen=True)
class Parameters:
    """The full parameter set of one simulation (SI units; pressures absolute in physical mode)."""

    # --- model selection (plant) and integration (solver) --------------------------------
    mode: str = _plant(
        "physical",
        "",
        "Model: 'physical' (corrected equations, both chambers, valve, end stops) or "
        "'paper' (the paper's Fig. 7 listing as printed)",
        choices=MODES,
    )
    method: str = _solver(
        "rk4",
        "",
        "Integrator: euler, rk4 (the paper's), rk45 (adaptive) or ros2 (implicit, for stiff settings)",
        choices=METHODS,
    )
    time_step_s: float = _solver(0.001, "s", "Output/physics step dt (paper: 0.001 s)", low=0.0, high=0.1)
    substeps: int = _solver(
        1,
        "",
        "Least integrator steps per time step; physical mode adds more where the explicit stability bound asks",
        low=1,
        low_inclusive=True,
        high=10000,
    )
    rtol: float = _solver(1e-6, "", "Relative tolerance of the adaptive rk45 method", low=0.0, high=0.1)
    atol_scale: float = _solver(
        1e-8,
        "",
        "Absolute tolerance of rk45 as a fraction of each state's scale (m, m/s, supply pressure, 1, J)",
        low=0.0,
        high=0.1,
    )

    # --- geometry (eq. 1-5) --------------------------------------------------------------
    a_m: float = _plant(0.4, "m", "a: boom pivot O to rod eye K on the boom", low=0.0, high=20.0)
    b_m: float = _plant(1.4, "m", "b: boom pivot O to cylinder base A on the column", low=0.0, high=20.0)
    boom_length_m: float = _plant(2.0, "m", "L1: boom length, pivot to load", low=0.0, high=50.0)
    support_height_m: float = _plant(
        1.307, "m", "h: boom support height (printed 1.307 m; 1.3 m under Fig. 2)", low=0.0, high=20.0
    )
    gravity_m_s2: float = _plant(9.81, "m/s^2", "g: acceleration of free fall", low=0.0, high=30.0)

    # --- masses (eq. 6, 8) ---------------------------------------------------------------
    boom_mass_kg: float = _plant(100.0, "kg", "m1: boom mass, concentrated at L1/2", low=0.0, high=1.0e5)
    payload_mass_kg: float = _plant(
        50.0, "kg", "mb: payload mass at the boom tip (L1)", low=0.0, low_inclusive=True, high=1.0e5
    )
    external_rod_force_n: float = _plant(
        0.0,
        "N",
        "F_ext: external force on the rod along the cylinder axis, positive extending (as the hydraulic force "
        "p1 S1 - p2 S2); e.g. a mechanical network pushing back on the rod (eq. 11)",
        low=-1.0e7,
        low_inclusive=True,
        high=1.0e7,
    )

    # --- elastic boom (docs/model.md, "Elastic boom") --------------------------------------
    boom_bending_stiffness_n_m2: float = _plant(
        0.0,
        "N m^2",
        "EI: the boom's bending stiffness in the lifting plane, for its first bending mode (a cantilever from the "
        "hinge with the payload at the tip); 0: a rigid boom (off). Steel E = 210 GPa (Roark's Formulas for Stress "
        "and Strain, table of elastic constants) times the section's I, for a box (B H^3 - (B - 2t)(H - 2t)^3) / 12",
        low=0.0,
        low_inclusive=True,
        high=1.0e12,
    )
    boom_damping_ratio: float = _plant(
        0.02,
        "",
        "zeta: structural damping ratio of the boom's bending mode (with boom_bending_stiffness_n_m2 > 0): welded "
        "steel at working stress 2-3 % (Newmark and Hall, in Chopra, Dynamics of Structures, Table 11.2.1)",
        low=0.0,
        low_inclusive=True,
        high=1.0,
    )

    # --- cylinder ------------------------------------------------------------------------
    piston_diameter_m: float = _plant(0.04, "m", "D: piston diameter (S1 = pi D^2 / 4)", low=0.0, high=1.0)
    rod_diameter_m: float = _plant(
        0.022, "m", "d: rod diameter (S2 = pi (D^2 - d^2) / 4); physical mode", low=0.0, high=1.0
    )
    cylinder_min_length_m: float = _plant(
        1.05, "m", "Retracted cylinder length (lower end stop), eye to eye; physical mode", low=0.0, high=40.0
    )
    cylinder_max_length_m: float = _plant(
        1.75, "m", "Extended cylinder length (upper end stop), eye to eye; physical mode", low=0.0, high=40.0
    )
    initial_length_m: float = _plant(1.37, "m", "q1(0): initial cylinder length", low=0.0, high=40.0)
    initial_velocity_m_s: float = _plant(
        0.0, "m/s", "dq1/dt(0): initial rod velocity", low=-10.0, low_inclusive=True, high=10.0
    )
    piston_dead_volume_m3: float = _plant(
        1.0e-4,
        "m^3",
        "V1: piston-side volume at full retraction incl. hoses (physical); "
        "the constant V1 of eq. 12 in paper mode (paper: 0.00002)",
        low=0.0,
        high=0.1,
    )
    rod_dead_volume_m3: float = _plant(
        1.0e-4, "m^3", "V2: rod-side volume at full extension incl. hoses; physical mode", low=0.0, high=0.1
    )

    # --- friction and spring (eq. 11) ----------------------------------------------------
    coulomb_friction_n: float = _plant(
        100.0, "N", "F_mp: Coulomb (semi-dry) friction of piston and rod", low=0.0, low_inclusive=True, high=1.0e6
    )
    static_friction_n: float = _plant(
        150.0, "N", "Breakaway (stiction) friction; physical mode", low=0.0, low_inclusive=True, high=1.0e6
    )
    stribeck_velocity_m_s: float = _plant(
        0.01, "m/s", "Velocity scale of the fall from stiction to Coulomb friction", low=0.0, high=10.0
    )
    friction_presliding_m: float = _plant(
        3.0e-4,
        "m",
        "Presliding displacement of the seals at breakaway: below the breakaway force the rod deflects "
        "by about this, then slides (LuGre bristle stiffness = static_friction_n / this); physical mode",
        low=0.0,
        high=0.1,
    )
    friction_presliding_damping_n_s_m: float = _plant(
        2.0e4,
        "N s/m",
        "Damping of the seals' presliding (LuGre sigma1): acts near rest only, fading above the Stribeck velocity; "
        "physical mode",
        low=0.0,
        low_inclusive=True,
        high=1.0e9,
    )
    viscous_friction_n_s_m: float = _plant(
        1000.0, "N s/m", "b_d: viscous friction coefficient", low=0.0, low_inclusive=True, high=1.0e8
    )
    spring_stiffness_n_m: float = _plant(
        0.0, "N/m", "c: spring stiffness (paper: 2000, on q1 itself)", low=0.0, low_inclusive=True, high=1.0e9
    )
    spring_free_length_m: float = _plant(
        1.4, "m", "Spring free length; physical mode (paper mode uses c * q1)", low=0.0, low_inclusive=True, high=40.0
    )

    # --- end stops (physical mode) -------------------------------------------------------
    end_stop_stiffness_n_m: float = _plant(
        1.0e8, "N/m", "End-stop contact stiffness (cushion, stop and mounts)", low=0.0, high=1.0e13
    )
    end_stop_damping_n_s_m2: float = _plant(
        1.0e9,
        "N s/m^2",
        "End-stop Hunt-Crossley damping lambda: F = k d + lambda d d' (grows with the penetration d, so the "
        "contact force starts from zero); restitution about 1 - 2/3 (lambda / k) v at impact speed v",
        low=0.0,
        low_inclusive=True,
        high=1.0e15,
    )

    # --- fluid ---------------------------------------------------------------------------
    density_kg_m3: float = _plant(860.0, "kg/m^3", "rho: oil density", low=0.0, high=5000.0)
    bulk_modulus_pa: float = _plant(
        1.0e9,
        "Pa",
        "E: effective bulk modulus of oil, hoses and air (paper prints 1.45 MPa / 14.5 MPa)",
        low=0.0,
        high=1.0e11,
    )
    cavitation_pressure_pa: float = _plant(
        5.0e3,
        "Pa",
        "Cavitation floor of chamber pressures (absolute); physical mode",
        low=0.0,
        low_inclusive=True,
        high=1.0e6,
    )

    # --- valve (eq. 14, 15, 17) ----------------------------------------------------------
    orifice_diameter_m: float = _plant(
        0.002, "m", "D_dr: throttle diameter at full opening, per flow path (eq. 17)", low=0.0, high=0.1
    )
    discharge_coefficient: float = _plant(0.62, "", "mu: orifice discharge coefficient", low=0.0, high=1.0)
    transition_pressure_pa: float = _plant(
        3.0e5,
        "Pa",
        "Pressure drop below which orifice flow turns laminar (finite dQ/dp); physical mode",
        low=0.0,
        high=1.0e7,
    )
    valve_leakage_m3_s_pa: float = _plant(
        1.0e-13,
        "m^3/(s Pa)",
        "Laminar leakage conductance of each closed valve path; physical mode",
        low=0.0,
        low_inclusive=True,
        high=1.0e-8,
    )
    spool_time_constant_s: float = _plant(
        0.02, "s", "First-order spool lag (0: none); physical mode", low=0.0, low_inclusive=True, high=10.0
    )
    load_holding_valve: str = _plant(
        "piston_side",
        "",
        "Load-holding valve: 'piston_side' (a pilot-operated check valve in the piston-chamber line, "
        "opened by the lowering command; the closed valve holds the boom) or 'none' (the spool alone holds it, "
        "and its leakage lets the boom creep down)",
        choices=("piston_side", "none"),
    )
    load_holding_leakage_m3_s_pa: float = _plant(
        2.0e-16,
        "m^3/(s Pa)",
        "Seat leakage of the closed load-holding valve (2e-16: about 5 drops/min at 20 MPa); physical mode",
        low=0.0,
        low_inclusive=True,
        high=1.0e-8,
    )

    # --- supply ---------------------------------------------------------------------------
    supply_pressure_pa: float = _plant(16.0e6, "Pa", "p_n: supply (pump) pressure", low=0.0, high=1.0e8)
    tank_pressure_pa: float = _plant(
        1.0e5, "Pa", "p_37: tank/drain pressure (absolute); physical mode", low=0.0, low_inclusive=True, high=1.0e7
    )
    ambient_pressure_pa: float = _plant(
        1.01325e5,
        "Pa",
        "Ambient (atmospheric) pressure on the rod's end: it pushes the rod in with p_amb (S1 - S2); physical mode",
        low=0.0,
        low_inclusive=True,
        high=1.0e7,
    )
    pump_max_flow_m3_s: float = _plant(
        5.0e-4, "m^3/s", "Maximum pump flow; above it the supply pressure drops", low=0.0, high=0.1
    )
    relief_pressure_pa: float = _plant(
        18.0e6, "Pa", "Cracking pressure of the port relief valves on both chambers", low=0.0, high=1.0e8
    )
    relief_range_pa: float = _plant(
        3.0e6, "Pa", "Pressure rise over which a relief valve opens fully", low=0.0, high=1.0e8
    )
    relief_rated_flow_m3_s: float = _plant(5.0e-4, "m^3/s", "Flow of a fully open relief valve", low=0.0, high=0.1)

    # --- drives, pump, electric motor and battery (docs/model.md, "Drives"; eq. D1-D25) ----
    drive: str = _drive(
        "pressure_compensated",
        "",
        "Drive that feeds the cylinder: pressure_compensated (the reference), fixed_pump (the paper's "
        "circuit, main relief at supply_pressure_pa), load_sensing, pump_controlled (EHA) or electro_mechanical "
        "(EMA: motor, gearing and ball screw); physical mode",
        choices=DRIVES,
        start_only=True,
    )
    pump_speed_rad_s: float = _drive(
        157.08,
        "rad/s",
        "Pump shaft speed of the constant-speed drives (157.08: 1500 rpm), and the top speed (command +-1) "
        "of pump_controlled; the pump's displacement is pump_max_flow_m3_s / this (eq. D4)",
        low=0.0,
        high=1000.0,
    )
    pump_volumetric_efficiency: float = _drive(
        0.95,
        "",
        "Pump's delivered over geometric flow at supply_pressure_pa and pump_speed_rad_s: sets its leakage (eq. D1)",
        low=0.0,
        high=1.0,
    )
    pump_hydromechanical_efficiency: float = _drive(
        0.9,
        "",
        "Pump's hydraulic over shaft torque when pumping (as a motor, lowering: 2 - 1/this) (eq. D2)",
        low=0.5,
        high=1.0,
    )
    motor_rated_torque_n_m: float = _drive(
        60.0, "N m", "Electric motor's rated torque, at which motor_efficiency holds (eq. D6)", low=0.0, high=1.0e5
    )
    motor_efficiency: float = _drive(
        0.9,
        "",
        "Motor and inverter: shaft over electrical power at rated torque and pump_speed_rad_s when motoring "
        "(generating: 2 - 1/this) (eq. D6)",
        low=0.5,
        high=1.0,
    )
    motor_copper_loss_fraction: float = _drive(
        0.6,
        "",
        "Share of the motor's and inverter's rated loss that grows with the torque squared (copper, conduction); "
        "the rest, less the shares and standby below, grows with the speed (hysteresis, friction) (eq. D6)",
        low=0.0,
        low_inclusive=True,
        high=1.0,
    )
    # motor and inverter losses, auxiliary power (docs/model.md, "Electric motor and inverter"; eq. D5, D6):
    # further shares of the rated loss, taken from the speed share (1 - motor_copper_loss_fraction); 0: off
    motor_switching_loss_fraction: float = _drive(
        0.0,
        "",
        "Share of the rated loss that grows with |torque|, as the current: the inverter's switching and its "
        "devices' threshold voltage (MOSFET/IGBT datasheet E_on + E_off per ampere; docs/model.md) (eq. D6)",
        low=0.0,
        low_inclusive=True,
        high=1.0,
    )
    motor_eddy_loss_fraction: float = _drive(
        0.0,
        "",
        "Share of the rated loss that grows with the speed squared: eddy currents in the laminations "
        "(Steinmetz/Bertotti iron loss, Pyrhonen et al., Design of Rotating Electrical Machines) (eq. D6)",
        low=0.0,
        low_inclusive=True,
        high=1.0,
    )
    motor_windage_loss_fraction: float = _drive(
        0.0,
        "",
        "Share of the rated loss that grows with the speed cubed: windage (and fan) (Larminie and Lowry, "
        "Electric Vehicle Technology Explained, loss model k_c T^2 + k_i w + k_w w^3 + C) (eq. D6)",
        low=0.0,
        low_inclusive=True,
        high=1.0,
    )
    inverter_standby_power_w: float = _drive(
        0.0,
        "W",
        "The enabled inverter's constant draw (gate drivers, logic, current sensors), part of the rated loss of "
        "motor_efficiency; booked as standby_loss (eq. D5, D6)",
        low=0.0,
        low_inclusive=True,
        high=1.0e5,
    )
    auxiliary_power_w: float = _drive(
        0.0,
        "W",
        "The machine's auxiliaries drawn from the battery while it is on, whatever the drive and load: "
        "controller, cooling fan, display, contactor coils (typical: tens of watts, docs/model.md); booked "
        "as standby_loss (eq. D5)",
        low=0.0,
        low_inclusive=True,
        high=1.0e5,
    )
    motor_time_constant_s: float = _drive(
        0.05,
        "s",
        "First-order lag of the pump_controlled motor's speed behind its command (0: none) (eq. D21)",
        low=0.0,
        low_inclusive=True,
        high=10.0,
    )
    battery_capacity_kwh: float = _drive(
        5.0, "kWh", "Battery's usable energy between full and empty (eq. D10)", low=0.0, high=1.0e4
    )
    battery_voltage_v: float = _drive(
        48.0, "V", "Battery's nominal (open-circuit) voltage (eq. D8)", low=0.0, high=2000.0
    )
    battery_resistance_ohm: float = _drive(
        0.01, "ohm", "Battery's internal resistance, cables included (eq. D8)", low=0.0, low_inclusive=True, high=100.0
    )
    battery_initial_soc: float = _drive(
        1.0, "", "Battery's state of charge at the start, 1 full (eq. D10)", low=0.0, low_inclusive=True, high=1.0
    )
    supply_line_volume_m3: float = _drive(
        2.0e-4, "m^3", "fixed_pump: oil volume between pump and valve, hoses included (eq. D13)", low=0.0, high=0.1
    )
    main_relief_range_pa: float = _drive(
        1.0e6,
        "Pa",
        "fixed_pump: pressure rise over supply_pressure_pa at which the main relief passes pump_max_flow_m3_s "
        "(eq. D12)",
        low=0.0,
        high=1.0e8,
    )
    load_sensing_margin_pa: float = _drive(
        2.0e6,
        "Pa",
        "load_sensing: pump pressure above the fed port's pressure (typically 1.5-2.5 MPa) (eq. D17)",
        low=0.0,
        high=1.0e7,
    )
    load_sensing_time_constant_s: float = _drive(
        0.05,
        "s",
        "load_sensing: first-order lag of the pump's pressure behind its target (eq. D18)",
        low=0.0,
        high=10.0,
    )
    reservoir_pressure_pa: float = _drive(
        5.0e5,
        "Pa",
        "pump_controlled: pressure of the low-pressure reservoir (accumulator) the checks connect to, absolute "
        "(eq. D23)",
        low=0.0,
        high=1.0e7,
    )
    pilot_check_diameter_m: float = _drive(
        0.006, "m", "pump_controlled: flow diameter of each pilot-operated check valve (eq. D23)", low=0.0, high=0.1
    )
    pilot_check_opening_pa: float = _drive(
        1.0e6,
        "Pa",
        "pump_controlled: pressure of the other line above the reservoir's at which a pilot-operated check is "
        "fully open (eq. D22)",
        low=0.0,
        high=1.0e8,
    )
    # --- electro-mechanical actuator (electro_mechanical; docs/model.md, "Drives", eq. D30-D36)
    ema_screw_lead_m: float = _drive(
        0.032,
        "m",
        "electro_mechanical: the ball screw's lead, rod travel per screw turn (a 32x32 ball screw: SKF/Ewellix "
        "and THK catalogues list 32 mm leads on 32 mm shafts) (eq. D30)",
        low=0.0,
        high=1.0,
    )
    ema_gear_ratio: float = _drive(
        2.0,
        "",
        "electro_mechanical: motor turns per screw turn of the gearing (a 2:1 toothed belt); with the lead it "
        "gives the valve drives' top rod speed, pump_max_flow_m3_s over the piston area, at pump_speed_rad_s "
        "(eq. D30)",
        low=0.0,
        high=1000.0,
    )
    ema_forward_efficiency: float = _drive(
        0.87,
        "",
        "electro_mechanical: gearing and screw together when the motor drives the load: a ball screw's 0.9 "
        "(THK, SKF catalogues: eta = tan(lead angle) / tan(lead angle + friction angle)) times a toothed "
        "belt's 0.97 (eq. D32)",
        low=0.0,
        high=1.0,
    )
    ema_backdrive_efficiency: float = _drive(
        0.78,
        "",
        "electro_mechanical: gearing and screw together when the load drives the motor (lowering): a ball "
        "screw's 0.8 (THK, SKF: tan(lead angle - friction angle) / tan(lead angle)) times the belt's 0.97; "
        "<= 0: a self-locking (trapezoidal) screw the load cannot drive (eq. D32)",
        low=-1.0,
        high=1.0,
    )
    ema_screw_stiffness_n_m: float = _drive(
        1.0e8,
        "N/m",
        "electro_mechanical: axial stiffness from the nut to the rod: a 32 mm screw shaft E A / L over 0.7 m "
        "(1.7e8), nut and thrust bearing (about 1e9 each, SKF/THK catalogues) and mounts in series (eq. D31)",
        low=0.0,
        high=1.0e11,
    )
    ema_screw_damping_n_s_m: float = _drive(
        3.0e4,
        "N s/m",
        "electro_mechanical: damping of that compliance: a structural damping ratio of about 0.05 (steel "
        "assemblies, 0.02-0.05) of the nut's mode on the motor's reflected inertia (eq. D31)",
        low=0.0,
        low_inclusive=True,
        high=1.0e8,
    )
    ema_inertia_kg_m2: float = _drive(
        5.0e-3,
        "kg m^2",
        "electro_mechanical: the motor's rotor with the gearing and the screw reflected to it (a 48 V PMSM of "
        "the 60 N m class, a few 1e-3 kg m^2; the screw's 6e-4 over the ratio squared) (eq. D33)",
        low=0.0,
        high=10.0,
    )
    ema_torque_limit_n_m: float = _drive(
        60.0,
        "N m",
        "electro_mechanical: the inverter's torque (current) limit of the speed controller; against an end stop "
        "the motor stalls at it (eq. D34)",
        low=0.0,
        high=1.0e5,
    )
    ema_speed_bandwidth_rad_s: float = _drive(
        1000.0,
        "rad/s",
        "electro_mechanical: the speed controller's gain over the motor's inertia, K_w = J_m times this (a servo "
        "inverter's speed loop of some 160 Hz on the rotor alone; the gain makes the speed droop under the "
        "holding torque about 2 % of pump_speed_rad_s) (eq. D34)",
        low=0.0,
        high=1.0e5,
    )
    ema_brake_torque_n_m: float = _drive(
        32.0,
        "N m",
        "electro_mechanical: holding torque of the spring-applied motor brake (a 32 N m size of the usual "
        "4-8-16-32-60 N m series); 0: no brake (eq. D35)",
        low=0.0,
        low_inclusive=True,
        high=1.0e5,
    )
    ema_brake_threshold: float = _drive(
        0.02,
        "",
        "electro_mechanical: command |u| below which the brake engages and the motor's torque fades out "
        "(fully engaged at u = 0, smoothly); the command sets the motor's speed u pump_speed_rad_s (eq. D35)",
        low=0.0,
        high=1.0,
    )

    # --- EHA as built: motor speed controller, standby, load-holding valve (docs/model.md, "The EHA as built";
    # eq. D50-D56; each off by default, so that pump_controlled's earlier answers stand) -------------------------
    eha_torque_limit_n_m: float = _drive(
        0.0,
        "N m",
        "pump_controlled: the motor controller's torque limit (0: off, the motor is the speed lag of eq. D21). "
        "On, the motor's speed is a state that a PI speed loop drives with at most min(this, "
        "eha_torque_constant_n_m_a x eha_current_limit_a) against the pump's torque and the rotors' inertia, "
        "so that the drive stalls at dp = T_max / (D (1 + c_f)) (55 N m: 15.6 MPa, below the port reliefs); at "
        "most the motor's peak torque, typically 2-3 x rated for a PMSM (eq. D50-D52)",
        low=0.0,
        low_inclusive=True,
        high=1.0e5,
    )
    eha_current_limit_a: float = _drive(
        375.0,
        "A",
        "pump_controlled: the inverter's phase current limit, rms (375: the 2-minute rating of a 36-48 V traction "
        "inverter, Curtis AC F4-A 48-375 manual, Table E-1; its 1-hour rating is 175 A) (eq. D50)",
        low=0.0,
        high=1.0e5,
    )
    eha_torque_constant_n_m_a: float = _drive(
        0.3,
        "N m/A",
        "pump_controlled: the motor's torque per phase current, rms (0.3: a 48 V PMSM whose back-EMF at "
        "pump_speed_rad_s stays within the inverter's output voltage, k_t = sqrt(3) k_e with k_e <= 0.18 V s/rad; "
        "its rated 60 N m then takes 200 A) (eq. D50)",
        low=0.0,
        high=100.0,
    )
    eha_motor_inertia_kg_m2: float = _drive(
        0.01,
        "kg m^2",
        "pump_controlled: the inertia of the motor's and pump's rotors, with the torque limit on (0.01: a 60 N m "
        "PMSM's rotor, of order 1e-2 kg m^2 in servo-motor catalogues, plus a 20 cm^3/rev pump's, of order "
        "1e-3) (eq. D51)",
        low=0.0,
        high=100.0,
    )
    eha_speed_gain_n_m_s_rad: float = _drive(
        2.0,
        "N m s/rad",
        "pump_controlled: the speed loop's proportional gain K_w, with the torque limit on (2: K_w / J = "
        "200 rad/s, a speed-loop bandwidth of about 30 Hz, below the 50-200 Hz of industrial servo drives) "
        "(eq. D50)",
        low=0.0,
        high=1.0e5,
    )
    eha_speed_integral_time_s: float = _drive(
        0.05,
        "s",
        "pump_controlled: the speed loop's integral time T_i (0: a proportional loop), with the torque limit on: "
        "the integral holds the commanded speed under load (eq. D50, D52)",
        low=0.0,
        low_inclusive=True,
        high=100.0,
    )
    eha_holding_valve: str = _drive(
        "none",
        "",
        "pump_controlled: load-holding valve between the pump and the piston chamber: 'none' (the pump and its "
        "leakage hold the boom) or 'piston_side' (a seat valve, as a pilot-operated check with an electric pilot, "
        "that the controller opens while the motor is commanded and closes at a zero command, once the motor "
        "stops, sealing the chamber; it needs a pump that leaks, pump_volumetric_efficiency < 1) (eq. D53-D55)",
        choices=("none", "piston_side"),
    )
    eha_holding_command: float = _drive(
        0.01,
        "",
        "pump_controlled, eha_holding_valve piston_side: the share of top speed commanded at which "
        "the load-holding valve is fully open; it closes towards a zero command (eq. D53)",
        low=0.0,
        high=1.0,
    )
    # motor strategies of the valve drives and the open-centre valve (docs/model.md, "Motor strategies",
    # "Open-centre valve"; eq. D60-D67)
    motor_strategy: str = _drive(
        "constant",
        "",
        "How the valve drives' motor runs: constant (at pump_speed_rad_s), idle_stop (stops after "
        "motor_idle_stop_s without valve demand, restarts on demand) or speed_on_demand (its speed follows "
        "the valves' demand: 'flow on demand', electronic load sensing); it follows its target with "
        "motor_time_constant_s; pump_controlled ignores it (eq. D60-D64)",
        choices=("constant", "idle_stop", "speed_on_demand"),  # motor_speed.STRATEGIES
        start_only=True,
    )
    motor_min_speed_rad_s: float = _drive(
        52.36,
        "rad/s",
        "speed_on_demand: lowest motor speed (52.36: 500 rpm, the order of the minimum speed at rated pressure "
        "in external gear pumps' data sheets; not read from one: check the chosen pump's) (eq. D62)",
        low=0.0,
        low_inclusive=True,
        high=1000.0,
    )
    motor_rotor_inertia_kg_m2: float = _drive(
        0.015,
        "kg m^2",
        "idle_stop, speed_on_demand: inertia of the motor's and the pump's rotors, J (0.015: the order of a "
        "10 kW, 60 N m permanent-magnet motor's rotor in servo-motor catalogues, 0.005-0.03 kg m^2; not read "
        "from one data sheet) (eq. D63)",
        low=0.0,
        low_inclusive=True,
        high=10.0,
    )
    motor_idle_stop_s: float = _drive(
        2.0,
        "s",
        "idle_stop: time without valve demand (|spool| below 2 %) after which the motor stops (issue 49's "
        "example; battery machines offer 1-10 s) (eq. D61)",
        low=0.0,
        high=3600.0,
    )
    valve_centre: str = _drive(
        "closed",
        "",
        "fixed_pump: the 4/3 valve's centre: closed (the pump's flow goes over the main relief in neutral) or "
        "open (it passes to tank through the open centre, which the spool closes as it opens); the variable "
        "pumps ignore it (eq. D65-D67)",
        choices=("closed", "open"),
        start_only=True,
    )
    open_centre_pressure_drop_pa: float = _drive(
        5.0e5,
        "Pa",
        "valve_centre open: pressure drop of the open centre in neutral at pump_max_flow_m3_s (the order of "
        "mobile open-centre valves' neutral P->T curves at rated flow, 0.3-1 MPa; not read from one) (eq. D65)",
        low=0.0,
        high=1.0e8,
    )
    open_centre_closed_opening: float = _drive(
        0.5,
        "",
        "valve_centre open: spool opening (either way) at which the open centre has closed; its area falls "
        "linearly from neutral to there (eq. D65)",
        low=0.0,
        high=1.0,
    )

    # --- gas-charged accumulator (docs/model.md, "Accumulator", eq. A1-A7) -----------------
    accumulator_gas_volume_m3: float = _plant(
        0.0,
        "m^3",
        "V0: the accumulator's size, its nitrogen volume at pre-charge (a bladder accumulator's nominal volume, "
        "Hydac SB330 / Bosch Rexroth HAB: 0.2-50 L); 0: no accumulator (eq. A1)",
        low=0.0,
        low_inclusive=True,
        high=0.1,
        start_only=True,
    )
    accumulator_precharge_pa: float = _plant(
        8.0e6,
        "Pa",
        "p0: the gas's pre-charge pressure (absolute) with the bladder empty; 0.9 of the least working "
        "pressure for storage, 0.6 of the highest for pulsation damping (Olaer/Parker, 'Correct pre-charge "
        "settings') (eq. A1)",
        low=0.0,
        high=1.0e8,
        start_only=True,
    )
    accumulator_polytropic_exponent: float = _plant(
        1.4,
        "",
        "n: the gas's polytropic exponent, 1.0 isothermal (slow cycles, minutes) to 1.4 adiabatic (nitrogen; "
        "cycles and oscillations faster than about 3 minutes, as accumulator makers size them: Rabie, 'Fluid "
        "Power Engineering', accumulators chapter) (eq. A1)",
        low=1.0,
        low_inclusive=True,
        high=1.4,
        start_only=True,
    )
    accumulator_orifice_diameter_m: float = _plant(
        0.006,
        "m",
        "d_A: the accumulator's connecting orifice (its port's or a damping restrictor's bore), with the valve's "
        "discharge_coefficient and transition_pressure_pa (eq. A3)",
        low=0.0,
        high=0.1,
    )
    accumulator_position: str = _plant(
        "piston",
        "",
        "Where the accumulator sits: piston (on the piston-side line at the piston chamber, behind the "
        "load-holding valve: damping, elasticity while holding) or supply (on the supply line of a drive that "
        "has one, fixed_pump: storage and recovery) (eq. A3)",
        choices=("piston", "supply"),
        start_only=True,
    )
    # --- hoses: lines with waves between the drive's ports and the chambers (docs/model.md, "Hoses") ---
    hose_length_m: float = _plant(
        0.0,
        "m",
        "L: length of each of the two hoses from the drive's ports (valve or EHA pump) to the chambers, one "
        "for both (they run side by side from the valve bank to the cylinder); 0: no hoses, their oil lumped in "
        "the dead volumes (today's model). Their oil (N - 1/2) A L is taken out of piston_dead_volume_m3 and "
        "rod_dead_volume_m3, which include the hoses (eq. H1-H6); physical mode; set at start (the lines' oil "
        "is their state)",
        low=0.0,
        low_inclusive=True,
        high=100.0,
        start_only=True,
    )
    hose_inner_diameter_m: float = _plant(
        0.0095,
        "m",
        "d: inner diameter of the hoses: 9.5 mm, SAE J517 100R2AT -6 (3/8 in, DN10 of ISO 1436), 3.9 m/s at "
        "the 16.6 L/min of the paper's boom lifting (Fig. 8), inside the 2-5 m/s of pressure lines; set at start",
        low=0.0,
        high=0.5,
        start_only=True,
    )
    hose_wall_modulus_pa: float = _plant(
        2.4e9,
        "Pa",
        "K_wall: the hose wall's compliance as a bulk modulus, 1 / K_eff = 1 / bulk_modulus_pa + 1 / K_wall "
        "(eq. H1): d / (2 dd/dp) with dd/dp = 2e-12 m/Pa, the pressure-diameter coefficient Simscape's "
        "Hydraulic Pipeline block takes for a hose, on the 9.5 mm bore (a steel-braided SAE 100R2 hose is "
        "stiffer than textile, Johnston et al., J. Vib. Acoust. 132 (2010) 021011)",
        low=0.0,
        high=1.0e12,
    )
    oil_viscosity_m2_s: float = _plant(
        3.2e-5,
        "m^2/s",
        "nu: the oil's kinematic viscosity, for the hoses' laminar friction R = 128 rho nu l / (pi d^4) "
        "(eq. H3): ISO VG 32 at 40 C, 32 cSt (ISO 3448)",
        low=0.0,
        high=0.1,
    )

    # --- closed-loop position control (see model/control.py) ------------------------------
    control_position_gain_1_rad: float = _controller(
        4.0, "1/rad", "Kp: valve opening per rad of boom-angle error; physical mode", low=0.0, high=1000.0
    )
    control_integral_gain_1_rad_s: float = _controller(
        2.0,
        "1/(rad s)",
        "Ki: valve opening per rad s of integrated angle error (anti-windup: it grows only within 2 degrees "
        "of the setpoint and while the valve is not saturated)",
        low=0.0,
        low_inclusive=True,
        high=1000.0,
    )
    control_deadband_rad: float = _controller(
        0.002,
        "rad",
        "With the setpoint at rest, the valve closes once the angle error is inside this and opens again "
        "beyond twice it (the load-holding valve holds the boom; no chatter)",
        low=0.0,
        low_inclusive=True,
        high=0.5,
    )
    control_max_speed_rad_s: float = _controller(
        0.3,
        "rad/s",
        "Peak boom rate of a move to a target angle (MoveBoom default, angle scenario)",
        low=0.0,
        high=10.0,
    )

    # --- valve command profile (the headless scenario) -----------------------------------
    command_profile: str = _scenario(
        "constant",
        "",
        "Valve command over time: constant, steps (hold each value from its time), "
        "ramp (linear between points), sine, or angle (closed loop: move the boom to command_angles_rad "
        "at command_times_s)",
        choices=COMMAND_PROFILES,
    )
    command_value: float = _scenario(
        1.0, "", "Opening of the constant profile, in [-1, 1]", low=-1.0, low_inclusive=True, high=1.0
    )
    command_times_s: list = _scenario(  # noqa: RUF009
        [0.0], "s", "Breakpoint times of steps/ramp (increasing)", low=0.0, low_inclusive=True, high=1.0e6
    )
    command_values: list = _scenario(  # noqa: RUF009
        [1.0], "", "Openings at command_times_s, in [-1, 1]", low=-1.0, low_inclusive=True, high=1.0
    )
    command_angles_rad: list = _scenario(  # noqa: RUF009
        [0.5236],
        "rad",
        "Angle profile: boom-angle targets at command_times_s, each reached by a move at up to control_max_speed_rad_s",
        low=-1.6,
        low_inclusive=True,
        high=1.6,
    )
    command_payload_times_s: list = _scenario(  # noqa: RUF009
        [0.0],
        "s",
        "Times at which the payload on the hook changes (increasing); physical mode for a share other than 1",
        low=0.0,
        low_inclusive=True,
        high=1.0e6,
    )
    command_payload_fractions: list = _scenario(  # noqa: RUF009
        [1.0],
        "",
        "From each of command_payload_times_s on, the share of payload_mass_kg on the hook (0: released, 1: all)",
        low=0.0,
        low_inclusive=True,
        high=1.0,
    )
    command_offset: float = _scenario(0.0, "", "Sine profile: mean opening", low=-1.0, low_inclusive=True, high=1.0)
    command_amplitude: float = _scenario(0.5, "", "Sine profile: amplitude", low=-1.0, low_inclusive=True, high=1.0)
    command_frequency_hz: float = _scenario(0.5, "Hz", "Sine profile: frequency", low=0.0, high=1000.0)

    def __post_init__(self) -> None:
        _check_fields(self)
        _check_cross_fields(self)


#: Parameter names in declaration order.
NAMES: tuple[str, ...] = tuple(f.name for f in dataclasses.fields(Parameters))
_FIELDS = {f.name: f for f in dataclasses.fields(Parameters)}
#: The parameters no solver reads yet: the drives' (model/drives/, docs/model.md "Drives").
#: Until the run kernels call the drive elements, the node does not declare them and
#: config/default.yaml does not list them; a params file or ``--set`` may give them.
UNSOLVED: tuple[str, ...] = tuple(name for name in NAMES if not _FIELDS[name].metadata["solved"])


def group_of(name: str) -> str:
    """The group (one of :data:`GROUPS`) parameter ``name`` belongs to."""
    return _FIELDS[name].metadata["group"]


def names_in(group: str) -> tuple[str, ...]:
    """The parameters of ``group`` (one of :data:`GROUPS`), in declaration order."""
    if group not in GROUPS:
        raise ValueError(f"unknown parameter group {group!r}; choose one of {', '.join(GROUPS)}")
    return tuple(name for name in NAMES if group_of(name) == group)


def describe(name: str) -> dict[str, Any]:
    """Metadata of one parameter: group, unit, description, low, high, low_inclusive, choices,
    start_only, solved, default and type."""
    f = _FIELDS[name]
    default = f.default if f.default is not dataclasses.MISSING else f.default_factory()
    return {**f.metadata, "default": default, "type": _kind(f)}


def _kind(f: dataclasses.Field) -> str:
    return {"str": "str", "int": "int", "float": "float", "list": "list"}[f.type]


def _coerce(name: str, value: Any) -> Any:
    """Return ``value`` as the parameter's type, or raise ConfigError naming what is wrong."""
    kind = _kind(_FIELDS[name])
    if kind == "str":
        if not isinstance(value, str):
            raise ConfigError(f"parameter '{name}' must be a string, got {value!r}")
        return value
    if kind == "int":
        if isinstance(value, bool) or not isinstance(value, int):
            if isinstance(value, float) and value.is_integer():
                return int(value)
            raise ConfigError(f"parameter '{name}' must be an integer, got {value!r}")
        return value
    if kind == "list":
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            value = [value]
        if not isinstance(value, (list, tuple)) or not all(
            isinstance(v, (int, float)) and not isinstance(v, bool) for v in value
        ):
            raise ConfigError(f"parameter '{name}' must be a list of numbers, got {value!r}")
        return [float(v) for v in value]
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ConfigError(f"parameter '{name}' must be {_a_number(value)}, got {value!r}")
    return float(value)


def _a_number(value: Any) -> str:
    """What a number parameter must be, said for ``value`` (text that reads as inf or nan is not finite)."""
    try:
        number = float(value) if isinstance(value, str) else 0.0
    except ValueError:
        number = 0.0
    return "a finite number" if not math.isfinite(number) else "a number"


#: What each field's check reads, once: name, choices, low, high, low_inclusive (a sweep
#: checks every field of every point: the metadata's lookups per value were most of its planning).
_CHECKS = tuple(
    (name, meta["choices"], meta["low"], meta["high"], meta["low_inclusive"])
    for name, meta in ((name, _FIELDS[name].metadata) for name in NAMES)
)


#: The check of each field by its name, and its place in NAMES.
_CHECK_OF = {check[0]: check for check in _CHECKS}
_PLACE = {name: place for place, name in enumerate(NAMES)}


def _check_fields(p: Parameters, names: Collection[str] | None = None) -> None:
    """Each field of ``p`` (of ``names`` only, if given) of its type's choices or range, finite;
    in the order of NAMES, so that the first field at fault is named whatever ``names``' order."""
    checks = _CHECKS if names is None else [_CHECK_OF[name] for name in sorted(names, key=_PLACE.__getitem__)]
    for check in checks:
        _check_field(check, getattr(p, check[0]))


def _check_field(check: tuple, value: Any) -> None:
    """``value`` (coerced) of one field among its choices or in its range, finite."""
    name, choices, low, high, low_inclusive = check
    if choices is not None:
        if value not in choices:
            raise ConfigError(f"parameter '{name}' is {value!r}; choose one of {', '.join(choices)}")
        return
    for v in value if isinstance(value, list) else (value,):
        inside = (low is None or (v >= low if low_inclusive else v > low)) and (high is None or v <= high)
        if not (inside and math.isfinite(v)):
            _refuse_value(name, v)


def check_value(name: str, value: Any) -> Any:
    """``value`` as parameter ``name``'s type, checked on its own (its type, choices, range):
    ConfigError naming what is wrong. The checks across fields need a whole set (from_mapping)."""
    _known(name)
    coerced = _coerce(name, value)
    _check_field(_CHECK_OF[name], coerced)
    return coerced


def _known(key: str) -> None:
    """ConfigError naming an unknown parameter with the closest valid names."""
    if key not in _FIELDS:
        close = difflib.get_close_matches(key, NAMES, n=3)
        hint = f"; did you mean {', '.join(close)}?" if close else ""
        raise ConfigError(f"unknown parameter '{key}'{hint} Valid parameters: {', '.join(NAMES)}")


def _refuse_value(name: str, v: float) -> None:
    """The ConfigError of a value of field ``name`` outside its range or not finite."""
    meta = _FIELDS[name].metadata
    if not math.isfinite(v):
        raise ConfigError(f"parameter '{name}' must be finite, got {v!r}")
    low, high = meta["low"], meta["high"]
    unit = f" {meta['unit']}" if meta["unit"] else ""
    if low is not None and (v < low if meta["low_inclusive"] else v <= low):
        relation = ">=" if meta["low_inclusive"] else ">"
        raise ConfigError(f"parameter '{name}' ({meta['description']}) is {v!r}{unit}; it must be {relation} {low!r}")
    raise ConfigError(f"parameter '{name}' is {v!r}{unit}; it must be <= {high!r}")


def _check_cross_fields(p: Parameters) -> None:
    _check_plant(p)
    _check_motor_losses(p)
    _check_scenario(p)


def _check_motor_losses(p: Parameters) -> None:
    """The shares of the motor's rated loss leave hysteresis and friction a share >= 0 (eq. D6)."""
    rated_loss = p.motor_rated_torque_n_m * p.pump_speed_rad_s * (1.0 / p.motor_efficiency - 1.0)
    shares = p.motor_copper_loss_fraction + p.motor_switching_loss_fraction
    shares += p.motor_eddy_loss_fraction + p.motor_windage_loss_fraction
    if shares * rated_loss + p.inverter_standby_power_w > (1.0 + 1e-12) * rated_loss:
        raise ConfigError(
            f"the motor's loss shares (motor_copper_loss_fraction, motor_switching_loss_fraction, "
            f"motor_eddy_loss_fraction, motor_windage_loss_fraction: {shares:.4g} together) and "
            f"inverter_standby_power_w ({p.inverter_standby_power_w} W of the rated loss {rated_loss:.4g} W) "
            "exceed the rated loss that motor_efficiency gives; lower them or motor_efficiency"
        )


#: Why a plant's parameters do not fit together: one line per check of :func:`plant_fault`,
#: in its order (fault k says ``PLANT_FAULTS[k - 1]``), a ``str.format`` of the set ``p`` and
#: of the lengths :func:`stroke_limits_m` gives, by the names of :data:`STROKE_LIMITS`. The
#: native FMU logs the same lines (fmu/export.py reads them).
PLANT_FAULTS = (
    "rod_diameter_m ({p.rod_diameter_m} m) must be smaller than piston_diameter_m "
    "({p.piston_diameter_m} m): the rod chamber would have no area",
    "support_height_m ({p.support_height_m} m) must be smaller than b_m ({p.b_m} m): eq. 3 takes arccos(h / b)",
    "stroke [{p.cylinder_min_length_m}, {p.cylinder_max_length_m}] m must be an "
    "increasing interval inside [{lo:.4g}, {hi:.4g}] m: the triangle of eq. 1 "
    "degenerates at q1 = |b - a| = {q_low:.4g} m and q1 = a + b = {q_high:.4g} m "
    f"(sin(phi) = 0, infinite rod force); keep {GEOMETRY_CLEARANCE_M} m clear for "
    "the end stops; set cylinder_min_length_m / cylinder_max_length_m",
    "initial_length_m ({p.initial_length_m} m) lies outside the stroke [cylinder_min_length_m, "
    "cylinder_max_length_m] = [{p.cylinder_min_length_m:.4g}, {p.cylinder_max_length_m:.4g}] m",
    "initial_length_m ({p.initial_length_m} m) lies outside the open geometry interval (|b - a|, a + b) "
    "minus its clearance = [{lo:.4g}, {hi:.4g}] m",
    "supply_pressure_pa ({p.supply_pressure_pa} Pa) must exceed tank_pressure_pa ({p.tank_pressure_pa} Pa)",
    "relief_pressure_pa ({p.relief_pressure_pa} Pa) must be at least supply_pressure_pa "
    "({p.supply_pressure_pa} Pa), or the relief valves would drain the supply",
    "cavitation_pressure_pa ({p.cavitation_pressure_pa} Pa) must be below tank_pressure_pa "
    "({p.tank_pressure_pa} Pa); both are absolute",
    "drive '{p.drive}' needs physical mode: the paper's model has its ideal source only; "
    f"set mode: physical, or drive: {DRIVES[0]}",
    "static_friction_n ({p.static_friction_n} N) must be at least coulomb_friction_n "
    "({p.coulomb_friction_n} N): breakaway friction is the larger one",
    "accumulator_position 'supply' needs a drive with a supply line (" + ", ".join(SUPPLY_LINE_DRIVES) + "); "
    "drive '{p.drive}' has none: set accumulator_position: piston or accumulator_gas_volume_m3: 0",
    "hose_length_m ({p.hose_length_m} m) needs physical mode: the paper's model has no lines; set hose_length_m: 0",
    "the hoses' oil ({p.hose_length_m} m of {p.hose_inner_diameter_m} m bore, less the half segment a chamber "
    "keeps) must be less than piston_dead_volume_m3 ({p.piston_dead_volume_m3} m^3) and rod_dead_volume_m3 "
    "({p.rod_dead_volume_m3} m^3), which include the hoses; shorten the hoses or raise the dead volumes",
)
#: The names PLANT_FAULTS gives the lengths of :func:`stroke_limits_m`, in its order.
STROKE_LIMITS = ("q_low", "q_high", "lo", "hi")


@jitable
def stroke_limits_m(a_m: float, b_m: float) -> tuple[float, float, float, float]:
    """(|b - a|, a + b, and the two less the end stops' clearance): where the triangle of eq. 1
    degenerates, and the interval a stroke must lie in, m."""
    q_low, q_high = triangle_bounds_m(a_m, b_m)
    return q_low, q_high, q_low + GEOMETRY_CLEARANCE_M, q_high - GEOMETRY_CLEARANCE_M


@jitable
def has_supply_line(drive: str) -> bool:
    """Whether drive ``drive`` has a supply line an accumulator can sit on (:data:`SUPPLY_LINE_DRIVES`)."""
    for name in SUPPLY_LINE_DRIVES:
        if drive == name:
            return True
    return False


@jitable
def plant_fault(p: Parameters) -> int:
    """0 where the plant's parameters fit together (areas, the triangle of eq. 1, the stroke,
    pressures, friction), else k: the first check that fails, in the order written, which
    ``PLANT_FAULTS[k - 1]`` words. Compiled code calls it too (the native FMU)."""
    if p.rod_diameter_m >= p.piston_diameter_m:
        return 1
    if p.support_height_m >= p.b_m:
        return 2
    _, _, lo, hi = stroke_limits_m(p.a_m, p.b_m)
    if not lo <= p.cylinder_min_length_m < p.cylinder_max_length_m <= hi:
        return 3
    physical = p.mode == "physical"
    if physical and not p.cylinder_min_length_m <= p.initial_length_m <= p.cylinder_max_length_m:
        return 4
    if not physical and not lo <= p.initial_length_m <= hi:
        return 5
    if physical and p.supply_pressure_pa <= p.tank_pressure_pa:
        return 6
    if physical and p.relief_pressure_pa < p.supply_pressure_pa:
        return 7
    if physical and p.cavitation_pressure_pa >= p.tank_pressure_pa:
        return 8
    if p.mode == "paper" and p.drive != DRIVES[0]:
        return 9
    if p.static_friction_n < p.coulomb_friction_n:
        return 10
    if p.accumulator_gas_volume_m3 > 0.0 and p.accumulator_position == "supply" and not has_supply_line(p.drive):
        return 11
    if not physical and p.hose_length_m > 0.0:
        return 12
    hose_oil = NODE_SEGMENTS / SEGMENTS * 0.25 * math.pi * p.hose_inner_diameter_m**2 * p.hose_length_m  # eq. H1
    if physical and hose_oil >= min(p.piston_dead_volume_m3, p.rod_dead_volume_m3):
        return 13
    return 0


def plant_fault_message(p: Parameters, fault: int) -> str:
    """What fault ``fault`` (of :func:`plant_fault`, not 0) of ``p`` is, in PLANT_FAULTS' words."""
    return PLANT_FAULTS[fault - 1].format(p=p, **dict(zip(STROKE_LIMITS, stroke_limits_m(p.a_m, p.b_m), strict=True)))


def _check_plant(p: Parameters) -> None:
    """The plant's parameters fit together (:func:`plant_fault`), or ConfigError saying why."""
    fault = plant_fault(p)
    if fault:
        raise ConfigError(plant_fault_message(p, fault))


def _check_scenario(p: Parameters) -> None:
    """The headless scenario's valve command fits the plant: its mode, its stroke; its payload
    schedule is one share per time, at increasing times, in physical mode."""
    changes, shares = p.command_payload_times_s, p.command_payload_fractions
    if len(changes) != len(shares):
        raise ConfigError(
            f"command_payload_times_s ({len(changes)} values) and command_payload_fractions ({len(shares)} "
            "values) must be of equal length"
        )
    if any(t1 <= t0 for t0, t1 in itertools.pairwise(changes)):
        raise ConfigError(f"command_payload_times_s must be strictly increasing, got {changes}")
    if any(share != 1.0 for share in shares) and p.mode != "physical":
        raise ConfigError("a payload that changes within the run (command_payload_fractions) needs mode: physical")
    times, values = p.command_times_s, p.command_values
    if p.command_profile == "angle":
        _check_angle_profile(p)
        return
    if p.command_profile in ("steps", "ramp"):
        if len(times) != len(values) or not times:
            raise ConfigError(
                f"command_times_s ({len(times)} values) and command_values ({len(values)} "
                "values) must be non-empty and of equal length"
            )
        if any(t1 <= t0 for t0, t1 in itertools.pairwise(times)):
            raise ConfigError(f"command_times_s must be strictly increasing, got {times}")
    low_u = 0.0 if p.mode == "paper" else -1.0
    openings = {
        "constant": [p.command_value],
        "steps": values,
        "ramp": values,
        "sine": [p.command_offset - abs(p.command_amplitude), p.command_offset + abs(p.command_amplitude)],
    }[p.command_profile]
    for u in openings:
        if not low_u <= u <= 1.0:
            raise ConfigError(
                f"valve opening {u!r} of command_profile '{p.command_profile}' is outside "
                f"[{low_u:g}, 1] ({p.mode} mode"
                + (": the paper's valve only connects pump to piston chamber)" if p.mode == "paper" else ")")
            )


def _check_angle_profile(p: Parameters) -> None:
    """The closed-loop angle scenario: physical mode, one target per time, targets within the stroke."""
    times, angles = p.command_times_s, p.command_angles_rad
    if p.mode != "physical":
        raise ConfigError("command_profile 'angle' (closed-loop control) needs mode: physical")
    if len(times) != len(angles) or not times:
        raise ConfigError(
            f"command_times_s ({len(times)} values) and command_angles_rad ({len(angles)} values) "
            "must be non-empty and of equal length"
        )
    if any(t1 <= t0 for t0, t1 in itertools.pairwise(times)):
        raise ConfigError(f"command_times_s must be strictly increasing, got {times}")
    for angle in angles:
        why = outside_stroke(p, angle, "target boom angle")
        if why is not None:
            raise ConfigError(why)


def from_mapping(values: Mapping[str, Any], base: Parameters | None = None) -> Parameters:
    """Parameters from ``base`` (defaults if None) with ``values`` applied, all validated.

    Raises :class:`ConfigError` naming an unknown key (with the closest valid names), a
    value of the wrong type or range, or an inconsistent combination.
    """
    updates: dict[str, Any] = {}
    for key, value in values.items():
        _known(key)
        updates[key] = _coerce(key, value)
    if base is None:
        return Parameters(**updates)
    return _updated(base, updates)


def _updated(base: Parameters, updates: dict[str, Any]) -> Parameters:
    """``base`` with ``updates`` (coerced): as dataclasses.replace gives it, but checking only
    the updated fields on their own (``base``'s were checked when it was made) and every check
    across fields. A sweep makes a Parameters per point: 220 us a point by replace, most of it
    checking again the fields no point changes. Its copy is its fields' dict copied into a new
    instance (0.7 us; copy.copy's reduce protocol took 2.9 us)."""
    params = object.__new__(Parameters)
    params.__dict__.update(base.__dict__, **updates)
    _check_fields(params, updates)
    _check_cross_fields(params)
    return params


def with_updates(params: Parameters, **updates: Any) -> Parameters:
    """A validated copy of ``params`` with ``updates`` applied (keyword form of from_mapping)."""
    return from_mapping(updates, base=params)


def as_dict(params: Parameters) -> dict[str, Any]:
    """All parameters as a plain dict (lists copied)."""
    return {name: (list(v) if isinstance(v := getattr(params, name), list) else v) for name in NAMES}
