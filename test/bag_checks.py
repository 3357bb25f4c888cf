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


def check_resim_within_a_tick(bag, out) -> None:
    """boom-resim of a bag boom-sim live recorded gives the recorded run again to within the
    motion of one tick (an unstamped command acts at the first step after it arrived; its log
    time is when it arrived): as many states, q1 within 0.3 m/s for 1/100 s."""
    import subprocess
    import sys

    import numpy as np

    from boom_hydraulics.bags.reading import read_drive_states

    resim = subprocess.run(
        [sys.executable, "-m", "boom_hydraulics.cli.resim", str(bag), "--out", str(out)],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert resim.returncode == 0, resim.stderr
    recorded, repeated = read_drive_states(bag), read_drive_states(out)
    assert len(repeated["q1"]) == len(recorded["q1"])
    assert np.max(np.abs(repeated["q1"] - recorded["q1"])) < 0.3 / 100.0  # 0.3 m/s for 1/100 s at most
