"""``boom-sweep``: which cylinder? A design sweep over any parameters, with a recommendation.

    boom-sweep --config config/default.yaml --vary piston_diameter=0.032:0.1:15 \\
        --vary payload=0:200:5 --scenario lift --out sweeps/diameter --across payload \\
        --max-pressure-pa 18e6 --max-lift-time-s 2.5 --no-cavitation

Every point runs the same valve scenario; the points are integrated together in
batches (numpy-vectorised), in this process, on local worker processes (``--workers``)
or on a Dask cluster (``--scheduler``), with identical results. OUT receives:

- ``results.csv`` / ``results.npz``: one row per point: its parameters, ``status``
  (ok, incomplete, failed, invalid), ``reason``, the design metrics and ``front``
  (1 on the trade-off front of lift time, lift energy and peak pressure);
- ``metrics_vs_<parameter>.png`` and ``trade_off.png``;
- with ``--recommend`` or a constraint: ``recommendation.txt`` and the recommended rows
  ranked, as ``recommendation.csv`` / ``.npz`` (with ``--across payload``: one row per
  cylinder, worst case over the payloads);
- ``sweep.json`` and ``batches/``: what was asked and each finished batch, so that an
  interrupted sweep finishes with ``--resume`` without redoing them.

OUT may hold other files (``--out .``): the sweep writes only the names above there, and refuses
a folder where one of them exists without a ``sweep.json``. Every failure ends in one line,
``boom-sweep: error: ...``: bad arguments, configs or numbers, a folder holding another sweep or
a batch file that is not this sweep's exit 2; a damaged ``sweep.json``, a failing point set on a
cluster or a disk error exit 1; Ctrl-C exits 130 and SIGTERM 143, keeping every finished batch
and naming the command that finishes the sweep. The size (points, batches, steps and a time
at a nominal rate) is said before planning a large sweep, and one that cannot fit in memory is
refused before anything is planned.
"""

from __future__ import annotations

import argparse
import math
import os
import shlex
import signal
import sys
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import ConfigError
from ..files import check_apart, csv_cell, write_bytes, write_csv, write_npz
from ..model import config
from ..model.parameters import Parameters, from_mapping
from ..programs import DefaultsFormatter, RaisingParser, Terminated, run_main
from ..sweeps import recommend, sweep
from ..sweeps.executors import DaskExecutor, LocalExecutor
from ..sweeps.sampling import SAMPLES, parse_axis, point_count, resolve_name
from ..sweeps.store import OUTPUTS, SweepStore, plot_names

#: Points integrated together unless --batch-size says otherwise: larger batches spend
#: less of their time in numpy's per-call overhead (bench/bench_sweep.py).
BATCH_SIZE = 1000

UNITS = {name: unit for name, unit, _ in sweep.METRICS}


