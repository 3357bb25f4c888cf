"""boom-resim: a recorded node run fed through the model again, unchanged and "what if"."""

from __future__ import annotations

import shutil
import signal
import subprocess
import time

import numpy as np
import pytest
from conftest import BOOM_SIM, run_tool, start_node

rclpy = pytest.importorskip("rclpy")
from bag_checks import check_bag  # noqa: E402
from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue  # noqa: E402
from rcl_interfaces.srv import SetParameters  # noqa: E402
from ros_client import Client  # noqa: E402
from rosbags.highlevel import AnyReader  # noqa: E402
from std_srvs.srv import SetBool  # noqa: E402

from boom_hydraulics.bags.reading import read_drive_states  # noqa: E402
from boom_hydraulics.resim import resimulation as resim  # noqa: E402
from boom_hydraulics_msgs.msg import DriveState, ValveCommand  # noqa: E402

BOOM_RESIM = shutil.which("boom-resim")
pytestmark = pytest.mark.skipif(BOOM_SIM is None or BOOM_RESIM is None, reason="run through tools/with-env")


def resim_main(*args) -> subprocess.CompletedProcess:
    """boom-resim's main in this process (conftest.run_tool; test_resim_refusals runs the real one)."""
    return run_tool("boom-resim", *args)


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    """A node run with /clock: lift, hold, lower, queued while paused, then as fast as possible."""
    folder = tmp_path_factory.mktemp("bags")
    proc = start_node(
        "publish_clock:=true", "real_time_factor:=0.0", "start_paused:=true", f"record_folder:={folder}", record=True
    )
    rclpy.init()
    node = rclpy.create_node("resim_driver")
    states: list[DriveState] = []
    node.create_subscription(DriveState, "drive_state", states.append, 10)
    pub = node.create_publisher(ValveCommand, "valve_command", 10)
    pause = node.create_client(SetBool, "/boom_sim/pause")
    try:
        assert pause.wait_for_service(timeout_sec=20)
        deadline = time.monotonic() + 10
        while pub.get_subscription_count() == 0 and time.monotonic() < deadline:
            rclpy.spin_once(node, timeout_sec=0.05)
        end = time.monotonic() + 1.0  # let discovery settle both ways (best-effort reader)
        while time.monotonic() < end:
            rclpy.spin_once(node, timeout_sec=0.05)
        for _ in range(2):  # twice: a stamped duplicate applies at the same time, in node and resim alike
            for at, opening in [(0.5, 1.0), (2.0, 0.0), (2.5, -0.8), (3.5, 0.0)]:
                msg = ValveCommand(opening=opening)
                msg.header.stamp.sec, msg.header.stamp.nanosec = int(at), round((at - int(at)) * 1e9)
                pub.publish(msg)
        for _ in range(10):
            rclpy.spin_once(node, timeout_sec=0.05)
        future = pause.call_async(SetBool.Request(data=False))
        deadline = time.monotonic() + 30
        while not (states and states[-1].header.stamp.sec >= 4) and time.monotonic() < deadline:
            rclpy.spin_once(node, timeout_sec=0.02)
        assert future.done()
    finally:
        node.destroy_node()
        rclpy.shutdown()
        proc.send_signal(signal.SIGINT)
        proc.communicate(timeout=20)
    (bag,) = list(folder.iterdir())
    return bag


def test_unchanged_resimulation_reproduces_the_recorded_run(recorded, tmp_path):
    result = resim_main(recorded, "--out", tmp_path / "same")
    assert result.returncode == 0, result.stderr
    original, again = read_drive_states(recorded), read_drive_states(tmp_path / "same")
    # it lifted and lowered (each for 0.5 s: the node's command timeout closes the valve)
    assert original["q1"].max() > original["q1"][0] + 0.05
    assert original["q1"][-1] < original["q1"].max() - 0.05
    n = min(len(original["q1"]), len(again["q1"]))
    assert n > 300
    assert np.max(np.abs(original["q1"][:n] - again["q1"][:n])) < 1e-12
    assert np.max(np.abs(original["p1"][:n] - again["p1"][:n])) < 1e-6


