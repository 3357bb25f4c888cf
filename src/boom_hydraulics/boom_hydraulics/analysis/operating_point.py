"""The operating point of a linearisation: the drive at rest, or in steady motion, at a rod length.

- **Valve centred** (opening 0): the static equilibrium. The rod is at rest (v = 0), the seals
  relaxed (bristle 0: no friction force), and the chamber pressures are those at which the boom
  stands still and the rod chamber's flows balance: the piston chamber holds the load
  (eq. 6 with p2), the rod chamber sits where the valve's leakage from P and to T cancel
  (dp2/dt = 0, eq. 13). What stays is the piston chamber's creep through the closed
  load-holding valve's seat (:attr:`OperatingPoint.drift`), slow against every mode.
- **Valve slightly open** (opening u != 0): the steady motion at that opening as the rod passes
  this length. Velocity, pressures and seal deflection stand still (dv/dt = dp1/dt = dp2/dt
  = ds/dt = 0, eq. 11-13 and the LuGre rate); only the rod length moves, at v.

Both are found by Newton's method on the model's own derivative (:func:`steady`), with the
Jacobian of :mod:`.jacobian`; a state whose equation does not depend on it (a sealed rod
chamber without leakage) keeps its value from the model's initial state. Floats for one
parameter set, or numpy arrays for a batch (:func:`centred_batch`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import ConfigError
from ..model import MODELS
from ..model.control import full_opening_rate
from ..model.drives import DRIVES
from ..model.geometry import boom_angle_rad, lever_rad_per_m, outside_stroke
from ..model.hydraulics import orifice_pressure_drop
from ..model.parameters import Parameters, with_updates
from ..solve.closed_loop import stacked_constants
from ..solve.simulator import Simulator, scale_sizes
from .jacobian import CENTRAL, FORWARD, jacobian

MODEL = MODELS["physical"]
Q1, V, P1, P2, SPOOL, BRISTLE = (MODEL.STATE_NAMES.index(n) for n in ("q1", "v", "p1", "p2", "x_v", "bristle"))
#: Keep this far inside the stroke (end stops within a Jacobian's step would bend it), m.
STROKE_MARGIN_M = 1e-3
#: Newton's method stops when no unknown moves by more than this fraction of its scale ...
TOLERANCE = 1e-12
#: (unknowns, equations): at a centred valve p1 and p2 from dv/dt = 0 and dp2/dt = 0; in steady
#: motion v, p1, p2 and the bristle from their own rates (dv/dt, dp1/dt, dp2/dt, ds/dt) = 0.
CENTRED = ((P1, P2), (V, P2))
MOVING = ((V, P1, P2, BRISTLE), (V, P1, P2, BRISTLE))
#: ... or after this many iterations.
MAX_ITERATIONS = 60


@dataclass(frozen=True)
class OperatingPoint:
    """Where a linear model is taken: parameters, full model state, valve command."""

    params: Parameters
    state: list[float]  # every component of the model's state (physical.STATE_NAMES)
    opening: float  # the valve command held there, -1..1
    drift: float  # dp1/dt that remains at a centred valve (the load-holding seat's creep), Pa/s

    @property
    def q1_m(self) -> float:
        return self.state[Q1]

    @property
    def angle_rad(self) -> float:
        p = self.params
        return boom_angle_rad(self.q1_m, p.a_m, p.b_m, p.support_height_m)

    @property
    def kink_side(self) -> int:
        """The side the spool is differenced on: at a centred valve the lifting side (FORWARD),
        where the spool's gain changes from one side to the other; elsewhere both (CENTRAL)."""
        return FORWARD if self.opening == 0.0 else CENTRAL


def rod_length_at_angle(p: Parameters, angle_rad: float) -> float:
    """The cylinder length q1 at boom elevation ``angle_rad`` (eq. 4 inverted: theta = alpha +
    pi/2 - arccos(h/b), then the law of cosines of eq. 1), m; ConfigError for an angle outside
    the stroke (the law of cosines would give the length of a mirrored angle, not this one)."""
    why = outside_stroke(p, angle_rad, "--angle-deg")
    if why is not None:
        raise ConfigError(f"{why}; choose an angle within it")
    theta = angle_rad + math.pi / 2.0 - math.acos(p.support_height_m / p.b_m)
    return math.sqrt(p.a_m * p.a_m + p.b_m * p.b_m - 2.0 * p.a_m * p.b_m * math.cos(theta))