def build_parser() -> argparse.ArgumentParser:
    parser = RaisingParser(
        prog="boom-sweep",
        description="Sweep cylinder designs through one valve scenario and rank them.",
        formatter_class=DefaultsFormatter,
    )
    what = parser.add_argument_group("what to sweep")
    what.add_argument(
        "--config",
        action="append",
        default=[],
        metavar="FILE",
        help="ROS 2 params YAML; repeat to sweep across configs (default: the built-in values)",
    )
    what.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="override a parameter")
    what.add_argument(
        "--vary",
        action="append",
        default=[],
        metavar="NAME=SPEC",
        help="START:STOP:COUNT, START:STOP:COUNT:log, V1,V2,... or LOW:HIGH (random/lhs); repeatable",
    )
    what.add_argument("--sample", choices=SAMPLES, default="grid", help="how the axes combine")
    what.add_argument("--samples", type=int, default=0, metavar="N", help="points of a random/lhs sample")
    what.add_argument("--seed", type=int, default=0, help="seed of a random/lhs sample")
    how = parser.add_argument_group("the scenario and its metrics")
    how.add_argument(
        "--scenario",
        default="lift",
        help="lift (open for half the run, then hold), lift:T, cycle, config, a profile such as steps:0=1,2=0, "
        "or a closed-loop move such as angle:0=30 (lift to 30 degrees under position control and hold)",
    )
    how.add_argument("--duration", type=float, default=5.0, help="simulated seconds per point")
    how.add_argument("--lift-angle-deg", type=float, default=20.0, help="boom rise that completes a lift")
    how.add_argument("--every", type=int, default=1, help="sample the signals every N steps for the metrics")
    run = parser.add_argument_group("where it runs")
    run.add_argument(
        "--batch-size",
        type=int,
        metavar="N",
        help=f"points integrated together (default {BATCH_SIZE}, or fewer to give each of --workers a share; "
        "about 0.37 GB per 1000 points of a 5 s run)",
    )
    where = run.add_mutually_exclusive_group()
    where.add_argument("--scheduler", metavar="ADDRESS", help="Dask scheduler, e.g. tcp://host:8786")
    where.add_argument("--workers", type=int, metavar="N", help="start a local Dask cluster of N processes")
    run.add_argument(
        "--scheduler-timeout",
        type=float,
        default=10.0,
        metavar="S",
        help="seconds to wait for the --scheduler to answer (default 10)",
    )
    run.add_argument("--out", type=Path, help="output folder (default: sweeps/sweep-DATE-TIME)")
    run.add_argument("--resume", action="store_true", help="finish the sweep begun in --out")
    run.add_argument("--no-plots", action="store_true", help="write tables only")
    run.add_argument(
        "--progress",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="progress bar on stderr (default: when stderr is a terminal)",
    )
    pick = parser.add_argument_group("recommendation")
    pick.add_argument("--recommend", action="store_true", help="rank the designs that meet the constraints")
    pick.add_argument("--max-pressure-pa", type=float, help="constraint: peak_pressure_pa <= VALUE")
    pick.add_argument("--max-lift-time-s", type=float, help="constraint: lift_time_s <= VALUE")
    pick.add_argument("--no-cavitation", action="store_true", help="constraint: cavitation_s == 0")
    pick.add_argument("--require", action="append", default=[], metavar="EXPR", help="e.g. 'damping_ratio>=0.1'")
    pick.add_argument(
        "--across",
        action="append",
        default=[],
        metavar="NAME",
        help="a varied parameter that is a condition, not a design choice (e.g. payload): a design must "
        "meet the constraints at all its values and is ranked by its worst case",
    )
    pick.add_argument("--top", type=int, default=10, help="designs shown in the recommendation")
    return parser


def load_configs(files: Sequence[str], assignments: Sequence[str]) -> list[tuple[str, Parameters]]:
    """(name, parameters) per config file (or the defaults), with the --set overrides."""
    overrides: dict[str, Any] = dict(config.parse_assignment(s) for s in assignments)
    if not files:
        return [("default", from_mapping(overrides))]
    return [(Path(f).stem, config.load(f, overrides)) for f in files]


def constraints_of(args: argparse.Namespace, columns: Sequence[str]) -> list[recommend.Constraint]:
    found = [recommend.parse_constraint(text, columns) for text in args.require]
    if args.max_pressure_pa is not None:
        found.append(recommend.Constraint("peak_pressure_pa", "<=", args.max_pressure_pa))
    if args.max_lift_time_s is not None:
        found.append(recommend.Constraint("lift_time_s", "<=", args.max_lift_time_s))
    if args.no_cavitation:
        found.append(recommend.Constraint("cavitation_s", "==", 0.0))
    return found


def _resume_command(argv: Sequence[str], out: Path, args: argparse.Namespace) -> str:
    words = ["boom-sweep", *argv]
    if args.out is None:
        words += ["--out", str(out)]
    if not args.resume:
        words.append("--resume")
    return shlex.join(words)


def check_numbers(args: argparse.Namespace) -> None:
    """Refuse, in one line, numbers that make no sense, before anything is read or planned."""
    for name in ("duration", "lift_angle_deg", "max_pressure_pa", "max_lift_time_s", "scheduler_timeout"):
        value = getattr(args, name)
        if value is not None and not math.isfinite(value):
            raise ConfigError(f"--{name.replace('_', '-')} must be a finite number, got {value}")
    sweep.check_duration(args.duration)
    if not args.scheduler_timeout > 0:
        raise ConfigError(f"--scheduler-timeout must be > 0 s, got {args.scheduler_timeout}")
    for name, least in (("samples", 0), ("seed", 0), ("every", 1), ("batch_size", 1), ("workers", 1), ("top", 1)):
        value = getattr(args, name)
        if value is not None and value < least:
            raise ConfigError(f"--{name.replace('_', '-')} must be a whole number >= {least}, got {value}")
    cores = os.cpu_count() or 1
    if args.workers is not None and args.workers > cores:
        raise ConfigError(
            f"--workers {args.workers}: this machine has {cores} cores, and each worker process runs on a share "
            "of them; give at most that many, or --scheduler to use a larger cluster"
        )


