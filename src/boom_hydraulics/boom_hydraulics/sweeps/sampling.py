"""The points of a design sweep: axes over parameters and how they are sampled.

An axis is written ``NAME=SPEC`` (the ``--vary`` option of ``boom-sweep``):

- ``piston_diameter_m=0.032:0.1:15``: 15 evenly spaced values from 0.032 to 0.1;
- ``bulk_modulus_pa=1e8:2e9:5:log``: 5 values evenly spaced in the logarithm;
- ``payload_mass_kg=0,100,200``: a list of values (numbers, or words such as ``rk4``);
- ``payload_mass_kg=0:200``: a range, for random and Latin-hypercube samples.

NAME is a parameter name or an unambiguous beginning of one (``payload`` means
``payload_mass_kg``). The axes are combined by one of :data:`SAMPLES`.
"""

from __future__ import annotations

import difflib
import itertools
import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import ConfigError
from ..model.parameters import NAMES, describe

#: grid: every combination; list: the i-th values of all axes together; random: uniform
#: in each range; lhs: Latin hypercube (each range cut into N strata, each used once).
SAMPLES = ("grid", "list", "random", "lhs")


@dataclass(frozen=True)
class Spacing(Sequence):
    """``count`` values evenly spaced from ``low`` to ``high`` (in the logarithm with ``log``), computed
    only when read: a sweep says how many points an axis gives, and refuses too many, before it holds them."""

    low: float
    high: float
    count: int
    log: bool = False

    def _array(self) -> np.ndarray:
        return (
            np.geomspace(self.low, self.high, self.count) if self.log else np.linspace(self.low, self.high, self.count)
        )

    def __len__(self) -> int:
        return self.count

    def __iter__(self) -> Iterator[float]:
        return iter(self._array().tolist())

    def __getitem__(self, index):  # type: ignore[override]
        return tuple(self)[index]

    def __eq__(self, other: object) -> bool:
        if isinstance(other, (Spacing, tuple, list)):
            return len(self) == len(other) and tuple(self) == tuple(other)
        return NotImplemented

    def __hash__(self) -> int:
        return hash((self.low, self.high, self.count, self.log))


@dataclass(frozen=True)
class Axis:
    """One varied parameter: explicit ``values``, or a range ``low``..``high`` (``log``: in the logarithm)."""

    name: str
    values: Sequence[Any] | None = None
    low: float | None = None
    high: float | None = None
    log: bool = False

    @property
    def is_range(self) -> bool:
        return self.values is None

    def as_request(self) -> dict[str, Any]:
        """The axis as a sweep's stored request keeps it (JSON: the values listed)."""
        values = None if self.values is None else list(self.values)
        return {"name": self.name, "values": values, "low": self.low, "high": self.high, "log": self.log}


def resolve_name(text: str) -> str:
    """The parameter that ``text`` names: itself, or the one parameter it is the beginning of."""
    if text in NAMES:
        return text
    matches = [n for n in NAMES if n.startswith(text)]
    if len(matches) == 1:
        return matches[0]
    if len(matches) > 1:
        raise ConfigError(f"'{text}' could mean {', '.join(matches)}; write the full parameter name")
    close = difflib.get_close_matches(text, NAMES, n=3)
    hint = f"; did you mean {', '.join(close)}?" if close else ""
    raise ConfigError(f"unknown parameter '{text}'{hint} (boom_sim --help lists them)")


