"""Shared test setup: isolate ROS traffic of this test run in its own DDS domain."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
CONFIG = ROOT / "config"

# One DDS domain per test run, so that a node left running elsewhere on the machine
# (make run, another checkout's tests) does not talk to these tests.
os.environ.setdefault("ROS_DOMAIN_ID", str(100 + os.getpid() % 100))
os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")


@pytest.fixture
def python_exe() -> str:
    return sys.executable


BOOM_SIM = shutil.which("boom_sim")


def start_node(*params: str, config_file: str = "default.yaml", record: bool = False) -> subprocess.Popen:
    """boom_sim through its real entry point, with ``-p`` parameters; recording off unless asked."""
    args = [BOOM_SIM, "--ros-args", "--params-file", str(CONFIG / config_file)]
    if not record:
        args += ["-p", "record:=false"]
    for p in params:
        args += ["-p", p]
    return subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)


def stop_process(proc: subprocess.Popen) -> str:
    """SIGINT (as Ctrl-C), a kill if it has not ended within 10 s; what it printed, if piped."""
    if proc.poll() is None:
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
    return proc.stdout.read() if proc.stdout and not proc.stdout.closed else ""


@pytest.fixture
def node() -> Iterator[subprocess.Popen]:
    """boom_sim (default config, 0.5 s command timeout, no recording), stopped after the test."""
    proc = start_node("command_timeout_s:=0.5")
    yield proc
    stop_process(proc)


@pytest.fixture(scope="module")
def ros_context() -> Iterator[None]:
    """rclpy initialised for the tests of one module that talk to a node."""
    rclpy = pytest.importorskip("rclpy")
    rclpy.init()
    yield
    rclpy.shutdown()


@pytest.fixture
def client(ros_context):
    """The test's side of the ROS graph (see ros_client.Client), for the default /boom_sim."""
    from ros_client import Client

    c = Client()
    yield c
    c.node.destroy_node()
