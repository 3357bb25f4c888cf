"""boom-bag-recover on cut and damaged files, and after an interrupted run of its own, as a user meets it.

A cut at any byte never gives a traceback: every complete chunk comes back, and a longer
prefix never keeps fewer messages. An interrupted run leaves a state a rerun finishes. The
command line runs as boom-bag-recover's main in this process (conftest.run_tool);
test_node_bags and test_recovery run the real one.
"""

from __future__ import annotations

import fcntl
import os
import random
import shutil
import stat
from pathlib import Path

import pytest
from conftest import run_tool

pytest.importorskip("rclpy")
from bag_checks import check_bag
from mcap.records import Message
from mcap.stream_reader import StreamReader
from rclpy.serialization import serialize_message

from boom_hydraulics.bags.recording import BagRecorder, Topic
from boom_hydraulics.bags.recovery import recover, salvage
from boom_hydraulics.errors import BagError
from boom_hydraulics_msgs.msg import DriveState

RECOVER = shutil.which("boom-bag-recover")
STATE = Topic("/drive_state", "boom_hydraulics_msgs/msg/DriveState")
NOISE = ("rod_velocity_m_s", "boom_angle_rad", "piston_pressure_pa", "rod_pressure_pa", "load_force_n")
pytestmark = pytest.mark.skipif(RECOVER is None, reason="boom-bag-recover not on PATH")


@pytest.fixture(scope="module")
def big_file(tmp_path_factory) -> bytes:
    """A finished recording of 3000 messages in 8 KiB chunks: over 200 KB, so cuts at 100 000 and 170 000 are inside."""
    rng = random.Random(5)
    folder = tmp_path_factory.mktemp("big") / "bag"
    with BagRecorder(folder, [STATE], custom_data={"clock_origin_ns": "0"}, chunk_size=8192, flush_s=3600.0) as rec:
        for i in range(3000):
            msg = DriveState(rod_position_m=float(i), **{name: rng.random() for name in NOISE})
            rec.write("/drive_state", i + 1, serialize_message(msg))
    data = rec.file.read_bytes()
    assert len(data) > 200_000
    return data


def _independent_count(data: bytes) -> int:
    """Messages in the complete, CRC-valid chunks of ``data``, as the mcap library reads them."""
    count = 0
    reader = StreamReader(_Bytes(data), skip_magic=False, emit_chunks=False, validate_crcs=True)
    try:
        for record in reader.records:
            count += isinstance(record, Message)
    except Exception:
        pass  # its reader stops at the cut with an exception (struct.error among them)
    return count


class _Bytes:
    def __init__(self, data: bytes):
        self.data, self.pos = data, 0

    def read(self, n: int = -1) -> bytes:
        end = len(self.data) if n < 0 else self.pos + n
        out = self.data[self.pos : end]
        self.pos += len(out)
        return out


def _chunk_ends(data: bytes, with_starts: bool = False) -> list:
    """Where each chunk record of the finished file ends (or starts and ends)."""
    starts, ends, pos = [], [], 8
    while pos + 9 <= len(data):
        length = int.from_bytes(data[pos + 1 : pos + 9], "little")
        if data[pos] == 0x0F:
            break
        if data[pos] == 0x06:
            starts.append(pos)
            ends.append(pos + 9 + length)
        pos += 9 + length
    return ends if not with_starts else list(zip(starts, ends))


def _cut_bag(tmp_path: Path, data: bytes, size: int, name: str = "cut") -> Path:
    bag = tmp_path / f"{name}{size}"
    bag.mkdir()
    (bag / f"{bag.name}_0.mcap").write_bytes(data[:size])
    return bag


