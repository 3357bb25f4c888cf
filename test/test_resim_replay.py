"""boom-resim's replay of a recorded run, called directly on runs made here (resim.resimulation):
each command acts where the node acted on it (at its stamp, or where the node took it, a stale
one never), the node's state instants are given again with their stamps, a reset and a pause
are reproduced, a recorded parameter change acts at its time unless --set holds it, and a bag
without drive states is stepped at its publish rate. The reference is the node's own rule,
stepped tick by tick with solve.command_queue.CommandedDrive as the node steps it."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from conftest import CONFIG
from machine_bags import EPOCH_NS, params_file, record_node, valve_command
from rosbags.highlevel import AnyReader

pytest.importorskip("rclpy")
from rclpy.serialization import serialize_message
from std_msgs.msg import String

from boom_hydraulics.bags.encoding import DRIVE_STATE, ENERGY_LEDGER, drive_state_cdr
from boom_hydraulics.bags.energy import ledger_every
from boom_hydraulics.bags.reading import read_drive_states, read_energy_ledger_messages
from boom_hydraulics.bags.recording import BagRecorder, Topic, run_description
from boom_hydraulics.bags.run_description import RunDescription
from boom_hydraulics.bags.run_events import EVENTS_TYPE, RunEvent
from boom_hydraulics.errors import ConfigError, SimulationError
from boom_hydraulics.model import config
from boom_hydraulics.model.parameters import Parameters, as_dict, with_updates
from boom_hydraulics.model.setpoints import SetpointPath
from boom_hydraulics.resim import resimulation
from boom_hydraulics.resim.recorded import Recorded, RecordedRun
from boom_hydraulics.resim.resimulation import Replay, resimulate
from boom_hydraulics.solve.command_queue import CommandedDrive
from boom_hydraulics.solve.simulation import Simulator

ORIGIN = 7_000_000_000  # the node-clock time of simulated time 0
MS = 1_000_000
PUBLISH_NS = 700_000  # a state is logged this long after its instant
TOPIC = "/boom_sim/valve_command"


def _command(opening: float, log_ms: float, stamp_ms: float | None, taken_after: int | None, origin: int = ORIGIN):
    """A command as read_run reads it: logged at ``log_ms``, stamped (or not), taken by the node
    after it had published ``taken_after`` states (None: a bag without drive states)."""
    log_ns = origin + round(log_ms * MS)
    stamp_ns = 0 if stamp_ms is None else origin + round(stamp_ms * MS)
    taken_ns = None if taken_after is None else origin + taken_after * 10 * MS
    at_ns = max(stamp_ns, log_ns if taken_ns is None else taken_ns)
    return Recorded(
        at_ns, log_ns, TOPIC, b"", opening, stamp_ns=stamp_ns, taken_ns=taken_ns,
        taken_after=taken_after or 0, origin_ns=origin,
    )  # fmt: skip


def _change(at_ms: float, **changes) -> Recorded:
    at_ns = ORIGIN + round(at_ms * MS)
    return Recorded(at_ns, at_ns, "/parameter_events", b"", changes=changes, origin_ns=ORIGIN)


def _run(
    states: Sequence[int],
    commands: Sequence[Recorded] = (),
    changes: Sequence[Recorded] = (),
    events: Sequence[RunEvent] = (),
    timeout_s: float = 0.0,
    end_ms: float = 200.0,
    params: Parameters | None = None,
    event_logs: Sequence[int] = (),
) -> RecordedRun:
    """A run whose states were stamped at ``states`` (ns on the node's clock), each logged
    PUBLISH_NS after it; with ``events``, a run that recorded them (logged at ``event_logs``,
    by default all at the origin)."""
    description = RunDescription.of(
        params or Parameters(), ORIGIN, 100.0, timeout_s, node="/boom_sim",
        events_topic="/boom_sim/events" if events else None,
    )  # fmt: skip
    return RecordedRun(
        description=description,
        end_ns=ORIGIN + round(end_ms * MS),
        state_topic="/boom_sim/drive_state",
        state_ns=list(states),
        state_log_ns=[s + PUBLISH_NS for s in states],
        topics=[],
        commands=list(commands),
        parameter_changes=sorted(changes, key=lambda r: r.at_ns),
        events=list(events),
        event_messages=[(log, b"") for log in event_logs or [ORIGIN] * len(events)],
    )


def _ticks(n: int) -> list[int]:
    return [ORIGIN + 10 * MS * k for k in range(1, n + 1)]


def _replayed(run: RecordedRun, overrides=()) -> list[tuple[int, dict]]:
    return list(Replay(run, dict(run.parameters), dict(overrides)))


def test_each_command_acts_at_its_stamp_or_where_the_node_took_it_and_a_stale_one_never():
    """States every 10 ms: a command stamped ahead acts at its stamp (35 ms); an unstamped one
    where the node took it, at the state before it (60 ms, logged at 62); one whose stamp had
    passed (80 ms, logged at 95) at the next step, its timeout of 100 ms counted from its stamp;
    one older than the timeout when it arrived is refused. Every state instant comes back with
    its stamp, and the rod moves as the node's rule moves it, step for step."""
    commands = [
        _command(0.6, 12.0, 35.0, 1),
        _command(-0.3, 62.0, None, 6),
        _command(0.9, 95.0, 80.0, 9),
        _command(-1.0, 150.0, 20.0, 15),  # 130 ms old on arrival: stale
    ]
    run = _run(_ticks(20), commands, timeout_s=0.1)
    given = _replayed(run)
    assert [stamp for stamp, _ in given] == run.state_ns
    u = {round((stamp - ORIGIN) / MS): out["u"] for stamp, out in given}
    # (a state's u is the opening of the step that ended there: c3 closes from 180 ms on)
    assert [u[t] for t in (30, 40, 60, 70, 90, 100, 180, 190, 200)] == [
        0.0, 0.6, 0.6, -0.3, -0.3, 0.9, 0.9, 0.0, 0.0
    ]  # fmt: skip
    # the node: ticks of 10 ms, the commands taken between them
    sim = Simulator(Parameters())
    drive = CommandedDrive(sim, 0.1)
    rods = []
    for k in range(20):
        if k == 1:
            drive.push(0.035, 0.6)
        if k == 6:
            drive.push(sim.t, -0.3)
        if k == 9:
            drive.push(0.08, 0.9)
        drive.advance(10)
        rods.append(sim.outputs()["q1"])
    assert [out["q1"] for _, out in given] == pytest.approx(rods, rel=0, abs=1e-12)


def test_a_command_logged_between_a_state_and_the_next_acts_after_that_state_not_before():
    """The node takes a command between ticks: one logged at 40.5 ms, before the state of 40 ms
    was logged (40.7 ms), was taken after the state of 30 ms: it acts from 30 ms."""
    run = _run(_ticks(6), [_command(0.5, 40.5, None, 3)])
    u = [out["u"] for _, out in _replayed(run)]
    assert u == [0.0, 0.0, 0.0, 0.5, 0.5, 0.5]


def test_a_run_without_drive_states_is_stepped_at_its_publish_rate_with_commands_when_logged():
    """No DriveState in the bag: states every 1/publish_rate (10 ms) up to the bag's end, each
    command at its stamp or its log time."""
    commands = [_command(0.4, 25.0, None, None), _command(-0.2, 41.0, 62.0, None)]
    run = _run([], commands, end_ms=95.0)
    given = _replayed(run)
    assert [stamp for stamp, _ in given] == _ticks(9)
    # a bag ending on an instant has it: 1 s at 10 Hz is 10 states (though 1.0 // 0.1 is 9)
    slow = _run([], end_ms=1000.0)
    slow.description = dataclasses.replace(slow.description, publish_rate_hz=10.0)
    assert [(stamp - ORIGIN) // MS for stamp, _ in _replayed(slow)] == list(range(100, 1001, 100))
    u = [out["u"] for _, out in given]
    assert u == [0.0, 0.0, 0.4, 0.4, 0.4, 0.4, -0.2, -0.2, -0.2]


def test_a_run_without_drive_states_published_faster_than_the_steps_is_stepped_a_step_at_a_time():
    """Published at 2 kHz with steps of 1 ms: a state at every step, never at none; a command
    that is not a number (a Float64MultiArray of another length) is ignored."""
    commands = [_command(0.5, 2.0, None, None), _command(float("nan"), 4.0, None, None)]
    run = _run([], commands, end_ms=6.0)
    run.description = RunDescription.of(Parameters(), ORIGIN, 2000.0, 0.0, node="/boom_sim")
    given = _replayed(run)
    assert [(stamp - ORIGIN) // MS for stamp, _ in given] == [1, 2, 3, 4, 5, 6]
    assert [out["u"] for _, out in given] == [0.0, 0.0, 0.5, 0.5, 0.5, 0.5]


def test_a_reset_puts_the_rod_where_the_node_put_it_and_a_pause_moves_the_stamps():
    """The node paused after its 5th state for 300 ms (its origin moved by that), then was reset
    to q1 = 1.3 m after its 10th (at 100 ms, the instant published again): the states come back
    with their recorded stamps, the rod at 1.3 m at rest there, and a command queued for later
    before the reset is forgotten, as the node forgot it; one logged after the reset, in the
    same gap between ticks, acts from there on."""
    moved = ORIGIN + 300 * MS
    events = [
        RunEvent("pause", 0.05, 5, ORIGIN),
        RunEvent("resume", 0.05, 5, moved, origin_moved_ns=300 * MS),
        RunEvent("reset", 0.1, 10, moved, cause="service", rod_position_m=1.3),
    ]
    sim_ms = [10 * k for k in range(1, 11)] + [100 + 10 * k for k in range(0, 6)]
    states = [(ORIGIN if k < 5 else moved) + ms * MS for k, ms in enumerate(sim_ms)]
    commands = [
        _command(0.7, 12.0, None, 1),
        _command(-0.7, 75.0, 130.0, 7, origin=moved),
        _command(0.4, 100.8, 140.0, 10, origin=moved),  # logged before the reset, in the same gap
        _command(-0.2, 101.2, 120.0, 10, origin=moved),  # logged after it
    ]
    logs = [ORIGIN + 50 * MS + PUBLISH_NS + 1, moved + 350 * MS, moved + round(101.0 * MS)]
    run = _run(states, commands, events=events, end_ms=500.0, event_logs=logs)
    given = _replayed(run)
    assert [stamp for stamp, _ in given] == states
    # with a longer step, an instant that rounds onto the one before is given all the same
    assert len(_replayed(run, {"time_step_s": 0.015})) == len(states)
    q1 = [out["q1"] for _, out in given]
    assert q1[9] > q1[4] > q1[1]  # lifting on the first command
    assert q1[10] == pytest.approx(1.3, abs=1e-12) and given[10][1]["u"] == 0.0 and given[10][1]["v"] == 0.0
    # the commands for 130 and 140 ms went with the reset; the one for 120 ms came after it
    assert [out["u"] for _, out in given[10:]] == [0.0, 0.0, 0.0, -0.2, -0.2, -0.2]
    assert q1[11] < 1.3  # the boom, let go at rest, sinks on its oil a little: it moves from 1.3 m


def _reset_between(before: int, after: int) -> Simulator:
    """The node's rule stepped tick by tick: valve 0.9 from 0 s, ``before`` ticks, a reset to
    q1 = 1.45 m keeping the time, then ``after`` ticks."""
    sim = Simulator(Parameters())
    drive = CommandedDrive(sim)
    drive.push(0.0, 0.9)
    drive.advance(before)
    sim.reset(1.45, keep_time=True)
    drive.reset()
    drive.advance(after)
    return sim


def test_a_reset_between_published_states_is_made_at_its_own_instant():
    """The node reset at 101 ms, a step after the state of 100 ms (a publish period longer than
    its ticks): the drive runs on to 101 ms, is reset there keeping the time, and the next
    state, 110 ms, is 9 ms after the reset."""
    events = [RunEvent("reset", 0.101, 10, ORIGIN, cause="service", rod_position_m=1.45)]
    run = _run(_ticks(14), [_command(0.9, 3.0, None, 0)], events=events, event_logs=[ORIGIN + 101 * MS])
    given = _replayed(run)
    sim = _reset_between(101, 9)
    assert given[10][1]["q1"] == pytest.approx(sim.outputs()["q1"], rel=0, abs=1e-12)
    assert given[10][0] == ORIGIN + 110 * MS and given[9][1]["q1"] > Parameters().initial_length_m + 0.005


def test_a_recorded_parameter_change_acts_at_its_time_and_a_set_value_stays_on_top():
    """A payload changed to 400 kg at 50 ms (with a setting of the node's own, not the model's):
    the rod from there moves as a drive that took it then; with --set payload_mass_kg the change
    is not taken, and the run is the unchanged one."""
    commands = [_command(0.8, 5.0, None, 0)]
    later_pace = _change(110.0, real_time_factor=1.0)  # (a change after it waits its own turn)
    run = _run(_ticks(12), commands, changes=[_change(50.0, payload_mass_kg=400.0, real_time_factor=2.0), later_pace])
    changed = [out["q1"] for _, out in _replayed(run)]
    # the node takes a change between ticks, within half a step of an instant: 50.4 ms at 50 ms
    near = _run(_ticks(12), commands, changes=[_change(50.4, payload_mass_kg=400.0)])
    assert [out["q1"] for _, out in _replayed(near)] == changed
    sim = Simulator(Parameters())
    drive = CommandedDrive(sim)
    drive.push(0.0, 0.8)
    rods = []
    for k in range(12):
        if k == 5:
            sim.set_parameters(with_updates(sim.params, payload_mass_kg=400.0))
            drive.parameters_changed()
        drive.advance(10)
        rods.append(sim.outputs()["q1"])
    assert changed == pytest.approx(rods, rel=0, abs=1e-12)
    later = _run(_ticks(12), commands, changes=[_change(50.6, payload_mass_kg=400.0)])
    at_60 = _run(_ticks(12), commands, changes=[_change(60.0, payload_mass_kg=400.0)])
    assert [out["q1"] for _, out in _replayed(later)] == [out["q1"] for _, out in _replayed(at_60)] != changed
    held = [out["q1"] for _, out in _replayed(run, {"payload_mass_kg": 50.0})]
    plain = [out["q1"] for _, out in _replayed(_run(_ticks(12), commands))]
    assert held == pytest.approx(plain, rel=0, abs=1e-12) and held[-1] > changed[-1] + 1e-4


def test_a_recorded_command_timeout_change_times_commands_out_from_its_time_on():
    """command_timeout_s set from 0 (none) to 30 ms at 40 ms: it times out the command of 20 ms
    at 50 ms, one of 60 ms 30 ms later, and one logged at 120 ms, stamped 40 ms before, arrived
    stale by it (a state's u is the opening of the step that ended there)."""
    commands = [_command(0.5, 15.0, 20.0, 1), _command(0.3, 55.0, 60.0, 5), _command(0.9, 120.0, 80.0, 12)]
    run = _run(_ticks(16), commands, changes=[_change(40.0, command_timeout_s=0.03)])
    u = [out["u"] for _, out in _replayed(run)]
    assert u == [0.0, 0.0, 0.5, 0.5, 0.5, 0.0, 0.3, 0.3, 0.3, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]


def test_a_recorded_change_that_does_not_fit_the_new_parameters_names_itself():
    run = _run(_ticks(8), changes=[_change(30.0, payload_mass_kg=-5.0)])
    with pytest.raises(ConfigError, match="a recorded parameter change does not fit the new parameters"):
        _replayed(run)


def test_a_longer_step_acts_a_command_where_the_node_took_it_and_gives_every_state():
    """States every 10 ms re-simulated with 15 ms steps: the instant 20 ms rounds onto 15 ms; a
    command the node took there acts from 15 ms, as one taken at 15 ms would; an instant that
    rounds onto the one before is not given twice (the run has no events)."""
    run = _run(_ticks(10), [_command(0.7, 25.0, None, 2)])
    given = _replayed(run, {"time_step_s": 0.015})
    assert [(round((stamp - ORIGIN) / MS), out["u"]) for stamp, out in given] == [
        (15, 0.0), (30, 0.7), (45, 0.7), (60, 0.7), (75, 0.7), (90, 0.7), (105, 0.7)
    ]  # fmt: skip


def test_the_replay_starts_from_the_bags_parameters():
    heavy = with_updates(Parameters(), payload_mass_kg=300.0)
    run = _run(_ticks(3), params=heavy)
    replay = Replay(run, as_dict(heavy))
    assert replay.params.payload_mass_kg == 300.0 and len(list(replay)) == replay.done == 3


def _messages(bag: Path) -> list[tuple[str, int, bytes]]:
    with AnyReader([bag]) as reader:
        return [(c.topic, log_ns, bytes(raw)) for c, log_ns, raw in reader.messages()]


def test_the_new_bag_has_each_state_where_the_node_logged_it_the_commands_as_recorded_and_the_ledger(tmp_path):
    """A node's bag re-simulated unchanged (boom-resim bag --out new): the states as recorded,
    stamp for stamp and logged when the node logged them, the commands copied byte for byte at
    their log times, the energy ledger at ENERGY_HZ; its count is the states'. A second run to
    the same --out is refused; a heavier payload (--set) lifts less."""
    bag = record_node(tmp_path / "node", commands=((0.005, 0.1), (0.05, 0.8), (0.3, -0.4)), duration_s=0.5)
    out, count = resimulate(bag, tmp_path / "new")
    assert out == tmp_path / "new"
    recorded, again = read_drive_states(bag), read_drive_states(out)
    assert count == len(again["q1"]) == len(recorded["q1"]) == 50
    assert np.array_equal(again["t"], recorded["t"]) and np.max(np.abs(again["q1"] - recorded["q1"])) < 1e-12
    assert np.array_equal(again["u"], recorded["u"]) and again["u"].max() == 0.8
    old, new = _messages(bag), _messages(out)
    states = lambda messages: [log for topic, log, _ in messages if topic == "/drive_state"]  # noqa: E731
    assert states(new) == states(old)
    commands = lambda messages: [m for m in messages if m[0] == "/valve_command"]  # noqa: E731
    assert commands(new) == commands(old) and len(commands(new)) == 3  # one before the first state
    # each in log order among the states, as the node logged it
    order = [topic for topic, _, _ in new if topic in ("/drive_state", "/valve_command")]
    assert order == [topic for topic, _, _ in old]
    ledger = read_energy_ledger_messages(out)
    assert len(ledger) == 50 // ledger_every(100.0) and ledger[0][0] == EPOCH_NS + ledger_every(100.0) * 10_000_000
    with pytest.raises(ConfigError, match="exists already"):
        resimulate(bag, out)
    heavy, _ = resimulate(bag, tmp_path / "heavy", overrides={"payload_mass_kg": 400.0, "mode": "physical"})
    assert len(read_energy_ledger_messages(heavy)) == len(ledger)
    assert read_drive_states(heavy)["q1"].max() < again["q1"].max() - 1e-4


def test_the_controller_follows_the_recorded_setpoints_from_the_instant_before_them_and_lets_go_at_their_end():
    """Setpoints recorded at the instants 30-80 ms, a ramp of 1 degree: the controller took over at
    20 ms (the instant before the first) from where the boom was, drove the valve along them and
    let go at 80 ms (the valve closed from there), as the node's controller, stepped tick by tick."""
    alpha0 = Simulator(Parameters()).outputs()["alpha"]
    ramp = math.radians(1.0)
    setpoints = [(ORIGIN + 10 * MS * k, alpha0 + ramp * (k - 2) / 6, ramp / 0.06) for k in range(3, 9)]
    run = _run(_ticks(15))
    run.setpoints = setpoints
    given = _replayed(run)
    # a stretch of the first two instants only: taken over at 10 ms, let go at 20 ms
    early = _run(_ticks(5))
    early.setpoints = [(ORIGIN + 10 * MS, alpha0, 0.0), (ORIGIN + 20 * MS, alpha0 + ramp, ramp / 0.01)]
    assert [out["u"] != 0.0 for _, out in _replayed(early)] == [False, True, False, False, False]
    # and one of the two before the last: taken over at 20 ms, let go at 40 ms
    late = _run(_ticks(5))
    late.setpoints = [(ORIGIN + 30 * MS, alpha0, 0.0), (ORIGIN + 40 * MS, alpha0 + ramp, ramp / 0.01)]
    assert [out["u"] != 0.0 for _, out in _replayed(late)] == [False, False, True, True, False]
    sim = Simulator(Parameters())
    drive = CommandedDrive(sim)
    rods = []
    for k in range(1, 16):
        if k == 3:
            angle, rate = drive.setpoint()
            times = [sim.t] + [(ns - ORIGIN) * 1e-9 for ns, _, _ in setpoints]
            path = SetpointPath.of(times, [angle] + [a for _, a, _ in setpoints], [rate] + [r for _, _, r in setpoints])
            drive.follow(path)
        drive.advance(10)
        if k == 8:
            drive.let_go()
        rods.append(sim.outputs()["q1"])
    assert [out["q1"] for _, out in given] == pytest.approx(rods, rel=0, abs=1e-12)
    u = [out["u"] for _, out in given]
    assert all(x == 0.0 for x in u[:2]) and all(x > 0.0 for x in u[2:8]) and all(x == 0.0 for x in u[8:])
    assert given[7][1]["alpha"] > alpha0 + 0.2 * ramp  # it lifted along the ramp


def _record_reset_node(folder: Path) -> list[float]:
    """A node's bag with its run events: states every 10 ms, a command at 12 ms, a reset to
    q1 = 1.3 m after the state of 100 ms (the instant published again), a command at 132 ms;
    returns the rod position of each state."""
    params = Parameters()
    sim = Simulator(params)
    drive = CommandedDrive(sim)
    events = "/boom_sim/events"
    custom = run_description(params, EPOCH_NS, 100.0, 0.0, node="/boom_sim", events_topic=events)
    topics = [
        Topic("/boom_sim/drive_state", DRIVE_STATE),
        Topic("/boom_sim/valve_command", "boom_hydraulics_msgs/msg/ValveCommand"),
        Topic(events, EVENTS_TYPE),
    ]
    rods = []
    with BagRecorder(folder, topics, custom_data=custom) as rec:

        def state() -> None:
            stamp_ns = EPOCH_NS + round(sim.t * 1e9)
            rec.write("/boom_sim/drive_state", stamp_ns + PUBLISH_NS, drive_state_cdr(sim.outputs(), stamp_ns))
            rods.append(float(sim.outputs()["q1"]))

        for k in range(1, 21):
            if k in (2, 14):  # taken after the state of 10 (130) ms
                log_ns = EPOCH_NS + (k - 1) * 10 * MS + 2 * MS
                rec.write("/boom_sim/valve_command", log_ns, valve_command(0, 0.8))
                drive.push(sim.t, 0.8)
            drive.advance(10)
            state()
            if k == 10:
                reset = RunEvent("reset", sim.t, 10, EPOCH_NS, cause="service", rod_position_m=1.3)
                rec.write(events, EPOCH_NS + 101 * MS, serialize_message(String(data=reset.to_json())))
                sim.reset(1.3, keep_time=True)
                drive.reset()
                state()
    return rods


def test_a_reset_node_run_is_written_again_with_its_reset_and_its_events(tmp_path):
    """A bag with the node's run events: the re-simulation resets where the node reset (the
    state after it at 1.3 m, the instant given twice), every state as recorded, and the new bag
    holds the run events as recorded, so that it can be re-simulated in turn."""
    bag = tmp_path / "node"
    rods = _record_reset_node(bag)
    out, count = resimulate(bag, tmp_path / "runs" / "what_if" / "new")  # (its parents made too)
    assert count == len(rods) == 21
    old, new = _messages(bag), _messages(out)
    again = [topic_log for topic_log in new if topic_log[0] == "/boom_sim/drive_state"]
    assert [log for _, log, _ in again] == [log for topic, log, _ in old if topic == "/boom_sim/drive_state"]
    assert [m for m in new if m[0] == "/boom_sim/events"] == [m for m in old if m[0] == "/boom_sim/events"]
    states = read_drive_states(out)  # (by stamp, stable: the instant of the reset before, then after it)
    assert list(states["q1"]) == pytest.approx(rods, rel=0, abs=1e-12) and states["q1"][10] == 1.3
    out2, count2 = resimulate(out, tmp_path / "again")
    assert count2 == 21 and np.array_equal(read_drive_states(out2)["q1"], states["q1"])


def test_a_disk_that_failed_is_named_with_its_cause_and_where_to_free_space(tmp_path):
    """The one line for a new bag the disk did not take: the cause, without the file's name or
    the recorder's tail, and where to free space."""
    out = tmp_path / "new"
    file = tmp_path / "staging" / "bag" / "new_0.mcap"
    recorder = SimpleNamespace(file=file, error=f"{file}: [Errno 28] No space left on device; recording stopped")
    message = str(resimulation._write_failure(out, recorder))
    assert message == (
        f"{out}: cannot write the new bag ([Errno 28] No space left on device); nothing was written. "
        f"Free space in {tmp_path} or choose another --out"
    )
    recorder.error = None
    assert "(the disk failed)" in str(resimulation._write_failure(out, recorder))


def test_the_bags_parameters_or_a_config_files_and_those_of_an_earlier_model_left_out(tmp_path, capsys):
    """read_recorded: the bag's own parameters, or --config's in their place; a bag of an earlier
    model keeps what this one has, and says what it left out."""
    bag = record_node(tmp_path / "node", truth={"payload_mass_kg": 120.0}, commands=((0.05, 0.5),), duration_s=0.1)
    run, values = resimulation.read_recorded(bag)
    assert values == run.parameters and values["payload_mass_kg"] == 120.0
    config_file = params_file(tmp_path / "params.yaml", {"payload_mass_kg": 80.0})
    _, values = resimulation.read_recorded(bag, config_file)
    assert values["payload_mass_kg"] == 80.0
    assert capsys.readouterr().err == ""
    old = resimulation.read_run_description(bag)
    old = dataclasses.replace(old, parameters={**old.parameters, "pump_ripple_n": 3.0})
    _, values = resimulation.read_recorded(bag, description=old)
    assert "pump_ripple_n" not in values and values["payload_mass_kg"] == 120.0
    err = capsys.readouterr().err
    assert err.startswith("boom-resim: note: ") and "(pump_ripple_n)" in err and len(err.splitlines()) == 1


def test_a_paper_mode_what_if_writes_no_energy_ledger(tmp_path):
    bag = record_node(tmp_path / "node", commands=((0.05, 0.5),), duration_s=0.3)
    out, count = resimulate(bag, tmp_path / "paper", overrides={"mode": "paper"})
    assert count == 30 and read_energy_ledger_messages(out) == []
    with AnyReader([out]) as reader:
        assert all(c.msgtype != ENERGY_LEDGER for c in reader.connections)


@pytest.mark.parametrize("stopped", [True, False])
def test_a_what_if_that_fails_before_a_reset_the_node_made_on_its_own_failure_goes_on_from_the_reset(stopped):
    """Paper mode's fig. 8, the valve held open: the node's rod left the geometry at 2.194 s, it
    stood still (no states after 2.1 s at 10 Hz) and was reset there. A lighter payload leaves it
    sooner, at 2.169 s, after the last state: the re-simulation stops there as the node did, is
    reset and goes on at rest. Where the node had not stopped, the failure is the what-if's own,
    and ends the run."""
    fig8 = config.load(CONFIG / "paper_fig8.yaml")
    instants = [ORIGIN + 100 * MS * k for k in range(1, 22)] + [ORIGIN + 100 * MS * k for k in range(22, 26)]
    events = [RunEvent("reset", 2.194, 21, ORIGIN, cause="service", stopped=stopped)]
    run = _run(instants, [_command(1.0, 1.0, None, 0)], events=events, params=fig8, end_ms=2500.0)
    run.description = RunDescription.of(fig8, ORIGIN, 10.0, 0.0, node="/boom_sim", events_topic="/boom_sim/events")
    replay = Replay(run, as_dict(fig8), {"payload_mass_kg": 45.0})
    if not stopped:
        with pytest.raises(SimulationError, match="the rod is about to leave the valid geometry"):
            list(replay)
        return
    given = list(replay)
    assert [stamp for stamp, _ in given][-4:] == instants[-4:]
    assert given[20][1]["q1"] > 1.75  # 2.1 s: nearly out
    assert given[21][1]["q1"] == pytest.approx(fig8.initial_length_m, abs=1e-3) and given[21][1]["u"] == 0.0


def test_a_reset_long_after_the_last_state_runs_the_drive_on_to_it_first():
    """States at 10-50 ms, then none until the node was reset at 107 ms (a run stepped without
    publishing): the drive runs on the 57 ms to the reset, is reset there, and goes on."""
    states = [ORIGIN + MS * ms for ms in (10, 20, 30, 40, 50, 110, 120, 130)]
    events = [RunEvent("reset", 0.107, 5, ORIGIN, cause="service", rod_position_m=1.45)]
    run = _run(states, [_command(0.9, 3.0, None, 0)], events=events, event_logs=[ORIGIN + 107 * MS])
    given = _replayed(run)
    sim = _reset_between(107, 3)
    assert given[5][0] == ORIGIN + 110 * MS
    assert given[5][1]["q1"] == pytest.approx(sim.outputs()["q1"], rel=0, abs=1e-12)


def test_a_recorded_timeout_counts_for_the_commands_logged_at_or_after_it_and_none_before():
    """The base command timeout 100 ms, set to 60 ms by a change logged at 40 ms. A command
    logged at 25 ms, stamped 75 ms before, arrived in time by the 100 ms (it acts at 20 ms); one
    logged at 40 ms, the change's very time, stamped 75 ms before, arrived stale by the 60 ms,
    and leaves the valve to the command of 35 ms, which closes 60 ms after its stamp."""
    commands = [
        _command(0.7, 25.0, -50.0, 2),
        _command(0.3, 33.0, 35.0, 3),
        _command(0.9, 40.0, -35.0, 4),
        _command(0.8, 52.0, -20.0, 5),  # logged after the change, 72 ms old: stale as well
    ]
    run = _run(_ticks(11), commands, changes=[_change(40.0, command_timeout_s=0.06)], timeout_s=0.1)
    u = [out["u"] for _, out in _replayed(run)]
    assert u == [0.0, 0.0, 0.7, 0.3, 0.3, 0.3, 0.3, 0.3, 0.3, 0.0, 0.0]


def test_a_run_on_simulated_time_without_drive_states_is_stepped_from_stamp_zero():
    """publish_clock: the time origin is 0 (stamps are simulated time); a bag without drive
    states is stepped on the publish rate's grid from there to its end."""
    run = _run([], end_ms=45.0)
    run = dataclasses.replace(
        run,
        description=dataclasses.replace(run.description, clock_origin_ns=0),
        end_ns=45 * MS,
        commands=[_command(0.6, 12.0, None, None, origin=0)],
    )
    given = _replayed(run)
    assert [(stamp // MS, out["u"]) for stamp, out in given] == [(10, 0.0), (20, 0.6), (30, 0.6), (40, 0.6)]


def test_a_reset_after_hundreds_of_states_is_made_there():
    """Published at 1 kHz, reset after the 280th state: the 281st is the rod at rest where the
    reset put it (the state counts are numbers, however large)."""
    states = [ORIGIN + k * MS for k in range(1, 281)] + [ORIGIN + k * MS for k in range(280, 300)]
    events = [RunEvent("reset", 0.28, 280, ORIGIN, cause="service", rod_position_m=1.45)]
    commands = [_command(0.9, 0.5, None, 0), _command(-0.5, 285.9, None, 285)]
    run = _run(states, commands, events=events, event_logs=[ORIGIN + 280 * MS + PUBLISH_NS + 1])
    given = _replayed(run)
    assert len(given) == 300 and given[279][1]["q1"] > 1.38
    assert given[280][1]["q1"] == 1.45 and given[280][0] == ORIGIN + 280 * MS
    assert [out["u"] for _, out in given[284:288]] == [0.0, -0.5, -0.5, -0.5]  # taken after 285 states
