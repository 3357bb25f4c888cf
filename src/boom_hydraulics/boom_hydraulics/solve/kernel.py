"""The run loop: a whole run of one parameter set, stepping, valve command and samples together.

:func:`run_set` is the one run loop of the package. It integrates one parameter set for
``n_steps`` time steps of ``dt`` from a given state and time, with its valve command
evaluated inside (:func:`_commands`: an open-loop profile of :mod:`profiles`, or the
closed-loop position controller following setpoint knots, or for an interpreted run any
Python command), and takes a sample at the start, every ``every``-th step and at the end
into the streaming metrics (:mod:`streaming`) and, when asked, into a table of every output:

- the command of a step is taken at its middle from the state at its start and held over it;
- the step is :func:`stepping.advance` (stability-bound substeps, finiteness, energy balance);
- a step that fails (non-finite, energy balance, too stiff, or the rod out of the geometry of
  eq. 1: :mod:`outcomes`) is not taken and ends the run.

It is written in the subset of Python that numba compiles and takes the model's and the
method's functions as arguments. Compiled, each model's kernel module (:mod:`physical_kernel`,
:mod:`paper_kernel`) runs :func:`batch_set` over the sets of a batch in parallel (``prange``),
or over one set in the calling thread (physical_kernel.set_rk4: the node's position
controller, a tick at a time), with those functions by name, so that a run costs its steps and no Python per step.
The physical model's kernel also runs blocks of sets in lock-step on the vector units
(physical_kernel.blocks_rk4): the same loop, with the block's state and constants in
:mod:`lanes` and each set's bookkeeping apart, each set's results those of its run alone.
Interpreted, :mod:`batch` calls the same :func:`run_set` with the same functions uncompiled
(or with the compiled stepping under a Python command): whole runs of the Simulator,
:func:`simulation.simulate`, the batch and the sweep all run through it.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any, NamedTuple

from .. import jit
from ..jit import jitable
from ..model import setpoints
from ..model.control import ControlState, Gains, position_command
from ..model.geometry import within_triangle
from ..model.setpoints import last_at_or_before
from . import lanes
from .outcomes import OK, OUT_OF_GEOMETRY, TOO_STIFF
from .profiles import ANGLE, profile_value
from .streaming import add_sample


class Command(NamedTuple):
    """A valve command as the run loop evaluates it for the sets of a run (see
    :func:`_commands`); each command class gives its own (``kernel_command``)."""

    kind: int  # profiles.CONSTANT, STEPS, RAMP, SINE; ANGLE: the controller
    times_s: Any  # the profile's times and values (profiles.profile_value), shared by the sets
    values: Any
    offset: float
    amplitude: float
    frequency_hz: float
    knot_times_s: Any  # kind ANGLE: each set's setpoint knots (sets x knots), s, rad, rad/s ...
    knot_angles_rad: Any
    knot_rates_rad_s: Any
    order: int  # ... joined linearly or by Hermite segments (model.setpoints)
    gains: Any  # ... and each set's controller gains (sets x 4): kp, ki, deadband, lower_limit


class RunSpec(NamedTuple):
    """What a run of a batch of sets reads and keeps from slice to slice (one per run)."""

    constants: Any  # each set's model Constants as a row of floats (sets x fields)
    command: Command
    dt_s: float  # the time step, s
    min_substeps: int
    limit: float  # the method's stability limit on dt x rate (0: no automatic substeps)
    max_substeps: int
    n_steps: int
    every: int  # a sample every ``every`` steps (and at the start and the end)
    energy_index: int  # the index of W in the state (-1: no energy balance)
    energy_base: Any  # per set: the value of H - W that the balance keeps, J
    settings: Any  # per set: the streaming metrics' settings (streaming.settings)
    measure: bool  # whether the samples go into the streaming metrics
    t0_s: float  # the time of step k0 of the run's time line, s: step i ends at t0_s + (k0 + i) dt
    k0: int
    payload_times_s: Any  # when the payload on the hook changes, s (empty: it does not)
    payload_shares: Any  # from each of those times on, the share of the sets' payload on the hook


#: Where run_set keeps a run between calls (status[k] of a batch): the time it failed (NaN:
#: it ran through), the outcome (outcomes.OK or a failure), the most substeps one step took
#: (on TOO_STIFF: the number the failing step would have needed), the command of the last
#: step taken; then what a run carries from one slice of steps to the next: the controller's
#: integral and holding flag, the command of the next step, the samples taken so far, and on
#: a failure the index of the failed step (the steps taken before it); the payload's share on
#: the hook, and how far its changes moved the energy balance's H - W (J).
FAILED_AT, OUTCOME, MOST, APPLIED_U, INTEGRAL, HOLDING, NEXT_U, TAKEN, FAILED_STEP = range(9)
PAYLOAD, BASE_SHIFT = 9, 10
STATUS_SIZE = 11


@jitable
def controller_value(
    command: Command, k: int, running: Any, status: Any, c: Any, y: Any, u: Any, dt_s: float, t_s: float
) -> Any:
    """The position controller's commands for the step whose middle is ``t_s``, following each
    set's knots of ``command`` (sets ``k`` ...) from its cylinder length y[0]
    (model.control.position_command, for a block of sets at once: :mod:`lanes`), in ``u``'s
    lanes where the set runs on (``running``); each set's controller state (integral, holding)
    moves on in its row of ``status``. Physical mode only."""
    zero = lanes.spread(0.0, u)
    kp, ki, deadband, lower, integral, holding = zero, zero, zero, zero, zero, zero
    # each set's setpoint (model.setpoints.setpoint_at): where it is on its knots, set by set;
    # the segments' polynomials on the block at once (a part block's spare lanes: a finite span)
    at_rest, held, w, span, a0, a1, r0, r1 = zero, zero, zero, lanes.spread(1.0, u), zero, zero, zero, zero
    for j in range(len(status)):
        knot = setpoints.segment_at(
            command.knot_times_s[k + j], command.knot_angles_rad[k + j], command.knot_rates_rad_s[k + j], t_s
        )
        at_rest, held = lanes.with_lane(at_rest, j, 1.0 * knot[0]), lanes.with_lane(held, j, float(knot[1]))
        w, span = lanes.with_lane(w, j, float(knot[2])), lanes.with_lane(span, j, float(knot[3]))
        a0, a1 = lanes.with_lane(a0, j, float(knot[4])), lanes.with_lane(a1, j, float(knot[5]))
        r0, r1 = lanes.with_lane(r0, j, float(knot[6])), lanes.with_lane(r1, j, float(knot[7]))
        g = command.gains[k + j]  # interpreted, floats: a numpy scalar would spread through the state
        kp, ki = lanes.with_lane(kp, j, float(g[0])), lanes.with_lane(ki, j, float(g[1]))
        deadband, lower = lanes.with_lane(deadband, j, float(g[2])), lanes.with_lane(lower, j, float(g[3]))
        integral = lanes.with_lane(integral, j, float(status[j, INTEGRAL]))
        holding = lanes.with_lane(holding, j, float(status[j, HOLDING]))
    ref, rate = setpoints.segment(command.order, w, span, a0, a1, r0, r1)
    ref, rate = lanes.choose(at_rest, held, ref), lanes.choose(at_rest, zero, rate)
    gains, state = Gains(kp, ki, deadband, lower), ControlState(integral, holding)
    command_u, state = position_command(gains, state, y[0], c, ref, rate, dt_s)
    for j in range(len(status)):
        if lanes.lane(running, j) != 0.0:
            status[j, INTEGRAL] = lanes.lane(state.integral, j)
            status[j, HOLDING] = lanes.lane(state.holding, j)
    return lanes.choose(running, command_u, u)


@jitable
def no_controller(
    command: Command, k: int, running: Any, status: Any, c: Any, y: Any, u: Any, dt_s: float, t_s: float
) -> Any:
    """The paper model's controller: none (its Constants have none of what the controller
    reads, its valve only lifts, and closed_loop.PositionLoop refuses paper mode): 0."""
    return lanes.choose(running, lanes.spread(0.0, u), u)


@jitable
def payload_share(times_s: Any, shares: Any, t_s: float) -> float:
    """The share of the payload on the hook at ``t_s``: ``shares[i]`` from ``times_s[i]`` on,
    all of it (1) before the first time."""
    i = last_at_or_before(times_s, t_s)
    return shares[i] if i >= 0 else 1.0


@jitable
def run_set(
    step_once: Callable[..., Any],
    step: Callable[..., Any],
    derivative: Callable[..., Any],
    stiffness_rate: Callable[..., float],
    energy: Callable[..., float],
    outputs: Callable[..., tuple],
    samples: Callable[..., tuple],
    controller: Callable[..., float],
    with_payload: Callable[..., Any],
    store: bool,
    c: Any,
    y: Any,
    spec: RunSpec,
    k: int,
    state: Any,
    status: Any,
    metrics: Any,
    rows: Any,
    taken: Any,
    first: int,
    last: int,
) -> None:
    """Run the sets ``k`` ... ``k`` + len(state) - 1 of ``spec`` (one set, or a block of sets in
    lock-step, whose constants ``c`` and state ``y`` hold a value per set: :mod:`lanes`) with
    ``step_once`` (:func:`stepping.advance`; for a block :func:`stepping.advance_lanes`;
    interpreted, a function of its arguments that steps otherwise) taking the method's ``step``
    on the model's ``derivative``, ``stiffness_rate`` and ``energy``; at each sample the
    model's ``samples`` (the outputs the metrics take) go into the metrics, and with ``store``
    (a constant in each call of :func:`batch_set`) all its ``outputs`` (a tuple of floats in the
    order of OUTPUT_NAMES) into ``rows``: a run that keeps no table computes no other output
    (which the compiler did not leave out by itself: the batch kernel was 20 % slower with all
    of them); ``controller``: see :func:`_commands`.

    Each set runs for ``spec.n_steps`` steps from its state (``y``: as the kernel keeps it, a
    tuple or a list), taking a sample at the start, every ``spec.every`` steps and at the end,
    until a failure, which ends that set's run (a block goes on with the others, each set's
    results what it would be alone). One call does the loop's passes ``first`` to ``last`` - 1
    of 0 ... n_steps (pass 0 the start, pass i the i-th step): a run is one call over
    (0, n_steps + 1) or several over consecutive slices, with the same result bit for bit, so
    that a caller can return to Python between slices (Ctrl-C, progress, streaming the rows
    out). Per set, one row each: ``state`` holds the state after the last pass done (the last
    good one), ``status`` the rest of what a run carries (the slots above); each sample goes
    into the streaming ``metrics`` (with ``spec.measure``) and, with ``store``, into ``rows``
    from row 0 at each call; ``taken`` gets the number of samples this call took.
    """
    sets = len(state)
    dt = spec.dt_s
    half = 0.5 * dt
    t = spec.t0_s + spec.k0 * dt
    full = c  # the constants with the whole payload; c: with the share on the hook now
    changes = len(spec.payload_times_s) > 0
    u = lanes.spread(0.0, y[0])
    if first == 0:
        for j in range(sets):
            _begin(status[j], spec.min_substeps)
        if changes:  # the share on the hook at the start
            c = _payload_change(with_payload, energy, full, c, y, spec, status, t)
        u = _commands(controller, spec.command, k, lanes.spread(1.0, y[0]), status, c, y, u, dt, t + half)
    else:
        for j in range(sets):  # floats: interpreted, a numpy scalar would spread through the state
            u = lanes.with_lane(u, j, float(status[j, NEXT_U]))
        if changes:
            c = with_payload(full, float(status[0, PAYLOAD]))
    running = _running(status, y)
    leader = _leader(running)
    if leader >= 0:  # lanes that do not run (failed sets, a part block's spares) follow a set that does
        c, full = _follow(c, running, leader), _follow(full, running, leader)
        y, u = _follow(y, running, leader), _follow(u, running, leader)
    for j in range(sets):
        taken[j] = 0
    energy_base = _energy_bases(spec, k, status, y[0])
    triangles = [(lanes.lane(c.a, j), lanes.lane(c.b, j)) for j in range(sets)]  # eq. 1's bounds of each set
    n = 0  # the samples each set that runs on took in this call
    for i in range(first, last if lanes.most(running) != 0.0 else first):
        if i > 0:
            t_start = spec.t0_s + (spec.k0 + i - 1) * dt
            if changes and payload_share(spec.payload_times_s, spec.payload_shares, t_start) != status[0, PAYLOAD]:
                c = _payload_change(with_payload, energy, full, c, y, spec, status, t_start)
                energy_base = _energy_bases(spec, k, status, y[0])
            _, outcome, most, y_new = step_once(
                step, derivative, stiffness_rate, energy, t_start, y, c, u, dt, spec.min_substeps, spec.limit,
                spec.max_substeps, 1, spec.energy_index, energy_base,
            )  # fmt: skip
            for j in range(sets):
                if lanes.lane(running, j) != 0.0 and _stepped(
                    status, j, int(lanes.lane(outcome, j)), lanes.lane(most, j), lanes.lane(u, j),
                    lanes.lane(y_new[0], j), triangles[j], t_start, dt, i,
                ):  # fmt: skip
                    # its run ends: its state the last good one, its next command the failed step's
                    running = lanes.with_lane(running, j, 0.0)
                    _keep(state[j], lanes.lane(y, j))
                    status[j, NEXT_U] = lanes.lane(u, j)
                    status[j, TAKEN] += n
                    taken[j] = n
                    leader = _leader(running)
                    if leader >= 0:
                        c, full = _follow(c, running, leader), _follow(full, running, leader)
            if lanes.most(running) == 0.0:
                break
            y = lanes.choose(running, y_new, y)
            t = spec.t0_s + (spec.k0 + i) * dt
            u = _commands(controller, spec.command, k, running, status, c, y, u, dt, t + half)
            if leader >= 0:
                y, u = _follow(y, running, leader), _follow(u, running, leader)
        if i % spec.every == 0 or i == spec.n_steps:
            if spec.measure:  # the model's samples alone: the outputs they take, not all of them
                taken_samples = samples(t, y, c, u)
                for j in range(sets):
                    if lanes.lane(running, j) != 0.0:
                        add_sample(metrics[j], spec.settings[k + j], *lanes.lane(taken_samples, j))
            if store:
                o = outputs(t, y, c, u)
                for j in range(sets):
                    if lanes.lane(running, j) != 0.0:
                        _keep(rows[j, n], lanes.lane(o, j))
            n += 1
    for j in range(sets):
        if lanes.lane(running, j) != 0.0:
            _keep(state[j], lanes.lane(y, j))
            status[j, NEXT_U] = lanes.lane(u, j)
            status[j, TAKEN] += n
            taken[j] = n


@jitable
def _begin(status: Any, min_substeps: int) -> None:
    """A set's status at the start of its run."""
    status[FAILED_AT], status[OUTCOME], status[MOST] = math.nan, OK, min_substeps
    status[APPLIED_U], status[TAKEN], status[FAILED_STEP] = math.nan, 0.0, -1.0
    status[INTEGRAL], status[HOLDING] = 0.0, 0.0
    status[PAYLOAD], status[BASE_SHIFT] = 1.0, 0.0


