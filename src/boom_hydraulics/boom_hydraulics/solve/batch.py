"""Parameter sets through the one run loop (:func:`kernel.run_set`), slice by slice.

:class:`SetRun` runs one parameter set (the Simulator's whole runs, :func:`simulation.simulate`,
:class:`simulation.RunStream`) or many together (:func:`run_sets`: the batch and the sweep),
with the metrics taken while it runs and, if asked, every output stored. What is plugged into
the loop depends on what can be compiled; the steps, commands and samples are the same:

- compiled: the model's parallel run kernel (:func:`kernel.batch_set` over the sets, in
  ``prange``; with ``serial``, one set's in the calling thread) where numba is available, the
  method is explicit (euler, rk4) and the command describes itself to the kernel
  (``command.kernel_command(n_sets)``: a profile, a position loop);
- stepped: the loop interpreted, each step through the model's compiled stepping (the
  Simulator's compiled step), for any other command (a Python function of time) or ros2;
- interpreted: the loop and every function uncompiled (no numba, ``jit=False``, rk45).

Compiled and interpreted runs agree to the last bits of the math library (1e-9 relative over
thousands of steps); a compiled run gives the same bits whichever of the first two runs it.
All sets of a batch share mode, method, time step and substeps; everything else (piston
diameter, payload, bulk modulus, ...) may differ.
"""

from __future__ import annotations

import contextlib
import math
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import ConfigError, SimulationError
from ..model import MODELS
from ..model.parameters import Parameters
from ..programs import raise_pending
from . import accelerate, integrators, kernel, streaming
from .integrators import BATCHED
from .kernel import Command, RunSpec
from .outcomes import MAX_SUBSTEPS, NONFINITE, OK, evaluation_message, message
from .outputs import BOOLEAN_OUTPUTS, OUTPUT_NAMES
from .profiles import ANGLE
from .stepping import loop_of
from .streaming import DEFAULT_LIFT_ANGLE_DEG, cycle_targets, move_window

SHARED = ("mode", "method", "time_step_s", "substeps")

#: One kernel call at a time per process: it runs on all the cores itself, and where numba's
#: threading layer is its own workqueue (no OpenMP or TBB), two threads launching parallel
#: kernels at once abort the process (a Dask worker with several threads would).
_KERNEL_LOCK = threading.Lock()

#: Wall time a slice of a run aims at, s: between slices the run is back in Python, where
#: Ctrl-C (KeyboardInterrupt) is seen, progress shown and rows streamed out.
SLICE_S = 0.2
#: Passes of the first slice (the kernel may compile in it), and the most a slice may grow by.
FIRST_SLICE, SLICE_GROWTH = 64, 4
#: Most floats the table of one slice's rows may hold, all sets together (64 MB).
SLICE_FLOATS = 8_000_000

#: What an interpreted model function may raise where compiled code gives NaN (math.acos
#: outside its domain, a singular ros2 matrix) ...
MODEL_ERRORS = (ValueError, ZeroDivisionError, OverflowError)
#: ... and what else a step or a Python command may raise (rk45's step control, a non-finite command).
EVALUATION_ERRORS = (SimulationError, *MODEL_ERRORS)

#: The command of a run whose command is a Python function (kind ANGLE: the loop asks its
#: controller, which is then that function).
CALLED = Command(ANGLE, (), (), 0.0, 0.0, 0.0, (), (), (), 0, ())


def payload_schedule(p: Parameters) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """(times s, shares) of the payload schedule the run loop takes: none where the whole
    payload hangs on the hook throughout (the loop then checks nothing per step)."""
    if all(share == 1.0 for share in p.command_payload_fractions):
        return (), ()
    return tuple(p.command_payload_times_s), tuple(p.command_payload_fractions)


def stability_limit(p: Parameters) -> float:
    """The limit on dt x rate of the parameters' method where their model asks for stability
    substeps (see stepping.advance), else 0 (no automatic substeps)."""
    return (integrators.METHODS[p.method].stability_limit or 0.0) if MODELS[p.mode].STABILITY_BOUND else 0.0


def sample_count(n_steps: int, every: int) -> int:
    """Samples of a run of ``n_steps``: at the start, after every ``every`` steps and at the end."""
    return 1 + n_steps // every + (1 if n_steps % every else 0)