def check_inside_stroke(p: Parameters, q1_m: float) -> None:
    """ConfigError unless ``q1_m`` lies inside the stroke, clear of the end stops."""
    low, high = p.cylinder_min_length_m + STROKE_MARGIN_M, p.cylinder_max_length_m - STROKE_MARGIN_M
    if not (math.isfinite(q1_m) and low <= q1_m <= high):
        raise ConfigError(
            f"rod length {q1_m:.4f} m lies outside the stroke [{low:.4f}, {high:.4f}] m (1 mm clear of the end "
            "stops, whose contact has no linear model); choose a rod length or angle within it"
        )


def steady(
    derivative: Callable[[list], Sequence[Any]],
    y0: list,
    unknowns: Sequence[int],
    equations: Sequence[int],
    scales: Sequence[float],
) -> tuple[list, bool]:
    """Newton's method for dy_i/dt = 0 (i in ``equations``) over y_j (j in ``unknowns``), from ``y0``.

    ``derivative(y)`` is dy/dt; ``scales`` the unknowns' sizes. An equation that does not
    depend on the unknowns (a row of zeros) holds its unknown at its start value. A step
    that does not lower the residual is halved (up to 30 times). Returns the state and
    whether every entry converged (floats, or arrays of a batch)."""
    y = list(y0)
    n = len(unknowns)

    def residual(x: list) -> np.ndarray:
        trial = list(y)
        for i, xi in zip(unknowns, x):
            trial[i] = xi
        d = derivative(trial)
        return np.moveaxis(np.asarray(np.broadcast_arrays(*(d[i] for i in equations)), dtype=float), 0, -1)

    x = [y[i] for i in unknowns]
    scale = np.array(scales, dtype=float)
    converged = np.zeros(np.shape(x[0]), dtype=bool)
    for _ in range(MAX_ITERATIONS):
        r = residual(x)
        j = jacobian(lambda z: list(np.moveaxis(residual(z), -1, 0)), x, scales)
        stuck = np.all(j == 0.0, axis=-1)  # no unknown moves this equation: hold its own
        j = np.where(stuck[..., None], np.eye(n) / scale, j)
        r = np.where(stuck, 0.0, r)
        size = np.max(np.abs(j) * scale, axis=-1)  # each equation in units of its unknowns
        size = np.where(size > 0.0, size, 1.0)
        try:
            dx = np.linalg.solve(j, r[..., None])[..., 0]
        except np.linalg.LinAlgError:
            break
        norm = np.max(np.abs(r) / size, axis=-1)
        alpha = np.ones(np.shape(norm))
        x_new = x
        for _halving in range(30):
            x_new = [xi - alpha * dx[..., k] for k, xi in enumerate(x)]
            better = np.max(np.abs(residual(x_new)) / size, axis=-1) <= norm
            if np.all(better):
                break
            alpha = np.where(better, alpha, 0.5 * alpha)
        moved = np.max(np.abs(alpha[..., None] * dx) / scale, axis=-1)
        x = x_new
        converged = moved <= TOLERANCE
        if np.all(converged):
            break
    for i, xi in zip(unknowns, x):
        y[i] = xi
    return y, bool(np.all(converged)) if np.ndim(converged) == 0 else converged


def _scales(p: Any) -> dict[int, float]:
    return {V: 1.0, P1: p.supply_pressure_pa, P2: p.supply_pressure_pa, BRISTLE: 1.0}


