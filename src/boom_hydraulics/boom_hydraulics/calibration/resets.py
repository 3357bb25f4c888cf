"""The recorded runs a calibration refuses because their time line broke (a reset, a clock
that jumped back), told from sensor noise by what they are.

A calibration re-simulates the recorded commands as boom-resim does, and refuses what
boom-resim refuses (resim.refusals): a bag that holds the node's run events is re-simulated
through its resets, pauses and steps, and refused only where it is not whole; a bag recorded
before the node recorded its events, where its time line breaks: the node's recorded
``~/reset`` (and, on ROS-time stamps, ``~/pause`` and ``~/step``) calls, the counts in its
diagnostics, or the drive states themselves; here they are read as a machine's noisy signals
may be:

- the rod jumped: it moved between two states further than their speeds and accelerations
  allow, by more than 1 mm and more than ``JUMP_SIGMAS`` times the noise of such a difference
  (estimated from the recorded positions themselves, :func:`.noise.noise_level`): 1 mm of
  sensor noise (1.4 mm on a difference) needs a jump of 14 mm, which Gaussian noise does not
  make in any run (a reset puts the rod back at its initial length, centimetres away);
- the valve's dissipated energy, counted from the start or the last reset and never falling
  between, fell by more than 1 mJ and ``JUMP_SIGMAS`` times its own noise;
- the stamps went back: a state logged later carries an earlier stamp (a ROS clock that
  jumped back).
"""

from __future__ import annotations

import math
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..bags.continuity import ENERGY_DROP_J, POSITION_SLACK_M
from ..bags.reading import read_run_description
from ..bags.run_description import RunDescription
from ..errors import ConfigError
from ..model import config
from ..model.parameters import NAMES
from ..resim.recorded import RecordedRun, read_run
from ..resim.refusals import check_calls, check_counts
from .noise import noise_level

#: A jump is this many times the noise of a difference of two samples, at least.
JUMP_SIGMAS = 10.0
_WHY = "a calibration re-simulates the commands on one continuous time line from the run's origin"


def break_in_states(
    stamps_ns: Sequence[int],
    log_ns: Sequence[int],
    q1: Sequence[float],
    v: Sequence[float],
    a: Sequence[float],
    energy: Sequence[float],
) -> tuple[int, str] | None:
    """(index, what) of the first drive state (in stamp order) that shows a reset or a clock
    that jumped back, or None (see the module docstring)."""
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
    slack = max(POSITION_SLACK_M, JUMP_SIGMAS * math.sqrt(2.0) * noise_level(q1, stamps))
    jump = np.nonzero(np.abs(np.diff(q1)) > reach + slack)[0]
    if len(jump):
        found.append((int(jump[0]) + 1, f"the rod jumped further than it can move (by more than {slack * 1e3:.3g} mm)"))
    drop_least = max(ENERGY_DROP_J, JUMP_SIGMAS * math.sqrt(2.0) * noise_level(energy, stamps))
    drop = np.nonzero(energy[:-1] - energy[1:] > drop_least)[0]
    if len(drop):
        found.append((int(drop[0]) + 1, "the energy dissipated in its valve, counted since start or reset, dropped"))
    return min(found) if found else None


def check_states(bag: Path, run: RecordedRun) -> None:
    """ConfigError if the node's diagnostics count a reset (resim.refusals.check_counts) or its
    drive states show one (:func:`break_in_states`); in a bag with the node's run events, if it
    is not whole (check_counts: its resets are re-simulated)."""
    check_counts(bag, run)
    if not run.state_ns or run.has_events:
        return
    found = break_in_states(run.state_ns, run.state_log_ns, *run.state_signals)
    if found is not None:
        k, what = found
        t = (run.state_ns[k] - run.clock_origin_ns) * 1e-9
        raise ConfigError(
            f"{bag}: the run appears to have been reset at t = {t:.3f} s ({what}); {_WHY}, so it cannot "
            "reproduce this run. Calibrate on a bag recorded without resets"
        )


def read_recorded(
    bag: Path, config_file: Path | None, prog: str, description: RunDescription | None = None
) -> tuple[RecordedRun, dict[str, Any]]:
    """The recorded run of ``bag`` and the parameter values to simulate it with (the bag's own or
    ``config_file``'s), as resim.resimulation.read_recorded reads them, with the drive states'
    reset check of :func:`check_states`. ``description`` stands in for a bag without one."""
    description = description or read_run_description(bag)
    check_calls(bag, description)
    run = read_run(bag, description)
    check_states(bag, run)
    values = dict(run.parameters) if config_file is None else config.read_values(config_file)
    retired = sorted(name for name in values if name not in NAMES) if config_file is None else []
    if retired:  # recorded by an earlier version of the model: what it no longer has cannot apply
        print(
            f"{prog}: note: {bag} holds parameters this version no longer has ({', '.join(retired)}); "
            "they are left out, and the model's defaults stand in for what replaced them",
            file=sys.stderr,
        )
        values = {name: value for name, value in values.items() if name in NAMES}
    return run, values
