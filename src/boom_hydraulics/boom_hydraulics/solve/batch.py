"""Many parameter sets integrated together, vectorised over the batch with numpy.

The model and integrator functions are the same as for one simulation: a state
component is an array with one entry per parameter set, the constants are arrays, and
``xp=numpy``. All sets of a batch share mode, method (euler or rk4), time step and
substeps; everything else (piston diameter, payload, bulk modulus, ...) may differ.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from ..errors import ConfigError
from ..model import MODELS
from ..model.parameters import Parameters
from . import integrators
from .integrators import FIXED_STEP
from .simulation import OUTPUT_NAMES

SHARED = ("mode", "method", "time_step_s", "substeps")


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
    if first.method not in FIXED_STEP:
        raise ConfigError(f"batches integrate with a fixed-step method (euler or rk4), not {first.method!r}")


def simulate_batch(
    params: Sequence[Parameters],
    duration_s: float,
    command: Callable[[float], float | np.ndarray],
    every: int = 1,
    outputs: Sequence[str] = OUTPUT_NAMES,
) -> dict[str, np.ndarray]:
    """Integrate every parameter set over ``duration_s`` with the valve command ``command(t)``.

    Returns each of ``outputs`` (names of :data:`simulation.OUTPUT_NAMES`) as an array of
    shape (samples, sets), sampled at the start and every ``every`` steps. A set whose
    state turns non-finite is frozen at its last finite state from then on and reported
    in ``failed_at_s`` (NaN where the set ran through).
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
    dt, substeps = params[0].time_step_s, params[0].substeps
    step = integrators.rk4_step if params[0].method == "rk4" else integrators.euler_step
    failed_at = np.full(n_sets, np.nan)
    n_steps = round(duration_s / dt)
    n_rows = 1 + n_steps // every + (1 if n_steps % every else 0)
    t = 0.0
    half = 0.5 * dt  # the command of a step is taken at its middle, as in Simulator.run
    first = model.observe(t, y, c, _as_array(command(t + half), n_sets), np)
    columns = {name: np.empty((n_rows, n_sets), dtype=np.asarray(first[name]).dtype) for name in outputs}

    def record(row: int, values: dict) -> None:
        for name in outputs:
            columns[name][row] = values[name]

    record(0, first)
    row = 1
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        for i in range(1, n_steps + 1):
            u = _as_array(command(t + half), n_sets)
            y_new = y
            h = dt / substeps
            for j in range(substeps):
                y_new = step(model.derivative, t + j * h, y_new, h, (c, u, np))
            y_new = model.project(y_new, c)
            ok = np.logical_and.reduce([np.isfinite(v) for v in y_new])
            if not ok.all():
                newly = ~ok & np.isnan(failed_at)
                failed_at[newly] = t + dt
                y = [np.where(ok, new, old) for new, old in zip(y_new, y)]
            else:
                y = y_new
            t = i * dt
            if i % every == 0 or i == n_steps:
                record(row, model.observe(t, y, c, _as_array(command(t + half), n_sets), np))
                row += 1
    out = dict(columns)
    out["failed_at_s"] = failed_at
    return out


def _as_array(u: float | np.ndarray, n: int) -> np.ndarray:
    return np.broadcast_to(np.asarray(u, dtype=float), (n,))