@jitable
def _running(status: Any, y: Any) -> Any:
    """1.0 for each set (lane of ``y``) that runs on, 0.0 for one whose run has ended."""
    running = lanes.spread(0.0, y[0])
    for j in range(len(status)):
        running = lanes.with_lane(running, j, 1.0 * (status[j, OUTCOME] == OK))
    return running


@jitable
def _leader(running: Any) -> int:
    """The first set of a block that runs on, where some of its lanes do not (a failed set, or a
    part block's spare lanes); -1 where all run (one set: always)."""
    leader, idle = -1, False
    for j in range(lanes.width(running)):
        if lanes.lane(running, j) == 0.0:
            idle = True
        elif leader < 0:
            leader = j
    return leader if idle else -1


@jitable
def _follow(x: Any, running: Any, leader: int) -> Any:
    """``x`` (a value or a tuple of a block) with each lane that does not run holding the
    ``leader``'s: such a lane then steps as the leader does, unseen, and holds no one up (a
    failed set's state alone could ask for every substep there is at every step)."""
    for j in range(lanes.width(running)):
        if lanes.lane(running, j) == 0.0:
            x = lanes.with_lane(x, j, lanes.lane(x, leader))
    return x


@jitable
def _stepped(
    status: Any, j: int, outcome: int, most: float, u: float, q1: float, triangle: tuple, t_start: float,
    dt: float, i: int,
) -> bool:  # fmt: skip
    """Set ``j``'s step from ``t_start`` with command ``u`` gave ``outcome`` (stepping's),
    needing ``most`` substeps and ending at cylinder length ``q1``: note it in its row of
    ``status``; True where it failed (the rod out of the geometry of eq. 1, the triangle of
    its a and b, too: the model cannot go on), which ends the set's run with the state it had
    before."""
    if outcome == OK and not within_triangle(q1, *triangle):
        outcome = OUT_OF_GEOMETRY
    if outcome != OK:
        status[j, FAILED_AT] = t_start if outcome == TOO_STIFF else t_start + dt
        status[j, OUTCOME] = outcome
        status[j, MOST] = most if outcome == TOO_STIFF else status[j, MOST]
        status[j, FAILED_STEP] = i - 1
        return True
    status[j, MOST] = max(status[j, MOST], most)
    status[j, APPLIED_U] = u
    return False


