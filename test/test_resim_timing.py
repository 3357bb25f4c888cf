"""boom-resim reproduces a node that fell behind its clock: a command the node took while it
lagged acts, in the re-simulation, at the simulated instant the node took it, not at the
later instant its log time names."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from conftest import run_tool
from machine_bags import EPOCH_NS, valve_command

from boom_hydraulics.bags.encoding import DRIVE_STATE, drive_state_cdr
from boom_hydraulics.bags.reading import read_drive_states
from boom_hydraulics.bags.recording import BagRecorder, Topic, run_description
from boom_hydraulics.model.parameters import from_mapping
from boom_hydraulics.solve.command_queue import CommandedDrive, stale
from boom_hydraulics.solve.simulation import Simulator

TICK_S, TIMEOUT_S = 0.01, 1.0
#: A tick starts this late after the instant it steps to, and publishes its state this late, s.
TICK_START_S, TICK_PUBLISH_S = 5e-4, 7e-4
#: The node's tick thread is stalled (a loaded machine, a debugger) from 2.0 s to 3.5 s of its
#: clock, then catches the whole backlog up in one tick.
STALL_S = (2.0, 3.5)
#: (log time s, stamp s or None for unstamped, opening), as the node received them
COMMANDS = (
    (0.2051, None, 0.8),  # unstamped: acts now
    (0.5003, 0.45, 0.3),  # passed, not stale: acts at the next step, times out 1 s after its stamp
    (0.7003, None, -0.2),  # logged after the instant 0.70, before its tick: acts at 0.69
    (2.6, 1.2, 0.9),  # stale when it arrived: refused
    (3.4002, None, -0.5),  # unstamped while the ticks lag: acts where the node was, 2.0 s
    (3.4501, 3.3, 0.6),  # passed on the clock, but ahead of the lagging node: acts at 3.3 s
)


def _record_lagging_node(folder: Path, commands=COMMANDS, stall_s=STALL_S, end_s: float = 4.0) -> dict[int, float]:
    """A bag as a boom_sim node on the system clock records it when its ticks stall: one
    DriveState at the end of each tick, stamped with the simulated instant and logged when
    published (a little after it), and the commands logged when received, taken between ticks
    by the node's rule (ros.commands). Returns the rod position at each state stamp."""
    params = from_mapping({})
    sim = Simulator(params)
    drive = CommandedDrive(sim, TIMEOUT_S)
    dt = params.time_step_s
    n = round(end_s / TICK_S)
    ticks = [round(k * TICK_S, 9) for k in range(1, n) if not stall_s[0] < k * TICK_S < stall_s[1]]
    commands = list(commands)
    rods = {}
    topics = [Topic("/drive_state", DRIVE_STATE), Topic("/valve_command", "boom_hydraulics_msgs/msg/ValveCommand")]
    custom = run_description(params, EPOCH_NS, 1 / TICK_S, TIMEOUT_S, node="/boom_sim")
    with BagRecorder(folder, topics, custom_data=custom) as rec:
        for wall_s in ticks:
            while commands and commands[0][0] < wall_s + TICK_START_S:  # taken before this tick
                log_s, stamp_s, opening = commands.pop(0)
                stamp_ns = 0 if stamp_s is None else EPOCH_NS + round(stamp_s * 1e9)
                rec.write("/valve_command", EPOCH_NS + round(log_s * 1e9), valve_command(stamp_ns, opening))
                if stamp_s is None or not stale(stamp_s, log_s, TIMEOUT_S):
                    drive.push(sim.t if stamp_s is None else stamp_s, opening)
            drive.advance(round(wall_s / dt) - sim.step_count)
            stamp_ns = EPOCH_NS + round(sim.t * 1e9)
            rods[stamp_ns] = float(sim.outputs()["q1"])
            log_ns = EPOCH_NS + round((wall_s + TICK_PUBLISH_S) * 1e9)
            rec.write("/drive_state", log_ns, drive_state_cdr(sim.outputs(), stamp_ns))
    return rods


def test_a_run_whose_node_fell_behind_resimulates_as_it_ran(tmp_path):
    bag = tmp_path / "lagging"
    rods = _record_lagging_node(bag)
    result = run_tool("boom-resim", bag, "--out", tmp_path / "again")
    assert result.returncode == 0, result.stderr
    again = read_drive_states(tmp_path / "again")
    recorded = read_drive_states(bag)
    assert len(again["q1"]) == len(rods) == len(recorded["q1"])
    # the unstamped command taken while the node lagged moved the boom from 1.0 s on
    caught_up = np.searchsorted(recorded["t"], STALL_S[1] - 1e-9)
    assert recorded["u"][caught_up] == 0.6
    assert np.max(np.abs(again["q1"] - np.array(list(rods.values())))) < 1e-12
    assert np.array_equal(again["u"], recorded["u"])
    # and boom-resim's own bag re-simulates the same: its states keep the recorded log times
    result = run_tool("boom-resim", tmp_path / "again", "--out", tmp_path / "once_more")
    assert result.returncode == 0, result.stderr
    assert np.max(np.abs(read_drive_states(tmp_path / "once_more")["q1"] - again["q1"])) < 1e-12


def test_a_what_if_with_a_longer_step_acts_a_command_where_the_node_took_it(tmp_path):
    """States every 10 ms re-simulated with 15 ms steps: the instant 20 ms rounds onto 15 ms.
    A command the node took at 20 ms acts from the step that starts at 15 ms, as a command
    taken at 15 ms would, not one step later."""
    bag = tmp_path / "node"
    _record_lagging_node(bag, commands=((0.025, None, 0.7),), stall_s=(0.0, 0.0), end_s=0.1)
    result = run_tool("boom-resim", bag, "--set", "time_step_s=0.015", "--out", tmp_path / "coarse")
    assert result.returncode == 0, result.stderr
    again = read_drive_states(tmp_path / "coarse")
    at_30_ms = int(np.argmin(np.abs(again["t"] - 0.03)))
    assert abs(again["t"][at_30_ms] - 0.03) < 1e-9 and again["u"][at_30_ms] == 0.7
    assert np.all(again["u"][again["t"] < 0.02] == 0.0)
