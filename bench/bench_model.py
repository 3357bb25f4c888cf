"""Model-core benchmarks: step cost, scipy comparison, batch throughput, stiff settings
(RK4 with substeps against ros2), Euler vs RK4.

    tools/with-env python bench/bench_model.py          # about two minutes

Prints tables; nothing is asserted (these machines are shared and noisy: read the
numbers, rerun when in doubt).
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tempfile
import time
import tracemalloc
from pathlib import Path

import numpy as np
from scipy.integrate import solve_ivp
from tables import best_of, table

from boom_hydraulics.model import config, paper, physical
from boom_hydraulics.model.drives import DRIVES
from boom_hydraulics.model.parameters import Parameters, from_mapping, with_updates
from boom_hydraulics.solve import accelerate, duty_cycles
from boom_hydraulics.solve.batch import run_sets
from boom_hydraulics.solve.commands import constant as constant_command
from boom_hydraulics.solve.commands import from_parameters
from boom_hydraulics.solve.commands import steps as steps_command
from boom_hydraulics.solve.simulation import Simulator, simulate

CONFIG = Path(__file__).resolve().parents[1] / "config"
FIG8 = config.load(CONFIG / "paper_fig8.yaml")
PHYSICAL = Parameters()
OPEN = constant_command(1.0)  # a profile: a compiled simulate() runs it whole in the kernel


def step_cost() -> dict[tuple[str, bool], float]:
    """Print and return us per RK4 step by (model, compiled)."""
    rows, costs = [], {}
    for label, params in (("paper (fig8)", FIG8), ("physical (default)", PHYSICAL)):
        for jit in (False, True):
            if jit and not accelerate.available():
                continue
            # paper mode reaches the degenerate geometry after ~2 s of simulated time
            n = 1500 if params.mode == "paper" else (200_000 if jit else 20_000)
            sim = Simulator(params, jit=jit)
            sim.step(0.5, 10)  # compile / warm up

            def run(sim=sim, n=n):
                sim.reset()
                sim.step(0.5, n)

            seconds = best_of(run, 5)
            us = seconds / n * 1e6
            costs[(params.mode, jit)] = us
            rows.append(
                [label, "compiled" if jit else "interpreted", f"{us:.2f}", f"{params.time_step_s / (us * 1e-6):.0f}"]
            )
    table(
        "RK4 step, one simulation, dt = 1 ms (many steps per call)",
        ["model", "path", "us/step", "sim s per wall s"],
        rows,
    )
    return costs


ANCHOR = Path(__file__).resolve().parent / "anchor" / "paper_rk4.c"
#: The anchor's run: fig. 8's parameters, this many RK4 steps of its dt with the valve half open
#: (paper mode reaches the degenerate geometry after about 2 s), best of this many runs.
ANCHOR_STEPS, ANCHOR_REPEATS, ANCHOR_U = 1500, 400, 0.5


def c_anchor() -> dict[str, float] | None:
    """The paper model's RK4 step in plain C (bench/anchor/paper_rk4.c, compiled here with
    ``$CC`` or cc at -O3 for this machine) beside the compiled Python step on the same
    constants and steps: us per step of each, and the largest relative difference of their
    final states (they must compute the same model). None without a C compiler."""
    compiler = shutil.which(os.environ.get("CC", "cc"))
    if compiler is None:
        print("no C compiler (cc or $CC): the C anchor is not measured")
        return None
    with tempfile.TemporaryDirectory(prefix="bench-anchor-") as folder:
        exe = Path(folder) / "paper_rk4"
        subprocess.run([compiler, "-O3", "-march=native", "-o", str(exe), str(ANCHOR), "-lm"], check=True)
        c = paper.constants(FIG8)
        y0 = paper.initial_state(FIG8)
        fields = (c.a, c.b, c.h, c.inertia, c.weight_coeff, c.s1, c.v1, c.bulk_modulus, c.k_orifice, c.p_n)
        fields += (c.coulomb, c.viscous, c.spring, c.f_external)
        args = [ANCHOR_U, FIG8.time_step_s, ANCHOR_STEPS, ANCHOR_REPEATS, *y0[:3], *fields]
        out = subprocess.run([str(exe), *(repr(float(a)) if isinstance(a, float) else str(a) for a in args)],
                             capture_output=True, text=True, check=True).stdout.split("\n")  # fmt: skip
    c_state = np.array(out[0].split(), dtype=float)
    c_us = float(out[1]) * 1e-3
    sim = Simulator(FIG8, jit=True)
    sim.step(ANCHOR_U, ANCHOR_STEPS)
    differs = float(np.max(np.abs(np.array(sim.y) - c_state) / np.maximum(np.abs(c_state), 1e-300)))

    def run() -> None:
        sim.reset()
        sim.step(ANCHOR_U, ANCHOR_STEPS)

    py_us = best_of(run, 20) / ANCHOR_STEPS * 1e6
    table(
        f"Paper RK4 step against plain C, fig. 8, {ANCHOR_STEPS} steps of {FIG8.time_step_s:g} s (best of each)",
        ["path", "us/step", "vs C", "final state, largest relative difference"],
        [["plain C (-O3, this machine)", f"{c_us:.3f}", "1.00", ""],
         ["compiled (numba), Simulator.step", f"{py_us:.3f}", f"{py_us / c_us:.2f}", f"{differs:.1e}"]],
    )  # fmt: skip
    return {"c_us": c_us, "compiled_us": py_us, "differs": differs}


def physical_scales() -> list[float]:
    """A natural scale of each physical state (m, m/s, Pa, 1, J) for absolute tolerances."""
    scale = {"length": 1.0, "velocity": 1.0, "pressure": 1e7, "unit": 1.0, "energy": 1e3}
    return [scale[kind] for kind in physical.STATE_SCALES]


def scipy_comparison() -> dict[str, float]:
    """The same 1.5 s physical lift with solve_ivp at the accuracy RK4 reaches at 1 ms: print
    the table and return the whole call's seconds by solver."""
    c = physical.constants(PHYSICAL)
    y0 = physical.initial_state(PHYSICAL)
    duration = 1.5

    def fun(t, y):
        return physical.derivative(t, list(y), c, 1.0)

    ref = solve_ivp(fun, (0, duration), y0, method="DOP853", rtol=1e-11, atol=[a * 1e-11 for a in physical_scales()])
    q_ref = ref.y[0, -1]
    rk4_time = best_of(lambda: simulate(PHYSICAL, duration, OPEN, every=10**9, jit=False), 2)
    rk4_err = abs(simulate(PHYSICAL, duration, OPEN, every=10**9, jit=False)["q1"][-1] - q_ref) / q_ref
    rows = [["rk4 dt=1 ms (ours, interpreted)", f"{rk4_err:.1e}", f"{rk4_time:.4f}", "1.0"]]
    seconds_by = {"rk4 interpreted": rk4_time}
    if accelerate.available():
        simulate(PHYSICAL, 0.01, OPEN, jit=True)  # load the compiled model outside the timing
        t_jit = best_of(lambda: simulate(PHYSICAL, duration, OPEN, every=10**9, jit=True), 5)
        rows.append(["rk4 dt=1 ms (ours, compiled)", f"{rk4_err:.1e}", f"{t_jit:.4f}", f"{t_jit / rk4_time:.3f}"])
        seconds_by["rk4 compiled"] = t_jit
    seconds_by["rk4 error"] = rk4_err
    for method in ("RK45", "LSODA"):
        chosen, reached = None, False
        for rtol in (1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10):
            atol = [rtol * s for s in physical_scales()]
            sol = solve_ivp(fun, (0, duration), y0, method=method, rtol=rtol, atol=atol)
            err = abs(sol.y[0, -1] - q_ref) / q_ref
            if sol.success:
                chosen = (rtol, atol, err)  # the tightest that ran, if none reaches it
            if sol.success and err <= rk4_err:
                reached = True
                break
        if chosen is None:
            rows.append([f"solve_ivp {method}", "failed", "", ""])
            continue
        rtol, atol, err = chosen
        seconds = best_of(
            lambda method=method, rtol=rtol, atol=atol: solve_ivp(
                fun, (0, duration), y0, method=method, rtol=rtol, atol=atol
            ),
            2,
        )
        label = f"solve_ivp {method} rtol={rtol:g}" + ("" if reached else " (its tightest; does not reach it)")
        rows.append([label, f"{err:.1e}", f"{seconds:.4f}", f"{seconds / rk4_time:.3f}"])
        seconds_by[method] = seconds
        seconds_by[f"{method} error"] = err
    table(
        "1.5 s physical lift at matching accuracy (error in final q1 against DOP853 rtol 1e-11)",
        ["solver", "rel. error q1", "wall s", "ratio to rk4 interpreted"],
        rows,
    )
    return seconds_by