@jitable
def _energy_bases(spec: RunSpec, k: int, status: Any, template: Any) -> Any:
    """The value of H - W that the energy balance of each set (``k`` ...) keeps now: its
    start's, moved by the payload's changes so far; in ``template``'s lanes."""
    bases = lanes.spread(0.0, template)
    for j in range(len(status)):
        bases = lanes.with_lane(bases, j, spec.energy_base[k + j] + status[j, BASE_SHIFT])
    return bases


@jitable
def _keep(row: Any, y: Any) -> None:
    """A set's state ``y`` into the first len(y) values of its ``row`` (the rest: the model
    elements' states, which a state without them leaves as they were: :func:`layout`)."""
    for m in range(len(y)):
        row[m] = y[m]


def layout(size: int) -> tuple:
    """A state's layout as the kernels take it: a tuple of ``size`` zeros, whose type (a tuple of
    that many floats) tells compiled code how many of the state's first components it steps
    (:func:`state_of`): the physical model's state with or without the model elements' states,
    which come last (physical_kernel.BASE, WHOLE); each layout is compiled on its own."""
    return (0.0,) * size


@jitable
def state_of(row: Any, layout: tuple) -> tuple:
    """The first len(``layout``) values of the state ``row`` as a tuple (the euler and rk4 steps
    keep it so, on the stack)."""
    return jit.tuple_like(row, layout)


