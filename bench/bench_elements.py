"""The accumulator, the hoses and the elastic boom (docs/model.md): what a step costs with them off and on.

    tools/with-env python bench/bench_elements.py --against CHECKOUT [--rounds 3] [--steps 20000]

Times compiled RK4 steps of one simulation at each config's own step (1 ms), the valve
open then closed as the loader cycle's first lift, in each checkout's own environment, the
checkouts in turn in each round:

- *default*: config/default.yaml, where every element is off, in both checkouts: the cost
  of their states when off (the target: nothing);
- *1 t crane, off*: config/loader_crane_1t.yaml with the three elements off (:data:`OFF`)
  here, against that file in the other checkout (which has none of them);
- *1 t crane, on*: config/loader_crane_1t.yaml as it ships (all three on) here, against
  the same other run (the target: at most 1.5 times).

A figure is microseconds of the process's CPU time per step of dt (the stepping runs in the
calling thread: what a shared machine's load moves least), substeps included (the hoses' waves
may ask the stability bound for more), best of the rounds, with the most substeps one step
took (the Simulator's most_substeps). Prints a table and writes it to
bench/results/elements-<date-time>.md; nothing is asserted (these machines are shared).
"""

from __future__ import annotations

import argparse
import json
import subprocess
from pathlib import Path

from bench_node import checkout_path, with_env
from tables import ROOT, publish_against

#: The three elements off, as the 1 t crane's file would read without them.
OFF = {"accumulator_gas_volume_m3": 0.0, "hose_length_m": 0.0, "boom_bending_stiffness_n_m2": 0.0}

#: Run in a checkout's environment: us per step of the params file argv[1] with the settings
#: argv[2] (JSON), the valve open for half the steps and closed for the rest, best of argv[4]
#: runs of argv[3] steps (after one run that compiles or loads the kernels), and the most
#: substeps a step took.
MEASURE = """
import json, sys, time
from boom_hydraulics.model import config
from boom_hydraulics.solve.simulation import Simulator
params = config.load(sys.argv[1], json.loads(sys.argv[2]))
steps, runs = int(sys.argv[3]), int(sys.argv[4])
sim = Simulator(params, jit=True)
sim.step(0.5, 10)
best = float("inf")
for _ in range(runs):
    sim.reset()
    t0 = time.process_time()
    sim.step(0.6, steps // 2)
    sim.step(0.0, steps - steps // 2)
    best = min(best, time.process_time() - t0)
print(best / steps * 1e6, sim.most_substeps)
"""


def us_per_step(checkout: Path, config: str, settings: dict[str, float], steps: int, runs: int) -> tuple[float, int]:
    """(microseconds per step, the most substeps a step took) in ``checkout`` (its environment)
    of its ``config`` with ``settings``."""
    args = [*with_env(checkout), "python", "-c", MEASURE, str(checkout / "config" / config), json.dumps(settings)]
    out = subprocess.run([*args, str(steps), str(runs)], cwd=checkout, capture_output=True, text=True)
    if out.returncode != 0:
        raise RuntimeError(f"{checkout}: {out.stderr.strip().splitlines()[-1:]}")
    us, most = out.stdout.strip().splitlines()[-1].split()
    return float(us), int(most)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--against", type=checkout_path, required=True, help="a built checkout to compare with")
    parser.add_argument("--rounds", type=int, default=3, help="rounds, each checkout once per round (3)")
    parser.add_argument("--steps", type=int, default=20_000, help="steps of one timed run (20000: 20 s)")
    args = parser.parse_args()
    if args.rounds < 1 or args.steps < 2:
        parser.error("--rounds must be at least 1 and --steps at least 2")
    runs = {
        "default, here": (ROOT, "default.yaml", {}),
        "default, other": (args.against, "default.yaml", {}),
        "1 t crane off, here": (ROOT, "loader_crane_1t.yaml", OFF),
        "1 t crane, other": (args.against, "loader_crane_1t.yaml", {}),
        "1 t crane on, here": (ROOT, "loader_crane_1t.yaml", {}),
    }
    best = dict.fromkeys(runs, float("inf"))
    most = dict.fromkeys(runs, 0)
    for k in range(args.rounds):
        for name, (checkout, config, settings) in runs.items():
            us, substeps = us_per_step(checkout, config, settings, args.steps, 3)
            best[name], most[name] = min(best[name], us), max(most[name], substeps)
            print(f"round {k + 1}: {name}: {us:.2f} us/step, {substeps} substeps at most", flush=True)
    pairs = [
        ("default (every element off)", "default, here", "default, other", "1.00x (nothing when off)"),
        ("1 t crane, the three off", "1 t crane off, here", "1 t crane, other", "1.00x (nothing when off)"),
        ("1 t crane, the three on", "1 t crane on, here", "1 t crane, other", "at most 1.50x"),
    ]
    rows = [
        [run, f"{best[here]:.2f}", f"{best[other]:.2f}", f"{best[here] / best[other]:.2f}x", target,
         f"{most[here]} / {most[other]}"]
        for run, here, other, target in pairs
    ]  # fmt: skip
    publish_against(
        "elements",
        "RK4 step with the accumulator, hoses and elastic boom, compiled, dt = 1 ms "
        "(CPU us per step, best of the rounds)",
        ["run", "here", "other checkout", "ratio", "target", "most substeps (here / other)"],
        rows,
        args.against,
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
