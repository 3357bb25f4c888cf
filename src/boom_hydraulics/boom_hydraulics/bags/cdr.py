"""The node's per-tick messages packed straight into CDR bytes, without message objects.

A message of a fixed shape (the same frame ids and joint names every tick) has a fixed
layout: :func:`layout` turns its fields into one precompiled :class:`struct.Struct`, with
the padding that CDR's alignment asks for (each primitive aligned to its size, counted from
the end of the 4-byte encapsulation header), and a message is one ``pack`` of its values.
Each message type has a packer (``*_packer``): the struct and the constant fields bound
once, a function of the stamp and the numbers that change, which the node takes once.
The bytes are those rclpy's serializer gives for the same message (tested), except that an
empty trailing sequence of float64 gets no padding after it, and that padding is zero
(rclpy leaves whatever its buffer held): canonical CDR, which strict readers (rosbags)
require. Published as serialized messages and recorded as they are.
"""

from __future__ import annotations

import functools
import struct
from collections.abc import Callable, Sequence
from typing import Any, NamedTuple

#: Little-endian plain CDR.
ENCAPSULATION = b"\x00\x01\x00\x00"
_SIZES = {"i": 4, "I": 4, "f": 4, "d": 8, "?": 1}

Layout = tuple[Any, ...]  # items: "i", "I", "f", "d", "?" or ("s", length in bytes)


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


def _stamp(stamp_ns: int) -> tuple[int, int]:
    """builtin_interfaces/Time of ``stamp_ns``: (int32 sec, uint32 nanosec)."""
    return divmod(stamp_ns, 1_000_000_000)


def _header_items(frame_id: bytes) -> Layout:
    """std_msgs/Header: the stamp (int32 sec, uint32 nanosec) and the frame id."""
    return ("i", "I", "I", ("s", len(frame_id)))


def _strings(texts: Sequence[str]) -> tuple[Layout, list[Any]]:
    """A string[] of constant ``texts``: its fields and their values (the count, then each
    string's length, NUL included, and bytes)."""
    items: Layout = ("I",)
    values: list[Any] = [len(texts)]
    for text in map(_text, texts):
        items += ("I", ("s", len(text)))
        values += [len(text), text]
    return items, values


# Each message of a fixed shape has a packer: a function of the stamp and the numbers that
# change, with the layout and the constant fields (frame ids, names, lengths) bound once.
# The node takes its packers once; the functions below them look them up per call.

DriveStatePacker = Callable[[int, Sequence[float], Sequence[bool]], bytes]
JointStatePacker = Callable[[int, Sequence[float], Sequence[float], Sequence[float]], bytes]
ScalarPacker = Callable[[int, float], bytes]
WrenchPacker = Callable[[int, Sequence[float], Sequence[float]], bytes]


@functools.lru_cache(maxsize=64)
def drive_state_packer(frame_id: str, n_floats: int, n_flags: int) -> DriveStatePacker:
    """boom_hydraulics_msgs/DriveState: the header, ``n_floats`` float64 fields, ``n_flags`` bools."""
    frame = _text(frame_id)
    struct_pack = layout(_header_items(frame) + ("d",) * n_floats + ("?",) * n_flags).pack

    def packed(stamp_ns: int, floats: Sequence[float], flags: Sequence[bool]) -> bytes:
        sec, nanosec = _stamp(stamp_ns)
        return struct_pack(ENCAPSULATION, sec, nanosec, len(frame), frame, *floats, *flags)

    return packed


@functools.lru_cache(maxsize=64)
def joint_state_packer(names: tuple[str, ...], lengths: tuple[int, int, int], frame_id: str = "") -> JointStatePacker:
    """sensor_msgs/JointState of the joints ``names``, with ``lengths`` positions, velocities, efforts."""
    frame = _text(frame_id)
    name_items, named = _strings(names)
    items = _header_items(frame) + name_items
    for n in lengths:
        items += ("I",) + ("d",) * n
    struct_pack = layout(items).pack
    n_position, n_velocity, n_effort = lengths

    def packed(stamp_ns: int, position: Sequence[float], velocity: Sequence[float], effort: Sequence[float]) -> bytes:
        sec, nanosec = _stamp(stamp_ns)
        return struct_pack(
            ENCAPSULATION,
            sec,
            nanosec,
            len(frame),
            frame,
            *named,
            n_position,
            *position,
            n_velocity,
            *velocity,
            n_effort,
            *effort,
        )

    return packed


