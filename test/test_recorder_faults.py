"""Fault injection: the recorder's disk fails part way (full, I/O error), and the run goes on.

The recorder stops recording with one line naming the file and the cause, write() keeps
returning, close() returns without metadata.yaml, the lock is freed, and boom-bag-recover
brings back every message of the complete chunks. Two ways to fail the disk: a stream that
refuses writes after a byte budget (runs anywhere), and a real small tmpfs (root only).
"""

from __future__ import annotations

import errno
import math
import os
import random
import shutil
import subprocess
from pathlib import Path

import pytest
from conftest import run_tool, small_tmpfs, wait_for

pytest.importorskip("rclpy")
from bag_checks import check_bag
from rclpy.serialization import deserialize_message, serialize_message
from rosbags.highlevel import AnyReader

from boom_hydraulics.bags import recording
from boom_hydraulics.bags.recording import BagRecorder, Topic, is_being_recorded
from boom_hydraulics.bags.recovery import salvage
from boom_hydraulics_msgs.msg import DriveState

RECOVER = shutil.which("boom-bag-recover")
STATE = Topic("/drive_state", "boom_hydraulics_msgs/msg/DriveState")
CHUNK = 4096
needs_recover = pytest.mark.skipif(RECOVER is None, reason="boom-bag-recover not on PATH")


def _state(i: int, rng: random.Random) -> bytes:
    """Message i: its index in rod_position_m, the rest noise, so that chunks do not compress to nothing."""
    noise = ("rod_velocity_m_s", "piston_pressure_pa", "rod_pressure_pa")
    return serialize_message(DriveState(rod_position_m=float(i), **{name: rng.random() for name in noise}))


class FullDisk(recording.BagFile):
    """A file system with ``budget`` bytes left: the write that crosses it is partial, then ENOSPC."""

    budget = 1 << 40

    def _write_some(self, data: memoryview) -> int:
        left = FullDisk.budget - os.fstat(self.fd).st_size
        if left <= 0:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return super()._write_some(data[:left])


class FailingSync(recording.BagFile):
    """A disk whose fsync reports an I/O error from the ``ok``-th call on."""

    ok = 1 << 40
    calls = 0

    def _fsync(self) -> None:
        FailingSync.calls += 1
        if FailingSync.calls > FailingSync.ok:
            raise OSError(errno.EIO, os.strerror(errno.EIO))
        super()._fsync()


def _recorded_indices(bag: Path) -> list[int]:
    with AnyReader([bag]) as reader:
        return [
            round(reader.deserialize(raw, c.msgtype).rod_position_m)
            for c, _, raw in reader.messages(reader.connections)
        ]


def _recover(bag: Path) -> subprocess.CompletedProcess:
    """boom-bag-recover's main in this process (conftest.run_tool)."""
    return run_tool("boom-bag-recover", bag)


def _check_failed_bag(rec: BagRecorder, cause: str) -> None:
    """What a failed recording leaves: one line, no metadata.yaml, no lock, a file ending at a whole record."""
    assert rec.failed and not rec.finished
    assert rec.error.startswith(f"{rec.file}: {cause}; recording stopped after ")
    assert f"run boom-bag-recover {rec.folder}" in rec.error and "\n" not in rec.error
    assert not (rec.folder / "metadata.yaml").exists()
    assert not is_being_recorded(rec.file)
    data = rec.file.read_bytes()
    assert salvage(data).stop == len(data)  # cut back to the last complete record


@needs_recover
def test_a_full_disk_stops_the_recording_and_the_complete_chunks_come_back(tmp_path, monkeypatch):
    monkeypatch.setattr(recording, "BagFile", FullDisk)
    monkeypatch.setattr(FullDisk, "budget", 60_000)  # about 15 chunks, then the disk is full
    rng = random.Random(1)
    rec = BagRecorder(tmp_path / "bag", [STATE], chunk_size=CHUNK, flush_s=3600.0)
    messages = [_state(i, rng) for i in range(3000)]
    for i, data in enumerate(messages):
        rec.write("/drive_state", i + 1, data)
    wait_for(lambda: rec.failed, "the writer reporting the full disk")
    for _ in range(100):
        rec.write("/drive_state", 10**9, messages[0])  # a cheap no-op now
    assert rec.close() == tmp_path / "bag"
    assert rec.close() == tmp_path / "bag"  # idempotent
    _check_failed_bag(rec, "No space left on device")
    assert rec.file.stat().st_size <= 60_000

    result = _recover(rec.folder)
    assert result.returncode == 0, result.stderr
    assert f"{rec.on_disk} messages kept in {rec.file}" in result.stdout
    assert check_bag(rec.folder) == {"/drive_state": rec.on_disk}
    kept = _recorded_indices(rec.folder)
    assert kept == list(range(len(kept)))  # every message up to the failure, in order
    per_chunk = math.ceil(CHUNK / len(messages[0])) + 1
    assert len(kept) >= sum(rec.counts.values()) - per_chunk  # at most the chunk in progress is lost
    assert len(kept) > 10 * per_chunk


