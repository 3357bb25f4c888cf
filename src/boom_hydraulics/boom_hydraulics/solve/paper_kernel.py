"""The compiled kernels of the paper model: its stepping, its outputs (and what a state
publishes) and its batch run.

Ordinary code that numba compiles as written (see :mod:`..jit`): each entry point calls the
one stepping loop (:func:`stepping.advance`; ros2's :func:`stepping.advance_halving`, which
calls it) or the one run loop (:func:`kernel.run_set`)
with the method's step and the model's functions by name, so that numba compiles them into
it; the state is a tuple (euler, rk4: on the stack) or a list (ros2, whose stages are numpy
arrays). Python hands the constants over as a row of floats (:func:`constants_of`): numba
types an array at once, a NamedTuple field by field on every call. The cache of these
kernels is keyed on a hash of :data:`SOURCES`, every file they compile.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from .. import jit
from ..jit import jitable, kernel, prange
from ..model import control, end_stops, friction, geometry, hydraulics, kinematics, mechanics, outputs, setpoints
from ..model import ledger as output_terms  # (not called: its terms name outputs, so it is part of the cache key)
from ..model import paper as model
from . import integrators, lanes, profiles, stepping, streaming
from . import kernel as run
from .integrators import euler_step, rk4_step, ros2_step

#: Every source the kernels compile: a change to any of them gives a fresh cache.
SOURCES = [
    *jit.module_sources(jit, geometry, hydraulics, friction, end_stops, mechanics, control, setpoints, outputs),
    *jit.module_sources(kinematics, output_terms),
    *jit.module_sources(model, integrators, lanes, stepping, profiles, streaming, run),
    Path(__file__).resolve(),
]


@jitable
def constants_of(row: Any) -> model.Constants:
    """The model's Constants from a row of floats, in the order of their fields."""
    return model.Constants(
        row[0],
        row[1],
        row[2],
        row[3],
        row[4],
        row[5],
        row[6],
        row[7],
        row[8],
        row[9],
        row[10],
        row[11],
        row[12],
        row[13],
        row[14],
        row[15],
        row[16],
        row[17],
    )


#: The state's layout (kernel.layout): the paper model has no model elements.
WHOLE = run.layout(len(model.STATE_NAMES))


@jitable
def state_of(row: Any) -> tuple:
    """The state as a tuple (the euler and rk4 steps keep it so)."""
    return run.state_of(row, WHOLE)


@jitable
def list_of(row: Any) -> list:
    """The state as a list (the ros2 step keeps it so)."""
    return [v for v in row]


@kernel(SOURCES)
def steps_euler(t: float, y0: Any, crow: Any, u: float, *rest: Any) -> tuple[int, int, int, np.ndarray]:
    """Up to n steps of explicit Euler (stepping.advance; ``rest``: dt, min_substeps, limit,
    max_substeps, n, energy_index, energy_base) -> (steps taken, outcome, most substeps, y)."""
    f = (euler_step, model.derivative, model.stiffness_rate, model.energy)
    done, outcome, most, y = stepping.advance(*f, t, state_of(y0), constants_of(crow), u, *rest)
    return done, outcome, most, np.array(y)


@kernel(SOURCES)
def steps_rk4(t: float, y0: Any, crow: Any, u: float, *rest: Any) -> tuple[int, int, int, np.ndarray]:
    """Up to n steps of classical RK4 (as :func:`steps_euler`)."""
    f = (rk4_step, model.derivative, model.stiffness_rate, model.energy)
    done, outcome, most, y = stepping.advance(*f, t, state_of(y0), constants_of(crow), u, *rest)
    return done, outcome, most, np.array(y)


@kernel(SOURCES)
def steps_ros2(t: float, y0: Any, crow: Any, u: float, *rest: Any) -> tuple[int, int, int, np.ndarray]:
    """Up to n steps of Rosenbrock ROS2, a step that fails its checks taken again in more
    substeps (stepping.advance_halving; as :func:`steps_euler`)."""
    f = (ros2_step, model.derivative, model.stiffness_rate, model.energy)
    done, outcome, most, y = stepping.advance_halving(*f, t, list_of(y0), constants_of(crow), u, *rest)
    return done, outcome, most, np.array(y)


@kernel(SOURCES)
def outputs_of(t: float, y0: Any, crow: Any, u: float) -> tuple:
    """The model's outputs (model.outputs: floats in the order of OUTPUT_NAMES, flags 1.0 or 0.0)."""
    return model.outputs(t, state_of(y0), constants_of(crow), u)


@kernel(SOURCES)
def published_of(t: float, y0: Any, crow: Any, u: float) -> np.ndarray:
    """What a state publishes (outputs.published: the outputs, the barrel's angle and rate, the
    lever and whether the published outputs are finite, in the order of PUBLISHED_NAMES)."""
    c = constants_of(crow)
    return outputs.published(model.outputs(t, state_of(y0), c, u), c.a, c.b, c.h)


@jitable
def batch_set(step: Any, k: int, arguments: tuple) -> None:
    """kernel.batch_set of set ``k`` with ``step`` and this model's functions by name;
    no controller (the paper valve only lifts)."""
    f = (step, model.derivative, model.stiffness_rate, model.energy, model.outputs, model.samples, run.no_controller)
    run.batch_set(stepping.advance, *f, model.with_payload, constants_of, 0.0, WHOLE, k, *arguments)


@kernel(SOURCES, parallel=True)
def batch_euler(*arguments: Any) -> None:
    """:func:`batch_set` with explicit Euler over every set of a batch, in parallel
    (``arguments``: see batch.run_sets)."""
    for k in prange(arguments[0].shape[0]):
        batch_set(euler_step, k, arguments)


@kernel(SOURCES, parallel=True)
def batch_rk4(*arguments: Any) -> None:
    """:func:`batch_set` with classical RK4 over every set of a batch, in parallel (as :func:`batch_euler`)."""
    for k in prange(arguments[0].shape[0]):
        batch_set(rk4_step, k, arguments)


#: The entry points by method: stepping, and the batch run (explicit methods only); no run of
#: one set in the calling thread (physical_kernel's SETS, for the position controller that a
#: node's ticks pace: paper mode has none), and no blocks of sets in lock-step (physical_kernel's
#: BLOCKS: the paper model runs one set per thread).
STEPS = {("euler", False): steps_euler, ("rk4", False): steps_rk4, ("ros2", False): steps_ros2}
OUTPUTS = {False: outputs_of}
PUBLISHED = {False: published_of}
BATCHES = {("euler", False): batch_euler, ("rk4", False): batch_rk4}
SETS: dict = {}
BLOCKS: dict = {}
