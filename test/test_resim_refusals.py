"""boom-resim and boom-replay are never wrong in silence: what they refuse, in one line each,
and what an interrupted or killed boom-resim leaves behind (nothing, or nothing for long)."""

from __future__ import annotations

import fcntl
import os
import shutil
import signal
import subprocess
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from conftest import BOOM_SIM, run_tool, stop_process

rclpy = pytest.importorskip("rclpy")
from rclpy.serialization import serialize_message  # noqa: E402
from std_srvs.srv import SetBool  # noqa: E402

from boom_hydraulics.bags import recording  # noqa: E402
from boom_hydraulics.bags.reading import read_drive_states  # noqa: E402
from boom_hydraulics.bags.recording import BagRecorder, Topic, run_description  # noqa: E402
from boom_hydraulics.errors import RecordingError  # noqa: E402
from boom_hydraulics.model.parameters import from_mapping  # noqa: E402
from boom_hydraulics_msgs.msg import DriveState, ValveCommand  # noqa: E402
from boom_hydraulics_msgs.srv import Reset, Step  # noqa: E402

BOOM_RESIM = shutil.which("boom-resim")
BOOM_REPLAY = shutil.which("boom-replay")
pytestmark = pytest.mark.skipif(BOOM_RESIM is None or BOOM_REPLAY is None, reason="run through tools/with-env")

EVENT_TYPES = {
    "reset": ("boom_hydraulics_msgs/srv/Reset_Event", Reset.Event),
    "pause": ("std_srvs/srv/SetBool_Event", SetBool.Event),
    "step": ("boom_hydraulics_msgs/srv/Step_Event", Step.Event),
}
_SEP = "=" * 80 + "\n"
_INFO = (
    "uint8 event_type\nbuiltin_interfaces/Time stamp\nuint8[16] client_gid\nint64 sequence_number\n"
    f"{_SEP}MSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n"
)
_PARTS = {
    "boom_hydraulics_msgs/srv/Reset_Event": (
        "boom_hydraulics_msgs",
        "Reset",
        "bool use_rod_position\nfloat64 rod_position_m\n",
        "bool success\nstring message\n",
    ),
    "std_srvs/srv/SetBool_Event": ("std_srvs", "SetBool", "bool data\n", "bool success\nstring message\n"),
    "boom_hydraulics_msgs/srv/Step_Event": (
        "boom_hydraulics_msgs",
        "Step",
        "uint32 steps\n",
        "bool success\nstring message\nfloat64 sim_time_s\n",
    ),
}


def _event_definition(msgtype: str) -> str:
    """A ros2msg definition of a service event, for recorders that do not write them yet."""
    package, name, request, response = _PARTS[msgtype]
    return (
        f"service_msgs/ServiceEventInfo info\n{name}_Request[<=1] request\n{name}_Response[<=1] response\n"
        f"{_SEP}MSG: service_msgs/ServiceEventInfo\n{_INFO}"
        f"{_SEP}MSG: {package}/{name}_Request\n{request}{_SEP}MSG: {package}/{name}_Response\n{response}"
    )


@pytest.fixture
def event_topics(monkeypatch):
    """BagRecorder able to write the service event types: as it is, or taught here the definitions
    (no hash) until the recorder knows them."""
    try:
        recording.type_hash(EVENT_TYPES["reset"][0])
    except RecordingError:
        definition, type_hash = recording.message_definition, recording.type_hash
        monkeypatch.setattr(
            recording, "message_definition", lambda t: _event_definition(t) if t in _PARTS else definition(t)
        )
        monkeypatch.setattr(recording, "type_hash", lambda t: "" if t in _PARTS else type_hash(t))


def _event(service: str, at_ns: int, success: bool = True):
    msg = EVENT_TYPES[service][1]()
    msg.info.event_type = 2  # RESPONSE_SENT
    msg.info.stamp.sec, msg.info.stamp.nanosec = divmod(at_ns, 1_000_000_000)
    request = {"reset": Reset.Request(), "pause": SetBool.Request(data=True), "step": Step.Request(steps=1)}[service]
    response = {"reset": Reset.Response, "pause": SetBool.Response, "step": Step.Response}[service]()
    response.success = success
    msg.request, msg.response = [request], [response]
    return serialize_message(msg)


