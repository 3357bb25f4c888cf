"""Choosing designs from a sweep table: constraints, the trade-off front, the ranking.

A constraint reads ``METRIC OP VALUE`` with OP one of ``<= < >= > ==``, for example
``peak_pressure_pa<=20e6`` or ``cavitation_s==0``. A design is recommended when its
status is ``ok`` (it lifted through the angle and its run did not fail) and it meets
every constraint; recommendations are ranked by the energy of the lift. A design can
also be a cylinder that has to serve several conditions (payloads, say): then every
one of its points must qualify, and its worst case counts (:func:`worst_case`).
"""

from __future__ import annotations

import math
import operator
import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError
from .sweep import METRIC_NAMES, STATUSES

#: Objectives of the trade-off front, all minimised: fast, frugal, gentle on the hoses.
TRADE_OFF = ("lift_time_s", "lift_energy_j", "peak_pressure_pa")

#: The ranking of recommended designs.
RANK_BY = "lift_energy_j"
#: What a recommendation can rank by (``--rank-by``): whether more of it is better, and its words.
RANKINGS: dict[str, tuple[bool, str]] = {
    "lift_energy_j": (False, "lift energy"),
    "battery_energy_j": (False, "battery energy"),
    "cycles_per_charge": (True, "cycles per charge"),
    "lift_time_s": (False, "lift time"),
    "peak_battery_power_w": (False, "peak battery power"),
}

_OPS: dict[str, Callable[[np.ndarray, float], np.ndarray]] = {
    "<=": operator.le,
    ">=": operator.ge,
    "==": operator.eq,
    "<": operator.lt,
    ">": operator.gt,
}
_PATTERN = re.compile(r"^\s*([A-Za-z_][A-Za-z0-9_]*)\s*(<=|>=|==|<|>)\s*(\S+)\s*$")


@dataclass(frozen=True)
class Constraint:
    """``metric op value`` over a column of the sweep table; ``magnitude``: over its absolute
    value; ``only_where``: a column that is NaN where the constraint does not apply (a work
    cycle's target in an open-loop run), which such a row passes; ``why``: what a row that
    fails it did, in words."""

    metric: str
    op: str
    value: float
    why: str = ""
    magnitude: bool = False
    only_where: str = ""

    def __str__(self) -> str:
        metric = f"|{self.metric}|" if self.magnitude else self.metric
        return f"{metric} {self.op} {self.value:g}"

    def holds(self, table: Mapping[str, np.ndarray]) -> np.ndarray:
        """Per row: the constraint holds (a value that is not finite never does), or does not
        apply (``only_where``)."""
        column = np.asarray(table[self.metric], dtype=float)
        if self.magnitude:
            column = np.abs(column)
        with np.errstate(invalid="ignore"):
            held = _OPS[self.op](column, self.value) & np.isfinite(column)
        return held | ~self.applies(table)

    def applies(self, table: Mapping[str, np.ndarray]) -> np.ndarray:
        """Per row: whether the constraint applies to it (see ``only_where``)."""
        if not self.only_where:
            return np.ones(len(table[self.metric]), dtype=bool)
        return ~np.isnan(np.asarray(table[self.only_where], dtype=float))


def parse_constraint(text: str, columns: Sequence[str] = METRIC_NAMES) -> Constraint:
    """A :class:`Constraint` from ``METRIC OP VALUE`` over one of ``columns``."""
    match = _PATTERN.match(text)
    if not match:
        raise ConfigError(f"--require {text!r}: write METRIC OP VALUE, e.g. peak_pressure_pa<=20e6")
    metric, op, value_text = match.groups()
    if metric not in columns:
        raise ConfigError(f"--require {text!r}: unknown metric '{metric}'; choose from {', '.join(columns)}")
    try:
        value = float(value_text)
    except ValueError:
        raise ConfigError(f"--require {text!r}: '{value_text}' is not a number") from None
    if math.isnan(value):
        raise ConfigError(f"--require {text!r}: the value must be a number, not NaN")
    return Constraint(metric, op, value)


