"""The fixed-step loop: stability-bound substeps and the energy-balance guard.

:func:`advance` takes ``n`` time steps of ``dt`` with a fixed-step method.
Before each step it asks the model for its fastest rate (``stiffness_rate``) and splits the
step into as many substeps as the method's stability limit needs (at least ``min_substeps``),
so that ``dt`` stays the output and command step whatever the parameters. After each step it
checks that the state is finite and that the stored energy changed by what the model says
flowed (the energy balance); a step that fails either is not taken.

It is written in the subset of Python that numba compiles, so the interpreted and the
compiled paths (the kernel modules, :mod:`physical_kernel` and :mod:`paper_kernel`) run this
same code. :func:`advance_lanes` takes the same step for a block of sets in lock-step
(:mod:`lanes`), each set with its own substeps and outcome.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

from ..jit import jitable
from ..model.hydraulics import larger
from . import integrators, lanes

#: Outcomes of the stepping loop.
OK, NONFINITE, ENERGY, TOO_STIFF = 0, 1, 2, 3

#: A bound on dt x rate / limit past which a too stiff step reports MAX_SUBSTEPS + 1 substeps
#: (an integer count of its own would overflow; NaN has none).
BEYOND = 1e18

#: The most substeps advance_halving takes a failed step again in (1024: a step that 2047
#: substeps in all have not taken through is not a matter of its size; the stiff cycle with 1 cm³
#: dead volumes takes up to 256). A ros2 step of the physical model costs about 16 us compiled
#: and 1.5 ms interpreted, so giving up costs 0.03 s and 3 s.
HALVED_MOST = 1024

#: The energy balance may be off by this fraction of the energy that changed hands ...
ENERGY_TOLERANCE = 0.01
#: ... plus this much, J (so that a run at rest never trips on rounding).
ENERGY_SLACK_J = 1.0


@jitable
def balance_broken(stored_j: Any, flowed_j: Any, flowed_abs_j: Any, base_j: Any) -> Any:
    """True where the stored energy H no longer matches H0 + W (floats or arrays alike):
    |H - W - (H0 - W0)| > ENERGY_TOLERANCE |W| + ENERGY_SLACK_J."""
    return abs(stored_j - flowed_j - base_j) > ENERGY_TOLERANCE * flowed_abs_j + ENERGY_SLACK_J


@jitable
def advance(
    step: Callable[..., list],
    derivative: Callable[..., list],
    stiffness_rate: Callable[..., float],
    energy: Callable[..., float],
    t0: float,
    y: Any,
    c: Any,
    u: float,
    dt: float,
    min_substeps: int,
    limit: float,
    max_substeps: int,
    n: int,
    energy_index: int,
    energy_base: float,
) -> tuple[int, int, int, Any]:
    """Up to ``n`` steps of ``dt`` from ``y`` at ``t0`` with valve command ``u``, by the
    method's ``step`` on the model's ``derivative``, ``stiffness_rate`` and ``energy`` (compiled,
    these are the functions themselves, called by name: see the kernel modules).

    ``limit`` is the method's stability limit on dt * rate (0: no automatic substeps);
    ``energy_index`` the index of W in the state (-1: no energy check) and ``energy_base``
    the value of H - W that the balance keeps. Returns (steps taken, outcome, most
    substeps used in one step, state after the steps taken); on TOO_STIFF the third value
    is the number of substeps the step would have needed.
    """
    most = min_substeps
    for i in range(n):
        substeps = min_substeps
        if limit > 0.0:
            bound = dt * stiffness_rate(y, c, u, dt) / limit
            if not bound <= max_substeps:  # a rate of NaN too: no count of substeps is known stable
                return i, TOO_STIFF, math.ceil(bound) if bound < BEYOND else max_substeps + 1, y
            substeps = max(substeps, math.ceil(bound))
        most = max(most, substeps)
        h = dt / substeps
        t = t0 + i * dt
        y_new = y
        for j in range(substeps):
            y_new = step(derivative, t + j * h, y_new, h, (c, u))
        for value in y_new:
            if not math.isfinite(value):
                return i, NONFINITE, most, y
        if energy_index >= 0 and balance_broken(
            energy(y_new, c), y_new[energy_index], y_new[energy_index + 1], energy_base
        ):
            return i, ENERGY, most, y
        y = y_new
    return n, OK, most, y


@jitable
def advance_halving(
    step: Callable[..., list], derivative: Callable[..., list], stiffness_rate: Callable[..., float],
    energy: Callable[..., float], t0: float, y: Any, c: Any, u: float, dt: float, min_substeps: int, limit: float,
    max_substeps: int, n: int, energy_index: int, energy_base: float,
) -> tuple[int, int, int, Any]:  # fmt: skip
    """:func:`advance` for a method whose steps no stability bound sizes (ros2: L-stable, it has
    no limit to split a step by): a step that fails its checks (not finite, or the energy
    balance broken) is taken again from the same state in twice as many substeps, and again,
    up to HALVED_MOST (and ``max_substeps``), before the run stops on it. The arguments and
    results are :func:`advance`'s (on a failure, the most substeps are the most it tried); a
    run whose steps all pass is :func:`advance`'s to the bit. Neither model's derivative reads
    the time, which a retried step computes as the time of its step from ``t0`` again.

    A linearly implicit step sees the model through its Jacobian at the step's start: where
    a chamber's void fills within the step (its pressure leaves the cavitation floor, where
    the chamber's stiffness jumps from none to E / V), the step overshoots, and its energy
    balance shows it (docs/model.md, "Stepping").
    """
    done = 0
    most = min_substeps
    while done < n:
        taken, outcome, used, y = advance(
            step, derivative, stiffness_rate, energy, t0 + done * dt, y, c, u, dt, min_substeps, limit,
            max_substeps, n - done, energy_index, energy_base,
        )  # fmt: skip
        done += taken
        most = max(most, used)
        if outcome == OK:
            return done, OK, most, y
        if outcome != NONFINITE and outcome != ENERGY:
            return done, outcome, used, y
        for value in y:
            if not math.isfinite(value):  # no step size mends a state that is not finite
                return done, outcome, most, y
        substeps = 2 * max(min_substeps, 1)
        while True:
            if substeps > min(max_substeps, HALVED_MOST):
                return done, outcome, most, y
            most = max(most, substeps)
            taken, again, used, y_again = advance(
                step, derivative, stiffness_rate, energy, t0 + done * dt, y, c, u, dt, substeps, limit,
                max_substeps, 1, energy_index, energy_base,
            )  # fmt: skip
            if again == OK:
                done += 1
                y = y_again
                break
            if again != NONFINITE and again != ENERGY:
                return done, again, used, y
            outcome = again
            substeps *= 2
    return done, OK, most, y


def loop_of(method: str) -> Callable[..., tuple[int, int, int, Any]]:
    """The stepping loop of integration method ``method``: :func:`advance_halving` where the
    method halves a failed step (integrators.Method.halving), else :func:`advance`."""
    return advance_halving if integrators.METHODS[method].halving else advance


# inlined into the run loop, as kernel._commands is: a call takes the block's constants and state
# by value (inlined: 308 -> 291 ns per set-step of the lift's opening, one thread)
@jitable(inline="always")
def advance_lanes(
    step: Callable[..., Any], derivative: Callable[..., Any], stiffness_rate: Callable[..., Any],
    energy: Callable[..., Any], t0: float, y: Any, c: Any, u: Any, dt: float, min_substeps: int, limit: float,
    max_substeps: int, n: int, energy_index: int, energy_base: Any,
) -> tuple[int, Any, Any, Any]:  # fmt: skip
    """One step of :func:`advance` (``n`` is 1) for a block of sets in lock-step: ``y``, ``c``,
    ``u`` and ``energy_base`` hold a value per set (:mod:`lanes`). Each set takes its own
    substeps, as many as it would alone: the block runs the most any set needs, and a set's
    state stops moving once it has taken its own (so each set's result equals, to the bit, its
    own run). Returns (1, outcome per set, substeps per set (TOO_STIFF: as many as it would
    need), state); a set whose step failed keeps its state at ``y``. A set too stiff to step
    takes one substep meanwhile, so that it does not hold the others up."""
    one = y[0]  # the block's lanes
    substeps = lanes.spread(min_substeps, one)
    too_stiff = lanes.spread(0.0, one)
    if limit > 0.0:
        bound = dt * stiffness_rate(y, c, u, dt) / limit
        needed = math.ceil(bound)
        too_stiff = 1.0 - (bound <= max_substeps)  # a rate of NaN too, as in advance
        beyond = lanes.spread(max_substeps + 1.0, one)
        substeps = lanes.choose(too_stiff, lanes.choose(bound < BEYOND, needed, beyond), larger(substeps, needed))
    taken = lanes.choose(too_stiff, lanes.spread(1.0, one), substeps)
    h = dt / taken
    y_new = y
    for j in range(int(lanes.most(taken))):
        y_new = lanes.choose(j < taken, step(derivative, t0 + j * h, y_new, h, (c, u)), y_new)
    finite = lanes.spread(1.0, one)
    for value in y_new:
        finite = finite * math.isfinite(value)
    outcome = lanes.choose(finite, lanes.spread(float(OK), one), lanes.spread(float(NONFINITE), one))
    if energy_index >= 0:
        broken = balance_broken(energy(y_new, c), y_new[energy_index], y_new[energy_index + 1], energy_base)
        outcome = lanes.choose(finite * broken, lanes.spread(float(ENERGY), one), outcome)
    outcome = lanes.choose(too_stiff, lanes.spread(float(TOO_STIFF), one), outcome)
    return 1, outcome, substeps, lanes.choose(outcome == OK, y_new, y)
