"""Recorded runs analysed: per bag its signals (CSV, NPZ) and metrics (JSON), and the plots
of all of them overlaid (the library side of ``boom-analyze``, also run by ``boom-demo``).

Only these files are written into the results folder, each whole or not at all; nothing
else in it is touched, and a folder that is or holds one of the bags is refused.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from ..bags.reading import read_drive_states, read_energy_ledger
from ..errors import ConfigError
from ..files import check_apart, json_text, results_folder, write_csv_columns, write_npz
from ..solve.outputs import OUTPUTS
from . import metrics as analysis
from . import plots

_UNITS = {name: unit for name, unit, _ in OUTPUTS}


def bag_label(bag: Path) -> str:
    """The name a bag's results carry: the .mcap file's stem, or the bag folder's name."""
    return bag.stem if bag.is_file() else bag.resolve().name


def default_results_folder(first: Path) -> Path:
    """``<first bag>.analysis`` next to it (``.``: named after the folder itself)."""
    named = first if first.name not in ("", ".", "..") else first.resolve()
    return named.with_name(f"{bag_label(first)}.analysis")


def write_signals(folder: Path, label: str, signals: dict[str, np.ndarray]) -> None:
    names = list(signals)
    header = [f"{n} [{_UNITS.get(n, 's' if n == 't' else '1')}]" for n in names]
    columns = [signals[n] for n in names]
    write_csv_columns(folder / f"{label}.csv", header, columns)
    write_npz(folder / f"{label}.npz", signals, compressed=True)


def analyze(bags: Sequence[Path], out: Path, align: str = "origin") -> dict[str, dict[str, float]]:
    """Read every bag, then write the results into ``out`` (only the files named above)."""
    check_apart(out, bags)
    labels = [bag_label(bag) for bag in bags]
    if len(set(labels)) < len(labels):
        raise ConfigError(f"two bags share the name {max(labels, key=labels.count)!r}; their results would collide")
    runs = [(label, read_drive_states(bag, align)) for label, bag in zip(labels, bags)]  # fails before writing
    ledgers = {label: read_energy_ledger(bag) for label, bag in zip(labels, bags)}
    results = {}
    with results_folder(out) as tmp:
        for label, signals in runs:
            write_signals(tmp, label, signals)
            results[label] = analysis.metrics(signals)
            energies = ledgers[label]
            if energies is not None:  # the battery's figures, from the bag's last energy ledger
                results[label].update(
                    battery_energy_j=energies["battery_drawn"] - energies["battery_returned"],
                    battery_drawn_j=energies["battery_drawn"],
                    battery_returned_j=energies["battery_returned"],
                    lift_work_j=energies["lift_work"],
                    state_of_charge=energies["state_of_charge"],
                )
            (tmp / f"{label}.metrics.json").write_text(json_text(results[label]))
        plots.dynamics(runs, tmp / "dynamics.png")
        plots.drive(runs, tmp / "drive.png")
        bars = [(label, e, e["battery_drawn"] - e["battery_returned"]) for label, e in ledgers.items() if e]
        if bars:
            title = "Where the battery's energy went over each run (above each bar: drawn less returned)"
            plots.energy_breakdown(bars, title, tmp / "energy.png")
    return results


def report(results: Mapping[str, Mapping[str, float]], out: Path) -> str:
    """What ``boom-analyze`` prints: a line of the main metrics per run, and where the results are."""
    lines = []
    for label, m in results.items():
        low, high = m["min_pressure_pa"] / 1e6, m["peak_pressure_pa"] / 1e6
        to_target = m["time_to_target_s"]  # NaN: q1 never reached 90 % of its rise (none: no lift)
        timing = f"90 % in {to_target:.2f} s" if math.isfinite(to_target) else "90 % never reached"
        lines.append(
            f"{label}: lift {m['lift_m']:.3f} m, {timing}, "
            f"peak speed {m['peak_speed_m_s']:.3f} m/s, pressures {low:.2f}..{high:.2f} MPa, "
            f"energy {m['supply_energy_j'] / 1e3:.2f} kJ"
            + (f", battery {m['battery_energy_j'] / 1e3:.2f} kJ" if math.isfinite(m["battery_energy_j"]) else "")
        )
    lines.append(f"boom-analyze: results in {out}")
    return "\n".join(lines)