def non_dominated(objectives: np.ndarray) -> np.ndarray:
    """Rows of ``objectives`` (n x k, all minimised) that no other row dominates.

    Row j dominates row i when it is no worse in every objective and better in one.
    Rows with a NaN are never on the front.

    A cull, O(n x front size) rather than O(n^2): of the rows left, the lexicographically
    smallest is on the front (a row that dominated it would sort before it); it and its equals
    join the front, and every row it dominates leaves. A row dominated by one that left
    earlier is dominated by that one's culler too, so only the front is ever compared.
    """
    objectives = np.asarray(objectives, dtype=float)
    finite = np.isfinite(objectives).all(axis=1)
    front = np.zeros(len(objectives), dtype=bool)
    index = np.nonzero(finite)[0]
    left = index[np.lexsort(objectives[index].T[::-1])] if len(index) else index
    while len(left):
        best = objectives[left[0]]
        rows = objectives[left]
        equal = (rows == best).all(axis=1)
        front[left[equal]] = True
        left = left[~(rows >= best).all(axis=1)]  # dominated by best, or equal to it (now on the front)
    return front


def trade_off_front(table: Mapping[str, np.ndarray]) -> np.ndarray:
    """Per row: an ``ok`` design on the front of :data:`TRADE_OFF`."""
    ok = np.asarray(table["status"]) == "ok"
    objectives = np.column_stack([np.asarray(table[m], dtype=float) for m in TRADE_OFF])
    objectives[~ok] = np.nan
    return non_dominated(objectives)


#: Metrics where a smaller value is the worse one; for every other metric a larger value is.
LOWER_IS_WORSE = frozenset(
    {
        "lift_completed",
        "rise_deg",
        "lift_m",
        "damping_ratio",
        "min_pressure_pa",
        "natural_frequency_hz",
        "linear_damping_ratio",
        "cycles_per_charge",
        "efficiency",
        "battery_returned_j",
        "lift_work_j",
    }
)


def designs_of(table: Mapping[str, np.ndarray], design_columns: Sequence[str]) -> dict[tuple, list[int]]:
    """The rows of each design (a distinct combination of ``design_columns``), in the order the
    designs first appear."""
    keys = list(zip(*(np.asarray(table[c]).tolist() for c in design_columns))) or [()] * len(table["status"])
    groups: dict[tuple, list[int]] = {}
    for i, key in enumerate(keys):
        groups.setdefault(key, []).append(i)
    return groups


def worst_case(table: Mapping[str, np.ndarray], design_columns: Sequence[str]) -> dict[str, np.ndarray]:
    """One row per design (a distinct combination of ``design_columns``): over all its points,
    the worst value of every metric, the worst status, and ``points``, how many it has.

    The other point columns (a payload, say) are the conditions a design has to cope with.
    A NaN (a lift that did not complete) is the worst value of all.
    """
    groups = designs_of(table, design_columns)
    designs = list(groups)
    members = [np.array(rows) for rows in groups.values()]
    out: dict[str, np.ndarray] = {"design": np.arange(len(designs))}
    for j, column in enumerate(design_columns):
        out[column] = np.array([d[j] for d in designs], dtype=np.asarray(table[column]).dtype)
    out["points"] = np.array([len(m) for m in members])
    rank = {s: k for k, s in enumerate(STATUSES)}
    status = np.asarray(table["status"])
    out["status"] = np.array([max(status[m].tolist(), key=rank.__getitem__) for m in members], dtype=str)
    for name in METRIC_NAMES:
        column = np.asarray(table[name], dtype=float)
        pick = np.min if name in LOWER_IS_WORSE else np.max
        out[name] = np.array([pick(column[m]) if not np.isnan(column[m]).any() else np.nan for m in members])
    return out


