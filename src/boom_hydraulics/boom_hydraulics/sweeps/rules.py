"""What a design has to do to be recommended: the rules every sweep applies, beside the
constraints a user adds (``--require``), and where the best design lies in the searched range.

A point qualifies when its status is ok (it lifted through ``--lift-angle-deg`` and its run
did not fail) and:

- every target of its closed-loop scenario (an ``angle:`` move or a work cycle such as
  ``loader``) is within ``target_tolerance_deg`` of the boom angle at its phase's end (the
  next target's time; the last target's phase ends with the run): ``worst_target_error_deg``;
- with ``settle_time_s``, every target is reached (within 2 % of its step, see
  solve.streaming) and held from at most that long after its phase's start:
  ``worst_settle_time_s``;
- the payload is put down within ``set_down_tolerance_deg`` of the ground (the target in
  effect when it is released): ``|set_down_error_deg|``;
- with ``max_pressure_pa``, no chamber pressure above it: ``peak_pressure_pa``;
- no port relief valve opened (``relief_s`` == 0) unless ``allow_relief``.

The rules but the pressure's apply to closed-loop runs alone (an open-loop scenario, which
slams the valve shut by itself, has no targets: NaN metrics), the set-down rule to those
that release a payload. With ``--across`` a design qualifies only if every one of its points does
(recommend.recommend): across operators, every operator's cycle.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError
from ..model.parameters import describe
from .recommend import Constraint, format_value

#: How close to its target a work cycle's boom has to be at each phase's end, degrees: a
#: loader crane's operator places the load by eye to about a degree of boom (10-15 cm at the
#: tip of a 6-8 m boom, the accuracy a payload is set down with).
TARGET_TOLERANCE_DEG = 1.0

#: The column that says a run has targets (NaN: open loop), where the rules of a closed-loop run apply.
TARGETS = "worst_target_error_deg"


@dataclass(frozen=True)
class Rules:
    """The rules' settings (``boom-sweep``'s options of the same names)."""

    target_tolerance_deg: float = TARGET_TOLERANCE_DEG
    set_down_tolerance_deg: float | None = None  # None: the target tolerance
    settle_time_s: float | None = None  # None: no rule on the settling time
    max_pressure_pa: float | None = None  # None: no rule on the peak pressure
    allow_relief: bool = False

    def __post_init__(self) -> None:
        for name in ("target_tolerance_deg", "set_down_tolerance_deg", "settle_time_s", "max_pressure_pa"):
            value = getattr(self, name)
            if value is not None and not (math.isfinite(value) and value > 0):
                raise ConfigError(f"--{name.replace('_', '-')} must be a positive number, got {value}")

    def constraints(self) -> list[Constraint]:
        """The rules as constraints over the sweep table, each saying what a failing point did."""
        tolerance = self.target_tolerance_deg
        set_down = tolerance if self.set_down_tolerance_deg is None else self.set_down_tolerance_deg
        found = [
            Constraint(
                "worst_target_error_deg", "<=", tolerance,
                f"a target missed by more than {tolerance:g} deg at its phase's end", only_where=TARGETS,
            ),
            Constraint(
                "set_down_error_deg", "<=", set_down,
                f"the payload put down more than {set_down:g} deg from the ground", magnitude=True,
                only_where="set_down_error_deg",
            ),
        ]  # fmt: skip
        if self.settle_time_s is not None:
            found.append(
                Constraint(
                    "worst_settle_time_s", "<=", self.settle_time_s,
                    f"a target not reached and held within {self.settle_time_s:g} s of its phase's start",
                    only_where=TARGETS,
                )
            )  # fmt: skip
        if self.max_pressure_pa is not None:
            found.append(
                Constraint(
                    "peak_pressure_pa", "<=", self.max_pressure_pa,
                    f"a chamber pressure above {self.max_pressure_pa / 1e6:g} MPa",
                )
            )  # fmt: skip
        if not self.allow_relief:
            found.append(Constraint("relief_s", "==", 0.0, "a port relief valve opened", only_where=TARGETS))
        return found


#: Within this share of the best's score a design inside the range is as good: the axis barely
#: matters there (a drive without a cylinder's oil, over piston diameters), and no end is named.
FLAT = 1e-3


def range_edges(
    table: Mapping[str, np.ndarray],
    axes: Sequence[str],
    row: int,
    whose: str = "best",
    score: np.ndarray | None = None,
) -> list[str]:
    """A line for each numeric column of ``axes`` where ``row`` of ``table`` lies at an end of
    the values the sweep searched (those of the column, over all rows), unless the parameter
    can go no further that way (a payload of 0 kg), or (with ``score``, what the best was chosen
    by, per row) a design that differs from it in that column alone, away from the end, scores
    within :data:`FLAT` of it: which end, and which way to extend the range. ``whose``: the
    design the line names ("best", "load_sensing's best")."""
    lines = []
    for axis in axes:
        if score is not None and _flat_along(table, axes, axis, row, np.asarray(score, dtype=float)):
            continue
        values = np.asarray(table[axis])
        if values.dtype.kind not in "fiu" or axis == "operator":
            continue
        values = values.astype(float)
        finite = values[np.isfinite(values)]
        if len(finite) == 0 or not finite.min() < finite.max():  # one value: no range
            continue
        limits = _limits(axis)
        value = float(values[row])
        for end, limit, word, way in (
            (finite.min(), limits[0], "lower", "below"),
            (finite.max(), limits[1], "upper", "above"),
        ):
            if value == end and end != limit:
                shown = format_value(float(end))
                lines.append(f"{axis}: {whose} at the {word} end {shown}; extend the range {way} {shown}")
    return lines


def _flat_along(table: Mapping[str, np.ndarray], axes: Sequence[str], axis: str, row: int, score: np.ndarray) -> bool:
    """Whether a row equal to ``row`` in every column of ``axes`` but ``axis``, at another value
    of ``axis``, scores within :data:`FLAT` of it."""
    same = np.ones(len(score), dtype=bool)
    for other in axes:
        if other != axis:
            same &= np.asarray(table[other]) == np.asarray(table[other])[row]
    values = np.asarray(table[axis])
    others = same & (values != values[row]) & np.isfinite(score)
    best = score[row]
    return bool(np.isfinite(best) and np.any(np.abs(score[others] - best) <= FLAT * abs(best)))


def _limits(name: str) -> tuple[float, float]:
    """The lowest and highest values parameter ``name`` may take (none for a column that is not a
    parameter)."""
    try:
        described = describe(name)
    except KeyError:
        return -math.inf, math.inf
    low, high = described.get("low"), described.get("high")
    return (-math.inf if low is None else float(low)), (math.inf if high is None else float(high))
