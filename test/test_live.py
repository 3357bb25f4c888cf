"""boom-sim live: a Foxglove client in this process, the server in its own, over the published
protocol (foxglove/ws-protocol's v1 messages): the shipped layout's topics with their schemas,
the 3D scene, steering by client-published channels, parameters, Ctrl-C and the bag."""

from __future__ import annotations

import json
import math
import select
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
import yaml
from bag_checks import check_bag, check_resim_within_a_tick
from conftest import small_tmpfs
from foxglove_client import ROOT, WS_PROTOCOL_OFFER, FoxgloveClient, LiveServer
from rosbags.typesys import Stores, get_typestore
from websockets.exceptions import InvalidStatus
from websockets.sync.client import connect

from boom_hydraulics.bags.encoding import START_SETPOINT
from boom_hydraulics.bags.reading import read_drive_states
from boom_hydraulics.model import config

pytestmark = pytest.mark.skipif(shutil.which("boom-sim") is None, reason="boom-sim not on PATH (tools/with-env)")

LAYOUT = ROOT / "src" / "boom_hydraulics" / "foxglove" / "boom_crane.json"
JAZZY = get_typestore(Stores.ROS2_JAZZY)  # the client's own ROS 2 types, to publish CDR as the app does


@pytest.fixture(scope="module")
def server():
    live = LiveServer()
    yield live
    live.stop()


@pytest.fixture
def client(server):
    with FoxgloveClient(server.port) as connection:
        yield connection


#: The layout's panel of the elastic boom: its path is there where the boom is elastic
#: (test_elastic_boom.py checks it against the 1 t crane's run), not on default.yaml's boom.
ELASTIC_PANELS = ("Plot!boom_tip",)


def _layout_paths(elastic: bool = False) -> list[tuple[str, str]]:
    """(topic, field) of every plotted path of the shipped layout (with ``elastic``, those of
    the elastic boom's panels alone, else the others)."""
    panels = json.loads(LAYOUT.read_text())["configById"]
    chosen = [panel for name, panel in panels.items() if (name in ELASTIC_PANELS) == elastic]
    return [tuple(path["value"].split(".", 1)) for panel in chosen for path in panel.get("paths", [])]


def field_value(msg: object, field: str) -> float:
    """A Foxglove message path's field of ``msg``: attributes by dots, array items by [i]."""
    for part in field.split("."):
        name, _, index = part.partition("[")
        msg = getattr(msg, name)
        if index:
            msg = msg[int(index.rstrip("]"))]
    return msg


def test_the_shipped_layout_finds_every_topic_it_names_with_the_fields_it_plots(server, client):
    assert client.ws.subprotocol == "foxglove.sdk.v1"  # the SDK's name for the protocol's v1, which it speaks
    assert {"clientPublish", "parameters", "parametersSubscribe"} <= set(client.info["capabilities"])
    assert {"json", "cdr"} <= set(client.info["supportedEncodings"])
    layout = json.loads(LAYOUT.read_text())["configById"]
    assert set(layout["3D!crane"]["topics"]) | {"/diagnostics"} <= set(client.channels)
    paths = _layout_paths()
    client.subscribe(*sorted({topic for topic, _ in paths}))
    for topic, field in paths:
        _, msg = client.next_message(topic)  # decoded with the schema the channel advertised
        assert math.isfinite(field_value(msg, field)), (topic, field)
        assert msg.header.stamp.sec > 0  # the plots take the header stamp
    assert "rclpy" not in Path(f"/proc/{server.proc.pid}/maps").read_text()  # no ROS in the server


def _matrix(transform) -> np.ndarray:
    t, q = transform.translation, transform.rotation
    x, y, z, w = q.x, q.y, q.z, q.w
    rotation = [
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ]
    m = np.eye(4)
    m[:3, :3], m[:3, 3] = rotation, (t.x, t.y, t.z)
    return m


