"""A valve command that closes the loop: the position controller following a setpoint path.

:class:`PositionLoop` is a feedback command: ``loop(t, y)`` gives the opening of the step
whose middle is ``t`` from the state ``y`` at its start, through
:func:`..model.control.position_command`. The controller's state (integral, dead-band) moves
on once per step: asking again for the same ``t`` returns the same opening. It works for one
simulation (floats) and for a batch (one array entry per parameter set).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from ..errors import ConfigError
from ..model import MODELS
from ..model.control import ControlState, Gains, gains_of, initial_control_state, position_command
from ..model.geometry import boom_angle_rad
from ..model.parameters import Parameters
from ..model.setpoints import SetpointPath, timed_moves
from .kernel import Command
from .profiles import ANGLE


class PositionLoop:
    """The controller of each parameter set following ``path`` (one set: floats in and out)."""

    feedback = True  # called as command(t, y), not command(t)

    def __init__(self, params: Sequence[Parameters], path: SetpointPath, constants: Any = None) -> None:
        if any(p.mode != "physical" for p in params):
            raise ConfigError("closed-loop position control needs mode: physical (paper mode's valve only lifts)")
        self.single = len(params) == 1
        self.path = path
        model = MODELS["physical"]
        if constants is None:
            constants = model.constants(params[0]) if self.single else stacked_constants(params)
        self.constants = constants
        per_set = [gains_of(p) for p in params]
        self.gains = per_set[0] if self.single else Gains(*(np.array(c, dtype=float) for c in zip(*per_set)))
        self.dt_s = params[0].time_step_s
        self.xp = math if self.single else np
        self.state: ControlState = initial_control_state(0.0 if self.single else np.zeros(len(params)))
        self._t: float | None = None
        self._u: Any = 0.0

    @classmethod
    def of_parameters(cls, params: Sequence[Parameters]) -> PositionLoop:
        """The ``angle`` scenario of the command_* parameters: moves to command_angles_rad at
        command_times_s at up to control_max_speed_rad_s, from the initial angle."""
        p0 = params[0]
        start = [boom_angle_rad(p.initial_length_m, p.a_m, p.b_m, p.support_height_m) for p in params]
        speed = [p.control_max_speed_rad_s for p in params]
        path = timed_moves(start, p0.command_times_s, p0.command_angles_rad, speed)
        return cls(params, path)

    @property
    def fresh(self) -> bool:
        """True before the first command: the controller has no history yet."""
        return self._t is None and not np.any(self.state.integral) and not np.any(self.state.holding)

    def kernel_command(self, n_sets: int) -> Command | None:
        """The loop as the run loop evaluates it (kernel.controller_value) for ``n_sets`` sets:
        each set's knots and gains; None once it has run (the kernel starts a controller afresh)."""
        if not self.fresh:
            return None
        path = self.path
        # fresh writable arrays: a read-only view (as broadcasting gives for one set) is another
        # type to numba, and a second compile of the whole run kernel (15 s)
        knots = [
            np.array(np.broadcast_to(a, (len(a), n_sets)).T, order="C")
            for a in (path.times_s, path.angles_rad, path.rates_rad_s)
        ]
        gains = np.column_stack([np.broadcast_to(np.asarray(g, dtype=float), (n_sets,)) for g in self.gains])
        return Command(ANGLE, np.zeros(1), np.zeros(1), 0.0, 0.0, 0.0, *knots, path.order, gains)

    def __call__(self, t_s: float, y: Sequence[Any]) -> Any:
        if t_s == self._t:
            return self._u
        ref, rate = self.path.at(t_s) if self.single else self.path.evaluate(t_s)
        self._u, self.state = position_command(
            self.gains, self.state, y[0], self.constants, ref, rate, self.dt_s, self.xp
        )
        self._t = t_s
        return self._u

    def restart(self, path: SetpointPath) -> None:
        """Follow ``path`` from now on; the integral and dead-band start afresh."""
        self.path = path
        self.state = initial_control_state(self.state.integral * 0.0)
        self._t = None


def stacked_constants(params: Sequence[Parameters]) -> Any:
    """The model's Constants with one array entry per parameter set."""
    model = MODELS[params[0].mode]
    per_set = [model.constants(p) for p in params]
    return type(per_set[0])(*(np.array(column, dtype=float) for column in zip(*per_set)))
