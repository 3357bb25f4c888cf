"""A whole run of one parameter set in one call: stepping, valve command and metrics together.

:func:`set_runner` builds ``run_set``, which integrates one parameter set from rest over
``n_steps`` time steps, with its valve command evaluated inside (an open-loop profile of
:mod:`profiles`, or the closed-loop position controller following setpoint knots), and takes
every ``every``-th sample into the streaming metrics (:mod:`..analysis.streaming`) and,
when asked, into a table of every output. It is written in the subset of Python that numba
compiles: :mod:`accelerate` compiles it with the model inlined and runs it over the sets of
a batch in parallel (``prange``), so that a run costs its steps and no Python per step.

The step, the command and the samples are those of :meth:`simulation.Simulator.run`: the
command of a step is taken at its middle from the state at its start and held over it, the
stepping loop is :func:`stepping.fixed_stepper`'s, and a step that fails (non-finite, energy
balance, too stiff, or the rod out of the geometry of eq. 1) is not taken and ends the run.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

from ..analysis.streaming import SAMPLE_SIGNALS, add_sample
from ..model.control import ControlState, Gains, position_command
from ..model.geometry import within_triangle
from ..model.setpoints import setpoint_at
from .outputs import OUTPUT_NAMES
from .profiles import ANGLE, profile_value
from .stepping import NONFINITE, OK, TOO_STIFF

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


def command_value(profile: tuple, path: tuple, control: Any, c: Any, q1_m: float, dt_s: float, t_s: float) -> float:
    """The valve command of the step whose middle is ``t_s``: the open-loop ``profile``
    (kind, times_s, values, offset, amplitude, frequency_hz; see profiles.profile_value), or
    for kind ANGLE the position controller following ``path`` from cylinder length ``q1_m``
    (see controller_value); the controller's state (integral, holding) moves on in ``control``."""
    kind, times_s, values, offset, amplitude, frequency_hz = profile
    if kind != ANGLE:
        return profile_value(kind, times_s, values, offset, amplitude, frequency_hz, t_s)
    return controller_value(path, control, c, q1_m, dt_s, t_s)


def controller_value(path: tuple, control: Any, c: Any, q1_m: float, dt_s: float, t_s: float) -> float:
    """The position controller's command following ``path`` = (knot times s, angles rad,
    rates rad/s, order, gains kp ki deadband lower_limit). Physical mode only: the compiled
    paper model, whose valve only lifts, has a stand-in returning 0."""
    knots_s, knots_rad, knot_rates, order, gains = path
    ref, rate = setpoint_at(knots_s, knots_rad, knot_rates, order, t_s)
    g = Gains(gains[0], gains[1], gains[2], gains[3])
    u, state = position_command(g, ControlState(control[0], control[1]), q1_m, c, ref, rate, dt_s)
    control[0] = state.integral
    control[1] = state.holding
    return u


def set_runner(_loop: Callable[..., tuple], observe_values: Callable[..., tuple]) -> Callable[..., int]:
    """``run_set`` of one model and method: ``_loop`` is its :func:`stepping.fixed_stepper`,
    ``observe_values(t, y, c, u)`` its outputs as a tuple of floats in the order of
    simulation.OUTPUT_NAMES.

    ``run_set(c, y, profile, path, dt, min_substeps, limit, max_substeps, n_steps, every,
    energy_index, energy_base, settings, metrics, rows, status, first, last)`` runs the set with
    constants ``c`` from rest for ``n_steps`` steps of ``dt``, with the valve command of
    ``profile`` and ``path`` (see command_value), taking a sample at the start, every
    ``every`` steps and at the end, until a failure. One call does the loop's passes ``first``
    to ``last`` - 1 of 0 ... ``n_steps`` (pass 0 the start, pass i the i-th step): a run is
    one call over (0, n_steps + 1) or several over consecutive slices, with the same result
    bit for bit, so that a caller can return to Python between slices (Ctrl-C, progress,
    streaming the rows out). ``y`` holds the state (the initial state before pass 0, then
    the state after the last pass done, or the last good one), ``status`` the rest of what a
    run carries (the slots above). Each sample goes into the streaming ``metrics``
    accumulator (with its ``settings``) and, where ``rows`` has rows, into ``rows`` from row
    0 at each call. Returns the number of samples this call took.
    """

    def run_set(
        c: Any,
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
        y = [v for v in y0]
        control = status[INTEGRAL : HOLDING + 1]
        half = 0.5 * dt
        store = rows.shape[0] > 0
        t = 0.0
        if first == 0:
            status[FAILED_AT], status[OUTCOME], status[MOST], status[LAST_Q1] = math.nan, OK, min_substeps, y[0]
            status[TAKEN], status[FAILED_STEP] = 0.0, -1.0
            control[0], control[1] = 0.0, 0.0
            status[NEXT_U] = command_value(profile, path, control, c, y[0], dt, t + half)
        elif status[OUTCOME] != OK:
            return 0
        u = status[NEXT_U]
        base = int(status[TAKEN])
        taken = base
        for i in range(first, last):
            if i > 0:
                t_start = (i - 1) * dt
                _, outcome, most, y_new = _loop(
                    t_start, y, c, u, dt, min_substeps, limit, max_substeps, 1, energy_index, energy_base
                )
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
                u = command_value(profile, path, control, c, y[0], dt, t + half)
            if i % every == 0 or i == n_steps:
                o = observe_values(t, y, c, u)
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

    return run_set
