"""A fit's weighting and its intervals (calibration/fit.py) on noisy data at mixed rates, with a
plant whose signals are linear in its two fitted values (no re-simulation: the fit's own
stages, residuals and intervals, each against its closed form): a rod position at 200 Hz with
0.2 mm of noise and a pressure at 50 Hz with 0.1 MPa, each counted in units of the noise the
recording shows, a failed run far above any fit, and intervals that match weighted least
squares' and hold the truth."""

from __future__ import annotations

import dataclasses
import math
import re
import time
from pathlib import Path
from types import SimpleNamespace
from typing import ClassVar

import numpy as np
import pytest
from machine_bags import EPOCH_NS, params_file, record_machine
from scipy import stats

from boom_hydraulics.analysis.linear_model import mid_stroke_modes
from boom_hydraulics.calibration import fit, starts
from boom_hydraulics.calibration.fittable import bounds
from boom_hydraulics.calibration.signals import Signal
from boom_hydraulics.resim.resimulation import Replay

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


def _problem(
    seed: int = 7, weights: dict[str, float] | None = None, noise=NOISE, start=START, kind=LinearProblem
) -> LinearProblem:
    rng = np.random.default_rng(seed)
    times = {s: np.arange(0.0, DURATION_S, 1.0 / RATE_HZ[s]) for s in RATE_HZ}
    clean = _signals_of(TRUTH, times)
    signals = {}
    for s in RATE_HZ:
        log_ns = ORIGIN_NS + np.round(times[s] * 1e9).astype(np.int64)
        signals[s] = Signal(s, log_ns, clean[s] + noise[s] * rng.standard_normal(len(times[s])), f"/{s}")
    weights = {s: 1.0 for s in signals} | (weights or {})
    problem = kind(Path("plant"), SimpleNamespace(clock_origin_ns=ORIGIN_NS), dict(start), {}, NAMES, signals, weights)
    problem.inside = {s: np.ones(len(sig.values), bool) for s, sig in signals.items()}
    return problem


def test_each_signals_noise_is_told_from_its_recording_and_its_range_from_its_values():
    problem = _problem()
    for s, sigma in NOISE.items():
        assert 0.7 * sigma < problem.noise[s] < 1.3 * sigma, (s, problem.noise[s])  # 100 samples of p1
        assert problem.ranges[s] == pytest.approx(np.ptp(problem.signals[s].values))
    assert problem.scales == START
    assert problem.times_s["p1"][:3].tolist() == pytest.approx([0.0, 0.02, 0.04])


def test_a_sample_before_the_runs_clock_origin_is_at_a_negative_time_and_a_parameter_starting_at_0_has_a_unit_scale():
    problem = _problem(start={"boom_mass_kg": 100.0, "payload_mass_kg": 0.0})
    problem.run = SimpleNamespace(clock_origin_ns=ORIGIN_NS + 10**9)  # a second after the first samples
    problem.__post_init__()
    assert problem.times_s["p1"][:2].tolist() == pytest.approx([-1.0, -0.98], rel=1e-12)
    assert problem.scales == {"boom_mass_kg": 100.0, "payload_mass_kg": 1.0}
    assert problem.fitted_values([1.5, 41.0]) == {"boom_mass_kg": 150.0, "payload_mass_kg": 41.0}


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


def test_a_straight_line_logged_at_jittered_times_shows_no_noise_but_the_floor():
    problem = _problem()
    rng = np.random.default_rng(5)
    jittered = np.sort(problem.times_s["q1"] + rng.uniform(-1e-3, 1e-3, 400))  # 200 Hz, +-1 ms
    log_ns = ORIGIN_NS + np.round(jittered * 1e9).astype(np.int64)
    line = 0.5 + 0.1 * (log_ns - ORIGIN_NS) * 1e-9  # 0.1 m/s, exact at each log time
    problem.signals = {"q1": Signal("q1", log_ns, line, "/q1")}
    problem.__post_init__()
    assert problem.noise["q1"] == pytest.approx(fit.NOISE_FLOOR * problem.ranges["q1"], rel=1e-9)


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
    coarse = problem.residual(None)  # ten ranges off at every sample: 100 a signal, where a fit costs 1 at most
    assert coarse[:400] == pytest.approx(np.full(400, 10.0 / math.sqrt(400)))
    assert coarse[400:] == pytest.approx(np.full(100, 10.0 / math.sqrt(100)))
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
    began = time.perf_counter()
    result = fit.calibrate(problem, workers=1, starts=1)
    took = time.perf_counter() - began
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
    # the last least squares stopped where its step moved each value far inside its interval
    assert "callback" in result.message, result.message
    assert result.correlation.shape == (2, 2) and result.correlation[0, 0] == 1.0
    assert result.evaluations == problem.evaluations > 10 and 0.0 < result.seconds <= took
    assert [end.cost for end in result.ends] == [result.cost_after]
    assert result.ends[0].start == START and result.ends[0].end == result.fitted
    with pytest.raises(dataclasses.FrozenInstanceError):  # an outcome, not to be changed
        result.fitted = TRUTH