@jitable
def state_row(row: Any, y: Any) -> Any:
    """A copy of the state ``row`` with its first len(``y``) values ``y``: the whole state after
    steps of its first values (the rest stand still: :func:`layout`)."""
    out = row.copy()
    _keep(out, y)
    return out


# inlined into the run loop: a call takes the block's constants and state by value (91 values of
# 4 lanes) at every step, even for a constant opening (inlined: 327 -> 308 ns per set-step of the
# lift's opening, one thread)
@jitable(inline="always")
def _commands(
    controller: Callable[..., Any], command: Command, k: int, running: Any, status: Any, c: Any, y: Any,
    u: Any, dt_s: float, t_s: float,
) -> Any:  # fmt: skip
    """The valve command of each set (sets ``k`` ...) that runs on (``running``) for the step
    whose middle is ``t_s``, from the state ``y`` at its start, in ``u``'s lanes (the others
    keep theirs): the open-loop profile of ``command``, one value for every set; or for kind
    ANGLE ``controller`` (:func:`controller_value`, :func:`no_controller`, or interpreted any
    Python command), with each set's controller state in its row of ``status``."""
    if command.kind != ANGLE:
        value = profile_value(
            command.kind, command.times_s, command.values, command.offset, command.amplitude, command.frequency_hz,
            t_s,
        )  # fmt: skip
        return lanes.choose(running, lanes.spread(value, u), u)
    return controller(command, k, running, status, c, y, u, dt_s, t_s)


