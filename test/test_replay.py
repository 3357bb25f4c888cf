"""boom-replay publishes a bag's messages on their topics, in order and with their spacing."""

from __future__ import annotations

import shutil
import signal
import subprocess
import time
from collections.abc import Callable, Iterator

import numpy as np
import pytest
from conftest import GUARD_S, run_tool

rclpy = pytest.importorskip("rclpy")
from rclpy.qos import QoSProfile, ReliabilityPolicy  # noqa: E402
from rclpy.serialization import serialize_message  # noqa: E402
from rosgraph_msgs.msg import Clock  # noqa: E402

from boom_hydraulics.bags.recording import BagRecorder, Topic, offered_qos  # noqa: E402
from boom_hydraulics_msgs.msg import DriveState, ValveCommand  # noqa: E402

BOOM_REPLAY = shutil.which("boom-replay")
pytestmark = pytest.mark.skipif(BOOM_REPLAY is None, reason="boom-replay not on PATH")


def _bag(folder):
    topics = [
        Topic("/drive_state", "boom_hydraulics_msgs/msg/DriveState"),
        Topic("/valve_command", "boom_hydraulics_msgs/msg/ValveCommand"),
    ]
    with BagRecorder(folder, topics) as rec:
        for i in range(60):  # 0.59 s of states, 10 ms apart
            msg = DriveState(rod_position_m=1.3 + i * 1e-3)
            msg.header.stamp.nanosec = i * 10_000_000
            rec.write("/drive_state", i * 10_000_000, serialize_message(msg))
        rec.write("/valve_command", 5_000_000, serialize_message(ValveCommand(opening=0.5)))


@pytest.fixture
def listener() -> Iterator:
    """rclpy, and a node of the test's own to listen with (each test starts rclpy: the refusals
    run boom-replay's main in this process, and it starts rclpy itself)."""
    rclpy.init()
    node = rclpy.create_node("replay_listener")
    yield node
    node.destroy_node()
    rclpy.shutdown()


@pytest.fixture
def start_replay() -> Iterator[Callable[..., subprocess.Popen]]:
    """Start a real boom-replay process (stdout and stderr piped); any still running after the
    test is killed."""
    started: list[subprocess.Popen] = []

    def start(*args: object) -> subprocess.Popen:
        proc = subprocess.Popen(
            [BOOM_REPLAY, *map(str, args)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
        )
        started.append(proc)
        return proc

    yield start
    for proc in started:
        if proc.poll() is None:
            proc.kill()
        proc.communicate()


def _spin_until(node, done: Callable[[], bool], what: str) -> None:
    """Spin the listener until ``done()`` (an event), failing after the guard."""
    deadline = time.monotonic() + GUARD_S
    while not done():
        assert time.monotonic() < deadline, f"{what}: not within {GUARD_S:g} s"
        rclpy.spin_once(node, timeout_sec=0.02)


def _replay(*args: object) -> subprocess.CompletedProcess:
    """boom-replay's main in this process (conftest.run_tool), for what it refuses or does alone."""
    return run_tool("boom-replay", *args)


def test_replay_publishes_every_message_in_order_with_its_spacing(tmp_path, listener, start_replay):
    _bag(tmp_path / "run")
    received: list[tuple[float, float]] = []
    qos = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
    listener.create_subscription(
        DriveState, "/drive_state", lambda m: received.append((time.monotonic(), m.rod_position_m)), qos
    )
    started = time.monotonic()
    waiting = ("--wait-for-subscribers", "--wait-timeout", GUARD_S)  # a guard far above any discovery
    proc = start_replay(tmp_path / "run", "--topics", "/drive_state", "--rate", "0.5", *waiting)
    _spin_until(listener, lambda: proc.poll() is not None, "boom-replay's end")
    ran_s = time.monotonic() - started
    _spin_until(listener, lambda: len(received) >= 60, "the 60 states")
    out, err = proc.communicate(timeout=10)
    assert proc.returncode == 0, err
    assert "published 60 messages" in out
    assert [round(q, 6) for _, q in received] == [round(1.3 + i * 1e-3, 6) for i in range(60)]
    # 0.59 s of recording at rate 0.5 takes at least 1.18 s (a lower bound: load only adds time).
    # Measured over the replay's run: DDS may deliver the first messages late, in a burst, so
    # the spacing of their arrival is no lower bound; the typical spacing is 10 ms / 0.5.
    assert ran_s >= 1.18
    assert np.median(np.diff([t for t, _ in received])) >= 0.9 * 0.02


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["nope"], "no such bag folder or file"),
        (["empty"], "not a bag: the folder has no .mcap file"),
        (["BAG", "--topics", "/missing"], "no topic /missing"),
        (["BAG", "--wait-for-subscribers", "--wait-timeout", "0.5"], "no subscriber appeared within 0.5 s"),
    ],
)
def test_replay_errors_are_one_line(tmp_path, args, message):
    _bag(tmp_path / "run")
    (tmp_path / "empty").mkdir()
    args = [str(tmp_path / "run") if a == "BAG" else str(tmp_path / a) if a in ("nope", "empty") else a for a in args]
    result = _replay(*args)
    assert result.returncode == 1
    assert message in result.stderr and "Traceback" not in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1


