"""Where a fit starts: the given start values and more, spread over a wide span of each
parameter, so that a start far off (at a bound, a decade out) does not decide the answer.

Each parameter's span reaches a decade beyond both its start value and the model's default
(a typical machine's) on either side, within the fit's bounds, in log space (a positive
span; a parameter that can be zero or negative in a linear one). The extra starts are a
Latin hypercube over those spans: each parameter's span cut into as many strata as starts,
one start in each, in a random pairing, seeded, so that a fit gives the same answer every
time.
"""

from __future__ import annotations

import numpy as np
from scipy.stats import qmc

#: A span reaches this factor beyond the start value and the default on either side.
REACH = 10.0
#: The seed of the extra starts.
SEED = 20261206


def spans(
    start: np.ndarray, default: np.ndarray, low: np.ndarray, high: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(lower, upper, whether in log space) of each parameter's span (see the module docstring)."""
    small = np.minimum(start, default)
    large = np.maximum(start, default)
    logarithmic = small > 0
    width = REACH * np.maximum(np.abs(large - small), np.maximum(np.abs(small), np.abs(large)))
    width = np.where(width > 0, width, 1.0)  # a start and default of 0: 1 either side
    lower = np.where(logarithmic, small / REACH, small - width)
    upper = np.where(logarithmic, large * REACH, large + width)
    lower, upper = np.maximum(lower, low), np.minimum(upper, high)
    logarithmic &= lower > 0
    return lower, upper, logarithmic


def starts(
    start: np.ndarray, default: np.ndarray, low: np.ndarray, high: np.ndarray, count: int, seed: int = SEED
) -> list[np.ndarray]:
    """``start`` and ``count - 1`` more starts spread over the spans (see the module docstring)."""
    if count <= 1:
        return [start]
    lower, upper, logarithmic = spans(start, default, low, high)
    unit = qmc.LatinHypercube(d=len(start), seed=np.random.default_rng(seed)).random(count - 1)
    log_lower = np.log(np.where(logarithmic, lower, 1.0))
    log_upper = np.log(np.where(logarithmic, upper, 1.0))
    spread = np.where(logarithmic, np.exp(log_lower + unit * (log_upper - log_lower)), lower + unit * (upper - lower))
    return [start] + [np.clip(row, low, high) for row in spread]
