"""The batch kernel beside another commit's, in rounds taken in turn.

    tools/with-env python bench/bench_batch.py --against CHECKOUT [--rounds 3]   # about a minute a round

One run of bench_speed measures the other commit's rows minutes before its own, and on
these shared machines the batch kernel's row has moved by 15 % between such runs with the
same code. Here each round measures each checkout in turn (A B A B ...), each in its own
environment, in a process of its own:

- the 5 s lift's opening (a constant command) on N = 10 000 sets of piston diameters, 1 s
  of it (10 M state-steps), best of 2;
- the loader cycle (position controller following its knots, the payload put down) on
  2000 sets, 5 s of it (10 M state-steps), best of 2.

It prints M state-steps/s, the median (smallest-largest) of the rounds for each checkout,
and this checkout's median over the other's; the table also goes to
bench/results/batch-<UTC date-time>.md. The kernel is loaded (compiled on a cold cache)
outside the timings.

    tools/with-env python bench/bench_batch.py --parts [--rounds 3]

With ``--parts`` instead, this checkout alone: what a step pays beyond the model, found by
leaving it out at run time (the same compiled kernel): the 5 s lift's opening on 4000 sets,
1 s of it, with a sample for the metrics at every step (as sweeps take them by default), with
one every 1000 steps, and with one every 1000 steps and no stability bound (its limit set to 0,
which the kernel skips; the lift at 1 ms needs no substeps, so the states are the same: the
script checks it). The cases run in turn in each round; each row is the best of the rounds
and its share of the first's time per step (bench/results/batch-parts-<UTC date-time>.md).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
from pathlib import Path

from bench_node import checkout_path, with_env
from tables import ROOT, commit, publish_against, table, write_results

#: One round of one checkout, run in its environment: prints {"lift": M/s, "loader": M/s}.
MEASURE = """
import json, time
from boom_hydraulics.model.parameters import Parameters, with_updates
from boom_hydraulics.solve import commands, duty_cycles
from boom_hydraulics.solve.batch import run_sets

def rate(params, duration_s, command):
    run_sets(params[:8], 0.01, commands.for_batch(params[:8]))  # load (or compile) the kernel
    best = float("inf")
    for _ in range(2):
        started = time.perf_counter()
        run_sets(params, duration_s, command)
        best = min(best, time.perf_counter() - started)
    return len(params) * round(duration_s / params[0].time_step_s) / best / 1e6

n = 10_000
lift = [with_updates(Parameters(), piston_diameter_m=0.04 + 0.04 * i / n, command_value=1.0) for i in range(n)]
loader = [with_updates(p, **duty_cycles.loader(p, 3)) for p in lift[:2000]]
print(json.dumps({
    "lift": rate(lift, 1.0, commands.constant(1.0)),
    "loader": rate(loader, 5.0, commands.for_batch(loader)),
}))
"""

PARTS = """
import json, time
from boom_hydraulics.model.parameters import Parameters, with_updates
from boom_hydraulics.solve import batch, commands

n, rounds = 4000, {rounds}
lift = [with_updates(Parameters(), piston_diameter_m=0.04 + 0.04 * i / n, command_value=1.0) for i in range(n)]
batch.run_sets(lift[:8], 0.01, commands.constant(1.0))  # load (or compile) the kernel
bound = batch.stability_limit
cases = {{"every": (1, bound), "sparse": (1000, bound), "unbound": (1000, lambda p: 0.0)}}
best, states = {{key: 0.0 for key in cases}}, {{}}
for _ in range(rounds):
    for key, (every, limit) in cases.items():
        batch.stability_limit = limit  # (SetRun reads it by name)
        started = time.perf_counter()
        states[key] = batch.run_sets(lift, 1.0, commands.constant(1.0), every=every).states
        best[key] = max(best[key], n * 1000 / (time.perf_counter() - started) / 1e6)
if not (states["every"] == states["sparse"]).all() or not (states["sparse"] == states["unbound"]).all():
    raise SystemExit("the cases' states differ: they do not take the same steps, and their rates do not compare")
print(json.dumps(best))
"""

PART_ROWS = (
    ("every", "a sample for the metrics at every step (sweeps' default --every 1)"),
    ("sparse", "a sample every 1000 steps"),
    ("unbound", "a sample every 1000 steps, and no stability bound"),
)

ROWS = (
    ("lift", "blocks kernel, 10 000 sets of the 5 s lift's opening (constant command), M state-steps/s"),
    ("loader", "blocks kernel, 2000 sets of the loader cycle (position controller, payload), M state-steps/s"),
)


def measured(checkout: Path, script: str = MEASURE) -> dict[str, float]:
    """One round of ``checkout``: ``script``'s rates (M state-steps/s), run in its environment."""
    out = subprocess.run([*with_env(checkout), "python", "-c", script], cwd=checkout, capture_output=True, text=True)
    if out.returncode != 0:
        raise RuntimeError(f"the batch run of {checkout} failed: {out.stderr.strip().splitlines()[-1:]}")
    return json.loads(out.stdout.strip().splitlines()[-1])


def spread(values: list[float]) -> str:
    """The median, with the smallest and the largest: '4.52 (4.35-4.83)'."""
    return f"{statistics.median(values):.2f} ({min(values):.2f}-{max(values):.2f})"


def parts(rounds: int) -> int:
    """--parts: what the metrics' samples and the stability bound cost a step, this checkout."""
    rates = measured(ROOT, PARTS.format(rounds=rounds))
    first = rates[PART_ROWS[0][0]]
    rows = [[what, f"{rates[key]:.2f}", f"{first / rates[key] * 100:.0f} %"] for key, what in PART_ROWS]
    title = f"Blocks kernel, 4000 sets of the lift's opening, best of {rounds} rounds ({os.cpu_count()} cores)"
    text = table(title, ["what a step takes", "M state-steps/s", "time per step"], rows)
    print(f"written to {write_results('batch-parts', text).relative_to(ROOT)}")
    return 0


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    which = parser.add_mutually_exclusive_group(required=True)
    which.add_argument("--against", type=checkout_path, help="a built checkout to compare with")
    which.add_argument("--parts", action="store_true", help="what a step pays beyond the model, this checkout")
    parser.add_argument("--rounds", type=int, default=3, help="rounds, each checkout once per round (3)")
    args = parser.parse_args()
    if args.rounds < 1:
        parser.error(f"--rounds must be at least 1, got {args.rounds}")
    if args.parts:
        return parts(args.rounds)
    checkouts = [ROOT, args.against]
    figures: dict[Path, dict[str, list[float]]] = {c: {key: [] for key, _ in ROWS} for c in checkouts}
    for n in range(args.rounds):
        for checkout in checkouts:
            rates = measured(checkout)
            for key, _ in ROWS:
                figures[checkout][key].append(rates[key])
            print(
                f"round {n + 1}/{args.rounds}, {commit(checkout)}: "
                + ", ".join(f"{key} {rates[key]:.2f} M state-steps/s" for key, _ in ROWS),
                flush=True,
            )
    header = ["what", f"{commit()} (this)", f"{commit(args.against)} ({args.against.name})", "ratio of medians"]
    rows = []
    for key, what in ROWS:
        this, other = figures[ROOT][key], figures[args.against][key]
        rows.append([what, spread(this), spread(other), f"{statistics.median(this) / statistics.median(other):.2f}"])
    title = f"Batch kernel, median (smallest-largest) of {args.rounds} rounds taken in turn ({os.cpu_count()} cores)"
    publish_against("batch", title, header, rows, args.against)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
