"""The node's rule for stamped valve commands, and the drive it steps (manual or closed loop)."""

from __future__ import annotations

import pytest

from boom_hydraulics.model.parameters import Parameters
from boom_hydraulics.solve.command_queue import CommandedDrive, CommandQueue, stale, valve_opening
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


def test_a_command_exactly_half_a_step_ahead_applies_at_this_step_and_one_past_it_at_the_next():
    """The rule's boundary: due at the first step that starts within half a step of its stamp."""
    dt = 0.001
    for n, at_s in ((3, 3.5 * dt), (4, 3.5 * dt + 0.01 * dt), (0, 0.5 * dt), (1, 0.5 * dt + 0.01 * dt)):
        q = CommandQueue()
        q.push(at_s, 0.7)
        assert q.steps_until_next(0.0, dt, 100) == max(1, n)  # the steps that run before it is due
        applied: list[int] = []
        for k in range(6):
            q.apply_due(k * dt, dt, lambda u, at, k=k, applied=applied: applied.append(k))
        assert applied == [n]
    q = CommandQueue()
    q.push(0.0505, 0.7)  # 50.5 steps ahead, but at most the limit asked for
    assert q.steps_until_next(0.0, dt, 20) == 20 and q.steps_until_next(0.0, dt, 80) == 50
    assert q.steps_until_next(0.047, dt, 80) == 3
    assert q.steps_until_next(0.2, dt, 80) == 1  # overdue: the next step


def test_an_opening_is_clamped_to_the_valves_range_and_a_non_finite_one_ignored():
    assert valve_opening(0.4, "physical") == 0.4 and valve_opening(-0.4, "physical") == -0.4
    assert valve_opening(1.0, "physical") == 1.0 and valve_opening(-1.0, "physical") == -1.0  # the ends
    assert valve_opening(1.5, "physical") == 1.0 and valve_opening(-1.5, "physical") == -1.0  # past them
    assert valve_opening(-0.4, "paper") == 0.0 and valve_opening(0.0, "paper") == 0.0  # paper: [0, 1]
    assert valve_opening(0.4, "paper") == 0.4 and valve_opening(1.5, "paper") == 1.0
    for bad in (float("nan"), float("inf"), float("-inf")):
        assert valve_opening(bad, "physical") is None and valve_opening(bad, "paper") is None


def test_a_command_as_old_as_the_timeout_when_received_is_stale_and_a_younger_one_is_not():
    assert stale(1.0, 1.25, 0.25)  # exactly the timeout old: stale
    assert not stale(1.0, 1.2499, 0.25)  # a hair younger: applied
    assert not stale(1.0, 1.0, 0.25) and not stale(1.3, 1.0, 0.25)  # now, or stamped ahead
    assert not stale(1.0, 1e6, 0.0)  # timeout 0: never stale


def test_the_valve_closes_at_the_first_step_within_half_a_step_of_the_command_timeout():
    """A manual command holds for ``timeout_s`` of simulated time, then the spring centres the
    valve: the step that starts within dt/2 of the deadline runs closed, the one before open."""
    sim = Simulator(Parameters())
    drive = CommandedDrive(sim, timeout_s=0.0052)  # deadline 5.2 ms: the step at 5 ms runs closed
    drive.push(0.0, 0.6)
    openings = []
    for _ in range(8):
        drive.advance(1)
        openings.append(sim.u)
    assert openings == [0.6] * 5 + [0.0] * 3
    drive.push(sim.t, 0.6)
    drive.advance(20)  # in one call, the same rule: it closes at the deadline within the call
    assert sim.u == 0.0 and drive.current == 0.0
    untimed = CommandedDrive(Simulator(Parameters()))  # timeout 0: it holds
    untimed.push(0.0, 0.6)
    untimed.advance(30)
    assert untimed.current == 0.6 and untimed.sim.u == 0.6


def test_a_timed_command_closes_at_the_same_step_in_one_advance_as_step_by_step():
    """The rule does not depend on how many steps a call asks for: a command's timeout inside a
    long advance closes the valve at the step it closes stepped one at a time."""
    for timeout_s in (0.0052, 0.0149, 0.011):
        stepped, whole = (CommandedDrive(Simulator(Parameters()), timeout_s=timeout_s) for _ in range(2))
        for d in (stepped, whole):
            d.push(0.0, 0.6)
        openings = []
        for _ in range(25):
            stepped.advance(1)
            openings.append(stepped.sim.u)
        whole.advance(25)
        assert openings.count(0.6) == round(timeout_s / 0.001)  # open until the step within dt/2 of it
        assert whole.sim.y == pytest.approx(stepped.sim.y, rel=1e-12, abs=1e-15)


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


