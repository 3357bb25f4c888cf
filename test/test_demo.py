"""boom-demo as a user meets it: stopped from a terminal, terminated, killed, on a full disk.

Each test starts boom-demo in a session of its own (as a terminal's job), waits for the first
row of its table (the node runs and records), then does what the user does.
"""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from bag_checks import check_bag
from conftest import CONFIG

DEMO = shutil.which("boom-demo")
pytestmark = pytest.mark.skipif(DEMO is None, reason="boom-demo not on PATH (run through tools/with-env)")
HEADER = " t [s]  opening"


def _start(bags: Path, *extra: str) -> subprocess.Popen:
    args = [DEMO, "--params-file", str(CONFIG / "default.yaml"), "--duration", "60", "--bags", str(bags), *extra]
    return subprocess.Popen(
        args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True, bufsize=1
    )


def _wait_for_first_row(demo: subprocess.Popen) -> list[str]:
    """The stdout lines up to the table's first row: from then on the scenario runs."""
    lines = []
    for line in demo.stdout:
        lines.append(line)
        if len(lines) >= 2 and lines[-2].startswith(HEADER):
            return lines
    pytest.fail(f"boom-demo ended before its first row: {lines} {demo.stderr.read()}")


@pytest.fixture
def demo(tmp_path) -> Iterator[subprocess.Popen]:
    proc = _start(tmp_path / "bags")
    _wait_for_first_row(proc)
    yield proc
    if proc.poll() is None:  # a failed test: stop it and its node
        os.killpg(proc.pid, signal.SIGINT)
        proc.communicate(timeout=60)


def _errors(stderr: str) -> list[str]:
    assert "Traceback" not in stderr, stderr
    return [line for line in stderr.splitlines() if "error:" in line]


def _one_finished_bag(bags: Path) -> Path:
    (bag,) = bags.glob("*_boom_sim")
    assert (bag / "metadata.yaml").is_file(), "the bag was not finished"
    assert check_bag(bag)["/drive_state"] > 0
    return bag


@pytest.mark.parametrize(
    ("send", "name", "status"),
    [
        (lambda proc: os.killpg(proc.pid, signal.SIGINT), "SIGINT", 130),  # Ctrl-C: the terminal signals the group
        (lambda proc: proc.send_signal(signal.SIGTERM), "SIGTERM", 143),  # as the exit table has it
    ],
    ids=["ctrl-c", "sigterm"],
)
def test_stopping_the_demo_finishes_the_bag_and_says_so_in_one_line(demo, tmp_path, send, name, status):
    send(demo)
    _, stderr = demo.communicate(timeout=60)
    assert demo.returncode == status, stderr
    bag = _one_finished_bag(tmp_path / "bags")
    assert _errors(stderr) == [
        f"boom-demo: error: stopped by {name}; the run so far is in {bag} (boom-analyze analyses it)"
    ]


@pytest.mark.skipif(not os.uname().sysname == "Linux", reason="the node follows its parent through Linux's prctl")
def test_a_killed_demo_takes_its_node_along_and_the_bag_is_finished(demo, tmp_path):
    demo.kill()
    demo.wait()
    # the node holds boom-demo's stdout until it ends: its end of file is the node's end
    rest = demo.stdout.read()
    assert "boom_sim: bag " in rest, rest
    _one_finished_bag(tmp_path / "bags")


