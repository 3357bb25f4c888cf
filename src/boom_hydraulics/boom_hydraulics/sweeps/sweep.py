"""Design sweeps: many parameter sets driven through one valve scenario, in batches.

:func:`request` checks what a sweep is asked (base configs, axes, a scenario, ...) and
:func:`plan` turns it into points and batches; every batch holds points that can be
integrated together (same mode, method, time step, substeps and valve command, see
:mod:`batch`). :func:`run_batch` integrates one batch and returns one table row per point:
the metrics of :mod:`analysis` plus a status and, where a point did not lift as asked, the
reason. A batch is a plain picklable value, so it runs the same in this process or on a Dask worker.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..analysis import metrics as analysis
from ..analysis.linear_model import mid_stroke_modes
from ..errors import BoomHydraulicsError, ConfigError
from ..model import ledger, physical
from ..model.battery import J_PER_KWH
from ..model.parameters import Parameters, as_dict, describe, from_mapping, names_in
from ..solve import commands, duty_cycles, lanes, streaming
from ..solve.batch import SHARED, run_sets
from ..solve.integrators import BATCHED
from .sampling import Axis, Spacing, point_count, sample_points

#: Metric columns a sweep takes from each run: name, unit, meaning (see analysis.metrics).
STREAMED_METRICS: tuple[tuple[str, str, str], ...] = (
    ("lift_completed", "1", "1 if the boom rose through the lift angle"),
    ("lift_time_s", "s", "time to rise through the lift angle"),
    ("lift_energy_j", "J", "energy drawn from the supply during the lift"),
    ("lift_valve_loss_j", "J", "energy dissipated in the valve during the lift"),
    ("rise_deg", "deg", "largest rise of the boom elevation"),
    ("lift_m", "m", "largest rise of the cylinder length"),
    ("peak_speed_m_s", "m/s", "peak rod speed"),
    ("rms_speed_m_s", "m/s", "RMS rod speed"),
    ("overshoot_m", "m", "rise of q1 after the valve closes above where it is when the hold ends"),
    ("oscillation_hz", "Hz", "frequency of p1's ringing after the valve closes, from its maxima"),
    ("damping_ratio", "1", "damping ratio of that ringing, from the decay of its swings"),
    ("peak_pressure_pa", "Pa", "highest chamber pressure"),
    ("min_pressure_pa", "Pa", "lowest chamber pressure"),
    ("cavitation_s", "s", "time with a chamber at the cavitation floor"),
    ("relief_s", "s", "time with a relief valve open"),
    ("settling_s", "s", "closed loop (angle scenario): time from the first move's start into +-2 % of its step"),
    ("target_overshoot_deg", "deg", "closed loop: how far the boom passed the first move's target"),
    ("target_error_deg", "deg", "closed loop: target minus boom angle when the first move's hold ends"),
    ("worst_target_error_deg", "deg", "closed loop: the largest |target - boom angle| at the end of a target's phase"),
    ("worst_settle_time_s", "s", "closed loop: the longest time from a target's phase start into +-2 % of its step"),
    ("set_down_error_deg", "deg", "closed loop: boom angle above the target (the ground) as the payload is released"),
    ("supply_energy_j", "J", "energy drawn from the supply over the whole run"),
    ("valve_loss_energy_j", "J", "energy dissipated in the valve over the whole run"),
    ("battery_energy_j", "J", "energy the battery gave less what it took back, over the whole run"),
    ("battery_drawn_j", "J", "energy the battery gave over the whole run"),
    ("battery_returned_j", "J", "energy the battery took back over the whole run (recovered)"),
    ("lift_work_j", "J", "potential energy raised over the whole run: the useful work"),
    ("efficiency", "1", "lift work over battery energy"),
    ("peak_battery_power_w", "W", "most power the battery gave, the mean over a sample interval (--every steps)"),
)
assert tuple(m[0] for m in STREAMED_METRICS) == streaming.NAMES, "the streamed metrics are streaming's, in its order"
#: Metric columns from each point's linear model at mid-stroke, valve centred (analysis.linear_model).
LINEAR_METRICS: tuple[tuple[str, str, str], ...] = (
    ("natural_frequency_hz", "Hz", "linear model at mid-stroke, valve centred: the hydraulic mode's natural frequency"),
    ("linear_damping_ratio", "1", "linear model at mid-stroke, valve centred: the hydraulic mode's damping ratio"),
)
#: Metric columns of each point's battery (model/battery.py).
BATTERY_METRICS: tuple[tuple[str, str, str], ...] = (
    ("cycles_per_charge", "1", "the battery's usable energy over battery_energy_j: runs (work cycles) per charge"),
)
#: The ledger's integrals over the run beyond the battery's and the lift's (model.ledger.INTEGRALS:
#: where the battery's energy went), from each point's last state; NaN in paper mode.
LEDGER_TERMS = ledger.INTEGRALS[2:-1]
LEDGER_METRICS: tuple[tuple[str, str, str], ...] = tuple(
    (f"{name}_j", "J", f"over the whole run: {meaning}") for name, _, _, meaning in ledger.TERMS if name in LEDGER_TERMS
)
#: Metric columns of a sweep table: name, unit, meaning.
METRICS = STREAMED_METRICS + LINEAR_METRICS + BATTERY_METRICS + LEDGER_METRICS
METRIC_NAMES = tuple(name for name, _, _ in METRICS)

#: Status of a point: ok (lifted through the angle), incomplete (did not within the run),
#: failed (the integration diverged or left the model's geometry), invalid (parameters
#: rejected before running).
STATUSES = ("ok", "incomplete", "failed", "invalid")
#: What a status other than ok means, as the sweep's summary says it.
STATUS_MEANINGS = {
    "incomplete": "did not lift through --lift-angle-deg within --duration",
    "failed": "the run stopped: see their reason column",
    "invalid": "parameters refused before running: see their reason column",
}

#: Parameters that all points of one batch share: integration and the scenario (the valve command).
BATCH_KEYS = (*SHARED, *names_in("scenario"))


#: Memory a point takes while a sweep runs, rounded up: its values and Parameters in the plan
#: (2.2 kB, measured with tracemalloc on a one-axis plan of 100 000 points), its table row
#: (0.6 kB, numpy's nbytes of a 10 000-point table) and its row's CSV text, kept from its
#: batch's end to the table's writing (0.7 kB; runner.BatchCells); while the plots are drawn,
#: the row again in the plots' process (0.45 kB, without its reason: sweeps.plotter) and its
#: spots in the figure each of two processes draws (12 panels of x and y, 0.4 kB each).
BYTES_PER_POINT = 5120

#: State-steps the compiled run kernel takes per second and core, for the up-front estimate of a
#: sweep's run time: a default 10 000-point sweep of the 5 s lift took 5e7 steps in 8.0-8.6 s of
#: batches on 2 cores (3.1 M per core), the answer's sweep of three drives over loader cycles
#: 3.56 M steps/s (1.8 M per core: the fixed pump's relief takes two substeps a step); measured
#: on 2026-12-04 (bench/bench_speed.py), the lower one taken for a loaded machine.
STEPS_PER_CORE_S = 1.8e6

#: Wall time planning takes per point (its Parameters checked and grouped into batches): 10-12 us
#: measured for 10 000 and 40 000 points on a 2-core machine (2026-12-04), 3x for a loaded one.
PLAN_S_PER_POINT = 3e-5

#: Steps of one point beyond which float64 time no longer tells one step from the next.
MAX_STEPS_PER_POINT = 2**53


@dataclass(frozen=True)
class Estimate:
    """What a sweep will cost, known before any point is planned."""

    points: int
    batches: int  # at least: points that cannot share a batch (another time step, say) make more
    steps: float  # state-steps of all points together (at least: the stability bound may add substeps)
    memory_bytes: float  # to hold the plan and the table while the sweep runs

    @property
    def plan_s(self) -> float:
        return self.points * PLAN_S_PER_POINT

    def run_time(self, points: int, cores: int) -> str:
        """The steps of ``points`` of these and how long they take, as a phrase."""
        steps = self.steps * points / self.points if self.points else 0.0
        seconds = steps / (STEPS_PER_CORE_S * max(1, cores))
        rate = f"{STEPS_PER_CORE_S / 1e6:g} M steps/s on each of {cores} cores"
        return f"{steps:.3g} steps, {duration_text(seconds)} at {rate}"


def duration_text(seconds: float) -> str:
    """A run time as a person reads it: about 40 s, 12 min, 35 h, 9 days, 2e+06 years; under a second."""
    for unit, size in (("years", 365.25 * 86400), ("days", 86400), ("h", 3600), ("min", 60)):
        if seconds >= 2 * size:
            return (
                f"about {seconds / size:.2g} {unit}" if seconds / size >= 100 else f"about {seconds / size:.0f} {unit}"
            )
    return f"about {seconds:.0f} s" if seconds >= 1 else "under a second"


def available_memory_bytes() -> float | None:
    """Memory the system can give this process without swapping (MemAvailable), or None if unknown."""
    try:
        with open("/proc/meminfo", encoding="ascii") as handle:
            for line in handle:
                if line.startswith("MemAvailable:"):
                    return float(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return float(os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))
    except (OSError, ValueError, AttributeError):
        return None


def _extreme(configs: Sequence[tuple[str, Parameters]], axes: Sequence[Axis], name: str, pick) -> float:
    """The smallest (``pick=min``) or largest valid (positive) value that parameter ``name`` takes in
    the sweep; values out of range make invalid points, which do not run."""
    values = [float(v) for _, params in configs if (v := getattr(params, name)) > 0]
    for axis in axes:
        if axis.name != name:
            continue
        if axis.values is None:
            ends: Sequence[Any] = (axis.low, axis.high)
        else:
            ends = (axis.values.low, axis.values.high) if isinstance(axis.values, Spacing) else axis.values
        values += [float(v) for v in ends if isinstance(v, (int, float)) and v > 0]
    return pick(values) if values else float(describe(name)["default"])


def check_duration(duration_s: float) -> None:
    """Raise ConfigError unless ``duration_s`` is a positive, finite number of seconds that a
    scenario's commands can span: a command's time is at most command_times_s's upper bound."""
    if not (duration_s > 0 and math.isfinite(duration_s)):
        raise ConfigError(f"--duration must be a positive number of seconds, got {duration_s}")
    longest = describe("command_times_s")["high"]
    if duration_s > longest:
        raise ConfigError(
            f"--duration {duration_s:g} s is longer than a scenario's commands can span (a command's time is at "
            f"most {longest:g} s); choose a duration of at most {longest:g} s"
        )


