"""Stepping one boom drive through time: the driver shared by the node, the CLI and tests.

:class:`Simulator` owns the state, the simulated time and the integrator, and applies a
valve command held constant over each step (zero-order hold). :meth:`Simulator.step` takes
steps with one command (the node's ticks, :class:`command_queue.CommandedDrive`) through the
stepping loop :func:`stepping.advance` (ros2's: :func:`stepping.advance_halving`);
:meth:`Simulator.run` and :meth:`Simulator.samples` run a whole command from the current
state through the run loop (:class:`batch.SetRun`, :func:`kernel.run_set`), whose step is
that same stepping loop, and :meth:`Simulator.following` and :meth:`Simulator.go_on` a
tick's steps of the position controller through it (the node's ticks while the controller
drives). Physics lives in the model modules (:mod:`physical`, :mod:`paper`); this module
only drives them.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import SimulationError
from ..model import MODELS
from ..model.geometry import triangle_bounds_m, within_triangle
from ..model.parameters import Parameters, with_updates
from . import accelerate, integrators, kernel, stepping
from .batch import MODEL_ERRORS, SetRun, Start, columns_of, stability_limit
from .closed_loop import PositionLoop
from .outcomes import MAX_SUBSTEPS, OK, OUT_OF_GEOMETRY, TOO_STIFF, evaluation_message, message
from .outputs import BOOLEAN_OUTPUTS, OUTPUT_NAMES, published

_SCALES = {"length": 1.0, "velocity": 1.0, "unit": 1.0, "energy": 1.0e3}

#: Rows of one chunk of a streamed run (RunStream, Simulator.samples): a few MB as CSV text.
CHUNK_ROWS = 8192

#: How long the position controller may follow in one run of Simulator.following, s (32 years).
FOLLOW_HORIZON_S = 1.0e9


def scale_sizes(p: Parameters) -> dict[str, float]:
    """The natural size of a state of each scale (a model's or a drive's STATE_SCALES): 1 m,
    1 m/s, 1, 1 kJ, the supply pressure, the pump's speed."""
    return dict(_SCALES, pressure=p.supply_pressure_pa, angular_velocity=p.pump_speed_rad_s, flow=p.pump_max_flow_m3_s)


def absolute_tolerances(p: Parameters) -> list[float]:
    """rk45 absolute tolerance per state: atol_scale times the state's natural scale."""
    model = MODELS[p.mode]
    scale = scale_sizes(p)
    return [p.atol_scale * scale[kind] for kind in model.STATE_SCALES]


def make_integrator(p: Parameters) -> integrators.Integrator:
    """The integrator the parameters ask for."""
    return integrators.make(p.method, p.substeps, p.rtol, absolute_tolerances(p))


