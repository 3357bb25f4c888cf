"""A design sweep run to its end: the configs, the plan and its batches on an executor
(this process, local workers or a Dask cluster), each finished batch stored, then the
results table, the plots and the recommendation (the library side of ``boom-sweep``; its
options and their checks are cli.sweep's).
"""

from __future__ import annotations

import contextlib
import gc
import math
import os
import sys
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import ConfigError
from ..files import check_apart, csv_cells, write_bytes, write_csv_columns, write_csv_lines, write_npz
from ..model import config
from ..model.parameters import Parameters
from ..programs import raise_pending
from ..solve import accelerate
from . import energy, plotter, recommend, sweep
from .executors import DaskExecutor, LocalExecutor
from .rules import Rules, range_edges
from .sampling import parse_axis, point_count, resolve_name
from .store import OUTPUTS, SweepStore, plot_names

#: Points integrated together unless --batch-size says otherwise: larger batches spend
#: less of their time in numpy's per-call overhead (bench/bench_sweep.py).
BATCH_SIZE = 1000

UNITS = {name: unit for name, unit, _ in sweep.METRICS}


@dataclass(frozen=True)
class SweepOptions:
    """What to sweep, how, where it runs and what to recommend: boom-sweep's options, by the
    names of their attributes (``cli.sweep.build_parser``; its help tells each one)."""

    config: Sequence[str] = ()  # params files; none: the built-in values
    set: Sequence[str] = ()  # KEY=VALUE overrides
    vary: Sequence[str] = ()  # the axes, NAME=SPEC
    sample: str = "grid"
    samples: int = 0
    seed: int = 0
    scenario: str = "lift"
    operators: int = 0  # seeded operator variations of a loader scenario per design
    duration: float = 5.0  # s
    lift_angle_deg: float = 20.0
    every: int = 1
    batch_size: int | None = None
    scheduler: str | None = None
    workers: int | None = None
    scheduler_timeout: float = 10.0  # s
    out: Path | None = None
    resume: bool = False
    no_plots: bool = False
    progress: bool | None = None
    recommend: bool = False
    max_pressure_pa: float | None = None
    max_lift_time_s: float | None = None
    no_cavitation: bool = False
    target_tolerance_deg: float = Rules.target_tolerance_deg
    set_down_tolerance_deg: float | None = None  # None: target_tolerance_deg
    settle_time_s: float | None = None
    allow_relief: bool = False
    require: Sequence[str] = ()
    across: Sequence[str] = ()
    rank_by: str | None = None  # recommend.RANKINGS; None: recommend.RANK_BY
    top: int = 10


def load_configs(files: Sequence[str], assignments: Sequence[str]) -> list[tuple[str, Parameters]]:
    """(name, parameters) per config file (or the defaults), with the --set overrides."""
    overrides: dict[str, Any] = dict(config.parse_assignment(s) for s in assignments)
    if not files:
        return [("default", config.from_overrides(overrides))]
    return [(Path(f).stem, config.load(f, overrides)) for f in files]


def rules_of(options: SweepOptions) -> Rules:
    """The rules every design must meet (see :mod:`rules`), as the options set them."""
    return Rules(
        options.target_tolerance_deg, options.set_down_tolerance_deg, options.settle_time_s, options.max_pressure_pa,
        options.allow_relief,
    )  # fmt: skip


def constraints_of(options: SweepOptions, columns: Sequence[str]) -> list[recommend.Constraint]:
    """The rules (:func:`rules_of`), then the constraints the options add."""
    found = rules_of(options).constraints()
    found += [recommend.parse_constraint(text, columns) for text in options.require]
    if options.max_lift_time_s is not None:
        found.append(recommend.Constraint("lift_time_s", "<=", options.max_lift_time_s))
    if options.no_cavitation:
        found.append(recommend.Constraint("cavitation_s", "==", 0.0))
    return found


def write_table(
    table: Mapping[str, np.ndarray], path_csv: Path, rows: Sequence[int] | None = None, cells: BatchCells | None = None
) -> None:
    """The table (or the given rows of it) as CSV, and beside a .npz of the same columns.
    ``cells``: the cells of the whole table's batch columns, formatted as its batches came."""
    names = list(table)
    index = np.arange(len(table[names[0]])) if rows is None else np.asarray(rows, dtype=int)
    columns = {n: np.asarray(table[n])[index] for n in names}
    if cells is not None and rows is None:
        write_csv_lines(path_csv, names, cells.lines(table))
    else:
        write_csv_columns(path_csv, names, [columns[n] for n in names])
    write_npz(path_csv.with_suffix(".npz"), columns)


