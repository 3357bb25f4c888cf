"""The compiled kernels of each model and method, where numba is available.

Each model has an explicit kernel module (:mod:`physical_kernel`, :mod:`paper_kernel`):
ordinary code that numba compiles as written, calling the model's and the method's
functions by name. This module picks the entry point of a model and method; it is None
without numba, with ``BOOM_HYDRAULICS_JIT=0`` in the environment (see :mod:`..jit`), or for
a method without a fixed step (rk45), and then the interpreted path runs the same functions.
The first compile takes a few seconds; a later process loads from the cache (:func:`..jit.cache_folder`).

The physical model's entry points come in two layouts of its state: without the model
elements' states (an accumulator, hoses, an elastic boom), which stand still where all three
are off, and the whole state (``elements``: :func:`with_elements` of the run's parameters).
Each compiles where a run first calls it, so that elements off cost neither steps nor compiling.
"""

from __future__ import annotations

import types
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from .. import jit
from ..model import physical
from ..model.parameters import Parameters
from . import lanes, paper_kernel, physical_kernel

#: The kernel module of each model.
KERNELS: dict[str, types.ModuleType] = {"physical": physical_kernel, "paper": paper_kernel}


def available() -> bool:
    """True when numba is installed and not switched off by BOOM_HYDRAULICS_JIT=0."""
    return jit.available()


def with_elements(params: Sequence[Parameters]) -> bool:
    """Whether the kernels run ``params`` with the model elements' states: one of the sets has an
    element on (physical.element_states; the paper model has none)."""
    return any(p.mode == "physical" and bool(physical.element_states(p)) for p in params)


def stepper(mode: str, method: str, elements: bool = False) -> Callable[..., tuple[int, int, int, np.ndarray]] | None:
    """The compiled stepping loop (:func:`stepping.advance`) of one model and method, with or
    without the model elements' states (``elements``: :func:`with_elements`), or None.

    ``run(t, y, constants, u, dt, min_substeps, limit, max_substeps, n, energy_index,
    energy_base) -> (steps taken, outcome, most substeps, y)`` with ``y`` (the whole state: the
    elements' states as they are where they are left out) and ``constants`` (the model's
    Constants in order) numpy arrays.
    """
    if not available():
        return None
    return KERNELS[mode].STEPS.get((method, elements))


def observer(mode: str, method: str, elements: bool = False) -> Callable[..., tuple] | None:
    """The compiled outputs of one model: ``outputs_of(t, y, constants, u)`` -> a tuple of
    floats in the order of OUTPUT_NAMES (flags 0.0 or 1.0), ``y`` and ``constants`` numpy
    arrays (as for :func:`stepper`); or None."""
    if stepper(mode, method, elements) is None:
        return None
    return KERNELS[mode].OUTPUTS[elements]


def publisher(mode: str, method: str, elements: bool = False) -> Callable[..., np.ndarray] | None:
    """What a state of one model publishes, compiled: ``published_of(t, y, constants, u)`` ->
    an array in the order of outputs.PUBLISHED_NAMES (``y`` and ``constants`` as for
    :func:`stepper`); or None."""
    if stepper(mode, method, elements) is None:
        return None
    return KERNELS[mode].PUBLISHED[elements]


def batch_runner(mode: str, method: str, sets: int = 1, elements: bool = False) -> Callable[..., None] | None:
    """The compiled parallel run kernel (kernel.batch_set over the sets of a batch) of one
    model and method for ``sets`` parameter sets, with or without the model elements' states
    (``elements``: :func:`with_elements`), or None: ``run(states, status, metrics, rows, taken,
    first, last, *kernel.flat(spec))`` (see kernel.batch_set and batch.SetRun). From
    lanes.WIDTH sets on, the kernel that runs them in blocks in lock-step on the vector units,
    where the model has one (the same results, see :mod:`lanes`); fewer sets, one per thread."""
    if not available():
        return None
    if sets >= lanes.WIDTH and (method, elements) in KERNELS[mode].BLOCKS:
        return KERNELS[mode].BLOCKS[(method, elements)]
    return KERNELS[mode].BATCHES.get((method, elements))


def run_kernels(mode: str, method: str, sets: int = 1, elements: bool = False) -> list[Callable[..., Any]]:
    """The compiled code a whole run of ``sets`` parameter sets of ``mode`` and ``method``
    calls (batch.SetRun): its run kernel (:func:`batch_runner`) or, for a method the run loop
    does not compile, the compiled steps its interpreted loop calls; none without numba."""
    run = batch_runner(mode, method, sets, elements)
    steps = stepper(mode, method, elements) if run is None else None
    return [k for k in (run, steps) if k is not None]


def not_in_cache(kernels: Sequence[Callable[..., Any] | None]) -> bool:
    """Whether numba's cache lacks one of ``kernels`` (jit.in_cache): its first call compiles."""
    return any(jit.in_cache(k) is False for k in kernels if k is not None)


def compiling_notice(mode: str, method: str, work: str) -> str:
    """What a program says where ``work`` (this run, its batches, this start) first compiles
    the model, ``mode`` and ``method``, because numba's cache does not hold it yet."""
    return (
        f"the {mode} model's {method} is not compiled on this machine yet: compiling it for {work} takes "
        "tens of seconds, minutes on a busy machine (once: later runs load it)"
    )


def set_runner(mode: str, method: str, elements: bool = False) -> Callable[..., None] | None:
    """The compiled run kernel of one set (kernel.batch_set of set 0, in the calling thread) of
    one model and method, with or without the model elements' states, or None: called as
    :func:`batch_runner`'s kernel with one set."""
    if not available():
        return None
    return KERNELS[mode].SETS.get((method, elements))