def check_batch(params: Sequence[Parameters]) -> None:
    """ConfigError unless ``params`` can run as one batch: at least one set, the SHARED
    parameters alike, an explicit fixed-step method."""
    if not params:
        raise ConfigError("a batch needs at least one parameter set")
    first = params[0]
    for name in SHARED:
        values = {getattr(p, name) for p in params}
        if len(values) > 1:
            raise ConfigError(f"all parameter sets of a batch must share {name}; got {sorted(map(str, values))}")
    if len({payload_schedule(p) for p in params}) > 1:
        raise ConfigError("all parameter sets of a batch must share their payload schedule (command_payload_*)")
    if first.method not in BATCHED:
        raise ConfigError(
            f"batches integrate with an explicit fixed-step method ({' or '.join(BATCHED)}), not {first.method!r}"
        )


@dataclass(frozen=True)
class Start:
    """Where a run of one set goes on from: a Simulator's state, time line and energy balance."""

    state: Sequence[float]
    t0_s: float  # the time line: step i of the run ends at t0_s + (k0 + i) dt, s
    k0: int
    energy_base_j: float  # the value of H - W that the balance keeps, J
    integrator: integrators.Integrator | None = None  # rk45's, which keeps its step size between calls


class Guard:
    """What an interpreted set's run raised first (see EVALUATION_ERRORS): the step or the
    command that raised is taken as non-finite, which ends the run there as compiled code
    ends it, and the error is kept for the message."""

    def __init__(self) -> None:
        self.error: Exception | None = None

    def keep(self, error: Exception) -> None:
        if self.error is None:
            self.error = error

    def stepping(self, step_once: Callable[..., tuple]) -> Callable[..., tuple]:
        """``step_once`` (stepping.advance's arguments and results), guarded."""

        def guarded(
            step: Any, derivative: Any, stiffness_rate: Any, energy: Any, t0: float, y: list, c: Any, u: float,
            dt: float, min_substeps: int, *rest: Any,
        ) -> tuple:  # fmt: skip
            try:
                return step_once(step, derivative, stiffness_rate, energy, t0, y, c, u, dt, min_substeps, *rest)
            except EVALUATION_ERRORS as exc:
                self.keep(exc)
                return 0, NONFINITE, min_substeps, y  # no step taken

        return guarded

    def command(self, command: Callable, k: int) -> Callable[..., float]:
        """A Python command (``command(t)``, or ``command(t, y)`` where it has ``feedback``) as
        the loop's controller of set ``k`` (a batch's command may give one value per set)."""
        feedback = getattr(command, "feedback", False)

        def controller(
            _: Command, __: int, running: Any, status: Any, c: Any, y: Any, last_u: float, dt_s: float, t_s: float
        ) -> float:
            try:
                value = command(t_s, y) if feedback else command(t_s)
                u = float(value if np.ndim(value) == 0 else np.asarray(value)[k])
                if not math.isfinite(u):
                    raise SimulationError(f"valve command must be finite, got {value!r}")
            except EVALUATION_ERRORS as exc:
                self.keep(exc)
                return math.nan
            return u

        return controller


def compiled_stepping(stepper: Callable[..., tuple]) -> Callable[..., tuple]:
    """stepping.advance through the model's compiled stepping ``stepper`` (accelerate.stepper)
    with the constants the loop steps with as a row (one per payload share the schedule puts
    on the hook): the Simulator's compiled step, under an interpreted loop."""
    rows: dict[Any, np.ndarray] = {}

    def step_once(
        step: Any, derivative: Any, stiffness_rate: Any, energy: Any, t0: float, y: list, c: Any, *rest: Any
    ) -> tuple:
        row = rows.get(c)
        if row is None:
            row = rows[c] = np.array(c, dtype=float)
        done, outcome, most, y_new = stepper(t0, np.array(y), row, *rest)
        return done, outcome, most, y_new.tolist()

    return step_once


