"""Valve command profiles over time: constant, steps, ramp, sine (the headless scenarios)."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import ConfigError
from ..model.parameters import Parameters
from ..model.setpoints import LINEAR
from . import duty_cycles
from .closed_loop import PositionLoop
from .kernel import Command
from .profiles import CONSTANT, RAMP, SINE, STEPS, profile_value

CommandProfile = Callable[[float], float]


@dataclass(frozen=True)
class Profile:
    """An open-loop command u(t) of :func:`profiles.profile_value` (the run loop takes it as its kernel_command)."""

    kind: int
    times_s: tuple[float, ...] = ()
    values: tuple[float, ...] = ()
    offset: float = 0.0
    amplitude: float = 0.0
    frequency_hz: float = 0.0

    def __call__(self, t: float) -> float:
        return profile_value(self.kind, self.times_s, self.values, self.offset, self.amplitude, self.frequency_hz, t)

    def kernel_command(self, n_sets: int) -> Command:
        """The profile as the run loop evaluates it, the same for each of ``n_sets`` sets."""
        no_knots = np.zeros((n_sets, 1))
        times, values = (np.array(v or (0.0,), dtype=float) for v in (self.times_s, self.values))
        shape = (self.kind, times, values, self.offset, self.amplitude, self.frequency_hz)
        return Command(*shape, no_knots, no_knots, no_knots, LINEAR, np.zeros((n_sets, 4)))


def constant(value: float) -> CommandProfile:
    """u(t) = value."""
    return Profile(CONSTANT, offset=float(value))


def steps(times_s: Sequence[float], values: Sequence[float]) -> CommandProfile:
    """Piecewise constant: values[i] from times_s[i] until times_s[i + 1]; 0 before times_s[0]."""
    return Profile(STEPS, tuple(map(float, times_s)), tuple(map(float, values)))


def ramp(times_s: Sequence[float], values: Sequence[float]) -> CommandProfile:
    """Piecewise linear through (times_s[i], values[i]); held flat before the first and after the last."""
    return Profile(RAMP, tuple(map(float, times_s)), tuple(map(float, values)))


def sine(offset: float, amplitude: float, frequency_hz: float) -> CommandProfile:
    """u(t) = offset + amplitude sin(2 pi f t)."""
    return Profile(SINE, offset=float(offset), amplitude=float(amplitude), frequency_hz=float(frequency_hz))


def from_parameters(p: Parameters) -> CommandProfile:
    """The profile that the ``command_*`` parameters describe (the ``angle`` profile: a
    feedback command, see :class:`closed_loop.PositionLoop`)."""
    if p.command_profile == "angle":
        return PositionLoop.of_parameters([p])
    if p.command_profile == "constant":
        return constant(p.command_value)
    if p.command_profile == "steps":
        return steps(list(p.command_times_s), list(p.command_values))
    if p.command_profile == "ramp":
        return ramp(list(p.command_times_s), list(p.command_values))
    return sine(p.command_offset, p.command_amplitude, p.command_frequency_hz)


def for_batch(params: Sequence[Parameters]) -> Callable:
    """The command of a batch whose sets share their command_* parameters (the ``angle``
    profile: one controller per set, each from its own initial angle)."""
    if params[0].command_profile == "angle":
        return PositionLoop.of_parameters(params)
    return from_parameters(params[0])


def parse_profile(text: str, option: str = "--profile") -> dict[str, Any]:
    """``constant:U``, ``steps:T=U,T=U``, ``ramp:T=U,T=U``, ``sine:OFFSET,AMPLITUDE,FREQ_HZ`` or
    ``angle:T=DEG,T=DEG`` (closed loop: at time T, move the boom to DEG degrees) -> the
    command_* parameters."""
    kind, _, body = text.partition(":")
    try:
        if kind == "constant":
            return {"command_profile": "constant", "command_value": float(body)}
        if kind in ("steps", "ramp"):
            pairs = [item.split("=") for item in body.split(",") if item]
            times = [float(t) for t, _ in pairs]
            values = [float(u) for _, u in pairs]
            return {"command_profile": kind, "command_times_s": times, "command_values": values}
        if kind == "angle":
            pairs = [item.split("=") for item in body.split(",") if item]
            times = [float(t) for t, _ in pairs]
            angles = [math.radians(float(a)) for _, a in pairs]
            if times:
                return {"command_profile": "angle", "command_times_s": times, "command_angles_rad": angles}
        if kind == "sine":
            offset, amplitude, frequency = (float(x) for x in body.split(","))
            return {
                "command_profile": "sine",
                "command_offset": offset,
                "command_amplitude": amplitude,
                "command_frequency_hz": frequency,
            }
    except ValueError:
        pass
    raise ConfigError(
        f"{option} {text!r}: expected constant:U, steps:T=U,T=U,..., ramp:T=U,T=U,..., "
        "sine:OFFSET,AMPLITUDE,FREQ_HZ (times in s, openings in [-1, 1]) or angle:T=DEG,... "
        "(closed loop: boom angles in degrees)"
    )


#: (start time s, opening): lift, hold, lower, hold; the demo's cycle.
CYCLE = ((0.0, 1.0), (3.0, 0.0), (5.0, -1.0), (8.0, 0.0))

#: Named valve scenarios of the design sweeps (see :func:`scenario`).
SCENARIOS = ("lift", "cycle", "loader", "config")


def loader_seed(text: str) -> int:
    """The operator's seed of the scenario ``loader`` (0: the nominal cycle) or ``loader:SEED``."""
    _, _, arg = text.partition(":")
    try:
        return int(arg) if arg else 0
    except ValueError:
        raise ConfigError(f"scenario {text!r}: write loader or loader:SEED with SEED a whole number") from None


