"""Where the node's position controller drove the valve: the recorded setpoints cut into
stretches on the state instants."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass


@dataclass(frozen=True)
class Control:
    """A stretch of the run in which the position controller drove the valve."""

    start_ns: int  # the state instant at which it took over (the one before its first setpoint)
    samples: list[tuple[int, float, float]]  # the recorded setpoints
    release_ns: int  # the state instant of its last setpoint: the controller had let go there, unless
    # the recording ends there


def control_stretches(setpoints: Sequence[tuple[int, float, float]], instants: Sequence[int]) -> list[Control]:
    """The recorded setpoints cut into stretches of consecutive ticks, each placed on the state
    instants: control began at the instant before its first setpoint, and the node publishes a
    setpoint for every tick in which the controller drove, so it had let go (canceled, or taken
    over by a valve command) by the instant of the last one."""
    position = {ns: k for k, ns in enumerate(instants)}
    stretches: list[list[tuple[int, float, float]]] = []
    for sample in setpoints:
        k = position.get(sample[0])
        if k is None:
            continue
        if stretches and position[stretches[-1][-1][0]] == k - 1:
            stretches[-1].append(sample)
        else:
            stretches.append([sample])
    out = []
    for samples in stretches:
        first = position[samples[0][0]]
        start = instants[first - 1] if first > 0 else samples[0][0]
        out.append(Control(start, samples, samples[-1][0]))
    return out