def _sparse_bag(folder, clock: bool = False):
    """Messages 20 s apart, a command and then a drive state (stamped with its bag time); a
    best-effort command topic; an empty topic; /clock if asked."""
    topics = [
        Topic("/drive_state", "boom_hydraulics_msgs/msg/DriveState"),
        Topic("/valve_command", "boom_hydraulics_msgs/msg/ValveCommand", (offered_qos(reliable=False),)),
        Topic("/never", "boom_hydraulics_msgs/msg/ValveCommand"),  # recorded, but no message
    ]
    if clock:
        topics.append(Topic("/clock", "rosgraph_msgs/msg/Clock"))
    with BagRecorder(folder, topics) as rec:
        for i in range(3):
            state = DriveState()
            state.header.stamp.sec = i * 20
            rec.write("/valve_command", i * 20_000_000_000, serialize_message(ValveCommand()))
            rec.write("/drive_state", i * 20_000_000_000 + 1, serialize_message(state))  # after it
            if clock:
                rec.write("/clock", i * 20_000_000_000, serialize_message(Clock()))


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_a_signal_stops_replay_between_widely_spaced_messages(tmp_path, listener, start_replay, sig):
    _sparse_bag(tmp_path / "run")
    got = []
    qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.BEST_EFFORT)
    listener.create_subscription(DriveState, "/drive_state", got.append, qos)
    listener.create_subscription(ValveCommand, "/valve_command", got.append, qos)
    # it waits for these subscribers (the guard far above any discovery); on a loaded machine
    # the listener may still miss the best-effort messages of t = 0 (the replay saw it before it
    # had matched the replay) and meet those of t = 20 s first: the drive state's stamp says which
    # (the last of its pair: the command went before it)
    proc = start_replay(tmp_path / "run", "--wait-for-subscribers", "--wait-timeout", GUARD_S)
    states = lambda: [m for m in got if isinstance(m, DriveState)]  # noqa: E731
    _spin_until(listener, lambda: len(states()) > 0, "the first drive state")
    sent = time.monotonic()  # it is waiting 20 s for the next messages now
    proc.send_signal(sig)
    out, err = proc.communicate(timeout=20)
    # it waits in 50 ms slices; a bound far below the 20 s gap, loose for a loaded machine
    assert time.monotonic() - sent < 5.0
    assert proc.returncode == 0 and "Traceback" not in err
    pairs = states()[0].header.stamp.sec // 20 + 1  # the drive state and command of each 20 s
    assert f"published {2 * pairs} messages" in out


