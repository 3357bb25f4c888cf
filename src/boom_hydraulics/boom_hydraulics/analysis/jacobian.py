"""Jacobians of a function of the model's state by finite differences (docs/linearize.md, "The Jacobian").

Complex-step differentiation, exact to rounding for analytic functions, does not apply to
this model: its branches are written with ``abs`` (``pos(z) = (z + |z|) / 2``, the valve's
``x_plus``/``x_minus``, the end stops, the seals), and ``abs`` of a complex number is its
modulus, not the analytic continuation; ``math.sqrt`` refuses complex numbers outright.
So the derivative is differenced in real arithmetic:

- **central** differences, (f(x + h) - f(x - h)) / 2h, whose truncation error is
  h^2 f''' / 6 and whose rounding error is about eps |f| / h; both are balanced by
  h = eps^(1/3) max(|x|, scale) (:data:`STEP`, about 6e-6 of the component's size), for a
  relative error near eps^(2/3), about 4e-11, where the scale is the size over which the
  function bends (1 m, 1 m/s, the supply pressure, 1);
- **one-sided** second-order differences, (-3 f(x) + 4 f(x + h) - f(x + 2h)) / 2h, with
  the same order and step, where the function has a kink at x (the spool at the valve's
  centre: there the lifting and the lowering side have different gains, and a central
  difference would average them).

The step is rounded to one that x + h represents exactly, so the division uses the step
actually taken. Every function works on floats and on numpy arrays (one entry per
parameter set of a batch) alike.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

Num = Any  # float or numpy.ndarray

#: Relative step of the differences: eps^(1/3) balances truncation (h^2) against rounding (eps / h).
STEP = float(np.finfo(float).eps ** (1.0 / 3.0))
#: Sides of a difference: both (central), or one side only where the function has a kink.
CENTRAL, FORWARD, BACKWARD = 0, 1, -1


def step_size(x: Num, scale: float) -> Num:
    """The step for component value ``x`` of natural size ``scale``: STEP max(|x|, scale), rounded
    so that x + h is exact in floating point."""
    h = STEP * np.maximum(np.abs(x), scale)
    return (x + h) - x


def jacobian(
    f: Callable[[list], Sequence[Num]],
    x: Sequence[Num],
    scales: Sequence[float],
    sides: Sequence[int] | None = None,
) -> np.ndarray:
    """df_i/dx_j of ``f`` (a list of components in, a sequence of components out) at ``x``.

    ``scales``: each component's natural size (see the module docstring); ``sides``: per
    component CENTRAL (default), FORWARD or BACKWARD. Returns an array of shape
    (len(f(x)), len(x)) for float components, (..., len(f(x)), len(x)) for array ones.
    """
    sides = sides or [CENTRAL] * len(x)
    f0 = None
    columns = []
    for j, (xj, scale, side) in enumerate(zip(x, scales, sides)):
        h = step_size(xj, scale)

        def at(offset: Num, j: int = j, xj: Num = xj) -> np.ndarray:
            shifted = list(x)
            shifted[j] = xj + offset
            return np.asarray(np.broadcast_arrays(*f(shifted)), dtype=float)

        if side == CENTRAL:
            columns.append((at(h) - at(-h)) / (2.0 * h))
            continue
        if f0 is None:
            f0 = np.asarray(np.broadcast_arrays(*f(list(x))), dtype=float)
        h = h * side
        columns.append((-3.0 * f0 + 4.0 * at(h) - at(2.0 * h)) / (2.0 * h))
    matrix = np.stack(columns, axis=1)  # (outputs, inputs, ...)
    return np.moveaxis(matrix, (0, 1), (-2, -1)) if matrix.ndim > 2 else matrix
