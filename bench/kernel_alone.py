"""The batches of boom-sweep's grid of a 5 s lift through the run kernel alone, and no more.

The reference a sweep's share of the kernel's throughput is measured against (bench_speed).

    python bench/kernel_alone.py SIDE     # the side x side grid in this new process; prints the plan's seconds

Run as a program, it is what a process does to give the sweep's numbers and no more: Python,
numpy, numba and its registries, the kernel loaded from the cache, the batches two at a time
as boom-sweep runs them (its LocalExecutor: a batch's Python beside the other's kernel), the
exit; its heap is frozen from the plan on, as boom-sweep's is. It prints the seconds its plan
took on a line of its own (``kernel_alone: plan_s=...``; the plan is boom-sweep's own work, as
storage and the table are), so that the caller can take them from the process's wall time.
It imports only the model and the sweep's planning and executor, so that the environment of
a checkout since b3199a5 (sweep.load_kernel, LocalExecutor's ``load``) can run it.
"""

from __future__ import annotations

import argparse
import gc
import sys
import time

from boom_hydraulics.model.parameters import Parameters
from boom_hydraulics.sweeps import sweep
from boom_hydraulics.sweeps.executors import LocalExecutor
from boom_hydraulics.sweeps.sampling import parse_axis

DURATION_S = 5.0


def grid_axes(side: int) -> list[str]:
    """The axes of the side x side grid, as boom-sweep's --vary takes them."""
    return [f"piston_diameter=0.032:0.1:{side}", f"payload=0:200:{side}"]


def grid_plan(side: int) -> sweep.Plan:
    """boom-sweep's plan of the grid (its default batch size)."""
    axes = [parse_axis(axis) for axis in grid_axes(side)]
    return sweep.plan(sweep.request([("default", Parameters())], axes, duration_s=DURATION_S))


def batches_s(plan: sweep.Plan) -> float:
    """Seconds the plan's batches take through sweep.run_batch alone (the run kernel and the
    batch's metrics, nothing else of boom-sweep), one after the other in this thread. What this
    process holds is out of the garbage collector's walks meanwhile, as boom-sweep's plan is
    during its batches (runner._frozen_heap)."""
    gc.freeze()
    try:
        t0 = time.perf_counter()
        done = sum(len(sweep.run_batch(batch)["point"]) for batch in plan.batches)
        seconds = time.perf_counter() - t0
    finally:
        gc.unfreeze()
    assert done == len(plan.points)
    return seconds


#: The line the program prints its plan's seconds on (stderr), and how a caller finds it.
PLAN_LINE = "kernel_alone: plan_s={:.6f}"
PLAN_PATTERN = r"^kernel_alone: plan_s=([0-9.]+)$"


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("side", type=int, help="points along each of the grid's two axes (100: 10 000 points)")
    side = parser.parse_args().side
    started = time.perf_counter()
    plan = grid_plan(side)
    plan_s = time.perf_counter() - started
    gc.freeze()  # from the plan on, as boom-sweep's heap is (runner._frozen_heap): the kernel's load too
    with LocalExecutor(load=sweep.load_kernel) as executor:
        done = sum(len(rows["point"]) for _, rows in executor.map(sweep.run_batch, plan.batches))
    assert done == len(plan.points)
    print(PLAN_LINE.format(plan_s), file=sys.stderr, flush=True)
    gc.freeze()  # Python's shutdown then skips numba's objects, as boom-sweep's does (entry_points)
