"""The bag writer: what rosbag2 and independent MCAP readers expect of a bag, and what survives a kill."""

from __future__ import annotations

import shutil

import pytest
import yaml
from conftest import wait_for

pytest.importorskip("rclpy")
from bag_checks import check_bag
from mcap.reader import make_reader
from mcap.records import Message
from mcap.stream_reader import StreamReader
from rclpy.serialization import serialize_message

from boom_hydraulics.bags.recording import (
    BagRecorder,
    Topic,
    is_being_recorded,
    message_definition,
    offered_qos,
)
from boom_hydraulics_msgs.msg import DriveState, ValveCommand

STATE = Topic("/drive_state", "boom_hydraulics_msgs/msg/DriveState")
COMMAND = Topic("/valve_command", "boom_hydraulics_msgs/msg/ValveCommand", (offered_qos(reliable=False),))


def _state(ns: int) -> bytes:
    msg = DriveState()
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(ns, 10**9)
    return serialize_message(msg)


def test_log_time_never_runs_back_within_a_channel(tmp_path):
    with BagRecorder(tmp_path / "bag", [STATE, COMMAND]) as rec:
        for ns in (1_000, 2_000, 3_000):
            rec.write("/drive_state", ns, _state(ns))
        rec.write("/valve_command", 5_000, serialize_message(ValveCommand()))
        rec.write("/valve_command", 4_000, serialize_message(ValveCommand()))  # a clock stepped back
    assert check_bag(tmp_path / "bag") == {"/drive_state": 3, "/valve_command": 2}


def test_a_lone_mcap_file_keeps_the_bags_metadata(tmp_path):
    custom = {"parameters": "mode: physical\n", "clock_origin_ns": "0"}
    with BagRecorder(tmp_path / "bag", [STATE], custom_data=custom) as rec:
        rec.write("/drive_state", 10, _state(10))
    lone = tmp_path / "copied.mcap"
    shutil.copy(next((tmp_path / "bag").glob("*.mcap")), lone)
    with lone.open("rb") as handle:
        records = {m.name: m.metadata for m in make_reader(handle).iter_metadata()}
    info = yaml.safe_load(records["rosbag2"]["serialized_metadata"])  # as rosbag2_storage_mcap writes it
    assert info["ros_distro"] == "jazzy" and info["custom_data"] == custom
    assert info["topics_with_message_count"][0]["message_count"] == 1
    assert records["boom_hydraulics"] == custom


def test_schemas_are_the_msg_texts_with_comments_as_rosbag2_stores_them():
    text = message_definition("boom_hydraulics_msgs/msg/ValveCommand")
    assert text.startswith("# Command for the 4/3 proportional spool valve")
    assert "# Normalised spool opening" in text and "float64 opening" in text
    header = text.index("=" * 80 + "\nMSG: std_msgs/Header\n")
    time_part = text.index("=" * 80 + "\nMSG: builtin_interfaces/Time\n")
    assert header < time_part  # nested types after their users, each once
    assert text.count("MSG: builtin_interfaces/Time") == 1


def test_a_setpoint_paths_schema_carries_the_trajectorys_types():
    """SetpointPath nests a standard JointTrajectory: its schema in the bag carries every type
    it uses, each once, so that a reader without this workspace decodes it."""
    text = message_definition("boom_hydraulics_msgs/msg/SetpointPath")
    assert "uint8 START_SETPOINT=1" in text and "trajectory_msgs/JointTrajectory trajectory" in text
    nested = [line[len("MSG: ") :] for line in text.splitlines() if line.startswith("MSG: ")]
    assert sorted(nested) == sorted(set(nested))
    assert {
        "trajectory_msgs/JointTrajectory",
        "trajectory_msgs/JointTrajectoryPoint",
        "std_msgs/Header",
        "builtin_interfaces/Time",
        "builtin_interfaces/Duration",
    } == set(nested)


def test_chunks_reach_the_disk_at_once_and_then_within_the_flush_bound(tmp_path):
    """Events, not durations: the first message reaches the disk with an hour's flush bound
    (at once, then), and the next ones in a chunk far from full once the bound is 0.3 s."""
    rec = BagRecorder(tmp_path / "bag", [STATE], flush_s=3600.0)
    try:
        assert is_being_recorded(rec.file)
        rec.write("/drive_state", 1, _state(1))
        wait_for(lambda: _messages_on_disk(rec.file) == 1, "the first message on the disk")
        rec.flush_s = 0.3
        for ns in range(2, 12):
            rec.write("/drive_state", ns, _state(ns))
        wait_for(lambda: _messages_on_disk(rec.file) == 11, "the chunk closed by the flush bound, far from full")
    finally:
        rec.close()
    assert not is_being_recorded(rec.file)


def test_a_flowing_topic_is_written_in_chunks_of_many_messages_at_the_shortest_flush_bound(tmp_path):
    """At record_flush_s's least value (0.05 s, the writer's own batching interval), messages
    that come as a node's ticks (six at a time, 100 Hz) share chunks: a chunk per message
    would bloat the bag and fsync at every message. Flushes come at most every flush_s, and
    ticks at least 10 ms apart: far fewer chunks than ticks, whatever the machine's load."""
    import time

    ticks = 40
    with BagRecorder(tmp_path / "bag", [STATE], flush_s=0.05) as rec:
        for tick in range(ticks):
            for k in range(6):
                rec.write("/drive_state", 6 * tick + k, _state(6 * tick + k))
            time.sleep(0.01)
    with (tmp_path / "bag" / "bag_0.mcap").open("rb") as handle:
        summary = make_reader(handle).get_summary()
    assert summary.statistics.message_count == 6 * ticks
    assert 1 < len(summary.chunk_indexes) < ticks, len(summary.chunk_indexes)


def _messages_on_disk(file) -> int:
    count = 0
    with file.open("rb") as handle:
        try:
            for record in StreamReader(handle, validate_crcs=True).records:
                count += isinstance(record, Message)
        except Exception:
            pass
    return count


def test_offers_of_new_publishers_reach_the_metadata(tmp_path):
    with BagRecorder(tmp_path / "bag", [COMMAND]) as rec:
        rec.add_offers("/valve_command", (offered_qos(reliable=True, transient_local=True),))
        rec.add_offers("/valve_command", (offered_qos(reliable=False),))  # already listed: not twice
    info = yaml.safe_load((tmp_path / "bag" / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    offers = info["topics_with_message_count"][0]["topic_metadata"]["offered_qos_profiles"]
    assert [(o["reliability"], o["durability"]) for o in offers] == [
        ("best_effort", "volatile"),
        ("reliable", "transient_local"),
    ]


def test_a_topic_declared_later_gets_its_channel_before_its_first_message(tmp_path):
    with BagRecorder(tmp_path / "bag", [STATE]) as rec:
        rec.write("/drive_state", 1, _state(1))
        rec.add_topic(COMMAND)
        rec.write("/valve_command", 2, serialize_message(ValveCommand(opening=0.5)))
    assert check_bag(tmp_path / "bag") == {"/drive_state": 1, "/valve_command": 1}
