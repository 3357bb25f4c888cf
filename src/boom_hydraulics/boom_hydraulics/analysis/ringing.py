"""The ringing of a small valve step, simulated: the nonlinear model's own frequency and damping
at an operating point, to hold a linear model to (docs/linearize.md, "Checks").

The drive starts at the operating point, the command steps by a small amount, and the rod
velocity rings on its oil springs. A damped cosine on a slow quadratic drift,
v(t) = c0 + c1 t + c2 t^2 + A exp(-sigma t) cos(omega_d t + phi), is fitted to the velocity
after the spool lag has settled (scipy.optimize.least_squares), started from the ringing's
zero crossings and its decay; the natural frequency is sqrt(sigma^2 + omega_d^2) and the
damping ratio sigma / sqrt(sigma^2 + omega_d^2). Nothing of the linear model goes in.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from ..model import MODELS
from ..solve.commands import constant
from ..solve.simulation import Simulator
from .operating_point import OperatingPoint

#: The default step of the command: small enough that the seals stay in their presliding range.
SMALL_STEP = 1e-4
#: The fit starts this long after the step: the spool lag (20 ms) has settled by then, s.
SETTLE_S = 0.1


@dataclass(frozen=True)
class Ringing:
    """What the simulated step shows: the fitted mode and the signal it was fitted to."""

    natural_frequency_hz: float
    damping_ratio: float
    t_s: np.ndarray  # from the step
    velocity_m_s: np.ndarray
    fitted_m_s: np.ndarray  # the fit over t_s >= SETTLE_S (nan before)


def simulate_step(point: OperatingPoint, step: float, duration_s: float) -> tuple[np.ndarray, np.ndarray]:
    """The rod velocity after the command steps from the operating point's opening by ``step``
    (the simulator starts in the point's state; W holds the energy stored since the model's
    rest state, so that the energy balance carries on from there)."""
    sim = Simulator(point.params)
    sim.reset(point.q1_m)
    model = MODELS[point.params.mode]
    rest = model.energy(sim.y, sim.constants)
    y = list(point.state)
    w = model.ENERGY_STATES[0]
    y[w] = model.energy(y, sim.constants) - rest
    y[w + 1] = abs(y[w])
    sim.y = y
    run = sim.run(duration_s, constant(point.opening + step))
    return np.asarray(run["t"]), np.asarray(run["v"])


def _start(t: np.ndarray, x: np.ndarray) -> tuple[float, float, float] | None:
    """(amplitude, decay rate, angular frequency) to start the fit from: the zero crossings and
    extremes of ``x`` with a quadratic trend taken off; None with fewer than two periods."""
    swing = x - np.polyval(np.polyfit(t, x, 2), t)
    crossings = np.nonzero(np.diff(np.signbit(swing)))[0]
    if len(crossings) < 5:
        return None
    half_period = float(np.mean(np.diff(t[crossings])))
    halves = np.split(np.abs(swing), crossings[1:])
    peaks = np.array([h.max() for h in halves[:-1] if len(h)])
    decay = -np.polyfit(np.arange(len(peaks)) * half_period, np.log(peaks), 1)[0] if len(peaks) > 2 else 0.0
    return float(np.max(np.abs(swing))), max(float(decay), 0.0), math.pi / half_period


def fit_ringing(t: np.ndarray, x: np.ndarray) -> tuple[float, float, np.ndarray]:
    """Natural frequency (Hz), damping ratio and the fitted curve of the damped cosine in ``x``
    (see the module docstring); nan, nan and nans where ``x`` does not ring two periods."""
    start = _start(t, x)
    if start is None:
        return math.nan, math.nan, np.full(len(t), math.nan)
    amplitude, decay, omega = start
    trend = np.polyfit(t, x, 2)[::-1]
    scale = float(np.ptp(x)) or 1.0

    def curve(theta: np.ndarray) -> np.ndarray:
        c0, c1, c2, a, sigma, w, phi = theta
        return c0 + c1 * t + c2 * t * t + a * np.exp(-sigma * t) * np.cos(w * t + phi)

    best = None
    for phi in np.linspace(0.0, 2.0 * math.pi, 8, endpoint=False):  # the phase has many local fits
        fit = least_squares(lambda th: (curve(th) - x) / scale, [*trend, amplitude, decay, omega, phi])
        if best is None or fit.cost < best.cost:
            best = fit
    sigma, w = best.x[4], abs(best.x[5])
    size = math.hypot(sigma, w)
    return size / (2.0 * math.pi), sigma / size, curve(best.x)


def ringing(point: OperatingPoint, step: float = SMALL_STEP, duration_s: float = 1.0) -> Ringing:
    """The ringing of a command step of ``step`` at ``point``, fitted over SETTLE_S..duration_s."""
    t, v = simulate_step(point, step, duration_s)
    window = t >= SETTLE_S
    fitted = np.full(len(t), math.nan)
    frequency, damping, fitted[window] = fit_ringing(t[window] - SETTLE_S, v[window])
    return Ringing(frequency, damping, t, v, fitted)
