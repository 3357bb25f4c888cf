"""The node's messages: each field from its own output, the boom torque, delivery between processes."""

from __future__ import annotations

import math
import subprocess
import sys
import textwrap
import time

import pytest

rclpy = pytest.importorskip("rclpy")
from builtin_interfaces.msg import Time  # noqa: E402
from geometry_msgs.msg import WrenchStamped  # noqa: E402
from rclpy.serialization import deserialize_message, serialize_message  # noqa: E402
from rosgraph_msgs.msg import Clock  # noqa: E402
from sensor_msgs.msg import FluidPressure, JointState  # noqa: E402

from boom_hydraulics.bags import cdr, messages  # noqa: E402
from boom_hydraulics.bags.encoding import DRIVE_STATE_FIELDS, drive_state_cdr, setpoint_cdr  # noqa: E402
from boom_hydraulics.model.geometry import boom_angle_rad  # noqa: E402
from boom_hydraulics.model.kinematics import chain  # noqa: E402
from boom_hydraulics.model.outputs import PUBLISHED_NAMES  # noqa: E402
from boom_hydraulics.model.parameters import Parameters, with_updates  # noqa: E402
from boom_hydraulics.solve.simulation import Simulator  # noqa: E402
from boom_hydraulics_msgs.msg import DriveState, ValveCommand  # noqa: E402


def _distinct_published() -> list[float]:
    """Everything a state publishes (Simulator.published), each with a value no other has: a
    swapped field shows."""
    values = {name: 1000.0 + i + 0.25 for i, name in enumerate(PUBLISHED_NAMES)}
    values.update(q1=1.42, at_end_stop=1.0, cavitation=0.0, relief_open=1.0, finite=1.0)
    return [values[name] for name in PUBLISHED_NAMES]


def test_every_drive_state_field_carries_its_own_output():
    values = _distinct_published()
    out = messages.by_name(values)
    ns = 12 * 10**9 + 5
    msg = deserialize_message(messages.drive_state(values, ns), DriveState)
    assert set(DRIVE_STATE_FIELDS) == set(DriveState.get_fields_and_field_types()) - {"header"}
    for field, name in DRIVE_STATE_FIELDS.items():
        assert getattr(msg, field) == out[name], field
    assert (msg.at_end_stop, msg.cavitation, msg.relief_open) == (True, False, True)
    assert msg.header.stamp == Time(sec=12, nanosec=5) and msg.header.frame_id == "base_link"
    # the same length as rclpy's serializer gives (the packing's alignment is CDR's)
    assert len(messages.drive_state(values, ns)) == len(serialize_message(msg))


@pytest.mark.parametrize("jit", [True, False])
def test_the_node_and_boom_resim_pack_one_drive_state_for_one_instant(jit):
    """The node packs what a state publishes (one compiled call), boom-resim the outputs by
    name: the same bytes, compiled and interpreted."""
    sim = Simulator(Parameters(), jit=jit)
    sim.step(0.6, 300)  # lifting, every output in motion
    ns = 3 * 10**9 + 1
    assert messages.drive_state(sim.published(), ns) == drive_state_cdr(sim.outputs(), ns)
    assert messages.finite(sim.published())


