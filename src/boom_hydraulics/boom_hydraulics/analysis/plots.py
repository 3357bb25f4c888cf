"""PNG plots of runs: the panels of the paper's Figs. 8-10, the drive's other signals, and where
the battery's energy went."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # files only, no display
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure

from ..model import ledger
from . import labels, layout

Run = tuple[str, Mapping[str, np.ndarray]]  # (label, signals)


def _panels(runs: Sequence[Run], rows: list[tuple[str, str, float, float]], title: str, path: Path) -> None:
    """One panel per (signal, y label, scale, offset-from-start flag) row, runs overlaid."""
    fig = panels_figure(runs, rows, title)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def panels_figure(runs: Sequence[Run], rows: list[tuple[str, str, float, float]], title: str) -> Figure:
    """The figure of :func:`_panels`: the runs' key in a row above the panels, where it covers
    no curve (in as many rows as its names need), the title wrapped to fit."""
    fig, axes = plt.subplots(len(rows), 1, figsize=(8, 2.2 * len(rows)), sharex=True, layout="constrained")
    for ax, (name, ylabel, scale, relative) in zip(axes, rows):
        for label, s in runs:
            y = np.asarray(s[name], dtype=float)
            ax.plot(s["t"], (y - y[0] * relative) * scale, label=label, linewidth=1.0)
        ax.set_ylabel(ylabel)
        ax.grid(True, alpha=0.3)
    axes[-1].set_xlabel("time t [s]")
    suptitle = fig.suptitle(title)
    layout.fit_title(fig, suptitle)
    handles, labels = axes[0].get_legend_handles_labels()
    columns = 1 if max((len(text) for text in labels), default=0) > 40 else min(len(labels), 2)
    axes[0].legend(handles, labels, loc="lower center", bbox_to_anchor=(0.5, 1.02), ncols=columns, fontsize="small")
    return fig


#: The panels of the paper's Figs. 8-10: (signal, y label, scale, offset-from-start flag).
DYNAMICS_ROWS = [
    ("q1", "displacement q1 - q1(0) [m]", 1.0, 1.0),
    ("v", "rod velocity [m/s]", 1.0, 0.0),
    ("a", "rod acceleration [m/s²]", 1.0, 0.0),
    ("p1", "piston chamber p1 [MPa]", 1e-6, 0.0),
]
#: The drive's other signals, as :data:`DYNAMICS_ROWS`.
DRIVE_ROWS = [
    ("p2", "rod chamber p2 [MPa]", 1e-6, 0.0),
    ("f_hyd", "hydraulic rod force [kN]", 1e-3, 0.0),
    ("u", "valve command u [-]", 1.0, 0.0),
    ("x_v", "spool opening x_v [-]", 1.0, 0.0),
]


def dynamics(runs: Sequence[Run], path: Path, title: str = "Rod motion and piston-chamber pressure") -> None:
    """Rod displacement, velocity, acceleration and piston-chamber pressure (Figs. 8-10)."""
    _panels(runs, DYNAMICS_ROWS, title, path)


def drive(runs: Sequence[Run], path: Path) -> None:
    """Rod-chamber pressure, hydraulic rod force and valve command/opening."""
    _panels(runs, DRIVE_ROWS, "Rod-chamber pressure, rod force and valve", path)


#: The energies a breakdown stacks, in order: the lift's work, then every loss and work term of
#: the ledger (model.ledger.INTEGRALS' names); the battery's returned energy goes below zero.
BREAKDOWN_TERMS = ("lift_work", *(name for name in ledger.TERM_NAMES if name not in ledger.SOURCES))


def energy_breakdown(bars: Sequence[tuple[str, Mapping[str, float], float]], title: str, path: Path) -> None:
    """:func:`energy_breakdown_figure` as a PNG at ``path``."""
    fig = energy_breakdown_figure(bars, title)
    fig.savefig(path, dpi=100)
    plt.close(fig)


def energy_breakdown_figure(bars: Sequence[tuple[str, Mapping[str, float], float]], title: str) -> Figure:
    """A stacked bar per (label, energies J by the ledger's names, battery energy J) of ``bars``:
    the positive ones of :data:`BREAKDOWN_TERMS` (stored terms net out over a cycle; what the
    surroundings give is not spent), the battery's returned energy below zero, and the battery
    energy written above the bar. The terms are named in words (labels.TERM_WORDS) in a key
    right of the bars; the bars' labels are broken onto lines, or turned, so that none
    overlaps the next; the title is wrapped to fit the figure."""
    fig, ax = plt.subplots(figsize=(max(7.0, 3.0 + 1.8 * len(bars)), 6), layout="constrained")
    palette = plt.get_cmap("tab20")
    named: set[str] = set()  # each term in the key once, where it is first drawn

    def label(name: str) -> str | None:
        first = name not in named
        named.add(name)
        return labels.term_words(name) if first else None

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
    ax.set_xticks(range(len(bars)))
    ax.set_ylabel("energy [kJ]")
    ax.axhline(0.0, color="black", linewidth=0.8)
    ax.grid(True, axis="y", alpha=0.3)
    ax.margins(y=0.06)  # room for the battery energy over the highest bar
    key = {"fontsize": "small", "title": "where it goes", "title_fontsize": "small"}
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), **key)
    suptitle = fig.suptitle(title)
    layout.fit_title(fig, suptitle)
    fig.draw_without_rendering()  # (the bars' room, once the key and title have theirs)
    layout.tick_labels_apart(fig, ax, [text for text, _, _ in bars])
    return fig
