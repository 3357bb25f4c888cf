"""The battery's side of a sweep: each design's energy per work cycle over the operators'
cycles, and where that energy went.

A sweep with ``--operators N`` runs every design (its point columns but ``operator``) through N
cycles an operator varies (solve.duty_cycles). :func:`operator_bands` gives, per design, the
10th, 50th and 90th percentiles of its battery energy per cycle and of its cycles per charge
over its cycles that ran ok, and the mean of each of the ledger's terms; :func:`best_per_drive`
picks each drive's design with the least median battery energy. Without operators each design
has one cycle, and its band is that cycle's value.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from .recommend import designs_of, format_value
from .rules import range_edges
from .sweep import LEDGER_METRICS

#: The band's percentiles.
PERCENTILES = (10, 50, 90)
#: The figures a band is taken of: (column, label, scale).
BANDED = (("battery_energy_j", "battery energy per cycle", 1e-3), ("cycles_per_charge", "cycles per charge", 1.0))
#: The columns a design's breakdown averages over its cycles: the lift's work and the ledger's terms.
BREAKDOWN = ("lift_work_j", "battery_returned_j", *(name for name, _, _ in LEDGER_METRICS))


def design_columns(point_columns: Sequence[str]) -> list[str]:
    """The point columns that name a design: all but the operator's seed."""
    return [c for c in point_columns if c != "operator"]


def operator_bands(table: Mapping[str, np.ndarray], point_columns: Sequence[str]) -> dict[str, np.ndarray]:
    """One row per design (in the order designs first appear): its design columns, ``cycles``
    (how many of its cycles ran ok), ``<figure>_p10`` / ``_p50`` / ``_p90`` of :data:`BANDED`
    over those (as numpy.percentile takes them), and the mean of each :data:`BREAKDOWN` column
    (NaN where none ran ok). Grouped in whole arrays: a sweep of 10 000 designs takes
    milliseconds, not a percentile call per design."""
    columns = design_columns(point_columns)
    ok = np.asarray(table["status"]) == "ok"
    groups = designs_of(table, columns)
    out: dict[str, np.ndarray] = {}
    for j, column in enumerate(columns):
        out[column] = np.array([key[j] for key in groups], dtype=np.asarray(table[column]).dtype)
    design = np.empty(len(ok), dtype=np.int64)  # each row's design, in the order designs first appear
    for g, rows in enumerate(groups.values()):
        design[rows] = g
    design, n = design[ok], len(groups)
    cycles = np.bincount(design, minlength=n)
    out["cycles"] = cycles
    for name, _, _ in BANDED:
        values = np.asarray(table[name], dtype=float)[ok]
        for q in PERCENTILES:
            out[f"{name}_p{q}"] = grouped_percentile(values, design, cycles, q)
    for name in BREAKDOWN:
        values = np.asarray(table[name], dtype=float)[ok]
        with np.errstate(invalid="ignore", divide="ignore"):
            out[name] = np.bincount(design, weights=values, minlength=n) / cycles
    return out


def grouped_percentile(values: np.ndarray, group: np.ndarray, sizes: np.ndarray, q: float) -> np.ndarray:
    """The ``q``-th percentile of ``values`` within each group (``group``: each value's group,
    ``sizes``: each group's count), linear between the order statistics as numpy.percentile
    takes it; NaN for a group that is empty or holds a NaN."""
    order = np.lexsort((values, group))  # by group, then by value (a NaN last in its group)
    ranked = values[order]
    starts = np.concatenate([[0], np.cumsum(sizes)[:-1]])
    position = (np.maximum(sizes, 1) - 1) * (q / 100.0)
    low = np.floor(position).astype(np.int64)
    high = np.minimum(low + 1, np.maximum(sizes - 1, 0))
    frac = position - low
    out = np.full(len(sizes), np.nan)
    has = sizes > 0
    a, b = ranked[(starts + low)[has]], ranked[(starts + high)[has]]
    with np.errstate(invalid="ignore"):  # inf - inf: NaN, as numpy's is
        span = b - a
        out[has] = np.where(frac[has] >= 0.5, b - span * (1.0 - frac[has]), a + span * frac[has])
    nans = np.bincount(group, weights=np.isnan(values), minlength=len(sizes)) > 0
    out[nans] = np.nan
    return out