@pytest.mark.parametrize("jit", [True, False])
def test_a_tick_carries_the_outputs_by_name_and_the_joints_of_the_geometry(jit):
    """Every message of a tick (TickMessages, as the node packs it from one compiled call)
    against what the outputs by name give: the pressures and the force, the markers as
    boom-sim live draws them, and the cylinder barrel's angle and rate worked out again from
    the points A and K of model.kinematics (and the rate by finite differences)."""
    from boom_hydraulics.bags.markers import crane_markers
    from boom_hydraulics.model.kinematics import along_boom_xz, base_xz

    p = Parameters()
    sim = Simulator(p, jit=jit)
    sim.step(0.6, 300)
    ns = 4 * 10**9 + 3
    packed = messages.TickMessages(p).state(sim.published(), ns, markers=True)
    out = sim.outputs()
    assert packed[-1] == crane_markers(out, ns, p)
    piston, rod = (deserialize_message(data, FluidPressure) for data in packed[2:4])
    force = deserialize_message(packed[4], WrenchStamped).wrench.force
    assert (piston.fluid_pressure, rod.fluid_pressure, force.x) == (out["p1"], out["p2"], out["f_hyd"])

    def barrel(q1: float) -> float:
        (kx, kz), (ax, az) = along_boom_xz(p, boom_angle_rad(q1, p.a_m, p.b_m, p.support_height_m), p.a_m), base_xz(p)
        return math.atan2(kz - az, kx - ax)

    joints = deserialize_message(packed[1], JointState)
    h = 1e-6
    assert joints.position[1] == pytest.approx(barrel(out["q1"]), rel=1e-12)
    rate = (barrel(out["q1"] + h) - barrel(out["q1"] - h)) / (2 * h) * out["v"]
    assert joints.velocity[1] == pytest.approx(rate, rel=1e-6)


@pytest.mark.parametrize("jit", [True, False])
def test_a_state_with_a_nan_is_not_published_and_paper_modes_battery_is_not_asked(jit):
    """The node publishes nothing of a state with a NaN among its published outputs; the
    battery's outputs, NaN in paper mode (no battery), are not among them."""
    paper = Simulator(with_updates(Parameters(), mode="paper"), jit=jit)
    values = paper.published()
    assert math.isnan(messages.by_name(values)["battery_power"]) and messages.finite(values)
    sim = Simulator(Parameters(), jit=jit)
    sim.y = [sim.y[0], math.nan, *sim.y[2:]]  # the rod's velocity
    assert not messages.finite(sim.published())


def test_joint_effort_is_the_boom_torque_and_pressures_keep_their_chambers():
    values = _distinct_published()
    out = messages.by_name(values)
    piston, rod = (deserialize_message(data, FluidPressure) for data in messages.state_messages(values, 0)[2:4])
    assert (piston.fluid_pressure, piston.header.frame_id) == (out["p1"], "piston_chamber")
    assert (rod.fluid_pressure, rod.header.frame_id) == (out["p2"], "rod_chamber")
    force = deserialize_message(messages.state_messages(values, 0)[4], WrenchStamped)
    assert (force.wrench.force.x, force.header.frame_id) == (out["f_hyd"], "cylinder_rod")
    joints = deserialize_message(messages.joint_state(values, 7), JointState)
    assert joints.position.tolist() == [out["alpha"], out["barrel"], out["q1"]]
    assert joints.velocity.tolist() == [out["alpha_rate"], out["barrel_rate"], out["v"]]
    assert joints.effort.tolist() == [out["f_hyd"] / out["lever"], 0.0, out["f_hyd"]]
    # a real instant: the joints consistent with each other (model.kinematics), and the boom's
    # torque by virtual work, torque * d(alpha) = force * dq1, with d(alpha)/dq1 by finite differences
    p = Parameters()
    sim = Simulator(p)
    sim.step(0.6, 300)
    data = messages.joint_state(sim.published(), 7)
    joints = deserialize_message(data, JointState)
    assert len(data) == len(serialize_message(joints)) and joints.header.stamp == Time(sec=0, nanosec=7)
    assert joints.name == ["boom_joint", "cylinder_barrel_joint", "cylinder_joint"]
    out = sim.outputs()
    c = chain(p, out["q1"], out["v"])
    assert joints.position.tolist() == [out["alpha"], c.barrel_rad, out["q1"]]
    assert joints.velocity.tolist() == [out["alpha_rate"], c.barrel_rate_rad_s, out["v"]]
    h = 1e-6
    k = (
        boom_angle_rad(out["q1"] + h, p.a_m, p.b_m, p.support_height_m)
        - boom_angle_rad(out["q1"] - h, p.a_m, p.b_m, p.support_height_m)
    ) / (2 * h)
    assert joints.effort[0] == pytest.approx(out["f_hyd"] / k, rel=1e-6)
    assert joints.effort[2] == out["f_hyd"]