def estimate(
    configs: Sequence[tuple[str, Parameters]],
    axes: Sequence[Axis],
    *,
    duration_s: float,
    sample: str = "grid",
    count: int = 0,
    batch_size: int = 1000,
) -> Estimate:
    """Points, batches, steps and memory of a sweep, without planning it (that takes about 1 ms a point).

    Raises ConfigError for a duration whose steps float64 time cannot count.
    """
    check_duration(duration_s)
    if batch_size < 1:
        raise ConfigError(f"--batch-size must be >= 1, got {batch_size}")
    points = len(configs) * point_count(axes, sample, count)
    dt = _extreme(configs, axes, "time_step_s", min)
    substeps = max(1.0, _extreme(configs, axes, "substeps", max))
    per_point = duration_s / dt * substeps
    if not per_point <= MAX_STEPS_PER_POINT:
        raise ConfigError(
            f"--duration {duration_s:g} s is {per_point:.3g} steps a point at time_step_s = {dt:g} s; "
            f"simulated time cannot count more than 2**53 steps: give a duration of seconds to hours"
        )
    return Estimate(points, math.ceil(points / batch_size), points * per_point, points * float(BYTES_PER_POINT))


def check_fits(cost: Estimate, available: float | None = None) -> None:
    """Raise ConfigError, before anything is planned, if the sweep cannot be held in memory."""
    free = available_memory_bytes() if available is None else available
    if free is not None and cost.memory_bytes > free:
        raise ConfigError(
            f"{cost.points} points need about {_bytes_text(cost.memory_bytes)} of memory to plan and tabulate, "
            f"and {_bytes_text(free)} is free; sweep fewer points (fewer values per axis, or a random or lhs "
            "sample of fewer --samples), or split the sweep into several, each with its own --out"
        )


