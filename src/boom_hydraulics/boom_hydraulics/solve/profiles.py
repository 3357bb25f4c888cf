"""Open-loop valve command profiles as one scalar function of time.

:func:`profile_value` is the one definition of the constant, steps, ramp and sine profiles:
the headless commands (:mod:`commands`) call it, and the compiled run kernel (:mod:`kernel`)
calls it for every step. It is written in the subset of Python that numba compiles.
"""

from __future__ import annotations

import math
from typing import Any

from ..jit import jitable
from ..model.setpoints import last_at_or_before

#: Profile kinds (the ``command_profile`` parameter); ANGLE is the closed loop of kernel.
CONSTANT, STEPS, RAMP, SINE, ANGLE = 0, 1, 2, 3, 4
KINDS = {"constant": CONSTANT, "steps": STEPS, "ramp": RAMP, "sine": SINE, "angle": ANGLE}


@jitable
def profile_value(
    kind: int, times_s: Any, values: Any, offset: float, amplitude: float, frequency_hz: float, t: float
) -> float:
    """The valve command of an open-loop profile at ``t`` (s):

    - CONSTANT: ``offset``;
    - STEPS: ``values[i]`` from ``times_s[i]`` until ``times_s[i + 1]``, 0 before ``times_s[0]``;
    - RAMP: linear through (``times_s[i]``, ``values[i]``), flat before the first and after the last;
    - SINE: ``offset + amplitude sin(2 pi frequency_hz t)``.
    """
    if kind == CONSTANT:
        return offset
    if kind == SINE:
        return offset + amplitude * math.sin(2.0 * math.pi * frequency_hz * t)
    i = last_at_or_before(times_s, t)
    if kind == STEPS:
        return values[i] if i >= 0 else 0.0
    if t <= times_s[0]:
        return values[0]
    if t >= times_s[len(times_s) - 1]:
        return values[len(values) - 1]
    w = (t - times_s[i]) / (times_s[i + 1] - times_s[i])
    return values[i] + w * (values[i + 1] - values[i])