def qualifying_designs(
    table: Mapping[str, np.ndarray], point_columns: Sequence[str], qualifies: np.ndarray
) -> np.ndarray:
    """Per row of :func:`operator_bands` (a design, in the order designs first appear): every
    one of its rows in ``table`` qualifies (``qualifies``: per row, recommend.qualifying)."""
    groups = designs_of(table, design_columns(point_columns))
    qualifies = np.asarray(qualifies, dtype=bool)
    return np.array([bool(qualifies[rows].all()) for rows in groups.values()], dtype=bool)


def best_per_drive(bands: Mapping[str, np.ndarray], qualifies: np.ndarray | None = None) -> dict[str, int | None]:
    """Each drive's row of ``bands`` with the least median battery energy per cycle, among its
    designs that qualify (``qualifies``: per row of ``bands``, see :func:`qualifying_designs`;
    None where none of a drive's does), or without ``qualifies`` among its designs whose every
    cycle ran ok (or, where none did, those with the most ok cycles); one entry "" without a
    drive column."""
    drives = np.asarray(bands["drive"]).tolist() if "drive" in bands else [""] * len(bands["cycles"])
    energy = np.asarray(bands["battery_energy_j_p50"], dtype=float)
    cycles = np.asarray(bands["cycles"])
    most = {d: max(cycles[i] for i, e in enumerate(drives) if e == d) for d in dict.fromkeys(drives)}
    best: dict[str, int | None] = dict.fromkeys(most) if qualifies is not None else {}
    for row, drive in enumerate(drives):
        if not np.isfinite(energy[row]):
            continue
        if qualifies is not None:
            if not qualifies[row]:
                continue
        elif cycles[row] < most[drive]:
            continue
        now = best.get(drive)
        if now is None or energy[row] < energy[now]:
            best[drive] = row
    return best


def summary(
    bands: Mapping[str, np.ndarray],
    columns: Sequence[str],
    qualifies: np.ndarray | None = None,
    conditions: Sequence[str] = (),
) -> str:
    """A line per drive: its best design (of those that qualify, with ``qualifies``: see
    :func:`best_per_drive`), battery energy per cycle and cycles per charge with their 10th-90th
    percentile band over its cycles (a design of one cycle has no band); and with ``qualifies``,
    where that design lies at an end of a searched axis other than the ``conditions`` (the
    columns of ``--across``), a line saying which way to extend it."""
    lines = []
    axes = [c for c in design_columns(columns) if c != "drive"]
    searched = [c for c in axes if c not in conditions]
    drives = np.asarray(bands["drive"]).tolist() if "drive" in bands else [""] * len(bands["cycles"])
    for drive, row in best_per_drive(bands, qualifies).items():
        with_drive = f" with {drive}" if drive else ""
        if row is None:
            count = drives.count(drive)
            lines.append(
                f"  least battery energy{with_drive}: none of its {count} designs meets every rule and constraint"
            )
            continue
        where = ", ".join(f"{c}={format_value(bands[c][row])}" for c in axes)
        energy = [float(bands[f"battery_energy_j_p{q}"][row]) * 1e-3 for q in PERCENTILES]
        cycles = [float(bands[f"cycles_per_charge_p{q}"][row]) for q in PERCENTILES]
        count = int(bands["cycles"][row])
        if count == 1:  # the one cycle's values
            figures = f"{energy[1]:.3g} kJ per cycle, {cycles[1]:.0f} cycles per charge (one cycle run: no band)"
        else:
            figures = (
                f"{energy[1]:.3g} kJ per cycle ({energy[0]:.3g}-{energy[2]:.3g}), {cycles[1]:.0f} cycles per charge "
                f"({cycles[0]:.0f}-{cycles[2]:.0f}), median (10th-90th percentile) over its {count} cycles"
            )
        lines.append(f"  least battery energy{with_drive}: {figures}" + (f" at {where}" if where else ""))
        whose = f"{drive}'s best" if drive else "best"
        if qualifies is not None:
            score = bands["battery_energy_j_p50"]  # what the least battery energy was chosen by
            lines += [f"    {line}" for line in range_edges(bands, searched, row, whose, score)]
    return "\n".join(lines)