def check_across(across: Sequence[str], point_columns: Sequence[str]) -> None:
    """Raise ConfigError unless every name in ``across`` is one of the point columns."""
    missing = sorted(set(across) - set(point_columns))
    if missing:
        choices = ", ".join(point_columns) or "none: nothing is varied"
        raise ConfigError(f"--across {', '.join(missing)}: not a varied parameter; choose from {choices}")


@dataclass(frozen=True)
class Recommendation:
    """The designs that meet every constraint, best first, and how each constraint fared."""

    table: Mapping[str, np.ndarray]  # the rows ranked: points, or designs (worst case over conditions)
    columns: tuple[str, ...]  # the columns that name a row of ``table``
    rows: np.ndarray  # row indices into ``table``, ranked by ``rank_by``
    constraints: tuple[Constraint, ...]
    passing: dict[str, int]  # constraint text (and "status ok") -> rows of ``table`` meeting it
    rank_by: str = RANK_BY


def _design_of(table: Mapping[str, np.ndarray], design_columns: Sequence[str]) -> tuple[np.ndarray, int]:
    """Each row's design (its index in the order designs first appear) and how many there are."""
    keys = list(zip(*(np.asarray(table[c]).tolist() for c in design_columns))) or [()] * len(table["status"])
    index = {k: i for i, k in enumerate(dict.fromkeys(keys))}
    return np.array([index[k] for k in keys], dtype=np.int64), len(index)


def _every(flags: np.ndarray, of_design: np.ndarray, designs: int) -> np.ndarray:
    """Per design: ``flags`` holds at every one of its rows."""
    failed = np.zeros(designs, bool)
    failed[of_design[~flags]] = True
    return ~failed


def qualifying(
    table: Mapping[str, np.ndarray],
    constraints: Sequence[Constraint],
    point_columns: Sequence[str] = (),
    across: Sequence[str] = (),
) -> np.ndarray:
    """Per row of ``table``: its design qualifies, i.e. every point of it (every row, without
    ``across``; with it, the rows that differ only in those columns) is ok and meets every
    constraint."""
    meets = np.asarray(table["status"]) == "ok"
    for c in constraints:
        meets &= c.holds(table)
    if not across:
        return meets
    of_design, designs = _design_of(table, [c for c in point_columns if c not in across])
    return _every(meets, of_design, designs)[of_design]


def recommend(
    table: Mapping[str, np.ndarray],
    constraints: Sequence[Constraint],
    point_columns: Sequence[str] = (),
    across: Sequence[str] = (),
    rank_by: str = RANK_BY,
) -> Recommendation:
    """The ``ok`` rows with a finite ``rank_by`` (one of :data:`RANKINGS`) that meet every
    constraint, ranked by it, best first.

    With ``across`` (some of ``point_columns``, e.g. the payload or the operator), a row is a
    design: the other point columns. A design qualifies only if every one of its points is ok
    and meets every constraint, and it is ranked by its worst case (see :func:`worst_case`).
    """
    if rank_by not in RANKINGS:
        raise ConfigError(f"--rank-by {rank_by}: choose {', '.join(RANKINGS)}")
    sign = -1.0 if RANKINGS[rank_by][0] else 1.0  # argsort ascending of sign * value: best first
    status_ok = np.asarray(table["status"]) == "ok"
    holds = {str(c): c.holds(table) for c in constraints}
    energy = np.asarray(table[rank_by], dtype=float)
    meets = status_ok & ~np.isnan(energy)  # (a run that gave more back than it drew: infinitely many cycles)
    for column in holds.values():
        meets &= column
    check_across(across, point_columns)
    if not across:
        rows = np.nonzero(meets)[0]
        passing = {"status ok": int(status_ok.sum()), **{k: int(v.sum()) for k, v in holds.items()}}
        ranked = rows[np.argsort(sign * energy[rows], kind="stable")]
        return Recommendation(table, ("point", *point_columns), ranked, tuple(constraints), passing, rank_by)
    design_columns = [c for c in point_columns if c not in across]
    designs = worst_case(table, design_columns)
    of_design, count = _design_of(table, design_columns)
    qualifies = _every(meets, of_design, count)
    passing = {
        "status ok": int(_every(status_ok, of_design, count).sum()),
        **{k: int(_every(v, of_design, count).sum()) for k, v in holds.items()},
    }
    rows = np.nonzero(qualifies)[0]
    ranked = rows[np.argsort(sign * designs[rank_by][rows], kind="stable")]
    return Recommendation(designs, ("design", *design_columns), ranked, tuple(constraints), passing, rank_by)