class _Logged(LinearProblem):
    """A LinearProblem that keeps the values it simulates and the residuals asked of it."""

    def __post_init__(self) -> None:
        super().__post_init__()
        self.tried: list[dict[str, float]] = []
        self.asked: list[tuple[float, bool]] = []  # (window s, weighted)

    def simulate(self, theta):
        self.tried.append(self.fitted_values(theta))
        return super().simulate(theta)

    def residual(self, simulated, window_s=0.0, weighted=False):
        self.asked.append((window_s, weighted))
        return super().residual(simulated, window_s, weighted)


def test_the_coarse_scan_tries_each_parameter_at_half_to_twice_its_start_averaged_over_4_periods_of_the_mode():
    problem = _problem(kind=_Logged)
    fit.calibrate(problem, workers=1, starts=1)
    assert problem.tried[0] == START == problem.tried[1]  # the start, then the scan's base
    assert [t["boom_mass_kg"] for t in problem.tried[2:6]] == pytest.approx([50.0, 70.0, 140.0, 200.0])
    assert all(t["payload_mass_kg"] == 50.0 for t in problem.tried[2:6])
    frequency = float(mid_stroke_modes([problem.start])[0][0])
    assert 1.0 < frequency < 100.0
    assert problem.asked[0] == (0.0, True)  # the start's cost
    assert problem.asked[1] == (pytest.approx(4.0 / frequency, rel=1e-12), False)
    # the scan's 1 + 2 x 4 and stage 2's least squares, all on the averaged residual (in ranges)
    smoothed = [weighted for window, weighted in problem.asked if window > 0.0]
    assert len(smoothed) > 1 + 2 * 4 and not any(smoothed)
    # and the rest, stage 3's scans and the last least squares, on the raw residual
    assert {window for window, _ in problem.asked} == {0.0, problem.asked[1][0]}


def test_a_start_without_an_oscillating_mode_averages_over_4_periods_of_8_hz():
    problem = _problem(kind=_Logged)
    problem.values["mode"] = "paper"  # the paper's model: no hydraulic mode
    problem.__post_init__()
    assert math.isnan(mid_stroke_modes([problem.start])[0][0])
    fit.calibrate(problem, workers=1, starts=1)
    assert problem.asked[1] == (pytest.approx(0.5, rel=1e-12), False)


def test_more_starts_spread_between_the_start_and_the_default_each_end_at_its_own_cost_the_best_first():
    far = {"boom_mass_kg": 300.0, "payload_mass_kg": 20.0}  # well off the defaults (100 and 50)
    problem = _problem(start=far)
    result = fit.calibrate(problem, workers=1, starts=3)
    scales = np.array([far[n] for n in NAMES])
    low, high = (np.array([bounds(n, problem.start, NAMES)[i] for n in NAMES]) / scales for i in (0, 1))
    spread = starts.starts(np.ones(2), np.array([100.0, 50.0]) / scales, low, high, 3)
    expected = np.array(sorted(tuple(point * scales) for point in spread))
    began = np.array(sorted(tuple(end.start[n] for n in NAMES) for end in result.ends))
    np.testing.assert_allclose(began, expected, rtol=1e-12)
    assert result.start == far and result.ends[0].end == result.fitted and result.ends[0].cost == result.cost_after
    for end in result.ends:
        r = problem.residual(problem.simulate(np.array([end.end[n] for n in NAMES]) / scales), weighted=True)
        assert end.cost == pytest.approx(float(r @ r), rel=1e-9)  # the chi-square of where it ended
        for name in NAMES:
            assert end.end[name] == pytest.approx(TRUTH[name], rel=0.05)
    # the others ended stage 3 in the valley of the best (within 1 % of each value): they are not
    # refined again, but left where stage 3 left them, above the best's chi-square
    for end in result.ends[1:]:
        assert end.cost > 1.05 * result.cost_after
    # and, far above the best (by more than the chi-square's 95 % on 2 values), they tell nothing
    assert result.exit_status == 0 and result.findings == []
    low, high = result.interval["boom_mass_kg"]
    assert low < TRUTH["boom_mass_kg"] < high


