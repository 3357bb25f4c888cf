"""Fitting parameters to a recorded bag: the recorded commands re-simulated (resim.Replay) until
the simulated signals match the recorded ones, by ``scipy.optimize.least_squares``.

- **The run.** A bag of boom_sim holds its parameters and time origin (its run description):
  they are the start, changed by ``--config`` and ``--set``. A bag without one (a real
  machine's) needs ``--config``; its run starts at rest at ``initial_length_m`` at the bag's
  first message, and the simulation is read at the time steps on either side of each
  recorded sample. A bag without commands (valve commands or the controller's setpoints) is
  refused: there is nothing to re-simulate; so is a run that was reset, as boom-resim refuses
  it (resim.refusals.break_in_states tells a reset from sensor noise).
- **The samples.** Each recorded sample is compared at the instant it shows (its stamp, where
  on the run's clock; see :mod:`.signals`) with the simulation there (linear between the
  simulated instants).
- **The residual.** Each sample's difference over its signal's noise, told from the recording
  itself (analysis.noise), times the signal's weight (``--weight``, 1 by default): signals of
  any unit and rate count by what they tell, a fast precise sensor more than a slow noisy
  one. (The coarse stages below, which only find the valley, measure each signal in units of
  its range, weighted ``w / sqrt(n)``, so that each counts alike.) A parameter set whose run
  fails (it diverged) costs a residual far above any fit.
- **The fit.** Trust-region reflective least squares on each parameter over its start value,
  within the bounds of :func:`.fittable.bounds`; the Jacobian by forward differences of 1e-3
  of each value (the stability substeps change in steps, so a finer difference would see them),
  its columns, like a scan's trials, re-simulated side by side on every core (:mod:`.evaluations`).
  The ringing of the oil springs makes the raw residual a narrow valley in what sets its
  frequency (the bulk modulus 10 % off puts the ringing half a period out of phase within a
  second), with a false bottom at every period, so the fit goes from coarse to fine:
  1. each parameter in turn through 0.5, 0.7, 1.4 and 2 times its value, and
  2. least squares, both on the residual averaged over 4 periods of the hydraulic mode (from
     the linear model at mid-stroke with the start values,
     :func:`..analysis.linear_model.mid_stroke_modes`), where the valley is wide and the
     ringing averages out: the slow part of the signals (speeds, pressure levels) settles;
  3. each parameter in turn through 0.42 to 2.4 times its value in steps of 10 %, then
     through 0.91 to 1.09 times the best in steps of 3 %, on the raw residual: a search along
     each parameter for the ringing's phase (the averaged residual above hardly sees the
     bulk modulus), and
  4. least squares on the noise-weighted residual from there.
  The first least squares stops at 0.1 % (it only has to reach the valley), the last at 1e-6.
- **The starts.** All of this from the given start and from ``starts - 1`` more spread over
  a decade beyond the start and the model's default of each parameter (:mod:`.starts`); the
  best end is kept, and where each start ended is reported.
- **The confidence intervals.** From the Jacobian and the residual at the solution, each
  signal's noise as its residual shows it, and residuals correlated from sample to sample
  counted as such (:mod:`.uncertainty`).
- **The verdict.** A fit that did not converge, or cannot tell a parameter, says so
  (:mod:`.verdict`).
"""

from __future__ import annotations

import itertools
import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np
from scipy.optimize import least_squares

from ..analysis.linear_model import mid_stroke_modes
from ..analysis.noise import noise_level
from ..bags.reading import read_custom_data
from ..bags.run_description import RunDescription
from ..errors import ConfigError, SimulationError
from ..model import config
from ..model.parameters import Parameters, describe, from_mapping
from ..resim.recorded import RecordedRun
from ..resim.resimulation import Replay, read_recorded
from . import verdict
from .evaluations import Evaluations, cores
from .fittable import bounds, check_fit
from .signals import UNITS, Signal, read_signals, start_ns
from .starts import starts as spread_starts
from .uncertainty import half_widths

