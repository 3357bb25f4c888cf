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

Errors in arguments or configs print one line and exit 2.
"""

from __future__ import annotations

import argparse
import math
import shlex
import sys
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import ConfigError
from ..files import check_apart, csv_cell, write_bytes, write_csv, write_npz
from ..model import config
from ..model.parameters import Parameters, from_mapping
from ..sweeps import recommend, sweep
from ..sweeps.executors import DaskExecutor, LocalExecutor
from ..sweeps.sampling import SAMPLES, parse_axis, resolve_name
from ..sweeps.store import SweepStore, stored_request
from .common import DefaultsFormatter, RaisingParser, run_main

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


def run(args: argparse.Namespace, argv: Sequence[str]) -> int:
    configs = load_configs(args.config, args.set)
    axes = [parse_axis(text) for text in args.vary]

    def make_plan(batch_size: int) -> sweep.Plan:
        return sweep.plan(
            configs,
            axes,
            scenario=args.scenario,
            duration_s=args.duration,
            sample=args.sample,
            count=args.samples,
            seed=args.seed,
            lift_angle_deg=args.lift_angle_deg,
            every=args.every,
            batch_size=batch_size,
        )

    out = args.out or Path("sweeps") / time.strftime("sweep-%Y%m%d-%H%M%S")
    check_apart(out, [Path(c) for c in args.config or []])
    stored = stored_request(out) if args.resume else None
    if args.batch_size is None and stored and isinstance(stored.get("batch_size"), int):
        plan = make_plan(stored["batch_size"])  # resume in the batches it began with, wherever it runs now
    else:
        plan = make_plan(args.batch_size or BATCH_SIZE)
        if args.batch_size is None and args.workers:  # a batch for every worker
            share = math.ceil((plan.size - len(plan.invalid)) / args.workers)
            if 0 < share < BATCH_SIZE:
                plan = make_plan(share)
    table_columns = [*plan.columns, "status", "reason", "failed_at_s", *sweep.METRIC_NAMES]
    constraints = constraints_of(args, table_columns)
    across = [resolve_name(name) for name in args.across]
    recommend.check_across(across, plan.columns)  # before the work, not after it
    if args.top < 1:
        raise ConfigError(f"--top must be >= 1, got {args.top}")
    store = SweepStore(out, plan.request, args.resume)
    parts = []
    done = store.done()
    for index in sorted(done):
        rows = store.load(index)
        if rows is None:
            done.discard(index)
        else:
            parts.append(rows)
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
        f"{executor.description}",
        file=sys.stderr,
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
    try:
        with executor, progress:
            for batch, rows in executor.map(sweep.run_batch, todo):
                store.save(batch.index, rows)
                parts.append(rows)
                progress.update(len(batch.points))
    except KeyboardInterrupt:
        print(
            f"\nboom-sweep: interrupted; {len(store.done())} of {len(plan.batches)} batches are stored in {out}. "
            f"Finish with:\n  {_resume_command(argv, out, args)}",
            file=sys.stderr,
        )
        return 130
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
        args = build_parser().parse_args(words)
        for name in ("duration", "lift_angle_deg", "max_pressure_pa", "max_lift_time_s"):
            value = getattr(args, name)
            if value is not None and not math.isfinite(value):
                raise ConfigError(f"--{name.replace('_', '-')} must be a finite number, got {value}")
        return run(args, words)

    return run_main("boom-sweep", body)


if __name__ == "__main__":
    sys.exit(main())
