"""Valve commands waiting for their simulated time: the node's rule for command stamps.

Rule (documented in the README and ValveCommand.msg):
- A command with a zero stamp, or stamped at or before the current simulated time, takes
  effect at the next physics step.
- A command stamped in the future waits, and takes effect at the first step that starts
  within half a step of its stamp. Commands due at the same step apply in stamp order
  (the last wins).
- At most ``max_pending`` future commands wait; more are refused.

With this rule a scenario sent ahead of time gives the same trajectory as ``boom-sim``
with the same commands, however late the messages are delivered or the node's timer fires.
"""

from __future__ import annotations

import heapq
import itertools
import math
from collections.abc import Callable


class CommandQueue:
    """Future valve commands ordered by their simulated time."""

    def __init__(self, max_pending: int = 10_000):
        self.max_pending = max_pending
        self._heap: list[tuple[float, int, float]] = []
        self._order = itertools.count()

    def __len__(self) -> int:
        return len(self._heap)

    def push(self, at_s: float, opening: float) -> bool:
        """Queue ``opening`` for simulated time ``at_s``; False when the queue is full."""
        if len(self._heap) >= self.max_pending:
            return False
        heapq.heappush(self._heap, (at_s, next(self._order), opening))
        return True

    def apply_due(self, t_s: float, dt_s: float, apply: Callable[[float, float], None]) -> None:
        """Apply, in order, every command due at the step that starts at ``t_s``."""
        while self._heap and self._heap[0][0] <= t_s + 0.5 * dt_s:
            at_s, _, opening = heapq.heappop(self._heap)
            apply(opening, at_s)

    def steps_until_next(self, t_s: float, dt_s: float, limit: int) -> int:
        """Steps that may run from ``t_s`` before the next queued command is due (1 .. limit)."""
        if not self._heap:
            return limit
        k = math.ceil((self._heap[0][0] - t_s) / dt_s - 0.5 - 1e-9)
        return max(1, min(limit, k))

    def clear(self) -> None:
        self._heap.clear()
