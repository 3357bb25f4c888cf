"""Many parameter sets integrated together: the compiled run kernel, or numpy.

:func:`run_sets` runs each set through the compiled kernel (:mod:`kernel`, in parallel over
the sets), with the metrics taken while it runs and, if asked, every output stored.
:func:`simulate_batch` vectorises over the sets with numpy instead: the model and
integrator functions are the same as for one simulation, a state component is an array
with one entry per parameter set, the constants are arrays, and ``xp=numpy``; it needs no
numba and keeps every output. All sets of a batch share mode, method (euler or rk4), time
step and substeps; everything else (piston diameter, payload, bulk modulus, ...) may differ.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError
from ..model import MODELS
from ..model.parameters import Parameters
from ..model.setpoints import LINEAR
from . import accelerate, integrators, kernel, stepping, streaming
from .closed_loop import PositionLoop
from .commands import Profile
from .integrators import BATCHED
from .outputs import BOOLEAN_OUTPUTS, OUTPUT_NAMES
from .profiles import ANGLE
from .simulation import MAX_SUBSTEPS, sample_count, stability_limit
from .streaming import DEFAULT_LIFT_ANGLE_DEG, move_window

SHARED = ("mode", "method", "time_step_s", "substeps")

#: One kernel call at a time per process: it runs on all the cores itself, and where numba's
#: threading layer is its own workqueue (no OpenMP or TBB), two threads launching parallel
#: kernels at once abort the process (a Dask worker with several threads would).
_KERNEL_LOCK = threading.Lock()


def stacked_constants(params: Sequence[Parameters]):
    """The model's Constants with one array entry per parameter set."""
    model = MODELS[params[0].mode]
    per_set = [model.constants(p) for p in params]
    return type(per_set[0])(*(np.array(column, dtype=float) for column in zip(*per_set)))


def _check_shared(params: Sequence[Parameters]) -> None:
    if not params:
        raise ConfigError("a batch needs at least one parameter set")
    first = params[0]
    for name in SHARED:
        values = {getattr(p, name) for p in params}
        if len(values) > 1:
            raise ConfigError(f"all parameter sets of a batch must share {name}; got {sorted(map(str, values))}")
    if first.method not in BATCHED:
        raise ConfigError(
            f"batches integrate with an explicit fixed-step method ({' or '.join(BATCHED)}), not {first.method!r}"
        )