def batch_throughput() -> dict[str, float]:
    """Print and return M state-steps/s of the batch paths at N = 10 000 (and smaller N): the
    compiled kernel over blocks of sets in lock-step on the vector units (solve/lanes.py), the
    same with one set per thread (the kernel before the blocks), each on all cores, and the
    interpreted run loop, one set after the other, at N = 1 and 10."""
    rows, rates = [], {}
    paths = [("interpreted", False, True)]
    if accelerate.available():
        paths += [("compiled kernel", True, True), ("compiled, one set per thread", True, False)]
    for label, compiled, lock_step in paths:
        for n in (1, 100, 10_000) if compiled else (1, 10):
            params = [with_updates(PHYSICAL, piston_diameter_m=0.04 + 0.04 * i / n) for i in range(n)]
            steps = 1000 if compiled else 200
            if compiled:  # load the compiled kernel outside the timing
                run_sets(params[: max(2, min(n, 8))], 0.01, OPEN, lock_step=lock_step)

            def run(p=params, s=steps, jit=compiled, lock_step=lock_step):
                run_sets(p, s * 1e-3, OPEN, jit=jit, lock_step=lock_step)

            seconds = best_of(run, 2)
            rate = n * steps / seconds / 1e6
            rows.append([label, str(n), str(steps), f"{seconds:.2f}", f"{rate:.3f}"])
            rates[label] = rate
    table(
        "Batched physical RK4 over N parameter sets (the run loop interpreted; compiled kernel, all cores, "
        "from 4 sets on in blocks of 4 in lock-step; streaming metrics)",
        ["path", "N", "steps", "wall s", "M state-steps/s"],
        rows,
    )
    return rates


