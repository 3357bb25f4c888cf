"""boom-bag-recover finishes a killed recording with every message that reached the disk.

The node-level case (a real SIGKILL, a live bag refused) is in test_node_bags.py.
"""

from __future__ import annotations

import shutil
import subprocess

import pytest
from conftest import wait_for

pytest.importorskip("rclpy")
from bag_checks import check_bag
from mcap.reader import make_reader
from rclpy.serialization import serialize_message

from boom_hydraulics.bags.reading import check_bag_path
from boom_hydraulics.bags.recording import BagRecorder, Topic
from boom_hydraulics.bags.recovery import recover
from boom_hydraulics.errors import BagError
from boom_hydraulics_msgs.msg import DriveState

RECOVER = shutil.which("boom-bag-recover")
STATE = Topic("/drive_state", "boom_hydraulics_msgs/msg/DriveState")


def _killed_bag(tmp_path, flushed: int, unflushed: int):
    """What a SIGKILL leaves: a copy of a live recording's file, taken mid-run."""
    live = BagRecorder(tmp_path / "live", [STATE], custom_data={"clock_origin_ns": "0"}, flush_s=0.2)
    for i in range(flushed):
        live.write("/drive_state", i, serialize_message(DriveState(rod_position_m=float(i))))
    wait_for(lambda: live.on_disk == flushed, "the first messages in complete chunks on the disk")
    live.flush_s = 3600.0  # from now on nothing more reaches the disk
    for i in range(flushed, flushed + unflushed):
        live.write("/drive_state", i, serialize_message(DriveState(rod_position_m=float(i))))
    wait_for(lambda: sum(live.counts.values()) == flushed + unflushed, "the writer thread taking the rest")
    bag = tmp_path / "killed"
    bag.mkdir()
    shutil.copy(live.file, bag / "killed_0.mcap")
    live.close()
    return bag


def test_every_flushed_message_comes_back_and_the_damaged_file_stays(tmp_path):
    bag = _killed_bag(tmp_path, flushed=50, unflushed=30)
    with pytest.raises(BagError, match="run boom-bag-recover"):
        check_bag_path(bag)
    damaged_bytes = (bag / "killed_0.mcap").read_bytes()
    result = recover(bag)
    file = result.file
    assert result.messages == 50 and result.dropped_chunks == 0 and not result.resumed
    assert check_bag(bag) == {"/drive_state": 50}
    assert (bag / "killed_0.mcap.damaged").read_bytes() == damaged_bytes  # kept as it was
    with file.open("rb") as handle:
        records = {m.name: m.metadata for m in make_reader(handle).iter_metadata()}
    assert records["boom_hydraulics"] == {"clock_origin_ns": "0"} and "rosbag2" in records


def test_recover_refuses_to_overwrite_and_to_redo(tmp_path):
    bag = _killed_bag(tmp_path, flushed=5, unflushed=0)
    (bag / "killed_0.mcap.damaged").write_bytes(b"the user's")
    with pytest.raises(BagError, match="exists already"):
        recover(bag)
    assert (bag / "killed_0.mcap.damaged").read_bytes() == b"the user's"
    (bag / "killed_0.mcap.damaged").unlink()
    recover(bag)
    with pytest.raises(BagError, match="nothing to recover"):
        recover(bag)


@pytest.mark.skipif(RECOVER is None, reason="boom-bag-recover not on PATH")
def test_the_command_line_says_one_line(tmp_path):
    result = subprocess.run([RECOVER, tmp_path / "nope"], capture_output=True, text=True, timeout=60)
    assert (
        result.returncode == 1
        and result.stderr.strip() == f"boom-bag-recover: error: {tmp_path / 'nope'}: not a bag folder"
    )