def failing(rec: Recommendation) -> list[str]:
    """A line per constraint (and "status ok"): the designs meeting it; where some fail one
    that says why (a rule's: see :mod:`rules`), how many and why."""
    total = len(rec.table[rec.columns[0]])
    whys = {str(c): c.why for c in rec.constraints}
    lines = []
    for name, count in rec.passing.items():
        line = f"  {name:<32} {count} of {total}"
        if count < total and whys.get(name):
            line += f"; {total - count} fail: {whys[name]}"
        lines.append(line)
    return lines


#: Columns of the readable table: (column, heading, scale).
SUMMARY = (
    ("lift_energy_j", "lift energy [kJ]", 1e-3),
    ("lift_time_s", "lift time [s]", 1.0),
    ("peak_pressure_pa", "peak p [MPa]", 1e-6),
    ("min_pressure_pa", "min p [MPa]", 1e-6),
    ("overshoot_m", "overshoot [mm]", 1e3),
    ("damping_ratio", "damping", 1.0),
    ("cavitation_s", "cavitation [s]", 1.0),
    ("battery_energy_j", "battery [kJ]", 1e-3),
    ("cycles_per_charge", "per charge", 1.0),
)


def format_table(rec: Recommendation, top: int = 10) -> str:
    """The recommendation as aligned text: the constraints, then the best ``top`` rows."""
    table, designs = rec.table, rec.columns[0] == "design"
    what = "designs meeting each at all their points" if designs else "designs meeting each"
    lines = [f"Constraints ({what}):", *failing(rec)]
    if not len(rec.rows):
        lines.append("No design meets every constraint; relax the tightest one above.")
        return "\n".join(lines) + "\n"
    front = trade_off_front(table)
    shown = rec.rows[:top]
    more, words = RANKINGS[rec.rank_by]
    worst = " worst-case" if designs else ""
    lines.append(
        f"{len(rec.rows)} of {len(table[rec.columns[0]])} designs meet every constraint; "
        f"the {len(shown)} with the {'most' if more else 'least'}{worst} {words} "
        "(* = on the trade-off front of lift time, energy and peak pressure):"
    )
    headings = ["rank", *rec.columns, *(h for _, h, _ in SUMMARY), "front"]
    body = []
    for rank, row in enumerate(shown, start=1):
        cells = [str(rank), *(format_value(table[c][row]) for c in rec.columns)]
        cells += [format_value(float(table[c][row]) * scale) for c, _, scale in SUMMARY]
        cells.append("*" if front[row] else "")
        body.append(cells)
    widths = [max(len(h), *(len(r[i]) for r in body)) for i, h in enumerate(headings)]
    lines.append("  ".join(h.rjust(w) for h, w in zip(headings, widths)))
    lines += ["  ".join(c.rjust(w) for c, w in zip(r, widths)) for r in body]
    return "\n".join(lines) + "\n"


def format_value(value: object) -> str:
    """A table cell for people: text as it is, numbers to 4 significant digits, NaN as '-'."""
    if isinstance(value, (str, np.str_)):
        return str(value)
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    v = float(value)  # type: ignore[arg-type]
    return "-" if math.isnan(v) else f"{v:.4g}"
