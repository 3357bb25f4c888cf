"""Whole runs of one parameter set: :func:`simulate` (kept whole) and :class:`RunStream` (streamed).

Both sit above the :class:`simulator.Simulator` and the batch (:mod:`batch`): a fresh
Simulator runs the command through the one run loop (:func:`kernel.run_set`), compiled in the
run kernel where it can be. This module also gives the names most callers take from here:
the Simulator, its Trajectory and the outputs.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator

import numpy as np

from ..errors import ConfigError, SimulationError
from ..model.parameters import Parameters
from .batch import columns_of, sample_count
from .commands import from_parameters
from .outputs import BOOLEAN_OUTPUTS, OUTPUT_NAMES, OUTPUTS
from .simulator import CHUNK_ROWS, Simulator, Trajectory

__all__ = ["BOOLEAN_OUTPUTS", "OUTPUTS", "OUTPUT_NAMES", "RunStream", "Simulator", "Trajectory", "simulate"]

#: Most steps a run may take: t = i dt stays exact in a float up to 2**53 steps.
MAX_STEPS = 2**53


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


def simulate(
    params: Parameters,
    duration_s: float,
    command: Callable[[float], float] | None = None,
    every: int = 1,
    jit: bool | None = None,
) -> Trajectory:
    """Run a fresh simulation of ``params`` for ``duration_s`` (command from the parameters by default).

    ``jit=None`` steps with the compiled model where numba is available (see :class:`Simulator`).
    Compiled, a command that describes itself to the kernel (commands.Profile,
    closed_loop.PositionLoop) runs whole in the compiled run kernel, with no Python per step;
    any other command runs the same loop in Python over the compiled steps. Both give the
    same trajectory (:meth:`Simulator.run`).
    """
    command = command or from_parameters(params)
    n_rows = sample_count(max(0, round(duration_s / params.time_step_s)), max(1, every))
    check_fits(2 * n_rows * len(OUTPUT_NAMES), f"a run of {duration_s:g} s kept whole ({n_rows} samples)",
               "sample less often (every), or stream the run (RunStream; boom-sim run does)")  # fmt: skip
    return Simulator(params, jit=jit).run(duration_s, command, every)


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

    The run goes through the run loop in slices of bounded wall time (batch.SetRun, compiled
    in the run kernel where it can be). After each chunk ``done_s`` is the simulated time run
    so far; at the end ``most_substeps`` and ``metrics`` (the streaming metrics of
    :mod:`streaming` over every sample, with the parameters' closed-loop move) are set. A run
    that fails raises its SimulationError, as :meth:`Simulator.run` does.
    """

    def __init__(
        self, params: Parameters, duration_s: float, command: Callable | None = None, every: int = 1,
        jit: bool | None = None,
    ) -> None:  # fmt: skip
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
        sim = Simulator(self.params, jit=self.jit)
        run = sim.whole_run(self.duration_s, self.command, self.every, slice_rows=CHUNK_ROWS, measure=True)
        dt = self.params.time_step_s
        for taken in run.slices():
            self.done_s = min(run.done, run.n_steps) * dt
            if taken[0]:
                yield columns_of(run.rows[0, : taken[0]])
        why = sim.take(run)
        if why is not None:
            raise SimulationError(why)
        self.done_s = run.n_steps * dt
        self.most_substeps = sim.most_substeps
        self.metrics = {name: float(values[0]) for name, values in run.result().metrics.items()}