def simulate_batch(
    params: Sequence[Parameters],
    duration_s: float,
    command: Callable[[float], float | np.ndarray],
    every: int = 1,
    outputs: Sequence[str] = OUTPUT_NAMES,
) -> dict[str, np.ndarray]:
    """Integrate every parameter set over ``duration_s`` with the valve command ``command(t)``
    (a feedback command, see :class:`closed_loop.PositionLoop`: ``command(t, y)``).

    Returns each of ``outputs`` (names of :data:`simulation.OUTPUT_NAMES`) as an array of
    shape (samples, sets), sampled at the start and every ``every`` steps. Each time step
    takes as many substeps as each set's stability bound needs (at least ``substeps``; see
    stepping.advance), as its single run would; the most any set took since the previous
    sample is reported per sample in ``substeps``. A set whose
    state turns non-finite, whose energy balance breaks, or that needs more than
    MAX_SUBSTEPS is frozen at its last good state from then on and reported in
    ``failed_at_s`` (NaN where the set ran through) and ``failed_why`` (a stepping outcome:
    NONFINITE, ENERGY or TOO_STIFF; 0 where the set ran through).
    """
    _check_shared(params)
    unknown = sorted(set(outputs) - set(OUTPUT_NAMES))
    if unknown:
        raise ConfigError(f"unknown outputs {unknown}; choose from {', '.join(OUTPUT_NAMES)}")
    if every < 1:
        raise ConfigError(f"every must be >= 1, got {every}")
    model = MODELS[params[0].mode]
    c = stacked_constants(params)
    n_sets = len(params)
    y = [np.array(column, dtype=float) for column in zip(*(model.initial_state(p) for p in params))]
    dt, min_substeps = params[0].time_step_s, params[0].substeps
    method = integrators.METHODS[params[0].method]
    step, limit = method.step, stability_limit(params[0])
    energy_index = -1 if model.ENERGY_STATES is None else model.ENERGY_STATES[0]
    failed_at = np.full(n_sets, np.nan)
    failed_why = np.zeros(n_sets, dtype=int)
    n_steps = round(duration_s / dt)
    n_rows = sample_count(n_steps, every)
    t = 0.0
    half = 0.5 * dt  # the command of a step is taken at its middle, as in Simulator.run
    feedback = getattr(command, "feedback", False)

    def opening(at_s: float) -> np.ndarray:
        """The command at ``at_s``; a feedback command reads the state of the step's start."""
        return _as_array(command(at_s, y) if feedback else command(at_s), n_sets)

    first = model.observe(t, y, c, opening(t + half), np)
    columns = {name: np.empty((n_rows, n_sets), dtype=np.asarray(first[name]).dtype) for name in outputs}
    substeps_column = np.empty(n_rows, dtype=int)

    def record(row: int, values: dict, substeps: int) -> None:
        for name in outputs:
            columns[name][row] = values[name]
        substeps_column[row] = substeps

    record(0, first, min_substeps)
    row, most = 1, min_substeps
    base = model.energy(y, c, np) - y[energy_index] if energy_index >= 0 else 0.0
    running = np.ones(n_sets, dtype=bool)
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        for i in range(1, n_steps + 1):
            u = opening(t + half)
            substeps = np.full(n_sets, min_substeps)
            if limit > 0.0:
                needed = np.ceil(dt * model.stiffness_rate(y, c, u, dt, np) / limit)
                _fail(running & (needed > MAX_SUBSTEPS), stepping.TOO_STIFF, t, failed_at, failed_why, running)
                substeps = np.maximum(substeps, np.where(running, needed, 1).astype(int))
            most = max(most, int(substeps.max()))
            h = dt / substeps  # each set steps as its own single run would
            y_new = y
            for j in range(int(substeps.max())):
                stepped = step(model.derivative, t + j * h, y_new, h, (c, u, np))
                y_new = (
                    stepped if j < substeps.min() else [np.where(j < substeps, a, b) for a, b in zip(stepped, y_new)]
                )
            finite = np.logical_and.reduce([np.isfinite(v) for v in y_new])
            _fail(running & ~finite, stepping.NONFINITE, t + dt, failed_at, failed_why, running)
            if energy_index >= 0:
                stored, flowed, flowed_abs = model.energy(y_new, c, np), y_new[energy_index], y_new[energy_index + 1]
                broken = stepping.balance_broken(stored, flowed, flowed_abs, base) | np.isnan(stored)
                _fail(running & broken, stepping.ENERGY, t + dt, failed_at, failed_why, running)
            y = [np.where(running, new, old) for new, old in zip(y_new, y)]
            t = i * dt
            if i % every == 0 or i == n_steps:
                record(row, model.observe(t, y, c, opening(t + half), np), most)
                row += 1
                most = min_substeps
    out = dict(columns)
    out["failed_at_s"] = failed_at
    out["failed_why"] = failed_why
    out["substeps"] = substeps_column
    return out


def _fail(
    which: np.ndarray, outcome: int, t: float, failed_at: np.ndarray, failed_why: np.ndarray, running: np.ndarray
) -> None:
    """Mark the sets in ``which`` as failed at ``t`` with ``outcome`` and stop them."""
    failed_at[which] = t
    failed_why[which] = outcome
    running &= ~which


def _as_array(u: float | np.ndarray, n: int) -> np.ndarray:
    return np.broadcast_to(np.asarray(u, dtype=float), (n,))


@dataclass
class SetRuns:
    """What :func:`run_sets` gives, one entry per parameter set."""

    metrics: dict[str, np.ndarray]  # streaming.NAMES -> one value per set
    failed_at_s: np.ndarray  # NaN where the set ran through
    failed_why: np.ndarray  # stepping outcome: OK (0), NONFINITE, ENERGY or TOO_STIFF
    most_substeps: np.ndarray  # the most substeps one step took (TOO_STIFF: as many as it needed)
    last_q1_m: np.ndarray  # the cylinder length at the end, or at the last good state
    samples: np.ndarray  # how many samples each set took (fewer where it failed)
    rows: np.ndarray | None  # with store: (sets, samples, outputs), outputs in OUTPUT_NAMES order

    def columns(self, k: int) -> dict[str, np.ndarray]:
        """The stored outputs of set ``k`` (run with store), as a trajectory's columns."""
        if self.rows is None:
            raise ValueError("run_sets(store=True) keeps the outputs")
        table = self.rows[k, : self.samples[k]]
        return {
            name: table[:, j].astype(bool) if name in BOOLEAN_OUTPUTS else table[:, j].copy()
            for j, name in enumerate(OUTPUT_NAMES)
        }


