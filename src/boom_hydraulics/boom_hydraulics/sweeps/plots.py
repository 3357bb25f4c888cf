"""PNG plots of a sweep table: each metric against each varied parameter, the trade-off front,
and the battery's energy per cycle and where it goes."""

from __future__ import annotations

import contextlib
import functools
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")  # files only, no display
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.lines import Line2D

from ..analysis.plots import energy_breakdown as breakdown
from ..files import atomic_path
from ..programs import Forked, can_fork
from .energy import BREAKDOWN, PERCENTILES, best_per_drive, design_columns, operator_bands
from .recommend import TRADE_OFF, format_value, trade_off_front

#: Metrics plotted against the varied parameters: (column, label, scale).
PLOTTED = (
    ("lift_time_s", "lift time [s]", 1.0),
    ("lift_energy_j", "lift energy [kJ]", 1e-3),
    ("lift_valve_loss_j", "valve loss in lift [kJ]", 1e-3),
    ("peak_speed_m_s", "peak rod speed [m/s]", 1.0),
    ("rms_speed_m_s", "RMS rod speed [m/s]", 1.0),
    ("overshoot_m", "overshoot [mm]", 1e3),
    ("oscillation_hz", "oscillation [Hz]", 1.0),
    ("damping_ratio", "damping ratio", 1.0),
    ("peak_pressure_pa", "peak pressure [MPa]", 1e-6),
    ("min_pressure_pa", "min pressure [MPa]", 1e-6),
    ("cavitation_s", "cavitation [s]", 1.0),
    ("relief_s", "relief open [s]", 1.0),
)


#: A design's spot, pt^2: filled, without an edge. Drawing the edge of each of 10 000 spots
#: took a quarter of a figure's time; this spot is about as large as the edged one.
SPOT = 20.0


#: Categories a row of a metrics figure's key holds.
KEY_COLUMNS = 6


def _save(fig, path: Path) -> None:
    """The figure as PNG at ``path``, whole or not at all (an interrupted plot leaves the old one)."""
    with atomic_path(path, suffix=".png") as tmp:
        fig.savefig(tmp, dpi=100, format="png")


def _numeric(column: np.ndarray) -> bool:
    return np.asarray(column).dtype.kind in "fiu"


def metrics_against(table: Mapping[str, np.ndarray], parameter: str, color_by: str | None, path: Path) -> None:
    """A panel per metric of :data:`PLOTTED` against ``parameter``; ok designs coloured by
    ``color_by`` (numeric or categorical), the others grey."""
    x = np.asarray(table[parameter])
    ok = np.asarray(table["status"]) == "ok"
    fig, axes = plt.subplots(3, 4, figsize=(15, 9.5))
    colours, mapper, key = _colours(table, color_by, ok)
    bar = mapper is not None
    # a fixed layout, with room for the labels of these panels: constrained layout measured
    # every tick label of the 12 panels, 0.35-0.4 s of a figure's 1.2 s
    rows = _key(fig, key)  # a key to categories goes in rows under the title
    top = max(0.5, 0.935 - 0.03 * rows)
    fig.subplots_adjust(left=0.05, right=0.895 if bar else 0.985, bottom=0.06, top=top, wspace=0.32, hspace=0.3)
    for ax, (name, label, scale) in zip(axes.flat, PLOTTED):
        y = np.asarray(table[name], dtype=float) * scale
        ax.plot(x[~ok], y[~ok], "x", markersize=3.2, markeredgewidth=0.8, color="0.7", label="not ok")
        ax.scatter(x[ok], y[ok], s=SPOT, linewidths=0, c=colours, cmap="viridis" if mapper else None, norm=mapper)
        ax.set_xlabel(parameter)
        ax.set_ylabel(label)
        ax.grid(True, alpha=0.3)
    if bar:
        bar_axes = fig.add_axes((0.915, 0.25, 0.012, 0.5))
        fig.colorbar(plt.cm.ScalarMappable(norm=mapper, cmap="viridis"), cax=bar_axes, label=color_by)
    fig.suptitle(
        f"Design metrics against {parameter}: {int(ok.sum())} ok designs coloured"
        + (f" by {color_by}" if color_by else "")
        + f", {int((~ok).sum())} others (x)"
    )
    _save(fig, path)
    plt.close(fig)


