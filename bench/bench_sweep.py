"""Design-sweep benchmarks: points per second of a 5 s lift at dt = 1 ms, metrics included.

    tools/with-env python bench/bench_sweep.py            # about three minutes
    tools/with-env python bench/bench_sweep.py --full     # plus boom-sweep over 10 000 points and the answer's sweep

Compares the batch paths (the compiled run kernel that boom-sweep runs, and the same run
loop interpreted that it falls back to without numba) with one simulation per point
(interpreted and compiled, metrics from the stored run) and with one scipy solve_ivp per point. Prints
tables; nothing is asserted (these machines are shared and noisy).
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from kernel_alone import DURATION_S, PLAN_PATTERN, batches_s, grid_axes, grid_plan
from scipy.integrate import solve_ivp
from tables import ROOT, table

from boom_hydraulics.analysis import metrics as analysis
from boom_hydraulics.model import physical
from boom_hydraulics.model.parameters import Parameters
from boom_hydraulics.solve import accelerate, commands
from boom_hydraulics.solve.simulation import simulate
from boom_hydraulics.sweeps import sweep
from boom_hydraulics.sweeps.executors import DaskExecutor, LocalExecutor
from boom_hydraulics.sweeps.sampling import parse_axis

OPEN_S = 2.5  # the lift scenario: valve open for the first half, then closed
AXES = [parse_axis("piston_diameter=0.032:0.1:40"), parse_axis("payload=0:200:25")]  # 1000 points


def sweep_plan(points: int, batch_size: int) -> sweep.Plan:
    plan = sweep.plan(sweep.request([("default", Parameters())], AXES, duration_s=DURATION_S, batch_size=batch_size))
    keep = [b for b in plan.batches if b.points[0] < points]
    return sweep.Plan(plan.request, plan.columns, plan.points, plan.invalid, tuple(keep))


def vectorised(points: int, batch_size: int, executor) -> float:
    """Seconds to run ``points`` points of the plan through ``executor`` in batches."""
    plan = sweep_plan(points, batch_size)
    t0 = time.perf_counter()
    with executor:
        done = sum(len(b.points) for b, _ in executor.map(sweep.run_batch, plan.batches))
    assert done == points
    return time.perf_counter() - t0


def one_at_a_time(points: int, jit: bool) -> float:
    plan = sweep_plan(1000, 1000)
    params = plan.batches[0].params[:points]
    if jit:
        simulate(params[0], 0.01, jit=True)  # compile outside the timing
    t0 = time.perf_counter()
    for p in params:
        run = simulate(p, DURATION_S, commands.from_parameters(p), jit=jit)
        analysis.metrics(run.columns)
    return time.perf_counter() - t0


def with_solve_ivp(points: int, method: str) -> float:
    """One solve_ivp per point, in two pieces around the valve closing, output every 1 ms."""
    plan = sweep_plan(1000, 1000)
    params = plan.batches[0].params[:points]
    t0 = time.perf_counter()
    for p in params:
        c = physical.constants(p)
        y = physical.initial_state(p)
        for (start, stop), u in (((0.0, OPEN_S), 1.0), ((OPEN_S, DURATION_S), 0.0)):
            t_eval = np.arange(start, stop + 1e-12, 1e-3)
            sol = solve_ivp(
                lambda t, y, u=u, c=c: physical.derivative(t, list(y), c, u),
                (start, stop),
                y,
                method=method,
                rtol=1e-6,
                atol=[1e-9, 1e-9, 1.0, 1.0, 1e-9, 1e-3, 1e-3, 1e-9, 1e-3, 1e-3],
                t_eval=t_eval,
            )
            y = sol.y[:, -1]
    return time.perf_counter() - t0


def full_sweep(
    workers: int | None, side: int = 100, plots: bool = False, checkout: Path | None = None
) -> tuple[float, float]:
    """boom-sweep over side x side points of a 5 s lift, start to finish, with its plots or
    without: (seconds, peak resident memory of the boom-sweep process in MB; with workers, of
    the parent alone). ``checkout``: that built checkout's boom-sweep, in its environment."""
    out = Path(tempfile.mkdtemp(prefix="bench-sweep-"))
    args = [shutil.which("boom-sweep")] if checkout is None else [str(checkout / "tools" / "with-env"), "boom-sweep"]
    for axis in grid_axes(side):
        args += ["--vary", axis]
    args += ["--duration", f"{DURATION_S:g}", "--out", str(out / "s"), "--no-progress"]
    args += [] if plots else ["--no-plots"]
    if workers:
        args += ["--workers", str(workers)]
    seconds, peak_mb, _ = timed(args, "boom-sweep")
    shutil.rmtree(out)
    return seconds, peak_mb