def operating_point(p: Parameters, q1_m: float, opening: float = 0.0) -> OperatingPoint:
    """The drive at rod length ``q1_m`` with the valve command ``opening`` held (see the module
    docstring). ConfigError for paper mode, a length outside the stroke, an opening outside
    [-1, 1] or a point where no steady state exists (the pump or a relief valve limits it)."""
    if p.mode != "physical":
        raise ConfigError("a linear model is taken of the physical drive: set mode: physical")
    check_inside_stroke(p, q1_m)
    if not (math.isfinite(opening) and -1.0 <= opening <= 1.0):
        raise ConfigError(f"--opening must be a valve opening in [-1, 1], got {opening}")
    c = MODEL.constants(p)
    y0 = MODEL.initial_state(p, q1_m)
    scales = _scales(p)
    y0[SPOOL] = opening
    unknowns, equations = CENTRED if opening == 0.0 else MOVING
    # a drive whose supply does not stand still: its own states settle too (their rates 0)
    drive = DRIVES[p.drive]
    own = () if drive.STEADY_SUPPLY else MODEL.DRIVE_STATES[: len(drive.STATE_NAMES)]
    unknowns, equations = (*unknowns, *own), (*equations, *own)
    sizes = scale_sizes(p)
    scales.update({i: sizes[kind] for i, kind in zip(own, drive.STATE_SCALES)})
    # the elastic boom's deflection settles too (docs/model.md, "Elastic boom"): its rates 0
    boom = MODEL.BOOM_STATES if p.boom_bending_stiffness_n_m2 > 0.0 else ()
    unknowns, equations = (*unknowns, *boom), (*equations, *boom)
    scales.update({i: sizes[kind] for i, kind in zip(boom, ("length", "velocity"))})
    if opening != 0.0:
        y0[V], y0[P1], y0[P2], y0[BRISTLE] = _motion_guess(c, q1_m, opening)
    derivative = lambda y: MODEL.derivative(0.0, y, c, opening)  # noqa: E731
    y, ok = steady(derivative, y0, unknowns, equations, [scales[i] for i in unknowns])
    if not ok and opening == 0.0 and own:
        y, ok = settled(p, q1_m, [scales[i] for i in equations], equations)
    d = MODEL.derivative(0.0, y, c, opening)
    if not ok or not all(math.isfinite(v) for v in y):
        raise ConfigError(
            f"no steady state at q1 = {q1_m:.4f} m with the valve at {opening:g}: the drive does not settle into "
            "steady motion there (the pump's flow or a relief valve limits it); choose a smaller --opening"
        )
    state = [float(v) for v in y]
    return OperatingPoint(p, state, float(opening), float(d[P1]) if opening == 0.0 else 0.0)


#: How long a drive with states of its own is left to settle at rest where Newton's method finds
#: no steady state, s: a friction or a brake that holds with any torque within its range leaves
#: the equations of its states without a unique root.
SETTLE_S = 1.0


def settled(p: Parameters, q1_m: float, scales: Sequence[float], equations: Sequence[int]) -> tuple[list, bool]:
    """The state the drive comes to rest in at ``q1_m`` with the valve closed, run for
    :data:`SETTLE_S` from its initial state (a brake or a screw's friction takes the load where
    it holds it), and whether the ``equations``' rates there are below 1e-6 of their scales per
    second (as Newton's method would have them)."""
    simulator = Simulator(with_updates(p, initial_length_m=q1_m))
    simulator.step(0.0, max(1, round(SETTLE_S / p.time_step_s)))
    y = [float(v) for v in simulator.y]
    rates = MODEL.derivative(0.0, y, MODEL.constants(p), 0.0)
    ok = all(abs(rates[i]) <= 1e-6 * scale for i, scale in zip(equations, scales)) and math.isfinite(sum(y))
    return y, ok


def _motion_guess(c: Any, q1_m: float, opening: float) -> tuple[float, float, float, float]:
    """Velocity, pressures and seal deflection of a quasi-static meter-in/meter-out pair (the
    feedforward's plant model, model.control.full_opening_rate) at ``opening``: Newton's start."""
    up, down = full_opening_rate(q1_m, c)
    lever = lever_rad_per_m(q1_m, c.a, c.b)
    v = opening * (up if opening > 0.0 else down) / lever
    k = c.k_valve * abs(opening)
    drop1 = orifice_pressure_drop(k, c.s1 * abs(v), c.transition2)  # meter-in lifting, meter-out lowering
    drop2 = orifice_pressure_drop(k, c.s2 * abs(v), c.transition2)
    if opening > 0.0:
        p1, p2 = c.p_set - drop1, c.p_tank + drop2
    else:
        p1, p2 = c.p_tank + drop1, c.p_set - drop2
    return v, p1, p2, math.copysign(c.coulomb_ratio, v)


def centred_batch(params: Sequence[Parameters], q1_m: np.ndarray) -> tuple[list[np.ndarray], Any, np.ndarray]:
    """The centred-valve operating points of many physical-mode parameter sets at once (one
    length each): the states as arrays per component, the stacked constants and whether each
    converged."""
    c = stacked_constants(params)
    y0 = [
        np.array(column, dtype=float)
        for column in zip(*(MODEL.initial_state(p, float(q)) for p, q in zip(params, q1_m)))
    ]
    scales = _scales(params[0])
    y, ok = steady(lambda y: MODEL.derivative(0.0, y, c, 0.0, np), y0, *CENTRED, [scales[P1], scales[P2]])
    return y, c, np.asarray(ok) & np.all(np.isfinite(y), axis=0)
