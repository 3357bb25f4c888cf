"""Reading the drive's signals back from a recorded bag (folder or single .mcap file)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from rosbags.highlevel import AnyReader, AnyReaderError

from .errors import BoomHydraulicsError
from .messages import DRIVE_STATE_FIELDS, FLAGS

DRIVE_STATE = "boom_hydraulics_msgs/msg/DriveState"


class BagError(BoomHydraulicsError):
    """A bag cannot be read or lacks what is asked of it."""


def check_bag_path(path: Path) -> None:
    """Raise BagError unless ``path`` is a folder or a file that starts like an MCAP file."""
    if not path.exists():
        raise BagError(f"{path}: no such bag folder or file")
    if path.is_file():
        with path.open("rb") as handle:
            if handle.read(8) != b"\x89MCAP0\r\n":
                raise BagError(f"{path}: not an MCAP file (wrong magic bytes)")


def read_drive_states(bag: str | Path) -> dict[str, np.ndarray]:
    """Every DriveState of ``bag`` as arrays (``t`` in s from the first message), by stamp order."""
    path = Path(bag)
    check_bag_path(path)
    try:
        with AnyReader([path]) as reader:
            connections = [c for c in reader.connections if c.msgtype == DRIVE_STATE]
            if not connections:
                topics = ", ".join(sorted(f"{c.topic} ({c.msgtype})" for c in reader.connections)) or "none"
                raise BagError(f"{path}: no {DRIVE_STATE} topic in this bag; topics: {topics}")
            rows = []
            for connection, _, raw in reader.messages(connections=connections):
                msg = reader.deserialize(raw, connection.msgtype)
                stamp = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
                rows.append((stamp, *(getattr(msg, field) for field in DRIVE_STATE_FIELDS)))
    except AnyReaderError as exc:
        raise BagError(f"{path}: cannot read the bag ({exc}); is it truncated or not a rosbag2/MCAP bag?") from None
    except (OSError, ValueError, KeyError) as exc:
        raise BagError(f"{path}: cannot read the bag ({exc})") from None
    if len(rows) < 2:
        raise BagError(f"{path}: only {len(rows)} DriveState message(s); nothing to analyse")
    rows.sort(key=lambda r: r[0])
    table = np.array(rows, dtype=float)
    out = {"t": table[:, 0] - table[0, 0]}
    for i, name in enumerate(DRIVE_STATE_FIELDS.values(), start=1):
        column = table[:, i]
        out[name] = column.astype(bool) if name in FLAGS else column
    return out
