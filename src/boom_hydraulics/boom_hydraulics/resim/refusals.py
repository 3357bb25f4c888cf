"""The recorded runs a re-simulation refuses: those whose time line is not one continuous
line from the run's origin (a reset; on ROS-time stamps also a pause, a resume or a step),
found in the recorded service calls, the node's diagnostics or the drive states."""

from __future__ import annotations

from pathlib import Path

from ..bags import continuity
from ..bags.run_description import RunDescription
from ..errors import ConfigError
from .recorded import RecordedRun

_WHY = "a re-simulation replays the commands on one continuous time line from the run's origin"


def check_calls(bag: Path, description: RunDescription) -> None:
    """Raise ConfigError, saying why, if the node recorded calls of its services that broke the
    run's time line: a reset jumps the state; on ROS-time stamps (a node without publish_clock)
    a pause, resume or step also moved the node's time origin. With publish_clock the stamps
    are simulated time itself, which pauses and steps do not break: those runs are re-simulated.
    Read before the rest of the bag, from its run description and the events alone."""
    origin_ns = description.clock_origin_ns
    sim_time = origin_ns == 0  # publish_clock: simulated time 0 is stamp 0
    calls = continuity.recorded_calls(bag, description.node, origin_ns)
    breaking = ("reset",) if sim_time else tuple(continuity.SERVICES)
    found = continuity.Calls({s: n for s, n in calls.counts.items() if s in breaking}, calls.first_s)
    if found.total():
        fix = "Record the run without resets" + (
            "" if sim_time else ", pauses or steps, or with publish_clock:=true, whose time line pauses and steps keep"
        )
        what = f"the run was {continuity.describe(found)}"
        raise ConfigError(f"{bag}: {what}; {_WHY}, so it cannot reproduce this run. {fix}")


def check_counts(bag: Path, run: RecordedRun) -> None:
    """Raise ConfigError if the node's own diagnostics count resets, or, on ROS-time stamps,
    pauses, steps or a moved time origin (a resume, a dropped backlog)."""
    counts = run.run_counts
    sim_time = run.clock_origin_ns == 0
    found = continuity.Calls()
    found.counts = {"reset": int(counts.get("resets", 0))}
    if not sim_time:
        found.counts.update(pause=int(counts.get("pauses", 0)), step=int(counts.get("step_calls", 0)))
    if found.total():
        what = f"the node counted {continuity.describe(found, with_times=False)} in its diagnostics"
        raise ConfigError(f"{bag}: {what}; {_WHY}, so it cannot reproduce this run. Record the run without them")
    shift_s = counts.get("clock_origin_shift_s", 0.0)
    if not sim_time and abs(shift_s) > 0.5e-6:
        raise ConfigError(
            f"{bag}: the node's time origin moved by {shift_s:.6f} s during the run (it was resumed, or fell behind "
            f"real time and dropped the backlog); {_WHY}, so it cannot reproduce this run. Record it with "
            "publish_clock:=true, whose stamps are simulated time"
        )


def check_states(bag: Path, run: RecordedRun) -> None:
    """Raise ConfigError if the recorded drive states show a reset (for bags from before the
    node recorded its service calls, and for a reset by a ROS clock that jumped back)."""
    check_counts(bag, run)
    if not run.state_ns:
        return
    k = continuity.reset_from_states(run.state_ns, *run.state_signals)
    if k is not None:
        t = (run.state_ns[k] - run.clock_origin_ns) * 1e-9
        raise ConfigError(
            f"{bag}: the run appears to have been reset at t = {t:.3f} s (the energy dissipated in its valve, "
            f"counted since start or reset, dropped, or the rod jumped further than it can move); {_WHY}, so it "
            "cannot reproduce this run. Record the run without resets"
        )