@needs_recover
def test_a_disk_that_fails_while_the_bag_is_finished_leaves_it_for_recovery(tmp_path, monkeypatch):
    monkeypatch.setattr(recording, "BagFile", FullDisk)
    rng = random.Random(2)
    rec = BagRecorder(tmp_path / "bag", [STATE], custom_data={"clock_origin_ns": "0"}, chunk_size=CHUNK, flush_s=0.05)
    for i in range(50):
        rec.write("/drive_state", i + 1, _state(i, rng))
    wait_for(lambda: rec.on_disk == 50, "50 messages on the disk")
    monkeypatch.setattr(FullDisk, "budget", rec.file.stat().st_size + 100)  # the summary does not fit
    rec.close()
    _check_failed_bag(rec, "No space left on device")
    assert rec.on_disk == 50
    result = _recover(rec.folder)
    assert result.returncode == 0 and "50 messages kept" in result.stdout, result.stderr
    assert _recorded_indices(rec.folder) == list(range(50))


def test_an_fsync_error_cuts_the_file_back_to_the_last_synced_chunk(tmp_path, monkeypatch):
    monkeypatch.setattr(recording, "BagFile", FailingSync)
    monkeypatch.setattr(FailingSync, "calls", 0)
    monkeypatch.setattr(FailingSync, "ok", 6)  # the header, then five chunks
    rng = random.Random(3)
    rec = BagRecorder(tmp_path / "bag", [STATE], chunk_size=CHUNK, flush_s=3600.0)
    for i in range(1000):
        rec.write("/drive_state", i + 1, _state(i, rng))
    wait_for(lambda: rec.failed, "the writer reporting the failure")
    rec.close()
    _check_failed_bag(rec, "Input/output error")
    found = salvage(rec.file.read_bytes())
    assert len(found.messages) == rec.on_disk > 0  # what was synced is there, and nothing after it
    kept = [round(deserialize_message(m[4], DriveState).rod_position_m) for m in found.messages]
    assert kept == list(range(rec.on_disk))


@pytest.fixture
def small_disk(tmp_path):
    """A real 64 KiB tmpfs: its writes fail with ENOSPC when it is full."""
    with small_tmpfs(tmp_path / "disk", "64k") as disk:
        yield disk


@needs_recover
def test_a_real_full_disk_then_recovery_on_it_then_a_rerun_with_space(small_disk):
    rng = random.Random(4)
    rec = BagRecorder(small_disk / "bag", [STATE], chunk_size=CHUNK, flush_s=3600.0)
    for i in range(3000):  # about 450 KiB of messages (compressed: over 100 KiB) for 64 KiB of disk
        rec.write("/drive_state", i + 1, _state(i, rng))
    wait_for(lambda: rec.failed, "the writer reporting the failure")
    rec.close()
    _check_failed_bag(rec, "No space left on device")
    assert rec.on_disk > 100

    before = {p.name: p.read_bytes() for p in rec.folder.iterdir()}
    full = _recover(rec.folder)  # no room for the recovered copy
    assert full.returncode == 1 and full.stdout == "", full.stdout
    (line,) = full.stderr.strip().splitlines()
    assert line.startswith(f"boom-bag-recover: error: {rec.file}: No space left on device; nothing was changed")
    assert {p.name: p.read_bytes() for p in rec.folder.iterdir()} == before  # as it was: no .partial, no .damaged

    subprocess.run(["mount", "-o", "remount,size=2m", small_disk], check=True)
    again = _recover(rec.folder)
    assert again.returncode == 0, again.stderr
    assert check_bag(rec.folder) == {"/drive_state": rec.on_disk}
    assert _recorded_indices(rec.folder) == list(range(rec.on_disk))