def kernel_command(command: Callable, n_sets: int) -> tuple | None:
    """The run kernel's command arguments for ``command`` (a :class:`commands.Profile`, or a
    :class:`closed_loop.PositionLoop` that has not run yet), or None where the kernel cannot
    evaluate it (any other function of time)."""
    no_knots = np.zeros((n_sets, 1))
    if isinstance(command, Profile):
        times = np.array(command.times_s or (0.0,), dtype=float)
        values = np.array(command.values or (0.0,), dtype=float)
        shape = (command.kind, times, values, command.offset, command.amplitude, command.frequency_hz)
        return (*shape, no_knots, no_knots, no_knots, LINEAR, np.zeros((n_sets, 4)))
    if isinstance(command, PositionLoop) and command.fresh:
        path = command.path
        knots = [
            np.ascontiguousarray(np.broadcast_to(a, (len(a), n_sets)).T)
            for a in (path.times_s, path.angles_rad, path.rates_rad_s)
        ]
        gains = np.column_stack([np.broadcast_to(np.asarray(g, dtype=float), (n_sets,)) for g in command.gains])
        return (ANGLE, np.zeros(1), np.zeros(1), 0.0, 0.0, 0.0, *knots, path.order, gains)
    return None


#: Wall time a slice of a kernel run aims at, s: between slices the run is back in Python,
#: where Ctrl-C (KeyboardInterrupt) is seen, progress shown and rows streamed out.
SLICE_S = 0.2
#: Passes of the first slice (the kernel may compile in it), and the most a slice may grow by.
FIRST_SLICE, SLICE_GROWTH = 64, 4
#: Most floats the table of one slice's rows may hold, all sets together (64 MB).
SLICE_FLOATS = 8_000_000


def next_slice(passes: int, seconds: float, most: int) -> int:
    """The passes of the next slice after one of ``passes`` took ``seconds``: as many as take
    about SLICE_S, growing at most SLICE_GROWTH-fold, at least 1 and at most ``most``."""
    wanted = passes * SLICE_S / seconds if seconds > 0 else passes * SLICE_GROWTH
    return max(1, min(most, passes * SLICE_GROWTH, int(wanted)))


class KernelRun:
    """A batch of parameter sets in the compiled run kernel, run slice by slice (:meth:`slices`).

    The kernel keeps each set's state, controller, command and sample count in ``state`` and
    ``status`` between calls, so a run split into slices gives what one call over all its steps
    would, bit for bit; each slice takes about SLICE_S of wall time, so that Ctrl-C ends a run
    of any length within a second.
    """

    def __init__(
        self, runner: Callable[..., None], params: Sequence[Parameters], spec: tuple, duration_s: float, every: int,
        lift_angle_deg: float, store: bool, slice_rows: int | None = None,
    ) -> None:  # fmt: skip
        p0 = params[0]
        model = MODELS[p0.mode]
        self.n_sets = len(params)
        constants = [model.constants(p) for p in params]
        initial = [model.initial_state(p) for p in params]
        energy_index = -1 if model.ENERGY_STATES is None else model.ENERGY_STATES[0]
        bases = [model.energy(y, c) - y[energy_index] if energy_index >= 0 else 0.0 for y, c in zip(initial, constants)]
        self.n_steps = round(duration_s / p0.time_step_s)
        self.every = every
        self.n_rows = sample_count(self.n_steps, every)
        self.settings = np.array([streaming.settings(lift_angle_deg, *move_window(p)) for p in params])
        self.accumulators = np.array([streaming.accumulator() for _ in params])
        self.state = np.array(initial, dtype=float)  # each set's state, carried from slice to slice
        self.status = np.zeros((self.n_sets, kernel.STATUS_SIZE))
        self.taken = np.zeros(self.n_sets, dtype=np.int64)  # samples of each set in the last slice
        self.done = 0  # passes done of n_steps + 1 (pass 0: the start, pass i: step i)
        self._runner = runner
        self._head = (np.array(constants, dtype=float), self.state, *spec)
        self._middle = (
            float(p0.time_step_s), int(p0.substeps), float(stability_limit(p0)), MAX_SUBSTEPS, int(self.n_steps),
            int(every), energy_index, np.array(bases, dtype=float), self.settings, self.accumulators,
        )  # fmt: skip
        width = len(OUTPUT_NAMES)
        if slice_rows is None:
            slice_rows = SLICE_FLOATS // (self.n_sets * width)
        slice_rows = max(2, slice_rows) if store else 0
        self.most_passes = max(1, (slice_rows - 2) * every) if store else self.n_steps + 1
        self.rows = np.empty((self.n_sets, slice_rows, width))  # the rows of the last slice

    @property
    def passes(self) -> int:
        """All passes of the run: the start and each step."""
        return self.n_steps + 1

    def slices(self) -> Iterator[np.ndarray]:
        """Run to the end, one slice per step of the iteration; after each, ``rows[k, :taken[k]]``
        are the samples set ``k`` took in it (overwritten by the next slice), and the samples
        per set are returned. Stops early once every set has failed."""
        size = FIRST_SLICE
        while self.done < self.passes:
            last = min(self.passes, self.done + min(size, self.most_passes))
            started = time.perf_counter()
            with _KERNEL_LOCK:
                self._runner(*self._head, *self._middle, self.rows, self.status, self.taken, self.done, last)
            seconds = time.perf_counter() - started
            passes, self.done = last - self.done, last
            yield self.taken
            if not (self.status[:, kernel.OUTCOME] == stepping.OK).any():
                self.done = self.passes  # every set has stopped: the rest would do nothing
                return
            size = next_slice(passes, seconds, self.most_passes)

    def result(self, rows: np.ndarray | None = None) -> SetRuns:
        """What the run gave (after :meth:`slices`), with ``rows`` the table of every sample, if kept."""
        values = np.empty((self.n_sets, len(streaming.NAMES)))
        for k in range(self.n_sets):
            streaming.finish(self.accumulators[k], self.settings[k], values[k])
        status = self.status
        return SetRuns(
            metrics={name: values[:, j] for j, name in enumerate(streaming.NAMES)},
            failed_at_s=status[:, kernel.FAILED_AT].copy(),
            failed_why=status[:, kernel.OUTCOME].astype(int),
            most_substeps=status[:, kernel.MOST].astype(int),
            last_q1_m=status[:, kernel.LAST_Q1].copy(),
            samples=status[:, kernel.TAKEN].astype(np.int64),
            rows=rows,
        )