def interpreted(command: Command) -> Command:
    """``command`` with Python floats and lists for numpy arrays (an interpreted loop computes
    in floats, as the model functions expect)."""
    return Command(
        int(command.kind), tuple(np.asarray(command.times_s, float).tolist()),
        tuple(np.asarray(command.values, float).tolist()), float(command.offset), float(command.amplitude),
        float(command.frequency_hz), np.asarray(command.knot_times_s, float).tolist(),
        np.asarray(command.knot_angles_rad, float).tolist(), np.asarray(command.knot_rates_rad_s, float).tolist(),
        int(command.order), np.asarray(command.gains, float).tolist(),
    )  # fmt: skip


def python_sets(
    params: Sequence[Parameters], command: Callable, encoded: bool, stepper: Callable[..., tuple] | None,
    start: Start | None,
) -> list[tuple[Guard, tuple, Any]]:  # fmt: skip
    """What each set runs the loop with in Python: its guard, the loop's functions (its
    stepping: ``stepper``, compiled, or stepping.advance; the method's step, the model's
    functions; the controller: the kernel's for an ``encoded`` command, else ``command``
    itself) and the model's constants."""
    p0 = params[0]
    model = MODELS[p0.mode]
    step = integrators.METHODS[p0.method].step
    if step is None:  # rk45: one adaptive advance per step, by the integrator the run goes on with
        integrator = start.integrator if start is not None else None
        if integrator is None:
            raise ConfigError("an rk45 run goes on from a Simulator's state (its integrator)")
        step = lambda fun, t, y, h, args: integrator.advance(fun, t, y, h, args)  # noqa: E731
    sets = []
    for k, p in enumerate(params):
        guard = Guard()
        c = model.constants(p)
        step_once = loop_of(p0.method) if stepper is None else compiled_stepping(stepper)
        controller = kernel.controller_value if encoded else guard.command(command, k)
        functions = (guard.stepping(step_once), step, model.derivative, model.stiffness_rate, model.energy,
                     model.outputs, model.samples, controller, model.with_payload)  # fmt: skip
        sets.append((guard, functions, c))
    return sets


@dataclass
class SetRuns:
    """What :func:`run_sets` gives, one entry per parameter set."""

    metrics: dict[str, np.ndarray]  # streaming.NAMES -> one value per set
    failed_at_s: np.ndarray  # NaN where the set ran through
    failed_why: np.ndarray  # outcome: OK (0) or a failure (outcomes: NONFINITE, ENERGY, TOO_STIFF, OUT_OF_GEOMETRY)
    most_substeps: np.ndarray  # the most substeps one step took (TOO_STIFF: as many as it needed)
    states: np.ndarray  # the state at the end, or the last good state (sets x state)
    samples: np.ndarray  # how many samples each set took (fewer where it failed)
    reasons: list[str | None]  # why each set stopped early (outcomes.message), None where it ran through
    rows: np.ndarray | None  # with store: (sets, samples, outputs), outputs in OUTPUT_NAMES order

    @property
    def last_q1_m(self) -> np.ndarray:
        """The cylinder length at the end, or at the last good state, m."""
        return self.states[:, 0]

    def of_sets(self, order: Sequence[int] | np.ndarray) -> SetRuns:
        """These runs of sets ``order`` (indices), in that order."""
        order = np.asarray(order, dtype=np.int64)
        return SetRuns(
            metrics={name: values[order] for name, values in self.metrics.items()},
            failed_at_s=self.failed_at_s[order],
            failed_why=self.failed_why[order],
            most_substeps=self.most_substeps[order],
            states=self.states[order],
            samples=self.samples[order],
            reasons=[self.reasons[k] for k in order],
            rows=None if self.rows is None else self.rows[order],
        )

    def columns(self, k: int) -> dict[str, np.ndarray]:
        """The stored outputs of set ``k`` (run with store), as a trajectory's columns."""
        if self.rows is None:
            raise ValueError("run_sets(store=True) keeps the outputs")
        return columns_of(self.rows[k, : self.samples[k]])


def columns_of(table: np.ndarray) -> dict[str, np.ndarray]:
    """Rows of outputs (OUTPUT_NAMES order, flags 1.0 or 0.0) as columns, flags as booleans."""
    return {
        name: table[:, j] != 0.0 if name in BOOLEAN_OUTPUTS else table[:, j].copy()
        for j, name in enumerate(OUTPUT_NAMES)
    }


