"""The node's rule for stamped valve commands."""

from __future__ import annotations

from boom_hydraulics.solve.command_queue import CommandQueue


def test_future_commands_wait_for_their_step_and_apply_in_order():
    q = CommandQueue()
    q.push(0.0104, 0.5)
    q.push(0.0030, 1.0)
    q.push(0.0030, -1.0)  # same time: the later one wins
    applied: list[tuple[float, float]] = []
    dt, t = 0.001, 0.0
    assert q.steps_until_next(t, dt, 100) == 3  # the steps starting at 0, 1, 2 ms run before 3 ms
    for n in range(20):
        q.apply_due(n * dt, dt, lambda u, at, n=n: applied.append((n, u)))
    assert applied == [(3, 1.0), (3, -1.0), (10, 0.5)]  # 10.4 ms rounds to the step at 10 ms (within dt/2)


def test_past_and_present_commands_apply_at_once_and_the_queue_is_bounded():
    q = CommandQueue(max_pending=2)
    assert q.push(-5.0, 0.2) and q.push(0.0, 0.3)
    assert not q.push(1.0, 0.4)  # full
    applied: list[float] = []
    q.apply_due(0.0, 0.001, lambda u, at: applied.append(u))
    assert applied == [0.2, 0.3] and len(q) == 0
    assert q.steps_until_next(0.0, 0.001, 7) == 7