def scenario(text: str, duration_s: float, base: Parameters | None = None) -> dict[str, Any]:
    """The command_* parameters of a named scenario or a profile (see :func:`parse_profile`).

    - ``lift``: valve fully open for the first half of the run, then closed (the hold shows
      overshoot and oscillation); ``lift:T`` opens for T seconds.
    - ``cycle``: lift, hold, lower, hold (:data:`CYCLE`, 9 s).
    - ``loader``: a loader crane's work cycle under position control, the payload released
      within it (:mod:`duty_cycles`, 18.5 s), from the elevation of ``base`` (default
      parameters if None); ``loader:SEED``: as an operator varies it (seed >= 1).
    - ``config``: the command_* parameters of the config file, unchanged ({}).
    - anything else: a profile such as ``steps:0=1,2=0``, or ``angle:0=30`` (closed loop:
      lift to 30 degrees and hold).
    """
    name, _, arg = text.partition(":")
    if name == "config" and not arg:
        return {}
    if name == "loader":
        return duty_cycles.loader(base if base is not None else Parameters(), loader_seed(text))
    if name == "cycle" and not arg:
        times, values = zip(*CYCLE)
        return {"command_profile": "steps", "command_times_s": list(times), "command_values": list(values)}
    if name == "lift":
        try:
            open_s = float(arg) if arg else 0.5 * duration_s
        except ValueError:
            raise ConfigError(f"scenario {text!r}: write lift or lift:T with T the opening time in s") from None
        if not 0.0 < open_s:
            raise ConfigError(f"scenario {text!r}: the valve must open for a positive time")
        return {"command_profile": "steps", "command_times_s": [0.0, open_s], "command_values": [1.0, 0.0]}
    if name in ("constant", "steps", "ramp", "sine", "angle"):
        return parse_profile(text, "--scenario")
    raise ConfigError(
        f"unknown scenario {text!r}; choose {', '.join(SCENARIOS)}, lift:T, loader:SEED, or a profile "
        "(constant:U, steps:T=U,..., ramp:T=U,..., sine:OFFSET,AMPLITUDE,FREQ_HZ, or angle:T=DEG,... "
        "for closed-loop moves)"
    )
