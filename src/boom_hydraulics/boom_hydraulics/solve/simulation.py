"""Stepping one boom drive through time: the driver shared by the node, the CLI and tests.

:class:`Simulator` owns the state, the simulated time and the integrator, and applies a
valve command held constant over each step (zero-order hold). Physics lives in the
model modules (:mod:`physical`, :mod:`paper`); this module only drives them.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError, SimulationError
from ..model import MODELS
from ..model.geometry import within_triangle
from ..model.parameters import Parameters
from . import accelerate, integrators, stepping
from .outputs import BOOLEAN_OUTPUTS, OUTPUT_NAMES, OUTPUTS  # noqa: F401 (OUTPUTS: the table of them)

_SCALES = {"length": 1.0, "velocity": 1.0, "unit": 1.0, "energy": 1.0e3}

#: Most substeps the stability bound may ask for in one time step before a run stops.
MAX_SUBSTEPS = 10_000
#: Rows of one chunk of a streamed run (RunStream, Simulator.samples): a few MB as CSV text.
CHUNK_ROWS = 8192


def stability_limit(p: Parameters) -> float:
    """The limit on dt x rate of the parameters' method where their model asks for stability
    substeps (see stepping.advance), else 0 (no automatic substeps)."""
    return (integrators.METHODS[p.method].stability_limit or 0.0) if MODELS[p.mode].STABILITY_BOUND else 0.0


def sample_count(n_steps: int, every: int) -> int:
    """Samples of a run of ``n_steps``: at the start, after every ``every`` steps and at the end."""
    return 1 + n_steps // every + (1 if n_steps % every else 0)


def available_memory() -> int | None:
    """Bytes of memory a process may still take (MemAvailable, within the cgroup's limit), or None."""
    sizes = []
    try:
        with open("/proc/meminfo", encoding="ascii") as handle:
            sizes += [int(line.split()[1]) * 1024 for line in handle if line.startswith("MemAvailable:")]
    except (OSError, ValueError, IndexError):
        pass
    try:
        with (
            open("/sys/fs/cgroup/memory.max", encoding="ascii") as limit,
            open("/sys/fs/cgroup/memory.current", encoding="ascii") as used,
        ):
            text = limit.read().strip()
            if text != "max":
                sizes.append(int(text) - int(used.read().strip()))
    except (OSError, ValueError):
        pass
    return min(sizes) if sizes else None


def size_text(n_bytes: float) -> str:
    """``n_bytes`` for people: 1.5 GiB, 182 TiB."""
    for unit in ("B", "KiB", "MiB", "GiB", "TiB", "PiB"):
        if n_bytes < 1024 or unit == "PiB":
            return f"{n_bytes:.3g} {unit}"
        n_bytes /= 1024
    raise AssertionError("unreachable")


def check_fits(n_floats: float, what: str, advice: str) -> None:
    """ConfigError, up front, where a table of ``n_floats`` float64 does not fit in the memory
    available: the user learns the size at once instead of meeting the OOM killer later."""
    available = available_memory()
    needed = 8.0 * n_floats
    if available is not None and needed > available:
        raise ConfigError(
            f"{what} needs {size_text(needed)} of memory, more than the {size_text(available)} available; {advice}"
        )


def absolute_tolerances(p: Parameters) -> list[float]:
    """rk45 absolute tolerance per state: atol_scale times the state's natural scale."""
    model = MODELS[p.mode]
    scale = dict(_SCALES, pressure=p.supply_pressure_pa)
    return [p.atol_scale * scale[kind] for kind in model.STATE_SCALES]


def make_integrator(p: Parameters) -> integrators.Integrator:
    """The integrator the parameters ask for."""
    return integrators.make(p.method, p.substeps, p.rtol, absolute_tolerances(p))


@dataclass
class Trajectory:
    """Outputs sampled over a run: one numpy array per name in :data:`OUTPUT_NAMES`."""

    columns: dict[str, np.ndarray]
    stopped: str | None = None  # why the run ended early (run(stop_on_error=True)), else None
    most_substeps: int = 1  # the most substeps one time step took (the stability bound's doing)

    def __getitem__(self, name: str) -> np.ndarray:
        return self.columns[name]

    def __len__(self) -> int:
        return len(self.columns["t"])


class Simulator:
    """One boom drive: state, simulated time and integrator for a parameter set.

    Fixed-step methods split each time step into as many substeps as the model's stability
    bound needs (at least ``substeps``): ``most_substeps`` tells the most used since the
    last reset. Every step checks the energy balance (physical mode). Steps run through the
    numba-compiled model where numba is available (compiled once and cached on disk, see
    accelerate; about 20 times faster per step), unless ``jit=False``; ``jit=True`` asks for
    it, ``jit=None`` (the default) takes it where available. Both give the same trajectory.
    """

    def __init__(self, params: Parameters, jit: bool | None = None):
        self.jit = accelerate.available() if jit is None else jit
        self.stopped: str | None = None  # why the last run(stop_on_error=True) ended early
        self._install(params)
        self.reset()

    @property
    def compiled(self) -> bool:
        """True when steps run through the numba-compiled model."""
        return self._compiled is not None

    def _install(self, params: Parameters) -> None:
        self.params = params
        self.model = MODELS[params.mode]
        self.constants = self.model.constants(params)
        self.integrator = make_integrator(params)
        self._method = integrators.METHODS[params.method]
        self._limit = stability_limit(params)
        if self._method.step is not None:
            model = self.model
            self._run = functools.partial(
                stepping.advance, self._method.step, model.derivative, model.stiffness_rate, model.energy
            )  # the compiled kernels' loop, interpreted
        self._compiled = accelerate.stepper(params.mode, params.method) if self.jit else None
        self._observe = accelerate.observer(params.mode, params.method) if self._compiled is not None else None
        self._constants_row = np.array(self.constants, dtype=float)  # what the compiled calls take

    # --- state --------------------------------------------------------------------------
    def reset(self, initial_length_m: float | None = None, keep_time: bool = False) -> None:
        """Back to rest at ``initial_length_m`` (default q1(0)), valve closed; t = 0 unless
        ``keep_time`` (a clock that others follow never runs backwards)."""
        p = self.params
        if initial_length_m is not None:
            low, high = (
                (p.cylinder_min_length_m, p.cylinder_max_length_m)
                if p.mode == "physical"
                else (abs(p.b_m - p.a_m), p.a_m + p.b_m)
            )
            if not (low <= initial_length_m <= high) or not math.isfinite(initial_length_m):
                raise SimulationError(
                    f"reset position {initial_length_m} m lies outside the stroke [{low:.4g}, {high:.4g}] m"
                )
        self.y = self.model.initial_state(p, initial_length_m)
        self.t = self.t if keep_time and hasattr(self, "t") else 0.0
        self.u = 0.0
        self.step_count = 0
        self.most_substeps = p.substeps
        self._t_base, self._n_base = self.t, 0  # t = t_base + (step_count - n_base) dt, no drift
        self.integrator = make_integrator(p)
        self._energy_base = 0.0
        self._energy_base = self.energy_residual()  # H - W at rest: the balance starts at zero

    @property
    def _energy_index(self) -> int:
        return -1 if self.model.ENERGY_STATES is None else self.model.ENERGY_STATES[0]

    def energy_residual(self) -> float:
        """How far the stored energy's change is from what flowed in and out since reset, J."""
        if self._energy_index < 0:
            return 0.0
        return self.model.energy(self.y, self.constants) - self.y[self._energy_index] - self._energy_base

    def set_parameters(self, params: Parameters) -> None:
        """Use ``params`` from the next step on, keeping the state (e.g. a new payload).

        A change of ``mode`` changes the state vector, so it resets the simulation.
        """
        mode_changed = params.mode != self.params.mode
        residual = self.energy_residual()
        self._install(params)
        if mode_changed:
            self.reset(keep_time=True)
        else:
            self._t_base, self._n_base = self.t, self.step_count
            # H changes with the payload, W does not: the balance carries on from where it was
            self._energy_base += self.energy_residual() - residual

    def set_payload_mass(self, payload_mass_kg: float) -> None:
        """Change the payload between steps (validated like any parameter)."""
        from ..model.parameters import with_updates

        self.set_parameters(with_updates(self.params, payload_mass_kg=payload_mass_kg))

    # --- stepping -------------------------------------------------------------------------
    def step(self, u: float, steps: int = 1) -> None:
        """Advance ``steps`` time steps with the valve command ``u`` held constant."""
        if not math.isfinite(u):
            raise SimulationError(f"valve command must be finite, got {u!r}")
        if self._method.step is None:
            self._step_adaptive(u, steps)
            return
        p = self.params
        rest = (float(u), p.time_step_s, p.substeps, self._limit, MAX_SUBSTEPS, steps)
        rest += (self._energy_index, self._energy_base)
        if self._compiled is not None:
            done, outcome, most, y = self._compiled(self.t, np.array(self.y), self._constants_row, *rest)
            y = y.tolist()
        else:
            try:
                done, outcome, most, y = self._run(self.t, self.y, self.constants, *rest)
            except (ValueError, ZeroDivisionError, OverflowError, np.linalg.LinAlgError) as exc:
                raise self._evaluation_error(exc) from None
        self.y = y
        self.step_count += int(done)
        self.t = self._t_base + (self.step_count - self._n_base) * p.time_step_s
        self.u = u
        if outcome == stepping.TOO_STIFF:
            raise self._too_stiff_error(int(most))
        self.most_substeps = max(self.most_substeps, int(most))
        if outcome == stepping.NONFINITE:
            raise self._nonfinite_error("the next step")
        if outcome == stepping.ENERGY:
            raise self._energy_error()
        self._check(self.y)

    def _step_adaptive(self, u: float, steps: int) -> None:
        derivative, dt, args = self.model.derivative, self.params.time_step_s, (self.constants, u)
        for _ in range(steps):
            try:
                y = self.integrator.advance(derivative, self.t, self.y, dt, args)
            except (ValueError, ZeroDivisionError, OverflowError) as exc:
                raise self._evaluation_error(exc) from None
            if not all(math.isfinite(v) for v in y):
                raise self._nonfinite_error(self._describe(y))
            self.y = y
            self.step_count += 1
            self.t = self._t_base + (self.step_count - self._n_base) * dt
            self._check(y)
            index = self._energy_index  # (the fixed-step loop checks this itself)
            if index >= 0 and stepping.balance_broken(
                self.model.energy(y, self.constants), y[index], y[index + 1], self._energy_base
            ):
                raise self._energy_error()
        self.u = u

    def _check(self, y: list) -> None:
        p = self.params
        q1 = y[0]
        if not within_triangle(q1, p.a_m, p.b_m):
            raise SimulationError(
                f"rod left the valid geometry at t = {self.t:.6g} s: q1 = {q1:.6g} m is outside "
                f"({abs(p.b_m - p.a_m):.4g}, {p.a_m + p.b_m:.4g}) m where the triangle of eq. 1 "
                f"degenerates; {self._likely_cause()}"
            )

    def _evaluation_error(self, exc: Exception) -> SimulationError:
        """math.acos/sqrt outside their domain: a stage left the geometry of eq. 1."""
        return SimulationError(
            f"the model cannot be evaluated near t = {self.t:.6g} s ({self._describe(self.y)}): "
            f"{exc}; {self._likely_cause()}"
        )

    def _likely_cause(self) -> str:
        """Why a run leaves the geometry or blows up: paper mode has no end stops; in physical
        mode the end stops hold the rod, so the integration itself diverged."""
        p = self.params
        if p.mode == "paper":
            return (
                f"the rod is about to leave the valid geometry ({abs(p.b_m - p.a_m):.4g}, {p.a_m + p.b_m:.4g}) m "
                "(paper mode has no end stops)"
            )
        return self._step_advice()

    def _step_advice(self) -> str:
        p = self.params
        fixes = "a smaller time_step_s or more substeps" + ("" if p.method == "ros2" else ", or method ros2")
        return (
            f"the integration diverged: the step of {p.time_step_s:g} s ({p.method}, at least "
            f"{p.substeps} substeps) is too large for these parameters; try {fixes}"
        )

    def _energy_error(self) -> SimulationError:
        tolerance = f"{stepping.ENERGY_TOLERANCE:.0%}"
        return SimulationError(
            f"energy balance broken after t = {self.t:.6g} s: the change of the stored energy no longer "
            f"matches the energy that flowed, by more than {tolerance} ({self._describe(self.y)}); "
            f"{self._step_advice()}"
        )

    def _too_stiff_error(self, needed: int) -> SimulationError:
        p = self.params
        return SimulationError(
            f"too stiff at t = {self.t:.6g} s: a stable {p.method} step of {p.time_step_s:g} s needs {needed} "
            f"substeps, more than {MAX_SUBSTEPS} ({self._describe(self.y)}); use method ros2 (implicit) "
            "or larger dead volumes, a lower bulk_modulus_pa or a smaller orifice"
        )

    def _nonfinite_error(self, what: str) -> SimulationError:
        return SimulationError(
            f"state became non-finite after t = {self.t:.6g} s ({what}; last finite state "
            f"{self._describe(self.y)}); {self._likely_cause()}"
        )

    def _describe(self, y: list) -> str:
        return ", ".join(f"{n} = {v:.6g}" for n, v in zip(self.model.STATE_NAMES[:5], y))

    def outputs(self) -> dict[str, float]:
        """Every output (see :data:`OUTPUTS`) at the current state and command (compiled, the
        model's observe as numba compiled it: a node asks for them every tick)."""
        if self._observe is None:
            return self.model.observe(self.t, self.y, self.constants, self.u)
        out = dict(zip(OUTPUT_NAMES, self._observe(self.t, np.array(self.y), self._constants_row, float(self.u))))
        for name in BOOLEAN_OUTPUTS:
            out[name] = out[name] != 0.0
        return out

    def run(
        self, duration_s: float, command: Callable[[float], float], every: int = 1, stop_on_error: bool = False
    ) -> Trajectory:
        """Simulate ``duration_s`` from the current state with valve command ``command(t)``
        (a feedback command, such as the closed-loop :class:`closed_loop.PositionLoop`, is
        asked ``command(t, y)`` with the state at the step's start).

        The command of a step is ``command`` at the step's middle, held over the step (so a
        step change at T takes effect at the step starting within half a step of T, as the
        node applies stamped commands). Records the outputs at the start and after every
        ``every`` steps. With ``stop_on_error``, a SimulationError ends the run early and the
        trajectory up to the last finite state is returned, with the reason in ``stopped``.
        """
        n_rows = sample_count(round(duration_s / self.params.time_step_s), every) if every >= 1 else 1
        (columns,) = self.samples(duration_s, command, every, stop_on_error, chunk_rows=n_rows)  # one chunk: all
        return Trajectory(columns, self.stopped, self.most_substeps)

    def samples(
        self,
        duration_s: float,
        command: Callable[[float], float],
        every: int = 1,
        stop_on_error: bool = False,
        chunk_rows: int = CHUNK_ROWS,
    ) -> Iterator[dict[str, np.ndarray]]:
        """The samples of :meth:`run`, as columns of up to ``chunk_rows`` rows at a time: a run of
        any length in flat memory. With ``stop_on_error``, ``stopped`` tells afterwards why the
        run ended early (None: it ran through)."""
        if every < 1:
            raise ValueError("every must be >= 1")
        opening = feedback_free(command, self)
        n_steps = round(duration_s / self.params.time_step_s)
        half = 0.5 * self.params.time_step_s
        columns: dict[str, np.ndarray] = {}
        self.stopped = None
        row = 0

        def record() -> None:
            nonlocal row
            values = self.model.observe(self.t, self.y, self.constants, opening(self.t + half))
            if not columns:
                for name in OUTPUT_NAMES:
                    columns[name] = np.empty(chunk_rows, dtype=bool if isinstance(values[name], bool) else float)
            for name in OUTPUT_NAMES:
                columns[name][row] = values[name]
            row += 1

        def flush() -> dict[str, np.ndarray]:
            nonlocal row
            chunk = {name: column[:row] for name, column in columns.items()}
            columns.clear()  # the next chunk gets fresh arrays: this one is the caller's, uncopied
            row = 0
            return chunk

        record()
        for i in range(1, n_steps + 1):
            if row == chunk_rows:
                yield flush()
            try:
                self.step(opening(self.t + half))
            except SimulationError as exc:
                if not stop_on_error:
                    raise
                self.stopped = str(exc)
                record()  # the last finite state
                break
            if i % every == 0 or i == n_steps:
                record()
        yield flush()


def feedback_free(command: Callable, sim: Simulator) -> Callable[[float], float]:
    """``command`` as a function of time alone: a feedback command reads ``sim``'s state."""
    if getattr(command, "feedback", False):
        return lambda t: command(t, sim.y)
    return command


def simulate(
    params: Parameters,
    duration_s: float,
    command: Callable[[float], float] | None = None,
    every: int = 1,
    jit: bool | None = None,
) -> Trajectory:
    """Run a fresh simulation of ``params`` for ``duration_s`` (command from the parameters by default).

    ``jit=None`` steps with the compiled model where numba is available (see :class:`Simulator`).
    Compiled, a command of the parameters' kinds (commands.Profile, closed_loop.PositionLoop)
    runs whole in the compiled kernel (batch.run_sets), with no Python per step; any other
    command, and a run that fails (to raise its error), steps through :meth:`Simulator.run`.
    Both give the same trajectory.
    """
    from .batch import run_sets
    from .commands import from_parameters

    command = command or from_parameters(params)
    n_rows = sample_count(max(0, round(duration_s / params.time_step_s)), max(1, every))
    check_fits(2 * n_rows * len(OUTPUT_NAMES), f"a run of {duration_s:g} s kept whole ({n_rows} samples)",
               "sample less often (every), or stream the run (RunStream; boom-sim run does)")  # fmt: skip
    sim = Simulator(params, jit=jit)
    if sim.compiled and every >= 1 and params.method in integrators.BATCHED:
        runs = run_sets([params], duration_s, command, every, store=True)
        if runs is not None and math.isnan(runs.failed_at_s[0]):
            return Trajectory(runs.columns(0), None, int(runs.most_substeps[0]))
    return sim.run(duration_s, command, every)


#: Most steps a run may take: t = i dt stays exact in a float up to 2**53 steps.
MAX_STEPS = 2**53


def step_count(params: Parameters, duration_s: float, option: str = "duration") -> int:
    """The steps of a run of ``duration_s``: ConfigError for a duration that is not a positive,
    finite number of seconds or that needs more than MAX_STEPS steps of the parameters' dt."""
    if not (duration_s > 0 and math.isfinite(duration_s)):
        raise ConfigError(f"{option} must be a positive number of seconds, got {duration_s}")
    steps = duration_s / params.time_step_s
    if steps > MAX_STEPS:
        raise ConfigError(
            f"{option} {duration_s:g} s is {steps:.3g} steps of {params.time_step_s:g} s, more than a run can take "
            f"({MAX_STEPS:.3g}); choose a shorter duration or a larger time_step_s"
        )
    return round(steps)


class RunStream:
    """A run of ``params`` whose samples come out chunk by chunk as it goes (iterate it), in
    flat memory however long the run; what :func:`simulate` keeps whole.

    Compiled, the run goes through the run kernel in slices of bounded wall time (batch.KernelRun);
    otherwise through :meth:`Simulator.samples`. After each chunk ``done_s`` is the simulated
    time run so far; at the end ``most_substeps`` and ``metrics`` (the streaming metrics of
    :mod:`..analysis.streaming` over every sample, with the parameters' closed-loop move) are
    set. A run that fails raises its SimulationError, as :meth:`Simulator.run` does.
    """

    def __init__(
        self, params: Parameters, duration_s: float, command: Callable | None = None, every: int = 1,
        jit: bool | None = None,
    ) -> None:  # fmt: skip
        from .commands import from_parameters

        self.params = params
        self.duration_s = duration_s
        self.n_steps = step_count(params, duration_s)
        self.every = every
        self.command = command or from_parameters(params)
        self.jit = jit
        self.done_s = 0.0
        self.most_substeps = params.substeps
        self.metrics: dict[str, float] = {}

    def __iter__(self) -> Iterator[dict[str, np.ndarray]]:
        from .batch import kernel_run

        sim = Simulator(self.params, jit=self.jit)
        run = None
        if sim.compiled and self.params.method in integrators.BATCHED:
            run = kernel_run(
                [self.params], self.duration_s, self.command, self.every, store=True, slice_rows=CHUNK_ROWS
            )
        if run is None:
            yield from self._interpreted(sim)
        else:
            yield from self._compiled(sim, run)

    def _compiled(self, sim: Simulator, run) -> Iterator[dict[str, np.ndarray]]:
        from . import kernel

        dt = self.params.time_step_s
        for taken in run.slices():
            table = run.rows[0, : taken[0]]
            self.done_s = min(run.done, run.n_steps) * dt
            if len(table):
                yield {
                    name: table[:, j] != 0.0 if name in BOOLEAN_OUTPUTS else table[:, j].copy()
                    for j, name in enumerate(OUTPUT_NAMES)
                }
        status = run.status[0]
        if status[kernel.OUTCOME] != stepping.OK:
            raise self._failure(sim, run.state[0], status)
        self.done_s = run.n_steps * dt
        self.most_substeps = int(status[kernel.MOST])
        result = run.result()
        self.metrics = {name: float(values[0]) for name, values in result.metrics.items()}

    def _failure(self, sim: Simulator, y: np.ndarray, status: np.ndarray) -> SimulationError:
        """The error of the step where the kernel stopped, as the Simulator words it: the
        Simulator takes that step again from the same state and command (the same compiled step)."""
        from . import kernel

        failed = int(status[kernel.FAILED_STEP])
        sim.y, sim.step_count = y.tolist(), failed
        sim.t = sim._t_base + failed * self.params.time_step_s
        sim.most_substeps = int(status[kernel.MOST])
        try:
            sim.step(float(status[kernel.NEXT_U]))
        except SimulationError as exc:
            return exc
        return SimulationError(f"the run stopped at t = {status[kernel.FAILED_AT]:.6g} s (stepping outcome "
                               f"{int(status[kernel.OUTCOME])}); {sim._step_advice()}")  # fmt: skip

    def _interpreted(self, sim: Simulator) -> Iterator[dict[str, np.ndarray]]:
        from . import streaming
        from .streaming import DEFAULT_LIFT_ANGLE_DEG, move_window

        settings = streaming.settings(DEFAULT_LIFT_ANGLE_DEG, *move_window(self.params))
        accumulator = streaming.accumulator()
        for chunk in sim.samples(self.duration_s, self.command, self.every):
            columns = [np.asarray(chunk[name], dtype=float).tolist() for name in streaming.SAMPLE_SIGNALS]
            for row in zip(*columns):
                streaming.add_sample(accumulator, settings, *row)
            self.done_s = sim.t
            yield chunk
        self.most_substeps = sim.most_substeps
        out = np.empty(len(streaming.NAMES))
        streaming.finish(accumulator, settings, out)
        self.metrics = dict(zip(streaming.NAMES, out.tolist()))