PROG = "boom-calibrate"
DEFAULT_SIGNALS = ("q1", "p1", "p2")
#: Relative step of the fit's forward differences.
DIFF_STEP = 1e-3
#: The residual of a sample whose run failed, in units of its signal's range.
FAILED_RESIDUAL = 10.0
#: A signal's noise is taken as at least this fraction of its range: the rounding of a 16-bit
#: reading over it (1/(2^16 sqrt(12))), the finest a sensor's is (a recording without noise,
#: such as the node's, would otherwise be held to the fit's own resolution).
NOISE_FLOOR = 2.0**-16 / math.sqrt(12.0)
#: The starts of a fit: the given one and this many less one more (see starts).
STARTS = 4
#: The coarse stages average the residual over this many periods of the hydraulic mode ...
SMOOTHING_PERIODS = 4.0
#: ... of this one where the start values' linear model has no oscillating mode, Hz.
DEFAULT_FREQUENCY_HZ = 8.0
#: The coarse scan's factors on each parameter ...
COARSE_FACTORS = (0.5, 0.7, 1.4, 2.0)
#: ... the wide scan's on the raw residual: 0.42 to 2.4 in steps of 10 % ...
WIDE_FACTORS = tuple(float(f) for f in 1.1 ** np.arange(-9, 10) if f != 1.0)
#: ... and the near one's around its best: 0.91 to 1.09 in steps of 3 %.
NEAR_FACTORS = tuple(float(f) for f in 1.03 ** np.arange(-3, 4) if f != 1.0)
#: Stage 4 runs from each start whose stage 3 ended within this factor of the best's raw cost ...
REFINE_WITHIN = 2.0
#: ... and not within this fraction of every value of a start already refined (the same valley).
SAME_VALLEY = 0.01
#: Relative tolerances (ftol, xtol) of the smoothed and of the final least squares.
COARSE_TOLERANCE, FINE_TOLERANCE = 1e-3, 1e-6
#: The final least squares also stops where a step moves each parameter by less than this
#: fraction of its standard error for the signals' estimated noise: what it could still gain
#: is far inside the interval (a recording without noise, which it would otherwise follow
#: ever closer, to its limit of evaluations).
STOP_WITHIN_ERROR = 1e-3