def next_slice(passes: int, seconds: float, most: int) -> int:
    """The passes of the next slice after one of ``passes`` took ``seconds``: as many as take
    about SLICE_S, growing at most SLICE_GROWTH-fold, at least 1 and at most ``most``."""
    wanted = passes * SLICE_S / seconds if seconds > 0 else passes * SLICE_GROWTH
    return max(1, min(most, passes * SLICE_GROWTH, int(wanted)))


class SetRun:
    """Parameter sets through the run loop, slice by slice (:meth:`slices`).

    The loop keeps each set's state, controller, command and sample count in ``state`` and
    ``status`` between calls, so a run split into slices gives what one call over all its steps
    would, bit for bit; each slice takes about SLICE_S of wall time, so that Ctrl-C ends a run
    of any length within a second. ``command`` is any valve command (see the module); the sets
    run from rest unless ``start`` says where one set goes on from. With ``store``, a slice
    takes at most ``slice_rows`` samples per set (default: the whole run's, at most SLICE_FLOATS
    in all); ``measure``: whether the streaming metrics are taken (over ``lift_angle_deg``);
    ``jit``: as for the Simulator (None: compiled where numba is available). Compiled, the sets
    run on every core (the parallel kernel) unless ``serial`` asks for the one set's kernel in
    the calling thread: a run gone on a few steps at a time (:meth:`go_on`), where the parallel
    runtime's threads would spin between calls (OpenMP's took three quarters of a core from a
    node that followed a path). ``payload``: the payload schedule (times s, shares on the
    hook; see kernel.payload_share), None: the parameters' (:func:`payload_schedule`).
    ``lock_step``: compiled, from lanes.WIDTH sets on, the sets run in blocks in lock-step on
    the vector units (accelerate.batch_runner; the same results, see :mod:`lanes`); False: one set per
    thread (the benchmark's reference).
    """

    def __init__(
        self, params: Sequence[Parameters], duration_s: float, command: Callable, every: int = 1, *,
        lift_angle_deg: float = DEFAULT_LIFT_ANGLE_DEG, store: bool = False, slice_rows: int | None = None,
        measure: bool = True, jit: bool | None = None, start: Start | None = None, serial: bool = False,
        payload: tuple[tuple[float, ...], tuple[float, ...]] | None = None, lock_step: bool = True,
    ) -> None:  # fmt: skip
        p0 = params[0]
        model = MODELS[p0.mode]
        self.params = tuple(params)
        self.n_sets = len(params)
        self.n_steps = max(0, round(duration_s / p0.time_step_s))
        self.every = every
        self.n_rows = sample_count(self.n_steps, every)
        constants = [model.constants(p) for p in params]
        energy_index = -1 if model.ENERGY_STATES is None else model.ENERGY_STATES[0]
        if start is None:
            initial = [model.initial_state(p) for p in params]
            bases = [model.energy(y, c) - y[energy_index] if energy_index >= 0 else 0.0
                     for y, c in zip(initial, constants)]  # fmt: skip
            t0_s, k0 = 0.0, 0
        else:
            initial, bases, t0_s, k0 = [list(start.state)], [start.energy_base_j], start.t0_s, start.k0
        self.state = np.array(initial, dtype=float)  # each set's state, carried from slice to slice
        self.status = np.zeros((self.n_sets, kernel.STATUS_SIZE))
        self.metrics = np.array([streaming.accumulator() for _ in params])
        self.taken = np.zeros(self.n_sets, dtype=np.int64)  # samples of each set in the last slice
        self.done = 0  # passes done of n_steps + 1 (pass 0: the start, pass i: step i)
        self.errors: list[Exception | None] = [None] * self.n_sets  # interpreted: what a set's run raised
        encode = getattr(command, "kernel_command", None)
        encoding = encode(self.n_sets) if encode is not None else None
        if encoding is None and self.n_sets > 1 and getattr(command, "feedback", False):
            raise ConfigError("a feedback command that has run already drives one parameter set; give each set its own")
        compiled = accelerate.available() if jit is None else jit and accelerate.available()
        adaptive = integrators.METHODS[p0.method].step is None  # rk45: one advance per step
        settings = np.array([streaming.settings(lift_angle_deg, *move_window(p), cycle_targets(p)) for p in params])
        schedule = payload_schedule(p0) if payload is None else payload
        spec = RunSpec(
            np.array(constants, dtype=float), encoding or CALLED, float(p0.time_step_s),
            1 if adaptive else int(p0.substeps), float(stability_limit(p0)), MAX_SUBSTEPS, int(self.n_steps),
            int(every), energy_index, np.array(bases, dtype=float), settings, bool(measure), float(t0_s), int(k0),
            *(np.array(v, dtype=float) for v in schedule),
        )  # fmt: skip
        elements = accelerate.with_elements(params)  # the kernels' layout of the state
        if serial and self.n_sets != 1:
            raise ValueError("a serial run has one parameter set")
        if not compiled or encoding is None:
            self._runner = None
        elif serial:
            self._runner = accelerate.set_runner(p0.mode, p0.method, elements)
        else:
            self._runner = accelerate.batch_runner(p0.mode, p0.method, self.n_sets if lock_step else 1, elements)
        self._parallel = self._runner is not None and not serial
        if self._runner is not None:
            self._spec, self._flat = spec, kernel.flat(spec)
        else:  # the loop in Python: each set with its own functions
            self._spec = spec._replace(
                command=CALLED if encoding is None else interpreted(encoding), energy_base=[float(b) for b in bases],
                payload_times_s=schedule[0], payload_shares=schedule[1],
            )  # fmt: skip
            stepper = accelerate.stepper(p0.mode, p0.method, elements) if compiled else None
            self._sets = python_sets(params, command, encoding is not None, stepper, start)
        width = len(OUTPUT_NAMES)
        if slice_rows is None:
            slice_rows = min(SLICE_FLOATS // (self.n_sets * width), self.n_rows)
        slice_rows = max(2, slice_rows) if store else 0
        # P passes take at most ceil(P / every) samples at multiples of every, and the last one
        self.most_passes = (slice_rows - 1) * every if store else self.n_steps + 1
        self.rows = np.empty((self.n_sets, slice_rows, width))  # the rows of the last slice

    @property
    def compiled(self) -> bool:
        """True when the sets run in the compiled run kernel."""
        return self._runner is not None

    @property
    def passes(self) -> int:
        """All passes of the run: the start and each step."""
        return self.n_steps + 1

    def _slice(self, first: int, last: int) -> None:
        if self._runner is not None:
            with _KERNEL_LOCK if self._parallel else contextlib.nullcontext():
                if self._parallel:
                    raise_pending()  # (a batch that waited for the kernel while its sweep stopped: no slice more)
                self._runner(self.state, self.status, self.metrics, self.rows, self.taken, first, last, *self._flat)
            return
        store = self.rows.shape[1] > 0
        for k, (guard, functions, c) in enumerate(self._sets):
            y = self.state[k].tolist()
            one = slice(k, k + 1)
            kernel.run_set(
                *functions, store, c, y, self._spec, k, self.state[one], self.status[one], self.metrics[one],
                self.rows[one], self.taken[one], first, last,
            )  # fmt: skip
            self.errors[k] = guard.error

    def slices(self) -> Iterator[np.ndarray]:
        """Run to the end, one slice per step of the iteration; after each, ``rows[k, :taken[k]]``
        are the samples set ``k`` took in it (overwritten by the next slice), and the samples
        per set are returned. Stops early once every set has failed."""
        size = FIRST_SLICE
        while self.done < self.passes:
            last = min(self.passes, self.done + min(size, self.most_passes))
            started = time.perf_counter()
            self._slice(self.done, last)
            raise_pending()  # a Ctrl-C whose KeyboardInterrupt a finalizer swallowed stops it here
            seconds = time.perf_counter() - started
            passes, self.done = last - self.done, last
            yield self.taken
            if not (self.status[:, kernel.OUTCOME] == OK).any():
                self.done = self.passes  # every set has stopped: the rest would do nothing
                return
            size = next_slice(passes, seconds, self.most_passes)

    def go_on(self, steps: int) -> None:
        """``steps`` more steps in one slice, fewer where the run ends (the first call takes the
        start, pass 0, too): a run that its caller paces, as the node's ticks pace the position
        controller's."""
        last = min(self.passes, self.done + steps + (1 if self.done == 0 else 0))
        self._slice(self.done, last)
        self.done = last

    def result(self, rows: np.ndarray | None = None) -> SetRuns:
        """What the run gave (after :meth:`slices`), with ``rows`` the table of every sample, if kept."""
        values = np.empty((self.n_sets, len(streaming.NAMES)))
        for k in range(self.n_sets):
            streaming.finish(self.metrics[k], self._spec.settings[k], values[k])
        status = self.status
        return SetRuns(
            metrics={name: values[:, j] for j, name in enumerate(streaming.NAMES)},
            failed_at_s=status[:, kernel.FAILED_AT].copy(),
            failed_why=status[:, kernel.OUTCOME].astype(int),
            most_substeps=status[:, kernel.MOST].astype(int),
            states=self.state.copy(),
            samples=status[:, kernel.TAKEN].astype(np.int64),
            reasons=[self.reason(k) for k in range(self.n_sets)],
            rows=rows,
        )

    def energy_base(self, k: int) -> float:
        """The value of H - W that set ``k``'s energy balance started from, J (see Start)."""
        return float(self._spec.energy_base[k])

    def steps_taken(self, k: int) -> int:
        """The steps set ``k`` took so far (all of them at the end, or those before the one that failed)."""
        status = self.status[k]
        return max(0, self.done - 1) if status[kernel.OUTCOME] == OK else int(status[kernel.FAILED_STEP])

    def holding(self, k: int) -> bool:
        """Whether set ``k``'s position controller holds its target within its dead-band now."""
        return bool(self.status[k, kernel.HOLDING] == 1.0)

    def time_after(self, steps: int) -> float:
        """The time on the run's time line after ``steps`` of its steps, s (as the Simulator keeps it)."""
        return self._spec.t0_s + (self._spec.k0 + steps) * self._spec.dt_s

    def reason(self, k: int) -> str | None:
        """Why set ``k`` stopped early, in the words of :mod:`outcomes` (what an interpreted run
        raised, where it did), from its last good state; None where it ran through."""
        status = self.status[k]
        outcome = int(status[kernel.OUTCOME])
        if outcome == OK:
            return None
        p, y, error = self.params[k], self.state[k].tolist(), self.errors[k]
        t_s = self.time_after(self.steps_taken(k))
        if isinstance(error, SimulationError):
            return str(error)
        if error is not None:
            return evaluation_message(p, t_s, y, error)
        return message(p, outcome, t_s, y, int(status[kernel.MOST]))

    def table(self) -> SetRuns:
        """Run to the end (:meth:`slices`), keeping every sample when run with store."""
        table = np.empty((self.n_sets, self.n_rows, self.rows.shape[2])) if self.rows.shape[1] > 0 else None
        filled = np.zeros(self.n_sets, dtype=np.int64)
        for taken in self.slices():
            if table is not None:
                for k in range(self.n_sets):
                    table[k, filled[k] : filled[k] + taken[k]] = self.rows[k, : taken[k]]
                filled += taken
        return self.result(table)


def run_sets(
    params: Sequence[Parameters],
    duration_s: float,
    command: Callable,
    every: int = 1,
    lift_angle_deg: float = DEFAULT_LIFT_ANGLE_DEG,
    store: bool = False,
    jit: bool | None = None,
    lock_step: bool = True,
) -> SetRuns:
    """Run every parameter set through the run loop (compiled in parallel where it can be, see
    the module): the metrics of :mod:`streaming` (over the samples at the start, every
    ``every`` steps and at the end), and with ``store`` every output at those samples.

    Each set runs as its single run would (:meth:`simulation.Simulator.run`: the same steps and
    substeps, commands and samples); a set that fails stops where it failed. A run in the
    compiled kernel goes in slices of about SLICE_S (:class:`SetRun`): Ctrl-C stops it within a
    second. ``lock_step``: see :class:`SetRun`.
    """
    check_batch(params)
    if every < 1:
        raise ConfigError(f"every must be >= 1, got {every}")
    run = SetRun(params, duration_s, command, every, lift_angle_deg=lift_angle_deg, store=store, jit=jit,
                 lock_step=lock_step)  # fmt: skip
    return run.table()