@jitable
def _payload_change(
    with_payload: Callable[..., Any], energy: Callable[..., float], full: Any, c: Any, y: Any, spec: RunSpec,
    status: Any, t_s: float,
) -> Any:  # fmt: skip
    """The payload's share on the hook becomes the schedule's at ``t_s`` (status[:, PAYLOAD]); the
    constants with it. The payload put down (or picked up) takes its potential and kinetic energy
    with it: the energy balance's H - W of each set moves by H's jump at its state ``y``."""
    share = payload_share(spec.payload_times_s, spec.payload_shares, t_s)
    changed = with_payload(full, share)
    jump = energy(y, changed) - energy(y, c) if spec.energy_index >= 0 else lanes.spread(0.0, y[0])
    for j in range(len(status)):
        status[j, PAYLOAD] = share
        status[j, BASE_SHIFT] += lanes.lane(jump, j)
    return changed


#: Where the command's fields end in a flat spec (:func:`flat`): after the constants.
_COMMAND_END = 1 + len(Command._fields)


def flat(spec: RunSpec) -> tuple:
    """``spec`` as one flat tuple of arrays and numbers, as a parallel kernel takes it (numba's
    parallel loop takes no tuple of arrays); :func:`spec_of` builds it again inside."""
    return (spec.constants, *spec.command, *spec[2:])


