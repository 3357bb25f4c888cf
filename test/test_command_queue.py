"""The node's rule for stamped valve commands, and the drive it steps (manual or closed loop)."""

from __future__ import annotations

import pytest

from boom_hydraulics.model.parameters import Parameters
from boom_hydraulics.solve.command_queue import CommandedDrive, CommandQueue
from boom_hydraulics.solve.simulation import Simulator


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


def test_the_drive_follows_a_path_and_a_valve_command_overrides_the_controller():
    from boom_hydraulics.model.setpoints import move

    sim = Simulator(Parameters())
    drive = CommandedDrive(sim, timeout_s=0.5)
    overrides = []
    drive.on_override = lambda: overrides.append(sim.t)
    angle, rate = drive.setpoint()
    assert rate == 0.0 and angle == pytest.approx(sim.outputs()["alpha"])
    drive.follow(move(sim.t, angle, rate, angle + 0.2, 0.3))
    drive.advance(1500)
    assert drive.followed is not None and drive.loop is not None
    assert sim.outputs()["alpha"] == pytest.approx(angle + 0.2, abs=0.004)
    drive.push(sim.t, -0.5)  # the operator takes over
    drive.advance(10)
    assert overrides == [pytest.approx(1.5)] and drive.loop is None and drive.current == -0.5
    assert drive.followed is None  # the controller did not drive in that advance
    drive.advance(600)  # the command's timeout closes the valve, as for any command
    assert drive.current == 0.0


def test_switching_to_paper_mode_lets_the_controller_go():
    from boom_hydraulics.model.parameters import with_updates
    from boom_hydraulics.model.setpoints import SetpointPath

    sim = Simulator(Parameters())
    drive = CommandedDrive(sim)
    drive.follow(SetpointPath.of([0.0], [0.3]))
    drive.advance(5)
    sim.set_parameters(with_updates(sim.params, mode="paper", piston_dead_volume_m3=2e-5))
    drive.parameters_changed()
    assert drive.loop is None and drive.current == 0.0


def _stepped_one_at_a_time(sim: Simulator, loop, steps: int) -> None:
    """The closed loop by its definition: the controller's opening at the middle of each step,
    from the state at its start, held over that step."""
    for _ in range(steps):
        sim.step(loop(sim.t + 0.5 * sim.params.time_step_s, sim.y), 1)


def test_the_closed_loop_in_ticks_of_any_size_is_the_controller_stepped_one_step_at_a_time():
    """The drive runs the controller in the compiled run loop a tick at a time; a new path, a
    new payload and ticks of 7 or 10 steps give what stepping the controller step by step gives
    (the node, boom-resim and bags recorded before this all agree on it)."""
    from boom_hydraulics.model.setpoints import move
    from boom_hydraulics.solve.closed_loop import PositionLoop

    sim, reference = Simulator(Parameters()), Simulator(Parameters())
    drive = CommandedDrive(sim)
    angle = float(sim.outputs()["alpha"])
    first, second = move(0.0, angle, 0.0, angle + 0.25, 0.3), move(0.6, angle + 0.1, 0.0, angle + 0.05, 0.3)
    drive.follow(first)
    loop = PositionLoop([reference.params], first, reference.constants)
    states = []
    for tick, steps in enumerate([7, 10] * 200):
        if tick == 60:  # a new goal while moving: the controller starts afresh on the new path
            drive.follow(second)
            loop = PositionLoop([reference.params], second, reference.constants)
        if tick == 120:  # a new payload: the controller takes the new constants, afresh
            for s in (sim, reference):
                s.set_payload_mass(150.0)
            drive.parameters_changed()
            loop = PositionLoop([reference.params], second, reference.constants)
        drive.advance(steps)
        _stepped_one_at_a_time(reference, loop, steps)
        assert (sim.step_count, sim.t) == (reference.step_count, reference.t)
        assert sim.y == pytest.approx(reference.y, rel=1e-12, abs=1e-15), f"tick {tick}"
        assert drive.current == pytest.approx(reference.u, rel=1e-12, abs=1e-15)
        # holding: the controller's state as it gives the next step's opening (asked again, the
        # reference gives the same opening: the controller moves on once per step)
        loop(reference.t + 0.5 * reference.params.time_step_s, reference.y)
        assert drive.holding == bool(loop.state.holding), f"tick {tick}"  # the move settled, or not yet
        states.append(drive.holding)
    assert not states[0] and drive.holding and states.count(True) > 100  # settled at the second path's end
    assert sim.outputs()["alpha"] == pytest.approx(angle + 0.05, abs=0.004)
    drive.follow(first)
    assert not drive.holding  # a new path: not settled until the controller says so
    drive.let_go()
    assert not drive.holding


def test_the_controller_goes_on_past_the_end_of_its_run(monkeypatch):
    """The controller's run is FOLLOW_HORIZON_S long (years); past its end the drive begins
    another and time goes on, rather than standing still."""
    from boom_hydraulics.model.setpoints import SetpointPath
    from boom_hydraulics.solve import simulator

    monkeypatch.setattr(simulator, "FOLLOW_HORIZON_S", 0.05)  # 50 steps
    sim = Simulator(Parameters())
    drive = CommandedDrive(sim)
    drive.follow(SetpointPath.of([0.0], [float(sim.outputs()["alpha"]) + 0.1]))
    for _ in range(12):
        drive.advance(10)
    assert sim.step_count == 120 and sim.t == pytest.approx(0.12)
    assert sim.outputs()["alpha_rate"] > 0.0  # still lifting towards the setpoint