class SteppedDrive(CommandedDrive):
    """The drive's rule taken one step at a time, as it was written before the controller ran
    in the run loop: each step, the commands due, then the controller's opening at the step's
    middle from the state at its start (or the manual opening), held over the step."""

    def advance(self, steps: int) -> None:
        dt = self.sim.params.time_step_s
        for _ in range(steps):
            t = self.sim.t
            self.queue.apply_due(t, dt, self._apply)
            if self.loop is not None:
                self.current = self.loop(t + 0.5 * dt, self.sim.y)
            self.sim.step(self.current, 1)

    @property
    def holding(self) -> bool:
        """The controller's dead-band state as it gives the next step's opening (asked again for
        the same step, it gives the same opening: it moves on once per step)."""
        if self.loop is None:
            return False
        self.loop(self.sim.t + 0.5 * self.sim.params.time_step_s, self.sim.y)
        return bool(self.loop.state.holding)


@pytest.mark.parametrize("jit", [True, False], ids=["compiled", "interpreted"])
def test_the_closed_loop_in_ticks_of_any_size_is_the_drive_stepped_one_step_at_a_time(jit):
    """The drive runs the controller in the run loop a tick at a time (compiled: one call per
    tick). A new path, an operator's command stamped inside a tick, a new payload and ticks of
    7 or 10 steps give what the drive's rule taken one step at a time gives (the node,
    boom-resim and the bags recorded before all agree on it); the parameters' payload
    schedule, which is for whole runs, is not applied, as a manual command's steps do not."""
    from boom_hydraulics.model.parameters import with_updates
    from boom_hydraulics.model.setpoints import move

    p = with_updates(Parameters(), command_payload_times_s=[0.3], command_payload_fractions=[0.0])
    sim, reference = Simulator(p, jit=jit), Simulator(p, jit=jit)
    drive, stepped = CommandedDrive(sim), SteppedDrive(reference)
    angle = float(sim.outputs()["alpha"])
    first, second = move(0.0, angle, 0.0, angle + 0.25, 0.3), move(0.6, angle + 0.1, 0.0, angle + 0.05, 0.3)
    ticks = 400 if jit else 60
    held = []
    for tick, steps in enumerate([7, 10] * (ticks // 2)):
        for d in (drive, stepped):
            if tick == 20:  # the operator takes over at a time inside the next tick (7 steps)
                d.push(d.sim.t + 3.4 * p.time_step_s, 0.2)
            if tick == 30:  # a new goal: the controller starts afresh on the new path
                d.follow(second if jit else first)
            if tick == 120:  # a new payload: the controller takes the new constants, afresh
                d.sim.set_payload_mass(150.0)
                d.parameters_changed()
            if tick == 0:
                d.follow(first)
            d.advance(steps)
        assert (sim.step_count, sim.t) == (reference.step_count, reference.t)
        assert sim.y == pytest.approx(reference.y, rel=1e-12, abs=1e-15), f"tick {tick}"
        assert drive.current == pytest.approx(stepped.current, rel=1e-12, abs=1e-15)
        assert (drive.loop is None) == (stepped.loop is None)
        assert drive.holding == stepped.holding, f"tick {tick}"  # the move settled, or not yet
        assert sim.constants == reference.constants  # the whole payload on the hook throughout
        held.append(drive.holding)
    assert held[21:30] == [False] * 9 and drive.loop is not None  # the override, then the new goal
    if jit:
        assert drive.holding and held.count(True) > 100  # settled at the second path's end
        assert sim.outputs()["alpha"] == pytest.approx(angle + 0.05, abs=0.004)
    drive.follow(first)
    assert not drive.holding  # a new path: not settled until the controller says so
    drive.let_go()
    assert not drive.holding


def test_the_controller_keeps_the_payload_a_whole_run_left_on_the_hook():
    """After a whole run whose payload schedule put the payload down, the controller steps
    with what is on the hook now, as manual commands do."""
    from boom_hydraulics.model.parameters import with_updates
    from boom_hydraulics.model.setpoints import SetpointPath

    p = with_updates(Parameters(), payload_mass_kg=200.0, command_payload_times_s=[0.005],
                     command_payload_fractions=[0.0])  # fmt: skip
    sim, reference = Simulator(p), Simulator(p)
    for s in (sim, reference):
        s.run(0.01, lambda t: 0.0)
    assert sim.constants != Simulator(p).constants  # the payload is down
    drive, stepped = CommandedDrive(sim), SteppedDrive(reference)
    for d in (drive, stepped):
        d.follow(SetpointPath.of([d.sim.t], [float(d.sim.outputs()["alpha"]) + 0.1]))
        d.advance(200)
    assert sim.constants == reference.constants
    assert sim.y == pytest.approx(reference.y, rel=1e-12, abs=1e-15)
    assert sim.energy_residual() == pytest.approx(reference.energy_residual(), abs=1e-9)


@pytest.mark.parametrize("horizon_s", [0.055, 0.3055])
def test_the_controller_goes_on_past_the_end_of_its_run(monkeypatch, horizon_s):
    """The controller's run is FOLLOW_HORIZON_S long (years); past its end the drive begins
    another and takes every step asked for, rather than standing still or losing steps (a run
    of 55 steps, not a whole number of ticks, and one of 305, whose count of passes is no small int)."""
    from boom_hydraulics.model.setpoints import SetpointPath
    from boom_hydraulics.solve import simulator

    monkeypatch.setattr(simulator, "FOLLOW_HORIZON_S", horizon_s)
    sim = Simulator(Parameters())
    drive = CommandedDrive(sim)
    start = float(sim.outputs()["alpha"])
    drive.follow(SetpointPath.of([0.0], [start + 0.1]))
    for _ in range(100):
        drive.advance(10)
    assert sim.step_count == 1000 and sim.t == pytest.approx(1.0)
    assert sim.outputs()["alpha"] > start + 0.08  # lifted towards the target, run after run


def test_the_default_queue_takes_ten_thousand_future_commands_and_refuses_the_next():
    """The documented bound (max_pending, 10 000 by default): exactly at it, then one past it."""
    q = CommandQueue()
    assert all(q.push(1.0 + k * 1e-3, 0.1) for k in range(10_000))
    assert len(q) == 10_000
    assert not q.push(20.0, 0.2)
    assert len(q) == 10_000


def test_new_physical_parameters_keep_the_controller_whatever_string_names_the_mode():
    """A mode read from a file or a ROS parameter is a string of its own, not the literal in the
    code: physical mode keeps the controller driving, with the new parameters."""
    from boom_hydraulics.model.parameters import with_updates
    from boom_hydraulics.model.setpoints import SetpointPath

    sim = Simulator(Parameters())
    drive = CommandedDrive(sim)
    drive.follow(SetpointPath.of([0.0], [0.3]))
    mode = "".join(["phys", "ical"])  # equal to "physical", another object
    sim.set_parameters(with_updates(sim.params, mode=mode, payload_mass_kg=150.0))
    drive.parameters_changed()
    assert drive.loop is not None and drive.loop.path.at(0.0)[0] == pytest.approx(0.3)


def test_a_command_far_older_than_the_timeout_is_stale_and_paper_mode_read_from_a_file_clamps_to_0_1():
    assert stale(0.0, 5.0, 0.25)  # 20 timeouts old
    assert stale(1.0, 1.2500001, 0.25)  # one past the timeout
    paper = "".join(["pa", "per"])  # equal to "paper", another object (as read from a file)
    assert valve_opening(-0.4, paper) == 0.0 and valve_opening(1.5, paper) == 1.0


@pytest.mark.parametrize(
    ("timeout_s", "open_steps"),
    [(0.0055, 5), (0.0055 + 1e-13, 6), (0.0045, 4), (0.00551, 6), (0.0005, 0), (0.00051, 1)],
)
def test_a_command_times_out_at_the_step_within_half_a_step_of_its_deadline_exactly_and_a_hair_past(
    timeout_s, open_steps
):
    """The boundary of the timeout: a deadline exactly half a step after a step's start closes
    the valve for that step; a hair (1e-13 s) later, for the next; taken in one advance or step by step."""
    for steps in (1, 12):
        drive = CommandedDrive(Simulator(Parameters()), timeout_s=timeout_s)
        drive.push(0.0, 0.6)
        openings = []
        for _ in range(12 // steps):
            drive.advance(steps)
            openings.append(drive.sim.u)
        assert drive.sim.step_count == 12
        if steps == 1:
            assert openings == [0.6] * open_steps + [0.0] * (12 - open_steps)
            stepped = drive.sim.y
        else:
            assert drive.current == 0.0
            assert drive.sim.y == pytest.approx(stepped, rel=1e-12, abs=1e-15)  # the same steps open


def test_a_reset_closes_the_valve_and_forgets_the_commands_waiting():
    drive = CommandedDrive(Simulator(Parameters()), timeout_s=0.0)
    drive.push(0.0, 0.6)
    drive.push(0.004, -0.3)
    drive.advance(2)
    assert drive.current == 0.6
    drive.reset()
    assert drive.current == 0.0 and len(drive.queue) == 0 and drive.last_command_s is None
    drive.advance(6)
    assert drive.sim.u == 0.0


@pytest.mark.parametrize("where", [0.25, 0.75])
def test_the_controller_starts_afresh_from_a_state_reset_under_it(where):
    """The boom put elsewhere, lower or higher, while the controller drives (the node's reset
    service, keeping the clock): the controller goes on from the new state, as the drive taken
    step by step does."""
    from boom_hydraulics.model.setpoints import SetpointPath

    p = Parameters()
    sims = Simulator(p), Simulator(p)
    drive, stepped = CommandedDrive(sims[0]), SteppedDrive(sims[1])
    length = p.cylinder_min_length_m + where * (p.cylinder_max_length_m - p.cylinder_min_length_m)
    for d in (drive, stepped):
        d.follow(SetpointPath.of([0.0], [float(d.sim.outputs()["alpha"]) + 0.1]))
        d.advance(30)
        d.sim.reset(length, keep_time=True)
        d.advance(30)
    assert sims[0].y == pytest.approx(sims[1].y, rel=1e-12, abs=1e-15)


@pytest.mark.parametrize("opening", [-1.0, 1.0, -0.25])
def test_a_command_at_either_end_of_the_valve_times_out_as_any_other(opening):
    drive = CommandedDrive(Simulator(Parameters()), timeout_s=0.003)
    drive.push(0.0, opening)
    openings = []
    for _ in range(5):
        drive.advance(1)
        openings.append(drive.sim.u)
    assert openings == [opening] * 3 + [0.0] * 2


def test_the_same_goal_sent_again_is_not_settled_until_the_controller_says_so():
    """A goal equal to the one followed, sent again (a new path with the same knots): the
    controller starts afresh on it, so the move is not settled until it says so again."""
    from boom_hydraulics.model.setpoints import SetpointPath

    drive = CommandedDrive(Simulator(Parameters()))
    target = float(drive.sim.outputs()["alpha"])
    drive.follow(SetpointPath.of([0.0], [target]))
    for _ in range(50):
        drive.advance(10)
        if drive.holding:
            break
    assert drive.holding
    drive.follow(SetpointPath.of([0.0], [target]))
    assert not drive.holding


def test_a_drive_keeps_the_valve_closed_until_its_first_command():
    drive = CommandedDrive(Simulator(Parameters()), timeout_s=0.5)
    drive.advance(5)
    assert drive.current == 0.0 and drive.sim.u == 0.0


def test_a_drive_takes_ten_thousand_future_commands_by_default_and_without_a_timeout_holds_the_valve():
    drive = CommandedDrive(Simulator(Parameters()))
    assert all(drive.push(1.0 + k * 1e-3, 0.1) for k in range(10_000))
    assert not drive.push(20.0, 0.2)  # one past the bound
    drive.queue.clear()
    drive.push(0.0, 0.6)
    drive.advance(1100)  # past a second: no timeout unless one is given
    assert drive.current == 0.6 and drive.sim.u == 0.6


def test_the_steps_before_the_next_command_count_to_the_earliest_queued_whatever_the_order_sent():
    q = CommandQueue()
    q.push(0.0030, 0.5)
    q.push(0.0104, 1.0)  # sent after, due later
    assert q.steps_until_next(0.0, 0.001, 100) == 3