def test_any_prefix_keeps_every_complete_chunk_and_more_bytes_never_keep_less(big_file):
    ends = _chunk_ends(big_file)
    assert len(ends) > 20
    offsets = {0, 5, 8, 9, 30, 100_000, 170_000, len(big_file) - 1}
    for end in ends[:: max(1, len(ends) // 10)]:
        offsets |= {end - 1, end, end + 1, end + 9, end + 40}  # at, and inside the next record
    offsets |= set(range(0, len(big_file), 19997))
    last = 0
    for size in sorted(o for o in offsets if o <= len(big_file)):
        found = salvage(big_file[:size])  # never raises on a prefix of an MCAP file
        assert found.dropped_chunks == 0 and found.stop <= size
        kept = len(found.messages)
        assert kept >= last, f"cut at {size} kept {kept} < {last}"
        assert kept == _independent_count(big_file[:size]), f"cut at {size}"
        last = kept
    assert len(salvage(big_file).messages) == 3000


@pytest.mark.parametrize("size", [100_000, 170_000, "mid-record"])
def test_the_command_line_recovers_a_cut_file(tmp_path, big_file, size):
    if size == "mid-record":
        size = _chunk_ends(big_file)[10] + 500  # half way into the twelfth chunk
    bag = _cut_bag(tmp_path, big_file, size)
    expected = _independent_count(big_file[:size])
    result = run_tool("boom-bag-recover", bag)
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip().splitlines() == [
        f"boom-bag-recover: {expected} messages kept in {bag / f'{bag.name}_0.mcap'} "
        f"(the damaged file is {bag.name}_0.mcap.damaged)"
    ]
    assert check_bag(bag) == {"/drive_state": expected} and expected > 0
    umask = os.umask(0)
    os.umask(umask)
    for name in (f"{bag.name}_0.mcap", "metadata.yaml"):
        assert stat.S_IMODE((bag / name).stat().st_mode) == 0o666 & ~umask  # as every other file of a bag


def test_a_file_cut_before_its_first_chunk_is_one_line(tmp_path, big_file):
    for size in (3, 30):
        bag = _cut_bag(tmp_path, big_file, size)
        result = run_tool("boom-bag-recover", bag)
        assert result.returncode == 1 and "Traceback" not in result.stderr
        file = bag / f"{bag.name}_0.mcap"
        assert result.stderr.strip() == f"boom-bag-recover: error: {file}: no channel survived; nothing to recover"
        assert sorted(p.name for p in bag.iterdir()) == [f"{bag.name}_0.mcap"]


def test_a_damaged_chunk_is_dropped_and_counted_and_the_rest_kept(tmp_path, big_file):
    chunks = _chunk_ends(big_file, with_starts=True)
    ends = [end for _, end in chunks]
    damaged = bytearray(big_file[: ends[20]])
    damaged[chunks[6][0] + 200] ^= 0xFF  # inside the seventh chunk's compressed data
    bag = tmp_path / "bag"
    bag.mkdir()
    (bag / "bag_0.mcap").write_bytes(bytes(damaged))
    found = salvage(bytes(damaged))
    whole = _independent_count(big_file[: ends[20]])
    assert found.dropped_chunks == 1 and 0 < len(found.messages) < whole
    result = run_tool("boom-bag-recover", bag)
    assert result.returncode == 0, result.stderr
    assert f"{len(found.messages)} messages kept" in result.stdout and "1 damaged chunk(s) dropped" in result.stdout
    assert check_bag(bag) == {"/drive_state": len(found.messages)}


def _killed(tmp_path: Path, big_file: bytes) -> tuple[Path, int]:
    size = _chunk_ends(big_file)[15] + 123
    return _cut_bag(tmp_path, big_file, size, "killed"), _independent_count(big_file[:size])


def test_a_rerun_removes_the_leftovers_of_a_killed_run_and_only_those(tmp_path, big_file):
    bag, expected = _killed(tmp_path, big_file)
    name = f"{bag.name}_0.mcap"
    leftovers = [f".{name}.a1b2c3d4.partial", ".metadata.yaml.k_9x2mq0.partial"]  # this tool's and atomic_path's
    for leftover in leftovers:
        (bag / leftover).write_bytes(b"half")
    (bag / ".notes.partial").write_text("the user's")  # not a name of ours
    result = run_tool("boom-bag-recover", bag)
    assert result.returncode == 0, result.stderr
    first, last = result.stdout.strip().splitlines()
    assert first == f"boom-bag-recover: removed 2 leftover(s) of an interrupted run: {', '.join(sorted(leftovers))}"
    assert last.startswith(f"boom-bag-recover: {expected} messages kept")
    assert (bag / ".notes.partial").read_text() == "the user's"
    assert sorted(p.name for p in bag.iterdir()) == [".notes.partial", name, f"{name}.damaged", "metadata.yaml"]


def test_a_run_stopped_after_renaming_the_original_is_finished_by_the_next(tmp_path, big_file):
    bag, expected = _killed(tmp_path, big_file)
    name = f"{bag.name}_0.mcap"
    original = (bag / name).read_bytes()
    os.rename(bag / name, bag / f"{name}.damaged")  # where a kill between the renames leaves it
    result = run_tool("boom-bag-recover", bag)
    assert result.returncode == 0, result.stderr
    assert f"recovered again from {name}.damaged" in result.stdout
    assert check_bag(bag) == {"/drive_state": expected}
    assert (bag / f"{name}.damaged").read_bytes() == original


def test_a_run_stopped_before_metadata_yaml_is_finished_by_the_next(tmp_path, big_file):
    bag, expected = _killed(tmp_path, big_file)
    recover(bag)
    (bag / "metadata.yaml").unlink()  # a kill before the last rename
    result = recover(bag)
    assert result.resumed and result.messages == expected
    assert check_bag(bag) == {"/drive_state": expected}
    with pytest.raises(BagError, match="nothing to recover"):
        recover(bag)


def test_a_damaged_file_beside_an_unfinished_one_is_still_refused(tmp_path, big_file):
    bag, _ = _killed(tmp_path, big_file)
    (bag / f"{bag.name}_0.mcap.damaged").write_bytes(b"the user's")
    result = run_tool("boom-bag-recover", bag)
    assert result.returncode == 1 and "exists already; move it out" in result.stderr
    assert (bag / f"{bag.name}_0.mcap.damaged").read_bytes() == b"the user's"


def test_a_second_run_on_the_same_bag_is_refused_and_touches_nothing(tmp_path, big_file):
    bag, _ = _killed(tmp_path, big_file)
    busy = bag / f".{bag.name}_0.mcap.0123abcd.partial"
    busy.write_bytes(b"the first run's file in progress")
    fd = os.open(bag, os.O_RDONLY)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)  # what a run in progress holds
        result = run_tool("boom-bag-recover", bag)
    finally:
        os.close(fd)
    assert result.returncode == 1
    assert (
        result.stderr.strip()
        == f"boom-bag-recover: error: {bag}: another boom-bag-recover is working on it; wait for it to end"
    )
    assert busy.exists() and not (bag / "metadata.yaml").exists()


def _snapshot(folder: Path) -> dict[str, tuple[bytes, int]]:
    """Every file below ``folder`` with its bytes and modification time: what 'unchanged' means."""
    return {
        str(p.relative_to(folder)): (p.read_bytes(), p.stat().st_mtime_ns)
        for p in sorted(folder.rglob("*"))
        if p.is_file()
    }


def _other_mcap(path: Path, profile: str) -> None:
    """A whole MCAP file another tool wrote: one channel, three messages."""
    from mcap.writer import Writer

    with path.open("wb") as handle:
        writer = Writer(handle)
        writer.start(profile=profile, library="someone else's logger")
        schema = writer.register_schema("pose", "jsonschema", b"{}")
        channel = writer.register_channel("/pose", "json", schema)
        for i in range(3):
            writer.add_message(channel, i, b"{}", i)
        writer.finish()


@pytest.mark.parametrize("profile", ["ros2", "", "ros1"])
def test_a_whole_mcap_of_another_tool_in_a_folder_of_notes_is_refused_and_nothing_changes(tmp_path, profile):
    folder = tmp_path / "notes"
    folder.mkdir()
    (folder / "ideas.md").write_text("the user's notes")
    (folder / ".run.mcap.a1b2c3d4.partial").write_text("the user's, though named like our leftovers")
    _other_mcap(folder / "run.mcap", profile)
    before = _snapshot(folder)
    result = run_tool("boom-bag-recover", folder)
    assert result.returncode == 1 and "Traceback" not in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1 and "nothing was changed" in result.stderr
    assert ("whole MCAP file" if profile == "ros2" else "is not a rosbag2 recording") in result.stderr
    assert _snapshot(folder) == before


def test_a_folder_whose_mcap_is_no_mcap_is_one_line_and_nothing_changes(tmp_path):
    folder = tmp_path / "notes"
    folder.mkdir()
    (folder / "n.md").write_text("notes")
    (folder / "x.mcap").write_text("not an MCAP file at all, just text")  # read through a map: a traceback before
    before = _snapshot(folder)
    result = run_tool("boom-bag-recover", folder)
    assert result.returncode == 1 and "Traceback" not in result.stderr
    assert result.stderr.strip() == (
        f"boom-bag-recover: error: {folder / 'x.mcap'}: not an MCAP file (wrong magic bytes); nothing was changed"
    )
    assert _snapshot(folder) == before


def test_the_nodes_whole_file_without_metadata_yaml_gets_one_and_is_not_rewritten(tmp_path, big_file):
    bag = _cut_bag(tmp_path, big_file, len(big_file), "late")  # killed after finishing the file, before metadata.yaml
    file = bag / f"{bag.name}_0.mcap"
    result = run_tool("boom-bag-recover", bag)
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == (
        f"boom-bag-recover: {file} was whole (its recorder was killed before writing metadata.yaml): "
        "wrote metadata.yaml for its 3000 messages, the file is unchanged"
    )
    assert file.read_bytes() == big_file
    assert sorted(p.name for p in bag.iterdir()) == [file.name, "metadata.yaml"]
    assert check_bag(bag) == {"/drive_state": 3000}
    again = run_tool("boom-bag-recover", bag)
    assert again.returncode == 1 and "nothing to recover" in again.stderr


def test_a_cut_file_beside_its_metadata_yaml_is_recovered_and_the_old_metadata_kept(tmp_path, big_file):
    whole = tmp_path / "whole"
    whole.mkdir()
    (whole / "whole_0.mcap").write_bytes(big_file)
    assert run_tool("boom-bag-recover", whole).returncode == 0  # a finished bag: the file and its metadata.yaml
    old_metadata = (whole / "metadata.yaml").read_bytes()
    bag, expected = _killed(tmp_path, big_file)  # then its file was cut (a copy broken off)
    (bag / "metadata.yaml").write_bytes(old_metadata)
    result = run_tool("boom-bag-recover", bag)
    assert result.returncode == 0, result.stderr
    assert f"{expected} messages kept" in result.stdout and "metadata.yaml.damaged" in result.stdout
    assert (bag / "metadata.yaml.damaged").read_bytes() == old_metadata
    assert check_bag(bag) == {"/drive_state": expected}


def test_a_full_disk_leaves_a_cut_file_and_its_metadata_yaml_as_they_were(tmp_path, big_file, monkeypatch):
    """Nothing is renamed before both new files are written: metadata.yaml was moved aside first,
    and a full disk then left the bag without it, though the line said nothing had changed."""
    import errno

    from boom_hydraulics.bags import recovery

    bag, _ = _killed(tmp_path, big_file)
    (bag / "metadata.yaml").write_text("rosbag2_bagfile_information: {}\n")
    before = _snapshot(bag)

    def full(final, fill):
        raise OSError(errno.ENOSPC, "No space left on device", str(final))

    monkeypatch.setattr(recovery, "_write_partial", full)
    with pytest.raises(BagError, match="nothing was changed, the bag is as it was"):
        recover(bag)
    assert _snapshot(bag) == before