def test_what_if_a_heavier_payload(recorded, tmp_path):
    out = tmp_path / "heavy"
    result = resim_main(recorded, "--set", "payload_mass_kg=250", "--out", out)
    assert result.returncode == 0, result.stderr
    original, heavy = read_drive_states(recorded), read_drive_states(out)
    lift = lambda s: s["q1"].max() - s["q1"][0]  # noqa: E731
    assert lift(heavy) < lift(original)  # same commands, slower lift
    assert heavy["p1"].max() > original["p1"][: len(heavy["p1"])].max() - 1.0


def test_what_if_a_mechanical_network_pushes_the_rod_in(recorded, tmp_path):
    out = tmp_path / "pushed"
    result = resim_main(recorded, "--set", "external_rod_force_n=-1500", "--out", out)
    assert result.returncode == 0, result.stderr
    original, pushed = read_drive_states(recorded), read_drive_states(out)
    s1 = np.pi * 0.04**2 / 4
    # held at rest: F / S1 more (to 1 %: the first state is a tick after the start, as the oil settles)
    assert pushed["p1"][0] - original["p1"][0] == pytest.approx(1500.0 / s1, rel=0.01)
    lift = lambda s: s["q1"].max() - s["q1"][0]  # noqa: E731
    assert lift(pushed) < lift(original)  # same commands against a larger load


def test_a_bag_recorded_before_the_external_rod_force_existed_is_resimulated_as_it_ran(recorded, tmp_path, monkeypatch):
    """Its parameters lack external_rod_force_n: the default 0 gives the recorded run again."""
    read_run = resim.read_run

    def older(bag, description):
        run = read_run(bag, description)
        assert run.parameters.pop("external_rod_force_n") == 0.0
        return run

    monkeypatch.setattr(resim, "read_run", older)
    out, _ = resim.resimulate(recorded, tmp_path / "older")
    original, again = read_drive_states(recorded), read_drive_states(out)
    n = min(len(original["q1"]), len(again["q1"]))
    assert n > 300 and np.max(np.abs(original["q1"][:n] - again["q1"][:n])) < 1e-12


def test_a_bag_from_an_earlier_model_is_resimulated_without_its_retired_parameters(
    recorded, tmp_path, monkeypatch, capsys
):
    """Bags recorded before the LuGre friction and Hunt-Crossley stops hold
    friction_smoothing_velocity_m_s and end_stop_damping_n_s_m: they are named and left out."""
    read_run = resim.read_run

    def older(bag, description):
        run = read_run(bag, description)
        run.parameters.update(friction_smoothing_velocity_m_s=0.001, end_stop_damping_n_s_m=2e6)
        return run

    monkeypatch.setattr(resim, "read_run", older)
    out, count = resim.resimulate(recorded, tmp_path / "again")
    assert count > 300 and out.exists()
    note = capsys.readouterr().err
    assert "end_stop_damping_n_s_m, friction_smoothing_velocity_m_s" in note and "left out" in note


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--set", "rod_diameter_m=0.05"], "must be smaller than piston_diameter_m"),
        (["--set", "nonsense=1"], "unknown parameter 'nonsense'"),
        (["--set", "time_step_s=0.5"], "'time_step_s' is 0.5 s; it must be <= 0.1"),
    ],
)
def test_bad_changes_are_refused_and_nothing_is_written(recorded, tmp_path, args, message):
    out = tmp_path / "never"
    result = resim_main(recorded, *args, "--out", out)
    assert result.returncode == 2 and message in result.stderr and "Traceback" not in result.stderr
    assert not out.exists()


