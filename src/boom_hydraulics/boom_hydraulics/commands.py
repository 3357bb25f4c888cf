"""Valve command profiles over time: constant, steps, ramp, sine (the headless scenarios)."""

from __future__ import annotations

import bisect
import math
from collections.abc import Callable

from .parameters import Parameters

CommandProfile = Callable[[float], float]


def constant(value: float) -> CommandProfile:
    """u(t) = value."""
    return lambda t: value


def steps(times_s: list[float], values: list[float]) -> CommandProfile:
    """Piecewise constant: values[i] from times_s[i] until times_s[i + 1]; 0 before times_s[0]."""

    def u(t: float) -> float:
        i = bisect.bisect_right(times_s, t) - 1
        return values[i] if i >= 0 else 0.0

    return u


def ramp(times_s: list[float], values: list[float]) -> CommandProfile:
    """Piecewise linear through (times_s[i], values[i]); held flat before the first and after the last."""

    def u(t: float) -> float:
        if t <= times_s[0]:
            return values[0]
        if t >= times_s[-1]:
            return values[-1]
        i = bisect.bisect_right(times_s, t) - 1
        w = (t - times_s[i]) / (times_s[i + 1] - times_s[i])
        return values[i] + w * (values[i + 1] - values[i])

    return u


def sine(offset: float, amplitude: float, frequency_hz: float) -> CommandProfile:
    """u(t) = offset + amplitude sin(2 pi f t)."""
    return lambda t: offset + amplitude * math.sin(2.0 * math.pi * frequency_hz * t)


def from_parameters(p: Parameters) -> CommandProfile:
    """The profile that the ``command_*`` parameters describe."""
    if p.command_profile == "constant":
        return constant(p.command_value)
    if p.command_profile == "steps":
        return steps(list(p.command_times_s), list(p.command_values))
    if p.command_profile == "ramp":
        return ramp(list(p.command_times_s), list(p.command_values))
    return sine(p.command_offset, p.command_amplitude, p.command_frequency_hz)
