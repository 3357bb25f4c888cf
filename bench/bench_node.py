"""Node benchmarks: CPU share, publish jitter and clock lock at real time; fastest real-time factor.

    tools/with-env python bench/bench_node.py [--seconds 60]     # about three minutes

1. The node in its own process at real-time factor 1 (100 Hz publishing, 1 ms RK4
   physics, interpreted and compiled): its CPU share of one core (from /proc), the
   period between consecutive drive_state stamps (the node's clock at publish: p50, p99,
   max) and how far simulated time trails the steady clock (the node's diagnostics).
2. The node's stepping in this process, without DDS: simulated seconds per wall second
   of ``advance`` alone (no publishing) and of the as-fast-as-possible tick (advance +
   publish), interpreted and compiled.
3. Where a tick's time goes (recording on, as by default): stepping, the model's outputs,
   building each message, serialising, publishing and recording, per tick of 10 steps.

Bags go to a temporary folder and are removed.
"""

from __future__ import annotations

import argparse
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from collections import defaultdict
from collections.abc import Callable
from pathlib import Path

import numpy as np
import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from rclpy.qos import QoSProfile, ReliabilityPolicy

from boom_hydraulics.bags import messages
from boom_hydraulics.ros import node as node_module
from boom_hydraulics.ros import recording as recording_module
from boom_hydraulics.ros.node import BoomSimNode
from boom_hydraulics_msgs.msg import DriveState, ValveCommand

CONFIG = Path(__file__).resolve().parents[1] / "config" / "default.yaml"
BAGS = Path(tempfile.mkdtemp(prefix="bench_node_bags."))  # removed at the end
ARGS = ["--ros-args", "-p", f"record_folder:={BAGS}"]


