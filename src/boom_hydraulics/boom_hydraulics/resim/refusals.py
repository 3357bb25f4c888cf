"""The recorded runs a re-simulation refuses.

A bag that holds its node's run events (its description names their topic,
bags.run_events) is re-simulated whatever the node did to its time line (resets, pauses,
steps, dropped backlogs): it is refused only where it is not whole, where the node's own
counts in its diagnostics name more events than the bag holds, or an event comes after
states the bag does not have. A bag recorded before the node recorded its events is refused
where its time line is not one continuous line from the run's origin (a reset; on ROS-time
stamps also a pause, a resume, a step or a dropped backlog), found in the recorded service
calls, the node's diagnostics or the drive states."""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ..analysis.noise import noise_level
from ..bags import continuity
from ..bags.run_description import RunDescription
from ..errors import ConfigError
from .recorded import RecordedRun

_WHY = "a re-simulation replays the commands on one continuous time line from the run's origin"

#: A jump is this many times the noise of a difference of two samples, at least.
JUMP_SIGMAS = 10.0


def check_calls(bag: Path, description: RunDescription) -> None:
    """Raise ConfigError, saying why, if the node recorded calls of its services that broke the
    run's time line: a reset jumps the state; on ROS-time stamps (a node without publish_clock)
    a pause, resume or step also moved the node's time origin. With publish_clock the stamps
    are simulated time itself, which pauses and steps do not break: those runs are re-simulated.
    Read before the rest of the bag, from its run description and the events alone. Nothing
    to refuse in a bag that holds the node's run events (those calls are among them)."""
    if description.events_topic is not None:
        return
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
    pauses, steps or a moved time origin (a resume, a dropped backlog); in a bag with the
    node's run events, if those counts name more events than the bag holds (:func:`check_whole`)."""
    if run.has_events:
        check_whole(bag, run)
        check_stamps(bag, run)
        return
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
    node recorded its service calls, and for a reset by a ROS clock that jumped back); in a bag
    with the node's run events, whether it is whole (:func:`check_whole`)."""
    check_counts(bag, run)
    if not run.state_ns or run.has_events:
        return
    found = break_in_states(run.state_ns, run.state_log_ns, *run.state_signals)
    if found is not None:
        k, what = found
        t = (run.state_ns[k] - run.clock_origin_ns) * 1e-9
        raise ConfigError(
            f"{bag}: the run appears to have been reset at t = {t:.3f} s ({what}); {_WHY}, so it cannot reproduce "
            "this run. Record the run without resets"
        )


def break_in_states(
    stamps_ns: Sequence[int],
    log_ns: Sequence[int],
    q1: Sequence[float],
    v: Sequence[float],
    a: Sequence[float],
    energy: Sequence[float],
) -> tuple[int, str] | None:
    """(index, what) of the first drive state (in stamp order) that shows a reset or a clock
    that jumped back, or None. Told from sensor noise by what each is (a machine's bag is noisy):

    - the rod jumped: it moved between two states further than their speeds and accelerations
      allow, by more than 1 mm and more than JUMP_SIGMAS times the noise of such a difference
      (estimated from the recorded positions themselves, analysis.noise.noise_level): 1 mm of
      sensor noise (1.4 mm on a difference) needs a jump of 14 mm, which Gaussian noise does
      not make in any run (a reset puts the rod back at its initial length, centimetres away);
    - the valve's dissipated energy, counted from the start or the last reset and never falling
      between, fell by more than 1 mJ and JUMP_SIGMAS times its own noise;
    - the stamps went back: a state logged later carries an earlier stamp (a ROS clock that
      jumped back).
    """
    q1, v, a, energy = (np.asarray(x, dtype=float) for x in (q1, v, a, energy))
    if len(q1) < 2:
        return None
    logged = np.asarray(log_ns, dtype=np.int64)
    stamps = np.asarray(stamps_ns, dtype=np.int64) - int(stamps_ns[0])
    back = np.nonzero(np.diff(logged) < 0)[0]
    found: list[tuple[int, str]] = []
    if len(back):
        found.append((int(back[0]) + 1, "a state logged later carries an earlier stamp: the clock jumped back"))
    dt = np.diff(np.asarray(stamps_ns, dtype=np.int64)).astype(float) * 1e-9
    speed = np.maximum(np.abs(v[:-1]), np.abs(v[1:]))
    acc = np.maximum(np.abs(a[:-1]), np.abs(a[1:]))
    reach = 2.0 * (speed * dt + acc * dt * dt)
    slack = max(continuity.POSITION_SLACK_M, JUMP_SIGMAS * math.sqrt(2.0) * noise_level(q1, stamps))
    jump = np.nonzero(np.abs(np.diff(q1)) > reach + slack)[0]
    if len(jump):
        found.append((int(jump[0]) + 1, f"the rod jumped further than it can move (by more than {slack * 1e3:.3g} mm)"))
    drop_least = max(continuity.ENERGY_DROP_J, JUMP_SIGMAS * math.sqrt(2.0) * noise_level(energy, stamps))
    drop = np.nonzero(energy[:-1] - energy[1:] > drop_least)[0]
    if len(drop):
        found.append((int(drop[0]) + 1, "the energy dissipated in its valve, counted since start or reset, dropped"))
    return min(found) if found else None


