"""The answer's sweep (docs/drives.md) in this checkout against an earlier one: steps per second per design.

    tools/with-env python bench/bench_answer.py --against CHECKOUT [--rounds 3] [--operators 5]

Runs boom-sweep over the loader cycle, start to finish (planning, the compiled kernel, the
table; no plots), in each checkout's own environment, the checkouts in turn in each round:

- *today's answer*: the drives both checkouts know, with their defaults, in both;
- *the new answer*: every drive of this checkout built as docs/drives.md answers with
  (:data:`AS_BUILT`, config/battery_crane.yaml), in this checkout alone, set against the other
  checkout's today's answer.

A design's rate is its simulated steps (of dt) per second of wall time, and per second of
CPU time (the sweep process's and its threads', user and system: what a shared machine's load
moves least); the ratios are this checkout's over the other's (1.0: as fast; the target for
the new answer is at least 1/1.3).
Each checkout's kernels are compiled before the first round. Prints a table and writes it
to bench/results/answer-<date-time>.md; nothing is asserted (these machines are shared).
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import subprocess
import tempfile
import time
from pathlib import Path

from bench_node import checkout_path, with_env
from tables import ROOT, commit, publish_against

#: The drives every checkout since the four drives' commit knows, in the README's order.
TODAYS_DRIVES = ("pressure_compensated", "fixed_pump", "load_sensing", "pump_controlled")
CYLINDERS = "piston_diameter=0.032:0.1:10"
DURATION_S = 24.0
DT_S = 1e-3


def drives_of(checkout: Path) -> tuple[str, ...]:
    """The drives ``checkout`` registers (parameters.DRIVES)."""
    script = "from boom_hydraulics.model.parameters import DRIVES; print(','.join(DRIVES))"
    out = subprocess.run([*with_env(checkout), "python", "-c", script], cwd=checkout, capture_output=True, text=True)
    if out.returncode != 0:
        raise RuntimeError(f"{checkout}: {out.stderr.strip().splitlines()[-1:]}")
    return tuple(out.stdout.strip().split(","))


#: The params file the new answer sweeps with (docs/drives.md, "The sweeps").
AS_BUILT = "battery_crane.yaml"


def cpu_s() -> float:
    """CPU seconds (user and system) of this process's children that have ended."""
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def sweep_s(
    checkout: Path, drives: tuple[str, ...], operators: int, config: str = "default.yaml"
) -> tuple[float, float]:
    """(wall seconds, CPU seconds) of one boom-sweep in ``checkout`` (its environment), start to finish."""
    with tempfile.TemporaryDirectory(prefix="bench-answer-") as folder:
        args = [*with_env(checkout), "boom-sweep", "--config", str(checkout / "config" / config)]
        args += ["--scenario", "loader", "--operators", str(operators), "--duration", f"{DURATION_S:g}"]
        args += ["--vary", f"drive={','.join(drives)}", "--vary", CYLINDERS, "--across", "operator"]
        args += ["--out", str(Path(folder) / "s"), "--no-plots", "--no-progress"]
        t0, cpu0 = time.perf_counter(), cpu_s()
        out = subprocess.run(args, cwd=checkout, capture_output=True, text=True)
        seconds, cpu = time.perf_counter() - t0, cpu_s() - cpu0
    if out.returncode != 0:
        raise RuntimeError(f"boom-sweep in {checkout} failed: {out.stderr.strip().splitlines()[-1:]}")
    return seconds, cpu


def designs(drives: tuple[str, ...], operators: int) -> int:
    return len(drives) * int(CYLINDERS.rsplit(":", 1)[1]) * operators


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--against", type=checkout_path, required=True, help="a built checkout to compare with")
    parser.add_argument("--rounds", type=int, default=3, help="rounds, each checkout once per round (3)")
    parser.add_argument("--operators", type=int, default=5, help="operators' cycles per design (5)")
    args = parser.parse_args()
    if args.rounds < 1 or args.operators < 1:
        parser.error("--rounds and --operators must be at least 1")
    ours = drives_of(ROOT)
    steps = DURATION_S / DT_S
    runs = {
        "today": (TODAYS_DRIVES, "default.yaml"),
        "new": (ours, AS_BUILT),
    }
    # compile each checkout's kernels first (a sweep of one design each)
    for checkout in (ROOT, args.against):
        sweep_s(checkout, TODAYS_DRIVES[:1], 1)
    keys = [("today", ROOT), ("today", args.against), ("new", ROOT)]
    rates: dict[tuple[str, Path], list[float]] = {key: [] for key in keys}  # per second of wall time
    cpu_rates: dict[tuple[str, Path], list[float]] = {key: [] for key in keys}  # per CPU second
    for n in range(args.rounds):
        for name, checkout in keys:
            drives, config = runs[name]
            seconds, cpu = sweep_s(checkout, drives, args.operators, config)
            total = designs(drives, args.operators) * steps / 1e6
            rates[(name, checkout)].append(total / seconds)
            cpu_rates[(name, checkout)].append(total / cpu)
            print(
                f"round {n + 1}/{args.rounds}, {name} in {commit(checkout)}: {total / seconds:.3f} M steps/s, "
                f"{total / cpu:.3f} per CPU second",
                flush=True,
            )
    other = statistics.median(rates[("today", args.against)])
    other_cpu = statistics.median(cpu_rates[("today", args.against)])

    def spread(values: list[float]) -> str:
        return f"{statistics.median(values):.3f} ({min(values):.3f}-{max(values):.3f})"

    def row(what: str, key: tuple[str, Path]) -> list[str]:
        wall, cpu = rates[key], cpu_rates[key]
        ratios = f"{statistics.median(wall) / other:.2f}"
        return [what, spread(wall), ratios, spread(cpu), f"{statistics.median(cpu) / other_cpu:.2f}"]

    header = [
        "sweep",
        "M steps of dt per second, median (smallest-largest)",
        f"ratio to {commit(args.against)}'s today's",
        "M steps per CPU second",
        "ratio (CPU)",
    ]
    rows = [
        row(f"today's answer ({len(TODAYS_DRIVES)} drives), {commit(args.against)} ({args.against.name})", keys[1]),
        row(f"today's answer ({len(TODAYS_DRIVES)} drives), {commit()} (this)", keys[0]),
        row(f"the new answer ({len(ours)} drives, config/{AS_BUILT}), {commit()}", keys[2]),
    ]
    title = (
        f"The answer's sweep: loader cycles of {DURATION_S:g} s at dt {DT_S * 1e3:g} ms, {args.operators} operators x "
        f"{CYLINDERS}, median of {args.rounds} rounds taken in turn ({os.cpu_count()} cores)"
    )
    publish_against("answer", title, header, rows, args.against)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