def kernel_run(
    params: Sequence[Parameters],
    duration_s: float,
    command: Callable,
    every: int = 1,
    lift_angle_deg: float = DEFAULT_LIFT_ANGLE_DEG,
    store: bool = False,
    slice_rows: int | None = None,
) -> KernelRun | None:
    """The sets prepared for the compiled kernel (see :func:`run_sets`), or None where numba
    is not available (or switched off) or the kernel cannot evaluate ``command``. With
    ``store``, a slice takes at most ``slice_rows`` samples per set (default: SLICE_FLOATS in all)."""
    _check_shared(params)
    if every < 1:
        raise ConfigError(f"every must be >= 1, got {every}")
    p0 = params[0]
    runner = accelerate.batch_runner(p0.mode, p0.method)
    spec = kernel_command(command, len(params))
    if runner is None or spec is None:
        return None
    return KernelRun(runner, params, spec, duration_s, every, lift_angle_deg, store, slice_rows)


def run_sets(
    params: Sequence[Parameters],
    duration_s: float,
    command: Callable,
    every: int = 1,
    lift_angle_deg: float = DEFAULT_LIFT_ANGLE_DEG,
    store: bool = False,
) -> SetRuns | None:
    """Run every parameter set through the compiled kernel: the metrics of
    :mod:`streaming` (over the samples at the start, every ``every`` steps and at the end),
    and with ``store`` every output at those samples. None where numba is not available
    (or switched off) or the kernel cannot evaluate ``command`` (see :func:`kernel_command`):
    then :func:`simulate_batch` does the work.

    Each set runs as its single run would (:meth:`simulation.Simulator.run`, the same steps
    and substeps, commands and samples); a set that fails stops where it failed. The kernel
    runs in slices of about SLICE_S (:class:`KernelRun`): Ctrl-C stops it within a second.
    """
    run = kernel_run(params, duration_s, command, every, lift_angle_deg, store)
    if run is None:
        return None
    table = None
    if store:
        table = np.empty((run.n_sets, run.n_rows, len(OUTPUT_NAMES)))
        filled = np.zeros(run.n_sets, dtype=np.int64)
    for taken in run.slices():
        if table is not None:
            for k in range(run.n_sets):
                table[k, filled[k] : filled[k] + taken[k]] = run.rows[k, : taken[k]]
            filled += taken
    return run.result(table)