def synthetic_bag(
    folder: Path,
    origin_ns: int = 0,
    calls: tuple[tuple[str, float, bool], ...] = (),
    energy_drop_at_s: float | None = None,
    seconds: float = 2.0,
    backflow_at_s: float | None = None,
) -> Path:
    """A boom_sim-like bag: the run description, DriveState at 100 Hz (at rest, its supply
    energy rising, dropping to 0 at ``energy_drop_at_s``), one valve command, and the service
    calls (service, at s, successful) as the node records them."""
    params = from_mapping({})
    custom = run_description(params, origin_ns, 100.0, 0.5, node="/boom_sim")
    topics = [Topic("/drive_state", "boom_hydraulics_msgs/msg/DriveState")]
    topics.append(Topic("/valve_command", "boom_hydraulics_msgs/msg/ValveCommand"))
    topics += [Topic(f"/boom_sim/{s}/_service_event", EVENT_TYPES[s][0]) for s in sorted({c[0] for c in calls})]
    with BagRecorder(folder, topics, custom_data=custom) as rec:
        rec.write("/valve_command", origin_ns + 5_000_000, serialize_message(ValveCommand(opening=0.0)))
        for k in range(1, round(seconds * 100) + 1):
            t = k * 0.01
            stamp = origin_ns + k * 10_000_000
            msg = DriveState(rod_position_m=1.3, supply_energy_j=100.0 * t, valve_loss_energy_j=10.0 * t)
            if energy_drop_at_s is not None and t >= energy_drop_at_s - 1e-9:  # a reset zeroes both
                msg.supply_energy_j = 100.0 * (t - energy_drop_at_s)
                msg.valve_loss_energy_j = 10.0 * (t - energy_drop_at_s)
            if backflow_at_s is not None and t >= backflow_at_s - 1e-9:  # oil pushed back into the supply
                msg.supply_energy_j = 100.0 * backflow_at_s - 50.0 * (t - backflow_at_s)
            msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(stamp, 1_000_000_000)
            rec.write("/drive_state", stamp, serialize_message(msg))
        for service, at_s, success in calls:
            at_ns = origin_ns + round(at_s * 1e9)
            rec.write(f"/boom_sim/{service}/_service_event", at_ns, _event(service, at_ns, success))
    return folder


def resim(*args) -> subprocess.CompletedProcess:
    """boom-resim's main in this process (conftest.run_tool): its exit status and output."""
    return run_tool("boom-resim", *args)


def one_line(result: subprocess.CompletedProcess, prog: str = "boom-resim") -> str:
    err = result.stderr.strip()
    assert "Traceback" not in err and len(err.splitlines()) == 1, err
    assert err.startswith(f"{prog}: error: ")
    return err


ROS_TIME_NS = 1_760_000_000_000_000_000  # a stamp origin on ROS (wall) time


def test_a_reset_run_is_refused_naming_the_calls(tmp_path, event_topics):
    calls = (*(("reset", 0.5 + 0.1 * i, True) for i in range(12)), ("pause", 1.8, True))
    bag = synthetic_bag(tmp_path / "run", ROS_TIME_NS, calls)
    result = resim(bag, "--out", tmp_path / "out")
    assert result.returncode == 2
    err = one_line(result)
    assert "reset 12 times (~/reset, first at t = 0.500 s)" in err
    assert "paused or resumed once (~/pause" in err and "one continuous time line" in err
    assert "Record the run without resets" in err
    assert not (tmp_path / "out").exists()


def test_a_paused_and_stepped_run_on_ros_time_is_refused(tmp_path, event_topics):
    calls = (("pause", 0.5, True), ("step", 0.5, True), ("step", 0.5, True), ("pause", 0.6, True))
    bag = synthetic_bag(tmp_path / "run", ROS_TIME_NS, calls)
    result = resim(bag, "--out", tmp_path / "out")
    assert result.returncode == 2
    err = one_line(result)
    assert "paused or resumed twice (~/pause" in err and "stepped twice (~/step" in err
    assert "publish_clock:=true" in err


