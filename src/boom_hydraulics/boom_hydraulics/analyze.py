"""``boom-analyze``: signals, metrics and plots of recorded runs.

    boom-analyze bags/20261122-043623_boom_sim
    boom-analyze run1/ run2/ --out out/compare      # runs overlaid in the plots

Per bag: ``<name>.csv`` (one column per signal, with units), ``<name>.npz`` and
``<name>.metrics.json``; for all bags together: ``dynamics.png`` (rod displacement,
velocity, acceleration, piston-chamber pressure: the panels of the paper's Figs. 8-10)
and ``drive.png`` (rod-chamber pressure, rod force, valve). Everything is written to a
temporary folder first: an error leaves no half-written results.
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from . import analysis, plots
from .bag_reading import read_drive_states
from .errors import BoomHydraulicsError
from .files import staged_folder
from .simulation import OUTPUTS

_UNITS = {name: unit for name, unit, _ in OUTPUTS}


def bag_label(bag: Path) -> str:
    return bag.stem if bag.is_file() else bag.name


def write_signals(folder: Path, label: str, signals: dict[str, np.ndarray]) -> None:
    names = list(signals)
    with (folder / f"{label}.csv").open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow([f"{n} [{_UNITS.get(n, 's' if n == 't' else '1')}]" for n in names])
        columns = [signals[n] for n in names]
        for i in range(len(signals["t"])):
            writer.writerow([repr(float(c[i])) for c in columns])
    np.savez_compressed(folder / f"{label}.npz", **signals)


def analyze(bags: Sequence[Path], out: Path) -> dict[str, dict[str, float]]:
    """Read every bag, then write all results to ``out`` (replaced as a whole at the end)."""
    runs = [(bag_label(bag), read_drive_states(bag)) for bag in bags]  # fails before writing
    results = {}
    with staged_folder(out) as tmp:
        for label, signals in runs:
            write_signals(tmp, label, signals)
            results[label] = analysis.metrics(signals)
            (tmp / f"{label}.metrics.json").write_text(json.dumps(results[label], indent=2) + "\n")
        plots.dynamics(runs, tmp / "dynamics.png")
        plots.drive(runs, tmp / "drive.png")
    return results


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="boom-analyze", description=__doc__.splitlines()[0])
    parser.add_argument("bags", nargs="+", type=Path, help="bag folders or .mcap files")
    parser.add_argument("--out", type=Path, help="results folder (default: <first bag>.analysis next to it)")
    args = parser.parse_args(argv)
    first = args.bags[0]
    out = args.out or first.with_name(f"{bag_label(first)}.analysis")
    try:
        results = analyze(args.bags, out)
    except BoomHydraulicsError as exc:
        print(f"boom-analyze: error: {exc}", file=sys.stderr)
        return 1
    for label, m in results.items():
        low, high = m["min_pressure_pa"] / 1e6, m["peak_pressure_pa"] / 1e6
        print(
            f"{label}: lift {m['lift_m']:.3f} m, 90 % in {m['time_to_target_s']:.2f} s, "
            f"peak speed {m['peak_speed_m_s']:.3f} m/s, pressures {low:.2f}..{high:.2f} MPa, "
            f"energy {m['supply_energy_j'] / 1e3:.2f} kJ"
        )
    print(f"boom-analyze: results in {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