def test_packed_messages_read_back_in_rosbags_as_in_rclpy():
    """The hand-packed CDR is canonical: rosbags (strict about padding) reads what rclpy reads,
    also the setpoint's JointState with its empty effort."""
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_JAZZY)
    setpoint = store.deserialize_cdr(setpoint_cdr("boom_joint", 0.5, -0.25, 3 * 10**9), "sensor_msgs/msg/JointState")
    assert (setpoint.name, list(setpoint.position), list(setpoint.velocity)) == (["boom_joint"], [0.5], [-0.25])
    assert len(setpoint.effort) == 0 and setpoint.header.stamp.sec == 3
    joints = store.deserialize_cdr(messages.joint_state(_distinct_published(), 0), "sensor_msgs/msg/JointState")
    assert joints.name == ["boom_joint", "cylinder_barrel_joint", "cylinder_joint"] and len(joints.effort) == 3
    clock = deserialize_message(cdr.clock(5 * 10**9 + 1), Clock)
    assert (clock.clock.sec, clock.clock.nanosec) == (5, 1)


@pytest.mark.parametrize("length", range(21))
def test_a_valve_command_reads_as_rclpy_reads_it(length):
    """The node reads a command's stamp and opening from its bytes (no message object): the
    same as rclpy's deserialisation, whatever the frame id's length does to the alignment; bytes
    in another encoding, or cut short, are left to rclpy."""
    import struct

    from boom_hydraulics.ros.commands import read_valve_command
    from boom_hydraulics_msgs.msg import ValveCommand

    command = ValveCommand(opening=-0.375)
    command.header.stamp, command.header.frame_id = Time(sec=1_765_000_123, nanosec=999_999_999), "f" * length
    data = serialize_message(command)
    assert cdr.valve_command(data) == (cdr.Stamp(1_765_000_123, 999_999_999), -0.375)
    assert cdr.valve_command(data[: len(data) - 1]) is None
    # the same command in big-endian CDR: rclpy reads it for the node
    frame = b"f" * length + b"\x00"
    pad = b"\x00" * ((-(12 + len(frame))) % 8)
    big = b"\x00\x00\x00\x00" + struct.pack(">iII", 1_765_000_123, 999_999_999, len(frame)) + frame + pad
    big += struct.pack(">d", -0.375)
    assert cdr.valve_command(big) is None
    stamp, opening = read_valve_command(big)
    assert (stamp.sec, stamp.nanosec, opening) == (1_765_000_123, 999_999_999, -0.375)


def test_packed_energy_ledger_is_the_canonical_cdr_of_the_same_message():
    """The EnergyLedger the node packs is byte for byte what rosbags' serializer writes for the
    same message, and rclpy reads each field back, every term with its own power and energy."""
    import numpy as np

    from boom_hydraulics.bags.encoding import ENERGY_LEDGER, message, stamp, to_cdr
    from boom_hydraulics.bags.energy import LedgerNow, energy_ledger_cdr
    from boom_hydraulics.model import ledger
    from boom_hydraulics_msgs.msg import EnergyLedger

    names = ledger.TERM_NAMES
    power = {name: 10.0 + i + 0.5 for i, name in enumerate(names)}
    energy = {name: 100.0 + i + 0.25 for i, name in enumerate(names)}
    energy.update(battery_drawn=5.5, battery_returned=1.25, lift_work=3.0)
    integrals = [5.5 - 1.25 if name == "battery_power" else energy[name] for name in names]
    packed = energy_ledger_cdr(LedgerNow(power, energy, 0.8), 12 * 10**9 + 7)
    expected = message(
        ENERGY_LEDGER,
        header={"stamp": stamp(12 * 10**9 + 7)},
        state_of_charge=0.8,
        battery_power_w=power["battery_power"],
        battery_drawn_j=5.5,
        battery_returned_j=1.25,
        lift_work_j=3.0,
        terms=list(names),
        power_w=np.array([power[name] for name in names]),
        energy_j=np.array(integrals),
    )
    assert packed == to_cdr(expected)
    msg = deserialize_message(packed, EnergyLedger)
    assert msg.header.stamp == Time(sec=12, nanosec=7) and msg.state_of_charge == 0.8
    assert (msg.battery_drawn_j, msg.battery_returned_j, msg.lift_work_j) == (5.5, 1.25, 3.0)
    assert list(msg.terms) == list(names)
    assert list(msg.power_w) == [power[name] for name in names] and list(msg.energy_j) == integrals


