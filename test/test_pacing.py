"""The pacing of the node's ticks, without ROS: steps due, catching up, dropping a backlog."""

from __future__ import annotations

import pytest

from boom_hydraulics.solve.pacing import Pacer

DT = 0.001


def test_a_tick_takes_the_steps_the_clock_says_are_due():
    pacer = Pacer(rate_hz=100.0, real_time_factor=1.0, max_catch_up_s=0.2)
    pacer.restart(wall_s=50.0, step_count=7)
    assert pacer.due(50.010, 7, DT).steps == 10
    assert pacer.due(50.035, 17, DT).steps == 25  # a late tick catches up: 35 due, 10 taken
    assert pacer.lag_s == pytest.approx(0.015)  # the backlog beyond one tick of 10 steps
    pacer.settled(42, DT)
    assert pacer.clock_error_s == pytest.approx(0.0, abs=1e-9)
    assert pacer.late_ticks == 0


def test_real_time_factor_scales_and_zero_runs_a_tick_at_a_time():
    fast = Pacer(100.0, 2.0, 0.2)
    fast.restart(0.0, 0)
    assert fast.due(0.010, 0, DT).steps == 20
    flat_out = Pacer(100.0, 0.0, 0.2)
    assert flat_out.due(123.0, 0, DT).steps == 10  # as fast as possible: one tick of steps per call
    assert Pacer(50.0, 1.0, 0.2).per_tick(DT) == 20


def test_a_backlog_beyond_the_catch_up_limit_is_dropped_and_counted():
    pacer = Pacer(100.0, 1.0, 0.2)
    pacer.restart(0.0, 0)
    tick = pacer.due(1.0, 0, DT)  # a second late (a stalled process)
    assert (tick.steps, tick.dropped_s) == (200, pytest.approx(0.8))
    assert pacer.late_ticks == 1
    assert pacer.due(1.0, 200, DT).steps == 0  # the origin moved on: nothing more is due now
    assert pacer.due(1.010, 200, DT).steps == 10


def test_on_a_shared_clock_a_backlog_is_worked_off_never_dropped():
    pacer = Pacer(100.0, 1.0, 0.2, drop_backlog=False)
    pacer.restart(0.0, 0)
    tick = pacer.due(1.0, 0, DT)  # a second behind the shared clock
    assert (tick.steps, tick.dropped_s) == (200, 0.0)
    assert pacer.late_ticks == 1
    assert pacer.due(1.0, 200, DT).steps == 200  # the rest is still due: simulated time stays the clock's
    assert pacer.due(1.0, 800, DT).steps == 200
    assert pacer.due(1.0, 1000, DT).steps == 0


def test_a_restart_ties_the_clock_to_the_state_as_it_is():
    """After a change of the time step, a step count means another simulated time."""
    pacer = Pacer(100.0, 1.0, 0.2)
    pacer.restart(0.0, 0)
    assert pacer.due(3.0, 2990, DT).steps == 10
    pacer.restart(3.0, 3000)  # the node restarts the pacing on every parameter change
    assert pacer.due(3.010, 3000, 0.0005).steps == 20
    assert pacer.late_ticks == 0