@jitable
def spec_of(fields: tuple) -> RunSpec:
    """The RunSpec of its :func:`flat` fields."""
    return RunSpec(fields[0], Command(*fields[1:_COMMAND_END]), *fields[_COMMAND_END:])


@jitable
def batch_set(
    step_once: Callable[..., Any],
    step: Callable[..., Any],
    derivative: Callable[..., Any],
    stiffness_rate: Callable[..., float],
    energy: Callable[..., float],
    outputs: Callable[..., tuple],
    samples: Callable[..., tuple],
    controller: Callable[..., float],
    with_payload: Callable[..., Any],
    constants_of: Callable[..., Any],
    template: Any,
    layout: tuple,
    block: int,
    states: Any,
    status: Any,
    metrics: Any,
    rows: Any,
    taken: Any,
    first: int,
    last: int,
    *spec_fields: Any,
) -> None:
    """:func:`run_set` of block ``block`` of a batch: as many sets as ``template`` holds (a float:
    one, set ``block``; Lanes: a block of lanes.WIDTH in lock-step, sets WIDTH x ``block`` ...)
    over its passes ``first`` ... ``last`` - 1, with ``step_once`` (stepping.advance, or
    advance_lanes for a block) and the run's spec from its flat fields (:func:`flat`): the
    model's constants from the rows ``spec.constants[k]`` (``constants_of``), the state from
    ``states[k]`` (:func:`state_of`, as the step keeps it: its first len(``layout``) values,
    the model's :func:`layout` of this run). A block past the last set fills its spare lanes
    with the first set's (run_set has them follow a set that runs, unseen). ``status``,
    ``metrics``, ``rows`` (its rows of this slice; none: no rows kept) and ``taken`` (its
    samples in this slice) hold one entry per set."""
    spec = spec_of(spec_fields)
    count = lanes.width(template)
    k = count * block
    end = min(k + count, len(states))
    c = lanes.spread(constants_of(spec.constants[k]), template)
    y = lanes.spread(state_of(states[k], layout), template)
    for j in range(1, end - k):
        c = lanes.with_lane(c, j, constants_of(spec.constants[k + j]))
        y = lanes.with_lane(y, j, state_of(states[k + j], layout))
    f = (step_once, step, derivative, stiffness_rate, energy, outputs, samples, controller, with_payload)
    sets = (states[k:end], status[k:end], metrics[k:end], rows[k:end], taken[k:end], first, last)
    if rows.shape[1] > 0:  # each call with its own constant store
        run_set(*f, True, c, y, spec, k, *sets)
    else:
        run_set(*f, False, c, y, spec, k, *sets)