@functools.lru_cache(maxsize=64)
def fluid_pressure_packer(frame_id: str, variance: float = 0.0) -> ScalarPacker:
    """sensor_msgs/FluidPressure in ``frame_id``: a function of the stamp and the pressure (Pa)."""
    frame = _text(frame_id)
    struct_pack = layout((*_header_items(frame), "d", "d")).pack

    def packed(stamp_ns: int, pressure_pa: float) -> bytes:
        sec, nanosec = _stamp(stamp_ns)
        return struct_pack(ENCAPSULATION, sec, nanosec, len(frame), frame, pressure_pa, variance)

    return packed


@functools.lru_cache(maxsize=64)
def wrench_stamped_packer(frame_id: str) -> WrenchPacker:
    """geometry_msgs/WrenchStamped in ``frame_id``: a function of the stamp, force and torque (x y z each)."""
    frame = _text(frame_id)
    struct_pack = layout(_header_items(frame) + ("d",) * 6).pack

    def packed(stamp_ns: int, force: Sequence[float], torque: Sequence[float]) -> bytes:
        sec, nanosec = _stamp(stamp_ns)
        return struct_pack(ENCAPSULATION, sec, nanosec, len(frame), frame, *force, *torque)

    return packed


EnergyLedgerPacker = Callable[[int, Sequence[float], Sequence[float], Sequence[float]], bytes]


@functools.lru_cache(maxsize=16)
def energy_ledger_packer(terms: tuple[str, ...], frame_id: str = "") -> EnergyLedgerPacker:
    """boom_hydraulics_msgs/EnergyLedger of the ledger's ``terms``: a function of the stamp,
    the five battery fields in the message's order (state_of_charge, battery_power_w,
    battery_drawn_j, battery_returned_j, lift_work_j), and each term's power (W) and integral
    (J) in the order of ``terms``."""
    frame = _text(frame_id)
    term_items, named = _strings(terms)
    n = len(terms)
    struct_pack = layout(
        _header_items(frame) + ("d",) * 5 + term_items + ("I",) + ("d",) * n + ("I",) + ("d",) * n
    ).pack

    def packed(stamp_ns: int, battery: Sequence[float], power_w: Sequence[float], energy_j: Sequence[float]) -> bytes:
        sec, nanosec = _stamp(stamp_ns)
        return struct_pack(ENCAPSULATION, sec, nanosec, len(frame), frame, *battery, *named, n, *power_w, n, *energy_j)

    return packed


def drive_state(stamp_ns: int, frame_id: str, floats: Sequence[float], flags: Sequence[bool]) -> bytes:
    """boom_hydraulics_msgs/DriveState: the header, its float64 fields and its bool flags in order."""
    return drive_state_packer(frame_id, len(floats), len(flags))(stamp_ns, floats, flags)


def joint_state(
    stamp_ns: int,
    names: Sequence[str],
    position: Sequence[float],
    velocity: Sequence[float],
    effort: Sequence[float],
    frame_id: str = "",
) -> bytes:
    """sensor_msgs/JointState."""
    packer = joint_state_packer(tuple(names), (len(position), len(velocity), len(effort)), frame_id)
    return packer(stamp_ns, position, velocity, effort)


def fluid_pressure(stamp_ns: int, frame_id: str, pressure_pa: float, variance: float = 0.0) -> bytes:
    """sensor_msgs/FluidPressure."""
    return fluid_pressure_packer(frame_id, variance)(stamp_ns, pressure_pa)


def wrench_stamped(stamp_ns: int, frame_id: str, force: Sequence[float], torque: Sequence[float]) -> bytes:
    """geometry_msgs/WrenchStamped: force then torque, x y z each."""
    return wrench_stamped_packer(frame_id)(stamp_ns, force, torque)


_CLOCK = layout(("i", "I"))


def clock(stamp_ns: int) -> bytes:
    """rosgraph_msgs/Clock."""
    return _CLOCK.pack(ENCAPSULATION, *_stamp(stamp_ns))


class Stamp(NamedTuple):
    """builtin_interfaces/Time as read from CDR bytes."""

    sec: int
    nanosec: int