@dataclass
class Problem:
    """A bag to fit: its run, the start values, what is fitted, the signals and their weights."""

    bag: Path
    run: RecordedRun
    values: dict[str, Any]  # the parameter values to re-simulate with (the bag's or --config's)
    overrides: dict[str, Any]  # --set: kept on top of the recorded parameter changes
    names: list[str]  # fitted
    signals: dict[str, Signal]
    weights: dict[str, float]
    start: Parameters = field(init=False)
    inside: dict[str, np.ndarray] = field(init=False, default_factory=dict)  # samples within the simulated span

    def __post_init__(self) -> None:
        self.start = from_mapping(self.values | self.overrides)
        self.scales = {n: abs(getattr(self.start, n)) or 1.0 for n in self.names}
        self.ranges = {s: _range(sig.values) for s, sig in self.signals.items()}
        self.noise = {
            s: max(noise_level(sig.values, sig.time_ns - sig.time_ns[0]), NOISE_FLOOR * self.ranges[s])
            for s, sig in self.signals.items()
        }
        origin = self.run.clock_origin_ns
        self.times_s = {s: (sig.time_ns - origin).astype(float) * 1e-9 for s, sig in self.signals.items()}
        self.read_at_s = np.unique(np.concatenate(list(self.times_s.values())))  # where simulate reads the run
        self.evaluations = 0

    def fitted_values(self, theta: Sequence[float]) -> dict[str, float]:
        return {n: float(x) * self.scales[n] for n, x in zip(self.names, theta)}

    def simulate(self, theta: Sequence[float]) -> dict[str, np.ndarray] | None:
        """The simulated signals at the recorded log times with the fitted parameters at ``theta``
        (nan outside the simulated span), or None where the run fails."""
        self.evaluations += 1
        last_ns = max(int(sig.time_ns[-1]) for sig in self.signals.values())
        try:
            replay = Replay(self.run, self.values, self.overrides | self.fitted_values(theta), self.read_at_s)
            t_ns, columns = [], {s: [] for s in self.signals}
            for stamp_ns, outputs in replay:
                t_ns.append(stamp_ns)
                for s in self.signals:
                    columns[s].append(outputs[s])
                if stamp_ns >= last_ns:
                    break
        except (SimulationError, ConfigError):
            return None
        t = (np.array(t_ns, dtype=np.int64) - self.run.clock_origin_ns).astype(float) * 1e-9
        return {s: np.interp(self.times_s[s], t, columns[s], left=np.nan, right=np.nan) for s in self.signals}

    def residual(
        self, simulated: Mapping[str, np.ndarray] | None, window_s: float = 0.0, weighted: bool = False
    ) -> np.ndarray:
        """The residual of every recorded sample (see the module docstring): ``weighted`` by the
        signals' noise and weights, else in units of their ranges, averaged over ``window_s`` (a
        moving mean over the samples within it; 0: raw)."""
        parts = []
        for s, sig in self.signals.items():
            inside = self.inside[s]
            if simulated is None:
                difference = np.full(inside.sum(), FAILED_RESIDUAL * self.ranges[s])
            else:
                difference = simulated[s][inside] - sig.values[inside]
            if weighted:
                parts.append(self.weights[s] / self.noise[s] * difference)
                continue
            if window_s > 0.0:
                spacing = float(np.median(np.diff(self.times_s[s][inside])))
                width = min(len(difference), max(1, round(window_s / spacing)))
                difference = np.convolve(difference, np.full(width, 1.0 / width), mode="valid")
            parts.append(self.weights[s] / (self.ranges[s] * math.sqrt(len(difference))) * difference)
        return np.concatenate(parts)

    def signal_weights(self) -> list[float]:
        """Each signal's ``--weight``, in the order of :meth:`segments`."""
        return [self.weights[s] for s in self.signals]

    def segments(self) -> list[slice]:
        """Where each signal's samples lie in :meth:`residual` (raw)."""
        ends = np.cumsum([0] + [int(self.inside[s].sum()) for s in self.signals])
        return [slice(int(a), int(b)) for a, b in itertools.pairwise(ends)]

    def rms(self, simulated: Mapping[str, np.ndarray] | None) -> dict[str, float]:
        """The RMS difference of each signal, in its own unit (nan where the run failed)."""
        if simulated is None:
            return dict.fromkeys(self.signals, math.nan)
        return {
            s: float(np.sqrt(np.mean((simulated[s][self.inside[s]] - sig.values[self.inside[s]]) ** 2)))
            for s, sig in self.signals.items()
        }


def _range(values: np.ndarray) -> float:
    """The size a signal's residual is measured in: its range, at least 1e-6 of its magnitude."""
    return max(float(np.ptp(values)), 1e-6 * float(np.max(np.abs(values))), 1e-300)


def prepare(
    bag: Path,
    names: Sequence[str],
    config_file: Path | None = None,
    overrides: Mapping[str, Any] = (),
    signal_names: Sequence[str] = DEFAULT_SIGNALS,
    weights: Mapping[str, float] = (),
    command_timeout_s: float = 0.0,
) -> Problem:
    """Read what a fit of ``names`` to ``bag`` needs, refusing (ConfigError, BagError) in one
    line what it cannot take (see the module docstring)."""
    check_fit(names)
    weights = dict(weights)
    unknown = sorted(set(weights) - set(signal_names))
    if unknown:
        raise ConfigError(f"--weight {unknown[0]}: not one of the signals fitted ({', '.join(signal_names)})")
    if any(not (w > 0 and math.isfinite(w)) for w in weights.values()):
        raise ConfigError(f"--weight must be positive and finite, got {weights}")
    description = None
    if read_custom_data(bag) is None:
        if config_file is None:
            raise ConfigError(
                f"{bag}: has no run description (not recorded by boom_sim); give --config with the machine's "
                "parameters: the run starts at rest at initial_length_m when the bag begins"
            )
        values = config.read_values(config_file)
        dt = from_mapping(values | dict(overrides)).time_step_s
        description = RunDescription(values, start_ns(bag), 1.0 / dt, command_timeout_s)
    run, values = read_recorded(bag, config_file, PROG, description)
    signals = read_signals(bag, signal_names, (run.clock_origin_ns, run.end_ns))
    if not run.commands and not run.setpoints:
        raise ConfigError(
            f"{bag}: holds no valve commands (ValveCommand, or Float64MultiArray on a commands topic) and no "
            "controller setpoints: there is nothing to re-simulate; calibrate on a bag of the commanded run"
        )
    problem = Problem(
        bag, run, values, dict(overrides), list(names), signals, {s: weights.get(s, 1.0) for s in signals}
    )
    return problem