@pytest.fixture(scope="module")
def namespaced(tmp_path_factory):
    """A run of /crane1/boom_sim with /clock whose payload is changed while it runs."""
    folder = tmp_path_factory.mktemp("ns_bags")
    params = (f"record_folder:={folder}", "publish_clock:=true", "real_time_factor:=2.0", "command_timeout_s:=0.0")
    proc = start_node(*params, config_file=None, record=True, ros_args=("-r", "__ns:=/crane1"))
    rclpy.init()
    client = Client("/crane1/boom_sim", namespace="/crane1")
    try:
        assert client.spin_until(lambda: len(client.states) > 3)
        client.spin_for(0.5)
        now = client.last().header.stamp.sec + client.last().header.stamp.nanosec * 1e-9
        client.command(1.0, stamp_s=now + 1.0)  # ahead of the node's simulated time
        client.command(0.0, stamp_s=now + 2.0)
        assert client.spin_until(lambda: client.last().header.stamp.sec >= now + 2.5, timeout=20)
        changed = Parameter(
            name="payload_mass_kg", value=ParameterValue(type=ParameterType.PARAMETER_DOUBLE, double_value=180.0)
        )
        assert client.call(client.set_params, SetParameters.Request(parameters=[changed])).results[0].successful
        assert client.spin_until(lambda: client.last().header.stamp.sec >= now + 4.5, timeout=20)
    finally:
        client.node.destroy_node()
        rclpy.shutdown()
        proc.send_signal(signal.SIGINT)
        proc.communicate(timeout=20)
    (bag,) = list(folder.iterdir())
    return bag


def test_a_parameter_changed_while_running_is_recorded_and_resimulated_at_its_time(namespaced, tmp_path):
    assert namespaced.name.endswith("_crane1_boom_sim")  # the node's name and namespace in the folder name
    check_bag(namespaced)
    result = resim_main(namespaced, "--out", tmp_path / "again")
    assert result.returncode == 0, result.stderr
    check_bag(tmp_path / "again")
    with AnyReader([tmp_path / "again"]) as reader:
        topics = {c.topic for c in reader.connections}
    assert "/crane1/drive_state" in topics and "/drive_state" not in topics  # stays namespaced
    original, again = read_drive_states(namespaced), read_drive_states(tmp_path / "again")
    assert np.array_equal(original["t"], again["t"]) and len(original["t"]) > 20  # the same instants (a tick each)
    assert np.max(np.abs(original["q1"] - again["q1"])) < 1e-12  # commands and change at the same instants
    assert np.max(np.abs(original["p1"] - again["p1"])) < 1e-6
    # the heavier payload shows: the holding pressure rose after the change
    assert again["p1"][-1] > again["p1"][0] * 1.3


def test_runs_overlay_on_their_common_origin(namespaced, tmp_path):
    resim = tmp_path / "heavy"
    assert resim_main(namespaced, "--set", "payload_mass_kg=150", "--out", resim).returncode == 0
    for align in ("origin", "command"):
        first_open = [
            (s := read_drive_states(bag, align))["t"][np.nonzero(s["u"])[0][0]] for bag in (namespaced, resim)
        ]
        assert first_open[0] == pytest.approx(first_open[1], abs=1e-9)
    signals = read_drive_states(namespaced, "origin")
    commands = read_drive_states(namespaced, "command")
    opened = np.nonzero(signals["u"])[0][0]
    assert signals["t"][opened] > 1.0 and commands["t"][opened] == 0.0  # simulated time; the opening


def test_resim_refuses_to_write_over_its_input_and_writes_nothing_when_it_fails(namespaced, tmp_path):
    for out in (namespaced, namespaced.parent):
        result = resim_main(namespaced, "--out", out)
        assert result.returncode == 2 and "input" in result.stderr
    check_bag(namespaced)  # untouched
    stopped = resim_main(namespaced, "--set", "mode=paper", "--set", "orifice_diameter_m=0.01", "--out", tmp_path / "x")
    assert stopped.returncode == 1 and "paper mode has no end stops" in stopped.stderr  # leaves the geometry
    assert len(stopped.stderr.strip().splitlines()) == 1
    assert list(tmp_path.iterdir()) == []  # no bag, no staging folder left


def test_a_truncated_bag_is_one_line(namespaced, tmp_path):
    data = next(namespaced.glob("*.mcap")).read_bytes()
    (tmp_path / "cut.mcap").write_bytes(data[: len(data) // 2])
    result = resim_main(tmp_path / "cut.mcap", "--out", tmp_path / "x")
    assert result.returncode == 1 and "truncated" in result.stderr and "boom-bag-recover" in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1