def stiff_settings() -> None:
    """The 9 s lift-hold-lower-hold cycle with stiff oil and short hoses: RK4 with the
    substeps its stability bound asks for, against ros2 at one step per millisecond."""
    cycle = steps_command([0.0, 3.0, 4.0, 7.0], [1.0, 0.0, -1.0, 0.0])
    rows = []
    for label, volume in (("default (100 cm3)", 1e-4), ("10 cm3", 1e-5), ("1 cm3", 1e-6)):
        base = with_updates(PHYSICAL, bulk_modulus_pa=1.6e9, piston_dead_volume_m3=volume, rod_dead_volume_m3=volume)
        for method in ("rk4", "ros2"):
            params = with_updates(base, method=method)
            paths = (False, True) if accelerate.available() else (False,)
            for jit in paths if volume > 1e-6 else paths[-1:]:  # 1 cm3: compiled only (minutes interpreted)
                sim = Simulator(params, jit=jit)
                sim.step(0.0, 1)  # compile / warm up
                t0 = time.perf_counter()
                sim.reset()
                tr = sim.run(9.0, cycle, every=10**9, stop_on_error=True)
                seconds = time.perf_counter() - t0
                path = "compiled" if jit else "interpreted"
                result = [f"{tr['q1'][-1]:.6f}", f"{tr['supply_energy'][-1]:.1f}"]
                if tr.stopped:
                    result = [f"stopped at {tr['t'][-1]:.2f} s", tr.stopped.split(":")[0]]
                rows.append([label, method, path, str(sim.most_substeps), f"{seconds:.2f}", *result])
    table(
        "9 s cycle, 1.6 GPa oil, dt = 1 ms: rk4 with its stability substeps vs ros2",
        ["dead volumes", "method", "path", "most substeps", "wall s", "final q1 m", "supply J"],
        rows,
    )


