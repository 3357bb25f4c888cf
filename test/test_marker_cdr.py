"""The crane's markers as the node publishes them: packed CDR that is rclpy's message, at 20 Hz,
following the parameters."""

from __future__ import annotations

import pytest

rclpy = pytest.importorskip("rclpy")
from builtin_interfaces.msg import Time  # noqa: E402
from geometry_msgs.msg import Point, Quaternion, Vector3  # noqa: E402
from rclpy.serialization import deserialize_message, serialize_message  # noqa: E402
from rosbags.typesys import Stores, get_typestore  # noqa: E402
from std_msgs.msg import ColorRGBA  # noqa: E402
from visualization_msgs.msg import Marker, MarkerArray  # noqa: E402

from boom_hydraulics.bags.cdr import MarkerFields  # noqa: E402
from boom_hydraulics.bags.markers import MARKER_ARRAY, NAMESPACE, CraneMarkers, crane_markers  # noqa: E402
from boom_hydraulics.model.kinematics import chain  # noqa: E402
from boom_hydraulics.model.parameters import Parameters, with_updates  # noqa: E402
from boom_hydraulics.model.robot_description import BASE_FRAME  # noqa: E402

STAMP_NS = 1_764_000_123 * 10**9 + 456_789


def _rclpy_message(markers: list[MarkerFields], stamp: Time) -> MarkerArray:
    """The same markers as rclpy message objects (ADD, in base_link, under the crane's namespace)."""
    array = MarkerArray()
    for f in markers:
        m = Marker(ns=NAMESPACE, id=f.id, type=f.type, action=Marker.ADD, text=f.text)
        m.header.frame_id, m.header.stamp = BASE_FRAME, stamp
        m.pose.position = Point(x=f.position[0], y=f.position[1], z=f.position[2])
        x, y, z, w = f.orientation
        m.pose.orientation = Quaternion(x=x, y=y, z=z, w=w)
        m.scale = Vector3(x=f.scale[0], y=f.scale[1], z=f.scale[2])
        m.color = ColorRGBA(r=f.color[0], g=f.color[1], b=f.color[2], a=f.color[3])
        array.markers.append(m)
    return array


def _outputs(**changes: float) -> dict:
    out = {"q1": 1.5, "v": 0.1, "p1": 8.0e6, "p2": 1.0e5, "void1": 0.0, "void2": 0.0}
    out.update(changes)
    return out


@pytest.mark.parametrize(
    "out",
    [_outputs(), _outputs(q1=1.06, void2=1e-7), _outputs(q1=1.74, p1=18.5e6), _outputs(void1=1e-7, p2=18.5e6)],
    ids=["normal", "rod cavitates", "piston relief", "both flagged"],
)
def test_packed_markers_are_the_bytes_rclpy_serialises_for_the_same_message(out):
    """Every field, every length and every alignment as rclpy's serializer gives them; the
    padding is zero (rclpy leaves in it whatever its buffer held), which is the canonical CDR
    that rosbags writes. The texts differ in length between the cases, so the alignment of
    the markers after them moves."""
    p = Parameters()
    crane = CraneMarkers(p)
    c = chain(p, out["q1"], out["v"])
    packed = crane.cdr(out, c, STAMP_NS)
    assert packed == crane_markers(out, STAMP_NS, p)
    by_rclpy = serialize_message(_rclpy_message(crane.fields(out, c), Time(sec=STAMP_NS // 10**9, nanosec=456_789)))
    assert len(packed) == len(by_rclpy)
    assert deserialize_message(packed, MarkerArray) == deserialize_message(by_rclpy, MarkerArray)
    differing = [i for i, (ours, theirs) in enumerate(zip(packed, by_rclpy)) if ours != theirs]
    assert all(packed[i] == 0 for i in differing), "only rclpy's uninitialised padding may differ"
    store = get_typestore(Stores.ROS2_JAZZY)
    assert bytes(store.serialize_cdr(store.deserialize_cdr(by_rclpy, MARKER_ARRAY), MARKER_ARRAY)) == packed


def _published_markers(node, ticks: int) -> list[tuple[int, MarkerArray]]:
    """(tick, markers) of what the node handed its topics in ``ticks`` ticks."""
    found = []
    for tick in range(ticks):
        sent: list = []
        node.recording.publish = lambda messages, log_ns, sent=sent: sent.extend(messages)
        node.on_tick()
        found += [(tick, deserialize_message(data, MarkerArray)) for pub, data in sent if pub is node.markers_pub]
    return found


@pytest.fixture
def sim_node():
    from boom_hydraulics.ros.node import BoomSimNode

    rclpy.init(args=["--ros-args", "-p", "record:=false", "-p", "real_time_factor:=0.0"])
    node = BoomSimNode()
    yield node
    node.destroy()
    rclpy.shutdown()


def test_the_node_publishes_the_markers_at_20_hz_and_follows_a_new_payload(sim_node):
    """At 100 Hz the markers go with every 5th state; after the payload changes, the sphere
    drawn at the boom tip is the new payload's size."""
    sim_node.drive.current = 0.5  # the boom lifts: the markers move
    before = _published_markers(sim_node, 10)
    assert [tick for tick, _ in before] == [4, 9]
    first, second = (by_id for _, by_id in before)
    assert first.markers[1].pose.position.z < second.markers[1].pose.position.z  # the boom rose
    assert all(m.header.stamp == first.markers[0].header.stamp for m in first.markers)
    payload_diameter = first.markers[2].scale.x
    sim_node.sim.set_parameters(with_updates(sim_node.sim.params, payload_mass_kg=800.0))
    _, after = _published_markers(sim_node, 5)[0]
    assert after.markers[2].scale.x == pytest.approx(payload_diameter * 16 ** (1 / 3), rel=1e-6)  # 16 x the mass
