"""Recording benchmarks: the cost of a write on the physics loop, and memory over a long run.

    tools/with-env python bench/bench_recording.py [--sim-seconds 3600]     # about 2-3 minutes

1. In-process: ``BagRecorder.write`` as the node calls it (six messages a tick), p50/p99/max
   per call while the writer thread compresses, and the writer's backlog.
2. The node in its own process, as fast as possible (compiled) with recording on, for an
   hour of simulated time at 100 Hz publishing: its resident memory every five simulated
   minutes, the bag's size, and how long SIGINT takes to finish the file.
"""

from __future__ import annotations

import argparse
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import rclpy
from rosgraph_msgs.msg import Clock

from boom_hydraulics.bags.messages import drive_state
from boom_hydraulics.bags.recording import BagRecorder, Topic
from boom_hydraulics.model.parameters import Parameters
from boom_hydraulics.solve.simulation import Simulator

CONFIG = Path(__file__).resolve().parents[1] / "config" / "default.yaml"


def rss_mib(pid: int) -> float:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    return float("nan")


def write_latency(ticks: int) -> None:
    sim = Simulator(Parameters())
    data = drive_state(sim.published(), 0)
    folder = Path(tempfile.mkdtemp()) / "bag"
    topics = [Topic(f"/t{i}", "boom_hydraulics_msgs/msg/DriveState") for i in range(6)]
    recorder = BagRecorder(folder, topics)
    times = np.empty(ticks * 6)
    backlog = 0
    for k in range(ticks):
        for i in range(6):
            t0 = time.perf_counter()
            recorder.write(f"/t{i}", k * 10_000_000, data)
            times[k * 6 + i] = time.perf_counter() - t0
        if k % 1000 == 0:
            backlog = max(backlog, recorder._queue.qsize())
            time.sleep(0.001)  # the node ticks every 10 ms; leave the writer some time
    t0 = time.perf_counter()
    recorder.close()
    close_s = time.perf_counter() - t0
    us = times * 1e6
    print(f"\nBagRecorder.write, {ticks} ticks x 6 DriveState messages ({len(data)} bytes each)")
    print(f"  per call p50 {np.percentile(us, 50):.2f} us, p99 {np.percentile(us, 99):.2f} us, max {us.max():.0f} us")
    print(f"  largest writer backlog {backlog} messages; close (drain + finish) {close_s:.2f} s")
    shutil.rmtree(folder.parent)


def long_run(sim_seconds: float) -> None:
    folder = Path(tempfile.mkdtemp())
    proc = subprocess.Popen(
        [
            shutil.which("boom_sim"),
            "--ros-args",
            "--params-file",
            str(CONFIG),
            "-p",
            "publish_clock:=true",
            "-p",
            "real_time_factor:=0.0",
            "-p",
            "jit:=true",
            "-p",
            f"record_folder:={folder}",
            "-p",
            "command_timeout_s:=0.0",
        ],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    rclpy.init()
    node = rclpy.create_node("bench_recording")
    now = [0.0]
    node.create_subscription(Clock, "/clock", lambda m: now.__setitem__(0, m.clock.sec + m.clock.nanosec * 1e-9), 10)
    samples = []
    next_sample = 0.0
    wall0 = time.monotonic()
    while now[0] < sim_seconds and time.monotonic() - wall0 < 1800:
        rclpy.spin_once(node, timeout_sec=0.1)
        if now[0] >= next_sample and now[0] > 0:
            samples.append((now[0], rss_mib(proc.pid)))
            next_sample += 300.0
    samples.append((now[0], rss_mib(proc.pid)))
    wall = time.monotonic() - wall0
    t0 = time.monotonic()
    proc.send_signal(signal.SIGINT)
    proc.wait(timeout=120)
    finish = time.monotonic() - t0
    node.destroy_node()
    rclpy.shutdown()
    size = sum(f.stat().st_size for f in folder.rglob("*.mcap")) / 2**20
    print(f"\nNode, as fast as possible (compiled), recording: {now[0]:.0f} s simulated in {wall:.0f} s")
    print("  sim time [s]  RSS [MiB]")
    for t, rss in samples:
        print(f"  {t:11.0f}  {rss:9.1f}")
    growth = samples[-1][1] - samples[1][1] if len(samples) > 2 else float("nan")
    print(f"  growth from 5 min to the end: {growth:+.1f} MiB (target: a few MB over an hour)")
    print(f"  bag size {size:.1f} MiB; SIGINT to exit (file finished) {finish:.2f} s")
    shutil.rmtree(folder)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sim-seconds", type=float, default=3600.0)
    parser.add_argument("--ticks", type=int, default=100_000)
    args = parser.parse_args()
    write_latency(args.ticks)
    long_run(args.sim_seconds)
    return 0


if __name__ == "__main__":
    sys.exit(main())