def test_pauses_and_steps_on_simulated_time_and_failed_calls_are_re_simulated(tmp_path, event_topics):
    """With publish_clock the stamps are simulated time: a pause or a step keeps the time line;
    a call that failed changed nothing."""
    calls = (("pause", 0.5, True), ("step", 0.5, True), ("pause", 0.6, True), ("reset", 1.0, False))
    bag = synthetic_bag(tmp_path / "run", 0, calls)
    result = resim(bag, "--out", tmp_path / "out")
    assert result.returncode == 0, result.stderr
    assert "200 drive states" in result.stdout


def test_a_reset_is_found_in_the_drive_states_of_an_older_bag(tmp_path):
    bag = synthetic_bag(tmp_path / "run", ROS_TIME_NS, energy_drop_at_s=1.5)
    result = resim(bag, "--out", tmp_path / "out")
    assert result.returncode == 2
    err = one_line(result)
    assert "appears to have been reset at t = 1.500 s" in err and "energy dissipated in its valve" in err
    assert not (tmp_path / "out").exists()


def test_supply_energy_pushed_back_is_no_reset(tmp_path):
    """Oil pushed back into the supply (the boom bouncing on its lower end stop, as at the end
    of make run) draws the supply energy down; only the valve's dissipation marks a reset."""
    bag = synthetic_bag(tmp_path / "run", ROS_TIME_NS, backflow_at_s=1.2)
    result = resim(bag, "--out", tmp_path / "out")
    assert result.returncode == 0, result.stderr


def test_a_bag_written_by_boom_resim_is_re_simulated(tmp_path):
    bag = synthetic_bag(tmp_path / "run")
    assert resim(bag, "--out", tmp_path / "once").returncode == 0
    result = resim(tmp_path / "once", "--set", "payload_mass_kg=150", "--out", tmp_path / "twice")
    assert result.returncode == 0, result.stderr
    assert len(read_drive_states(tmp_path / "twice")["t"]) == 200


@pytest.mark.parametrize(
    ("content", "message"),
    [
        (b"rosbag2_bagfile_information:\n  version: 9\xff\xfe\n", "is not UTF-8 text (byte 41 is 0xff)"),
        (b"rosbag2_bagfile_information: [unclosed\n", "is not valid YAML at line 2"),
        (b"- just\n- a list\n", "no rosbag2_bagfile_information mapping"),
        (b"rosbag2_bagfile_information:\n  version: nine\n", "version is missing or not an int"),
        # a RecursionError traceback
        (b"rosbag2_bagfile_information: " + b"[" * 100_000 + b"]" * 100_000 + b"\n", "nested deeper than can be read"),
    ],
)
@pytest.mark.parametrize("tool", ["boom-resim", "boom-replay"])
def test_a_damaged_metadata_yaml_is_one_line(tmp_path, content, message, tool):
    bag = synthetic_bag(tmp_path / "run")
    (bag / "metadata.yaml").write_bytes(content)
    result = run_tool(tool, bag, *(["--out", tmp_path / "out"] if tool == "boom-resim" else ["--no-wait"]))
    assert result.returncode == 1
    err = one_line(result, tool)
    assert message in err and "read its MCAP file" in err
    # the fix it names works: the .mcap file alone carries the same metadata
    (mcap,) = bag.glob("*.mcap")
    if tool == "boom-resim":
        assert resim(mcap, "--out", tmp_path / "out").returncode == 0


@pytest.mark.parametrize("value", ["inf", "nan", "-inf"])
def test_a_non_finite_change_is_refused(tmp_path, value):
    bag = synthetic_bag(tmp_path / "run")
    result = resim(bag, "--set", f"payload_mass_kg={value}", "--out", tmp_path / "out")
    assert result.returncode == 2
    assert "payload_mass_kg" in one_line(result)


def _staging(folder: Path, name: str) -> Path:
    """A staging folder as a killed boom-resim leaves it: ``.NAME.xxxxxxxx.partial/bag/NAME_0.mcap``."""
    (folder / name / "bag").mkdir(parents=True)
    (folder / name / "bag" / "out_0.mcap").write_bytes(b"\x89MCAP0\r\n" + b"\0" * 1000)
    return folder / name


