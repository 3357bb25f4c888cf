"""What the node's ~/pause and ~/step services take and what they refuse (docs/ros-api.md,
"Services"), without rclpy: the node (ros/node.py) asks these under its lock before it acts,
and a refusal is the one line its response carries."""

from __future__ import annotations

import math

#: The most simulated time one ~/step call may take, s: the executor serves nothing else
#: meanwhile, so a larger request is refused with how to get there.
STEP_CALL_LIMIT_S = 10.0
#: A step count this close (relatively) below a whole number is that number: 10 s of steps of
#: 1e-5 s are 1 000 000 steps, which the division gives as 999 999.9999999999. (Far above the
#: division's rounding, 1e-16, and a hundredth of a step at the node's finest step, 1e-9 s.)
_ROUNDING = 1e-12


def step_limit(time_step_s: float) -> int:
    """The most steps of ``time_step_s`` one ~/step call takes: STEP_CALL_LIMIT_S of simulated
    time, and at least one step."""
    return max(1, math.floor(STEP_CALL_LIMIT_S / time_step_s * (1.0 + _ROUNDING)))


def steps_asked(steps: int) -> int:
    """The steps a ~/step request asks for: 0 is taken as 1 (Step.srv)."""
    return max(1, steps)


def step_refusal(paused: bool, failure: str | None, steps: int, time_step_s: float) -> str | None:
    """Why a ~/step call for ``steps`` steps of ``time_step_s`` is refused, or None: it steps.
    It steps only while paused, a simulation that stopped (``failure``) only after a reset,
    and at most :func:`step_limit` steps at once."""
    if not paused:
        return "step works while paused; call ~/pause with data: true"
    if failure:
        return f"simulation stopped: {failure}; call ~/reset"
    limit = step_limit(time_step_s)
    if steps > limit:
        return (
            f"steps: {steps} is {steps * time_step_s:g} s of simulated time; one call takes at most "
            f"{STEP_CALL_LIMIT_S:g} s ({limit} steps of {time_step_s:g} s): call ~/step again for more"
        )
    return None


def pause_unchanged(asked: bool, paused: bool) -> str | None:
    """The answer to a ~/pause request (``asked``: data) that changes nothing, "already paused"
    or "already running" (a success), or None: the node pauses or resumes."""
    if asked == paused:
        return "already paused" if paused else "already running"
    return None
