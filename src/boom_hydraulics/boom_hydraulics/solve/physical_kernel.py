"""The compiled kernels of the physical model: its stepping, its outputs (and what a state
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

import sys
from pathlib import Path
from typing import Any

import numpy as np

from .. import jit
from ..jit import jitable, kernel, prange
from ..model import (
    accumulator,
    battery,
    control,
    drives,
    elastic_boom,
    electric_motor,
    end_stops,
    friction,
    geometry,
    hoses,
    hydraulics,
    kinematics,
    ledger,
    mechanics,
    outputs,
    pump,
    setpoints,
    valve,
)
from ..model import physical as model
from . import integrators, lanes, profiles, stepping, streaming
from . import kernel as run
from .integrators import euler_step, rk4_step, ros2_step

#: Every source the kernels compile: a change to any of them gives a fresh cache.
SOURCES = [
    *jit.module_sources(jit, geometry, hydraulics, friction, end_stops, mechanics, control, setpoints, outputs),
    *jit.module_sources(kinematics),
    *jit.module_sources(pump, electric_motor, battery, ledger, valve),
    *jit.module_sources(accumulator, hoses, elastic_boom),  # the model elements physical compiles in
    *jit.module_sources(drives, sys.modules[drives.constants.__module__], *drives.DRIVES.values()),
    *jit.module_sources(*(sys.modules[f"{drives.__name__}.{name}"] for name in ("motor_speed", "eha_motor"))),
    *jit.module_sources(model, integrators, lanes, stepping, profiles, streaming, run),
    Path(__file__).resolve(),
]


#: How many constants the model has, and how many states.
N_CONSTANTS = len(model.Constants._fields)
N_STATE = len(model.STATE_NAMES)
#: A row of the constants as compiled code takes it (jit.tuple_like: its size is its type).
CONSTANTS_ROW = (0.0,) * N_CONSTANTS
#: The state's layouts (kernel.layout): without the model elements' states (their states stand
#: still where all three are off: physical.element_states), and the whole state. Each entry
#: point below comes in both, the second named ``..._elements``: numba compiles the one a run
#: calls (accelerate picks it), so that elements that are off cost neither steps nor compiling.
BASE = run.layout(model.BASE_SIZE)
WHOLE = run.layout(N_STATE)


@jitable
def constants_of(row: Any) -> model.Constants:
    """The model's Constants from a row of floats, in the order of their fields."""
    return model.Constants(*jit.tuple_like(row, CONSTANTS_ROW))


@jitable
def list_of(row: Any) -> list:
    """The state as a list (the ros2 step keeps it so)."""
    return [v for v in row]


@jitable
def steps(step: Any, layout: tuple, t: float, y0: Any, crow: Any, u: float, rest: tuple) -> tuple:
    """Up to n steps of ``step`` (stepping.advance; ``rest``: dt, min_substeps, limit,
    max_substeps, n, energy_index, energy_base) from the state row ``y0``, its first
    len(``layout``) values -> (steps taken, outcome, most substeps, the state row after them)."""
    f = (step, model.derivative, model.stiffness_rate, model.energy)
    done, outcome, most, y = stepping.advance(*f, t, run.state_of(y0, layout), constants_of(crow), u, *rest)
    return done, outcome, most, run.state_row(y0, y)


@kernel(SOURCES)
def steps_euler(t: float, y0: Any, crow: Any, u: float, *rest: Any) -> tuple[int, int, int, np.ndarray]:
    """Up to n steps of explicit Euler (:func:`steps`) -> (steps taken, outcome, most substeps, y)."""
    return steps(euler_step, BASE, t, y0, crow, u, rest)


@kernel(SOURCES)
def steps_euler_elements(t: float, y0: Any, crow: Any, u: float, *rest: Any) -> tuple[int, int, int, np.ndarray]:
    """:func:`steps_euler` of the whole state."""
    return steps(euler_step, WHOLE, t, y0, crow, u, rest)


@kernel(SOURCES)
def steps_rk4(t: float, y0: Any, crow: Any, u: float, *rest: Any) -> tuple[int, int, int, np.ndarray]:
    """Up to n steps of classical RK4 (as :func:`steps_euler`)."""
    return steps(rk4_step, BASE, t, y0, crow, u, rest)