def cpu_seconds(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")  # utime + stime


def real_time_run(seconds: float, jit: bool) -> float:
    """Print the real-time figures of one run; return its CPU share of one core."""
    exe = shutil.which("boom_sim")
    proc = subprocess.Popen(
        [
            exe,
            "--ros-args",
            "--params-file",
            str(CONFIG),
            "-p",
            "command_timeout_s:=0.0",
            "-p",
            f"jit:={str(jit).lower()}",
            "-p",
            f"record_folder:={BAGS}",
        ],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    node = rclpy.create_node("bench_node_client")
    stamps: list[float] = []
    clock_errors: list[float] = []

    def on_state(msg: DriveState) -> None:
        stamps.append(msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9)  # node's clock at publish

    def on_diagnostics(msg: DiagnosticArray) -> None:
        for status in msg.status:
            for kv in status.values:
                if kv.key == "clock_error_s":
                    clock_errors.append(float(kv.value))

    qos = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
    node.create_subscription(DriveState, "drive_state", on_state, qos)
    node.create_subscription(DiagnosticArray, "/diagnostics", on_diagnostics, qos)
    pub = node.create_publisher(ValveCommand, "valve_command", qos)
    while len(stamps) < 100:  # up and running for a second
        rclpy.spin_once(node, timeout_sec=0.01)
    stamps.clear()
    clock_errors.clear()
    cpu0, wall0 = cpu_seconds(proc.pid), time.monotonic()
    next_command = wall0
    while time.monotonic() - wall0 < seconds:
        if time.monotonic() >= next_command:  # a slow lift-and-lower sine at 20 Hz keeps the drive moving
            pub.publish(ValveCommand(opening=0.6 * np.sin(2 * np.pi * 0.1 * (time.monotonic() - wall0))))
            next_command += 0.05
        rclpy.spin_once(node, timeout_sec=0.005)
    cpu = (cpu_seconds(proc.pid) - cpu0) / (time.monotonic() - wall0)
    proc.send_signal(signal.SIGINT)
    proc.wait(timeout=10)
    node.destroy_node()

    period_ms = np.diff(np.array(stamps)) * 1e3
    errors_ms = np.array(clock_errors) * 1e3
    path = "compiled" if jit else "interpreted"
    print(f"\nReal time (factor 1), {seconds:.0f} s, 100 Hz publishing, dt = 1 ms RK4, {path}")
    print(f"  CPU share of one core (all threads)   {cpu * 100:.1f} %   (target <= 8 %)")
    print(f"  drive_state messages                  {len(stamps)} (expected {seconds * 100:.0f})")
    print(
        f"  publish period (node stamps)          p50 {np.percentile(period_ms, 50):.2f} ms, "
        f"p99 {np.percentile(period_ms, 99):.2f} ms, max {period_ms.max():.2f} ms   (target p99 <= 12 ms)"
    )
    print(
        f"  sim time behind steady clock at tick  last {errors_ms[-1]:.3f} ms, largest {errors_ms.max():.3f} ms "
        f"(1 Hz samples; target within 1 ms after 60 s)"
    )
    return cpu


def in_process_rates() -> dict[bool, tuple[float, float]]:
    """Print and return {jit: (advance-only rate, tick rate)} in simulated s per wall s."""
    rates = {}
    print("\nNode stepping in-process (no DDS subscriber), simulated s per wall s")
    print("  path         advance only   tick (advance + publish every 10 ms sim)")
    for jit in (False, True):
        rclpy.try_shutdown()
        rclpy.init(args=[*ARGS, "-p", f"jit:={str(jit).lower()}", "-p", "real_time_factor:=0.0"])
        node = BoomSimNode()
        node.drive.current = 0.3
        n = 20_000 if jit else 5_000
        t0 = time.perf_counter()
        node.advance(n)
        advance_rate = n * 1e-3 / (time.perf_counter() - t0)
        node.sim.reset()
        ticks = 1000 if jit else 200
        t0 = time.perf_counter()
        for _ in range(ticks):
            node.on_tick()  # as fast as possible: 10 steps and a publish per tick
        tick_rate = ticks * 10e-3 / (time.perf_counter() - t0)
        print(f"  {'compiled' if jit else 'interpreted':<12} {advance_rate:>10.0f}x    {tick_rate:>10.0f}x")
        node.destroy_node()
        rates[jit] = (advance_rate, tick_rate)
    return rates


def _timed(owner: object, name: str, label: str, spent: dict[str, float]) -> None:
    """Wrap ``owner.name`` so that its time adds up under ``label``."""
    original: Callable = getattr(owner, name)

    def wrapper(*args, **kwargs):
        t0 = time.perf_counter()
        try:
            return original(*args, **kwargs)
        finally:
            spent[label] += time.perf_counter() - t0

    setattr(owner, name, wrapper)


def tick_breakdown() -> None:
    """Time per tick by stage: each stage's own functions wrapped with a timer."""
    print("\nWhere a tick goes (10 steps and a publish, recording on), us per tick")
    rows = []
    for jit in (False, True):
        rclpy.try_shutdown()
        rclpy.init(args=[*ARGS, "-p", f"jit:={str(jit).lower()}", "-p", "real_time_factor:=0.0"])
        node = BoomSimNode()
        node.drive.current = 0.3
        spent: dict[str, float] = defaultdict(float)
        _timed(node, "advance", "stepping (advance)", spent)
        _timed(node.sim, "outputs", "model outputs", spent)
        for name in ("drive_state", "joint_state", "chamber_pressures", "rod_force"):
            _timed(messages, name, "building messages", spent)
        _timed(node_module, "crane_markers", "building markers (every 5th tick)", spent)
        _timed(recording_module, "serialize_message", "serialising", spent)
        for publisher in (node.state_pub, node.joint_pub, node.p1_pub, node.p2_pub, node.force_pub, node.markers_pub):
            _timed(publisher, "publish", "publishing", spent)
        node.clock.restart()
        node._begin_recording()  # as start() does, without the loop thread
        _timed(node.recording.recorder, "write", "recording", spent)
        ticks = 2000 if jit else 300
        t0 = time.perf_counter()
        for _ in range(ticks):
            node.on_tick()
        total = time.perf_counter() - t0
        spent["rest (tick logic, locks, pacing)"] = max(0.0, total - sum(spent.values()))
        rows.append(("compiled" if jit else "interpreted", total / ticks, dict(spent)))
        node.recording.finish()
        node.destroy()
    labels = list(rows[0][2])
    print(f"  {'stage':<36} {'interpreted':>12} {'compiled':>10}")
    for label in labels:
        values = [f"{r[2].get(label, 0.0) / (2000 if r[0] == 'compiled' else 300) * 1e6:.0f}" for r in rows]
        print(f"  {label:<36} {values[0]:>12} {values[1]:>10}")
    print(f"  {'whole tick':<36} {rows[0][1] * 1e6:>12.0f} {rows[1][1] * 1e6:>10.0f}")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=60.0, help="length of the real-time run")
    args = parser.parse_args()
    rclpy.init()
    real_time_run(args.seconds, jit=False)
    real_time_run(args.seconds, jit=True)
    in_process_rates()
    tick_breakdown()
    rclpy.try_shutdown()
    shutil.rmtree(BAGS, ignore_errors=True)  # created by this run
    return 0


if __name__ == "__main__":
    sys.exit(main())