def timed(args: list[str], what: str) -> tuple[float, float, str]:
    """Run ``args`` through :data:`PEAK_OF`: (its seconds start to finish, its peak resident
    memory in MB, what it printed on stderr); RuntimeError naming ``what`` if it failed."""
    run = subprocess.run([sys.executable, "-c", PEAK_OF, *args], capture_output=True, text=True, errors="replace")
    status, seconds, peak_kb = run.stdout.split() if run.returncode == 0 else (f"{run.returncode} (the timer)", "", "")
    if status != "0":
        raise RuntimeError(f"{what} failed with status {status}: {run.stderr.strip()[-400:]}")
    return float(seconds), int(peak_kb) / 1024, run.stderr


#: Runs the command of its arguments and prints its exit status, its seconds start to finish
#: and its peak resident memory (kB), from a small process of its own: Linux counts in a child's
#: peak the peak of the memory it was started from, up to its exec (Python starts children with
#: vfork, in the parent's memory), and this benchmark's peak is hundreds of MB by the time it
#: starts a sweep.
PEAK_OF = """
import os, subprocess, sys, time
t0 = time.perf_counter()
child = subprocess.Popen(sys.argv[1:], stdout=subprocess.DEVNULL)
_, status, usage = os.wait4(child.pid, 0)
print(os.waitstatus_to_exitcode(status), time.perf_counter() - t0, usage.ru_maxrss)
"""


def plan_kernel_s(side: int = 100) -> float:
    """Seconds the batches of :func:`full_sweep`'s plan take through sweep.run_batch alone, in
    this process, the kernel loaded before (kernel_alone.batches_s): what the sweep's batches
    would take at the kernel's own speed, without what a new process pays first."""
    plan = grid_plan(side)
    sweep.load_kernel(plan.batches[0])  # outside the timing
    return batches_s(plan)


def kernel_program_s(side: int = 100, checkout: Path | None = None) -> float:
    """Seconds of bench/kernel_alone.py over :func:`full_sweep`'s grid in a new process, start
    to finish, less its plan's: what a process does to give the sweep's numbers and no more
    (Python, numpy, numba and its registries, the kernel loaded, the batches as boom-sweep runs
    them, the exit), beside which the sweep adds its own planning, storage and table.
    ``checkout``: in that checkout's environment (the program is this checkout's; it calls what
    the sweep's planning and batches are called by)."""
    program = str(ROOT / "bench" / "kernel_alone.py")
    python = [sys.executable] if checkout is None else [str(checkout / "tools" / "with-env"), "python"]
    seconds, _, printed = timed([*python, program, str(side)], "kernel_alone.py")
    found = re.search(PLAN_PATTERN, printed, re.MULTILINE)
    if found is None:
        raise RuntimeError(f"kernel_alone.py printed no plan's seconds: {printed.strip()[-400:]}")
    return seconds - float(found.group(1))


#: The answer's sweep at the issue's size: 3 drives x 30 cylinders x 20 operators' loader cycles.
ANSWER_DRIVES = "fixed_pump,load_sensing,pump_controlled"
ANSWER_DURATION_S = 24.0


