"""Speed and memory targets side by side: every row of the performance table in one run.

    tools/with-env python bench/bench_speed.py [--seconds 20]     # about five minutes

Runs the measurements of bench_model, bench_node and bench_sweep that the targets name
(each prints its own table as it goes), then one table: what was measured, the target,
and whether it is met. scipy's LSODA and RK45 are timed on the same 1.5 s lift at the
accuracy RK4 reaches at 1 ms. Nothing is asserted: these machines are shared and noisy.
The table, with the date, the machine and the commit, is also written to
bench/results/speed-<UTC date-time>.md.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import time

import rclpy
from bench_model import batch_throughput, scipy_comparison, step_cost
from bench_node import BAGS, in_process_rates, print_real_time, real_time_run
from bench_sweep import full_sweep
from tables import table, write_results

from boom_hydraulics.solve import accelerate

FIRST_START = """
import time
t0 = time.perf_counter()
from boom_hydraulics.model.parameters import Parameters
from boom_hydraulics.solve.simulation import Simulator
imported = time.perf_counter()
Simulator(Parameters(), jit=True).step(0.5, 10)
print(time.perf_counter() - imported)
"""


def first_start_s() -> float:
    """Seconds to the first compiled steps in a new process (after imports), cache warm."""
    times = []
    for _ in range(3):  # the first may fill the cache
        out = subprocess.run([sys.executable, "-c", FIRST_START], capture_output=True, text=True, check=True)
        times.append(float(out.stdout))
    return min(times[1:])


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=20.0, help="length of each real-time node run")
    args = parser.parse_args()
    if not accelerate.available():
        print("numba is not available: the compiled rows cannot be measured")
        return 1
    rows: list[list[str]] = []

    def row(what: str, now: str, target: str, met: bool) -> None:
        rows.append([what, now, target, "yes" if met else "NO"])

    costs = step_cost()
    row(
        "physical RK4 step, compiled / interpreted",
        f"{costs[('physical', True)]:.2f} us / {costs[('physical', False)]:.1f} us",
        "<= 0.5 us compiled",
        costs[("physical", True)] <= 0.5,
    )
    start = first_start_s()
    row("first compiled steps in a new process, cache warm", f"{start:.2f} s", "<= 1 s", start <= 1.0)

    rclpy.init()
    try:
        cpu = {}
        for jit in (False, True):
            run = real_time_run(args.seconds, jit)
            print_real_time(run, args.seconds, jit)
            cpu[jit] = run.cpu
        rates = in_process_rates()
    finally:
        rclpy.try_shutdown()
        shutil.rmtree(BAGS, ignore_errors=True)
    row(
        "node CPU at real time (100 Hz, 1 ms RK4), compiled / interpreted",
        f"{cpu[True] * 100:.1f} % / {cpu[False] * 100:.1f} %",
        "<= 8 %",
        cpu[True] <= 0.08,
    )
    row(
        "node as fast as possible, publishing every 10 ms, compiled / interpreted",
        f"{rates[True][1]:.0f}x / {rates[False][1]:.0f}x",
        ">= 100x",
        rates[True][1] >= 100,
    )

    lift = scipy_comparison()
    fastest_scipy = min(lift.get("LSODA", float("inf")), lift.get("RK45", float("inf")))
    row(
        "1.5 s lift at matched accuracy, whole call: rk4 compiled / LSODA / RK45 (relative error on q1)",
        f"{lift['rk4 compiled'] * 1e3:.1f} ms ({lift['rk4 error']:.0e}) / "
        f"{lift.get('LSODA', float('nan')) * 1e3:.1f} ms ({lift.get('LSODA error', float('nan')):.0e}) / "
        f"{lift.get('RK45', float('nan')) * 1e3:.1f} ms ({lift.get('RK45 error', float('nan')):.0e})",
        "<= 3 ms, >= 5x faster than LSODA",
        lift["rk4 compiled"] <= 3e-3 and lift["rk4 compiled"] * 5 <= fastest_scipy,
    )

    throughput = batch_throughput()
    row(
        "batched physical RK4, N = 10 000: compiled kernel / interpreted (N = 10)",
        f"{throughput['compiled kernel']:.2f} M / {throughput['interpreted']:.3f} M state-steps/s",
        ">= 5 M on 2 cores",
        throughput["compiled kernel"] >= 5.0,
    )

    sweeps = {}
    for label, workers, side in (("1000", None, 32), ("10000", None, 100), ("10000 workers", 2, 100)):
        t0 = time.perf_counter()
        sweeps[label] = full_sweep(workers, side)
        print(f"boom-sweep {label}: {time.perf_counter() - t0:.1f} s")
    row(
        "boom-sweep of 10 000 points, 5 s lift: this process / --workers 2",
        f"{sweeps['10000'][0]:.1f} s / {sweeps['10000 workers'][0]:.1f} s",
        "<= 15 s on 2 cores",
        min(sweeps["10000"][0], sweeps["10000 workers"][0]) <= 15.0,
    )
    small, large = sweeps["1000"][1], sweeps["10000"][1]
    row(
        "boom-sweep peak memory: 1000 / 10 000 points",
        f"{small:.0f} MB / {large:.0f} MB",
        "O(points), not O(points x steps)",
        large < 2 * small,  # 10x the points: the table grows, the batches do not
    )
    text = table(
        f"Speed and memory targets ({os.cpu_count()} cores; measured in this run)",
        ["what", "measured", "target", "met"],
        rows,
    )
    print(f"written to {write_results('speed', text)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