class BatchCells:
    """The CSV cells of a sweep table's batch columns (sweep.run_batch's: status, reason, failure
    time and metrics), formatted as each batch is stored, while the next ones run, rather than
    all once the last is done: a float's text takes 0.35 us, 0.2 s for these 48 columns of the
    10 000 rows of a 5 s lift's sweep, which beside a kernel on every core costs about half of that."""

    columns = ("status", "reason", "failed_at_s", *sweep.METRIC_NAMES)

    def __init__(self, points: int) -> None:
        self._by_point: list[str | None] = [None] * points

    def add(self, rows: Mapping[str, np.ndarray]) -> None:
        """Format the rows of a batch (``rows["point"]``: their points)."""
        cells = csv_cells([rows[name] for name in self.columns])
        for point, text in zip(np.asarray(rows["point"]).tolist(), cells, strict=True):
            self._by_point[point] = text

    def lines(self, table: Mapping[str, np.ndarray]) -> list[str]:
        """The CSV lines of ``table`` (sweep.assemble's: row k is point k, with the batch columns
        together after the point's), with the batch columns' cells formatted here; those of rows
        not added (stored by an earlier run, invalid) are formatted now."""
        names = list(table)
        first = names.index(self.columns[0])
        after = first + len(self.columns)
        if tuple(names[first:after]) != self.columns:
            raise ValueError(f"the table's batch columns are not {self.columns} in that order: {names}")
        missing = [point for point, text in enumerate(self._by_point) if text is None]
        if missing:
            self.add({"point": np.array(missing)} | {name: np.asarray(table[name])[missing] for name in self.columns})
        parts = [csv_cells([table[name] for name in names[:first]]), self._by_point]
        if after < len(names):
            parts.append(csv_cells([table[name] for name in names[after:]]))
        return list(map(",".join, zip(*parts, strict=True)))


def applicable(
    constraints: Sequence[recommend.Constraint], table: Mapping[str, np.ndarray]
) -> list[recommend.Constraint]:
    """The constraints that apply to some row of ``table`` (an open-loop sweep's table has no
    targets: the rules of a closed-loop run do not apply to it, see rules.Rules)."""
    return [c for c in constraints if c.applies(table).any()]


def _summary(table: Mapping[str, np.ndarray], columns: Sequence[str], qualifies: np.ndarray) -> str:
    """The points' statuses, and the fastest and most frugal lift of the points whose design
    qualifies (``qualifies``: per row)."""
    status = np.asarray(table["status"])
    counts = ", ".join(
        f"{int((status == s).sum())} {s}" + (f" ({sweep.STATUS_MEANINGS[s]})" if s in sweep.STATUS_MEANINGS else "")
        for s in sweep.STATUSES
        if (status == s).any()
    )
    lines = [f"{len(status)} points: {counts}"]
    ok = np.nonzero(qualifies)[0]
    if len(ok) < int((status == "ok").sum()):
        lines.append(f"  of the ok points, {len(ok)} are of designs that meet every rule and constraint:")
    if len(ok):
        for metric, label in (("lift_time_s", "fastest lift"), ("lift_energy_j", "least lift energy")):
            best = ok[np.nanargmin(np.asarray(table[metric], float)[ok])]
            where = ", ".join(f"{c}={recommend.format_value(table[c][best])}" for c in columns) or "the one point"
            lines.append(f"  {label}: {float(table[metric][best]):.4g} {UNITS[metric]} at {where}")
    return "\n".join(lines)


def _kernel_call(batch: sweep.Batch) -> tuple:
    """What the first batch of its kind may compile: its run kernel (batch.SetRun), for the
    arguments that its points' shared settings give it (sweep.batch_key)."""
    p = batch.params[0]
    elements = accelerate.with_elements(batch.params)
    return sweep.batch_key(p), accelerate.batch_runner(p.mode, p.method, len(batch.params), elements)


def _compiling(batches: Sequence[sweep.Batch]) -> list[str]:
    """A line for each model and method whose compiled code ``batches`` (run on this machine)
    call and numba's cache does not hold yet: its batches compile it, for tens of seconds,
    without a word else. (A batch's sets share their mode and method: sweep.SHARED.)"""
    kernels: dict[tuple[str, str], set] = {}
    for batch in batches:
        p = batch.params[0]
        kernels.setdefault((p.mode, p.method), set()).update(
            accelerate.run_kernels(p.mode, p.method, len(batch.params), accelerate.with_elements(batch.params))
        )
    return [
        accelerate.compiling_notice(mode, method, "its batches")
        for (mode, method), needed in kernels.items()
        if accelerate.not_in_cache(list(needed))
    ]


def _settings(options: SweepOptions) -> dict[str, Any]:
    """The keyword arguments of sweep.request that the options give."""
    return {
        "scenario": options.scenario,
        "duration_s": options.duration,
        "sample": options.sample,
        "count": options.samples,
        "seed": options.seed,
        "lift_angle_deg": options.lift_angle_deg,
        "every": options.every,
        "operators": options.operators,
    }


