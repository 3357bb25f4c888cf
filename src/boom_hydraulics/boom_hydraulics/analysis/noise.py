"""How noisy a recorded signal is, told from the signal itself.

A sensor's noise is white and the motion it measures is smooth at its sampling rate, so how
far each sample lies off the straight line through its two neighbours (at their times, as
irregular as they come) is mostly noise: for white noise of deviation sigma that distance
has deviation sigma sqrt(1 + a^2 + b^2), a and b the neighbours' shares of the line, while
a smooth signal's is its curvature times the spacing squared. The median absolute deviation
of those distances (each over its sqrt(1 + a^2 + b^2), times 1.4826, a normal deviation's)
is robust: a jump, an end stop's knock or a valve's opening touches only a few of them.
The estimate is high where a signal rings at near its sampling rate, never low.
"""

from __future__ import annotations

import numpy as np

#: A normal distribution's deviation over its median absolute deviation.
MAD_TO_SIGMA = 1.4826


def robust_deviation(x: np.ndarray) -> float:
    """1.4826 times the median absolute deviation of ``x`` from its median (0 for fewer than 2)."""
    x = np.asarray(x, dtype=float)
    x = x[np.isfinite(x)]
    if len(x) < 2:
        return 0.0
    return MAD_TO_SIGMA * float(np.median(np.abs(x - np.median(x))))


def noise_level(values: np.ndarray, times: np.ndarray | None = None) -> float:
    """The deviation of the white noise on ``values`` (samples in time order, at ``times``;
    None: evenly spaced), see the module docstring; 0 for fewer than 3 samples."""
    x = np.asarray(values, dtype=float)
    if len(x) < 3:
        return 0.0
    t = np.arange(len(x), dtype=float) if times is None else np.asarray(times, dtype=float)
    span = t[2:] - t[:-2]
    keep = span > 0
    b = np.divide(t[1:-1] - t[:-2], span, out=np.full(len(span), 0.5), where=keep)  # the next one's share
    a = 1.0 - b
    off = (x[1:-1] - (a * x[:-2] + b * x[2:])) / np.sqrt(1.0 + a * a + b * b)
    return robust_deviation(off)
