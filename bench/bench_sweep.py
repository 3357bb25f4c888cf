"""Design-sweep benchmarks: points per second of a 5 s lift at dt = 1 ms, metrics included.

    tools/with-env python bench/bench_sweep.py            # about three minutes
    tools/with-env python bench/bench_sweep.py --full     # plus boom-sweep over 10 000 points

Compares the vectorised batch path (what boom-sweep runs) with one simulation per
point (interpreted and compiled) and with one scipy solve_ivp per point. Prints
tables; nothing is asserted (these machines are shared and noisy).
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np
from scipy.integrate import solve_ivp
from tables import table

from boom_hydraulics.analysis import metrics as analysis
from boom_hydraulics.model import physical
from boom_hydraulics.model.parameters import Parameters
from boom_hydraulics.solve import accelerate, commands
from boom_hydraulics.solve.simulation import simulate
from boom_hydraulics.sweeps import sweep
from boom_hydraulics.sweeps.executors import DaskExecutor, LocalExecutor
from boom_hydraulics.sweeps.sampling import parse_axis

DURATION_S = 5.0
OPEN_S = 2.5  # the lift scenario: valve open for the first half, then closed
AXES = [parse_axis("piston_diameter=0.032:0.1:40"), parse_axis("payload=0:200:25")]  # 1000 points


def sweep_plan(points: int, batch_size: int) -> sweep.Plan:
    plan = sweep.plan([("default", Parameters())], AXES, duration_s=DURATION_S, batch_size=batch_size)
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


def full_sweep(workers: int | None) -> float:
    out = Path(tempfile.mkdtemp(prefix="bench-sweep-"))
    args = ["boom-sweep", "--vary", "piston_diameter=0.032:0.1:100", "--vary", "payload=0:200:100"]
    args += ["--duration", "5", "--out", str(out / "s"), "--no-plots", "--no-progress"]
    if workers:
        args += ["--workers", str(workers)]
    t0 = time.perf_counter()
    subprocess.run(args, check=True, capture_output=True)
    seconds = time.perf_counter() - t0
    shutil.rmtree(out)
    return seconds


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--full", action="store_true", help="also time boom-sweep over 10 000 points")
    args = parser.parse_args()
    rows: list[list[str]] = []

    def add(label: str, points: int, seconds: float) -> None:
        rows.append([label, str(points), f"{seconds:.1f}", f"{points / seconds:.1f}"])

    add("vectorised, 1 batch of 1000, this process", 1000, vectorised(1000, 1000, LocalExecutor()))
    add("vectorised, 4 batches of 250, this process", 1000, vectorised(1000, 250, LocalExecutor()))
    add("vectorised, 2 batches of 500, 2 Dask workers", 1000, vectorised(1000, 500, DaskExecutor(workers=2)))
    add("one at a time, interpreted", 10, one_at_a_time(10, jit=False))
    if accelerate.available():
        add("one at a time, compiled (numba)", 50, one_at_a_time(50, jit=True))
    add("one solve_ivp (RK45, rtol 1e-6) per point", 5, with_solve_ivp(5, "RK45"))
    add("one solve_ivp (LSODA, rtol 1e-6) per point", 5, with_solve_ivp(5, "LSODA"))
    base = float(rows[3][3])
    for r in rows:
        r.append(f"{float(r[3]) / base:.1f}x")
    table(
        f"Points per second: {DURATION_S:g} s lift at dt = 1 ms (physical, RK4), metrics included",
        ["path", "points", "seconds", "points/s", "vs one at a time"],
        rows,
    )
    if args.full:
        full = [["boom-sweep, this process", f"{full_sweep(None):.0f}"]]
        full.append(["boom-sweep --workers 2", f"{full_sweep(2):.0f}"])
        table("boom-sweep over 10 000 points (100 x 100 grid), 5 s lift, start to finish", ["run", "seconds"], full)


if __name__ == "__main__":
    main()
