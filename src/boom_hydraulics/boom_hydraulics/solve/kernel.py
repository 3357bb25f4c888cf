"""A whole run of one parameter set in one call: stepping, valve command and metrics together.

:func:`run_set` integrates one parameter set from rest over
``n_steps`` time steps, with its valve command evaluated inside (an open-loop profile of
:mod:`profiles`, or the closed-loop position controller following setpoint knots), and takes
every ``every``-th sample into the streaming metrics (:mod:`streaming`) and, when asked,
into a table of every output. It is written in the subset of Python that numba compiles,
and takes the model's and the method's functions as arguments: each model's kernel module
(:mod:`physical_kernel`, :mod:`paper_kernel`) calls it with them by name and runs it over
the sets of a batch in parallel (``prange``), so that a run costs its steps and no Python
per step; numba compiles the functions into it.

The step, the command and the samples are those of :meth:`simulation.Simulator.run`: the
command of a step is taken at its middle from the state at its start and held over it, the
stepping loop is :func:`stepping.advance`, and a step that fails (non-finite, energy
balance, too stiff, or the rod out of the geometry of eq. 1) is not taken and ends the run.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

from ..jit import jitable
from ..model.control import ControlState, Gains, position_command
from ..model.geometry import within_triangle
from ..model.setpoints import setpoint_at
from .outputs import OUTPUT_NAMES
from .profiles import ANGLE, profile_value
from .stepping import NONFINITE, OK, TOO_STIFF, advance
from .streaming import SAMPLE_SIGNALS, add_sample

#: Where run_set keeps a run between calls (status[k] of a batch): the time it failed (NaN:
#: it ran through), the stepping outcome (stepping.OK, NONFINITE, ENERGY or TOO_STIFF), the
#: most substeps one step took (on TOO_STIFF: the number the failing step would have needed),
#: the cylinder length at the end (or at the last good state), m; then what a run carries from
#: one slice of steps to the next: the controller's integral and holding flag, the command of
#: the next step, the samples taken so far, and on a failure the index of the failed step.
FAILED_AT, OUTCOME, MOST, LAST_Q1, INTEGRAL, HOLDING, NEXT_U, TAKEN, FAILED_STEP = range(9)
STATUS_SIZE = 9
#: Where the signals of the streaming metrics are among the outputs, in add_sample's order.
SAMPLED = tuple(OUTPUT_NAMES.index(name) for name in SAMPLE_SIGNALS)


@jitable
def command_value(
    controller: Callable[..., float], profile: tuple, path: tuple, control: Any, c: Any, q1_m: float, dt_s: float,
    t_s: float,
) -> float:  # fmt: skip
    """The valve command of the step whose middle is ``t_s``: the open-loop ``profile``
    (kind, times_s, values, offset, amplitude, frequency_hz; see profiles.profile_value), or
    for kind ANGLE the model's ``controller`` (:func:`controller_value`, or
    :func:`no_controller`) following ``path`` from cylinder length ``q1_m``; the controller's
    state (integral, holding) moves on in ``control``."""
    kind, times_s, values, offset, amplitude, frequency_hz = profile
    if kind != ANGLE:
        return profile_value(kind, times_s, values, offset, amplitude, frequency_hz, t_s)
    return controller(path, control, c, q1_m, dt_s, t_s)


@jitable
def controller_value(path: tuple, control: Any, c: Any, q1_m: float, dt_s: float, t_s: float) -> float:
    """The position controller's command following ``path`` = (knot times s, angles rad,
    rates rad/s, order, gains kp ki deadband lower_limit). Physical mode only."""
    knots_s, knots_rad, knot_rates, order, gains = path
    ref, rate = setpoint_at(knots_s, knots_rad, knot_rates, order, t_s)
    g = Gains(gains[0], gains[1], gains[2], gains[3])
    u, state = position_command(g, ControlState(control[0], control[1]), q1_m, c, ref, rate, dt_s)
    control[0] = state.integral
    control[1] = state.holding
    return u


@jitable
def no_controller(path: tuple, control: Any, c: Any, q1_m: float, dt_s: float, t_s: float) -> float:
    """The paper model's controller: none (its Constants have none of what the controller
    reads, its valve only lifts, and closed_loop.PositionLoop refuses paper mode): 0."""
    return 0.0


@jitable
def run_set(
    step: Callable[..., Any],
    derivative: Callable[..., Any],
    stiffness_rate: Callable[..., float],
    energy: Callable[..., float],
    outputs: Callable[..., tuple],
    controller: Callable[..., float],
    store: bool,
    c: Any,
    y: Any,
    y0: Any,
    profile: tuple,
    path: tuple,
    dt: float,
    min_substeps: int,
    limit: float,
    max_substeps: int,
    n_steps: int,
    every: int,
    energy_index: int,
    energy_base: float,
    settings: Any,
    metrics: Any,
    rows: Any,
    status: Any,
    first: int,
    last: int,
) -> int:
    """Run one set with the method's ``step`` on the model's ``derivative``, ``stiffness_rate``,
    ``energy``, ``outputs`` (a tuple of floats in the order of OUTPUT_NAMES) and
    ``controller`` (see command_value); ``store``: whether the samples go into ``rows`` (a
    constant in each call of :func:`batch_set`, so that the compiler may leave the outputs
    the metrics do not take uncomputed).

    The set has constants ``c`` and runs from rest for ``n_steps`` steps of ``dt``, with the
    valve command of ``profile`` and ``path`` (see command_value), taking a sample at the
    start, every ``every`` steps and at the end, until a failure. One call does the loop's
    passes ``first`` to ``last`` - 1 of 0 ... ``n_steps`` (pass 0 the start, pass i the i-th
    step): a run is one call over (0, n_steps + 1) or several over consecutive slices, with
    the same result bit for bit, so that a caller can return to Python between slices
    (Ctrl-C, progress, streaming the rows out). ``y0`` holds the state (the initial state
    before pass 0, then the state after the last pass done, or the last good one) and ``y``
    the same as the kernel's state (a tuple or list), ``status`` the rest of what a run
    carries (the slots above). Each sample goes into the streaming ``metrics`` accumulator
    (with its ``settings``) and, with ``store``, into ``rows`` from row 0 at each call.
    Returns the number of samples this call took.
    """
    control = status[INTEGRAL : HOLDING + 1]
    half = 0.5 * dt
    t = 0.0
    if first == 0:
        status[FAILED_AT], status[OUTCOME], status[MOST], status[LAST_Q1] = math.nan, OK, min_substeps, y[0]
        status[TAKEN], status[FAILED_STEP] = 0.0, -1.0
        control[0], control[1] = 0.0, 0.0
        status[NEXT_U] = command_value(controller, profile, path, control, c, y[0], dt, t + half)
    elif status[OUTCOME] != OK:
        return 0
    u = status[NEXT_U]
    base = int(status[TAKEN])
    taken = base
    for i in range(first, last):
        if i > 0:
            t_start = (i - 1) * dt
            _, outcome, most, y_new = advance(
                step, derivative, stiffness_rate, energy, t_start, y, c, u, dt, min_substeps, limit, max_substeps, 1,
                energy_index, energy_base,
            )  # fmt: skip
            if outcome == OK and not within_triangle(y_new[0], c.a, c.b):
                outcome = NONFINITE  # the rod left the geometry: the model cannot go on
            status[LAST_Q1] = y[0]
            if outcome != OK:
                status[FAILED_AT] = t_start if outcome == TOO_STIFF else t_start + dt
                status[OUTCOME] = outcome
                status[MOST] = most if outcome == TOO_STIFF else status[MOST]
                status[FAILED_STEP] = i - 1
                break
            status[MOST] = max(status[MOST], most)
            y = y_new
            t = i * dt
            u = command_value(controller, profile, path, control, c, y[0], dt, t + half)
        if i % every == 0 or i == n_steps:
            o = outputs(t, y, c, u)
            add_sample(
                metrics, settings, o[SAMPLED[0]], o[SAMPLED[1]], o[SAMPLED[2]], o[SAMPLED[3]], o[SAMPLED[4]],
                o[SAMPLED[5]], o[SAMPLED[6]], o[SAMPLED[7]], o[SAMPLED[8]], o[SAMPLED[9]], o[SAMPLED[10]],
            )  # fmt: skip
            if store:
                for j in range(len(o)):
                    rows[taken - base, j] = o[j]
            taken += 1
    if status[OUTCOME] == OK:
        status[LAST_Q1] = y[0]
    for j in range(len(y0)):
        y0[j] = y[j]
    status[NEXT_U] = u
    status[TAKEN] = taken
    return taken - base


@jitable
def batch_set(
    step: Callable[..., Any],
    derivative: Callable[..., Any],
    stiffness_rate: Callable[..., float],
    energy: Callable[..., float],
    outputs: Callable[..., tuple],
    controller: Callable[..., float],
    constants_of: Callable[..., Any],
    state_of: Callable[..., Any],
    k: int,
    C: Any, Y: Any, kind: int, times_s: Any, values: Any, offset: float, amplitude: float, frequency_hz: float,
    KT: Any, KA: Any, KR: Any, order: int, G: Any, dt: float, min_substeps: int, limit: float, max_substeps: int,
    n_steps: int, every: int, energy_index: int, EB: Any, S: Any, M: Any, ROWS: Any, STATUS: Any, TAKEN: Any,
    first: int, last: int,
) -> None:  # fmt: skip
    """:func:`run_set` of set ``k`` of a batch, over its passes ``first`` ... ``last`` - 1 (see
    batch.run_sets for the arguments after ``k``): the model's constants from the row ``C[k]``
    (``constants_of``), its state from ``Y[k]`` (``state_of``, as the step keeps it)."""
    profile = (kind, times_s, values, offset, amplitude, frequency_hz)
    path = (KT[k], KA[k], KR[k], order, G[k])
    c = constants_of(C[k])
    y = state_of(Y[k])
    if ROWS.shape[1] > 0:  # each call with its own constant store
        TAKEN[k] = run_set(
            step, derivative, stiffness_rate, energy, outputs, controller, True, c, y, Y[k], profile, path, dt,
            min_substeps, limit, max_substeps, n_steps, every, energy_index, EB[k], S[k], M[k], ROWS[k], STATUS[k],
            first, last,
        )  # fmt: skip
    else:
        TAKEN[k] = run_set(
            step, derivative, stiffness_rate, energy, outputs, controller, False, c, y, Y[k], profile, path, dt,
            min_substeps, limit, max_substeps, n_steps, every, energy_index, EB[k], S[k], M[k], ROWS[k], STATUS[k],
            first, last,
        )  # fmt: skip