def test_a_killed_runs_temporary_folder_is_removed_by_the_next_run_to_the_same_out(tmp_path):
    bag = synthetic_bag(tmp_path / "run")
    results = tmp_path / "results"
    results.mkdir()
    stale = _staging(results, ".out.k1ll3d_x.partial")
    other_out = _staging(results, ".other.k1ll3d_x.partial")  # another --out's: not this run's business
    not_ours = _staging(results, ".out.partial")  # not the tool's pattern
    live = _staging(results, ".out.l1ve_run.partial")  # a run to the same --out that is still going
    with (live / "bag" / "out_0.mcap").open("rb") as held:
        fcntl.flock(held.fileno(), fcntl.LOCK_EX)
        result = resim(bag, "--out", results / "out")
    assert result.returncode == 0, result.stderr
    assert f"removed {stale}" in result.stderr
    assert not stale.exists() and other_out.exists() and not_ours.exists() and live.exists()
    assert sorted(p.name for p in results.iterdir()) == sorted([other_out.name, not_ours.name, live.name, "out"])


def _long_bag(folder: Path) -> Path:
    """A bag without DriveState whose last message is an hour in: boom-resim simulates the hour
    (on the recorded publish rate's grid), long enough to be interrupted."""
    custom = run_description(from_mapping({}), 0, 100.0, 0.5, node="/boom_sim")
    with BagRecorder(
        folder, [Topic("/valve_command", "boom_hydraulics_msgs/msg/ValveCommand")], custom_data=custom
    ) as r:
        for at_s in (0.01, 3600.0):
            r.write("/valve_command", round(at_s * 1e9), serialize_message(ValveCommand(opening=0.0)))
    return folder


