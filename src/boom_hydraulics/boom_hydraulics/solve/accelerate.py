"""Optional compilation of the scalar model with numba: the same source, compiled.

numba compiles the element functions exactly as they are written (their ``xp`` argument
defaults to :mod:`math`, which numba supports). Each function of the model's modules is
copied into one namespace per model in which every name refers to the compiled copy, so
compiled code calls compiled code; nothing is written twice. A test holds the compiled
and the interpreted trajectories equal.

Compiling takes a few seconds once per process (numba cannot cache these copies on disk,
as they do not live in a module), so callers compile only for long runs. Without numba,
or with ``BOOM_HYDRAULICS_JIT=0`` in the environment, :func:`stepper` returns None and
the interpreted path runs (about 20 times slower per step).
"""

from __future__ import annotations

import functools
import os
import types
from collections.abc import Callable
from typing import Any

import numpy as np

from ..model import MODELS, end_stops, friction, geometry, hydraulics, mechanics
from . import integrators, stepping

try:  # numba is optional: the interpreted path gives the same results
    import numba
except ImportError:  # pragma: no cover - exercised on machines without numba
    numba = None

_ELEMENTS = (geometry, hydraulics, friction, end_stops, mechanics, integrators, stepping)
_STEPS = {name: method.step.__name__ for name, method in integrators.METHODS.items() if method.step is not None}


def available() -> bool:
    """True when numba is installed and not switched off by BOOM_HYDRAULICS_JIT=0."""
    return numba is not None and os.environ.get("BOOM_HYDRAULICS_JIT", "1") != "0"


def _compiled_namespace(model: types.ModuleType) -> dict[str, Any]:
    """Every function of the elements and ``model``, compiled, in one shared namespace."""
    namespace: dict[str, Any] = {}
    modules = (*_ELEMENTS, model)
    for module in modules:
        namespace.update({k: v for k, v in vars(module).items() if not k.startswith("__")})
    for module in modules:
        for name, obj in vars(module).items():
            if isinstance(obj, types.FunctionType) and obj.__module__ == module.__name__:
                copy = types.FunctionType(obj.__code__, namespace, name, obj.__defaults__, obj.__closure__)
                namespace[name] = numba.njit(copy)
    return namespace


@functools.cache
def stepper(mode: str, method: str) -> Callable[..., tuple[int, int, int, np.ndarray]] | None:
    """The compiled stepping loop (:func:`stepping.fixed_stepper`) of one model and method, or None.

    ``run(t, y, constants, u, dt, min_substeps, limit, max_substeps, n, energy_index,
    energy_base) -> (steps taken, outcome, most substeps, y)`` with ``y`` a numpy array.
    """
    if not available() or method not in _STEPS:
        return None
    namespace = _compiled_namespace(MODELS[mode])
    loop = numba.njit(
        stepping.fixed_stepper(
            namespace[_STEPS[method]],
            namespace["derivative"],
            namespace["stiffness_rate"],
            namespace["energy"],
            namespace["balance_broken"],
        )
    )

    @numba.njit
    def run(t: float, y0: np.ndarray, c: Any, u: float, dt: float, *rest: Any) -> tuple:
        done, outcome, most, y = loop(t, [v for v in y0], c, u, dt, *rest)
        return done, outcome, most, np.array(y)

    return run