class _Folded(LinearProblem):
    """The plant with the boom's mass folded at 100 kg: a boom of 100 - d kg shows as one of 100 + d
    (two answers, 88 and 112 kg, fit the recording equally)."""

    def simulate(self, theta):
        self.evaluations += 1
        values = self.values | self.fitted_values(theta)
        values["boom_mass_kg"] = 100.0 + abs(values["boom_mass_kg"] - 100.0)
        return _signals_of(values, self.times_s)


def test_a_start_ending_as_well_in_another_valley_is_refined_and_makes_the_fit_not_identifiable():
    problem = _problem(start={"boom_mass_kg": 105.0, "payload_mass_kg": 50.0}, kind=_Folded)
    result = fit.calibrate(problem, workers=1, starts=3)
    valleys = sorted(end.end["boom_mass_kg"] for end in result.ends[:2])
    # the two valleys refined first, the best of them the fit, each at its answer, mirrored at 100 kg
    assert valleys[0] == pytest.approx(200.0 - valleys[1], rel=1e-6) and 111.0 < valleys[1] < 113.0
    assert result.ends[0].end == result.fitted
    assert result.ends[1].cost == pytest.approx(result.cost_after, rel=1e-9)
    assert result.ends[2].cost > 1.05 * result.cost_after  # the best's valley, left as stage 3 left it
    low, high = result.interval["boom_mass_kg"]
    assert high - low < 1.0  # each answer is sharp, yet the other is as good
    assert result.exit_status == 4
    (finding,) = result.findings
    assert finding.subject == "boom_mass_kg" and "ended as well at" in finding.why


def test_the_fit_on_every_core_from_4_starts_by_default_is_the_fit_on_one():
    one = fit.calibrate(_problem(seed=3), workers=1, starts=4)
    every = fit.calibrate(_problem(seed=3))
    assert len(every.ends) == 4
    assert every.fitted == pytest.approx(one.fitted, rel=1e-12)
    assert every.interval == one.interval


def test_a_weight_moves_the_fit_and_its_interval_takes_it_as_it_is():
    right = fit.calibrate(_problem(seed=11), workers=1, starts=1)
    q1_only = fit.calibrate(_problem(seed=11, weights={"p1": 0.01}), workers=1, starts=1)
    for name in NAMES:
        low, high = q1_only.interval[name]
        assert low < TRUTH[name] < high
        rlow, rhigh = right.interval[name]
        assert high - low > rhigh - rlow  # less evidence counted: wider
        assert q1_only.fitted[name] != pytest.approx(right.fitted[name], rel=1e-6)


@pytest.mark.parametrize(
    ("truth", "at_bound", "value"),
    [
        # the boom's mass is bounded by 1e-4 kg below: a truth below it is fitted at the bound
        ({"boom_mass_kg": -30.0, "payload_mass_kg": 41.0}, {"boom_mass_kg": True, "payload_mass_kg": False}, 1e-4),
        # and the payload's by 100 t above
        ({"boom_mass_kg": 112.0, "payload_mass_kg": 2e5}, {"boom_mass_kg": False, "payload_mass_kg": True}, 1e5),
    ],
)
def test_a_fit_against_its_bound_says_so(truth, at_bound, value):
    bounded = _problem()
    bounded.signals = {
        s: Signal(s, sig.log_ns, _signals_of(truth, bounded.times_s)[s], s) for s, sig in bounded.signals.items()
    }
    bounded.ranges = {s: fit._range(sig.values) for s, sig in bounded.signals.items()}
    result = fit.calibrate(bounded, workers=1, starts=1)
    assert result.at_bound == at_bound
    (name,) = (n for n, bound in at_bound.items() if bound)
    assert result.fitted[name] == pytest.approx(value, rel=1e-6)
    assert result.exit_status != 0
    # it converged there, its residual above the noise: not a fit stopped at --max-evaluations
    assert "least squares" not in {f.subject for f in result.findings}
    stopped = fit.calibrate(bounded, max_evaluations=2, workers=1, starts=1)
    assert "least squares" in {f.subject for f in stopped.findings}


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


