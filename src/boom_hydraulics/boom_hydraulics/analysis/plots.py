"""PNG plots of runs: the panels of the paper's Figs. 8-10, the drive's other signals, and where
the battery's energy went."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # files only, no display
import matplotlib.pyplot as plt
import numpy as np

from ..model import ledger

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


#: The energies a breakdown stacks, in order: the lift's work, then every loss and work term of
#: the ledger (model.ledger.INTEGRALS' names); the battery's returned energy goes below zero.
BREAKDOWN_TERMS = ("lift_work", *(name for name in ledger.TERM_NAMES if name not in ledger.SOURCES))


def energy_breakdown(bars: Sequence[tuple[str, Mapping[str, float], float]], title: str, path: Path) -> None:
    """A stacked bar per (label, energies J by the ledger's names, battery energy J) of ``bars``:
    the positive ones of :data:`BREAKDOWN_TERMS` (stored terms net out over a cycle; what the
    surroundings give is not spent), the battery's returned energy below zero, and the battery
    energy written above the bar."""
    fig, ax = plt.subplots(figsize=(max(6.0, 2.0 + 2.0 * len(bars)), 6), constrained_layout=True)
    palette = plt.get_cmap("tab20")
    named: set[str] = set()  # each term in the legend once, where it is first drawn

    def label(name: str) -> str | None:
        first = name not in named
        named.add(name)
        return name if first else None

    for column, (_, energies, battery_j) in enumerate(bars):
        bottom = 0.0
        for k, name in enumerate(BREAKDOWN_TERMS):
            value = float(energies.get(name, 0.0)) * 1e-3
            if value > 0.0:
                ax.bar(column, value, bottom=bottom, color=palette(k % 20), label=label(name))
                bottom += value
        returned = float(energies.get("battery_returned", 0.0)) * 1e-3
        if returned > 0.0:
            ax.bar(column, -returned, color="0.4", label=label("battery_returned"))
        ax.annotate(f"{battery_j * 1e-3:.3g} kJ", (column, bottom), ha="center", va="bottom", fontsize="small")
    ax.set_xticks(range(len(bars)), [text for text, _, _ in bars], fontsize="small")
    ax.set_ylabel("energy [kJ]")
    ax.axhline(0.0, color="black", linewidth=0.8)
    ax.grid(True, axis="y", alpha=0.3)
    ax.legend(loc="upper left", bbox_to_anchor=(1.0, 1.0), fontsize="x-small")
    ax.set_title(title)
    fig.savefig(path, dpi=100)
    plt.close(fig)
