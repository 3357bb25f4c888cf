"""The crane as a robot model: URDF with a real URDF library, markers, viewer configs, launch."""

from __future__ import annotations

import ast
import io
import json
import math
import signal
from pathlib import Path

import numpy as np
import pytest
import yaml
from conftest import BOOM_SIM, ROOT

from boom_hydraulics.errors import ConfigError
from boom_hydraulics.model import config
from boom_hydraulics.model.parameters import Parameters, with_updates
from boom_hydraulics.model.robot_description import urdf
from boom_hydraulics.ros import launch_arguments

yourdfpy = pytest.importorskip("yourdfpy")
rclpy = pytest.importorskip("rclpy")

PACKAGE = ROOT / "src" / "boom_hydraulics"


def _load(description: str):
    return yourdfpy.URDF.load(
        io.StringIO(description), build_scene_graph=True, load_meshes=False, build_collision_scene_graph=False
    )


def _position(robot, frame: str) -> np.ndarray:
    return robot.get_transform(frame, "base_link")[:3, 3]


def _of_tick(states: list, joints: object) -> list:
    """The DriveStates stamped as ``joints`` (published in the same tick)."""
    return [s for s in states if s.header.stamp == joints.header.stamp]


@pytest.mark.skipif(BOOM_SIM is None, reason="boom_sim not on PATH (run through tools/with-env)")
@pytest.mark.usefixtures("ros_context")
def test_forward_kinematics_with_the_published_joints_closes_the_chain(nodes, client):
    """robot_description and joint_states from the running node, at three rod lengths: rod_eye
    lands on boom_rod_mount within 1 mm, and the boom tip is at the model's angle."""
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    from std_msgs.msg import String

    from boom_hydraulics_msgs.srv import Reset

    node = nodes.start("payload_mass_kg:=120.0")
    try:
        descriptions: list[String] = []
        latched = QoSProfile(
            depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL
        )
        client.node.create_subscription(String, "robot_description", descriptions.append, latched)
        assert client.spin_until(lambda: descriptions and len(client.joints) > 3, 20), "no robot_description"
        robot = _load(descriptions[-1].data)
        assert robot.robot.name == "boom_crane"
        for q1 in (1.06, 1.37, 1.74):
            response = client.call(client.reset, Reset.Request(use_rod_position=True, rod_position_m=q1))
            assert response.success, response.message
            seen = len(client.joints)
            assert client.spin_until(lambda seen=seen: len(client.joints) > seen + 3)
            joints = client.joints[-1]
            # the DriveState of the same tick (the latest of each may be a tick apart: the boom sags after a reset)
            assert client.spin_until(lambda joints=joints: _of_tick(client.states, joints))
            state = _of_tick(client.states, joints)[-1]
            values = dict(zip(joints.name, joints.position))
            assert set(values) == {"boom_joint", "cylinder_barrel_joint", "cylinder_joint"}
            robot.update_cfg(values)
            gap = np.linalg.norm(_position(robot, "rod_eye") - _position(robot, "boom_rod_mount"))
            assert gap < 1e-3, (q1, gap)
            pivot, tip = _position(robot, "boom"), _position(robot, "boom_tip")
            angle = math.atan2(tip[2] - pivot[2], tip[0] - pivot[0])
            assert angle == pytest.approx(state.boom_angle_rad, abs=1e-4)
            assert values["cylinder_joint"] == pytest.approx(state.rod_position_m, abs=1e-12)
            assert abs(tip[1]) < 1e-12  # the crane moves in the x-z plane; positive angle lifts (REP 103)
        assert tip[2] > pivot[2]
    finally:
        node.send_signal(signal.SIGINT)
        node.wait(timeout=10)


def test_the_shipped_urdf_is_that_of_config_default_yaml_and_follows_its_dimensions():
    shipped = (PACKAGE / "urdf" / "boom_crane.urdf").read_text()
    assert shipped == urdf(config.load(ROOT / "config" / "default.yaml"))
    longer = _load(urdf(with_updates(Parameters(), boom_length_m=3.0)))
    longer.update_cfg({"boom_joint": 0.0, "cylinder_barrel_joint": 0.0, "cylinder_joint": 1.4})
    assert _position(longer, "boom_tip")[0] == pytest.approx(3.0)
    limits = {j.name: (j.limit.lower, j.limit.upper) for j in _load(shipped).robot.joints if j.limit}
    assert limits["cylinder_joint"] == (1.05, 1.75)
    assert limits["boom_joint"][0] < 0.0 < math.radians(30) < limits["boom_joint"][1]


