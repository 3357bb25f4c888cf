"""DriveState messages (rclpy) from model outputs, by the one field mapping in :mod:`..bags.encoding`."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from ..bags.encoding import DRIVE_STATE_FIELDS, FLAGS


def drive_state(out: Mapping[str, Any], stamp: Any, frame_id: str = "boom_base") -> Any:
    """A boom_hydraulics_msgs/DriveState of the outputs ``out`` (imported here: needs the messages)."""
    from boom_hydraulics_msgs.msg import DriveState

    msg = DriveState()
    msg.header.stamp = stamp
    msg.header.frame_id = frame_id
    for field, name in DRIVE_STATE_FIELDS.items():
        setattr(msg, field, bool(out[name]) if name in FLAGS else float(out[name]))
    return msg