@kernel(SOURCES)
def steps_rk4_elements(t: float, y0: Any, crow: Any, u: float, *rest: Any) -> tuple[int, int, int, np.ndarray]:
    """:func:`steps_rk4` of the whole state."""
    return steps(rk4_step, WHOLE, t, y0, crow, u, rest)


@kernel(SOURCES)
def steps_ros2(t: float, y0: Any, crow: Any, u: float, *rest: Any) -> tuple[int, int, int, np.ndarray]:
    """Up to n steps of Rosenbrock ROS2, a step that fails its checks taken again in more
    substeps (stepping.advance_halving; as :func:`steps_euler`), of the whole state (a list:
    its stages are numpy arrays), with the elements on or off."""
    f = (ros2_step, model.derivative, model.stiffness_rate, model.energy)
    done, outcome, most, y = stepping.advance_halving(*f, t, list_of(y0), constants_of(crow), u, *rest)
    return done, outcome, most, np.array(y)


@kernel(SOURCES)
def outputs_of(t: float, y0: Any, crow: Any, u: float) -> tuple:
    """The model's outputs (model.outputs: floats in the order of OUTPUT_NAMES, flags 1.0 or 0.0)."""
    return model.outputs(t, run.state_of(y0, BASE), constants_of(crow), u)


@kernel(SOURCES)
def outputs_of_elements(t: float, y0: Any, crow: Any, u: float) -> tuple:
    """:func:`outputs_of` of the whole state."""
    return model.outputs(t, run.state_of(y0, WHOLE), constants_of(crow), u)


@jitable
def published_at(layout: tuple, t: float, y0: Any, crow: Any, u: float) -> np.ndarray:
    """What a state publishes (outputs.published: the outputs, the barrel's angle and rate, the
    lever and whether the published outputs are finite, in the order of PUBLISHED_NAMES)."""
    c = constants_of(crow)
    return outputs.published(model.outputs(t, run.state_of(y0, layout), c, u), c.a, c.b, c.h)


@kernel(SOURCES)
def published_of(t: float, y0: Any, crow: Any, u: float) -> np.ndarray:
    """What a state publishes (:func:`published_at`)."""
    return published_at(BASE, t, y0, crow, u)


@kernel(SOURCES)
def published_of_elements(t: float, y0: Any, crow: Any, u: float) -> np.ndarray:
    """:func:`published_of` of the whole state."""
    return published_at(WHOLE, t, y0, crow, u)


@jitable
def batch_set(step_once: Any, step: Any, template: Any, layout: tuple, block: int, arguments: tuple) -> None:
    """kernel.batch_set of block ``block`` of as many sets as ``template`` holds (a float: one;
    Lanes: a block in lock-step, with ``step_once`` stepping.advance_lanes) with ``step`` and
    this model's functions by name, the states of ``layout``; the position controller."""
    f = (step, model.derivative, model.stiffness_rate, model.energy, model.outputs, model.samples, run.controller_value)
    run.batch_set(step_once, *f, model.with_payload, constants_of, template, layout, block, *arguments)


@kernel(SOURCES, parallel=True)
def batch_euler(*arguments: Any) -> None:
    """:func:`batch_set` with explicit Euler over every set of a batch, in parallel
    (``arguments``: see batch.run_sets)."""
    for k in prange(arguments[0].shape[0]):
        batch_set(stepping.advance, euler_step, 0.0, BASE, k, arguments)


@kernel(SOURCES, parallel=True)
def batch_euler_elements(*arguments: Any) -> None:
    """:func:`batch_euler` of the whole state."""
    for k in prange(arguments[0].shape[0]):
        batch_set(stepping.advance, euler_step, 0.0, WHOLE, k, arguments)


@kernel(SOURCES, parallel=True)
def batch_rk4(*arguments: Any) -> None:
    """:func:`batch_set` with classical RK4 over every set of a batch, in parallel (as :func:`batch_euler`)."""
    for k in prange(arguments[0].shape[0]):
        batch_set(stepping.advance, rk4_step, 0.0, BASE, k, arguments)