def euler_vs_rk4() -> None:
    """Step size each method needs for 1e-6 relative error on q1 (paper fig. 8, 1 s), as the paper stored it."""
    duration = 1.0
    reference = simulate(with_updates(FIG8, time_step_s=1.25e-4), duration, every=10**9, jit=False)["q1"][-1]
    rows = []
    for method, steps in (("euler", [1e-4, 3e-5, 1e-5, 5e-6, 2e-6, 1e-6]), ("rk4", [1e-2, 5e-3, 2.5e-3, 1e-3])):
        for h in steps:
            params = with_updates(FIG8, method=method, time_step_s=h)
            tracemalloc.start()
            t0 = time.perf_counter()
            tr = simulate(params, duration, every=1, jit=False)  # every point kept, as the paper's listing does
            seconds = time.perf_counter() - t0
            peak = tracemalloc.get_traced_memory()[1]
            tracemalloc.stop()
            err = abs(tr["q1"][-1] - reference) / reference
            if err <= 1e-6:
                rows.append([method, f"{h:g}", f"{err:.1e}", f"{len(tr)}", f"{seconds:.2f}", f"{peak / 2**20:.1f}"])
                break
        else:
            rows.append([method, f"< {steps[-1]:g}", f"{err:.1e}", "", "", ""])
    table(
        "Step size for 1e-6 relative error on q1 (paper fig. 8, 1 s, every point stored)",
        ["method", "dt s", "rel. error", "points", "wall s", "peak MiB"],
        rows,
    )


def drive_cost() -> dict[tuple[str, bool], float]:
    """Print and return us per 1 ms step of each drive on the loader cycle (duty_cycles), its
    stability substeps included, by (drive, compiled): the compiled path over the whole cycle,
    the interpreted one over its first 3 s (the lift)."""
    rows, costs = [], {}
    for drive in DRIVES:
        params = from_mapping(duty_cycles.loader(PHYSICAL), base=with_updates(PHYSICAL, drive=drive))
        for jit in (False, True):
            if jit and not accelerate.available():
                continue
            duration = duty_cycles.LOADER_DURATION_S if jit else 3.0
            sim = Simulator(params, jit=jit)
            sim.run(0.01, from_parameters(params), every=10**9)  # compile / warm up

            def run(sim=sim, duration=duration, params=params):
                sim.reset()
                sim.run(duration, from_parameters(params), every=10**9)

            seconds = best_of(run, 3 if jit else 1)
            us = seconds / round(duration / params.time_step_s) * 1e6
            costs[(drive, jit)] = us
            rows.append(
                [drive, "compiled" if jit else "interpreted", f"{duration:g}", f"{us:.2f}", str(sim.most_substeps)]
            )
    table(
        "Each drive on the loader cycle: us per 1 ms step, stability substeps included",
        ["drive", "path", "simulated s", "us/step", "most substeps"],
        rows,
    )
    return costs


def main() -> int:
    print(f"numba: {'yes' if accelerate.available() else 'no'}; numpy {np.__version__}")
    step_cost()
    if accelerate.available():
        c_anchor()
    drive_cost()
    scipy_comparison()
    batch_throughput()
    stiff_settings()
    euler_vs_rk4()
    return 0


if __name__ == "__main__":
    sys.exit(main())
