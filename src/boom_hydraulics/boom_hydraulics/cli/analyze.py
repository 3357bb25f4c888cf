"""``boom-analyze``: signals, metrics and plots of recorded runs.

    boom-analyze bags/20261122-043623_boom_sim
    boom-analyze run1/ run2/ --out out/compare      # runs overlaid in the plots

Per bag: <name>.csv (one column per signal, with units; time in s from the run's origin),
<name>.npz and <name>.metrics.json (strict JSON: a metric without a value is null); for
all bags together: dynamics.png (rod displacement, velocity, acceleration, piston-chamber
pressure: the panels of the paper's Figs. 8-10) and drive.png (rod-chamber pressure, rod
force, valve). Only these files are written into the results folder, each whole or not at
all; nothing else in it is touched, and a folder that is or holds one of the bags is refused.

Runs are overlaid on a common time axis (--align): t = 0 at the recorded time origin, the
node's simulated time 0 (default; a boom-resim bag shares its source's origin), at the
first opening of the valve, or at each run's first message.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ..analysis import metrics as analysis
from ..analysis import plots
from ..bags.reading import ALIGNMENTS, read_drive_states
from ..errors import ConfigError
from ..files import check_apart, csv_cell, json_text, results_folder, write_csv, write_npz
from ..solve.simulation import OUTPUTS
from .common import RaisingParser, run_main, summary

_UNITS = {name: unit for name, unit, _ in OUTPUTS}


def bag_label(bag: Path) -> str:
    return bag.stem if bag.is_file() else bag.resolve().name


def write_signals(folder: Path, label: str, signals: dict[str, np.ndarray]) -> None:
    names = list(signals)
    header = [f"{n} [{_UNITS.get(n, 's' if n == 't' else '1')}]" for n in names]
    columns = [signals[n] for n in names]
    write_csv(folder / f"{label}.csv", header, ([csv_cell(c[i]) for c in columns] for i in range(len(signals["t"]))))
    write_npz(folder / f"{label}.npz", signals, compressed=True)


def analyze(bags: Sequence[Path], out: Path, align: str = "origin") -> dict[str, dict[str, float]]:
    """Read every bag, then write the results into ``out`` (only the files named above)."""
    check_apart(out, bags)
    labels = [bag_label(bag) for bag in bags]
    if len(set(labels)) < len(labels):
        raise ConfigError(f"two bags share the name {max(labels, key=labels.count)!r}; their results would collide")
    runs = [(label, read_drive_states(bag, align)) for label, bag in zip(labels, bags)]  # fails before writing
    results = {}
    with results_folder(out) as tmp:
        for label, signals in runs:
            write_signals(tmp, label, signals)
            results[label] = analysis.metrics(signals)
            (tmp / f"{label}.metrics.json").write_text(json_text(results[label]))
        plots.dynamics(runs, tmp / "dynamics.png")
        plots.drive(runs, tmp / "drive.png")
    return results


def main(argv: Sequence[str] | None = None) -> int:
    def body() -> int:
        parser = RaisingParser(prog="boom-analyze", description=summary(__doc__))
        parser.add_argument("bags", nargs="+", type=Path, help="bag folders or .mcap files")
        parser.add_argument("--out", type=Path, help="results folder (default: <first bag>.analysis next to it)")
        parser.add_argument(
            "--align",
            choices=ALIGNMENTS,
            default="origin",
            help="t = 0 at the recorded time origin (default), the first valve opening, or the first message",
        )
        args = parser.parse_args(argv)
        first = args.bags[0]
        named = first if first.name not in ("", ".", "..") else first.resolve()  # '.': the folder's own name
        out = args.out or named.with_name(f"{bag_label(first)}.analysis")
        results = analyze(args.bags, out, args.align)
        for label, m in results.items():
            low, high = m["min_pressure_pa"] / 1e6, m["peak_pressure_pa"] / 1e6
            print(
                f"{label}: lift {m['lift_m']:.3f} m, 90 % in {m['time_to_target_s']:.2f} s, "
                f"peak speed {m['peak_speed_m_s']:.3f} m/s, pressures {low:.2f}..{high:.2f} MPa, "
                f"energy {m['supply_energy_j'] / 1e3:.2f} kJ"
            )
        print(f"boom-analyze: results in {out}")
        return 0

    return run_main("boom-analyze", body)


if __name__ == "__main__":
    sys.exit(main())