@pytest.fixture
def running_resim(tmp_path) -> Iterator[tuple[subprocess.Popen, Path]]:
    """A real boom-resim process on an hour-long bag into ``results/out``, once it has made its
    staging folder's bag file (the event: it is writing); (the process, the results folder).
    Stopped after the test if it still runs."""
    bag = _long_bag(tmp_path / "run")
    results = tmp_path / "results"
    results.mkdir()
    proc = subprocess.Popen(
        [BOOM_RESIM, bag, "--out", results / "out"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    try:
        deadline = time.monotonic() + 120  # a guard only: the staging file is the event waited for
        while not list(results.glob(".out.*.partial/bag/*.mcap")):
            assert proc.poll() is None, f"boom-resim made no staging folder (exit {proc.poll()}): {proc.stderr.read()}"
            assert time.monotonic() < deadline, "boom-resim made no staging folder within 120 s"
            time.sleep(0.01)
        yield proc, results
    finally:
        if proc.poll() is None:
            proc.kill()
        proc.communicate()


@pytest.mark.parametrize(
    ("sig", "code", "line"),
    [(signal.SIGINT, 130, "interrupted (Ctrl-C)"), (signal.SIGTERM, 143, "terminated (SIGTERM)")],
)
def test_an_interrupted_resim_ends_in_one_line_and_leaves_nothing(running_resim, sig, code, line):
    proc, results = running_resim
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == code
    assert len(err.strip().splitlines()) == 1 and err.startswith(f"boom-resim: error: {line}")
    assert list(results.iterdir()) == []


@pytest.mark.filterwarnings("error::pytest.PytestUnraisableExceptionWarning")  # no "Exception ignored" either
def test_a_ctrl_c_that_a_finalizer_swallowed_still_stops_a_resim_at_its_next_state(tmp_path, capsys):
    """Python drops an exception raised in ``__del__``: a Ctrl-C landing in a finalizer while
    boom-resim runs is raised again at its next state (as boom-sweep's batches raise it: seen as
    an interrupted boom-resim that ran to its end and exited 0, twice in loaded test runs)."""
    from boom_hydraulics.programs import run_main
    from boom_hydraulics.resim.resimulation import resimulate

    bag = synthetic_bag(tmp_path / "run")

    class Finalized:
        def __del__(self) -> None:
            os.kill(os.getpid(), signal.SIGINT)
            for _ in range(1000):  # the handler runs here, inside the finalizer: its exception is dropped
                pass

    def body() -> int:
        Finalized()
        resimulate(bag, tmp_path / "out")
        return 0

    assert run_main("boom-resim", body) == 130
    assert capsys.readouterr().err.startswith("boom-resim: error: interrupted (Ctrl-C)")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run"]


def test_a_killed_resim_is_cleaned_up_by_the_next_run(running_resim, tmp_path):
    proc, results = running_resim
    proc.kill()
    proc.communicate(timeout=30)
    (left,) = list(results.iterdir())
    short = synthetic_bag(tmp_path / "short")
    result = resim(short, "--out", results / "out")
    assert result.returncode == 0, result.stderr
    assert f"removed {left}" in result.stderr
    assert [p.name for p in results.iterdir()] == ["out"]


@pytest.mark.skipif(os.geteuid() != 0, reason="mounting a small tmpfs (a full disk) needs root")
def test_a_full_disk_names_the_new_bag_and_leaves_nothing(tmp_path):
    bag = synthetic_bag(tmp_path / "run", seconds=120.0)
    disk = tmp_path / "disk"
    disk.mkdir()
    subprocess.run(["mount", "-t", "tmpfs", "-o", "size=256k", "tmpfs", str(disk)], check=True)
    try:
        result = resim(bag, "--out", disk / "out")
        assert result.returncode == 1
        err = one_line(result)
        assert f"{disk / 'out'}: cannot write the new bag" in err and "No space left on device" in err
        assert list(disk.iterdir()) == []
    finally:
        subprocess.run(["umount", str(disk)], check=True)


# --- with the node --------------------------------------------------------------------------


def _settle(client, seconds_of_states: int) -> None:
    n = len(client.states)
    assert client.spin_until(lambda: len(client.states) >= n + seconds_of_states)


@pytest.mark.skipif(BOOM_SIM is None, reason="run through tools/with-env")
def test_a_reset_node_run_is_reproduced_as_a_user_meets_it(tmp_path, nodes, client):
    """Record a default-clock run, lift, reset it twice through ~/reset, stop it with Ctrl-C,
    and re-simulate: the node recorded its resets among its run events, and the re-simulation
    resets where it did (it refused such runs before the node recorded them)."""
    proc = nodes.start(f"record_folder:={tmp_path / 'bags'}", "command_timeout_s:=0.0", record=True)
    assert client.spin_until(lambda: len(client.states) > 3)
    client.command(1.0)
    _settle(client, 30)
    for _ in range(2):
        assert client.call(client.reset, Reset.Request()).success
        _settle(client, 10)
    stop_process(proc)
    (bag,) = list((tmp_path / "bags").iterdir())
    result = resim(bag, "--out", tmp_path / "out")
    assert result.returncode == 0, result.stderr
    original, again = read_drive_states(bag), read_drive_states(tmp_path / "out")
    assert len(again["q1"]) == len(original["q1"])
    assert np.max(np.abs(original["q1"] - again["q1"])) < 1e-9


def _events_bag(folder: Path, events: list[dict], diagnostics: dict[str, str], **description) -> Path:
    """A bag as the node records it with its run events (the description names their topic)
    and its "boom_sim: run" diagnostics (the counts given), at rest for a second."""
    import json

    from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
    from std_msgs.msg import String

    custom = run_description(
        from_mapping({}), ROS_TIME_NS, 100.0, 0.5, node="/boom_sim", events_topic="/boom_sim/events", **description
    )
    topics = [
        Topic("/drive_state", "boom_hydraulics_msgs/msg/DriveState"),
        Topic("/boom_sim/events", "std_msgs/msg/String"),
    ]
    topics.append(Topic("/diagnostics", "diagnostic_msgs/msg/DiagnosticArray"))
    with BagRecorder(folder, topics, custom_data=custom) as rec:
        for k in range(1, 101):
            stamp = ROS_TIME_NS + k * 10_000_000
            msg = DriveState(rod_position_m=1.37)
            msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(stamp, 1_000_000_000)
            rec.write("/drive_state", stamp, serialize_message(msg))
            for event in [e for e in events if e.get("states_before") == k]:
                rec.write("/boom_sim/events", stamp + 1, serialize_message(String(data=json.dumps(event))))
        status = DiagnosticStatus(
            name="boom_sim: run", values=[KeyValue(key=k, value=v) for k, v in diagnostics.items()]
        )
        rec.write("/diagnostics", ROS_TIME_NS + 1_000_000_001, serialize_message(DiagnosticArray(status=[status])))
    return folder


def _reset_event(states_before: int) -> dict:
    return {
        "event": "reset", "sim_time_s": states_before * 0.01, "states_before": states_before,
        "clock_origin_ns": ROS_TIME_NS, "origin_moved_ns": 0, "cause": "~/reset", "rod_position_m": None,
        "stopped": False, "state": [],
    }  # fmt: skip


def test_a_bag_with_fewer_events_than_the_node_counted_is_refused_as_not_whole(tmp_path):
    bag = _events_bag(tmp_path / "run", [_reset_event(40)], {"resets": "2", "pauses": "0", "step_calls": "0"})
    result = resim(bag, "--out", tmp_path / "out")
    assert result.returncode == 2
    err = one_line(result)
    assert "count 2 resets and the bag holds 1 of them on /boom_sim/events" in err and "not whole" in err
    assert not (tmp_path / "out").exists()
    # with the events the node counted, the same run is re-simulated
    whole = _events_bag(tmp_path / "whole", [_reset_event(40), _reset_event(70)], {"resets": "2"})
    result = resim(whole, "--out", tmp_path / "out")
    assert result.returncode == 0, result.stderr
    assert len(read_drive_states(tmp_path / "out")["q1"]) == 100


@pytest.mark.parametrize("pace", ["at the start", "changed"])
def test_a_run_at_another_pace_on_the_nodes_own_clock_is_refused_naming_publish_clock(tmp_path, pace):
    """There the node stamps a state with the time it published it, not its simulated instant."""
    start, events = (
        (2.0, []) if pace == "at the start" else (1.0, [{**_reset_event(40), "event": "pace", "real_time_factor": 0.0}])
    )
    bag = _events_bag(tmp_path / "run", events, {}, clock="system", real_time_factor=start)
    result = resim(bag, "--out", tmp_path / "out")
    assert result.returncode == 2
    err = one_line(result)
    assert f"ran at real_time_factor {start if pace == 'at the start' else 0:g} on its own clock" in err
    assert "publish_clock:=true" in err
    # with publish_clock the same pace is re-simulated
    bag = _events_bag(tmp_path / "published", events, {}, clock="published", real_time_factor=start)
    assert resim(bag, "--out", tmp_path / "out").returncode == 0


def test_a_run_event_that_does_not_read_is_refused_in_one_line(tmp_path):
    bad = {**_reset_event(40), "sim_time_s": "soon"}
    bag = _events_bag(tmp_path / "run", [bad], {})
    result = resim(bag, "--out", tmp_path / "out")
    assert result.returncode != 0
    err = one_line(result)
    assert "a run event on /boom_sim/events does not read ('sim_time_s' is 'soon', not a float)" in err


@pytest.mark.skipif(BOOM_SIM is None, reason="run through tools/with-env")
def test_a_paused_and_stepped_run_on_its_own_clock_is_reproduced(tmp_path, nodes, client):
    """With publish_clock a pause and steps keep simulated time one line: re-simulated exactly."""
    proc = nodes.start(
        f"record_folder:={tmp_path / 'bags'}", "publish_clock:=true", "command_timeout_s:=0.0", record=True
    )
    assert client.spin_until(lambda: len(client.states) > 3)
    client.command(1.0)
    _settle(client, 20)
    assert client.call(client.pause, SetBool.Request(data=True)).success
    client.command(-0.5)  # received while paused
    for _ in range(3):
        assert client.call(client.step, Step.Request(steps=7)).success
    assert client.call(client.pause, SetBool.Request(data=False)).success
    _settle(client, 20)
    client.command(0.0)
    _settle(client, 10)
    stop_process(proc)
    (bag,) = list((tmp_path / "bags").iterdir())
    result = resim(bag, "--out", tmp_path / "out")
    assert result.returncode == 0, result.stderr
    original, again = read_drive_states(bag), read_drive_states(tmp_path / "out")
    assert np.array_equal(original["t"], again["t"])
    assert np.max(np.abs(original["q1"] - again["q1"])) < 1e-12