def test_a_bad_params_file_is_the_nodes_one_line_and_exit_2(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("/**:\n  ros__parameters:\n    payload_mass_kgg: 80.0\n")
    result = subprocess.run(
        [DEMO, "--params-file", str(bad), "--bags", str(tmp_path / "bags")], capture_output=True, text=True, timeout=120
    )
    assert result.returncode == 2, result.stderr
    output = result.stdout + result.stderr
    assert "Traceback" not in output
    errors = [line for line in output.splitlines() if "error:" in line]
    assert len(errors) == 1 and "unknown parameter 'payload_mass_kgg'" in errors[0], output


@pytest.fixture
def full_disk(tmp_path) -> Iterator[Path]:
    """A 64 KiB file system, filled."""
    if os.geteuid() != 0:
        pytest.skip("mounting a small full file system needs root")
    mount = tmp_path / "full"
    mount.mkdir()
    subprocess.run(["mount", "-t", "tmpfs", "-o", "size=64k", "tmpfs", str(mount)], check=True)
    try:
        fd = os.open(mount / "filler", os.O_WRONLY | os.O_CREAT)
        try:
            while True:
                os.write(fd, b"\0" * 4096)
        except OSError:
            pass
        finally:
            os.close(fd)
        yield mount
    finally:
        subprocess.run(["umount", str(mount)], check=True)


def test_bags_on_a_full_disk_end_in_one_line_and_exit_1(full_disk):
    result = subprocess.run(
        [DEMO, "--params-file", str(CONFIG / "default.yaml"), "--bags", str(full_disk / "bags")],
        capture_output=True,
        text=True,
        timeout=120,
    )
    output = result.stdout + result.stderr
    assert result.returncode == 1, output
    errors = _errors(output)
    assert len(errors) == 1 and "No space left on device" in errors[0], output


def _payload_changes(bag: Path) -> list[float]:
    """The payload_mass_kg values the bag's /parameter_events announce, in order."""
    from rosbags.highlevel import AnyReader

    with AnyReader([bag]) as reader:
        events = [c for c in reader.connections if c.topic == "/parameter_events"]
        return [
            p.value.double_value
            for connection, _, raw in reader.messages(connections=events)
            for p in reader.deserialize(raw, connection.msgtype).changed_parameters
            if p.name == "payload_mass_kg"
        ]


def test_the_loader_cycle_moves_the_boom_by_goals_and_releases_the_payload(tmp_path):
    """The loader work cycle through the node's own interfaces, up to just past the release:
    lift 25 degrees, lower back to the ground, payload off (10.5 s of the 18.5)."""
    from boom_hydraulics.bags.reading import read_drive_states

    bags = tmp_path / "bags"
    result = subprocess.run(
        [DEMO, "--params-file", str(CONFIG / "default.yaml"), "--scenario", "loader", "--duration", "10.5",
         "--bags", str(bags)],
        capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    assert _errors(result.stderr) == []
    bag = _one_finished_bag(bags)
    states = read_drive_states(bag)
    alpha = np.degrees(states["alpha"])
    ground = alpha[0]
    assert np.max(alpha) == pytest.approx(ground + 25.0, abs=1.0)  # the lift's goal, held
    after_lift = alpha[np.argmax(alpha) :]
    assert np.min(after_lift) == pytest.approx(ground, abs=1.0)  # lowered to the ground ...
    assert alpha[-1] > ground + 3.0  # ... and the empty lift has begun
    assert _payload_changes(bag) == [0.0]  # released: the whole payload off
    assert "battery" in result.stdout  # boom-analyze read the energy ledger the bag keeps


@pytest.mark.parametrize(
    ("extra", "says"),
    [
        (["--scenario", "unloader"], "unknown --scenario 'unloader'"),
        (["--scenario", "loader:x"], "loader:SEED with SEED a whole number"),
        (["--scenario", "loader", "--params-file", str(CONFIG / "paper_fig8.yaml")], "needs mode: physical"),
    ],
)
def test_a_scenario_the_node_cannot_run_is_one_line_and_exit_2_before_it_starts(tmp_path, extra, says):
    result = subprocess.run(
        [DEMO, "--bags", str(tmp_path / "bags"), *extra], capture_output=True, text=True, timeout=120
    )
    assert result.returncode == 2, result.stderr
    (error,) = _errors(result.stderr)
    assert says in error
    assert not (tmp_path / "bags").exists()  # the node never started