def _batch_size(options: SweepOptions, stored: Mapping[str, Any] | None, points: int) -> int:
    """Points a batch: those a resumed sweep began with, else --batch-size, or, with --workers and no
    --batch-size, fewer than BATCH_SIZE where that gives every worker a batch."""
    if options.batch_size is None and stored is not None:
        return int(stored["batch_size"])  # resume in the batches it began with, wherever it runs now
    if options.batch_size is None and options.workers:
        share = math.ceil(points / options.workers)
        return share if 0 < share < BATCH_SIZE else BATCH_SIZE
    return options.batch_size or BATCH_SIZE


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
class Reached:
    """How far a sweep got, for the line it ends with if it is interrupted."""

    out: Path | None = None
    store: SweepStore | None = None
    plan: sweep.Plan | None = None

    def interrupted(self, why: str, finish: Callable[[Path], str]) -> str:
        """What stopped the sweep, what is kept, and how to go on (``finish(out)``: the command
        that finishes the sweep stored in ``out``). What this process was writing when it stopped
        is removed: only whole batches stay."""
        if self.store is not None:
            self.store.remove_own_temporaries()
        done = len(self.store.done()) if self.store is not None else 0
        if self.out is None or done == 0:
            return f"boom-sweep: error: {why} before a batch finished; nothing was stored"
        total = f" of {len(self.plan.batches)}" if self.plan is not None else ""
        return (
            f"boom-sweep: error: {why}; {done}{total} batches are stored in {self.out}; finish with: {finish(self.out)}"
        )


def run_sweep(options: SweepOptions, reached: Reached) -> int:
    """The sweep the options describe, recording in ``reached`` how far it got (for the line an
    interruption ends with); 0 when done. Numbers are checked by the caller (cli.sweep)."""
    configs = load_configs(options.config, options.set)
    axes = [parse_axis(text) for text in options.vary]
    across = [name if name == "operator" else resolve_name(name) for name in options.across]
    out = options.out or Path("sweeps") / time.strftime("sweep-%Y%m%d-%H%M%S")
    check_apart(out, [Path(c) for c in options.config or []])
    operator = ("operator",) if options.operators else ()
    columns = (("config",) if len(configs) > 1 else ()) + operator + tuple(a.name for a in axes)
    recommend.check_across(across, columns)  # before the work, not after it
    constraints = constraints_of(options, [*columns, "status", "reason", "failed_at_s", *sweep.METRIC_NAMES])
    store = SweepStore(out, options.resume, [*OUTPUTS, *plot_names(columns)])
    reached.out, reached.store = out, store
    variants = configs * max(1, options.operators)  # each config once per operator
    points = len(variants) * point_count(axes, options.sample, options.samples)
    batch_size = _batch_size(options, store.stored, points)
    settings = _settings(options)
    cost = sweep.estimate(variants, axes, duration_s=options.duration, sample=options.sample, count=options.samples,
                          batch_size=batch_size)  # fmt: skip
    sweep.check_fits(cost)
    asked = sweep.request(configs, axes, batch_size=batch_size, **settings)
    if store.stored is not None:  # the folder's sweep must be this one: known before planning it
        store.begin(asked.as_json())
    for path in store.removed:
        print(f"boom-sweep: note: removed {path}, left unfinished by an earlier run that was stopped", file=sys.stderr)
    if cost.plan_s >= 1:
        print(
            f"boom-sweep: planning {cost.points} points in {cost.batches} or more batches "
            f"({sweep.duration_text(cost.plan_s)}); to run: {cost.run_time(cost.points, os.cpu_count() or 1)}",
            file=sys.stderr,
            flush=True,
        )
    drawer = None
    try:  # forked now, the plots' process loads matplotlib while this one plans and loads its kernel
        drawer = None if options.no_plots else plotter.start()
        plan = reached.plan = sweep.plan(asked)
        store.begin(plan.request)
        with _frozen_heap():
            return _run_plan(options, out, store, plan, cost, constraints, across, drawer)
    except BaseException:
        if drawer is not None:
            drawer.stop()
        raise


def _recommending(options: SweepOptions) -> bool:
    """Whether the options ask for a recommendation (the rules alone do not: every sweep has them)."""
    return bool(
        options.recommend or options.require or options.max_pressure_pa is not None
        or options.max_lift_time_s is not None or options.no_cavitation or options.settle_time_s is not None
        or options.across or options.rank_by
    )  # fmt: skip


@contextlib.contextmanager
def _frozen_heap() -> Iterator[None]:
    """What is alive now (the plan: a Parameters and a dict per point) out of the garbage
    collector's walks while the batches run, back in them after: its full collections walked
    all of it (gc.callbacks, a 10 000-point sweep: 0.19 s of collections, 0.09 s frozen)."""
    gc.freeze()
    try:
        yield
    finally:
        gc.unfreeze()


