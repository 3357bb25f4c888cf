"""PNG plots of runs: the panels of the paper's Figs. 8-10 and the drive's other signals."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # files only, no display
import matplotlib.pyplot as plt
import numpy as np

Run = tuple[str, Mapping[str, np.ndarray]]  # (label, signals)


def _panels(runs: Sequence[Run], rows: list[tuple[str, str, float, float]], title: str, path: Path) -> None:
    """One panel per (signal, y label, scale, offset-from-start flag) row, runs overlaid."""
    fig, axes = plt.subplots(len(rows), 1, figsize=(8, 2.2 * len(rows)), sharex=True, constrained_layout=True)
    for ax, (name, ylabel, scale, relative) in zip(axes, rows):
        for label, s in runs:
            y = np.asarray(s[name], dtype=float)
            ax.plot(s["t"], (y - y[0] * relative) * scale, label=label, linewidth=1.0)
        ax.set_ylabel(ylabel)
        ax.grid(True, alpha=0.3)
    axes[0].legend(loc="best", fontsize="small")
    axes[-1].set_xlabel("time t [s]")
    fig.suptitle(title)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def dynamics(runs: Sequence[Run], path: Path, title: str = "Rod motion and piston-chamber pressure") -> None:
    """Rod displacement, velocity, acceleration and piston-chamber pressure (Figs. 8-10)."""
    _panels(
        runs,
        [
            ("q1", "displacement q1 - q1(0) [m]", 1.0, 1.0),
            ("v", "rod velocity [m/s]", 1.0, 0.0),
            ("a", "rod acceleration [m/s²]", 1.0, 0.0),
            ("p1", "piston-chamber pressure p1 [MPa]", 1e-6, 0.0),
        ],
        title,
        path,
    )


def drive(runs: Sequence[Run], path: Path) -> None:
    """Rod-chamber pressure, hydraulic rod force and valve command/opening."""
    _panels(
        runs,
        [
            ("p2", "rod-chamber pressure p2 [MPa]", 1e-6, 0.0),
            ("f_hyd", "hydraulic rod force [kN]", 1e-3, 0.0),
            ("u", "valve command u [-]", 1.0, 0.0),
            ("x_v", "spool opening x_v [-]", 1.0, 0.0),
        ],
        "Rod-chamber pressure, rod force and valve",
        path,
    )
