"""Work cycles: the named duty cycles of the scenarios (``--scenario``), nominal or varied.

A duty cycle is a closed-loop scenario (the ``angle`` profile: moves to boom angles at given
times, docs/model.md "Position control") with, where the payload changes within it, a
payload schedule (``command_payload_times_s`` and ``command_payload_fractions``: from each
time on, that share of ``payload_mass_kg`` hangs on the hook). Its angles are measured from
the boom's elevation at rest at ``initial_length_m`` (the ground), so that the cycle ends
where it began and its battery energy is the energy of one cycle.

- ``loader``: a loader crane's work cycle. Lift the payload from the ground by
  :data:`LOADER_RISE_DEG`, hold, lower it to the ground, release it, lift empty, lower empty.
  Its phases start at :data:`LOADER_TIMES_S`; the cycle takes :data:`LOADER_DURATION_S`.

Operator variation: ``loader:SEED`` (SEED >= 1) draws each phase's length within
:data:`VARIATION` and each lift's height within :data:`RISE_VARIATION` of the nominal
(uniform) from a seeded generator, so that N seeds give N cycles of one distribution
(``boom-sweep --operators N``). Seed 0 is the nominal cycle.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..errors import ConfigError
from ..model.geometry import boom_angle_rad
from ..model.parameters import Parameters

#: The work cycles by name (``--scenario`` / ``--profile NAME`` or ``NAME:SEED``).
CYCLES = ("loader",)
#: How far each lift raises the boom above the ground, degrees.
LOADER_RISE_DEG = 25.0
#: When each phase of the loader cycle starts, s: lift loaded, lower loaded, release the
#: payload, lift empty, lower empty; and when the cycle ends.
LOADER_TIMES_S = (0.0, 4.5, 9.0, 9.5, 14.0)
LOADER_DURATION_S = 18.5
#: Operator variation: a phase's length lies within this fraction of the nominal ...
VARIATION = 0.2
#: ... and a lift's height within this one (so that it still rises through a sweep's 20 degrees).
RISE_VARIATION = 0.1


def ground_rad(p: Parameters) -> float:
    """The boom's elevation at rest at ``initial_length_m``: where a cycle starts and ends, rad."""
    return float(boom_angle_rad(p.initial_length_m, p.a_m, p.b_m, p.support_height_m))


def _phases(seed: int) -> tuple[np.ndarray, np.ndarray]:
    """(each phase's length s, each lift's rise rad) of the loader cycle of ``seed``."""
    if seed < 0:
        raise ConfigError(f"scenario loader:{seed}: the operator's seed must be >= 0")
    lengths = np.diff([*LOADER_TIMES_S, LOADER_DURATION_S])
    rises = np.full(2, math.radians(LOADER_RISE_DEG))
    if seed > 0:
        rng = np.random.default_rng(seed)
        lengths = lengths * rng.uniform(1.0 - VARIATION, 1.0 + VARIATION, len(lengths))
        rises = rises * rng.uniform(1.0 - RISE_VARIATION, 1.0 + RISE_VARIATION, len(rises))
    return lengths, rises


def loader(p: Parameters, seed: int = 0) -> dict[str, Any]:
    """The command_* parameters of the loader cycle for the boom of ``p`` (seed 0: nominal;
    otherwise varied by the operator, see the module)."""
    lengths, rises = _phases(seed)
    lift, lower, release, lift_empty, lower_empty = np.concatenate([[0.0], np.cumsum(lengths)[:-1]])
    ground = ground_rad(p)
    return {
        "command_profile": "angle",
        "command_times_s": [float(t) for t in (lift, lower, lift_empty, lower_empty)],
        "command_angles_rad": [float(a) for a in (ground + rises[0], ground, ground + rises[1], ground)],
        "command_payload_times_s": [float(release)],
        "command_payload_fractions": [0.0],
    }


def loader_duration_s(seed: int = 0) -> float:
    """How long the loader cycle of ``seed`` takes, s."""
    return float(np.sum(_phases(seed)[0]))