#: The node's diagnostics count -> the run event it counts (and how a count reads).
_COUNTED = {"resets": ("reset", "resets"), "pauses": ("pause", "pauses"), "step_calls": ("step", "~/step calls")}


def check_whole(bag: Path, run: RecordedRun) -> None:
    """Raise ConfigError if a bag with the node's run events lacks some of them: its
    diagnostics (the latest the bag holds) count more resets, pauses or steps, or a larger
    move of the time origin by dropped backlogs, than its events, or an event comes after
    drive states the bag does not hold (it was cut)."""
    counts, events = run.run_counts, run.events
    for key, (kind, what) in _COUNTED.items():
        held = sum(1 for e in events if e.event == kind)
        if int(counts.get(key, 0)) > held:
            raise ConfigError(
                f"{bag}: the node's diagnostics count {int(counts[key])} {what} and the bag holds {held} of "
                f"them on {run.description.events_topic}; the bag is not whole, so a re-simulation cannot "
                "reproduce its run"
            )
    dropped_s = sum(e.dropped_s for e in events if e.event == "backlog_dropped")
    if counts.get("clock_origin_shift_s", 0.0) > dropped_s + 1e-6:  # (counted to 1e-6 s)
        raise ConfigError(
            f"{bag}: the node's diagnostics count {counts['clock_origin_shift_s']:.6f} s of dropped backlog and "
            f"the bag's events {dropped_s:.6f} s; the bag is not whole, so a re-simulation cannot reproduce its run"
        )
    beyond = [e for e in events if e.states_before > len(run.state_ns)]
    if beyond and run.state_ns:
        raise ConfigError(
            f"{bag}: a run event ({beyond[0].event} at t = {beyond[0].sim_time_s:.3f} s) comes after "
            f"{beyond[0].states_before} drive states and the bag holds {len(run.state_ns)}; the bag is not whole, "
            "so a re-simulation cannot reproduce its run"
        )


def check_stamps(bag: Path, run: RecordedRun) -> None:
    """Raise ConfigError for a run on the node's own clock (no publish_clock) at a real-time
    factor other than 1 at any time: there a state is stamped with the time it was published,
    not with its simulated instant, which a re-simulation then cannot know."""
    description = run.description
    if description.clock != "system":
        return
    factors = [description.real_time_factor or 1.0] + [e.real_time_factor for e in run.events if e.event == "pace"]
    other = next((f for f in factors if f != 1.0), None)
    if other is not None:
        raise ConfigError(
            f"{bag}: the node ran at real_time_factor {other:g} on its own clock, where it stamps a state with the "
            "time it was published, not with its simulated instant, so a re-simulation cannot place its states. "
            "Record such runs with publish_clock:=true, whose stamps are simulated time"
        )
