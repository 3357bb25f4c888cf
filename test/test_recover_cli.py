"""boom-bag-recover on cut and damaged files, and after an interrupted run of its own, as a user meets it.

A cut at any byte never gives a traceback: every complete chunk comes back, and a longer
prefix never keeps fewer messages. An interrupted run leaves a state a rerun finishes. Files
made record by record (at the end) put a cut or a damage at each boundary of a record, a chunk
and the header, exactly at it and one byte past it. The
command line runs as boom-bag-recover's main in this process (conftest.run_tool);
test_node_bags and test_recovery run the real one.
"""

from __future__ import annotations

import errno
import fcntl
import os
import random
import shutil
import stat
import sys
import zlib
from pathlib import Path

import pytest
import yaml
from conftest import run_tool, wait_for

pytest.importorskip("rclpy")
import lz4.frame
import zstandard
from bag_checks import check_bag
from mcap.reader import make_reader
from mcap.records import Message
from mcap.stream_reader import StreamReader
from rclpy.serialization import serialize_message

from boom_hydraulics.bags import recovery
from boom_hydraulics.bags.recording import MCAP_MAGIC, BagRecorder, Topic
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
    for size in (0, 3, 30):
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


def _other_mcap(path: Path, profile: str, library: str = "someone else's logger") -> None:
    """A whole MCAP file another tool wrote: one channel, three messages."""
    from mcap.writer import Writer

    with path.open("wb") as handle:
        writer = Writer(handle)
        writer.start(profile=profile, library=library)
        schema = writer.register_schema("pose", "jsonschema", b"{}")
        channel = writer.register_channel("/pose", "json", schema)
        for i in range(3):
            writer.add_message(channel, i, b"{}", i)
        writer.finish()


@pytest.mark.parametrize("profile", ["ros2", "", "ros1", "ros3"])
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


@pytest.mark.parametrize("text", ["not an MCAP file at all, just text", "\xff: bytes that sort after the magic"])
def test_a_folder_whose_mcap_is_no_mcap_is_one_line_and_nothing_changes(tmp_path, text):
    folder = tmp_path / "notes"
    folder.mkdir()
    (folder / "n.md").write_text("notes")
    (folder / "x.mcap").write_text(text)  # read through a map: a traceback before
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
    bag, _ = _killed(tmp_path, big_file)
    (bag / "metadata.yaml").write_text("rosbag2_bagfile_information: {}\n")
    before = _snapshot(bag)
    monkeypatch.setattr(recovery, "_write_partial", _full_disk)
    with pytest.raises(BagError) as error:
        recover(bag)
    assert str(error.value) == (
        f"{bag / f'{bag.name}_0.mcap'}: No space left on device; nothing was changed, the bag is as it was "
        f"(free about 1 MiB and run boom-bag-recover {bag} again)"  # a file of less than 1 MiB
    )
    assert _snapshot(bag) == before


def _full_disk(final: Path, fill: object) -> Path:
    """recovery._write_partial on a full disk."""
    raise OSError(errno.ENOSPC, "No space left on device", str(final))


def _failing_replace(src: object, dst: object) -> None:
    """os.replace on a disk that fails."""
    raise OSError(errno.EIO, "Input/output error", str(dst))


# --- files made record by record (the MCAP specification's records): each boundary of a record, chunk, header
def _u(value: int, size: int) -> bytes:
    return value.to_bytes(size, "little")


def _text(text: str) -> bytes:
    return _u(len(text.encode()), 4) + text.encode()


def _record(opcode: int, content: bytes) -> bytes:
    """An MCAP record: opcode, content length (uint64), content."""
    return bytes([opcode]) + _u(len(content), 8) + content


def _header(library: str = "boom_hydraulics") -> bytes:
    return _record(0x01, _text("ros2") + _text(library))


def _string_map(pairs: dict[str, str]) -> bytes:
    inner = b"".join(_text(k) + _text(v) for k, v in pairs.items())
    return _u(len(inner), 4) + inner