def test_the_3d_scene_has_the_urdf_the_markers_and_frames_that_close_the_chain(client):
    client.subscribe("/robot_description", "/tf_static", "/tf", "/boom_sim/markers", "/diagnostics")
    _, description = client.next_message("/robot_description")  # latched: sent on subscribing
    assert '<robot name="boom_crane">' in description.data
    _, static = client.next_message("/tf_static")
    _, moving = client.next_message("/tf")
    frames = {t.child_frame_id: (t.header.frame_id, _matrix(t.transform)) for t in static.transforms}
    frames.update({t.child_frame_id: (t.header.frame_id, _matrix(t.transform)) for t in moving.transforms})

    def in_base(frame: str) -> np.ndarray:
        parent, m = frames[frame]
        return m if parent == "base_link" else in_base(parent) @ m

    # the rod's eye lands on the boom's rod mount: the frames are those of one consistent state
    gap = np.linalg.norm(in_base("rod_eye")[:3, 3] - in_base("boom_rod_mount")[:3, 3])
    assert gap < 1e-3, gap
    _, markers = client.next_message("/boom_sim/markers")
    assert len(markers.markers) == 6 and {m.header.frame_id for m in markers.markers} == {"base_link"}
    _, diagnostics = client.next_message("/diagnostics")
    assert {s.hardware_id for s in diagnostics.status} == {"boom_hydraulics"}  # the layout's filter


def test_a_client_published_valve_command_moves_the_rod_up_and_a_teleop_twist_down(client):
    client.subscribe("/drive_state")
    _, start = client.next_message("/drive_state")
    client.advertise(1, "/valve_command", "json", "boom_hydraulics_msgs/msg/ValveCommand")
    client.publish(1, {"opening": 1.0})
    top = client.until("/drive_state", lambda s: s.rod_position_m > start.rod_position_m + 0.01)
    assert top.valve_command == 1.0
    client.advertise(2, "/valve_command", "cdr", "geometry_msgs/msg/Twist")  # Foxglove's Teleop panel
    twist = JAZZY.types["geometry_msgs/msg/Twist"]
    vector = JAZZY.types["geometry_msgs/msg/Vector3"]
    down = twist(linear=vector(x=-1.0, y=0.0, z=0.0), angular=vector(x=0.0, y=0.0, z=0.0))
    client.publish(2, bytes(JAZZY.serialize_cdr(down, "geometry_msgs/msg/Twist")))
    lowered = client.until("/drive_state", lambda s: s.rod_position_m < top.rod_position_m - 0.01)
    assert lowered.valve_command == -1.0


def test_a_client_that_offers_only_the_first_name_connects_subscribes_and_publishes(server):
    """@foxglove/ws-protocol's clients offer the protocol's first name alone, which the SDK's
    server by itself refuses with HTTP 400: they get the same server under that name."""
    with FoxgloveClient(server.port, subprotocols=WS_PROTOCOL_OFFER) as client:
        assert client.ws.request.headers.get_all("Sec-WebSocket-Protocol") == ["foxglove.websocket.v1"]
        assert client.ws.subprotocol == "foxglove.websocket.v1"  # the name it offered (its client checks it)
        assert {"clientPublish", "parameters", "parametersSubscribe"} <= set(client.info["capabilities"])
        assert {"/drive_state", "/joint_states", "/tf", "/robot_description"} <= set(client.channels)
        client.subscribe("/drive_state")
        _, start = client.next_message("/drive_state")
        _, following = client.next_message("/drive_state")
        assert following.header.stamp.sec * 10**9 + following.header.stamp.nanosec > (
            start.header.stamp.sec * 10**9 + start.header.stamp.nanosec
        )  # in the order they were published
        client.advertise(1, "/valve_command", "json", "boom_hydraulics_msgs/msg/ValveCommand")
        client.publish(1, {"opening": 1.0})
        top = client.until("/drive_state", lambda s: s.rod_position_m > following.rod_position_m + 0.01)
        assert top.valve_command == 1.0
        assert client.get_parameters("g1", "payload_mass_kg")["parameters"][0]["name"] == "payload_mass_kg"


def test_a_client_that_offers_neither_name_is_refused_at_the_handshake(server):
    with pytest.raises(InvalidStatus) as refused:
        connect(f"ws://127.0.0.1:{server.port}", subprotocols=["foxglove.websocket.v2"], open_timeout=30)
    assert refused.value.response.status_code == 400


#: The client's channel of target angles (advertised with :func:`_advertise_target`).
TARGET_CHANNEL = 3


def _advertise_target(client: FoxgloveClient) -> None:
    client.advertise(TARGET_CHANNEL, "/boom_sim/target_angle_deg", "cdr", "std_msgs/msg/Float64")


def _target(client: FoxgloveClient, deg: float) -> None:
    """Publish a target angle of ``deg`` degrees as CDR, as the app does."""
    as_cdr = JAZZY.types["std_msgs/msg/Float64"]
    client.publish(TARGET_CHANNEL, bytes(JAZZY.serialize_cdr(as_cdr(data=deg), "std_msgs/msg/Float64")))


