"""What every bag of ours must satisfy, checked by independent readers."""

from __future__ import annotations

import yaml
from mcap.reader import make_reader
from rosbags.highlevel import AnyReader


def check_bag(folder):
    """What every bag of ours must satisfy: CRC-checked MCAP, log time non-decreasing per
    channel, metadata.yaml times equal to the messages', readable by rosbags. Returns counts."""
    (file,) = folder.glob("*.mcap")
    last: dict[str, int] = {}
    counts: dict[str, int] = {}
    first_ns, last_ns = None, None
    with file.open("rb") as handle:
        reader = make_reader(handle, validate_crcs=True)
        for _, channel, message in reader.iter_messages(log_time_order=False):
            assert message.log_time >= last.get(channel.topic, 0), f"log time went back on {channel.topic}"
            last[channel.topic] = message.log_time
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
            first_ns = message.log_time if first_ns is None else min(first_ns, message.log_time)
            last_ns = message.log_time if last_ns is None else max(last_ns, message.log_time)
    info = yaml.safe_load((folder / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert info["starting_time"]["nanoseconds_since_epoch"] == (first_ns or 0)
    assert info["duration"]["nanoseconds"] == (last_ns or 0) - (first_ns or 0)
    assert info["message_count"] == sum(counts.values())
    with AnyReader([folder]) as reader:
        for connection, _, raw in reader.messages():
            reader.deserialize(raw, connection.msgtype)
    return counts