def _channel() -> bytes:
    """Schema 1 and channel 1 (/drive_state), as records outside chunks."""
    schema = _record(0x03, _u(1, 2) + _text(STATE.msgtype) + _text("ros2msg") + _text(""))
    return schema + _record(0x04, _u(1, 2) + _u(1, 2) + _text(STATE.name) + _text("cdr") + _string_map({}))


def _message(i: int, data: bytes | None = None) -> bytes:
    """Message ``i`` of channel 1, logged at i + 1 ns."""
    payload = serialize_message(DriveState(rod_position_m=float(i))) if data is None else data
    return _record(0x05, _u(1, 2) + _u(i, 4) + _u(i + 1, 8) + _u(i + 1, 8) + payload)


def _chunk(
    records: bytes, compression: str = "", packed: bytes | None = None, size: int | None = None, crc: int | None = None
) -> bytes:
    """A chunk record of ``records`` (``packed``: as stored; ``size``, ``crc``: the size and CRC it states)."""
    packed = records if packed is None else packed
    size = len(records) if size is None else size
    crc = zlib.crc32(records) if crc is None else crc
    content = _u(0, 8) + _u(0, 8) + _u(size, 8) + _u(crc, 4) + _text(compression)
    return _record(0x06, content + _u(len(packed), 8) + packed)


def _file(*records: bytes, library: str = "boom_hydraulics") -> bytes:
    """A killed recording: the magic, a header and ``records``, cut after the last."""
    return MCAP_MAGIC + _header(library) + _channel() + b"".join(records)


def _bag_of(tmp_path: Path, data: bytes) -> Path:
    """A bag folder of one file, bag_0.mcap, of ``data``."""
    bag = tmp_path / "bag"
    bag.mkdir()
    (bag / "bag_0.mcap").write_bytes(data)
    return bag


TWO = _message(0) + _message(1)


