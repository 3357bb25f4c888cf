"""The node's /diagnostics array (bags/diagnostics.py) as a user reads it, built from a real
Simulator (interpreted: no compiling) and read back from its CDR: each status's name, level,
message and key/values, the thresholds of each level, and which statuses appear when."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import pytest

from boom_hydraulics.bags.diagnostics import DIAGNOSTIC_ARRAY, LOW_CHARGE, CommandCounts, RunCounts, diagnostics
from boom_hydraulics.bags.encoding import typestore
from boom_hydraulics.model.parameters import Parameters, with_updates
from boom_hydraulics.solve.simulation import Simulator

# the levels as diagnostic_msgs/msg/DiagnosticStatus defines them (what a reader compares with)
_LEVEL = typestore().types["diagnostic_msgs/msg/DiagnosticStatus"]
OK, WARN, ERROR = _LEVEL.OK, _LEVEL.WARN, _LEVEL.ERROR
RATE_HZ = 50.0  # the node's tick rate here: lag beyond 2 / RATE_HZ = 40 ms is behind


@dataclass
class _Pacer:
    """What the array reads of a solve.pacing.Pacer."""

    lag_s: float = 0.0
    clock_error_s: float = 0.0
    late_ticks: int = 0


def _read(sim: Any, failure: str | None = None, *, paused: bool = False, pacer: _Pacer | None = None,
          rate_hz: float = RATE_HZ, real_time_factor: float = 1.0, commands: CommandCounts | None = None,
          run: RunCounts | None = None, origin_shift_s: float = 0.0,
          recording: tuple[str | None, str] | None = None, stamp_ns: int = 0) -> Any:  # fmt: skip
    data = diagnostics(
        stamp_ns, sim, failure, paused, pacer or _Pacer(), rate_hz, real_time_factor,
        commands or CommandCounts(), run or RunCounts(), origin_shift_s, recording,
    )  # fmt: skip
    return typestore().deserialize_cdr(data, DIAGNOSTIC_ARRAY)


def _statuses(array: Any) -> dict[str, Any]:
    return {s.name: s for s in array.status}


def _values(status: Any) -> dict[str, str]:
    return {kv.key: kv.value for kv in status.values}


def _status(array: Any, name: str) -> Any:
    return _statuses(array)[f"boom_sim: {name}"]


def _sim(**updates: Any) -> Simulator:
    return Simulator(with_updates(Parameters(), **updates) if updates else Parameters(), jit=False)


class _Flagged:
    """A real simulator whose outputs carry the given flags (cavitation and an open relief valve
    take states that are long to reach)."""

    def __init__(self, sim: Simulator, **flags: bool):
        self._sim, self._flags = sim, flags

    def __getattr__(self, name: str) -> Any:
        return getattr(self._sim, name)

    def outputs(self) -> dict[str, Any]:
        return {**self._sim.outputs(), **self._flags}


def test_a_running_drive_shows_every_status_in_order_with_its_values_formatted():
    sim = _sim()
    sim.step(0.5, 123)  # 0.123 s: the battery has given some energy
    array = _read(
        sim,
        paused=True,
        pacer=_Pacer(lag_s=0.0123456, clock_error_s=-0.00012345678),
        real_time_factor=0.5,
        commands=CommandCounts(received=17),
        run=RunCounts(resets=2, pauses=3, step_calls=5),
        origin_shift_s=1.23456789,
        stamp_ns=7 * 10**9 + 11,
    )
    assert (array.header.stamp.sec, array.header.stamp.nanosec) == (7, 11)
    names = [s.name for s in array.status]
    assert names == [
        "boom_sim: drive",
        "boom_sim: battery",
        "boom_sim: real-time",
        "boom_sim: commands",
        "boom_sim: run",
    ]
    assert {s.hardware_id for s in array.status} == {"boom_hydraulics"}
    assert [(s.level, s.message) for s in array.status] == [(OK, "ok")] * 5
    assert _values(array.status[0]) == {
        "sim_time_s": "0.123",
        "paused": "True",
        "substeps_most": str(sim.most_substeps),
        "energy_residual_j": f"{sim.energy_residual():.4g}",
    }
    assert float(_values(array.status[0])["energy_residual_j"]) != 0.0  # the figure, not a placeholder
    battery = _values(array.status[1])
    assert list(battery) == ["state_of_charge", "battery_drawn_j", "battery_returned_j"]
    drawn = float(battery["battery_drawn_j"])
    assert drawn > 0.0 and len(battery["battery_drawn_j"].replace(".", "")) == 6  # 6 significant digits
    assert battery["battery_returned_j"] == "0"
    capacity_j = sim.params.battery_capacity_kwh * 3.6e6
    assert battery["state_of_charge"] == f"{1.0 - drawn / capacity_j:.4f}" == "1.0000"
    assert _values(array.status[2]) == {
        "lag_s": "0.0123",
        "clock_error_s": "-0.000123",
        "dropped_backlogs": "0",
        "real_time_factor": "0.5",
    }
    assert _values(array.status[3]) == {"received": "17", "stale": "0", "lost": "0", "refused": "0"}
    assert _values(array.status[4]) == {
        "resets": "2",
        "pauses": "3",
        "step_calls": "5",
        "clock_origin_shift_s": "1.234568",
    }


def test_the_drive_at_rest_is_not_paused_and_its_balance_starts_at_zero():
    array = _read(_sim(), commands=CommandCounts(), run=RunCounts())
    assert _values(_status(array, "commands")) == {"received": "0", "stale": "0", "lost": "0", "refused": "0"}
    assert _values(_status(array, "run")) == {
        "resets": "0",
        "pauses": "0",
        "step_calls": "0",
        "clock_origin_shift_s": "0.000000",
    }
    assert _values(_status(array, "drive")) == {
        "sim_time_s": "0.000",
        "paused": "False",
        "substeps_most": "1",
        "energy_residual_j": "0",
    }


def test_an_end_stop_is_a_note_and_cavitation_relief_and_an_overloaded_battery_are_warnings():
    resting = _sim()
    resting.reset(resting.params.cylinder_min_length_m)  # on the lower end stop
    drive = _status(_read(resting), "drive")
    assert (drive.level, drive.message) == (OK, "at_end_stop")
    weak = _sim(battery_resistance_ohm=2.0)  # U^2 / (4 R) well below what the motor asks (eq. D11)
    weak.step(1.0, 50)
    drive = _status(_read(weak), "drive")
    assert (drive.level, drive.message) == (WARN, "battery_overloaded")
    for flag in ("cavitation", "relief_open"):
        drive = _status(_read(_Flagged(_sim(), **{flag: True})), "drive")
        assert (drive.level, drive.message) == (WARN, flag)
    every = _Flagged(_sim(), at_end_stop=True, cavitation=True, relief_open=True, battery_overloaded=True)
    drive = _status(_read(every), "drive")
    assert (drive.level, drive.message) == (WARN, "cavitation, relief_open, battery_overloaded, at_end_stop")
    drive = _status(_read(_Flagged(_sim(), relief_open=True, at_end_stop=True)), "drive")
    assert (drive.level, drive.message) == (WARN, "relief_open, at_end_stop")


@pytest.mark.parametrize(
    ("soc", "level", "text"),
    [
        (1.0, OK, "ok"),
        (LOW_CHARGE, OK, "ok"),
        (math.nextafter(LOW_CHARGE, 0.0), WARN, "low"),
        (0.05, WARN, "low"),
        (math.nextafter(0.0, 1.0), WARN, "low"),
        (0.0, ERROR, "empty"),
    ],
)
def test_the_battery_warns_below_its_low_charge_and_is_an_error_when_empty(soc: float, level: int, text: str):
    battery = _status(_read(_sim(battery_initial_soc=soc)), "battery")
    assert (battery.level, battery.message) == (level, text)
    assert _values(battery)["state_of_charge"] == f"{soc:.4f}"


def test_a_battery_drawn_below_empty_is_empty():
    sim = _sim(battery_initial_soc=0.0)
    sim.step(1.0, 20)
    battery = _status(_read(sim), "battery")
    assert (battery.level, battery.message) == (ERROR, "empty")
    assert float(_values(battery)["state_of_charge"]) <= 0.0


def test_paper_mode_has_no_battery_status():
    sim = _sim(mode="paper")
    sim.step(0.5, 10)
    names = [s.name for s in _read(sim).status]
    assert names == ["boom_sim: drive", "boom_sim: real-time", "boom_sim: commands", "boom_sim: run"]
    assert _values(_status(_read(sim), "drive"))["energy_residual_j"] == "0"


def test_a_failure_replaces_the_drive_and_the_battery():
    array = _read(_sim(), "the rod left the stroke", commands=CommandCounts(received=1))
    assert [s.name for s in array.status] == [
        "boom_sim: simulation",
        "boom_sim: real-time",
        "boom_sim: commands",
        "boom_sim: run",
    ]
    failed = array.status[0]
    assert (failed.level, failed.message, list(failed.values)) == (ERROR, "stopped: the rod left the stroke", [])
    assert _values(array.status[2])["received"] == "1"


def test_real_time_is_behind_only_past_two_ticks_of_lag():
    at_limit = 2.0 / RATE_HZ
    status = _status(_read(_sim(), pacer=_Pacer(lag_s=at_limit)), "real-time")
    assert (status.level, status.message) == (OK, "ok")
    assert _values(status)["lag_s"] == "0.0400"
    status = _status(_read(_sim(), pacer=_Pacer(lag_s=math.nextafter(at_limit, 1.0))), "real-time")
    assert (status.level, status.message) == (WARN, "cannot keep up")
    status = _status(_read(_sim(), pacer=_Pacer(lag_s=0.5), rate_hz=1.0), "real-time")  # 2 s allowed at 1 Hz
    assert (status.level, status.message) == (OK, "ok")


def test_dropped_backlogs_warn_once_and_reading_them_resets_their_count():
    sim, pacer = _sim(), _Pacer(late_ticks=3, clock_error_s=0.25)
    status = _status(_read(sim, pacer=pacer), "real-time")
    assert (status.level, status.message) == (WARN, "cannot keep up")
    assert _values(status)["dropped_backlogs"] == "3"
    assert _values(status)["clock_error_s"] == "0.250000"
    assert pacer.late_ticks == 0
    status = _status(_read(sim, pacer=pacer), "real-time")
    assert (status.level, status.message, _values(status)["dropped_backlogs"]) == (OK, "ok", "0")


@pytest.mark.parametrize("why", ["stale", "lost", "refused"])
def test_any_command_not_applied_warns(why: str):
    commands = CommandCounts(received=9, **{why: 4})
    status = _status(_read(_sim(), commands=commands), "commands")
    assert (status.level, status.message) == (WARN, "some commands were not applied")
    expected = {"received": "9", "stale": "0", "lost": "0", "refused": "0"}
    assert _values(status) == {**expected, why: "4"}


@pytest.mark.parametrize("counts", [{"stale": 2, "lost": 2}, {"lost": 3, "refused": 3}, {"stale": 1, "refused": 1}])
def test_commands_not_applied_for_different_reasons_add_up(counts: dict[str, int]):
    status = _status(_read(_sim(), commands=CommandCounts(received=10, **counts)), "commands")
    assert (status.level, status.message) == (WARN, "some commands were not applied")


def test_the_recording_status_is_there_only_while_recording_and_an_error_stops_it():
    sim = _sim()
    assert "boom_sim: recording" not in _statuses(_read(sim))
    array = _read(sim, recording=(None, "/tmp/bags/run_1"))
    status = array.status[-1]
    assert (status.name, status.level, status.message) == ("boom_sim: recording", OK, "ok")
    assert _values(status) == {"folder": "/tmp/bags/run_1"}
    status = _read(sim, recording=("No space left on device", "/tmp/bags/run_1")).status[-1]
    assert (status.name, status.level, status.message) == (
        "boom_sim: recording",
        ERROR,
        "stopped: No space left on device",
    )
    assert list(status.values) == []
    failed = _read(sim, "diverged", recording=(None, "/tmp/bags/run_1"))
    assert [s.name for s in failed.status][-1] == "boom_sim: recording"
