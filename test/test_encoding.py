"""Messages as CDR bytes without ROS (bags/encoding.py): every field of a made message at the
zero value a generated message class gives it, bytes that rosbags (strict about padding) and
rclpy read back field by field, stamps split at the second, and a parameter event of every
ParameterType carrying its value in its own field."""

from __future__ import annotations

import math

import numpy as np
import pytest

from boom_hydraulics.bags.encoding import (
    DRIVE_STATE,
    DRIVE_STATE_FIELDS,
    FLAGS,
    drive_state_cdr,
    message,
    parameter_event_cdr,
    stamp,
    to_cdr,
    typestore,
)


def _read(data: bytes, msgtype: str):
    return typestore().deserialize_cdr(data, msgtype)


def test_a_made_message_has_every_other_field_at_its_zero_value():
    info = message("sensor_msgs/msg/CameraInfo", height=480, header={"frame_id": "camera"})
    assert info.height == 480 and info.width == 0 and isinstance(info.width, int)
    assert info.distortion_model == ""
    assert info.header.frame_id == "camera" and info.header.stamp.sec == 0 and info.header.stamp.nanosec == 0
    assert info.d.dtype == np.float64 and len(info.d) == 0  # a sequence: empty
    assert info.k.dtype == np.float64 and info.k.shape == (9,) and not info.k.any()  # a fixed array: its size
    assert info.p.shape == (12,)
    assert info.roi.do_rectify is False and info.roi.x_offset == 0
    value = message("rcl_interfaces/msg/ParameterValue")
    assert value.double_value == 0.0 and isinstance(value.double_value, float)
    assert value.bool_value is False and value.integer_value == 0 and value.string_value == ""
    assert value.byte_array_value.dtype == np.uint8 and value.bool_array_value.dtype == np.bool_
    assert value.integer_array_value.dtype == np.int64 and value.string_array_value == []
    assert message("sensor_msgs/msg/JointState").name == []
    assert message("trajectory_msgs/msg/JointTrajectory").points == []  # a sequence of messages


def test_a_field_that_the_message_has_not_is_refused():
    with pytest.raises(TypeError, match="sensor_msgs/msg/JointState has no field effort_n_m, speed"):
        message("sensor_msgs/msg/JointState", speed=[1.0], effort_n_m=[2.0], name=["boom_joint"])


def test_a_made_message_reads_back_field_by_field():
    info = message(
        "sensor_msgs/msg/CameraInfo",
        header={"stamp": stamp(7 * 10**9 + 3), "frame_id": "camera"},
        width=640,
        distortion_model="plumb_bob",
        d=np.array([0.1, -0.2]),
        k=np.arange(9.0),
        roi={"do_rectify": True, "width": 5},
    )
    back = _read(to_cdr(info), "sensor_msgs/msg/CameraInfo")
    assert (back.header.stamp.sec, back.header.stamp.nanosec, back.header.frame_id) == (7, 3, "camera")
    assert back.width == 640 and back.distortion_model == "plumb_bob"
    assert back.d.tolist() == [0.1, -0.2] and back.k.tolist() == list(range(9))
    assert back.roi.do_rectify is True and back.roi.width == 5 and back.roi.height == 0


@pytest.mark.parametrize(
    ("stamp_ns", "sec", "nanosec"),
    [(0, 0, 0), (999_999_999, 0, 999_999_999), (10**9, 1, 0), (1_765_000_123 * 10**9 + 5, 1_765_000_123, 5)],
)
def test_a_stamp_splits_at_the_second(stamp_ns, sec, nanosec):
    assert stamp(stamp_ns) == {"sec": sec, "nanosec": nanosec}


def _outputs() -> dict[str, float]:
    """Each output a value no other has (a swapped field shows); flags alternate."""
    out = {name: 1000.0 + i + 0.25 for i, name in enumerate(DRIVE_STATE_FIELDS.values())}
    out.update(at_end_stop=1.0, cavitation=0.0, relief_open=1.0)
    return out