@pytest.mark.parametrize("within", [1, 2])
def test_a_signal_needs_two_samples_within_the_run(within):
    problem = _problem()
    original = LinearProblem.simulate

    def few(self, theta):
        out = original(self, theta)
        if out is not None:
            out["p1"][within:] = math.nan  # only the first ``within`` samples of p1 within the run
        return out

    problem.simulate = few.__get__(problem)
    if within < 2:
        with pytest.raises(fit.ConfigError, match="no recorded p1 sample falls within"):
            fit.calibrate(problem, workers=1, starts=1)
    else:
        result = fit.calibrate(problem, workers=1, starts=1)
        assert problem.segments() == [slice(0, 400), slice(400, 402)]
        assert result.fitted["boom_mass_kg"] == pytest.approx(TRUTH["boom_mass_kg"], rel=0.01)


# -- a machine's bag: what prepare reads and what a re-simulation gives at the recorded instants

#: The machine's sensors: the rod position at 1 kHz, the pressures at 200 and 100 Hz, with noise.
BAG_RATES_HZ = {"q1": 1000.0, "p1": 200.0, "p2": 100.0}
BAG_NOISE = {"q1": 2e-4, "p1": 5e4, "p2": 5e4}


@pytest.fixture(scope="module")
def machine(tmp_path_factory) -> Path:
    """A machine's bag (no run description) of 50 ms of a lift from rest, its log times jittered."""
    folder = tmp_path_factory.mktemp("machine") / "bag"
    return record_machine(folder, commands=((0.0, 1.0),), duration_s=0.05, rate_hz=BAG_RATES_HZ, noise=BAG_NOISE)


@pytest.fixture(scope="module")
def still(tmp_path_factory) -> Path:
    """A machine's bag without a command."""
    return record_machine(tmp_path_factory.mktemp("still") / "bag", commands=(), duration_s=0.02)


def _prepared(machine: Path, folder: Path, **kwargs) -> fit.Problem:
    """The boom's and payload's masses to fit to ``machine`` from a config of a 1 ms step."""
    return fit.prepare(machine, NAMES, params_file(folder / "start.yaml", {"time_step_s": 1e-3}), **kwargs)


def test_a_machines_bag_runs_from_its_first_message_sampled_every_step_of_its_config_and_the_set_values(
    machine, tmp_path
):
    overrides = {"time_step_s": 5e-4, "payload_mass_kg": 60.0}
    problem = _prepared(machine, tmp_path, overrides=overrides, weights={"p1": 0.5}, command_timeout_s=0.25)
    description = problem.run.description
    assert description.clock_origin_ns == EPOCH_NS == problem.run.clock_origin_ns
    assert description.publish_rate_hz == pytest.approx(2000.0)  # every step of --set's 0.5 ms, not the config's
    assert description.command_timeout_s == 0.25
    assert problem.start.payload_mass_kg == 60.0 and problem.start.time_step_s == 5e-4
    assert problem.scales == {"boom_mass_kg": 100.0, "payload_mass_kg": 60.0}
    assert list(problem.signals) == list(fit.DEFAULT_SIGNALS) and problem.names == NAMES
    assert problem.weights == {"q1": 1.0, "p1": 0.5, "p2": 1.0}  # --weight's, else 1
    assert problem.times_s["q1"][0] == 0.0 and 0.04 < problem.times_s["q1"][-1] < 0.055
    # the rod position's noise from its 50 samples, jittered log times at an epoch's nanoseconds
    assert 0.6 * BAG_NOISE["q1"] < problem.noise["q1"] < 1.4 * BAG_NOISE["q1"], problem.noise["q1"]
    assert problem.evaluations == 0


