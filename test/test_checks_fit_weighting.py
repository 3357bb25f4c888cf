"""A fit's weighting and its intervals (calibration/fit.py) on noisy data at mixed rates, with a
plant whose signals are linear in its two fitted values (no re-simulation: the fit's own
stages, residuals and intervals, each against its closed form): a rod position at 200 Hz with
0.2 mm of noise and a pressure at 50 Hz with 0.1 MPa, each counted in units of the noise the
recording shows, a failed run far above any fit, and intervals that match weighted least
squares' and hold the truth."""

from __future__ import annotations

import math
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from scipy import stats

from boom_hydraulics.calibration import fit
from boom_hydraulics.calibration.signals import Signal

NAMES = ["boom_mass_kg", "payload_mass_kg"]
START = {"boom_mass_kg": 100.0, "payload_mass_kg": 50.0}  # the defaults: the fit's scales
TRUTH = {"boom_mass_kg": 112.0, "payload_mass_kg": 41.0}
NOISE = {"q1": 2e-4, "p1": 1e5}
RATE_HZ = {"q1": 200.0, "p1": 50.0}
ORIGIN_NS = 5 * 10**9
DURATION_S = 2.0


def _signals_of(values: dict[str, float], t: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """The plant: q1 and p1 linear in the boom's and the payload's mass."""
    mb, mp = values["boom_mass_kg"], values["payload_mass_kg"]
    return {
        "q1": 1e-4 * mb * (1.0 + t["q1"]) + 1e-4 * mp * t["q1"] ** 2,
        "p1": 1e4 * (mb * np.cos(3.0 * t["p1"]) + 2.0 * mp),
    }


class LinearProblem(fit.Problem):
    """A fit problem whose simulation is :func:`_signals_of` (None: a failed run, where ``fails``)."""

    fails = staticmethod(lambda values: False)

    def simulate(self, theta):
        self.evaluations += 1
        values = self.values | self.fitted_values(theta)
        return None if self.fails(values) else _signals_of(values, self.times_s)


def _problem(seed: int = 7, weights: dict[str, float] | None = None, noise=NOISE) -> LinearProblem:
    rng = np.random.default_rng(seed)
    times = {s: np.arange(0.0, DURATION_S, 1.0 / RATE_HZ[s]) for s in RATE_HZ}
    clean = _signals_of(TRUTH, times)
    signals = {}
    for s in RATE_HZ:
        log_ns = ORIGIN_NS + np.round(times[s] * 1e9).astype(np.int64)
        signals[s] = Signal(s, log_ns, clean[s] + noise[s] * rng.standard_normal(len(times[s])), f"/{s}")
    weights = {s: 1.0 for s in signals} | (weights or {})
    problem = LinearProblem(
        Path("plant"), SimpleNamespace(clock_origin_ns=ORIGIN_NS), dict(START), {}, NAMES, signals, weights
    )
    problem.inside = {s: np.ones(len(sig.values), bool) for s, sig in signals.items()}
    return problem


def test_each_signals_noise_is_told_from_its_recording_and_its_range_from_its_values():
    problem = _problem()
    for s, sigma in NOISE.items():
        assert 0.7 * sigma < problem.noise[s] < 1.3 * sigma, (s, problem.noise[s])  # 100 samples of p1
        assert problem.ranges[s] == pytest.approx(np.ptp(problem.signals[s].values))
    assert problem.scales == START
    assert problem.times_s["p1"][:3].tolist() == pytest.approx([0.0, 0.02, 0.04])


def test_a_recording_without_noise_counts_at_the_rounding_of_a_16_bit_reading():
    assert fit.NOISE_FLOOR == pytest.approx(1.0 / (65536.0 * math.sqrt(12.0)), rel=1e-15)
    problem = _problem()
    ramp = problem.signals["q1"]
    problem.signals = {
        "q1": Signal("q1", ramp.log_ns, 0.5 + 0.1 * problem.times_s["q1"], "/q1"),  # a straight line
        "p1": Signal("p1", problem.signals["p1"].log_ns, np.full(100, 2e7), "/p1"),  # constant: 20 MPa
    }
    problem.__post_init__()
    assert problem.ranges["p1"] == pytest.approx(20.0)  # a millionth of its size
    for s in RATE_HZ:
        assert problem.noise[s] == pytest.approx(fit.NOISE_FLOOR * problem.ranges[s], rel=1e-9)


def test_the_range_of_a_flat_signal_is_a_millionth_of_its_size():
    assert fit._range(np.array([2.0, 5.0, 3.0])) == 3.0
    assert fit._range(np.array([-5.0, -5.0])) == pytest.approx(5e-6)
    assert fit._range(np.zeros(4)) == 1e-300


def test_the_weighted_residual_is_each_samples_difference_over_its_signals_noise_times_its_weight():
    problem = _problem(weights={"p1": 3.0})
    theta = np.array([1.0, 1.0])
    simulated = problem.simulate(theta)
    r = problem.residual(simulated, weighted=True)
    nq, npr = len(problem.signals["q1"].values), len(problem.signals["p1"].values)
    assert (nq, npr) == (400, 100) and len(r) == nq + npr
    assert problem.segments() == [slice(0, nq), slice(nq, nq + npr)]
    assert problem.signal_weights() == [1.0, 3.0]
    q = (simulated["q1"] - problem.signals["q1"].values) / problem.noise["q1"]
    p = 3.0 * (simulated["p1"] - problem.signals["p1"].values) / problem.noise["p1"]
    assert r[:nq] == pytest.approx(q, rel=1e-12) and r[nq:] == pytest.approx(p, rel=1e-12)
    rms = problem.rms(simulated)
    assert rms["q1"] == pytest.approx(math.sqrt(np.mean((simulated["q1"] - problem.signals["q1"].values) ** 2)))
    assert set(rms) == {"q1", "p1"}


def test_the_coarse_residual_counts_each_signal_alike_in_units_of_its_range():
    problem = _problem(weights={"p1": 2.0})
    simulated = {s: sig.values + 0.5 * problem.ranges[s] for s, sig in problem.signals.items()}  # half a range off
    r = problem.residual(simulated)
    assert r[:400] == pytest.approx(np.full(400, 0.5 / math.sqrt(400)), rel=1e-12)
    assert r[400:] == pytest.approx(np.full(100, 2.0 * 0.5 / math.sqrt(100)), rel=1e-12)
    # each signal's sum of squares is its weight squared times (1/2)^2, whatever its rate
    assert float(r[:400] @ r[:400]) == pytest.approx(0.25) and float(r[400:] @ r[400:]) == pytest.approx(1.0)


def test_the_smoothed_residual_is_a_moving_mean_over_the_window():
    problem = _problem()
    simulated = {s: sig.values.copy() for s, sig in problem.signals.items()}
    simulated["q1"][::2] += 1e-3  # +1 mm at every other sample: averages to 0.5 mm
    simulated["p1"][50] += 1e5  # one sample off
    r = problem.residual(simulated, window_s=0.1)  # 20 samples of q1, 5 of p1
    q = r[: 400 - 20 + 1] * problem.ranges["q1"] * math.sqrt(400 - 20 + 1)
    assert len(r) == (400 - 20 + 1) + (100 - 5 + 1)
    assert q == pytest.approx(np.full(len(q), 0.5e-3), rel=1e-9)
    p = r[381:] * problem.ranges["p1"] * math.sqrt(96)
    assert np.count_nonzero(np.abs(p) > 1.0) == 5 and p.max() == pytest.approx(2e4, rel=1e-9)
    whole = problem.residual(simulated, window_s=100.0)  # a window longer than the run: one mean each
    assert len(whole) == 2 and whole[0] * problem.ranges["q1"] == pytest.approx(0.5e-3, rel=1e-9)
    tiny = problem.residual(simulated, window_s=1e-6)  # shorter than a sample: the samples themselves
    assert len(tiny) == 500


def test_a_failed_run_costs_far_more_than_any_fit():
    problem = _problem()
    weighted = problem.residual(None, weighted=True)
    assert weighted[:400] == pytest.approx(
        np.full(400, fit.FAILED_RESIDUAL * problem.ranges["q1"] / problem.noise["q1"])
    )
    coarse = problem.residual(None)
    assert coarse[:400] == pytest.approx(np.full(400, fit.FAILED_RESIDUAL / math.sqrt(400)))
    assert coarse[400:] == pytest.approx(np.full(100, fit.FAILED_RESIDUAL / math.sqrt(100)))
    assert all(math.isnan(v) for v in problem.rms(None).values())


class _Quadratic:
    """Evaluations of a cost (x0 - 1.3)^2 + (x1 - 0.6)^2, each residual a vector of two."""

    def __init__(self) -> None:
        self.calls: list[int] = []

    def residuals(self, thetas, window_s):
        self.calls.append(len(thetas))
        return [np.array([th[0] - 1.3, th[1] - 0.6]) for th in thetas]


def test_a_scan_keeps_the_best_factor_of_each_parameter_in_turn_within_the_bounds():
    evaluations = _Quadratic()
    best, cost = fit._scan(
        evaluations, np.array([1.0, 1.0]), np.array([0.0, 0.0]), np.array([1.2, 2.0]), 0.0, fit.COARSE_FACTORS
    )
    # x0: 0.5, 0.7, 1.4 -> 1.2 (the bound), 2.0 -> 1.2 (the same trial, kept as one); x1 from there: 0.5
    assert best.tolist() == [1.2, 0.5] and cost == pytest.approx(0.1**2 + 0.1**2)
    assert evaluations.calls == [1, 4, 4]
    at_bound = _Quadratic()
    best, _ = fit._scan(at_bound, np.array([1.2, 0.6]), np.array([0.0, 0.0]), np.array([1.2, 2.0]), 0.0, (1.4, 2.0))
    assert best.tolist() == [1.2, 0.6] and at_bound.calls == [1, 0, 2]  # no trial beyond the bound
    still = _Quadratic()
    best, cost = fit._scan(still, np.array([1.3, 0.6]), np.array([0.0, 0.0]), np.array([3.0, 3.0]), 0.0, (1.0,))
    assert best.tolist() == [1.3, 0.6] and cost == 0.0 and still.calls == [1, 0, 0]  # a factor of 1 tries nothing


def test_the_scans_factors():
    assert fit.WIDE_FACTORS[0] == pytest.approx(1.1**-9) and fit.WIDE_FACTORS[-1] == pytest.approx(1.1**9)
    assert len(fit.WIDE_FACTORS) == 18 and 1.0 not in fit.WIDE_FACTORS
    assert 0.42 < fit.WIDE_FACTORS[0] < 0.43 and 2.35 < fit.WIDE_FACTORS[-1] < 2.36
    assert fit.NEAR_FACTORS == pytest.approx((1.03**-3, 1.03**-2, 1.03**-1, 1.03, 1.03**2, 1.03**3))


def _least_squares_half_widths(problem: LinearProblem) -> np.ndarray:
    """The textbook interval of weighted least squares: J of the residual over the true noise."""
    t = problem.times_s
    columns = []
    for name in NAMES:
        unit = {n: 0.0 for n in NAMES} | {name: START[name]}  # one step of theta in the fit's scale
        columns.append(np.concatenate([_signals_of(unit, t)[s] / NOISE[s] for s in ("q1", "p1")]))
    jac = np.column_stack(columns)
    n = len(jac)
    return (
        stats.t.ppf(0.975, n - 2) * np.sqrt(np.diag(np.linalg.inv(jac.T @ jac))) * np.array([START[n] for n in NAMES])
    )


def test_a_fit_on_noisy_mixed_rate_data_has_least_squares_intervals_that_hold_the_truth():
    problem = _problem()
    result = fit.calibrate(problem, workers=1, starts=1)
    expected = _least_squares_half_widths(problem)
    for k, name in enumerate(NAMES):
        low, high = result.interval[name]
        assert low < TRUTH[name] < high, (name, low, high)
        assert (high - low) / 2 == pytest.approx(expected[k], rel=0.12), name
        assert result.fitted[name] == pytest.approx((low + high) / 2, rel=1e-12)
    assert result.start == START and not any(result.at_bound.values())
    assert result.cost_after < result.cost_before
    assert result.cost_after == pytest.approx(500, rel=0.2)  # chi-square of 500 samples at their noise
    for s in RATE_HZ:
        assert result.rms_after[s] == pytest.approx(NOISE[s], rel=0.15) and result.rms_before[s] > 2 * NOISE[s]
    assert result.exit_status == 0 and result.findings == []
    assert result.correlation.shape == (2, 2) and result.correlation[0, 0] == 1.0
    assert result.evaluations == problem.evaluations > 10 and result.seconds > 0.0
    assert [end.cost for end in result.ends] == [result.cost_after]


def test_a_weight_moves_the_fit_and_its_interval_takes_it_as_it_is():
    right = fit.calibrate(_problem(seed=11), workers=1, starts=1)
    q1_only = fit.calibrate(_problem(seed=11, weights={"p1": 0.01}), workers=1, starts=1)
    for name in NAMES:
        low, high = q1_only.interval[name]
        assert low < TRUTH[name] < high
        rlow, rhigh = right.interval[name]
        assert high - low > rhigh - rlow  # less evidence counted: wider
        assert q1_only.fitted[name] != pytest.approx(right.fitted[name], rel=1e-6)


def test_a_fit_against_its_bound_says_so():
    bounded = _problem()
    # the boom's mass is bounded by 1e-4 kg below: a truth below it is fitted at the bound
    bounded.signals = {
        s: Signal(s, sig.log_ns, _signals_of({"boom_mass_kg": -30.0, "payload_mass_kg": 41.0}, bounded.times_s)[s], s)
        for s, sig in bounded.signals.items()
    }
    bounded.ranges = {s: fit._range(sig.values) for s, sig in bounded.signals.items()}
    result = fit.calibrate(bounded, workers=1, starts=1)
    assert result.at_bound == {"boom_mass_kg": True, "payload_mass_kg": False}
    assert result.fitted["boom_mass_kg"] == pytest.approx(1e-4, rel=1e-6)
    assert result.exit_status != 0


def test_a_start_whose_run_fails_is_refused_and_a_failing_trial_is_left_behind():
    failing = _problem()
    failing.fails = staticmethod(lambda values: True)
    with pytest.raises(fit.SimulationError, match="plant: the re-simulation fails with the start values"):
        fit.calibrate(failing, workers=1, starts=1)
    heavy = _problem()
    heavy.fails = staticmethod(lambda values: values["payload_mass_kg"] > 60.0)  # a heavy payload diverges
    result = fit.calibrate(heavy, workers=1, starts=1)
    low, high = result.interval["payload_mass_kg"]
    assert low < TRUTH["payload_mass_kg"] < high


def test_no_samples_within_the_run_is_refused_in_one_line():
    problem = _problem()
    problem.times_s["p1"] = problem.times_s["p1"] + 100.0
    original = LinearProblem.simulate

    def outside(self, theta):
        out = original(self, theta)
        return out if out is None else out | {"p1": np.full(len(out["p1"]), math.nan)}

    problem.simulate = outside.__get__(problem)
    with pytest.raises(fit.ConfigError, match="plant: no recorded p1 sample falls within the re-simulated run"):
        fit.calibrate(problem, workers=1, starts=1)
