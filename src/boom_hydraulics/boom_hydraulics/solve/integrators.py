"""Time integrators behind one interface: ``advance(fun, t, y, dt) -> y(t + dt)``.

``fun(t, y, *args)`` returns dy/dt as a sequence (``args`` as in scipy's solve_ivp). A state
``y`` is a list of components, each a float (one simulation) or a numpy array (a batch
of simulations integrated together), so the same fixed-step code serves both. Methods:

- ``euler``: explicit Euler, order 1.
- ``rk4``: classical Runge-Kutta of order 4, the paper's method (Fig. 7).
- ``rk45``: Dormand-Prince 5(4) with error control and adaptive internal steps (as
  scipy's RK45); floats only.
- ``ros2``: the two-stage Rosenbrock method ROS2 (Verwer et al. 1999), order 2 and
  L-stable: linearly implicit, with a finite-difference Jacobian. For stiff settings
  (short hoses, stiff oil) where an explicit method would need tiny steps; floats only.

Fixed-step methods take ``substeps`` internal steps per ``advance``; an explicit one is
stable while its step times the problem's fastest rate stays under its ``stability_limit``.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from .. import jit
from ..errors import SimulationError
from ..jit import compiled_as, jitable
from . import lanes

Derivative = Callable[..., list]


class Integrator(Protocol):
    """What every method offers."""

    name: str

    def advance(self, fun: Derivative, t: float, y: list, dt: float, args: tuple = ()) -> list:
        """The state at ``t + dt``."""
        ...


def stage(y: Sequence, h: float, k: Sequence) -> list:
    """y + h k, component by component (a list; compiled, a tuple of the state's size, which
    numba keeps on the stack where a list would go to the heap)."""
    return [yi + h * ki for yi, ki in zip(y, k)]


def rk4_combination(y: Sequence, h6: float, k1: Sequence, k2: Sequence, k3: Sequence, k4: Sequence) -> list:
    """y + h/6 (k1 + 2 k2 + 2 k3 + k4), component by component (compiled, as :func:`stage`)."""
    return [yi + h6 * (a + 2.0 * (b + c) + d) for yi, a, b, c, d in zip(y, k1, k2, k3, k4)]


def _component_sums(combine: Callable[..., Any], arity: int) -> Any:
    """A numba intrinsic ``f(y, h, k_1 .. k_arity)`` that builds a state tuple whose i-th
    component is ``combine(builder, y_i, h, k_1i, ...)``: straight-line code, one sum per
    component, at any state size (a loop of tuple_setitem, which LLVM leaves rolled at 11
    components, keeps the tuple in memory and ran 5 times slower). The components are floats,
    or :mod:`lanes` (a block of sets in lock-step) where any operand is: then each sum is one
    vector sum. Without numba, None."""
    if jit.numba is None:
        return None
    from numba.core import types
    from numba.extending import intrinsic

    def component(of: Any) -> Any:
        """Lanes where ``of`` (the operands' types) holds any, else float64."""
        return next((t for t in of if isinstance(t, lanes.Lanes)), types.float64)

    def values(context: Any, builder: Any, of: Any, value: Any, out: Any) -> list:
        elements = [builder.extract_value(value, i) for i in range(len(of))]
        return [as_type(context, builder, e, t, out) for e, t in zip(elements, of)]

    def as_type(context: Any, builder: Any, value: Any, of: Any, out: Any) -> Any:
        if out == types.float64:
            return context.cast(builder, value, of, types.float64)
        return lanes.spread_value(context, builder, value, of, out.count)

    def typed(y: Any, h: Any, ks: tuple) -> Any:
        if any(len(k) != len(y) for k in ks):
            return None  # no such sum: numba says so where it is called
        item = component([*y.types, h, *(t for k in ks for t in k.types)])
        out = types.UniTuple(item, len(y))

        def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
            hv = as_type(context, builder, args[1], h, item)
            ys = values(context, builder, y, args[0], item)
            columns = zip(ys, *(values(context, builder, k, a, item) for k, a in zip(ks, args[2:])))
            value = context.get_constant_undef(out)
            for i, (yi, *ki) in enumerate(columns):
                value = builder.insert_value(value, combine(builder, yi, hv, *ki), i)
            return value

        return out(y, h, *ks), codegen

    if arity == 1:
        return intrinsic(lambda typingctx, y, h, k: typed(y, h, (k,)))
    return intrinsic(lambda typingctx, y, h, k1, k2, k3, k4: typed(y, h, (k1, k2, k3, k4)))


def _twice(builder: Any, x: Any) -> Any:
    """2 x (a float or a vector of them)."""
    from llvmlite import ir

    kind = x.type
    return builder.fmul(ir.Constant(kind, [2.0] * kind.count if isinstance(kind, ir.VectorType) else 2.0), x)


#: y + h k, per component (:func:`stage`'s sums, in its order).
_stage_sums = _component_sums(lambda b, y, h, k: b.fadd(y, b.fmul(h, k)), 1)
#: y + h6 (k1 + 2 (k2 + k3) + k4), per component (:func:`rk4_combination`'s sums, in its order).
_rk4_sums = _component_sums(
    lambda b, y, h6, k1, k2, k3, k4: b.fadd(y, b.fmul(h6, b.fadd(b.fadd(k1, _twice(b, b.fadd(k2, k3))), k4))),
    4,
)


@compiled_as(stage)
def _stage_compiled(y: Any, h: Any, k: Any) -> Callable[..., Any]:
    """:func:`stage` as compiled code runs it: the same sums, built into a tuple of the state's
    size (the implementation's annotations are those of this typing function, as numba asks)."""

    def into_tuple(y: Any, h: Any, k: Any) -> Callable[..., Any]:
        return _stage_sums(y, h, k)

    return into_tuple


@compiled_as(rk4_combination)
def _rk4_combination_compiled(y: Any, h6: Any, k1: Any, k2: Any, k3: Any, k4: Any) -> Callable[..., Any]:
    """:func:`rk4_combination` as compiled code runs it (see :func:`_stage_compiled`)."""

    def into_tuple(y: Any, h6: Any, k1: Any, k2: Any, k3: Any, k4: Any) -> Callable[..., Any]:
        return _rk4_sums(y, h6, k1, k2, k3, k4)

    return into_tuple


@jitable
def euler_step(fun: Derivative, t: float, y: list, h: float, args: tuple = ()) -> list:
    """y + h f(t, y)."""
    k1 = fun(t, y, *args)
    return stage(y, h, k1)


@jitable
def rk4_step(fun: Derivative, t: float, y: list, h: float, args: tuple = ()) -> list:
    """Classical RK4: y + h/6 (k1 + 2 k2 + 2 k3 + k4) (the listing's rk4Step)."""
    h2 = 0.5 * h
    k1 = fun(t, y, *args)
    k2 = fun(t + h2, stage(y, h2, k1), *args)
    k3 = fun(t + h2, stage(y, h2, k2), *args)
    k4 = fun(t + h, stage(y, h, k3), *args)
    h6 = h / 6.0
    return rk4_combination(y, h6, k1, k2, k3, k4)


#: ROS2's gamma = 1 + 1/sqrt(2): the method is L-stable (its amplification tends to 0 for stiff modes).
ROS2_GAMMA = 1.0 + 1.0 / math.sqrt(2.0)


@jitable
def ros2_step(fun: Derivative, t: float, y: list, h: float, args: tuple = ()) -> list:
    """ROS2: (I - g h J) k1 = f(y); (I - g h J) k2 = f(y + h k1) - 2 k1; y + h (3 k1 + k2) / 2.

    J is the Jacobian at y by forward differences; the command is held over the step, so
    the system is autonomous within it. The matrix is factored once for both stages, by
    :func:`lu_factor`.
    """
    n = len(y)
    f0 = np.array(fun(t, y, *args))
    matrix = np.empty((n, n))
    for j in range(n):
        delta = 1e-7 * max(abs(y[j]), 1e-3)
        shifted = [y[i] + delta * (i == j) for i in range(n)]
        column = (np.array(fun(t, shifted, *args)) - f0) / delta
        for i in range(n):
            matrix[i, j] = -ROS2_GAMMA * h * column[i] + (i == j)
    if not np.isfinite(matrix).all():  # a model not finite near y: so is the step, not a wrong solve
        return [math.nan for _ in range(n)]
    rows = lu_factor(matrix)
    k1 = lu_solve(matrix, rows, f0)
    stage = [y[i] + h * k1[i] for i in range(n)]
    k2 = lu_solve(matrix, rows, np.array(fun(t + h, stage, *args)) - 2.0 * k1)
    return [y[i] + h * (1.5 * k1[i] + 0.5 * k2[i]) for i in range(n)]


def lu_factor(a: np.ndarray) -> np.ndarray:
    """Factor the square matrix ``a`` in place into L (below the diagonal, unit diagonal) and
    U by Gaussian elimination with partial pivoting; returns the row order (row k of the
    factors is row ``rows[k]`` of ``a``). A zero pivot (a singular matrix) leaves NaN in U,
    so that a step that solves with it is not finite.

    Written out, not LAPACK's: each entry is updated by one product and one difference in a
    fixed order (no sums whose order a vector unit chooses), so the solve gives the same bits
    on every machine, interpreted and compiled alike (the model's exp, sin and acos still come
    from the machine's C library). LAPACK's dgesv, as numpy and numba call it,
    orders its sums by the BLAS kernels of the processor it runs on: a stiff cycle held a
    cavitating chamber against an end stop through on one processor and broke its energy
    balance on another (docs/model.md, "Stepping"). Compiled, the same operations run as
    loops (:func:`_lu_factor_compiled`).
    """
    n = a.shape[0]
    rows = np.arange(n)
    for k in range(n):
        pivot = k + int(np.argmax(np.abs(a[k:, k])))
        if pivot != k:
            a[[k, pivot]] = a[[pivot, k]]
            rows[[k, pivot]] = rows[[pivot, k]]
        if a[k, k] == 0.0:
            a[k:, k:] = np.nan
            return rows
        a[k + 1 :, k] /= a[k, k]
        a[k + 1 :, k + 1 :] -= np.outer(a[k + 1 :, k], a[k, k + 1 :])
    return rows


def lu_solve(lu: np.ndarray, rows: np.ndarray, b: np.ndarray) -> np.ndarray:
    """x with A x = b, from A's factors ``lu`` and row order ``rows`` (:func:`lu_factor`),
    column by column (products and differences only, as there; compiled, as loops:
    :func:`_lu_solve_compiled`)."""
    n = lu.shape[0]
    x = b[rows]
    for j in range(n):  # L z = P b
        x[j + 1 :] -= lu[j + 1 :, j] * x[j]
    for j in range(n - 1, -1, -1):  # U x = z
        x[j] /= lu[j, j]
        x[:j] -= lu[:j, j] * x[j]
    return x


@compiled_as(lu_factor)
def _lu_factor_compiled(a: Any) -> Callable[..., Any]:
    """:func:`lu_factor` as compiled code runs it: the same operations in the same order, as
    loops (numba compiles the Python form too, but allocates each slice's temporaries: 32 us
    a factorization of 30 states and two solves, against 4 us as loops and 11 us by LAPACK)."""

    def factor(a: Any) -> Any:
        n = a.shape[0]
        rows = np.arange(n)
        for k in range(n):
            pivot = k
            for i in range(k + 1, n):  # the first of the largest, as argmax (ros2_step hands it no NaN)
                if abs(a[i, k]) > abs(a[pivot, k]):
                    pivot = i
            if pivot != k:
                for j in range(n):
                    a[k, j], a[pivot, j] = a[pivot, j], a[k, j]
                rows[k], rows[pivot] = rows[pivot], rows[k]
            if a[k, k] == 0.0:
                a[k:, k:] = np.nan
                return rows
            for i in range(k + 1, n):
                a[i, k] /= a[k, k]
            for i in range(k + 1, n):
                for j in range(k + 1, n):
                    a[i, j] -= a[i, k] * a[k, j]
        return rows

    return factor


@compiled_as(lu_solve)
def _lu_solve_compiled(lu: Any, rows: Any, b: Any) -> Callable[..., Any]:
    """:func:`lu_solve` as compiled code runs it (see :func:`_lu_factor_compiled`)."""

    def solve(lu: Any, rows: Any, b: Any) -> Any:
        n = lu.shape[0]
        x = np.empty(n)
        for i in range(n):
            x[i] = b[rows[i]]
        for j in range(n):
            for i in range(j + 1, n):
                x[i] -= lu[i, j] * x[j]
        for j in range(n - 1, -1, -1):
            x[j] /= lu[j, j]
            for i in range(j):
                x[i] -= lu[i, j] * x[j]
        return x

    return solve


class FixedStep:
    """A fixed-step method with ``substeps`` internal steps per advance."""

    def __init__(self, name: str, step: Callable[..., list], substeps: int = 1):
        if substeps < 1:
            raise ValueError("substeps must be >= 1")
        self.name = name
        self._step = step
        self.substeps = substeps

    def advance(self, fun: Derivative, t: float, y: list, dt: float, args: tuple = ()) -> list:
        if self.substeps == 1:
            return self._step(fun, t, y, dt, args)
        h = dt / self.substeps
        for i in range(self.substeps):
            y = self._step(fun, t + i * h, y, h, args)
        return y


# Dormand-Prince 5(4) tableau (as in scipy.integrate.RK45).
_DP_C = (0.0, 1 / 5, 3 / 10, 4 / 5, 8 / 9, 1.0)
_DP_A = (
    (),
    (1 / 5,),
    (3 / 40, 9 / 40),
    (44 / 45, -56 / 15, 32 / 9),
    (19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729),
    (9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656),
)
_DP_B = (35 / 384, 0.0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84)
# b (5th order) - b* (4th order), weights of the error estimate, last for the FSAL stage
_DP_E = (71 / 57600, 0.0, -71 / 16695, 71 / 1920, -17253 / 339200, 22 / 525, -1 / 40)


class DormandPrince45:
    """Adaptive Dormand-Prince 5(4) with error control, for one (float) state.

    Internal steps adapt so that each component's local error stays below
    ``atol_i + rtol |y_i|``; ``advance`` lands exactly on ``t + dt`` and remembers the
    last accepted step size for the next call.
    """

    name = "rk45"
    max_steps_per_advance = 200_000

    def __init__(self, rtol: float, atol: Sequence[float], min_step: float = 1e-12):
        self.rtol = rtol
        self.atol = list(atol)
        self.min_step = min_step
        self._h: float | None = None
        self.accepted = 0
        self.rejected = 0

    def _try_step(self, fun: Derivative, t: float, y: list, h: float, k1: list, args: tuple) -> tuple:
        ks = [k1]
        for i in range(1, 6):
            a = _DP_A[i]
            yi = [y0 + h * sum(aij * kj[n] for aij, kj in zip(a, ks)) for n, y0 in enumerate(y)]
            ks.append(fun(t + _DP_C[i] * h, yi, *args))
        y_new = [y0 + h * sum(bj * kj[n] for bj, kj in zip(_DP_B, ks)) for n, y0 in enumerate(y)]
        k7 = fun(t + h, y_new, *args)
        ks.append(k7)
        err = 0.0
        for n, (y0, y1) in enumerate(zip(y, y_new)):
            e = h * sum(ej * kj[n] for ej, kj in zip(_DP_E, ks))
            scale = self.atol[n] + self.rtol * max(abs(y0), abs(y1))
            err = max(err, abs(e) / scale)
        if not all(math.isfinite(v) for v in y_new):
            err = math.inf  # a NaN or infinite trial state is never accepted
        return y_new, k7, err

    def advance(self, fun: Derivative, t: float, y: list, dt: float, args: tuple = ()) -> list:
        t_end = t + dt
        h_try = self._h or dt
        k1 = fun(t, y, *args)
        for _ in range(self.max_steps_per_advance):
            if t >= t_end - 1e-12 * dt:
                self._h = h_try
                return y
            h = min(h_try, t_end - t)
            truncated = h < h_try  # shortened to land on t_end: not a measure of the right step
            y_new, k_new, err = self._try_step(fun, t, y, h, k1, args)
            if err <= 1.0:
                t, y, k1 = t + h, y_new, k_new
                self.accepted += 1
                grown = h * (5.0 if err == 0.0 else min(5.0, 0.9 * err**-0.2))
                h_try = max(h_try, grown) if truncated else grown
            else:
                self.rejected += 1
                h_try = h * max(0.2, 0.9 * err**-0.2)
                if h_try < self.min_step:
                    raise SimulationError(
                        f"rk45: step size fell below {self.min_step:g} s at t = {t:.6g} s; "
                        "the equations are too stiff or the state diverged"
                    )
        raise SimulationError(
            f"rk45: more than {self.max_steps_per_advance} internal steps in one advance at "
            f"t = {t:.6g} s; loosen rtol/atol_scale or use rk4 with a smaller time_step_s"
        )


@dataclass(frozen=True)
class Method:
    """One integration method: its fixed step (None for an adaptive method) and how to build it."""

    name: str
    step: Callable[..., list] | None
    description: str
    #: Largest |h lambda| at which the method is stable for every eigenvalue lambda of the
    #: problem on the negative real axis and near the imaginary one, with a margin (RK4:
    #: 2.785 and 2.828; Euler: 2 and none); None for an implicit or adaptive method.
    stability_limit: float | None = None
    batched: bool = True  # runs on numpy arrays (one entry per parameter set)
    #: A step that fails its checks is taken again in more substeps (stepping.advance_halving):
    #: the implicit method, whose steps no stability bound sizes.
    halving: bool = False

    def build(self, substeps: int, rtol: float, atol: Sequence[float]) -> Integrator:
        if self.step is not None:
            return FixedStep(self.name, self.step, substeps)
        return DormandPrince45(rtol, atol)


#: Every integration method, by name (as scipy.integrate's METHODS): the one list of them.
METHODS: dict[str, Method] = {
    "euler": Method("euler", euler_step, "explicit Euler, first order", stability_limit=1.0),
    "rk4": Method("rk4", rk4_step, "classic Runge-Kutta, fourth order (the paper's)", stability_limit=2.5),
    "rk45": Method("rk45", None, "Dormand-Prince 5(4), adaptive with error control", batched=False),
    "ros2": Method(
        "ros2", ros2_step, "Rosenbrock ROS2, second order, L-stable (stiff settings)", batched=False, halving=True
    ),
}
#: The methods with a fixed step: the compiled path runs these.
FIXED_STEP = tuple(name for name, method in METHODS.items() if method.step is not None)
#: The methods that integrate a batch of parameter sets at once.
BATCHED = tuple(name for name, method in METHODS.items() if method.batched)


def make(name: str, substeps: int = 1, rtol: float = 1e-6, atol: Sequence[float] = (1e-8,)) -> Integrator:
    """The integrator called ``name`` (one of :data:`METHODS`)."""
    if name not in METHODS:
        raise ValueError(f"unknown integration method {name!r}; choose {', '.join(METHODS)}")
    return METHODS[name].build(substeps, rtol, atol)