def _bytes_text(size: float) -> str:
    for unit, scale in (("TB", 1e12), ("GB", 1e9), ("MB", 1e6)):
        if size >= scale:
            return f"{size / scale:.3g} {unit}"
    return f"{size / 1e3:.3g} kB"


@dataclass(frozen=True)
class Batch:
    """Points that are integrated together."""

    index: int
    points: tuple[int, ...]
    params: tuple[Parameters, ...]
    duration_s: float
    every: int
    lift_angle_deg: float


@dataclass(frozen=True)
class Plan:
    """Everything a sweep will compute, before any of it runs."""

    request: dict[str, Any]  # what was asked, JSON-able (kept with the results for resuming)
    columns: tuple[str, ...]  # the point-describing columns: config (if several) and the axes
    points: tuple[dict[str, Any], ...]  # per point, its values of ``columns``
    invalid: dict[int, str]  # point -> why its parameters were rejected
    batches: tuple[Batch, ...]

    @property
    def size(self) -> int:
        return len(self.points)


def _bases(
    configs: Sequence[tuple[str, Parameters]], scenario: str, duration_s: float, operators: int = 0
) -> list[tuple[str, Parameters]]:
    """Each config with the scenario's valve command applied, checked to run in a batch; with
    ``operators``, one base per config and operator (the scenario ``NAME:SEED``, seeds 1 to N,
    named CONFIG/SEED)."""
    bases = []
    for name, params in configs:
        variants = [(name, scenario)]
        if operators:
            variants = [(f"{name}/{seed}", f"{scenario}:{seed}") for seed in range(1, operators + 1)]
        for variant, text in variants:
            try:
                bases.append((variant, from_mapping(commands.scenario(text, duration_s, params), base=params)))
            except ConfigError as exc:
                raise ConfigError(f"scenario {text!r} does not fit config {name!r}: {exc}") from None
    for base_name, base in bases:
        if base.method not in BATCHED:
            raise ConfigError(
                f"config {base_name!r} uses method {base.method!r}; sweeps integrate with an explicit "
                f"fixed step ({' or '.join(BATCHED)}): set method: rk4"
            )
    return bases


