"""The pacer across a reset, without ROS: the simulator counts its steps from 0 again, and
simulated time stays due where it was."""

from __future__ import annotations

from boom_hydraulics.solve.pacing import Pacer

DT = 0.001


def test_a_reset_counts_steps_afresh_and_leaves_simulated_time_due_where_it_was():
    pacer = Pacer(rate_hz=100.0, real_time_factor=1.0, max_catch_up_s=10.0)
    pacer.restart(wall_s=0.0, step_count=0)
    assert pacer.due(2.0, 1990, DT).steps == 10  # 2 s in, 1990 steps taken
    pacer.rebase(2000, DT, counted_from=0)  # a reset after 2000 steps: the count starts at 0 again
    assert pacer.due(2.010, 0, DT).steps == 10  # one tick's steps, not the 2 s since the start again
    assert pacer.late_ticks == 0


def test_a_change_of_time_step_keeps_the_count():
    pacer = Pacer(100.0, 1.0, 10.0)
    pacer.restart(0.0, 0)
    pacer.rebase(1000, DT)  # 1 s of 1 ms steps; steps of 0.5 ms from here
    assert pacer.due(1.010, 1000, 0.0005).steps == 20


def test_boom_sim_lives_clock_keeps_time_across_a_change_of_mode():
    """boom-sim live's clock across a change of mode, which resets the simulator's state and its
    step count: one tick's steps are due after it, not every step since the start again."""
    from boom_hydraulics.live.clock import LiveClock
    from boom_hydraulics.model.parameters import Parameters, with_updates
    from boom_hydraulics.solve.simulation import Simulator

    sim = Simulator(Parameters(), jit=False)
    clock = LiveClock(sim, rate_hz=100.0, real_time_factor=1.0, max_catch_up_s=10.0)
    clock.pacer.restart(0.0, 0)
    sim.step_count = 2000  # 2 s run (the count is all the clock reads of them)
    steps_before = sim.step_count
    sim.set_parameters(with_updates(sim.params, mode="paper"))
    assert sim.step_count == 0  # a change of mode starts the count again
    clock.rebase(DT, steps_before)
    assert clock.pacer.due(2.010, sim.step_count, DT).steps == 10