def test_the_ros2_control_tag_drives_boom_joint_through_the_node_s_joint_topics():
    """The tag ros2_control reads: the JointState topic hardware interface on the node's topics
    (a namespaced node's when asked), boom_joint (the URDF's revolute boom joint) with position
    and velocity interfaces, its position starting at the angle of the initial cylinder length."""
    import xml.etree.ElementTree as ElementTree

    from boom_hydraulics.model.geometry import boom_angle_rad

    p = config.load(ROOT / "config" / "default.yaml")
    for robot, topics in (
        (
            ElementTree.fromstring((PACKAGE / "urdf" / "boom_crane.urdf").read_text()),
            ("/joint_commands", "/joint_states"),
        ),
        (
            ElementTree.fromstring(urdf(p, "/crane1/joint_commands", "/crane1/joint_states")),
            ("/crane1/joint_commands", "/crane1/joint_states"),
        ),
    ):
        (control,) = robot.findall("ros2_control")
        assert control.get("type") == "system"
        hardware = control.find("hardware")
        assert hardware.findtext("plugin") == "joint_state_topic_hardware_interface/JointStateTopicSystem"
        params = {e.get("name"): e.text for e in hardware.findall("param")}
        assert (params["joint_commands_topic"], params["joint_states_topic"]) == topics
        assert float(params["trigger_joint_command_threshold"]) < 0.0  # every update is published
        (joint,) = control.findall("joint")
        urdf_joints = {j.get("name"): j for j in robot.findall("joint")}
        assert urdf_joints[joint.get("name")].get("type") == "revolute" and joint.get("name") == "boom_joint"
        assert [c.get("name") for c in joint.findall("command_interface")] == ["position", "velocity"]
        assert [c.get("name") for c in joint.findall("state_interface")] == ["position", "velocity"]
        initial = float(joint.find("state_interface/param[@name='initial_value']").text)
        assert initial == pytest.approx(boom_angle_rad(p.initial_length_m, p.a_m, p.b_m, p.support_height_m), abs=1e-5)


def _distinct(p: Parameters, **flags) -> dict:
    out = {"q1": 1.5, "p1": 8.0e6, "p2": 1.0e5, "void1": 0.0, "void2": 0.0}
    out.update(flags)
    return out


def test_markers_colour_the_chambers_by_pressure_and_flag_cavitation_and_relief_red():
    from boom_hydraulics.bags.encoding import typestore
    from boom_hydraulics.bags.markers import MARKER_ARRAY
    from boom_hydraulics.bags.markers import crane_markers as crane_markers_cdr

    def crane_markers(out, stamp_ns, p):  # as a reader of the bag or the topic sees them
        return typestore().deserialize_cdr(crane_markers_cdr(out, stamp_ns, p), MARKER_ARRAY)

    p = Parameters()
    normal = crane_markers(_distinct(p), 3 * 10**9, p)
    by_id = {m.id: m for m in normal.markers}
    assert all(m.header.frame_id == "base_link" and m.header.stamp.sec == 3 for m in normal.markers)
    barrel, rod = by_id[3], by_id[4]
    assert barrel.color.r > rod.color.r and rod.color.b > barrel.color.b  # higher pressure, warmer
    assert (barrel.color.r, barrel.color.g, barrel.color.b) != (1.0, 0.0, 0.0)
    cavitating = {m.id: m for m in crane_markers(_distinct(p, void2=1e-7), 0, p).markers}
    assert (cavitating[4].color.r, cavitating[4].color.g) == (1.0, 0.0) and "ROD CAVITATION" in cavitating[5].text
    relief = {m.id: m for m in crane_markers(_distinct(p, p1=18.5e6), 0, p).markers}
    assert (relief[3].color.r, relief[3].color.g) == (1.0, 0.0) and "PISTON RELIEF" in relief[5].text
    # the rod ends at the boom's rod eye K, whatever the length
    tip_of_rod = by_id[4].pose.position.z + 0.5 * by_id[4].scale.z * math.cos(
        2 * math.asin(by_id[4].pose.orientation.y)
    )
    boom = by_id[1]
    alpha = math.atan2(boom.pose.position.z - (0.2 + p.support_height_m), boom.pose.position.x)
    assert tip_of_rod == pytest.approx(0.2 + p.support_height_m + p.a_m * math.sin(alpha), abs=1e-9)


