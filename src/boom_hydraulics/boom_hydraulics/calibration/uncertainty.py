"""The confidence intervals of a fit, from the Jacobian and the residual at its solution.

The residual a fit minimises is each recorded sample's difference from the simulation over
its signal's noise (:mod:`.noise`, times the signal's ``--weight``). Its covariance is the
sandwich A^-1 B A^-1 with A = J^T J and B summed signal by signal (the signals' noises are
independent of each other): for signal s, c_s k_s J_s^T J_s, with

- c_s the mean square of its residual: each signal's own noise, as its residual shows it
  (not the noise estimate the weights came from, nor one level shared by signals of
  different units and rates);
- k_s = 1 + 2 sum (1 - l/(L+1)) rho_l, at least 1, over the autocorrelations rho_l of its
  residual up to L = n^(1/3) samples apart (Bartlett weights): n/k_s is its effective number
  of samples, fewer than n where the residual is correlated from sample to sample (a
  sensor sampled faster than its noise changes, a misfit that lasts), which would otherwise
  count as independent evidence;

times n/(n-p); the weights enter as they are. (Newey and West's full estimator, summing the
products J_i r_i J_j r_j themselves, gave intervals 10 to 15 % narrower than the spread of
blind trials' errors on runs of 300 samples; this one is within a few per cent.)

A signal whose residual is below half its estimated noise (a recording without noise, where
what is left is the fit's own resolution) counts as if it were at half its noise: a residual
of zero would give an interval of zero width around wherever the fit stopped.

The half-width is Student's t at LEVEL on n - p degrees of freedom times the standard error.
A direction J does not see (a singular value below 1e-9 of the largest) gives an infinite
half-width.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from scipy import stats

#: Confidence level of the intervals.
LEVEL = 0.95
#: A singular value of J below this fraction of the largest is a direction the signals do not see.
BLIND = 1e-9
#: A signal's residual counts as at least this fraction of its estimated noise.
LEAST_NOISE = 0.5


def inflation(r: np.ndarray) -> float:
    """k = 1 + 2 sum (1 - l/(L+1)) rho_l over the autocorrelations of ``r`` up to L = n^(1/3)
    apart, at least 1: how many samples count as one."""
    lags = math.ceil(len(r) ** (1.0 / 3.0))
    centred = r - r.mean()
    power = float(centred @ centred)
    if power <= 0 or len(r) < 3:
        return 1.0
    total = 0.0
    for lag in range(1, min(lags, len(r) - 1) + 1):
        total += (1.0 - lag / (lags + 1.0)) * float(centred[lag:] @ centred[:-lag]) / power
    return max(1.0, 1.0 + 2.0 * total)


def covariance(
    jac: np.ndarray, residual: np.ndarray, segments: Sequence[slice], weights: Sequence[float]
) -> tuple[np.ndarray, np.ndarray]:
    """(covariance of the fitted values in fit units, whether each value lies in a direction J
    does not see), see the module docstring; ``residual`` each sample's difference over its
    signal's noise times its signal's weight (``weights``, one per segment)."""
    n, p = jac.shape
    _, singular, vt = np.linalg.svd(jac, full_matrices=False)
    seen = singular > BLIND * singular[0] if len(singular) and singular[0] > 0 else np.zeros(p, bool)
    blind = (vt[~seen].T ** 2).sum(axis=1) > 1e-6
    inverse = (vt[seen].T / singular[seen] ** 2) @ vt[seen]  # (J^T J)^-1 on the seen directions
    meat = np.zeros((p, p))
    for segment, weight in zip(segments, weights):
        r = residual[segment]
        rms = float(np.sqrt(np.mean((r / weight) ** 2))) if len(r) else 0.0
        if rms < LEAST_NOISE:  # in units of the noise
            r = r * (LEAST_NOISE / rms) if rms > 0 else np.full(len(r), LEAST_NOISE * weight)
        if len(r):
            block = jac[segment]
            meat += float(np.mean(r * r)) * inflation(r) * (block.T @ block)
    meat *= n / max(n - p, 1)
    return inverse @ meat @ inverse, blind


def half_widths(
    jac: np.ndarray, residual: np.ndarray, segments: Sequence[slice], weights: Sequence[float]
) -> tuple[np.ndarray, np.ndarray]:
    """(the LEVEL interval's half-width of each fitted value in fit units, inf where J does not
    see it; the correlation matrix of the values), see :func:`covariance`."""
    n, p = jac.shape
    dof = n - p
    if dof <= 0:
        return np.full(p, math.inf), np.eye(p)
    cov, blind = covariance(jac, residual, segments, weights)
    deviation = np.sqrt(np.maximum(np.diag(cov), 0.0))
    with np.errstate(divide="ignore", invalid="ignore"):
        correlation = cov / np.outer(deviation, deviation)
    correlation = np.where(np.isfinite(correlation), correlation, 0.0)
    np.fill_diagonal(correlation, 1.0)
    half = stats.t.ppf(0.5 + LEVEL / 2, dof) * deviation
    return np.where(blind, math.inf, half), correlation
