"""The re-simulations of a fit, on every core: the points a scan tries and the columns of a
forward-difference Jacobian are independent, so they run side by side in worker processes.

The workers are forked from the fitting process once the problem is read (the bag, the
signals, the compiled kernels loaded): each starts at once with all of it. One worker, or a
machine with one core, evaluates in this process.
"""

from __future__ import annotations

import multiprocessing
import os
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from typing import Any

import numpy as np

#: The problem the worker processes evaluate (set before they fork).
_PROBLEM: Any = None


def _residual(theta: np.ndarray, window_s: float, weighted: bool) -> np.ndarray:
    return _PROBLEM.residual(_PROBLEM.simulate(theta), window_s, weighted)


def cores() -> int:
    """The cores this process may run on."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)


class Evaluations:
    """The weighted residuals of a problem at many parameter points, ``workers`` at a time."""

    def __init__(self, problem: Any, workers: int) -> None:
        global _PROBLEM
        _PROBLEM = problem
        self.problem = problem
        self.pool = None
        if workers > 1:
            self.pool = ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("fork"))
        self._memo: dict[tuple[bytes, float, bool], np.ndarray] = {}
        self.last_jacobian: np.ndarray | None = None  # the one :meth:`jacobian` gave last

    def __enter__(self) -> Evaluations:
        return self

    def __exit__(self, *exc: object) -> None:
        if self.pool is not None:
            self.pool.shutdown(wait=True, cancel_futures=True)

    def residuals(self, thetas: Sequence[np.ndarray], window_s: float, weighted: bool = False) -> list[np.ndarray]:
        """The residual at each of ``thetas``: averaged over ``window_s`` (0: raw), or ``weighted``
        by the signals' noise (the problem's :meth:`residual`)."""
        if self.pool is None or len(thetas) == 1:
            return [self.problem.residual(self.problem.simulate(th), window_s, weighted) for th in thetas]
        self.problem.evaluations += len(thetas)
        n = len(thetas)
        return list(self.pool.map(_residual, thetas, [window_s] * n, [weighted] * n))

    def function(self, window_s: float, weighted: bool = False) -> Callable[[np.ndarray], np.ndarray]:
        """f(theta) for least_squares, remembering its last values for :meth:`jacobian`."""

        def f(theta: np.ndarray) -> np.ndarray:
            (r,) = self.residuals([theta], window_s, weighted)
            self._memo = {(theta.tobytes(), window_s, weighted): r}
            return r

        return f

    def jacobian(
        self, window_s: float, step: float, low: np.ndarray, high: np.ndarray, weighted: bool = False
    ) -> Callable[[np.ndarray], np.ndarray]:
        """J(theta) by differences of ``step`` (relative, at least ``step``), all columns at once:
        ``weighted``, central differences (their error is of the step squared, where a forward
        difference's is of the step: the final stage walks valleys narrower than 1e-3), else
        forward ones; a step that would cross a bound (``low``, ``high``) goes the other way
        only."""

        def jac(theta: np.ndarray) -> np.ndarray:
            key = (theta.tobytes(), window_s, weighted)
            f0 = self._memo[key] if key in self._memo else self.residuals([theta], window_s, weighted)[0]
            h = step * np.maximum(1.0, np.abs(theta))
            h = np.where(theta + h > high, -h, h)
            unit = np.eye(len(theta))
            points = [theta + h[k] * unit[k] for k in range(len(theta))]
            back = [k for k in range(len(theta)) if weighted and low[k] <= theta[k] - h[k] <= high[k]]
            columns = self.residuals(points + [theta - h[k] * unit[k] for k in back], window_s, weighted)
            behind = dict(zip(back, columns[len(theta) :]))
            self.last_jacobian = np.column_stack(
                [
                    (c - behind[k]) / (2.0 * h[k]) if k in behind else (c - f0) / h[k]
                    for k, c in enumerate(columns[: len(theta)])
                ]
            )
            return self.last_jacobian

        return jac