def test_a_setpoint_path_reads_in_rclpy_with_where_it_starts_in_a_field_of_its_own():
    """~/setpoint_path as the node packs it (bags.encoding, without rclpy) is what rclpy reads
    into boom_hydraulics_msgs/SetpointPath: where its first point came from in ``start`` (the
    encoder's constants are the message's), the path a JointTrajectory in no frame, stamped
    with the instant taken, its knots' times whole ns; it decodes back to the same path."""
    from boom_hydraulics.bags.encoding import (
        START_BOOM,
        START_OWN,
        START_SETPOINT,
        RecordedPath,
        recorded_path,
        setpoint_path_cdr,
    )
    from boom_hydraulics.model.setpoints import QUINTIC
    from boom_hydraulics_msgs.msg import SetpointPath

    assert (START_OWN, START_SETPOINT, START_BOOM) == (
        SetpointPath.START_OWN,
        SetpointPath.START_SETPOINT,
        SetpointPath.START_BOOM,
    )
    path = RecordedPath(7 * 10**9 + 3, START_BOOM, [0, 250_000_001], [0.25, 0.5], [0.125, 0.0], QUINTIC)
    msg = deserialize_message(setpoint_path_cdr("boom_joint", path), SetpointPath)
    trajectory = msg.trajectory
    assert msg.start == SetpointPath.START_BOOM
    assert trajectory.header.stamp == Time(sec=7, nanosec=3) and trajectory.header.frame_id == ""
    assert list(trajectory.joint_names) == ["boom_joint"]
    assert [(p.time_from_start.sec, p.time_from_start.nanosec) for p in trajectory.points] == [(0, 0), (0, 250_000_001)]
    assert [list(p.positions) for p in trajectory.points] == [[0.25], [0.5]]
    assert [list(p.velocities) for p in trajectory.points] == [[0.125], [0.0]]
    assert recorded_path(msg) == path


PUBLISHER = textwrap.dedent(
    """
    import time, rclpy
    from boom_hydraulics_msgs.msg import ValveCommand
    rclpy.init()
    node = rclpy.create_node("test_publisher")
    pub = node.create_publisher(ValveCommand, "valve_command", 10)
    i = 0
    while True:  # until the test kills it: how long discovery takes is not this test's business
        pub.publish(ValveCommand(opening=0.25 + (i % 50) * 1e-3))
        i += 1
        rclpy.spin_once(node, timeout_sec=0.05)
    """
)


def test_message_crosses_process_boundary():
    """A ValveCommand published by another process arrives here intact."""
    proc = subprocess.Popen([sys.executable, "-c", PUBLISHER])
    rclpy.init()
    node = rclpy.create_node("test_subscriber")
    received: list[float] = []
    node.create_subscription(ValveCommand, "valve_command", lambda m: received.append(m.opening), 10)
    try:
        deadline = time.monotonic() + 120.0  # a guard against a hang, not a timing: waits for 3 messages
        while len(received) < 3 and time.monotonic() < deadline and proc.poll() is None:
            rclpy.spin_once(node, timeout_sec=0.1)
        ended = proc.poll()  # None: it still ran
    finally:
        node.destroy_node()
        rclpy.shutdown()
        proc.kill()
        proc.wait()
    assert len(received) >= 3, f"{len(received)} messages from the publisher process (it ended with {ended})"
    assert all(0.25 <= u < 0.3 for u in received)
