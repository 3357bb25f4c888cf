"""Shared test setup: each test process talks ROS in a DDS domain of its own, and under
pytest-xdist the compiled kernels are built once before the workers start. Nodes a test starts
are stopped after it (``nodes``), or shared by the tests of a class (``shared_node``,
``node_at_rest``); a tool's refusals run its main in the test process (``run_tool``); waits are
for events, with a guard (``wait_for``, ``GUARD_S``)."""

from __future__ import annotations

import contextlib
import fcntl
import io
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ThreadPoolExecutor
from importlib.metadata import entry_points
from pathlib import Path
from typing import IO, Any

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

# The tests that stop a program with Ctrl-C send SIGINT to this process or to those it starts: a
# test run started with SIGINT ignored (a background job of a script, `make test &`, nohup), which
# every process it starts inherits, would see none of them act. Python's own handler is put back
# here (and a handled signal is SIGINT's default action again in a program the tests start).
if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)


#: What the node compiles at its start (ros/node.py warms a new model or method the same way):
#: Simulator.warm, its stepping, its outputs and the run loop of its position controller.
STEPPING = (
    "import sys\n"
    "from boom_hydraulics.model import config\n"
    "from boom_hydraulics.model.parameters import with_updates\n"
    "from boom_hydraulics.solve.simulation import Simulator\n"
    "Simulator(with_updates(config.load(sys.argv[1]), method=sys.argv[2]), jit=True).warm()\n"
)

#: What builds every compiled kernel the suite uses, two lanes run side by side, each kernel
#: in one lane only (two processes compiling one kernel at once do the work twice): the
#: whole-run kernels through the real tools (so the kernels get the types the tests give
#: them), the stepping kernels as the node builds them (:data:`STEPPING`).
WARM_UP_LANES = (
    (  # the physical model's rk4 and euler run kernels (setup compiled rk4), its stepping, outputs
        ("boom-sim", "run", "--config", CONFIG / "default.yaml", "--duration", "0.01"),
        ("stepping", CONFIG / "default.yaml", "rk4"),
        ("boom-sim", "run", "--config", CONFIG / "default.yaml", "--duration", "0.01", "--target-angle-deg", "5"),
        ("boom-sweep", "--duration", "0.2", "--vary", "piston_diameter=0.05,0.06", "--no-plots", "--no-progress"),
        ("boom-sim", "run", "--config", CONFIG / "default.yaml", "--duration", "0.01", "--method", "euler"),
        ("stepping", CONFIG / "default.yaml", "euler"),
    ),
    (  # the paper model's run kernel and stepping, the physical model's ros2 stepping (make setup
        # compiled the blocks of sets in lock-step that batches of 4 sets and more run, for rk4)
        ("boom-sim", "run", "--config", CONFIG / "paper_fig8.yaml", "--duration", "0.01"),
        ("stepping", CONFIG / "paper_fig8.yaml", "rk4"),
        ("boom-sim", "run", "--config", CONFIG / "default.yaml", "--duration", "0.01", "--method", "ros2"),
        # the physical model's rk4 with its elements' states (the 1 t crane's hoses, accumulator
        # and elastic boom): its whole-run kernel and its stepping
        ("boom-sim", "run", "--config", CONFIG / "loader_crane_1t.yaml", "--duration", "0.01"),
        ("stepping", CONFIG / "loader_crane_1t.yaml", "rk4"),
    ),
)


def _warm_up_lane(commands: tuple[tuple, ...], folder: Path) -> list[str]:
    """Run one lane's commands in turn; what failed (the tests then compile for themselves)."""
    failed = []
    for n, (tool, *args) in enumerate(commands):
        if tool == "stepping":
            argv = [sys.executable, "-c", STEPPING, *map(str, args)]
        elif (exe := shutil.which(tool)) is None:
            failed.append(f"{tool} (not on PATH)")
            continue
        else:
            out = folder / f"{tool}-{n}"
            argv = [exe, *map(str, args), "--out", str(out if tool == "boom-sweep" else out.with_suffix(".csv"))]
        if subprocess.run(argv, capture_output=True, text=True).returncode != 0:
            failed.append(" ".join(map(str, [tool, *args])))
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