def test_viewer_configs_show_what_the_node_publishes():
    rviz = yaml.safe_load((PACKAGE / "rviz" / "boom_crane.rviz").read_text())
    displays = {d["Class"]: d for d in rviz["Visualization Manager"]["Displays"]}
    assert displays["rviz_default_plugins/RobotModel"]["Description Topic"]["Value"] == "/robot_description"
    assert displays["rviz_default_plugins/MarkerArray"]["Topic"]["Value"] == "/boom_sim/markers"
    assert rviz["Visualization Manager"]["Global Options"]["Fixed Frame"] == "base_link"
    layout = json.loads((PACKAGE / "foxglove" / "boom_crane.json").read_text())
    three_d = layout["configById"]["3D!crane"]
    assert three_d["topics"]["/boom_sim/markers"]["visible"] and three_d["followTf"] == "base_link"
    plotted = {path["value"] for panel in layout["configById"].values() for path in panel.get("paths", [])}
    assert {"/piston_pressure.fluid_pressure", "/rod_pressure.fluid_pressure"} <= plotted

    def panels(node) -> set:
        return {node} if isinstance(node, str) else panels(node["first"]) | panels(node["second"])

    assert panels(layout["layout"]) == set(layout["configById"])


def test_launch_arguments_and_what_they_start(monkeypatch, tmp_path):
    monkeypatch.setenv("ROS_HOME", str(tmp_path / "ros_home"))
    plain = launch_arguments.plan({}, "/share/config/default.yaml", state_publisher_installed=False)
    assert plain.namespace == "" and plain.params_file == "/share/config/default.yaml"
    assert plain.sim_parameters == {
        "use_sim_time": False,
        "record": False,  # a robot stack finds no bags/ folder in its working directory
        "record_folder": str(tmp_path / "ros_home" / "boom_hydraulics" / "bags"),
        "publish_robot_description": True,
    }
    assert not plain.state_publisher and not plain.rviz
    mine = tmp_path / "my.yaml"  # (a params_file:= that is not there is refused: test_launch)
    mine.write_text("/**:\n  ros__parameters:\n    payload_mass_kg: 80.0\n")
    stack = launch_arguments.plan(
        {"namespace": "/crane1", "use_sim_time": "true", "params_file": str(mine), "record": "true"},
        "/share/config/default.yaml",
        state_publisher_installed=True,
    )
    assert (stack.namespace, stack.params_file, stack.state_publisher) == ("crane1", str(mine), True)
    assert stack.sim_parameters["use_sim_time"] and stack.sim_parameters["record"]
    assert stack.sim_parameters["publish_robot_description"] is False  # one publisher: robot_state_publisher
    assert not launch_arguments.plan({"robot_state_publisher": "false"}, "x", True).state_publisher
    with pytest.raises(ConfigError, match="not installed"):
        launch_arguments.plan({"robot_state_publisher": "true"}, "x", False)
    with pytest.raises(ConfigError, match="expected true or false"):
        launch_arguments.plan({"record": "maybe"}, "x", False)
    with pytest.raises(ConfigError, match="unknown launch arguments"):
        launch_arguments.plan({"namespce": "a"}, "x", False)


def test_the_launch_file_declares_every_argument():
    """With the launch library installed, load the description; else read the file's code."""
    path = PACKAGE / "launch" / "boom_sim.launch.py"
    try:
        import importlib.util

        import launch  # noqa: F401
        import launch_ros  # noqa: F401
    except ImportError:
        tree = ast.parse(path.read_text())
        calls = {n.func.id for n in ast.walk(tree) if isinstance(n, ast.Call) and isinstance(n.func, ast.Name)}
        assert {"DeclareLaunchArgument", "OpaqueFunction", "plan", "Node"} <= calls
        declared = [
            n for n in ast.walk(tree) if isinstance(n, ast.comprehension) and getattr(n.iter, "id", "") == "ARGUMENTS"
        ]
        assert len(declared) == 2  # one to declare, one to read every argument
        return
    spec = importlib.util.spec_from_file_location("boom_sim_launch", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    description = module.generate_launch_description()
    names = [a.name for a in description.get_launch_arguments()]
    assert names == list(launch_arguments.NAMES)


def test_boom_sim_urdf_writes_the_description_of_a_config(tmp_path):
    import subprocess
    import sys

    out = tmp_path / "crane.urdf"
    result = subprocess.run(
        [
            sys.executable,
            "-m",
            "boom_hydraulics.cli.sim",
            "urdf",
            "--config",
            str(ROOT / "config" / "paper_fig8.yaml"),
            "--out",
            str(out),
        ],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert result.returncode == 0, result.stderr
    assert out.read_text() == urdf(config.load(ROOT / "config" / "paper_fig8.yaml"))
    assert Path(out).stat().st_size > 1000