@dataclass(frozen=True)
class Request:
    """What a sweep is asked, checked (:func:`request`), before a point is planned (:func:`plan`)."""

    configs: tuple[tuple[str, Parameters], ...]  # (name, parameters) with the scenario's valve command
    axes: tuple[Axis, ...]
    scenario: str
    duration_s: float
    sample: str
    count: int
    seed: int
    lift_angle_deg: float
    every: int
    batch_size: int
    operators: int = 0  # seeded operator variations of the scenario per design (0: the nominal only)

    def as_json(self) -> dict[str, Any]:
        """The request, JSON-able, as the sweep's folder keeps it (to match it when resuming)."""
        return {
            "configs": {name: as_dict(base) for name, base in self.configs},
            "axes": [a.as_request() for a in self.axes],
            "sample": self.sample,
            "count": self.count,
            "seed": self.seed,
            "scenario": self.scenario,
            "duration_s": self.duration_s,
            "lift_angle_deg": self.lift_angle_deg,
            "every": self.every,
            "batch_size": self.batch_size,
            "operators": self.operators,
        }


def request(
    configs: Sequence[tuple[str, Parameters]],
    axes: Sequence[Axis],
    *,
    scenario: str = "lift",
    duration_s: float = 5.0,
    sample: str = "grid",
    count: int = 0,
    seed: int = 0,
    lift_angle_deg: float = analysis.DEFAULT_LIFT_ANGLE_DEG,
    every: int = 1,
    batch_size: int = 1000,
    operators: int = 0,
) -> Request:
    """What a sweep is asked, checked, and found without planning a point, so that a sweep
    folder can be matched against it before any planning. ``configs`` are (name, parameters)
    pairs; with more than one, the config name is a column of the table. With ``operators`` N,
    every design runs the N seeded variations of the scenario (``loader:1`` ...), and the seed is
    the table's column ``operator``."""
    if not configs:
        raise ConfigError("a sweep needs at least one config")
    check_duration(duration_s)
    if not (0 < lift_angle_deg < 180):
        raise ConfigError(f"--lift-angle-deg must lie in (0, 180), got {lift_angle_deg}")
    if every < 1 or batch_size < 1:
        raise ConfigError(f"--every and --batch-size must be >= 1, got {every} and {batch_size}")
    names = [name for name, _ in configs]
    if len(set(names)) != len(names):
        raise ConfigError(f"two configs share the name {names}; give the files different names")
    if operators < 0:
        raise ConfigError(f"--operators must be >= 0, got {operators}")
    if operators and scenario.partition(":")[0] not in duty_cycles.CYCLES:
        raise ConfigError(
            f"--operators varies the scenarios {', '.join(duty_cycles.CYCLES)}; {scenario!r} has no operator"
        )
    if operators and ":" in scenario:
        raise ConfigError(f"--operators seeds the scenario itself: give --scenario {scenario.partition(':')[0]}")
    if scenario.partition(":")[0] in duty_cycles.CYCLES:  # a work cycle counts whole: per cycle, per charge
        seeds = range(1, operators + 1) if operators else [int(scenario.partition(":")[2] or 0)]
        cycle_s = max(duty_cycles.loader_duration_s(seed) for seed in seeds)
        if duration_s < cycle_s:
            raise ConfigError(
                f"--duration {duration_s:g} s is shorter than the {scenario} cycle ({cycle_s:.1f} s"
                + (f", the longest of the {operators} operators'" if operators else "")
                + f"); give --duration {math.ceil(cycle_s)} or more"
            )
    bases = tuple(_bases(configs, scenario, duration_s, operators))
    return Request(
        bases, tuple(axes), scenario, duration_s, sample, count, seed, lift_angle_deg, every, batch_size, operators
    )