#: The test files that take longest (``--durations=0`` of a run on 2 busy cores: 20 s and more
#: each), longest first. They are handed to the workers before the others, so that no worker is
#: left running a long file while the rest are done; a file missing here only runs later.
#: test_demo_cycle.py, about 120 s of node runs on a quiet machine (the longest file), first.
LONGEST_FIRST = (
    "test_demo_cycle.py",
    "test_fmu.py",
    "test_calibrate_noisy.py",
    "test_fmu_in_process.py",
    "test_node.py",
    "test_sweep_cli.py",
    "test_calibrate.py",
    "test_python_page.py",
    "test_node_bags.py",
    "test_node_clock.py",
    "test_node_stamps.py",
    "test_node_motion.py",
    "test_stepping.py",
    "test_demo.py",
    "test_studies.py",
    "test_node_parameters.py",
    "test_tool_outputs.py",
    "test_resim_refusals.py",
    "test_resim.py",
    "test_live.py",
)


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """The files of :data:`LONGEST_FIRST` first, in its order, then the rest as collected; the
    tests of a file keep their order (pytest-xdist's loadfile hands out whole files in this order)."""
    rank = {name: k for k, name in enumerate(LONGEST_FIRST)}
    items.sort(key=lambda item: rank.get(item.path.name, len(rank)))


#: How long a wait for an event may take before the test fails, s: a guard, never a duration a
#: passing test waits (on a machine at load 15 a node took over 30 s to start).
GUARD_S = 120.0


def wait_for(condition: Callable[[], object], what: str, guard_s: float = GUARD_S) -> None:
    """Wait until ``condition()`` is true (an event: a thread's or another process's work),
    polling every 10 ms; fail naming ``what`` if it is not within the guard."""
    deadline = time.monotonic() + guard_s
    while not condition():
        assert time.monotonic() < deadline, f"{what}: not within {guard_s:g} s"
        time.sleep(0.01)


@pytest.fixture
def python_exe() -> str:
    return sys.executable


BOOM_SIM = shutil.which("boom_sim")


#: The node parameter every test node starts with, so that it keeps one time line on a loaded
#: machine (a bag boom-resim reproduces, a pace measured over seconds): work off a backlog of up
#: to 10 s rather than drop it. The default, 0.2 s, is a hiccup of a busy machine's scheduler, and
#: a dropped backlog moves the time origin of command stamps (CI failed so at load). A test about
#: dropping passes its own max_catch_up_s, which comes later and wins.
NO_DROPPED_BACKLOG = "max_catch_up_s:=10.0"


def start_node(
    *params: str, config_file: str | None = "default.yaml", record: bool = False, ros_args: Sequence[str] = ()
) -> subprocess.Popen:
    """boom_sim through its real entry point, with ``ros_args`` (``-r`` remaps), the params file
    from config/ (None: none) and ``-p`` parameters; recording off unless asked. The node holds
    this process's DDS domain claim as long as it runs (the lock's file descriptor is passed on),
    so a node that outlives its test process keeps the domain from another run's tests. It
    starts with :data:`NO_DROPPED_BACKLOG`."""
    args = [BOOM_SIM, "--ros-args", *ros_args, "-p", NO_DROPPED_BACKLOG]
    if config_file is not None:
        args += ["--params-file", str(CONFIG / config_file)]
    if not record:
        args += ["-p", "record:=false"]
    for p in params:
        args += ["-p", p]
    claims = tuple(lock.fileno() for lock in _domain_claim)
    return subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, pass_fds=claims)


def stop_process(proc: subprocess.Popen) -> str:
    """SIGINT (as Ctrl-C), a kill if it has not ended within 30 s; what it printed, if piped."""
    if proc.poll() is None:
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(timeout=30)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
    return proc.stdout.read() if proc.stdout and not proc.stdout.closed else ""


class Nodes:
    """The boom_sim processes of one test (:func:`start_node`), each stopped after the test
    however it ends: a node left running would answer the next test in this DDS domain."""

    def __init__(self) -> None:
        self.started: list[subprocess.Popen] = []

    def start(self, *params: str, **options: Any) -> subprocess.Popen:
        proc = start_node(*params, **options)
        self.started.append(proc)
        return proc

    def stop_all(self) -> None:
        for proc in self.started:
            stop_process(proc)


@pytest.fixture
def nodes() -> Iterator[Nodes]:
    """Start nodes in a test with ``nodes.start(...)`` (as :func:`start_node`); all stopped after it."""
    started = Nodes()
    yield started
    started.stop_all()