def _number(text: str, where: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise ConfigError(f"{where}: '{text}' is not a number") from None
    if not math.isfinite(value):
        raise ConfigError(f"{where}: '{text}' is not a finite number")
    return value


def _value(text: str, kind: str, where: str) -> Any:
    if kind == "str":
        return text
    if kind == "list":
        raise ConfigError(f"{where}: list parameters cannot be varied")
    return _number(text, where)


def parse_axis(spec: str) -> Axis:
    """An :class:`Axis` from ``NAME=SPEC`` (see the module docstring)."""
    name_text, sep, rest = spec.partition("=")
    if not sep or not name_text.strip() or not rest.strip():
        raise ConfigError(f"--vary '{spec}': write NAME=START:STOP:COUNT, NAME=V1,V2,... or NAME=LOW:HIGH")
    name = resolve_name(name_text.strip())
    kind = describe(name)["type"]
    where = f"--vary '{spec}'"
    rest = rest.strip()
    if ":" not in rest:
        values = tuple(_value(v.strip(), kind, where) for v in rest.split(","))
        return Axis(name, values=values)
    if kind not in ("float", "int"):
        raise ConfigError(f"{where}: '{name}' is not numeric; list its values with commas")
    parts = rest.split(":")
    log = parts[-1] == "log"
    if log:
        parts = parts[:-1]
    if len(parts) not in (2, 3):
        raise ConfigError(f"{where}: a range is START:STOP:COUNT or LOW:HIGH, optionally ending in :log")
    low, high = _number(parts[0], where), _number(parts[1], where)
    if log and (low <= 0 or high <= 0):
        raise ConfigError(f"{where}: a log range needs positive ends")
    if len(parts) == 2:
        if not low < high:
            raise ConfigError(f"{where}: LOW must be below HIGH")
        return Axis(name, low=low, high=high, log=log)
    count = _number(parts[2], where)
    if count < 1 or not count.is_integer():
        raise ConfigError(f"{where}: COUNT must be a whole number >= 1, got {parts[2]}")
    return Axis(name, values=Spacing(low, high, int(count), log))


def _need_lists(axes: Sequence[Axis], sample: str) -> None:
    for axis in axes:
        if axis.is_range:
            raise ConfigError(
                f"--vary {axis.name}={axis.low:g}:{axis.high:g} is a range without a count; "
                f"the {sample} sample needs values (START:STOP:COUNT or V1,V2,...), or use --sample random/lhs"
            )


def _need_ranges(axes: Sequence[Axis], sample: str) -> None:
    for axis in axes:
        if not axis.is_range:
            raise ConfigError(f"--vary {axis.name}: the {sample} sample draws from ranges; write {axis.name}=LOW:HIGH")


def _scale(axis: Axis, unit: np.ndarray) -> np.ndarray:
    """Map numbers in [0, 1) onto the axis range."""
    assert axis.low is not None and axis.high is not None
    if axis.log:
        return np.exp(np.log(axis.low) + unit * (np.log(axis.high) - np.log(axis.low)))
    return axis.low + unit * (axis.high - axis.low)


def point_count(axes: Sequence[Axis], sample: str = "grid", count: int = 0) -> int:
    """How many points :func:`sample_points` gives, found without computing them.

    Raises ConfigError where the axes do not fit the sample, as :func:`sample_points` would.
    """
    _check_sample(axes, sample)
    if not axes:
        return 1
    if sample == "grid":
        _need_lists(axes, sample)
        return math.prod(len(a.values) for a in axes)
    if sample == "list":
        _need_lists(axes, sample)
        lengths = {a.name: len(a.values) for a in axes}
        if len(set(lengths.values())) > 1:
            raise ConfigError(f"--sample list pairs the i-th values of every axis; their lengths differ: {lengths}")
        return len(axes[0].values)
    _need_ranges(axes, sample)
    if count < 1:
        raise ConfigError(f"--sample {sample} needs --samples N (N >= 1), got {count}")
    return count


def _check_sample(axes: Sequence[Axis], sample: str) -> None:
    names = [a.name for a in axes]
    if len(set(names)) != len(names):
        raise ConfigError(f"a parameter is varied twice: {', '.join(names)}")
    if sample not in SAMPLES:
        raise ConfigError(f"unknown sample '{sample}'; choose one of {', '.join(SAMPLES)}")


def sample_points(axes: Sequence[Axis], sample: str = "grid", count: int = 0, seed: int = 0) -> list[dict[str, Any]]:
    """The points (one ``{name: value}`` per point) that ``axes`` span under ``sample``.

    ``count`` is the number of points of a random or Latin-hypercube sample; ``seed``
    makes them reproducible.
    """
    point_count(axes, sample, count)  # checks the axes against the sample
    names = [a.name for a in axes]
    if not axes:
        return [{}]
    if sample == "grid":
        return [dict(zip(names, combo)) for combo in itertools.product(*(a.values for a in axes))]
    if sample == "list":
        return [dict(zip(names, combo)) for combo in zip(*(a.values for a in axes))]
    if seed < 0:
        raise ConfigError(f"--seed must be a whole number >= 0, got {seed}")
    rng = np.random.default_rng(seed)
    if sample == "random":
        unit = rng.random((count, len(axes)))
    else:  # Latin hypercube: one point in each of the count strata of every axis
        strata = np.column_stack([rng.permutation(count) for _ in axes])
        unit = (strata + rng.random((count, len(axes)))) / count
    columns = [_scale(axis, unit[:, k]) for k, axis in enumerate(axes)]
    return [{name: float(col[i]) for name, col in zip(names, columns)} for i in range(count)]