_VALVE_COMMAND_HEAD = struct.Struct("<iII")  # header.stamp.sec, .nanosec, the length of header.frame_id
_FLOAT64 = struct.Struct("<d")


def valve_command(data: bytes) -> tuple[Stamp, float] | None:
    """The stamp and opening of a boom_hydraulics_msgs/ValveCommand received as CDR bytes
    (little-endian plain CDR, as rmw publishes it here), read without a message object; None
    for bytes in another encoding or cut short (the caller has rclpy deserialise them)."""
    if data[:4] != ENCAPSULATION or len(data) < 16:
        return None
    sec, nanosec, length = _VALVE_COMMAND_HEAD.unpack_from(data, 4)
    at = 4 + ((12 + length + 7) & ~7)  # the opening, aligned to 8 after the frame id
    if len(data) < at + 8:
        return None
    return Stamp(sec, nanosec), _FLOAT64.unpack_from(data, at)[0]


class MarkerFields(NamedTuple):
    """What one visualization_msgs/Marker carries here: an ADD of a shape (or a text) in
    place, for ever (lifetime 0), with no points, per-point colours, texture or mesh."""

    id: int
    type: int  # visualization_msgs/Marker's CUBE, SPHERE, CYLINDER, TEXT_VIEW_FACING...
    position: tuple[float, float, float]  # m
    orientation: tuple[float, float, float, float]  # quaternion x y z w
    scale: tuple[float, float, float]  # m (a text: scale z is its height)
    color: tuple[float, float, float, float]  # r g b a in 0..1 (float32 in the message)
    text: str = ""


_EMPTY = (1, b"\x00")  # an empty string: its length, NUL included, and the NUL
_ADD = 0  # visualization_msgs/Marker.ADD
# a Marker's constant fields between its color and its text, and after its text
_TO_TEXT = (0, 0, False, 0, 0, *_EMPTY, 0, 0, *_EMPTY, *_EMPTY, 0, 0)
_AFTER_TEXT = (*_EMPTY, *_EMPTY, 0, False)


@functools.lru_cache(maxsize=256)
def _marker_items(frame_length: int, ns_length: int, text_length: int) -> Layout:
    """One visualization_msgs/Marker's fields (strings' lengths in bytes, NUL included)."""
    string = ("I", ("s", 1))  # an empty one
    return (
        ("i", "I", "I", ("s", frame_length))  # header
        + ("I", ("s", ns_length), "i", "i", "i")  # ns, id, type, action
        + ("d",) * 10  # pose (position, orientation), scale
        + ("f",) * 4  # color
        + ("i", "I", "?", "I", "I")  # lifetime, frame_locked, points[], colors[]
        + string  # texture_resource
        + ("i", "I")
        + string
        + string
        + ("I",)  # texture: header, format, data[]
        + ("I",)  # uv_coordinates[]
        + ("I", ("s", text_length))  # text
        + string  # mesh_resource
        + string
        + ("I", "?")  # mesh_file: filename, data[]; mesh_use_embedded_materials
    )


@functools.lru_cache(maxsize=256)
def _marker_array_struct(frame_length: int, ns_length: int, text_lengths: tuple[int, ...]) -> struct.Struct:
    """A MarkerArray of markers with texts of ``text_lengths`` bytes (NUL included), one each."""
    items: Layout = ("I",)
    for text_length in text_lengths:
        items += _marker_items(frame_length, ns_length, text_length)
    return layout(items)


def marker_array(stamp_ns: int, frame_id: str, namespace: str, markers: Sequence[MarkerFields]) -> bytes:
    """visualization_msgs/MarkerArray of ``markers`` (action ADD), each stamped ``stamp_ns`` in
    ``frame_id`` under ``namespace``."""
    frame, ns = _text(frame_id), _text(namespace)
    head = (*_stamp(stamp_ns), len(frame), frame, len(ns), ns)
    texts = [_text(m.text) for m in markers]
    values: list[Any] = [len(markers)]
    for m, text in zip(markers, texts):
        values += head
        values += (m.id, m.type, _ADD, *m.position, *m.orientation, *m.scale, *m.color)
        values += _TO_TEXT
        values += (len(text), text)
        values += _AFTER_TEXT
    return _marker_array_struct(len(frame), len(ns), tuple(map(len, texts))).pack(ENCAPSULATION, *values)
