"""A node recording onto a disk that fills up: it goes on simulating and publishing, stops
recording with one error line and a /diagnostics error, ends on SIGINT, and leaves a bag
that boom-bag-recover brings back up to its last complete chunk."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess

import pytest
from conftest import BOOM_SIM, small_tmpfs

rclpy = pytest.importorskip("rclpy")

RECOVER = shutil.which("boom-bag-recover")
pytestmark = [
    pytest.mark.usefixtures("ros_context"),
    pytest.mark.skipif(BOOM_SIM is None or RECOVER is None, reason="run through tools/with-env"),
    pytest.mark.skipif(os.geteuid() != 0, reason="mounting a small tmpfs (a disk that fills up) needs root"),
]
ERROR = b"\x02"


@pytest.fixture
def small_disk(tmp_path):
    """A 300 KiB file system: a node's bag fills it within seconds."""
    with small_tmpfs(tmp_path / "disk", "300k") as disk:
        yield disk


def _recording_status(client):
    for array in reversed(client.diagnostics):
        for status in array.status:
            if status.name.endswith("recording"):
                return status
    return None


def test_a_full_disk_stops_the_recording_not_the_run_and_the_bag_is_recoverable(nodes, client, small_disk):
    proc = nodes.start(f"record_folder:={small_disk}", "record_chunk_kib:=16", "record_flush_s:=0.2", record=True)
    try:
        assert client.spin_until(lambda: (s := _recording_status(client)) is not None and s.level == ERROR, 120)
        failed_at = len(client.states)
        assert client.spin_until(lambda: len(client.states) > failed_at + 20, 30)  # it goes on publishing
    finally:
        proc.send_signal(signal.SIGINT)
        out, _ = proc.communicate(timeout=60)
    assert "No space left on device" in _recording_status(client).message
    assert proc.returncode == 1, out
    assert "Traceback" not in out
    assert out.count("[boom_sim]: recording stopped:") == 1, out  # the node's one error line while it runs
    assert "boom_sim: error: recording failed:" in out
    (bag,) = small_disk.iterdir()
    assert not (bag / "metadata.yaml").exists()  # left for boom-bag-recover
    subprocess.run(["mount", "-o", "remount,size=8m", str(small_disk)], check=True)
    result = subprocess.run([RECOVER, str(bag)], capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    kept = int(result.stdout.split(" messages kept")[0].split()[-1])
    assert kept > 100, result.stdout
    assert (bag / "metadata.yaml").is_file()


def test_a_bag_that_cannot_start_on_a_shared_clock_ends_the_node_in_one_line(nodes, small_disk):
    """Under use_sim_time the bag starts at the first /clock: on a disk without room the node
    ends with one line and status 1, as it does on its own clock at start (it stepped on with
    'simulation stopped, waiting for ~/reset', for ever)."""
    import sys
    from pathlib import Path

    from conftest import stop_process

    # the disk full before the node starts (dd stops at "No space left on device")
    subprocess.run(["dd", "if=/dev/zero", f"of={small_disk / 'filler'}", "bs=4k"], capture_output=True)
    assert shutil.disk_usage(small_disk).free < 4096
    proc = nodes.start("use_sim_time:=true", f"record_folder:={small_disk}", record=True)
    clock_source = Path(__file__).with_name("clock_source.py")  # /clock from a process of its own
    source = subprocess.Popen([sys.executable, str(clock_source), "5.0", "1.0:60"], stdout=subprocess.DEVNULL)
    try:
        out, _ = proc.communicate(timeout=120)  # ends by itself once the clock has come
    finally:
        stop_process(source)
    assert proc.returncode == 1, out
    assert "Traceback" not in out and "waiting for ~/reset" not in out
    (line,) = [line for line in out.splitlines() if line.startswith("boom_sim: error:")]
    assert "No space left on device" in line, out
