"""Shared test setup: each test process talks ROS in a DDS domain of its own, and under
pytest-xdist the compiled kernels are built once before the workers start."""

from __future__ import annotations

import fcntl
import os
import shutil
import signal
import subprocess
import sys
import tempfile
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import IO

import pytest

ROOT = Path(__file__).resolve().parents[1]
CONFIG = ROOT / "config"

#: The DDS domains the tests may use: 100-199, clear of a user's usual 0 and of ROS's limit 232.
TEST_DOMAINS = range(100, 200)
_domain_claim: list[IO] = []


def claim_domain() -> int:
    """A DDS domain that no other test process on this machine holds, held until this process
    ends: an exclusive lock on a file per domain in the temporary folder, which the system
    releases when the process ends, however it ends. A domain from the pid alone (as before)
    let two test runs, or two xdist workers, with equal pids modulo 100 share a domain, and
    then each one's node answered the other's tests."""
    folder = Path(tempfile.gettempdir())
    start = os.getpid() % len(TEST_DOMAINS)
    for k in range(len(TEST_DOMAINS)):
        domain = TEST_DOMAINS[(start + k) % len(TEST_DOMAINS)]
        lock = open(folder / f"boom_hydraulics-test-domain-{domain}.lock", "a")  # held open: the lock lasts while it is
        try:
            fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            lock.close()
            continue
        _domain_claim.append(lock)
        return domain
    raise RuntimeError(f"every DDS domain of {TEST_DOMAINS} is held by another test process")


# One DDS domain per test process, so that a node left running elsewhere on the machine
# (make run, another checkout's tests, the other xdist worker) does not talk to these tests.
# A single process keeps a ROS_DOMAIN_ID given to it; an xdist worker always claims its own,
# since the workers inherit one environment and must not share a domain.
if "PYTEST_XDIST_WORKER" in os.environ or "ROS_DOMAIN_ID" not in os.environ:
    os.environ["ROS_DOMAIN_ID"] = str(claim_domain())
os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")


#: What builds every compiled kernel the suite uses, two lanes run side by side: each a list of
#: command lines run through the real tools (so the kernels get the types the tests give them).
WARM_UP_LANES = (
    (
        ("boom-sim", "run", "--config", CONFIG / "default.yaml", "--duration", "0.01"),
        ("boom-sim", "run", "--config", CONFIG / "default.yaml", "--duration", "0.01", "--target-angle-deg", "5"),
        ("boom-sim", "run", "--config", CONFIG / "paper_fig8.yaml", "--duration", "0.01"),
    ),
    (
        ("boom-sim", "run", "--config", CONFIG / "default.yaml", "--duration", "0.01", "--method", "euler"),
        ("boom-sim", "run", "--config", CONFIG / "default.yaml", "--duration", "0.01", "--method", "ros2"),
        ("boom-sweep", "--duration", "0.2", "--vary", "piston_diameter=0.05,0.06", "--no-plots", "--no-progress"),
    ),
)


def _warm_up_lane(commands: tuple[tuple, ...], folder: Path) -> list[str]:
    """Run one lane's commands in turn; what failed (the tests then compile for themselves)."""
    failed = []
    for n, (tool, *args) in enumerate(commands):
        exe = shutil.which(tool)
        out = folder / f"{tool}-{n}"
        argv = [exe, *map(str, args), "--out", str(out if tool == "boom-sweep" else out.with_suffix(".csv"))]
        if exe is None or subprocess.run(argv, capture_output=True, text=True).returncode != 0:
            failed.append(" ".join(argv[1:]) if exe else f"{tool} (not on PATH)")
    return failed


def pytest_sessionstart(session: pytest.Session) -> None:
    """Under pytest-xdist, build the compiled kernels once, in the controller, before the
    workers start: numba's cache is then warm for every worker and every tool a test starts.
    Otherwise two workers would compile the same kernel at once (safe, numba writes its cache
    by atomic renames, but twice the work on two cores), and a fresh clone's first compile
    (15 s idle, minutes on a loaded machine) would fall inside some test's timeout."""
    config = session.config
    if hasattr(config, "workerinput") or not config.getoption("numprocesses", default=None):
        return
    with tempfile.TemporaryDirectory(prefix="boom-warm-up-") as folder:
        with ThreadPoolExecutor(len(WARM_UP_LANES)) as pool:
            lanes = pool.map(_warm_up_lane, WARM_UP_LANES, [Path(folder)] * len(WARM_UP_LANES))
            failed = [line for lane in lanes for line in lane]
    if failed:
        reporter = config.pluginmanager.get_plugin("terminalreporter")
        if reporter is not None:
            reporter.write_line("kernel warm-up: failed (the tests compile for themselves): " + "; ".join(failed))


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
