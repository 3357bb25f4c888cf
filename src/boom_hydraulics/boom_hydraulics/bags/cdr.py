"""The node's per-tick messages packed straight into CDR bytes, without message objects.

A message of a fixed shape (the same frame ids and joint names every tick) has a fixed
layout: :func:`layout` turns its fields into one precompiled :class:`struct.Struct`, with
the padding that CDR's alignment asks for (each primitive aligned to its size, counted from
the end of the 4-byte encapsulation header), and a message is one ``pack`` of its values.
The bytes are those rclpy's serializer gives for the same message (tested), except that an
empty trailing sequence of float64 gets no padding after it: canonical CDR, which strict
readers (rosbags) require. Published as serialized messages and recorded as they are.
"""

from __future__ import annotations

import functools
import struct
from collections.abc import Sequence
from typing import Any

#: Little-endian plain CDR.
ENCAPSULATION = b"\x00\x01\x00\x00"
_SIZES = {"i": 4, "I": 4, "d": 8, "?": 1}

Layout = tuple[Any, ...]  # items: "i", "I", "d", "?" or ("s", length in bytes)


@functools.lru_cache(maxsize=128)
def layout(items: Layout) -> struct.Struct:
    """A struct for the CDR fields ``items`` in order, after the encapsulation header."""
    parts, offset = ["<4s"], 0
    for item in items:
        if isinstance(item, tuple):  # a string's bytes, NUL included
            parts.append(f"{item[1]}s")
            offset += item[1]
            continue
        size = _SIZES[item]
        pad = (-offset) % size
        if pad:
            parts.append(f"{pad}x")
        parts.append(item)
        offset += pad + size
    return struct.Struct("".join(parts))


def _text(value: str) -> bytes:
    return value.encode() + b"\x00"


def _header(stamp_ns: int, frame_id: bytes) -> tuple[Layout, list[Any]]:
    """std_msgs/Header: the stamp (int32 sec, uint32 nanosec) and the frame id."""
    sec, nanosec = divmod(stamp_ns, 1_000_000_000)
    return ("i", "I", "I", ("s", len(frame_id))), [sec, nanosec, len(frame_id), frame_id]


def pack(items: Layout, values: list[Any]) -> bytes:
    """The CDR bytes of ``values`` laid out as ``items``."""
    return layout(items).pack(ENCAPSULATION, *values)


def drive_state(stamp_ns: int, frame_id: str, floats: Sequence[float], flags: Sequence[bool]) -> bytes:
    """boom_hydraulics_msgs/DriveState: the header, its float64 fields and its bool flags in order."""
    items, values = _header(stamp_ns, _text(frame_id))
    return pack(items + ("d",) * len(floats) + ("?",) * len(flags), [*values, *floats, *flags])


def joint_state(
    stamp_ns: int,
    names: Sequence[str],
    position: Sequence[float],
    velocity: Sequence[float],
    effort: Sequence[float],
    frame_id: str = "",
) -> bytes:
    """sensor_msgs/JointState."""
    items, values = _header(stamp_ns, _text(frame_id))
    items += ("I",)
    values.append(len(names))
    for name in names:
        text = _text(name)
        items += ("I", ("s", len(text)))
        values += [len(text), text]
    for sequence in (position, velocity, effort):
        items += ("I",) + ("d",) * len(sequence)
        values += [len(sequence), *sequence]
    return pack(items, values)


def fluid_pressure(stamp_ns: int, frame_id: str, pressure_pa: float, variance: float = 0.0) -> bytes:
    """sensor_msgs/FluidPressure."""
    items, values = _header(stamp_ns, _text(frame_id))
    return pack((*items, "d", "d"), [*values, pressure_pa, variance])


def wrench_stamped(stamp_ns: int, frame_id: str, force: Sequence[float], torque: Sequence[float]) -> bytes:
    """geometry_msgs/WrenchStamped: force then torque, x y z each."""
    items, values = _header(stamp_ns, _text(frame_id))
    return pack(items + ("d",) * 6, [*values, *force, *torque])


def clock(stamp_ns: int) -> bytes:
    """rosgraph_msgs/Clock."""
    sec, nanosec = divmod(stamp_ns, 1_000_000_000)
    return pack(("i", "I"), [sec, nanosec])