def answer_sweep(cylinders: int = 30, operators: int = 20) -> tuple[int, float, float]:
    """boom-sweep across drives, cylinders and operators' loader cycles (docs/drives.md's
    command, three drives), start to finish: (points, seconds, M steps of dt per second)."""
    out = Path(tempfile.mkdtemp(prefix="bench-answer-"))
    args = [shutil.which("boom-sweep"), "--config", str(ROOT / "config" / "default.yaml"), "--scenario", "loader"]
    args += ["--operators", str(operators), "--duration", f"{ANSWER_DURATION_S:g}", "--vary", f"drive={ANSWER_DRIVES}"]
    args += ["--vary", f"piston_diameter=0.032:0.1:{cylinders}", "--across", "operator", "--max-pressure-pa", "18e6"]
    args += ["--rank-by", "cycles_per_charge", "--out", str(out / "s"), "--no-plots", "--no-progress"]
    t0 = time.perf_counter()
    subprocess.run(args, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    seconds = time.perf_counter() - t0
    shutil.rmtree(out)
    points = 3 * cylinders * operators
    return points, seconds, points * ANSWER_DURATION_S / 1e-3 / seconds / 1e6


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--full", action="store_true", help="also time boom-sweep over 10 000 points and the answer's sweep"
    )
    args = parser.parse_args()
    rows: list[list[str]] = []

    def add(label: str, points: int, seconds: float) -> None:
        rows.append([label, str(points), f"{seconds:.1f}", f"{points / seconds:.1f}"])

    sweep.load_kernel(sweep_plan(1000, 1000).batches[0])  # the compiled kernel loaded outside the timing
    add("compiled kernel, 1 batch of 1000, this process", 1000, vectorised(1000, 1000, LocalExecutor()))
    add("compiled kernel, 4 batches of 250, this process", 1000, vectorised(1000, 250, LocalExecutor()))
    add("compiled kernel, 2 batches of 500, 2 Dask workers", 1000, vectorised(1000, 500, DaskExecutor(workers=2)))
    os.environ["BOOM_HYDRAULICS_JIT"] = "0"  # the run loop interpreted, as without numba
    add("interpreted batch (no numba), 1 batch of 10, this process", 10, vectorised(10, 10, LocalExecutor()))
    del os.environ["BOOM_HYDRAULICS_JIT"]
    add("one at a time, interpreted", 10, one_at_a_time(10, jit=False))
    if accelerate.available():
        add("one at a time, compiled (numba)", 50, one_at_a_time(50, jit=True))
    add("one solve_ivp (RK45, rtol 1e-6) per point", 5, with_solve_ivp(5, "RK45"))
    add("one solve_ivp (LSODA, rtol 1e-6) per point", 5, with_solve_ivp(5, "LSODA"))
    base = float(rows[4][3])
    for r in rows:
        r.append(f"{float(r[3]) / base:.1f}x")
    table(
        f"Points per second: {DURATION_S:g} s lift at dt = 1 ms (physical, RK4), metrics included",
        ["path", "points", "seconds", "points/s", "vs one at a time"],
        rows,
    )
    if args.full:
        full = []
        for label, workers, side in (
            ("boom-sweep, 1000 points, this process", None, 32),
            ("boom-sweep, 10 000 points, this process", None, 100),
            ("boom-sweep --workers 2, 10 000 points", 2, 100),
        ):
            seconds, peak_mb = full_sweep(workers, side)
            full.append([label, f"{side * side}", f"{seconds:.1f}", f"{peak_mb:.0f}"])
        points, seconds, rate = answer_sweep()
        full.append([f"boom-sweep of the answer ({ANSWER_DRIVES}, loader)", f"{points}", f"{seconds:.1f}", "-"])
        print(f"the answer's sweep: {points / seconds:.1f} points/s, {rate:.2f} M steps of dt per second")
        table(
            "boom-sweep over a grid of points, 5 s lift, start to finish",
            ["run", "points", "seconds", "peak MB (boom-sweep process)"],
            full,
        )


if __name__ == "__main__":
    main()