def write_table(table: Mapping[str, np.ndarray], path_csv: Path, rows: Sequence[int] | None = None) -> None:
    """The table (or the given rows of it) as CSV, and beside a .npz of the same columns."""
    names = list(table)
    index = np.arange(len(table[names[0]])) if rows is None else np.asarray(rows, dtype=int)
    write_csv(path_csv, names, ([csv_cell(table[n][i]) for n in names] for i in index))
    write_npz(path_csv.with_suffix(".npz"), {n: np.asarray(table[n])[index] for n in names})


def _summary(table: Mapping[str, np.ndarray], columns: Sequence[str]) -> str:
    status = np.asarray(table["status"])
    counts = ", ".join(f"{int((status == s).sum())} {s}" for s in sweep.STATUSES if (status == s).any())
    lines = [f"{len(status)} points: {counts}"]
    ok = np.nonzero(status == "ok")[0]
    if len(ok):
        for metric, label in (("lift_time_s", "fastest lift"), ("lift_energy_j", "least lift energy")):
            best = ok[np.nanargmin(np.asarray(table[metric], float)[ok])]
            where = ", ".join(f"{c}={recommend.format_value(table[c][best])}" for c in columns) or "the one point"
            lines.append(f"  {label}: {float(table[metric][best]):.4g} {UNITS[metric]} at {where}")
    return "\n".join(lines)


def _settings(args: argparse.Namespace) -> dict[str, Any]:
    """The keyword arguments of sweep.request and sweep.plan that the options give."""
    return {
        "scenario": args.scenario,
        "duration_s": args.duration,
        "sample": args.sample,
        "count": args.samples,
        "seed": args.seed,
        "lift_angle_deg": args.lift_angle_deg,
        "every": args.every,
    }


def _batch_size(args: argparse.Namespace, stored: Mapping[str, Any] | None, points: int) -> int:
    """Points a batch: those a resumed sweep began with, else --batch-size, or, with --workers and no
    --batch-size, fewer than BATCH_SIZE where that gives every worker a batch."""
    if args.batch_size is None and stored is not None:
        return int(stored["batch_size"])  # resume in the batches it began with, wherever it runs now
    if args.batch_size is None and args.workers:
        share = math.ceil(points / args.workers)
        return share if 0 < share < BATCH_SIZE else BATCH_SIZE
    return args.batch_size or BATCH_SIZE


def _stored_parts(store: SweepStore, plan: sweep.Plan) -> tuple[list[dict[str, np.ndarray]], set[int]]:
    """The rows of the batches stored before, checked to be this plan's; and their indices."""
    columns = ["point", "status", "reason", "failed_at_s", *sweep.METRIC_NAMES]
    by_index = {b.index: b for b in plan.batches}
    parts, done = [], set()
    for index in sorted(store.done()):
        batch = by_index.get(index)
        if batch is None:
            raise ConfigError(
                f"{store.path(index)} is not a batch of this sweep (it has {len(plan.batches)}); move it out "
                f"of {store.batches} and run the same command again"
            )
        rows = store.load(index, batch.points, columns)
        if rows is not None:
            parts.append(rows)
            done.add(index)
    return parts, done


@dataclass
class _Reached:
    """How far a sweep got, for the line it ends with if it is interrupted."""

    out: Path | None = None
    store: SweepStore | None = None
    plan: sweep.Plan | None = None

    def interrupted(self, argv: Sequence[str], args: argparse.Namespace, why: str) -> str:
        """What stopped the sweep, what is kept, and how to go on."""
        done = len(self.store.done()) if self.store is not None else 0
        if self.out is None or done == 0:
            return f"boom-sweep: error: {why} before a batch finished; nothing was stored"
        total = f" of {len(self.plan.batches)}" if self.plan is not None else ""
        return (
            f"boom-sweep: error: {why}; {done}{total} batches are stored in {self.out}; "
            f"finish with: {_resume_command(argv, self.out, args)}"
        )


def run(args: argparse.Namespace, argv: Sequence[str]) -> int:
    """The sweep; Ctrl-C (exit 130) or SIGTERM (143, see run_main) at any moment ends it with one line
    saying what is stored and the command that finishes it; a batch being written is not kept."""
    reached = _Reached()
    try:
        return _sweep(args, argv, reached)
    except Terminated:
        print(reached.interrupted(argv, args, "terminated (SIGTERM)"), file=sys.stderr)
        return 128 + signal.SIGTERM
    except KeyboardInterrupt:
        print(reached.interrupted(argv, args, "interrupted (Ctrl-C)"), file=sys.stderr)
        return 130


