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
