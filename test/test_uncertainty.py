"""A fit's confidence intervals (calibration/uncertainty.py) against closed forms: the mean of
independent samples (Student's t over sqrt(n)), a straight line's correlated slope and
intercept, signals of different noise counted each by its own residual, a correlated residual
counting as fewer samples, the floor of half the noise, and directions the signals do not see."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from boom_hydraulics.calibration.uncertainty import BLIND, LEAST_NOISE, LEVEL, covariance, half_widths, inflation


def _alternating(n: int, level: float = 1.0) -> np.ndarray:
    """A residual of +-level, sample by sample: no positive correlation (k = 1)."""
    return level * np.where(np.arange(n) % 2 == 0, 1.0, -1.0)


def test_inflation_of_a_worked_example():
    # r = 1..5: centred -2..2, power 10; L = ceil(5^(1/3)) = 2; rho_1 = 4/10, rho_2 = -1/10;
    # k = 1 + 2 (2/3 * 0.4 + 1/3 * -0.1) = 1 + 2 * 0.7/3.
    assert inflation(np.arange(1.0, 6.0)) == pytest.approx(1.0 + 1.4 / 3.0, rel=1e-12)
    # n = 9: L = ceil(9^(1/3)) = 3 lags, a ramp's rho_l = sum c_i c_(i+l) / power.
    r = np.arange(9.0)
    c = r - r.mean()
    rho = [float(c[lag:] @ c[:-lag]) / float(c @ c) for lag in (1, 2, 3)]
    expected = 1.0 + 2.0 * sum((1.0 - lag / 4.0) * rho[lag - 1] for lag in (1, 2, 3))
    assert inflation(r) == pytest.approx(expected, rel=1e-12)


def test_inflation_is_one_for_independent_alternating_constant_and_tiny_residuals():
    assert inflation(_alternating(50)) == 1.0  # negative correlation does not count as more samples
    assert inflation(np.full(20, 3.0)) == 1.0  # no variation about the mean
    assert inflation(np.array([1.0, 2.0])) == 1.0 and inflation(np.array([5.0])) == 1.0
    white = np.random.default_rng(4).standard_normal(4000)
    assert 1.0 <= inflation(white) < 1.15


def test_a_slow_residual_counts_as_fewer_samples():
    # An AR(1) residual with rho = 0.9 over many samples: k approaches (1 + rho)/(1 - rho) = 19
    # only with many lags; with L = n^(1/3) and Bartlett weights it is well above 1 but below 19.
    rng = np.random.default_rng(1)
    r = np.zeros(8000)
    for i in range(1, len(r)):
        r[i] = 0.9 * r[i - 1] + rng.standard_normal()
    k = inflation(r)
    assert 5.0 < k < 19.0


def test_the_interval_of_a_mean_is_students_t_over_root_n():
    n = 10
    jac = np.ones((n, 1))
    half, correlation = half_widths(jac, _alternating(n), [slice(0, n)], [1.0])
    # s^2 = sum r^2 / (n - 1) = 10/9; standard error s / sqrt(n) = 1/3.
    assert LEVEL == 0.95
    assert half[0] == pytest.approx(stats.t.ppf(0.975, n - 1) / 3.0, rel=1e-12)
    assert correlation.tolist() == [[1.0]]
    # a value seen weakly (every singular value below 1) is seen all the same: 10 times as wide
    faint, _ = half_widths(0.1 * jac, _alternating(n), [slice(0, n)], [1.0])
    assert faint[0] == pytest.approx(10.0 * half[0], rel=1e-12)
    cov, blind = covariance(jac, _alternating(n), [slice(0, n)], [1.0])
    assert cov[0, 0] == pytest.approx(1.0 / 9.0, rel=1e-12) and not blind.any()


def test_a_line_fit_has_the_textbook_covariance_and_correlation():
    t = np.linspace(0.0, 2.0, 12)
    jac = np.column_stack([np.ones_like(t), t])
    r = _alternating(len(t), 0.8)
    cov, _ = covariance(jac, r, [slice(0, len(t))], [1.0])
    s2 = float(r @ r) / (len(t) - 2)
    assert cov == pytest.approx(s2 * np.linalg.inv(jac.T @ jac), rel=1e-10)
    half, correlation = half_widths(jac, r, [slice(0, len(t))], [1.0])
    assert half == pytest.approx(stats.t.ppf(0.975, len(t) - 2) * np.sqrt(np.diag(cov)), rel=1e-10)
    expected = -t.sum() / math.sqrt(len(t) * float(t @ t))
    assert correlation[0, 1] == pytest.approx(expected, rel=1e-10) and correlation[1, 0] == correlation[0, 1]
    assert np.diag(correlation).tolist() == [1.0, 1.0]


def test_each_signal_counts_with_its_own_residual():
    """Two signals of 10 samples, one seeing the value twice as strongly and three times as noisy:
    B = 1 * 10 + 9 * 40, A = 10 + 40; not one noise level pooled over both."""
    jac = np.concatenate([np.ones(10), 2.0 * np.ones(10)])[:, None]
    r = np.concatenate([_alternating(10, 1.0), _alternating(10, 3.0)])
    cov, _ = covariance(jac, r, [slice(0, 10), slice(10, 20)], [1.0, 1.0])
    assert cov[0, 0] == pytest.approx(370.0 * (20.0 / 19.0) / 50.0**2, rel=1e-12)


def test_a_correlated_residual_widens_the_interval_by_the_root_of_its_inflation():
    n = 64
    slow = np.where((np.arange(n) // 8) % 2 == 0, 1.0, -1.0)  # a misfit that lasts 8 samples
    k = inflation(slow)
    assert k > 2.0
    jac = np.ones((n, 1))
    wide, _ = half_widths(jac, slow, [slice(0, n)], [1.0])
    narrow, _ = half_widths(jac, _alternating(n), [slice(0, n)], [1.0])
    assert wide[0] == pytest.approx(math.sqrt(k) * narrow[0], rel=1e-12)


def test_a_residual_below_half_the_noise_counts_as_half_the_noise():
    assert LEAST_NOISE == 0.5
    n, weight = 10, 2.0
    jac = np.ones((n, 1))
    floor, _ = covariance(jac, _alternating(n, LEAST_NOISE * weight), [slice(0, n)], [weight])
    below, _ = covariance(jac, _alternating(n, 0.1 * weight), [slice(0, n)], [weight])
    assert below[0, 0] == pytest.approx(floor[0, 0], rel=1e-12)
    # floor: r^2 = (0.5 w)^2 = 1 in fit units: cov = 1 * n * n/(n-1) / n^2
    assert floor[0, 0] == pytest.approx(1.0 / (n - 1), rel=1e-12)
    zero, _ = covariance(jac, np.zeros(n), [slice(0, n)], [weight])  # a recording without noise
    assert zero[0, 0] == pytest.approx(floor[0, 0], rel=1e-12)
    above, _ = covariance(jac, _alternating(n, 0.6 * weight), [slice(0, n)], [weight])
    assert above[0, 0] == pytest.approx(floor[0, 0] * (0.6 / 0.5) ** 2, rel=1e-12)  # taken as it is


def test_a_weighted_signal_is_judged_in_units_of_its_own_noise():
    """A residual of 0.8 with weight 2 is 0.4 of its noise: below the floor, raised to 0.5 of it
    (r = 1.0); the same residual with weight 1 is 0.8 of its noise, taken as it is."""
    n = 10
    jac = np.ones((n, 1))
    weighted, _ = covariance(jac, _alternating(n, 0.8), [slice(0, n)], [2.0])
    plain, _ = covariance(jac, _alternating(n, 0.8), [slice(0, n)], [1.0])
    assert weighted[0, 0] == pytest.approx(1.0 / (n - 1), rel=1e-12)
    assert plain[0, 0] == pytest.approx(0.64 / (n - 1), rel=1e-12)


def test_an_empty_signal_adds_nothing():
    n = 10
    jac = np.ones((n, 1))
    alone, _ = covariance(jac, _alternating(n), [slice(0, n)], [1.0])
    with_empty, _ = covariance(jac, _alternating(n), [slice(0, n), slice(n, n)], [1.0, 3.0])
    assert with_empty[0, 0] == pytest.approx(alone[0, 0], rel=1e-12)


def test_a_value_the_signals_do_not_see_has_an_infinite_interval():
    n = 8
    t = np.arange(n, dtype=float)
    unseen = np.column_stack([np.ones(n), t, np.zeros(n)])
    half, correlation = half_widths(unseen, _alternating(n), [slice(0, n)], [1.0])
    assert np.isfinite(half[:2]).all() and half[2] == math.inf
    assert correlation[2].tolist() == [0.0, 0.0, 1.0] and np.isfinite(correlation).all()
    # two values seen only together (their sum): neither alone is known
    together = np.column_stack([t, t])
    half, _ = half_widths(together, _alternating(n), [slice(0, n)], [1.0])
    assert (half == math.inf).all()
    # a value seen faintly but above BLIND is known, with a wide interval
    assert BLIND == 1e-9
    faint = np.column_stack([np.ones(n), 1e-7 * t])
    half, _ = half_widths(faint, _alternating(n), [slice(0, n)], [1.0])
    assert np.isfinite(half).all() and half[1] > 1e6 * half[0]
    blind = np.column_stack([np.ones(n), 1e-11 * t])
    assert half_widths(blind, _alternating(n), [slice(0, n)], [1.0])[0][1] == math.inf
    # blind is relative to the best-seen direction, not an absolute size: in pascals, say
    assert half_widths(1e6 * blind, _alternating(n), [slice(0, n)], [1.0])[0][1] == math.inf
    nothing = np.zeros((n, 2))
    assert (half_widths(nothing, _alternating(n), [slice(0, n)], [1.0])[0] == math.inf).all()


def test_no_interval_without_more_samples_than_values():
    jac = np.column_stack([np.ones(3), np.arange(3.0), np.arange(3.0) ** 2])
    half, correlation = half_widths(jac, np.array([0.1, -0.2, 0.1]), [slice(0, 3)], [1.0])
    assert (half == math.inf).all() and (correlation == np.eye(3)).all()
    jac4 = np.column_stack([np.ones(4), np.arange(4.0), np.arange(4.0) ** 2])
    half, _ = half_widths(jac4, _alternating(4), [slice(0, 4)], [1.0])  # one degree of freedom
    assert np.isfinite(half).all()
    cov, _ = covariance(jac4, _alternating(4), [slice(0, 4)], [1.0])
    assert half == pytest.approx(stats.t.ppf(0.975, 1) * np.sqrt(np.diag(cov)), rel=1e-12)


def test_one_degree_of_freedom_in_closed_form():
    # n = 2, p = 1: r = +-1, mean square 1; B = 1 * 2 * 2/1, A = 2: variance 4/4 = 1.
    cov, _ = covariance(np.ones((2, 1)), np.array([1.0, -1.0]), [slice(0, 2)], [1.0])
    assert cov[0, 0] == pytest.approx(1.0, rel=1e-12)
    half, _ = half_widths(np.ones((2, 1)), np.array([1.0, -1.0]), [slice(0, 2)], [1.0])
    assert half[0] == pytest.approx(12.706204736, rel=1e-9)  # Student's t, 97.5 %, 1 degree of freedom


def test_fewer_samples_than_values_have_no_interval():
    jac = np.column_stack([np.ones(2), np.arange(2.0), np.arange(2.0) ** 2])
    half, correlation = half_widths(jac, np.array([0.5, -0.5]), [slice(0, 2)], [1.0])
    assert (half == math.inf).all() and (correlation == np.eye(3)).all()


def test_a_value_all_but_orthogonal_to_an_unseen_direction_is_known():
    """Two values seen only as their sum and a third whose share of that blind direction is 1e-4
    (1e-8 of its variance, below the 1e-6 that counts as blind): the third is known."""
    n = 10
    t = np.linspace(0.0, 1.0, n)
    jac = np.column_stack([np.ones(n), t, t + 1.4e-4])  # c2 - c1 = 1.4e-4 c0: blind along (1.4e-4, 1, -1)
    half, _ = half_widths(jac, _alternating(n), [slice(0, n)], [1.0])
    assert math.isfinite(half[0]) and half[1] == math.inf and half[2] == math.inf


def test_a_correlated_residual_below_the_floor_keeps_its_correlation():
    n = 64
    slow = np.where((np.arange(n) // 8) % 2 == 0, 1.0, -1.0)
    jac = np.ones((n, 1))
    quiet, _ = covariance(jac, 0.1 * slow, [slice(0, n)], [1.0])  # a tenth of the noise: raised to half
    floor, _ = covariance(jac, 0.5 * slow, [slice(0, n)], [1.0])
    assert quiet[0, 0] == pytest.approx(floor[0, 0], rel=1e-12)
    assert quiet[0, 0] == pytest.approx(0.25 * inflation(slow) / (n - 1), rel=1e-12)


def test_how_many_samples_count_as_one_does_not_depend_on_the_residuals_size():
    slow = np.where((np.arange(64) // 8) % 2 == 0, 1.0, -1.0)
    assert inflation(slow) > 2.0
    for scale in (1e-3, 0.1, 1e4):  # a residual in units of a small noise, or of a large one
        assert inflation(scale * slow) == pytest.approx(inflation(slow), rel=1e-12)