@dataclass(frozen=True)
class Fit:
    """The outcome of a fit."""

    problem: Problem
    start: dict[str, float]  # the fitted parameters' start values
    fitted: dict[str, float]
    interval: dict[str, tuple[float, float]]  # LEVEL confidence interval of each fitted value
    at_bound: dict[str, bool]
    rms_before: dict[str, float]  # per signal, its unit
    rms_after: dict[str, float]
    cost_before: float  # sum of squares of the noise-weighted residual
    cost_after: float
    initial: dict[str, np.ndarray] | None  # the simulated signals at the recorded times
    final: dict[str, np.ndarray] | None
    evaluations: int
    seconds: float
    message: str
    correlation: np.ndarray = field(default_factory=lambda: np.eye(0))  # of the fitted values
    ends: list[verdict.End] = field(default_factory=list)  # where each start ended, the best first
    findings: list[verdict.Finding] = field(default_factory=list)  # why it cannot be trusted (none: it can)

    @property
    def exit_status(self) -> int:
        """0, or verdict.NOT_CONVERGED (3), or verdict.NOT_IDENTIFIABLE (4)."""
        return verdict.exit_status(self.findings)


def calibrate(problem: Problem, max_evaluations: int = 200, workers: int | None = None, starts: int = STARTS) -> Fit:
    """Fit the problem's parameters (see the module docstring) from ``starts`` starts,
    re-simulating on ``workers`` processes at a time (default: every core)."""
    began = time.perf_counter()
    names = problem.names
    scales = np.array([problem.scales[n] for n in names])
    bound = {n: bounds(n, problem.start, names) for n in names}
    low = np.array([bound[n][0] for n in names]) / scales
    high = np.array([bound[n][1] for n in names]) / scales
    theta0 = np.array([getattr(problem.start, n) for n in names]) / scales
    theta0 = np.clip(theta0, low, high)
    initial = problem.simulate(theta0)
    if initial is None:
        raise SimulationError(f"{problem.bag}: the re-simulation fails with the start values; fix them first")
    problem.inside = {s: np.isfinite(initial[s]) for s in problem.signals}
    for s, inside in problem.inside.items():
        if inside.sum() < 2:
            raise ConfigError(f"{problem.bag}: no recorded {s} sample falls within the re-simulated run")
    r0 = problem.residual(initial, weighted=True)
    frequency = float(mid_stroke_modes([problem.start])[0][0])
    period_s = 1.0 / (frequency if math.isfinite(frequency) else DEFAULT_FREQUENCY_HZ)
    window_s = SMOOTHING_PERIODS * period_s
    default = np.array([getattr(Parameters(), n) for n in names]) / scales
    points = spread_starts(theta0, default, low, high, starts)
    with Evaluations(problem, cores() if workers is None else workers) as evaluations:

        def within_error() -> Any:
            """A callback that stops the least squares where its step is far inside the interval:
            below STOP_WITHIN_ERROR of each standard error (J^T J)^-1, J weighted by the noise."""
            last = {}

            def stop(intermediate_result: Any) -> None:
                x, jac = intermediate_result.x, evaluations.last_jacobian
                if "x" in last and jac is not None:
                    error = np.sqrt(np.abs(np.diag(np.linalg.pinv(jac.T @ jac))))
                    if np.all(np.abs(x - last["x"]) < STOP_WITHIN_ERROR * error):
                        raise StopIteration
                last["x"] = x.copy()

            return stop

        def fit_from(theta: np.ndarray, window: float, tolerance: float, weighted: bool = False) -> Any:
            return least_squares(
                evaluations.function(window, weighted),
                theta,
                jac=evaluations.jacobian(window, DIFF_STEP, low, high, weighted),
                bounds=(low, high),
                method="trf",
                x_scale=1.0,
                ftol=tolerance,
                xtol=tolerance,
                max_nfev=max_evaluations,
                callback=within_error() if weighted else None,
            )

        def approach(theta: np.ndarray) -> tuple[np.ndarray, float]:
            """Stages 1 to 3 from ``theta``: (where they end, the raw residual's cost there)."""
            theta, _ = _scan(evaluations, theta, low, high, window_s, COARSE_FACTORS)
            theta = fit_from(theta, window_s, COARSE_TOLERANCE).x
            theta, _ = _scan(evaluations, theta, low, high, 0.0, WIDE_FACTORS)
            return _scan(evaluations, theta, low, high, 0.0, NEAR_FACTORS)

        approached = [approach(point) for point in points]
        results: list[Any] = []
        refined: list[np.ndarray] = []
        best_cost = min(cost for _, cost in approached)
        for theta, cost in sorted(approached, key=lambda a: a[1]):
            # stage 4 from each valley worth it: the best, and others as good within REFINE_WITHIN
            same = any(np.all(np.abs(theta - r) <= SAME_VALLEY * np.maximum(np.abs(r), 1e-12)) for r in refined)
            if cost <= REFINE_WITHIN * best_cost and not same:
                refined.append(theta)
                results.append(fit_from(theta, 0.0, FINE_TOLERANCE, weighted=True))
            else:
                (r,) = evaluations.residuals([theta], 0.0, weighted=True)
                results.append(SimpleNamespace(x=theta, cost=0.5 * float(r @ r)))
        points = [points[k] for k, _ in sorted(enumerate(approached), key=lambda a: a[1][1])]
    # the refined ends first (the best of them is the fit), each group by its cost
    order = sorted(range(len(results)), key=lambda k: (not hasattr(results[k], "jac"), results[k].cost))
    result = results[order[0]]
    final = problem.simulate(result.x)
    fitted = problem.fitted_values(result.x)
    half, correlation = half_widths(result.jac, result.fun, problem.segments(), problem.signal_weights())
    interval = {n: (fitted[n] - h * problem.scales[n], fitted[n] + h * problem.scales[n]) for n, h in zip(names, half)}
    tight = 1e-9 * np.maximum(1.0, np.abs(result.x))
    at_bound = {
        n: bool(abs(x - lo) <= t or abs(hi - x) <= t) for n, x, lo, hi, t in zip(names, result.x, low, high, tight)
    }
    ends = [
        verdict.End(problem.fitted_values(points[k]), problem.fitted_values(results[k].x), 2.0 * results[k].cost)
        for k in order
    ]
    rms_after = problem.rms(final)
    units = {n: describe(n)["unit"] for n in names} | {s: UNITS[s] for s in problem.signals}
    findings = verdict.identifiability(
        names, fitted, interval, bound, correlation, ends[1:], ends[0].cost, len(result.fun) - len(names), units
    )
    findings += verdict.convergence(
        result.status == 0, at_bound, fitted, rms_after, problem.noise, problem.ranges, units
    )
    unique = {(f.kind, f.subject): f for f in reversed(findings)}  # the first of each
    findings = [f for f in findings if unique[(f.kind, f.subject)] is f]
    return Fit(
        problem,
        {n: getattr(problem.start, n) for n in names},
        fitted,
        interval,
        at_bound,
        problem.rms(initial),
        rms_after,
        float(r0 @ r0),
        ends[0].cost,
        initial,
        final,
        problem.evaluations,
        time.perf_counter() - began,
        str(result.message),
        correlation,
        ends,
        findings,
    )


def _scan(
    evaluations: Evaluations,
    theta: np.ndarray,
    low: np.ndarray,
    high: np.ndarray,
    window_s: float,
    factors: Sequence[float],
) -> tuple[np.ndarray, float]:
    """Each parameter in turn through ``factors`` times its value (within its bounds; the trials
    of one parameter side by side), keeping the best of each on the residual averaged over
    ``window_s`` (0: raw): (the best, its cost)."""
    best = theta.copy()
    (r,) = evaluations.residuals([best], window_s)
    best_cost = float(r @ r)
    for k in range(len(theta)):
        trials = []
        for factor in factors:
            trial = best.copy()
            trial[k] = min(max(best[k] * factor, low[k]), high[k])
            if trial[k] != best[k]:
                trials.append(trial)
        for trial, r in zip(trials, evaluations.residuals(trials, window_s)):
            if float(r @ r) < best_cost:
                best, best_cost = trial, float(r @ r)
    return best, best_cost