@dataclass
class Trajectory:
    """Outputs sampled over a run: one numpy array per name in :data:`OUTPUT_NAMES`."""

    columns: dict[str, np.ndarray]
    stopped: str | None = None  # why the run ended early (run(stop_on_error=True)), else None
    most_substeps: int = 1  # the most substeps one time step took (outcomes.substeps_cause: why)

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
        self._full = self.model.constants(params)  # with the whole payload_mass_kg on the hook
        self.integrator = make_integrator(params)
        self._limit = stability_limit(params)
        step = integrators.METHODS[params.method].step
        adaptive = step is None  # rk45: one adaptive advance per step, in the same stepping loop
        self._min_substeps = 1 if adaptive else params.substeps
        model = self.model
        self._run = functools.partial(
            stepping.loop_of(params.method),
            self._adaptive_step if adaptive else step,
            model.derivative,
            model.stiffness_rate,
            model.energy,
        )  # the compiled kernels' loop, interpreted
        self._elements = accelerate.with_elements([params])  # the compiled calls' layout of the state
        kernels = (params.mode, params.method, self._elements)
        self._compiled = accelerate.stepper(*kernels) if self.jit else None
        self._observe = accelerate.observer(*kernels) if self._compiled is not None else None
        self._publish = accelerate.publisher(*kernels) if self._compiled is not None else None
        self._hold(self._full)

    def _hold(self, constants: Any, payload_share: float = 1.0) -> None:
        """Step with ``constants`` from now on, with ``payload_share`` of the payload on the hook
        (a payload schedule may take a share off it)."""
        self.constants = constants
        self._payload_share = payload_share
        self._constants_row = np.array(constants, dtype=float)  # what the compiled calls take

    def _adaptive_step(self, fun: Callable, t: float, y: list, h: float, args: tuple) -> list:
        """rk45's step: its integrator's adaptive advance over ``h`` (it keeps its step size)."""
        return self.integrator.advance(fun, t, y, h, args)

    # --- state --------------------------------------------------------------------------
    def reset(self, initial_length_m: float | None = None, keep_time: bool = False) -> None:
        """Back to rest at ``initial_length_m`` (default q1(0)), valve closed; t = 0 unless
        ``keep_time`` (a clock that others follow never runs backwards)."""
        p = self.params
        if initial_length_m is not None:
            low, high = (
                (p.cylinder_min_length_m, p.cylinder_max_length_m)
                if p.mode == "physical"
                else triangle_bounds_m(p.a_m, p.b_m)
            )
            if not (low <= initial_length_m <= high) or not math.isfinite(initial_length_m):
                raise SimulationError(
                    f"reset position {initial_length_m} m lies outside the stroke [{low:.4g}, {high:.4g}] m"
                )
        self._hold(self._full)  # the whole payload again (a schedule may have changed it)
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
        self.set_parameters(with_updates(self.params, payload_mass_kg=payload_mass_kg))

    def _moved(self, y: list, steps: int) -> None:
        """The state ``y`` after ``steps`` more steps."""
        self.y = y
        self.step_count += steps
        self.t = self._t_base + (self.step_count - self._n_base) * self.params.time_step_s

    def warm(self) -> None:
        """Compile (or load from the cache) what this simulator steps with, so that its first
        steps do not stall: its stepping, its outputs, what a state publishes and, where the
        position controller can drive the valve (physical mode), the run loop of
        :meth:`following`. Nothing where it steps interpreted; where it is, its state and time
        stay as they are."""
        if not self.compiled:
            return
        self.step(0.0, 0)
        self.outputs()
        self.published()
        if self.params.mode == "physical":
            self.following(PositionLoop.of_parameters([self.params])).go_on(0)  # its start, taken by no one

    def warm_kernels(self) -> list[Callable[..., Any]]:
        """The compiled entry points :meth:`warm` loads (none interpreted)."""
        if not self.compiled:
            return []
        p = self.params
        kernels = [self._compiled, self._observe, self._publish]
        if p.mode == "physical":  # (the controller's run too)
            kernels.append(accelerate.set_runner(p.mode, p.method, self._elements))
        return [k for k in kernels if k is not None]

    def compiles_first(self) -> bool:
        """Whether :meth:`warm` compiles what this simulator steps with (numba's cache does not
        hold it yet: tens of seconds), rather than loading it: for a start to say so first."""
        return accelerate.not_in_cache(self.warm_kernels())

    # --- stepping -------------------------------------------------------------------------
    def step(self, u: float, steps: int = 1) -> None:
        """Advance ``steps`` time steps with the valve command ``u`` held constant. A step that
        fails (outcomes) is not taken: the state is the last good one, and SimulationError says why."""
        if not math.isfinite(u):
            raise SimulationError(f"valve command must be finite, got {u!r}")
        p = self.params
        rest = (float(u), p.time_step_s, self._min_substeps, self._limit, MAX_SUBSTEPS, steps)
        rest += (self._energy_index, self._energy_base)
        before = self.y, self.step_count
        if self._compiled is not None:
            done, outcome, most, y = self._compiled(self.t, np.array(self.y), self._constants_row, *rest)
            y = y.tolist()
        else:
            try:
                done, outcome, most, y = self._run(self.t, self.y, self.constants, *rest)
            except MODEL_ERRORS as exc:  # math.acos/sqrt outside their domain: a stage left eq. 1
                for _ in range(steps if steps > 1 else 0):  # which step: one at a time (bit for bit the same)
                    self.step(u, 1)
                raise SimulationError(evaluation_message(p, self.t, self.y, exc)) from None
        self._moved(y, int(done))
        self.u = u
        if not within_triangle(self.y[0], p.a_m, p.b_m):  # a step left the geometry: it is not taken
            self.y, self.step_count = before
            self._moved(self.y, 0)
            if done > 1:  # which one it is: the steps before it again (bit for bit the same), then it
                self.step(u, int(done) - 1)
                self.step(u, 1)
            raise SimulationError(message(p, OUT_OF_GEOMETRY, self.t, self.y))
        if outcome == TOO_STIFF:
            raise SimulationError(message(p, TOO_STIFF, self.t, self.y, int(most)))
        self.most_substeps = max(self.most_substeps, int(most))
        if outcome != OK:
            raise SimulationError(message(p, outcome, self.t, self.y))

    def outputs(self) -> dict[str, float]:
        """Every output (see :data:`OUTPUTS`) at the current state and command (compiled, the
        model's observe as numba compiled it: a node asks for them every tick)."""
        if self._observe is None:
            return self.model.observe(self.t, self.y, self.constants, self.u)
        out = dict(zip(OUTPUT_NAMES, self._observe(self.t, np.array(self.y), self._constants_row, float(self.u))))
        for name in BOOLEAN_OUTPUTS:
            out[name] = out[name] != 0.0
        return out

    def published(self) -> list[float]:
        """What a state publishes now, in the order of :data:`.outputs.PUBLISHED_NAMES`: every
        output (flags 1.0 or 0.0), the cylinder barrel's angle and rate, the lever, and 1.0 where
        the published outputs are finite (compiled: the node's one call a tick)."""
        if self._publish is None:
            c = self.constants
            return published(self.model.outputs(self.t, self.y, c, self.u), c.a, c.b, c.h).tolist()
        return self._publish(self.t, np.array(self.y), self._constants_row, float(self.u)).tolist()

    # --- whole runs -----------------------------------------------------------------------
    def whole_run(
        self, duration_s: float, command: Callable, every: int = 1, *, store: bool = True,
        slice_rows: int | None = None, measure: bool = False, serial: bool = False,
        payload: tuple[tuple[float, ...], tuple[float, ...]] | None = None,
    ) -> SetRun:  # fmt: skip
        """``duration_s`` of valve command ``command(t)`` (a feedback command, such as the
        closed-loop :class:`closed_loop.PositionLoop`, is asked ``command(t, y)`` with the
        state at the step's start) from the current state, as a run of the run loop to go
        through (:meth:`SetRun.slices`) and then hand to :meth:`take`; see SetRun for the rest."""
        # the run starts from the parameters' constants (the whole payload; its schedule puts the
        # share of now back): H - W as those constants count H
        base = self._energy_base
        if self._energy_index >= 0:
            base += self.model.energy(self.y, self._full) - self.model.energy(self.y, self.constants)
        start = Start(list(self.y), self._t_base, self.step_count - self._n_base, base, self.integrator)
        return SetRun([self.params], duration_s, command, every, store=store, slice_rows=slice_rows,
                      measure=measure, jit=self.jit, start=start, serial=serial, payload=payload)  # fmt: skip

    def take(self, run: SetRun, since: int = 0) -> str | None:
        """The drive as ``run`` (of :meth:`whole_run`, gone through, or of :meth:`following`, gone
        on) left it, which was here after its first ``since`` steps: its state, time and command;
        the reason it stopped early (a failure, see :mod:`outcomes`), or None."""
        status = run.status[0]
        outcome = int(status[kernel.OUTCOME])
        steps = run.steps_taken(0)
        self._moved(run.state[0].tolist(), steps - since)
        # the payload schedule leaves its share of the payload on the hook, and H - W as it counts H
        share = float(status[kernel.PAYLOAD])
        if share != self._payload_share:  # (the controller's run, taken at every tick, keeps it)
            self._hold(self.model.with_payload(self._full, share), share)
        self._energy_base = run.energy_base(0) + float(status[kernel.BASE_SHIFT])
        if outcome != OK:
            self.u = float(status[kernel.NEXT_U])  # the command of the step that failed
        elif steps > 0:
            self.u = float(status[kernel.APPLIED_U])
        if outcome != TOO_STIFF:
            self.most_substeps = max(self.most_substeps, int(status[kernel.MOST]))
        return run.reason(0)

    def following(self, loop: PositionLoop) -> SetRun:
        """The position controller ``loop`` (fresh: one that has not run) driving the valve from
        the current state on, as a run of the run loop with the compiled controller, that
        :meth:`go_on` takes on a few steps at a time; it keeps no samples and ends after
        FOLLOW_HORIZON_S. The payload stays as it is now, as for :meth:`step`: the parameters'
        payload schedule is for whole runs."""
        if not loop.fresh:
            raise ValueError("the controller has run already: follow with a fresh PositionLoop")
        hold = ((-math.inf,), (self._payload_share,)) if self._payload_share != 1.0 else ((), ())
        return self.whole_run(FOLLOW_HORIZON_S, loop, store=False, serial=True, payload=hold)

    def go_on(self, run: SetRun, steps: int) -> None:
        """Up to ``steps`` more steps of ``run`` (of :meth:`following`; fewer where it reaches
        its end), as :meth:`step` takes them: a step that fails is not taken, and
        SimulationError says why."""
        since = run.steps_taken(0)
        run.go_on(steps)
        why = self.take(run, since)
        if why is not None:
            raise SimulationError(why)

    def _last_sample(self) -> np.ndarray:
        """The outputs at the current state and command, as one row (OUTPUT_NAMES order)."""
        return np.array([self.model.outputs(self.t, self.y, self.constants, self.u)], dtype=float)

    def run(
        self, duration_s: float, command: Callable[[float], float], every: int = 1, stop_on_error: bool = False
    ) -> Trajectory:
        """Simulate ``duration_s`` from the current state with valve command ``command(t)`` (see
        :meth:`whole_run`), through the run loop.

        The command of a step is ``command`` at the step's middle, held over the step (so a
        step change at T takes effect at the step starting within half a step of T, as the
        node applies stamped commands). Records the outputs at the start, after every
        ``every`` steps and at the end. With ``stop_on_error``, a failure ends the run early and
        the trajectory up to the last finite state is returned, with the reason in ``stopped``.
        """
        if every < 1:
            raise ValueError("every must be >= 1")
        run = self.whole_run(duration_s, command, every)
        runs = run.table()
        table = runs.rows[0, : runs.samples[0]]
        self.stopped = self._stopped(run, stop_on_error)
        if self.stopped is not None:
            table = np.concatenate([table, self._last_sample()])  # the last finite state
        return Trajectory(columns_of(table), self.stopped, self.most_substeps)

    def _stopped(self, run: SetRun, stop_on_error: bool) -> str | None:
        why = self.take(run)
        if why is not None and not stop_on_error:
            raise SimulationError(why)
        return why

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
        self.stopped = None
        run = self.whole_run(duration_s, command, every, slice_rows=chunk_rows)
        for taken in run.slices():
            if taken[0]:
                yield columns_of(run.rows[0, : taken[0]])
        self.stopped = self._stopped(run, stop_on_error)
        if self.stopped is not None:
            yield columns_of(self._last_sample())  # the last finite state