def _key(fig, key: Mapping[Any, Any]) -> int:
    """The key to categories (a drive, a config: which colour is which) in a row under the
    title, in as many columns as fit the figure's width (at most KEY_COLUMNS); its rows."""
    if not key:
        return 0
    spots = [Line2D([], [], linestyle="", marker="o", color=c, label=str(name)) for name, c in key.items()]
    renderer = fig.canvas.get_renderer()
    for columns in range(min(len(spots), KEY_COLUMNS), 0, -1):
        legend = fig.legend(handles=spots, loc="upper center", bbox_to_anchor=(0.5, 0.96), ncols=columns)
        if columns == 1 or legend.get_window_extent(renderer).width <= 0.98 * fig.bbox.width:
            return -(-len(spots) // columns)
        legend.remove()
    return len(spots)


def _colours(table: Mapping[str, np.ndarray], color_by: str | None, ok: np.ndarray):
    """Colours of the ok points, the norm of a colour bar (None for categories), and for
    categories, each one's colour: {category: colour}."""
    if color_by is None:
        return "tab:blue", None, {}
    values = np.asarray(table[color_by])[ok]
    if _numeric(values):
        values = values.astype(float)
        low, high = (float(values.min()), float(values.max())) if len(values) else (0.0, 1.0)
        return values, matplotlib.colors.Normalize(low, high if high > low else low + 1.0), {}
    categories = sorted(set(values.tolist()))
    palette = plt.get_cmap("tab10" if len(categories) <= 10 else "tab20")  # (beyond 20, colours repeat)
    key = {category: palette(k % palette.N) for k, category in enumerate(categories)}
    return [key[v] for v in values.tolist()], None, key


def trade_off(table: Mapping[str, np.ndarray], label_columns: Sequence[str], path: Path) -> None:
    """Lift time against lift energy and against peak pressure; the front of all three ringed."""
    ok = np.asarray(table["status"]) == "ok"
    front = trade_off_front(table)
    time_s, energy_kj, pressure_mpa = (
        np.asarray(table[m], dtype=float) * s for m, s in zip(TRADE_OFF, (1.0, 1e-3, 1e-6))
    )
    fig, (left, right) = plt.subplots(1, 2, figsize=(13, 5.5), constrained_layout=True)
    panels = ((left, energy_kj, "lift energy [kJ]", pressure_mpa, "peak pressure [MPa]"),
              (right, pressure_mpa, "peak pressure [MPa]", energy_kj, "lift energy [kJ]"))  # fmt: skip
    for ax, y, ylabel, colour, clabel in panels:
        points = ax.scatter(time_s[ok], y[ok], c=colour[ok], s=SPOT, linewidths=0, cmap="viridis")
        ax.scatter(time_s[front], y[front], s=70, facecolors="none", edgecolors="tab:red", label="non-dominated")
        fig.colorbar(points, ax=ax, label=clabel)
        ax.set_xlabel("lift time [s]")
        ax.set_ylabel(ylabel)
        ax.grid(True, alpha=0.3)
        ax.legend(loc="best", fontsize="small")
    if label_columns:  # name a few front designs by their parameter values
        for row in np.nonzero(front)[0][:12]:
            text = ", ".join(format_value(table[c][row]) for c in label_columns)
            left.annotate(text, (time_s[row], energy_kj[row]), fontsize=6, xytext=(4, 4), textcoords="offset points")
        left.set_title(f"front designs labelled ({', '.join(label_columns)})", fontsize="small")
    fig.suptitle(
        f"Trade-off: {int(front.sum())} non-dominated of {int(ok.sum())} ok designs "
        "(lower lift time, energy and peak pressure are better)"
    )
    _save(fig, path)
    plt.close(fig)


def battery_energy(bands: Mapping[str, np.ndarray], parameter: str, path: Path) -> None:
    """Battery energy per cycle against ``parameter``, one line per drive (the median over the
    operators' cycles, their 10th-90th percentile shaded), from :func:`energy.operator_bands`."""
    x = np.asarray(bands[parameter], dtype=float)
    drives = np.asarray(bands["drive"]).tolist() if "drive" in bands else [""] * len(x)
    fig, ax = plt.subplots(figsize=(8, 5.5), constrained_layout=True)
    for drive in dict.fromkeys(drives):
        rows = np.array([i for i, d in enumerate(drives) if d == drive])
        rows = rows[np.argsort(x[rows], kind="stable")]
        low, mid, high = (np.asarray(bands[f"battery_energy_j_p{q}"], float)[rows] * 1e-3 for q in PERCENTILES)
        (line,) = ax.plot(x[rows], mid, marker="o", markersize=3, label=drive or "battery energy")
        ax.fill_between(x[rows], low, high, color=line.get_color(), alpha=0.2)
    ax.set_xlabel(parameter)
    ax.set_ylabel("battery energy per cycle [kJ]")
    ax.set_yscale("log")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(loc="best", fontsize="small")
    cycles = int(np.max(bands["cycles"])) if len(bands["cycles"]) else 0
    ax.set_title(f"Battery energy per cycle: median and 10th-90th percentile over {cycles} cycle(s) per design")
    _save(fig, path)
    plt.close(fig)


def energy_breakdown(bands: Mapping[str, np.ndarray], design_columns: Sequence[str], path: Path) -> None:
    """Where the battery's energy goes, a stacked bar for each drive at its best design (the
    least median battery energy per cycle): the lift's work and every loss and work term of
    the ledger, averaged over its cycles; the energy it took back is drawn below zero."""
    bars = []
    for drive, row in best_per_drive(bands).items():
        energies = {name.removesuffix("_j"): float(bands[name][row]) for name in BREAKDOWN}
        where = ", ".join(format_value(bands[c][row]) for c in design_columns if c != "drive")
        text = f"{drive}\n{where}" if where else drive or "best design"
        bars.append((text, energies, float(bands["battery_energy_j_p50"][row])))
    title = (
        "Where the battery's energy goes, each drive at its best design (mean over its cycles;\n"
        "above each bar the median battery energy per cycle)"
    )
    with atomic_path(path, suffix=".png") as tmp:
        breakdown(bars, title, tmp)


def plot_all(
    table: Mapping[str, np.ndarray],
    point_columns: Sequence[str],
    folder: Path,
    first: Sequence[tuple[Path, Callable[[], None]]] = (),
) -> list[Path]:
    """Every sweep plot into ``folder``; returns the files written: with the battery (physical
    mode), also the battery energy per cycle and its breakdown. Where it can fork
    (programs.can_fork), a child process draws every other plot meanwhile: a figure is up to
    a second of Python, on one core (a 10 000-point sweep's five plots took 1.95-2.05 s so,
    against 3.2-3.3 s one after the other). ``first``: other files and what writes each, put
    before the plots in the one list that is shared out: the first of them is written by this
    process before its plots, whether it forks or not (boom-sweep's results table, 0.05 s of
    Python for 10 000 points, while the child draws). A failure here stops the child; plots it
    finished before that stay, whole."""
    plots = _plots(table, point_columns, folder)
    jobs = [*first, *plots]
    theirs, mine = jobs[1::2], jobs[0::2]
    forked = None
    try:
        if theirs and can_fork():
            with contextlib.suppress(OSError):  # (a fork the system refuses: all of them here)
                forked = Forked(lambda: _draw(theirs))
        _draw(mine if forked is not None else jobs)
        if forked is not None:
            forked.wait()
    except BaseException:
        if forked is not None:
            forked.stop()
        raise
    return [path for path, _ in plots]


def _draw(jobs: Sequence[tuple[Path, Callable[[], None]]]) -> None:
    for _, draw in jobs:
        draw()


def _plots(
    table: Mapping[str, np.ndarray], point_columns: Sequence[str], folder: Path
) -> list[tuple[Path, Callable[[], None]]]:
    """The plots of :func:`plot_all`, each as its file and what draws it, in their order."""
    jobs: list[tuple[Path, Callable[[], None]]] = []
    varied = [c for c in point_columns if _numeric(table[c]) and len(np.unique(table[c])) > 1]
    for parameter in varied:
        others = [c for c in point_columns if c != parameter and len(np.unique(table[c])) > 1]
        path = folder / f"metrics_vs_{parameter}.png"
        jobs.append((path, functools.partial(metrics_against, table, parameter, others[0] if others else None, path)))
    path = folder / "trade_off.png"
    jobs.append((path, functools.partial(trade_off, table, point_columns, path)))
    ok = np.asarray(table["status"]) == "ok"
    if np.isfinite(np.asarray(table["battery_energy_j"], dtype=float)[ok]).any():
        bands = operator_bands(table, point_columns)
        designs = design_columns(point_columns)
        axes = [c for c in designs if c in varied]
        if axes:
            path = folder / "battery_energy.png"
            parameter = "piston_diameter_m" if "piston_diameter_m" in axes else axes[0]
            jobs.append((path, functools.partial(battery_energy, bands, parameter, path)))
        path = folder / "energy_breakdown.png"
        jobs.append((path, functools.partial(energy_breakdown, bands, designs, path)))
    return jobs