def test_replay_waits_for_subscribers_by_default(tmp_path, start_replay):
    """As a user meets it: start boom-replay, then the listener; no message is lost to discovery."""
    _bag(tmp_path / "run")
    proc = start_replay(tmp_path / "run", "--topics", "/drive_state")
    rclpy.init()
    node = rclpy.create_node("late_listener")
    received: list[float] = []
    qos = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
    try:
        node.create_subscription(DriveState, "/drive_state", lambda m: received.append(m.rod_position_m), qos)
        _spin_until(node, lambda: proc.poll() is not None and len(received) >= 60, "the replay of 60 states")
    finally:
        node.destroy_node()
        rclpy.shutdown()
    out, err = proc.communicate(timeout=10)
    assert proc.returncode == 0, err
    assert len(received) == 60 and "published 60 messages" in out


def test_replay_without_waiting_and_without_subscribers_replays_at_once(tmp_path):
    _bag(tmp_path / "run")
    result = _replay(tmp_path / "run", "--no-wait")
    assert result.returncode == 0, result.stderr
    assert "published 61 messages" in result.stdout and "note" not in result.stderr


def test_replay_without_subscribers_replays_after_the_wait_with_a_note(tmp_path):
    _bag(tmp_path / "run")
    result = _replay(tmp_path / "run", "--wait-timeout", "0.2")
    assert result.returncode == 0, result.stderr
    assert "note: no subscriber on" in result.stderr and "replaying anyway" in result.stderr
    assert "published 61 messages" in result.stdout


@pytest.mark.parametrize(
    ("args", "option"),
    [
        (["--start", "inf"], "--start inf"),
        (["--start", "nan"], "--start nan"),
        (["--start", "-1"], "--start -1"),
        (["--rate", "0"], "--rate 0"),
        (["--rate", "inf"], "--rate inf"),
        (["--rate", "nan"], "--rate nan"),
        (["--wait-timeout=-inf"], "--wait-timeout -inf"),
        (["--wait-timeout", "0"], "--wait-timeout 0"),
        (["--start", "5"], "--start 5 s is past the bag's end"),
        (["--rate", "fast"], "invalid float value"),
        (["--no-wait", "--wait-for-subscribers"], "not allowed with argument"),
    ],
)
def test_bad_numbers_are_refused_in_one_line(tmp_path, args, option):
    _bag(tmp_path / "run")
    result = _replay(tmp_path / "run", *args)
    assert result.returncode == 2, result.stderr
    assert option in result.stderr and "Traceback" not in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1 and result.stderr.startswith("boom-replay: error: ")


def test_replay_offers_the_recorded_qos_and_one_clock(tmp_path, listener, start_replay):
    _sparse_bag(tmp_path / "run", clock=True)
    proc = start_replay(tmp_path / "run", "--clock", "--wait-for-subscribers", "--wait-timeout", "60")
    qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.BEST_EFFORT)
    got = []  # subscribers on the topics with messages (not /never): replay starts
    listener.create_subscription(DriveState, "/drive_state", got.append, qos)
    listener.create_subscription(ValveCommand, "/valve_command", got.append, qos)
    listener.create_subscription(Clock, "/clock", got.append, qos)
    _spin_until(listener, lambda: len(got) >= 3 or proc.poll() is not None, "the replay's start")
    assert len(got) >= 3, f"replay did not start: it waited for /never ({proc.communicate()[1]})"
    offers = {t: [i.qos_profile.reliability for i in listener.get_publishers_info_by_topic(t)] for t in TOPICS}
    proc.send_signal(signal.SIGINT)
    proc.communicate(timeout=20)
    assert offers["/drive_state"] == [ReliabilityPolicy.RELIABLE]
    assert offers["/valve_command"] == [ReliabilityPolicy.BEST_EFFORT]  # as its publisher offered
    assert len(offers["/clock"]) == 1  # the bag's own, not a second one from --clock


TOPICS = ("/drive_state", "/valve_command", "/clock")