def _sweep(args: argparse.Namespace, argv: Sequence[str], reached: _Reached) -> int:
    check_numbers(args)
    configs = load_configs(args.config, args.set)
    axes = [parse_axis(text) for text in args.vary]
    across = [resolve_name(name) for name in args.across]
    out = args.out or Path("sweeps") / time.strftime("sweep-%Y%m%d-%H%M%S")
    check_apart(out, [Path(c) for c in args.config or []])
    columns = (("config",) if len(configs) > 1 else ()) + tuple(a.name for a in axes)
    recommend.check_across(across, columns)  # before the work, not after it
    constraints = constraints_of(args, [*columns, "status", "reason", "failed_at_s", *sweep.METRIC_NAMES])
    store = SweepStore(out, args.resume, [*OUTPUTS, *plot_names(columns)])
    reached.out, reached.store = out, store
    points = len(configs) * point_count(axes, args.sample, args.samples)
    batch_size = _batch_size(args, store.stored, points)
    settings = _settings(args)
    cost = sweep.estimate(configs, axes, duration_s=args.duration, sample=args.sample, count=args.samples,
                          batch_size=batch_size)  # fmt: skip
    sweep.check_fits(cost)
    if store.stored is not None:  # the folder's sweep must be this one: known before planning it
        store.begin(sweep.request(configs, axes, batch_size=batch_size, **settings))
    for path in store.removed:
        print(f"boom-sweep: note: removed {path}, left unfinished by an earlier run that was stopped", file=sys.stderr)
    if cost.plan_s >= 1:
        print(
            f"boom-sweep: planning {cost.points} points in {cost.batches} or more batches "
            f"({sweep.duration_text(cost.plan_s)}); to run: {cost.run_time(cost.points, os.cpu_count() or 1)}",
            file=sys.stderr,
            flush=True,
        )
    plan = reached.plan = sweep.plan(configs, axes, batch_size=batch_size, **settings)
    store.begin(plan.request)
    return _run_plan(args, out, store, plan, cost, constraints, across)


def _run_plan(
    args: argparse.Namespace,
    out: Path,
    store: SweepStore,
    plan: sweep.Plan,
    cost: sweep.Estimate,
    constraints: Sequence[recommend.Constraint],
    across: Sequence[str],
) -> int:
    """Run what is not stored yet, storing each batch as it finishes; then the table, plots and ranking."""
    parts, done = _stored_parts(store, plan)
    todo = [b for b in plan.batches if b.index not in done]
    executor = (
        DaskExecutor(args.scheduler, args.workers, args.scheduler_timeout)
        if (args.scheduler or args.workers) is not None
        else LocalExecutor()
    )
    runnable = plan.size - len(plan.invalid)
    print(
        f"boom-sweep: {plan.size} points ({len(plan.invalid)} invalid) in {len(plan.batches)} batches of up to "
        f"{plan.request['batch_size']}; {len(plan.batches) - len(todo)} done before, {len(todo)} to run "
        f"{executor.description} ({cost.run_time(sum(len(b.points) for b in todo), os.cpu_count() or 1)})",
        file=sys.stderr,
        flush=True,
    )
    from tqdm import tqdm

    progress = tqdm(
        total=runnable,
        initial=sum(len(b.points) for b in plan.batches if b.index in done),
        unit="pt",
        disable=None if args.progress is None else not args.progress,
        file=sys.stderr,
    )
    started = time.perf_counter()
    with executor, progress:
        for batch, rows in executor.map(sweep.run_batch, todo):
            store.save(batch.index, rows)
            parts.append(rows)
            progress.update(len(batch.points))
    seconds = time.perf_counter() - started
    table = sweep.assemble(plan, parts)
    table["front"] = recommend.trade_off_front(table).astype(np.int64)
    write_table(table, out / "results.csv")
    written = ["results.csv", "results.npz"]
    if not args.no_plots:
        from ..sweeps.plots import plot_all

        written += [p.name for p in plot_all(table, plan.columns, out)]
    ran = sum(len(b.points) for b in todo)
    rate = f" ({ran / seconds:.0f} points/s)" if ran and seconds > 0 else ""
    print(f"{out}: {', '.join(written)}; {ran} points run in {seconds:.1f} s{rate}")
    print(_summary(table, plan.columns))
    if args.recommend or constraints or args.across:
        rec = recommend.recommend(table, constraints, plan.columns, across)
        text = recommend.format_table(rec, args.top)
        write_bytes(out / "recommendation.txt", text.encode())
        write_table(rec.table, out / "recommendation.csv", rows=rec.rows)
        print(text, end="")
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    words = list(sys.argv[1:] if argv is None else argv)

    def body() -> int:
        return run(build_parser().parse_args(words), words)

    return run_main("boom-sweep", body)


if __name__ == "__main__":
    sys.exit(main())