def plan(asked: Request) -> Plan:
    """The points of the request's axes (sampled by its ``sample``) over every base config,
    driven by its scenario.

    Points whose parameters are invalid (a rod wider than its piston, say) are kept with the
    reason and not run. A sweep that cannot be held in memory is refused before any point is
    planned (:func:`check_fits`).
    """
    configs, axes = asked.configs, asked.axes
    check_fits(estimate(configs, axes, duration_s=asked.duration_s, sample=asked.sample, count=asked.count,
                        batch_size=asked.batch_size))  # fmt: skip
    samples = sample_points(axes, asked.sample, asked.count, asked.seed)
    several = len(configs) > max(1, asked.operators)  # more than one config file
    operator = ("operator",) if asked.operators else ()
    columns = (("config",) if several else ()) + operator + tuple(a.name for a in axes)
    points: list[dict[str, Any]] = []
    invalid: dict[int, str] = {}
    groups: dict[tuple, list[tuple[int, Parameters]]] = {}
    for base_name, base in configs:
        config, _, operator = base_name.rpartition("/") if asked.operators else (base_name, "", "")
        described = ({"config": config} if several else {}) | ({"operator": int(operator)} if operator else {})
        base_key = batch_key(base)
        for values in samples:
            index = len(points)
            points.append({**described, **values})
            try:
                params = from_mapping(values, base=base)
            except ConfigError as exc:
                invalid[index] = str(exc)
                continue
            key = batch_key(params) if _BATCH_KEY_SET.intersection(values) else base_key
            groups.setdefault(key, []).append((index, params))
    batches = []
    for members in groups.values():
        for start in range(0, len(members), asked.batch_size):
            chunk = members[start : start + asked.batch_size]
            batches.append(
                Batch(
                    index=len(batches),
                    points=tuple(i for i, _ in chunk),
                    params=tuple(p for _, p in chunk),
                    duration_s=asked.duration_s,
                    every=asked.every,
                    lift_angle_deg=asked.lift_angle_deg,
                )
            )
    return Plan(asked.as_json(), columns, tuple(points), invalid, tuple(batches))


_BATCH_KEY_SET = frozenset(BATCH_KEYS)


def batch_key(params: Parameters) -> tuple:
    """What the points of one batch share (BATCH_KEYS), as a key (:func:`plan` gives a point
    that changes none of them its base config's, without computing it again)."""
    return tuple(_hashable(getattr(params, k)) for k in BATCH_KEYS)


def _hashable(value: Any) -> Any:
    return tuple(value) if isinstance(value, list) else value