@pytest.fixture
def node(nodes: Nodes) -> subprocess.Popen:
    """boom_sim (default config, 0.5 s command timeout, no recording), stopped after the test."""
    return nodes.start("command_timeout_s:=0.5")


#: The opening of a handshake (ros_client.Client.handshake, :func:`node_at_rest`): too small to move the boom.
HANDSHAKE_OPENING = 1e-6

#: What the tests of a shared node start it with and put back before each (:func:`node_at_rest`).
SHARED_NODE_START = {"payload_mass_kg": 50.0, "external_rod_force_n": 0.0, "command_timeout_s": 0.5}  # (default.yaml's)


@pytest.fixture(scope="class")
def shared_node(ros_context) -> Iterator[subprocess.Popen]:
    """One boom_sim (default config, no recording, :data:`SHARED_NODE_START`) for the tests of a
    class, which take it through :func:`node_at_rest`: the tests of a class run one after the
    other on one worker, and no other /boom_sim runs meanwhile (the class's node is stopped
    before the file's next test). Stopped with SIGTERM, as a launch system stops a node, which
    must end it with status 0."""
    proc = start_node(*(f"{name}:={value}" for name, value in SHARED_NODE_START.items()))
    yield proc
    if proc.poll() is None:
        proc.send_signal(signal.SIGTERM)
    try:
        status = proc.wait(timeout=GUARD_S)
    finally:
        out = stop_process(proc)
    assert status == 0, f"the shared node ended with status {status} on SIGTERM: {out}"


@pytest.fixture
def node_at_rest(shared_node: subprocess.Popen, client) -> subprocess.Popen:
    """The class's shared node as a test finds a node it started itself: running, with the
    start parameters, acting on this test's commands (DDS discovery done both ways: a node just
    started takes longer to start than discovery takes), at rest (~/reset: valve closed, goals
    ended), publishing."""
    from std_srvs.srv import SetBool

    from boom_hydraulics_msgs.srv import Reset

    assert shared_node.poll() is None, f"the shared node has ended: {stop_process(shared_node)}"
    assert client.call(client.pause, SetBool.Request(data=False)).success
    for name, value in SHARED_NODE_START.items():
        assert client.set_parameter(name, value).successful, name

    client.handshake()  # the node acts on this client's commands, and none is left on the way
    assert client.call(client.reset, Reset.Request()).success
    client.states.clear()
    assert client.spin_until(lambda: len(client.states) > 5), "no drive_state from the shared node"
    return shared_node


def run_tool(tool: str, *args: object, cwd: Path | None = None) -> subprocess.CompletedProcess:
    """A command-line tool's ``main`` (its console script's entry point) run in this process,
    as its console script runs it (``sys.exit(main(argv))``): the exit status and what it
    printed, without the seconds of imports a new interpreter takes. The real console scripts
    are the tests' that send signals, start nodes or check what a new process does."""
    (entry,) = entry_points(group="console_scripts", name=tool)
    argv = [str(a) for a in args]
    out, err = io.StringIO(), io.StringIO()
    saved_argv, sys.argv = sys.argv, [tool, *argv]  # a program names itself after argv[0]
    try:
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err), contextlib.chdir(cwd or os.getcwd()):
            code = entry.load()(argv)
    except SystemExit as stop:  # argparse's --help
        code = stop.code if isinstance(stop.code, int) else (0 if stop.code is None else 1)
    finally:
        sys.argv = saved_argv
    return subprocess.CompletedProcess([tool, *argv], code, out.getvalue(), err.getvalue())


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


@contextlib.contextmanager
def small_tmpfs(disk: Path, size: str) -> Iterator[Path]:
    """A tmpfs of ``size`` (mount's ``size=``, e.g. ``300k``) mounted at the new folder ``disk``:
    a real disk that fills up (its writes fail with ENOSPC); the test is skipped where one cannot
    be mounted (not root, no tmpfs)."""
    if os.geteuid() != 0:
        pytest.skip("mounting a small tmpfs (a disk that fills up) needs root")
    disk.mkdir()
    mounted = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(disk)], capture_output=True)
    if mounted.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here: {mounted.stderr.decode().strip()}")
    try:
        yield disk
    finally:
        subprocess.run(["umount", "-l", str(disk)], check=False)