@pytest.mark.parametrize(
    ("compression", "packed", "kept"),
    [
        ("", TWO, 2),
        ("zstd", zstandard.ZstdCompressor().compress(TWO), 2),
        ("lz4", lz4.frame.compress(TWO), 2),
        ("snappy", lz4.frame.compress(TWO), 0),  # a compression this reader does not know, whatever the bytes
        ("bz2", lz4.frame.compress(TWO), 0),
        ("zzz", zstandard.ZstdCompressor().compress(TWO), 0),  # a name sorting after zstd, of zstd bytes
    ],
    ids=["none", "zstd", "lz4", "snappy", "bz2", "zzz"],  # the bytes can differ between processes (CDR padding)
)
def test_a_chunk_is_kept_in_each_compression_it_reads_and_dropped_in_any_other(compression, packed, kept):
    found = salvage(_file(_chunk(TWO, compression, packed), _message(2)))
    assert (len(found.messages), found.dropped_chunks) == (kept + 1, 1 - kept // 2)


def test_a_chunk_is_dropped_where_its_records_do_not_fill_its_stated_size_exactly():
    found = salvage(_file(_chunk(TWO + TWO[:5]), _message(2)))  # five bytes of a record that never ended
    assert (len(found.messages), found.dropped_chunks) == (1, 1)
    bigger = _chunk(TWO, size=len(TWO) - 1)  # its contents are one byte longer than it says
    found = salvage(_file(bigger, _message(2)))
    assert (len(found.messages), found.dropped_chunks) == (1, 1)
    found = salvage(_file(_chunk(TWO, size=len(TWO) + 1), _message(2)))  # one byte shorter than it says
    assert (len(found.messages), found.dropped_chunks) == (1, 1)
    for crc in (zlib.crc32(TWO) - 1, zlib.crc32(TWO) + 1):  # a CRC one off, either way
        found = salvage(_file(_chunk(TWO, crc=crc), _message(2)))
        assert (len(found.messages), found.dropped_chunks) == (1, 1)
    found = salvage(_file(_chunk(TWO, crc=0), _message(2)))  # CRC 0: none written, nothing to check
    assert (len(found.messages), found.dropped_chunks) == (3, 0)
    found = salvage(_file(_chunk(b""), _message(2)))  # an empty chunk is whole, not damaged
    assert (len(found.messages), found.dropped_chunks) == (1, 0)
    found = salvage(_file(_chunk(TWO + _record(0x80, b"")), _message(2)))  # ends in a record of only its 9-byte head
    assert (len(found.messages), found.dropped_chunks) == (3, 0)


def test_the_custom_data_comes_from_its_own_metadata_record_only(tmp_path):
    first = _record(0x0C, _text("a_note") + _string_map({"by": "someone"}))  # named before ours
    second = _record(0x0C, _text("z_note") + _string_map({"by": "someone else"}))  # and after
    ours = _record(0x0C, _text("boom_hydraulics") + _string_map({"clock_origin_ns": "7"}))
    bag = _bag_of(tmp_path, _file(first, second, ours, _message(0), _message(1)))
    assert recover(bag).messages == 2
    info = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert info["custom_data"] == {"clock_origin_ns": "7"}


@pytest.mark.parametrize(
    "tail",
    [
        b"\x02" + _u(5, 8) + bytes(20) + MCAP_MAGIC,  # a footer's opcode and the magic, with a length not 20
        b"\x02" + _u(20, 8) + bytes(20) + b"\xffnomagic",  # a footer, without the magic (sorting after it)
        b"\x02" + _u(20, 8) + bytes(20) + b"\x00nomagic",  # (sorting before it)
        b"\x02" + _u(21, 8) + bytes(20) + MCAP_MAGIC,  # a length one past a footer's
        b"\x01" + _u(20, 8) + bytes(20) + MCAP_MAGIC,  # the opcodes either side of a footer's
        b"\x03" + _u(20, 8) + bytes(20) + MCAP_MAGIC,
    ],
)
def test_a_cut_file_whose_last_message_ends_in_bytes_shaped_like_a_footer_is_recovered(tmp_path, tail):
    bag = _bag_of(tmp_path, _file(_message(0), _message(1, data=b"\0\1\0\0" + tail)))
    result = recover(bag)
    assert result.damaged == bag / "bag_0.mcap.damaged" and result.messages == 2


@pytest.mark.parametrize("library", ["", "boom_hydraulics"])
def test_a_file_cut_exactly_after_its_header_is_one_line(tmp_path, library):
    bag = _bag_of(tmp_path, MCAP_MAGIC + _header(library))  # 29 bytes without a library name: shorter than a footer
    file = bag / "bag_0.mcap"
    with pytest.raises(BagError, match="no channel survived; nothing to recover"):
        recover(bag)
    assert [p.name for p in bag.iterdir()] == [file.name]


def test_a_leftover_that_cannot_be_removed_is_one_line_naming_it(tmp_path, monkeypatch):
    bag = _bag_of(tmp_path, _file(_message(0)))
    leftover = bag / ".bag_0.mcap.a1b2c3d4.partial"
    leftover.write_bytes(b"half")
    unlink = Path.unlink

    def refuse(path: Path, missing_ok: bool = False) -> None:
        if path == leftover:
            raise PermissionError(errno.EACCES, "Permission denied", str(path))
        unlink(path, missing_ok=missing_ok)

    monkeypatch.setattr(Path, "unlink", refuse)
    with pytest.raises(BagError) as error:
        recover(bag)
    assert str(error.value) == f"{leftover}: cannot remove this leftover of an interrupted run (Permission denied)"


def _recorded(folder: Path) -> Path:
    with BagRecorder(folder, [STATE], custom_data={"clock_origin_ns": "0"}) as rec:
        for i in range(5):
            rec.write(STATE.name, i + 1, serialize_message(DriveState(rod_position_m=float(i))))
    return rec.file


@pytest.mark.parametrize("cut", [False, True])
def test_the_nodes_file_gets_the_metadata_yaml_its_recorder_would_have_written(tmp_path, cut):
    file = _recorded(tmp_path / "late")
    written = (tmp_path / "late" / "metadata.yaml").read_text()
    (tmp_path / "late" / "metadata.yaml").unlink()  # killed after finishing the file, before metadata.yaml
    if cut:  # or killed after its last chunk, before the file's end: every message comes back
        file.write_bytes(file.read_bytes()[: _chunk_ends(file.read_bytes())[-1]])
    assert (recover(tmp_path / "late").damaged is None) != cut
    assert (tmp_path / "late" / "metadata.yaml").read_text() == written


def test_a_full_disk_while_writing_metadata_yaml_for_a_whole_file_names_it_and_changes_nothing(tmp_path, monkeypatch):
    file = _recorded(tmp_path / "late")
    (tmp_path / "late" / "metadata.yaml").unlink()
    before = file.read_bytes()

    monkeypatch.setattr(recovery, "_write_partial", _full_disk)
    with pytest.raises(BagError) as error:
        recover(tmp_path / "late")
    metadata = tmp_path / "late" / "metadata.yaml"
    assert str(error.value) == f"{metadata}: No space left on device; nothing was changed"
    assert sorted(p.name for p in file.parent.iterdir()) == [file.name] and file.read_bytes() == before


def test_an_lz4_chunk_without_the_lz4_module_is_dropped_not_a_traceback(monkeypatch):
    monkeypatch.setitem(sys.modules, "lz4.frame", None)  # import lz4.frame raises ImportError
    found = salvage(_file(_chunk(TWO, "lz4", lz4.frame.compress(TWO)), _message(2)))
    assert (len(found.messages), found.dropped_chunks) == (1, 1)


@pytest.mark.parametrize("opcode", [0x00, 0x80, 0xFF])
def test_a_record_of_an_opcode_it_does_not_know_is_skipped_even_shaped_like_a_schema_or_channel(opcode):
    ghost = _u(2, 2) + _u(1, 2) + _text("/ghost") + _text("cdr") + _string_map({})
    fake = _u(1, 2) + _text("fake/msg/Type") + _text("ros2msg") + _text("")
    note = _text("ghost_note") + _string_map({"by": "no one"})
    found = salvage(_file(_record(opcode, ghost), _record(opcode, fake), _record(opcode, note), _message(0)))
    assert list(found.channels) == [1] and len(found.messages) == 1 and found.metadata == []
    assert [name for name, _, _ in found.schemas.values()] == [STATE.msgtype]


def test_every_metadata_record_but_rosbag2s_own_comes_back(tmp_path):
    notes = [
        ("a_note", {"by": "someone"}),
        ("z_note", {"by": "someone else"}),
        ("rosbag2", {"serialized_metadata": ""}),
    ]
    records = [_record(0x0C, _text(name) + _string_map(pairs)) for name, pairs in notes]
    bag = _bag_of(tmp_path, _file(*records, _message(0)))
    recover(bag)  # the old rosbag2 record (of the whole recording) is dropped, a new one written
    with (bag / "bag_0.mcap").open("rb") as handle:
        metadata = [(m.name, m.metadata) for m in make_reader(handle).iter_metadata()]
    assert metadata[:2] == notes[:2] and [name for name, _ in metadata[2:]] == ["rosbag2"]  # rewritten


@pytest.mark.parametrize("files", [0, 2])
def test_a_folder_without_one_mcap_file_is_one_line(tmp_path, files):
    (tmp_path / "notes.md").write_text("the user's")
    for i in range(files):
        (tmp_path / f"run_{i}.mcap").write_bytes(_file(_message(0)))
    with pytest.raises(BagError) as error:
        recover(tmp_path)
    assert str(error.value) == f"{tmp_path}: expected one .mcap file, found {files}"


@pytest.mark.parametrize("name", ["bag_0.mcap", "bag_0.mcap.damaged"])
def test_a_file_that_cannot_be_read_is_one_line_naming_why(tmp_path, name):
    bag = tmp_path / "bag"
    (bag / name).mkdir(parents=True)  # a folder where the recording, or the original kept, should be
    with pytest.raises(BagError) as error:
        recover(bag)
    assert str(error.value) == f"{bag / name}: cannot read it (Is a directory)"


def test_a_cut_file_beside_metadata_yaml_and_an_old_one_kept_is_refused(tmp_path):
    bag = _bag_of(tmp_path, _file(_message(0)))
    (bag / "metadata.yaml").write_text("rosbag2_bagfile_information: {}\n")
    (bag / "metadata.yaml.damaged").write_text("the user's")
    with pytest.raises(BagError) as error:
        recover(bag)
    assert str(error.value) == f"{bag / 'metadata.yaml.damaged'} exists already; move it out of the bag folder first"


def test_a_run_that_fails_between_its_renames_says_so_and_the_next_finishes_the_bag(tmp_path, monkeypatch):
    bag = _bag_of(tmp_path, _file(_message(0), _message(1)))
    replace = os.replace

    monkeypatch.setattr(os, "replace", _failing_replace)
    with pytest.raises(BagError) as error:
        recover(bag)
    assert str(error.value) == (
        f"{bag / 'bag_0.mcap'}: Input/output error; the bag is half renamed: "
        f"run boom-bag-recover {bag} again to finish it"
    )
    monkeypatch.setattr(os, "replace", replace)
    result = recover(bag)  # from the original, renamed already, and without the first run's files
    assert result.resumed and result.messages == 2 and len(result.removed) == 2
    assert sorted(p.name for p in bag.iterdir()) == ["bag_0.mcap", "bag_0.mcap.damaged", "metadata.yaml"]


def test_a_whole_file_whose_metadata_yaml_cannot_be_put_in_place_names_why_and_leaves_nothing(tmp_path, monkeypatch):
    file = _recorded(tmp_path / "late")
    (tmp_path / "late" / "metadata.yaml").unlink()

    monkeypatch.setattr(os, "replace", _failing_replace)
    with pytest.raises(BagError) as error:
        recover(tmp_path / "late")
    assert str(error.value) == f"{tmp_path / 'late' / 'metadata.yaml'}: Input/output error; nothing was changed"
    assert [p.name for p in file.parent.iterdir()] == [file.name]


def test_a_whole_file_whose_folder_cannot_be_synced_says_metadata_yaml_is_written_not_that_nothing_changed(
    tmp_path, monkeypatch
):
    file = _recorded(tmp_path / "late")
    (tmp_path / "late" / "metadata.yaml").unlink()

    def failing_sync(folder: Path) -> None:
        raise OSError(errno.EIO, "Input/output error", str(folder))

    monkeypatch.setattr(recovery, "_sync_folder", failing_sync)
    with pytest.raises(BagError) as error:
        recover(tmp_path / "late")
    assert str(error.value) == (
        f"{tmp_path / 'late'}: Input/output error; metadata.yaml is written but the folder could not be synced to "
        f"disk: the bag reads now, and after a power cut boom-bag-recover {tmp_path / 'late'} writes it again"
    )
    assert sorted(p.name for p in file.parent.iterdir()) == [file.name, "metadata.yaml"]
    assert check_bag(tmp_path / "late")  # it reads


def test_a_message_of_no_data_is_kept_and_one_cut_inside_its_head_is_not():
    whole = _message(0, data=b"")  # 22 bytes: channel, sequence, log and publish time
    cut = _record(0x05, _u(1, 2) + _u(1, 4) + _u(2, 8) + _u(2, 7))  # 21 bytes
    found = salvage(_file(whole, cut, _message(2, data=b"two")))
    assert [(m[1], m[4]) for m in found.messages] == [(0, b""), (2, b"two")]
    found = salvage(_file(_chunk(whole + _message(1))))
    assert [m[1] for m in found.messages] == [0, 1] and found.dropped_chunks == 0
    found = salvage(_file(_chunk(cut + _message(1))))
    assert found.messages == [] and found.dropped_chunks == 1


@pytest.mark.parametrize("whole", [False, "someone else's logger", "a logger"])  # named after or before ours
def test_a_file_not_of_this_tool_beside_a_damaged_one_is_refused_and_kept(tmp_path, whole):
    """Only a finished file this tool wrote (an earlier run's) is replaced when a .damaged is there."""
    bag = tmp_path / "bag"
    bag.mkdir()
    (bag / "bag_0.mcap.damaged").write_bytes(_file(_message(0)))
    if whole:  # another tool's finished MCAP file
        _other_mcap(bag / "bag_0.mcap", "ros2", library=whole)
    else:  # one that only ends as a finished MCAP file does
        (bag / "bag_0.mcap").write_bytes(b"the user's, cut at its start" + b"\x02" + _u(20, 8) + bytes(20) + MCAP_MAGIC)
    not_ours = (bag / "bag_0.mcap").read_bytes()
    with pytest.raises(BagError, match=r"bag_0\.mcap\.damaged exists already; move it out of the bag folder first"):
        recover(bag)
    assert (bag / "bag_0.mcap").read_bytes() == not_ours


@pytest.mark.parametrize("opcode", [0x00, 0x80])  # an opcode before a header's and one after it
def test_a_file_whose_first_record_is_no_header_is_recovered_whatever_that_record_says(tmp_path, opcode):
    posing = _record(opcode, _text("ros1") + _text("someone else's"))  # a header's contents, not its opcode
    bag = _bag_of(tmp_path, MCAP_MAGIC + posing + _channel() + _message(0))
    assert recover(bag).messages == 1


def test_a_file_whose_header_does_not_read_is_recovered(tmp_path):
    bag = _bag_of(tmp_path, MCAP_MAGIC + _record(0x01, _u(200, 4)) + _channel() + _message(0))
    assert recover(bag).messages == 1


@pytest.mark.parametrize("interrupted", [True, False])  # Ctrl-C, or a full disk
def test_a_run_stopped_while_writing_metadata_yaml_leaves_the_bag_as_it_was(tmp_path, monkeypatch, interrupted):
    bag = _bag_of(tmp_path, _file(_message(0)))
    before = {p.name: p.read_bytes() for p in bag.iterdir()}
    write_partial = recovery._write_partial

    def stopping(final, fill):
        if final.name != "metadata.yaml":  # the first of the two: the new MCAP file is written
            return write_partial(final, fill)
        if interrupted:
            raise KeyboardInterrupt
        return _full_disk(final, fill)

    monkeypatch.setattr(recovery, "_write_partial", stopping)
    with pytest.raises(KeyboardInterrupt if interrupted else BagError) as error:
        recover(bag)
    assert {p.name: p.read_bytes() for p in bag.iterdir()} == before
    assert interrupted or str(error.value).startswith(f"{bag / 'metadata.yaml'}: No space left on device; nothing")


def test_reading_stops_exactly_at_the_end_of_the_last_whole_record():
    data = _file(_message(0), _message(1))
    last = len(data) - len(_message(1))
    for size, stop, kept in [(last, last, 1), (last + 1, last, 1), (len(data) - 1, last, 1), (len(data), len(data), 2)]:
        found = salvage(data[:size])
        assert (found.stop, len(found.messages), found.complete) == (stop, kept, False), size
    found = salvage(data + _record(0x0F, _u(0, 4)) + b"summary and footer")  # the data section ends
    assert found.complete and found.stop == len(data) and len(found.messages) == 2
    found = salvage(b"")
    assert (found.stop, found.complete, found.messages) == (0, False, [])  # a file cut at 0 bytes stops at 0


def test_a_channel_whose_topic_runs_past_its_record_is_skipped_and_its_messages_with_it():
    rest = _text("cdr") + _string_map({})
    past = _record(0x04, _u(2, 2) + _u(1, 2) + _u(len("/ghost") + len(rest) + 4, 4) + b"/ghost" + rest)
    found = salvage(_file(past, _message(0), _record(0x05, _u(2, 2) + bytes(20) + b"on the lost channel")))
    assert list(found.channels) == [1] and len(found.messages) == 1 and found.orphans == 1


def test_a_channel_without_a_schema_is_kept(tmp_path):
    bare = _record(0x04, _u(2, 2) + _u(0, 2) + _text("/raw") + _text("json") + _string_map({}))  # schema 0: none
    bag = _bag_of(tmp_path, _file(bare, _record(0x05, _u(2, 2) + _u(0, 4) + _u(5, 8) + _u(5, 8) + b"{}")))
    assert recover(bag).messages == 1
    with (bag / "bag_0.mcap").open("rb") as handle:
        summary = make_reader(handle).get_summary()
    assert [(c.topic, c.schema_id) for c in summary.channels.values() if c.topic == "/raw"] == [("/raw", 0)]


def test_the_recovered_file_holds_its_messages_in_log_time_order(tmp_path):
    logged = [(30, 1), (10, 2), (20, 3)]  # (log time, publish time): published in another order than logged
    messages = [
        _record(0x05, _u(1, 2) + _u(i, 4) + _u(log, 8) + _u(pub, 8) + b"m") for i, (log, pub) in enumerate(logged)
    ]
    bag = _bag_of(tmp_path, _file(*messages))
    recover(bag)
    with (bag / "bag_0.mcap").open("rb") as handle:
        records = StreamReader(handle, skip_magic=False, emit_chunks=False).records
        assert [(m.log_time, m.publish_time) for m in records if isinstance(m, Message)] == sorted(logged)
    info = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert (info["starting_time"], info["duration"]) == ({"nanoseconds_since_epoch": 10}, {"nanoseconds": 20})


def test_a_bag_folder_that_cannot_be_opened_is_one_line(tmp_path, monkeypatch):
    bag = _bag_of(tmp_path, _file(_message(0)))
    open_ = os.open

    def refusing(path, flags, *args):
        if Path(path) == bag:
            raise PermissionError(errno.EACCES, "Permission denied", str(path))
        return open_(path, flags, *args)

    monkeypatch.setattr(os, "open", refusing)
    with pytest.raises(BagError) as error:
        recover(bag)
    assert str(error.value) == f"{bag}: cannot open the bag folder (Permission denied)"


def test_a_bag_folder_replaced_by_a_file_after_the_check_is_one_line(tmp_path, monkeypatch):
    """The folder is opened as a folder: a file in its place by then (another program) is refused."""
    file = tmp_path / "bag"
    file.write_bytes(_file(_message(0)))
    monkeypatch.setattr(Path, "is_dir", lambda path: True)  # it was a folder when checked
    with pytest.raises(BagError) as error:
        recover(file)
    assert str(error.value) == f"{file}: cannot open the bag folder (Not a directory)"


@pytest.mark.parametrize("repeats", [333, 3000])
def test_a_whole_mcap_of_another_tool_with_a_long_header_is_refused_and_nothing_changes(tmp_path, repeats):
    """A header of 3 kB, and one of 27 kB read whole by its stated length (a first 4 KiB alone
    held no header: such a file was taken for a killed recording and rewritten)."""
    folder = tmp_path / "notes"
    folder.mkdir()
    _other_mcap(folder / "run.mcap", "ros1", library="a logger " * repeats)
    before = _snapshot(folder)
    with pytest.raises(BagError, match=r"is not a rosbag2 recording \(profile 'ros1'\); nothing was changed"):
        recover(folder)
    assert _snapshot(folder) == before


def test_the_smallest_whole_mcap_of_another_tool_is_refused_as_whole(tmp_path):
    footer = _record(0x02, _u(0, 8) + _u(0, 8) + _u(0, 4))  # no summary
    bag = _bag_of(tmp_path, MCAP_MAGIC + _header("a") + _record(0x0F, _u(0, 4)) + footer + MCAP_MAGIC)  # 80 bytes
    with pytest.raises(BagError, match=r"is a whole MCAP file \(written by a\), not a killed recording"):
        recover(bag)
    assert [p.name for p in bag.iterdir()] == ["bag_0.mcap"]


def test_a_full_disk_while_writing_the_new_file_leaves_no_temporary_file(tmp_path, monkeypatch):
    bag = _bag_of(tmp_path, _file(_message(0)))
    before = _snapshot(bag)

    def full(fd: int) -> None:
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(os, "fsync", full)
    with pytest.raises(BagError, match="No space left on device; nothing was changed, the bag is as it was"):
        recover(bag)
    assert _snapshot(bag) == before


def test_a_temporary_name_taken_by_a_link_is_passed_over_and_what_it_points_to_is_kept(tmp_path, monkeypatch):
    bag = _bag_of(tmp_path, _file(_message(0)))
    (tmp_path / "precious").write_text("the user's")
    (bag / ".bag_0.mcap.aaaaaaaa.partial").symlink_to(tmp_path / "precious")  # a link is no leftover of ours
    names = iter(["aaaaaaaa", "bbbbbbbb", "cccccccc"])
    monkeypatch.setattr(recovery.secrets, "token_hex", lambda n: next(names))
    assert recover(bag).messages == 1
    assert (tmp_path / "precious").read_text() == "the user's"
    assert (bag / ".bag_0.mcap.aaaaaaaa.partial").is_symlink()


def test_a_full_disk_names_about_the_space_the_bag_needs(tmp_path, monkeypatch):
    bag = _bag_of(tmp_path, _file(_message(0, data=bytes(3 << 20))))  # a file of 3 MiB
    monkeypatch.setattr(recovery, "_write_partial", _full_disk)
    with pytest.raises(BagError, match=r"\(free about 3 MiB and run boom-bag-recover "):
        recover(bag)


def test_a_folder_that_cannot_be_synced_after_metadata_yaml_is_one_line(tmp_path, monkeypatch):
    file = _recorded(tmp_path / "late")
    (tmp_path / "late" / "metadata.yaml").unlink()
    fsync = os.fsync
    synced = []

    def failing_second(fd: int) -> None:
        synced.append(fd)
        if len(synced) == 2:  # the folder's, after metadata.yaml was put in place
            raise OSError(errno.EIO, "Input/output error")
        fsync(fd)

    monkeypatch.setattr(os, "fsync", failing_second)
    with pytest.raises(BagError, match="Input/output error"):
        recover(file.parent)
    assert not [p for p in file.parent.iterdir() if p.name.endswith(".partial")]


def test_a_file_with_channels_and_no_message_is_recovered_empty(tmp_path):
    bag = _bag_of(tmp_path, _file())
    assert recover(bag).messages == 0
    info = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert (info["starting_time"], info["duration"]) == ({"nanoseconds_since_epoch": 0}, {"nanoseconds": 0})
    assert [t["message_count"] for t in info["topics_with_message_count"]] == [0]


def test_bytes_that_are_no_mcap_file_are_refused_whichever_way_they_sort(tmp_path):
    for data in (b"\x00not MCAP", b"\xffnot MCAP"):
        with pytest.raises(BagError, match=r"^not an MCAP file \(wrong magic bytes\)$"):
            salvage(data)
    bag = tmp_path / "bag"
    bag.mkdir()
    (bag / "bag_0.mcap.damaged").write_bytes(b"\xffnot MCAP")  # the original kept by an interrupted run
    with pytest.raises(BagError) as error:
        recover(bag)
    assert str(error.value) == f"{bag / 'bag_0.mcap.damaged'}: not an MCAP file (wrong magic bytes)"


def test_a_bag_still_being_recorded_is_refused_and_left_alone(tmp_path):
    with BagRecorder(tmp_path / "live", [STATE], flush_s=0.0) as live:
        live.write(STATE.name, 1, serialize_message(DriveState()))
        wait_for(lambda: live.on_disk == 1, "the message on the disk")  # (the writer thread's own writes done)
        before = _snapshot(live.folder)
        with pytest.raises(BagError, match="is still being recorded; stop its recorder first"):
            recover(live.folder)
        assert _snapshot(live.folder) == before