@kernel(SOURCES, parallel=True)
def batch_rk4_elements(*arguments: Any) -> None:
    """:func:`batch_rk4` of the whole state."""
    for k in prange(arguments[0].shape[0]):
        batch_set(stepping.advance, rk4_step, 0.0, WHOLE, k, arguments)


@kernel(SOURCES, parallel=True)
def blocks_euler(*arguments: Any) -> None:
    """:func:`batch_set` with explicit Euler over the blocks of lanes.WIDTH sets of a batch, each
    block in lock-step on the vector units (:mod:`lanes`), the blocks in parallel (as
    :func:`batch_euler`: the same results, see :mod:`lanes`)."""
    for block in prange((arguments[0].shape[0] + lanes.WIDTH - 1) // lanes.WIDTH):
        batch_set(stepping.advance_lanes, euler_step, lanes.block(), BASE, block, arguments)


@kernel(SOURCES, parallel=True)
def blocks_euler_elements(*arguments: Any) -> None:
    """:func:`blocks_euler` of the whole state."""
    for block in prange((arguments[0].shape[0] + lanes.WIDTH - 1) // lanes.WIDTH):
        batch_set(stepping.advance_lanes, euler_step, lanes.block(), WHOLE, block, arguments)


@kernel(SOURCES, parallel=True)
def blocks_rk4(*arguments: Any) -> None:
    """:func:`blocks_euler` with classical RK4."""
    for block in prange((arguments[0].shape[0] + lanes.WIDTH - 1) // lanes.WIDTH):
        batch_set(stepping.advance_lanes, rk4_step, lanes.block(), BASE, block, arguments)


@kernel(SOURCES, parallel=True)
def blocks_rk4_elements(*arguments: Any) -> None:
    """:func:`blocks_rk4` of the whole state."""
    for block in prange((arguments[0].shape[0] + lanes.WIDTH - 1) // lanes.WIDTH):
        batch_set(stepping.advance_lanes, rk4_step, lanes.block(), WHOLE, block, arguments)


@kernel(SOURCES)
def set_euler(*arguments: Any) -> None:
    """:func:`batch_set` with explicit Euler over the one set of a run, in the calling thread
    (a serial batch.SetRun: see there)."""
    batch_set(stepping.advance, euler_step, 0.0, BASE, 0, arguments)


@kernel(SOURCES)
def set_euler_elements(*arguments: Any) -> None:
    """:func:`set_euler` of the whole state."""
    batch_set(stepping.advance, euler_step, 0.0, WHOLE, 0, arguments)


@kernel(SOURCES)
def set_rk4(*arguments: Any) -> None:
    """:func:`batch_set` with classical RK4 over the one set of a run (as :func:`set_euler`)."""
    batch_set(stepping.advance, rk4_step, 0.0, BASE, 0, arguments)


@kernel(SOURCES)
def set_rk4_elements(*arguments: Any) -> None:
    """:func:`set_rk4` of the whole state."""
    batch_set(stepping.advance, rk4_step, 0.0, WHOLE, 0, arguments)


#: The entry points by method and whether the model elements' states are stepped (accelerate
#: picks them): stepping, outputs and what a state publishes, and the run of a batch (one set
#: per thread, or blocks in lock-step) or of one set in the calling thread (explicit methods only).
STEPS = {
    ("euler", False): steps_euler,
    ("euler", True): steps_euler_elements,
    ("rk4", False): steps_rk4,
    ("rk4", True): steps_rk4_elements,
    ("ros2", False): steps_ros2,
    ("ros2", True): steps_ros2,
}
OUTPUTS = {False: outputs_of, True: outputs_of_elements}
PUBLISHED = {False: published_of, True: published_of_elements}
BATCHES = {
    ("euler", False): batch_euler,
    ("euler", True): batch_euler_elements,
    ("rk4", False): batch_rk4,
    ("rk4", True): batch_rk4_elements,
}
BLOCKS = {
    ("euler", False): blocks_euler,
    ("euler", True): blocks_euler_elements,
    ("rk4", False): blocks_rk4,
    ("rk4", True): blocks_rk4_elements,
}
SETS = {
    ("euler", False): set_euler,
    ("euler", True): set_euler_elements,
    ("rk4", False): set_rk4,
    ("rk4", True): set_rk4_elements,
}