def run_batch(batch: Batch) -> dict[str, np.ndarray]:
    """Integrate the points of ``batch`` together; one table row per point.

    Columns: ``point``, ``status``, ``reason``, ``failed_at_s`` and :data:`METRIC_NAMES`. The
    run loop takes the metrics while it integrates (batch.run_sets: the compiled run kernel
    in parallel where numba is available, else the same loop interpreted). A point that fails
    stops where it failed, with the run's reason (outcomes.message); its metrics cover the run
    up to then.
    """
    params = batch.params
    # run by drive, so that the run kernel's blocks of sets in lock-step (solve/lanes) share
    # theirs: a block of mixed drives computes every drive's equations and the most substeps
    order = sorted(range(len(params)), key=lambda k: params[k].drive)
    by_drive = [params[k] for k in order]
    runs = run_sets(
        by_drive, batch.duration_s, commands.for_batch(by_drive), every=batch.every,
        lift_angle_deg=batch.lift_angle_deg,
    )  # fmt: skip
    runs = runs.of_sets(np.argsort(order))  # in the batch's order again
    battery_j = runs.metrics["battery_energy_j"]
    capacity_j = np.array([p.battery_capacity_kwh * J_PER_KWH for p in params])
    with np.errstate(divide="ignore", invalid="ignore"):  # a run that drew nothing: infinitely many
        cycles = np.where(battery_j > 0.0, capacity_j / battery_j, math.inf)
    cycles[np.isnan(battery_j)] = math.nan
    if params[0].mode == "physical":  # a batch shares its mode
        first = physical.LEDGER_STATES + ledger.INTEGRALS.index(LEDGER_TERMS[0])
        spent = runs.states[:, first : first + len(LEDGER_TERMS)]
    else:
        spent = np.full((len(params), len(LEDGER_TERMS)), np.nan)
    values = np.column_stack(
        [*(runs.metrics[name] for name in streaming.NAMES), *mid_stroke_modes(params), cycles, spent]
    )
    rows: dict[str, list] = {"status": [], "reason": []}
    completed = METRIC_NAMES.index("lift_completed")
    rise = METRIC_NAMES.index("rise_deg")
    for k, reason in enumerate(runs.reasons):
        if reason is not None:
            status = "failed"
        elif not values[k, completed]:
            status = "incomplete"
            reason = f"rose {values[k, rise]:.3g} deg of the {batch.lift_angle_deg:g} deg in {batch.duration_s:g} s"
        else:
            status, reason = "ok", ""
        rows["status"].append(status)
        rows["reason"].append(reason)
    out: dict[str, np.ndarray] = {
        "point": np.array(batch.points, dtype=np.int64),
        "status": np.array(rows["status"], dtype=str),
        "reason": np.array(rows["reason"], dtype=str),
        "failed_at_s": np.asarray(runs.failed_at_s, dtype=float),
    }
    for j, name in enumerate(METRIC_NAMES):
        out[name] = values[:, j]
    return out


def load_kernel(batch: Batch) -> None:
    """Load the compiled run kernel that :func:`run_batch` calls for ``batch`` (or compile it,
    where numba's cache lacks it), by a run of one step of up to lanes.WIDTH of its sets: the
    kernel it takes for them is the batch's (accelerate.batch_runner), for the same types."""
    params = list(batch.params[: lanes.WIDTH])
    run_sets(params, params[0].time_step_s, commands.for_batch(params), every=batch.every,
             lift_angle_deg=batch.lift_angle_deg)  # fmt: skip


def invalid_rows(plan: Plan) -> dict[str, np.ndarray]:
    """Table rows of the points whose parameters were rejected (all metrics NaN)."""
    points = sorted(plan.invalid)
    out: dict[str, np.ndarray] = {
        "point": np.array(points, dtype=np.int64),
        "status": np.array(["invalid"] * len(points), dtype=str),
        "reason": np.array([plan.invalid[i] for i in points], dtype=str),
        "failed_at_s": np.full(len(points), np.nan),
    }
    for name in METRIC_NAMES:
        out[name] = np.full(len(points), np.nan)
    return out


def assemble(plan: Plan, parts: Sequence[Mapping[str, np.ndarray]]) -> dict[str, np.ndarray]:
    """The whole table, one row per point in point order: point columns, status, metrics."""
    parts = [*parts, invalid_rows(plan)]
    merged = {name: np.concatenate([np.asarray(p[name]) for p in parts]) for name in parts[0]}
    order = np.argsort(merged["point"], kind="stable")
    if not np.array_equal(merged["point"][order], np.arange(plan.size)):
        raise BoomHydraulicsError("the sweep's batches do not cover every point once; rerun without --resume")
    table: dict[str, np.ndarray] = {"point": merged["point"][order]}
    for column in plan.columns:
        values = [point[column] for point in plan.points]
        table[column] = np.array(values, dtype=str if any(isinstance(v, str) for v in values) else float)
    for name, column in merged.items():
        if name != "point":
            table[name] = column[order]
    return table
