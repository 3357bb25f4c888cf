"""DriveState messages from model outputs: the one mapping of DriveState fields to outputs."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

#: DriveState field -> model output name (simulation.OUTPUTS), in the message's order.
DRIVE_STATE_FIELDS: dict[str, str] = {
    "rod_position_m": "q1",
    "rod_velocity_m_s": "v",
    "rod_acceleration_m_s2": "a",
    "boom_angle_rad": "alpha",
    "boom_rate_rad_s": "alpha_rate",
    "piston_pressure_pa": "p1",
    "rod_pressure_pa": "p2",
    "piston_flow_m3_s": "q_in1",
    "rod_flow_m3_s": "q_in2",
    "hydraulic_force_n": "f_hyd",
    "load_force_n": "f_load",
    "valve_command": "u",
    "valve_opening": "x_v",
    "supply_power_w": "power",
    "supply_energy_j": "supply_energy",
    "valve_loss_energy_j": "valve_loss_energy",
    "at_end_stop": "at_end_stop",
    "cavitation": "cavitation",
    "relief_open": "relief_open",
}
FLAGS = ("at_end_stop", "cavitation", "relief_open")


def drive_state(out: Mapping[str, Any], stamp: Any, frame_id: str = "boom_base") -> Any:
    """A boom_hydraulics_msgs/DriveState of the outputs ``out`` (imported here: needs the messages)."""
    from boom_hydraulics_msgs.msg import DriveState

    msg = DriveState()
    msg.header.stamp = stamp
    msg.header.frame_id = frame_id
    for field, name in DRIVE_STATE_FIELDS.items():
        setattr(msg, field, bool(out[name]) if name in FLAGS else float(out[name]))
    return msg