@pytest.mark.parametrize(
    ("weights", "message"),
    [
        ({"v": 2.0}, "--weight v: not one of the signals fitted (q1, p1, p2)"),
        ({"z": 2.0, "a": 2.0}, "--weight a: not one of the signals fitted"),  # the first, sorted
        ({"q1": 0.0}, "--weight must be positive and finite"),
        ({"p1": -1.0}, "--weight must be positive and finite"),
        ({"p2": math.inf}, "--weight must be positive and finite"),
        ({"q1": math.nan}, "--weight must be positive and finite"),
    ],
)
def test_a_weight_of_no_signal_fitted_or_not_positive_and_finite_is_refused_in_one_line(
    machine, tmp_path, weights, message
):
    with pytest.raises(fit.ConfigError, match=re.escape(message)):
        _prepared(machine, tmp_path, weights=weights)


def test_a_bag_without_run_description_or_config_or_commands_is_refused(machine, still, tmp_path):
    with pytest.raises(fit.ConfigError, match=r"has no run description .* give --config"):
        fit.prepare(machine, NAMES)
    with pytest.raises(fit.ConfigError, match=r"holds no valve commands .* nothing to re-simulate"):
        _prepared(still, tmp_path)
    with pytest.raises(fit.ConfigError, match="--fit names no parameter"):  # before anything else
        fit.prepare(machine, [], weights={"v": 2.0})


class _Told(Replay):
    """A Replay that keeps each instant it gives: (stamp ns, q1, p1, p2)."""

    given: ClassVar[list[tuple[int, float, float, float]]] = []

    def __iter__(self):
        for stamp_ns, outputs in super().__iter__():
            self.given.append((stamp_ns, outputs["q1"], outputs["p1"], outputs["p2"]))
            yield stamp_ns, outputs


def test_the_simulation_is_compared_at_each_samples_instant_linear_between_the_simulated_ones(
    machine, tmp_path, monkeypatch
):
    problem = _prepared(machine, tmp_path, signal_names=("p1", "p2"))  # the pressures end before the rod position
    assert problem.run.description.command_timeout_s == 0.0  # none unless given
    theta = np.array([1.3, 0.8])
    # the whole run at the fitted values, as boom-resim would give it
    replay = Replay(problem.run, problem.values, problem.fitted_values(theta))
    whole = [(t, o["q1"], o["p1"], o["p2"]) for t, o in replay]
    monkeypatch.setattr(_Told, "given", [])
    monkeypatch.setattr(fit, "Replay", _Told)
    simulated = problem.simulate(theta)
    assert problem.evaluations == 1
    t_s = np.array([t - EPOCH_NS for t, *_ in whole]) * 1e-9
    for k, s in ((2, "p1"), (3, "p2")):
        expected = np.interp(problem.times_s[s], t_s, [w[k] for w in whole], left=np.nan, right=np.nan)
        assert np.isfinite(expected).sum() >= 0.8 * len(expected), s  # most samples within the run
        np.testing.assert_allclose(simulated[s], expected, rtol=1e-12, err_msg=s)  # nan where it is
    # it stops at the first instant at or past the last sample: nothing beyond is compared
    last_ns = max(int(sig.time_ns[-1]) for sig in problem.signals.values())
    stamps = [t for t, *_ in _Told.given]
    assert stamps[-1] >= last_ns > stamps[-2] and stamps[-1] < whole[-1][0]


class _Diverges(Replay):
    def __iter__(self):
        raise fit.SimulationError("the boom diverged")
        yield


class _Misfits(Replay):
    def __iter__(self):
        raise fit.ConfigError("a recorded change does not fit")
        yield


@pytest.mark.parametrize("replay", [_Diverges, _Misfits])
def test_a_re_simulation_that_fails_is_no_signal_but_a_failed_runs_cost(machine, tmp_path, monkeypatch, replay):
    problem = _prepared(machine, tmp_path)
    monkeypatch.setattr(fit, "Replay", replay)
    assert problem.simulate(np.array([1.0, 1.0])) is None
    assert problem.evaluations == 1
