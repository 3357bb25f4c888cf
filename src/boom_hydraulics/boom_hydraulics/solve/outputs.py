"""The outputs of a simulation: every quantity the node publishes and a run records."""

#: Output names, units and descriptions, in the order of CSV columns.
OUTPUTS: tuple[tuple[str, str, str], ...] = (
    ("t", "s", "simulated time"),
    ("q1", "m", "cylinder length q1"),
    ("v", "m/s", "rod velocity"),
    ("a", "m/s^2", "rod acceleration"),
    ("alpha", "rad", "boom elevation (eq. 4)"),
    ("alpha_rate", "rad/s", "boom angular rate"),
    ("p1", "Pa", "piston-chamber pressure"),
    ("p2", "Pa", "rod-chamber pressure"),
    ("q_in1", "m^3/s", "flow into the piston chamber"),
    ("q_in2", "m^3/s", "flow into the rod chamber"),
    ("f_hyd", "N", "hydraulic rod force p1 S1 - p2 S2"),
    ("f_load", "N", "load force of eq. 10"),
    ("f_friction", "N", "seal friction force, opposing the motion"),
    ("u", "1", "valve command"),
    ("x_v", "1", "spool position applied"),
    ("p_supply", "Pa", "pressure at the valve P port"),
    ("power", "W", "hydraulic power drawn from the supply"),
    ("supply_energy", "J", "energy drawn from the supply"),
    ("valve_loss_energy", "J", "energy dissipated in the valve and relief valves"),
    ("void1", "m^3", "void (gas and vapour) volume in the piston chamber while it cavitates"),
    ("void2", "m^3", "void volume in the rod chamber while it cavitates"),
    ("at_end_stop", "bool", "rod against an end stop"),
    ("cavitation", "bool", "a chamber at the cavitation floor"),
    ("relief_open", "bool", "a relief valve passes flow"),
    ("pump_saturated", "bool", "pump at its maximum flow"),
)
OUTPUT_NAMES = tuple(name for name, _, _ in OUTPUTS)
#: Outputs that are flags (0.0 or 1.0 in a table of floats).
BOOLEAN_OUTPUTS = tuple(name for name, unit, _ in OUTPUTS if unit == "bool")