def _run_plan(
    options: SweepOptions,
    out: Path,
    store: SweepStore,
    plan: sweep.Plan,
    cost: sweep.Estimate,
    constraints: Sequence[recommend.Constraint],
    across: Sequence[str],
    drawer: plotter.Plotter | None,
) -> int:
    """Run what is not stored yet, storing each batch as it finishes; then the table, plots and
    ranking. ``drawer``: the process that draws the plots, forked before the plan (None: this
    process draws them, unless --no-plots)."""
    parts, done = _stored_parts(store, plan)
    todo = [b for b in plan.batches if b.index not in done]
    executor = (
        DaskExecutor(options.scheduler, options.workers, options.scheduler_timeout)
        if (options.scheduler or options.workers) is not None
        else LocalExecutor(load=sweep.load_kernel, kind=_kernel_call)
    )
    runnable = plan.size - len(plan.invalid)
    batches = f"{len(plan.batches)} batch" + ("" if len(plan.batches) == 1 else "es")
    print(
        f"boom-sweep: {plan.size} points ({len(plan.invalid)} invalid) in {batches} of up to "
        f"{plan.request['batch_size']}; {len(plan.batches) - len(todo)} done before, {len(todo)} to run "
        f"{executor.description} ({cost.run_time(sum(len(b.points) for b in todo), os.cpu_count() or 1)})",
        file=sys.stderr,
        flush=True,
    )
    for notice in _compiling(todo if options.scheduler is None else []):
        print(f"boom-sweep: {notice}", file=sys.stderr, flush=True)
    from tqdm import tqdm

    class Progress(tqdm):
        monitor_interval = 0  # (no monitor thread: plots.plot_all may fork, programs.can_fork)

    progress = Progress(
        total=runnable,
        initial=sum(len(b.points) for b in plan.batches if b.index in done),
        unit="pt",
        disable=None if options.progress is None else not options.progress,
        file=sys.stderr,
    )
    started = time.perf_counter()
    cells = BatchCells(plan.size)
    with executor, progress:
        for batch, rows in executor.map(sweep.run_batch, todo):
            store.save(batch.index, rows)
            parts.append(rows)
            cells.add(rows)
            progress.update(len(batch.points))
            raise_pending()  # a Ctrl-C a finalizer swallowed here (batches on workers): stop after this one
    seconds = time.perf_counter() - started
    table = sweep.assemble(plan, parts)
    table["front"] = recommend.trade_off_front(table).astype(np.int64)
    constraints = applicable(constraints, table)
    qualifies = recommend.qualifying(table, constraints, plan.columns, across)
    table["qualifies"] = qualifies.astype(np.int64)
    if drawer is not None:
        drawer.draw(table, plan.columns, out)  # it draws while the files below are written here
    write_table(table, out / "results.csv", cells=cells)
    written = ["results.csv", "results.npz"]
    battery = np.isfinite(np.asarray(table["battery_energy_j"], dtype=float)[np.asarray(table["status"]) == "ok"]).any()
    # each design's band over its operators' cycles: their table, and the battery's summary
    bands = energy.operator_bands(table, plan.columns) if battery or "operator" in plan.columns else None
    if bands is not None:
        bands["qualifies"] = energy.qualifying_designs(table, plan.columns, qualifies).astype(np.int64)
    if "operator" in plan.columns:
        write_table(bands, out / "operators.csv")
        written += ["operators.csv", "operators.npz"]
    ranked = None
    if _recommending(options):
        ranked = recommend.recommend(table, constraints, plan.columns, across, options.rank_by or recommend.RANK_BY)
        text = recommend.format_table(ranked, options.top)
        if len(ranked.rows):
            rank_by = options.rank_by or recommend.RANK_BY
            score = ranked.table[rank_by] if rank_by in ranked.table else None
            edges = range_edges(ranked.table, ranked.columns[1:], int(ranked.rows[0]), score=score)
            text += "".join(f"{line}\n" for line in edges)
        write_bytes(out / "recommendation.txt", text.encode())
        write_table(ranked.table, out / "recommendation.csv", rows=ranked.rows)
    if drawer is not None:
        written += drawer.wait()
    elif not options.no_plots:
        from .plots import plot_all

        written += [p.name for p in plot_all(table, plan.columns, out)]
    ran = sum(len(b.points) for b in todo)
    rate = f" ({ran / seconds:.0f} points/s)" if ran and seconds > 0 else ""
    print(f"{out}: {', '.join(written)}; {ran} points run in {seconds:.1f} s{rate}")
    print(_summary(table, plan.columns, qualifies))
    if battery:
        print(energy.summary(bands, plan.columns, bands["qualifies"].astype(bool), across))
    if ranked is not None:
        print(text, end="")
    return 0