def test_a_target_angle_moves_the_boom_there_and_one_outside_the_stroke_is_refused(client):
    """A target angle moves the boom there along the path told on /boom_sim/setpoint_path (as
    the node tells a MoveBoom goal's: from the controller's setpoint to the target), with the
    setpoint on /boom_sim/setpoint meanwhile; one outside the stroke is refused in one line."""
    client.subscribe("/drive_state", "/boom_sim/setpoint", "/boom_sim/setpoint_path")
    _advertise_target(client)
    _target(client, 20.0)
    _, told = client.next_message("/boom_sim/setpoint_path")
    assert told.start == START_SETPOINT and list(told.trajectory.joint_names) == ["boom_joint"]
    assert told.trajectory.points[-1].positions[0] == pytest.approx(math.radians(20.0), abs=1e-12)
    client.until("/drive_state", lambda s: abs(math.degrees(s.boom_angle_rad) - 20.0) < 0.5)
    _, setpoint = client.next_message("/boom_sim/setpoint")  # the controller's setpoint, as the node's
    assert setpoint.name == ["boom_joint"]
    _target(client, 170.0)
    refusal = client.status(lambda m: m["message"].startswith("target angle refused"))
    assert refusal["level"] == 1 and "outside the stroke" in refusal["message"]


def test_a_parameter_set_takes_effect_and_a_bad_one_is_refused_whole_in_one_line(client):
    started = config.load(ROOT / "config" / "default.yaml").payload_mass_kg
    assert client.get_parameters("g1", "payload_mass_kg")["parameters"][0]["value"] == started
    client.subscribe("/drive_state")
    _, before = client.next_message("/drive_state")
    done = client.set_parameters("s1", payload_mass_kg=300)  # an integer for a float, as Foxglove sends it
    assert done["parameters"] == [{"name": "payload_mass_kg", "type": "float64", "value": 300.0}]
    client.until("/drive_state", lambda s: abs(s.load_force_n - before.load_force_n) > 500.0)  # 200 kg more
    refused = client.set_parameters("s2", piston_diameter_m=0.07, payload_mass_kg=-5.0)
    assert {p["name"]: p["value"] for p in refused["parameters"]} == {
        "piston_diameter_m": client.get_parameters("g2", "piston_diameter_m")["parameters"][0]["value"],
        "payload_mass_kg": 300.0,
    }
    assert client.get_parameters("g3", "piston_diameter_m")["parameters"][0]["value"] != 0.07  # none applied
    status = client.status(lambda m: m["message"].startswith("parameters not changed"))
    assert status["level"] == 2 and "payload_mass_kg" in status["message"] and "\n" not in status["message"]
    client.set_parameters("s3", payload_mass=1.0)
    unknown = client.status(lambda m: "unknown parameter 'payload_mass'" in m["message"])
    assert unknown["level"] == 2


@pytest.mark.parametrize(
    ("args", "says"),
    [
        (["--rate", "-1"], "--rate must be a number in [0, 1000], got -1.0"),
        (["--record", "docs"], "--record docs exists already; name a new bag folder"),
        (["--set", "payload_mass_kg=-5"], "payload_mass_kg"),
        ([], "choose another --port (0: any free port)"),  # the module's server has the port
    ],
)
def test_bad_input_is_one_line_with_status_2(server, args, says):
    port = [] if args else ["--port", str(server.port)]
    command = ["boom-sim", "live", "--config", "config/default.yaml", *args, *port]
    done = subprocess.run(command, capture_output=True, text=True, cwd=ROOT, timeout=300)
    assert done.returncode == 2, done.stderr
    (line,) = done.stderr.splitlines()
    assert line.startswith("boom-sim: error: ") and says in line


def test_ctrl_c_twice_ends_it_cleanly_with_the_bag_the_node_would_record(tmp_path):
    bag = tmp_path / "live_bag"
    live = LiveServer("--record", str(bag), "--max-catch-up-s", "10")  # a loaded machine's late ticks catch up
    try:
        with FoxgloveClient(live.port) as client:
            client.subscribe("/drive_state")
            _, start = client.next_message("/drive_state")
            client.advertise(1, "/commands", "json", "std_msgs/msg/Float64MultiArray")
            client.publish(1, {"data": [0.8]})
            client.until("/drive_state", lambda s: s.rod_position_m > start.rod_position_m + 0.01)
            client.set_parameters("s1", payload_mass_kg=150.0)
            client.status(lambda m: m["message"].startswith("parameters changed"))
    finally:
        live.interrupt()
        live.interrupt()  # a second Ctrl-C while it finishes: it still ends cleanly
        status, out, err = live.wait()
    assert status == 0, err
    assert f"boom-sim live: bag {bag} (" in out and "Traceback" not in err
    counts = check_bag(bag)  # CRC-checked MCAP, log times, metadata.yaml, readable by rosbags
    node_topics = {"/drive_state", "/joint_states", "/piston_pressure", "/rod_pressure", "/rod_force", "/hinge_wrench"}
    assert node_topics | {"/boom_sim/markers", "/robot_description", "/diagnostics"} <= set(counts)
    assert counts["/commands"] == 1 and counts["/parameter_events"] == 1 and "/tf" not in counts
    info = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert info["custom_data"]["node"] == "/boom_sim" and info["ros_distro"] == "jazzy"
    # boom-resim takes it as one of the node's bags: the commands and the parameter change through
    # the model again give the recorded run, to within the motion of one tick
    check_resim_within_a_tick(bag, tmp_path / "again")