@pytest.mark.parametrize("frame_id", ["base_link", "crane_2/base", "arm"])  # (sorting after and before base_link)
def test_a_drive_state_carries_each_output_in_its_own_field(frame_id):
    out = _outputs()
    data = drive_state_cdr(out, 12 * 10**9 + 5, frame_id)
    msg = _read(data, DRIVE_STATE)
    assert (msg.header.stamp.sec, msg.header.stamp.nanosec, msg.header.frame_id) == (12, 5, frame_id)
    for field, name in DRIVE_STATE_FIELDS.items():
        expected = bool(out[name]) if name in FLAGS else out[name]
        assert getattr(msg, field) == expected, field
    # byte for byte the canonical CDR of the same message
    fields = {f: (bool(out[n]) if n in FLAGS else out[n]) for f, n in DRIVE_STATE_FIELDS.items()}
    made = message(DRIVE_STATE, header={"stamp": stamp(12 * 10**9 + 5), "frame_id": frame_id}, **fields)
    assert data == to_cdr(made)


def test_drive_state_fields_are_the_messages_and_the_flags_are_its_bools():
    definitions = dict(typestore().fielddefs[DRIVE_STATE][1])
    assert list(definitions) == ["header", *DRIVE_STATE_FIELDS]
    bools = [f for f, (node, detail) in definitions.items() if f != "header" and detail[0] == "bool"]
    assert bools == list(FLAGS)


CHANGED = [
    ("allow", 1, True),
    ("substeps", 2, -7),
    ("gain", 3, 0.125),
    ("drive", 4, "load_sensing"),
    ("blob", 5, [1, 127]),
    ("flags", 6, [True, False, True]),
    ("counts", 7, [3, -4]),
    ("times_s", 8, [0.5, 1.5]),
    ("names", 9, ["a", "bc"]),
]
#: ParameterType -> the ParameterValue field that holds it, from the messages' own definitions
#: (rcl_interfaces: PARAMETER_BOOL is bool_value, ..., PARAMETER_STRING_ARRAY string_array_value).
FIELDS = {
    value: name.removeprefix("PARAMETER_").lower() + "_value"
    for name, _, value in typestore().fielddefs["rcl_interfaces/msg/ParameterType"][0]
    if name != "PARAMETER_NOT_SET"
}
assert set(FIELDS.values()) == {f for f, _ in typestore().fielddefs["rcl_interfaces/msg/ParameterValue"][1]} - {"type"}


def test_a_parameter_event_carries_each_type_in_its_own_field_and_the_rest_empty():
    data = parameter_event_cdr("/boom_hydraulics", 3 * 10**9 + 250, CHANGED)
    event = _read(data, "rcl_interfaces/msg/ParameterEvent")
    assert (event.stamp.sec, event.stamp.nanosec, event.node) == (3, 250, "/boom_hydraulics")
    assert event.new_parameters == [] and event.deleted_parameters == []
    assert [p.name for p in event.changed_parameters] == [name for name, _, _ in CHANGED]
    empty = message("rcl_interfaces/msg/ParameterValue")
    for parameter, (_, kind, value) in zip(event.changed_parameters, CHANGED):
        assert parameter.value.type == kind
        for field in FIELDS.values():
            got = getattr(parameter.value, field)
            if field == FIELDS[kind]:
                got = got.tolist() if isinstance(got, np.ndarray) else got
                assert got == value and type(got) is type(value), (kind, field)
            else:
                zero = getattr(empty, field)
                assert (list(got) == list(zero)) if isinstance(zero, np.ndarray | list) else got == zero, (kind, field)


def test_a_parameter_event_reads_in_rclpy_as_in_rosbags():
    rclpy_serialization = pytest.importorskip("rclpy.serialization")
    from rcl_interfaces.msg import ParameterEvent

    event = rclpy_serialization.deserialize_message(
        parameter_event_cdr("/boom_hydraulics", 1, [("gain", 3, math.pi), ("times_s", 8, [0.5])]), ParameterEvent
    )
    assert event.stamp.nanosec == 1 and [p.name for p in event.changed_parameters] == ["gain", "times_s"]
    assert event.changed_parameters[0].value.double_value == math.pi
    assert list(event.changed_parameters[1].value.double_array_value) == [0.5]


def test_a_nested_message_is_taken_as_given_and_our_own_messages_default_alike():
    header = message("std_msgs/msg/Header", frame_id="camera")
    assert message("sensor_msgs/msg/CameraInfo", header=header).header is header
    ledger = message("boom_hydraulics_msgs/msg/EnergyLedger")
    assert ledger.terms == [] and len(ledger.power_w) == 0 and ledger.power_w.dtype == np.float64
    image = message("sensor_msgs/msg/Image")  # an unsigned sequence (its name sorts after "string")
    assert image.data.dtype == np.uint8 and len(image.data) == 0