def test_a_recorded_target_move_resimulates_exactly(tmp_path):
    """A bag with a target move and no valve command: boom-resim's controller follows the path
    the run told (/boom_sim/setpoint_path) from the same instant, so the run comes back to 1e-9 m
    at every recorded state (not only to within a tick, as an unstamped valve command does)."""
    bag = tmp_path / "target_bag"
    live = LiveServer("--record", str(bag), "--max-catch-up-s", "10")  # a loaded machine's late ticks catch up
    try:
        with FoxgloveClient(live.port) as client:
            client.subscribe("/drive_state")
            client.next_message("/drive_state")
            _advertise_target(client)
            _target(client, 15.0)
            client.until("/drive_state", lambda s: abs(math.degrees(s.boom_angle_rad) - 15.0) < 0.5)
    finally:
        live.interrupt()
        status, _, err = live.wait()
    assert status == 0, err
    assert check_bag(bag)["/boom_sim/setpoint_path"] == 1
    again = tmp_path / "again"
    done = subprocess.run(["boom-resim", str(bag), "--out", str(again)], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    recorded, repeated = read_drive_states(bag), read_drive_states(again)
    assert len(repeated["q1"]) == len(recorded["q1"])
    assert np.max(np.abs(repeated["q1"] - recorded["q1"])) < 1e-9


def test_the_parameters_offered_are_the_ones_the_node_declares():
    pytest.importorskip("rclpy")
    from boom_hydraulics.live.parameters import OFFERED
    from boom_hydraulics.ros.node_parameters import MODEL_NAMES

    assert OFFERED == MODEL_NAMES


def test_paper_mode_goes_live_too_without_a_battery():
    """Paper mode has no battery (its battery outputs are NaN): its states still reach the client."""
    live = LiveServer("--config", str(ROOT / "config" / "paper_fig8.yaml"))
    try:
        with FoxgloveClient(live.port) as client:
            client.subscribe("/drive_state")
            _, state = client.next_message("/drive_state")
    finally:
        live.interrupt()
        status, _, err = live.wait()
    assert math.isfinite(state.rod_position_m) and state.rod_pressure_pa == 0.0
    assert status == 0, err


@pytest.fixture
def small_disk(tmp_path):
    """A 300 KiB file system: a live run's bag fills it within its first seconds."""
    with small_tmpfs(tmp_path / "disk", "300k") as disk:
        yield disk


def test_a_full_disk_is_said_at_once_in_one_line_and_the_run_goes_on(small_disk):
    """As the node does: the moment the disk fills, one error line on stderr (it said nothing
    until Ctrl-C), the run goes on publishing, and Ctrl-C ends it with status 1 and the bag left
    for boom-bag-recover."""
    bag = small_disk / "live_bag"
    live = LiveServer("--record", str(bag))
    try:
        # the first thing it says after 'serving': the disk is full (the guard: it said nothing until Ctrl-C)
        ready, _, _ = select.select([live.proc.stderr], [], [], 120.0)
        assert ready, "boom-sim live said nothing of the full disk"
        said = live.proc.stderr.readline()
        assert said.startswith("boom-sim live: error: recording stopped: ") and "No space left on device" in said
        assert said.rstrip().endswith("the simulation goes on"), said
        with FoxgloveClient(live.port) as client:
            client.subscribe("/drive_state")
            client.next_message("/drive_state")  # it still publishes
    finally:
        live.interrupt()
        status, _, err = live.wait()
    assert status == 1, err
    assert "Traceback" not in err
    assert sum("recording stopped:" in line for line in [said, *err.splitlines()]) == 1
    assert "boom-sim live: error: recording failed: " in err
