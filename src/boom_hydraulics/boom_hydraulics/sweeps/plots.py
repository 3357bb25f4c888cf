"""PNG plots of a sweep table: each metric against each varied parameter, the trade-off front,
and the battery's energy per cycle and where it goes."""

from __future__ import annotations

import contextlib
import functools
import gc
from collections.abc import Callable, Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any, NamedTuple

import matplotlib

matplotlib.use("Agg")  # files only, no display
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.lines import Line2D
from matplotlib.ticker import FuncFormatter, MaxNLocator

from ..analysis import labels, layout
from ..analysis.plots import energy_breakdown_figure
from ..files import atomic_path
from ..programs import Forked, can_fork
from .energy import BREAKDOWN, PERCENTILES, best_per_drive, design_columns, operator_bands, qualifying_designs
from .recommend import TRADE_OFF, trade_off_front

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


#: A design's spot, its diameter in pt: filled, without an edge (about as large as scatter's
#: default spot with its edge).
SPOT = 4.5

#: Colour bands of a numeric colouring: at most this many, between round values; a parameter
#: with this many values or fewer has a band (a colour) for each. The spots of a band are one
#: line of markers, whose marker Agg draws once and stamps at every spot: a 12-panel figure of
#: 10 000 designs took 0.5 s so, against 0.84 s with a colour for each spot (scatter, whose
#: every spot Agg draws as a path of its own).
BANDS = 10

#: The bands' colours, low to high.
COLOUR_MAP = "viridis"


#: Intervals between a metrics panel's ticks, at most: its 24 axes made 214 ticks by default,
#: each five artists (tick marks, grid line, labels), 0.4 s of the figure's 0.67 s (cProfile).
TICKS = 4

#: Categories a row of a metrics figure's key holds.
KEY_COLUMNS = 6


def _save(fig, path: Path) -> None:
    """The figure as PNG at ``path``, whole or not at all (an interrupted plot leaves the old one)."""
    with atomic_path(path, suffix=".png") as tmp:
        # zlib's fastest level: 0.036 s a 1500 x 950 figure, against 0.056 s at PIL's default
        # (6), for a file 10 % larger
        fig.savefig(tmp, dpi=100, format="png", pil_kwargs={"compress_level": 1})


def _numeric(column: np.ndarray) -> bool:
    return np.asarray(column).dtype.kind in "fiu"


def metrics_against(table: Mapping[str, np.ndarray], parameter: str, color_by: str | None, path: Path) -> None:
    """:func:`metrics_figure` as a PNG at ``path``."""
    fig = metrics_figure(table, parameter, color_by)
    _save(fig, path)
    plt.close(fig)


def metrics_figure(table: Mapping[str, np.ndarray], parameter: str, color_by: str | None):
    """A panel per metric of :data:`PLOTTED` against ``parameter`` (in its shown unit,
    labels.quantity); ok designs coloured by ``color_by`` (numeric: bands and a colour bar in
    its shown unit; categorical: a colour each, named in words in a key under the title), the
    others grey crosses."""
    xlabel, xscale = labels.quantity(parameter)
    x = np.asarray(table[parameter], dtype=float) * xscale
    ok = np.asarray(table["status"]) == "ok"
    fig, axes = plt.subplots(3, 4, figsize=(15, 9.5))
    colouring = _colours(table, color_by, ok)
    bar = colouring.norm is not None
    # a fixed layout, with room for the labels of these panels: constrained layout measured
    # every tick label of the 12 panels, 0.35-0.4 s of a figure's 1.2 s
    key = dict(colouring.key or {})
    if key and not ok.all():
        key[NOT_OK] = "0.7"
    rows = _key(fig, key)  # a key to categories goes in rows under the title
    top = max(0.5, 0.935 - 0.03 * rows)
    fig.subplots_adjust(left=0.05, right=0.895 if bar else 0.985, bottom=0.06, top=top, wspace=0.32, hspace=0.3)
    for ax, (name, label, scale) in zip(axes.flat, PLOTTED):
        y = np.asarray(table[name], dtype=float) * scale
        ax.plot(x[~ok], y[~ok], "x", markersize=3.2, markeredgewidth=0.8, color="0.7", label=NOT_OK)
        _spots(ax, x[ok], y[ok], colouring.groups)
        ax.set_xlabel(xlabel)
        ax.set_ylabel(label)
        ax.locator_params(nbins=TICKS)
        ax.grid(True, alpha=0.3)
    if bar:
        bar_axes = fig.add_axes((0.915, 0.25, 0.012, 0.5))
        colouring.colour_bar(fig, labels.quantity(color_by).label if color_by else None, cax=bar_axes)
    coloured = f" coloured by {_words(color_by)}" if color_by else ""
    title = fig.suptitle(
        f"Design metrics against {_words(parameter)}: {int(ok.sum())} ok designs{coloured}, "
        f"{int((~ok).sum())} not ok (x)"
    )
    layout.fit_title(fig, title)
    return fig


#: The key's name for the designs that did not run ok (grey crosses).
NOT_OK = "not ok (incomplete or failed)"


def _words(column: str) -> str:
    """A column's name in words, without its unit (labels.quantity)."""
    label = labels.quantity(column).label
    return label[: label.rfind(" [")] if label.endswith("]") else label


def _key(fig, key: Mapping[Any, Any] | None) -> int:
    """The key to categories (a drive, a config: which colour is which) in a row under the
    title, in as many columns as fit the figure's width (at most KEY_COLUMNS); its rows."""
    if not key:
        return 0
    spots = [
        Line2D([], [], linestyle="", marker="x" if name == NOT_OK else "o", color=c, label=str(name))
        for name, c in key.items()
    ]
    renderer = fig.canvas.get_renderer()
    for columns in range(min(len(spots), KEY_COLUMNS), 0, -1):
        legend = fig.legend(handles=spots, loc="upper center", bbox_to_anchor=(0.5, 0.96), ncols=columns)
        if columns == 1 or legend.get_window_extent(renderer).width <= 0.98 * fig.bbox.width:
            return -(-len(spots) // columns)
        legend.remove()
    return len(spots)


class Colouring(NamedTuple):
    """How a figure colours its ok designs: ``groups``, [(their rows among the ok designs, a
    colour)]; for numbers, the colour bar's ``norm`` (a BoundaryNorm of the bands) and
    ``ticks`` (None: at the bands' edges); for categories, ``key``, {category in words: colour}."""

    groups: list[tuple[np.ndarray, Any]]
    norm: matplotlib.colors.BoundaryNorm | None = None
    ticks: np.ndarray | None = None
    key: Mapping[Any, Any] | None = None

    def colour_bar(self, fig, label: str | None, **where: Any) -> None:
        """The bands' colour bar in ``fig``, placed by ``where`` (colorbar's ``cax`` or ``ax``);
        ticks at the values to 3 significant digits (36.9, not 36.86)."""
        mapper = plt.cm.ScalarMappable(norm=self.norm, cmap=COLOUR_MAP)
        short = None if self.ticks is None else FuncFormatter(lambda v, _: _three_digits(v))
        fig.colorbar(mapper, label=label, ticks=self.ticks, format=short, **where)


def _three_digits(value: float) -> str:
    """A number to 3 significant digits, a whole number of 4 or more digits whole (1500)."""
    return f"{value:.0f}" if abs(value) >= 1000 else f"{value:.3g}"


def _colours(table: Mapping[str, np.ndarray], color_by: str | None, ok: np.ndarray) -> Colouring:
    """The colours of the ok designs by ``color_by``: one for all without it, a band's colour of
    viridis for a number (:func:`bands`), a colour of tab10 (tab20) for each category."""
    everyone = np.arange(int(ok.sum()))
    if color_by is None:
        return Colouring([(everyone, "tab:blue")])
    values = np.asarray(table[color_by])[ok]
    if _numeric(values):
        return banded(values.astype(float) * labels.quantity(color_by).scale)
    categories = _in_order(color_by, values)
    palette = plt.get_cmap("tab10" if len(categories) <= 10 else "tab20")  # (beyond 20, colours repeat)
    colours = {category: palette(k % palette.N) for k, category in enumerate(categories)}
    key = {labels.value_words(color_by, category): colours[category] for category in categories}
    return Colouring([(everyone[values == category], colours[category]) for category in categories], key=key)


def _in_order(column: str, values: np.ndarray) -> list[Any]:
    """The categories of ``values``: drives in parameters.DRIVES' order (each its colour in
    every plot of a sweep), others sorted."""
    present = set(values.tolist())
    if column == "drive":
        known = [d for d in labels.DRIVE_WORDS if d in present]
        return known + sorted(present - set(known))
    return sorted(present)


def bands(values: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
    """The edges of the colour bands of ``values`` (their finite ones), ascending, and the colour
    bar's ticks: a band around each distinct value where there are at most :data:`BANDS` (the
    edges half-way between them, the ticks at the values), else at most :data:`BANDS` bands
    between round values that hold them all (the ticks at the edges: None)."""
    distinct = np.unique(values[np.isfinite(values)])
    if len(distinct) > 1:  # values a rounding apart (0.3 and 0.1 * 3) are one: a band has a width
        apart = np.diff(distinct) > 1e-9 * np.abs(distinct).max()
        distinct = distinct[np.concatenate([[True], apart])]
    if len(distinct) <= 1:
        middle = float(distinct[0]) if len(distinct) else 0.0
        half = 0.5 * abs(middle) if middle else 0.5
        return np.array([middle - half, middle + half]), distinct
    if len(distinct) <= BANDS:
        between = 0.5 * (distinct[1:] + distinct[:-1])
        first, last = 2.0 * distinct[0] - between[0], 2.0 * distinct[-1] - between[-1]
        return np.concatenate([[first], between, [last]]), distinct
    low, high = float(distinct[0]), float(distinct[-1])
    for most in range(BANDS, 0, -1):  # (round edges that hold the values may take one band more)
        edges = MaxNLocator(nbins=most).tick_values(low, high)
        first = np.searchsorted(edges, low, side="right") - 1  # the last edge at or below the lowest value
        last = np.searchsorted(edges, high, side="left")  # the first at or above the highest
        edges = edges[max(first, 0) : last + 1]
        if len(edges) <= BANDS + 1:
            break
    return edges, None


def banded(values: np.ndarray) -> Colouring:
    """``values`` coloured by :func:`bands` in viridis; a value that is not finite is not drawn
    (as scatter draws it)."""
    edges, ticks = bands(values)
    viridis = plt.get_cmap(COLOUR_MAP)
    norm = matplotlib.colors.BoundaryNorm(edges, viridis.N)
    band = np.clip(np.searchsorted(edges, values, side="right") - 1, 0, len(edges) - 2)
    rows = np.arange(len(values))
    finite = np.isfinite(values)
    groups = [
        (rows[finite & (band == k)], viridis(norm(0.5 * (edges[k] + edges[k + 1])))) for k in range(len(edges) - 1)
    ]
    return Colouring([(r, colour) for r, colour in groups if len(r)], norm, ticks)


def _spots(ax, x: np.ndarray, y: np.ndarray, groups: Sequence[tuple[np.ndarray, Any]]) -> None:
    """A spot at each (x, y), each group's in its colour (a line of markers per group)."""
    for rows, colour in groups:
        ax.plot(x[rows], y[rows], linestyle="none", marker="o", markersize=SPOT, markeredgewidth=0, color=colour)


def trade_off(table: Mapping[str, np.ndarray], label_columns: Sequence[str], path: Path) -> None:
    """:func:`trade_off_figure` as a PNG at ``path``."""
    fig = trade_off_figure(table, label_columns)
    _save(fig, path)
    plt.close(fig)


def trade_off_figure(table: Mapping[str, np.ndarray], label_columns: Sequence[str]):
    """Lift time against lift energy and against peak pressure; the front of all three ringed.
    With a categorical column among ``label_columns`` (the drive, else a config) the designs
    are coloured by it, with a key in words; else each panel by the third metric, in bands. A few
    front designs are named by their other values, with units, where the names do not
    overlap."""
    ok = np.asarray(table["status"]) == "ok"
    front = trade_off_front(table)
    time_s, energy_kj, pressure_mpa = (
        np.asarray(table[m], dtype=float) * s for m, s in zip(TRADE_OFF, (1.0, 1e-3, 1e-6))
    )
    categories = [c for c in label_columns if not _numeric(table[c]) and len(np.unique(table[c])) > 1]
    by = "drive" if "drive" in categories else (categories[0] if categories else None)
    fig, (left, right) = plt.subplots(1, 2, figsize=(13, 5.5))
    # a fixed layout (constrained layout drew the figure twice: 0.27 s of its 0.75 s)
    fig.subplots_adjust(left=0.055, right=0.985, bottom=0.1, top=0.86 if by is None else 0.8, wspace=0.2)
    panels = ((left, energy_kj, "lift energy [kJ]", pressure_mpa, "peak pressure [MPa]"),
              (right, pressure_mpa, "peak pressure [MPa]", energy_kj, "lift energy [kJ]"))  # fmt: skip
    for ax, y, ylabel, colour, clabel in panels:
        colouring = _colours(table, by, ok) if by is not None else banded(colour[ok])
        _spots(ax, time_s[ok], y[ok], colouring.groups)
        ax.scatter(time_s[front], y[front], s=70, facecolors="none", edgecolors="tab:red", label="non-dominated")
        if colouring.norm is not None:
            colouring.colour_bar(fig, clabel, ax=ax)
        ax.set_xlabel("lift time [s]")
        ax.set_ylabel(ylabel)
        ax.grid(True, alpha=0.3)
        ax.legend(loc="best", fontsize="small")
    if by is not None:
        fig.legend(
            handles=[Line2D([], [], linestyle="", marker="o", color=c, label=n) for n, c in colouring.key.items()],
            loc="upper center",
            bbox_to_anchor=(0.5, 0.935),
            ncols=len(colouring.key),
        )
    named = [c for c in label_columns if c != "operator" and c != by and len(np.unique(table[c])) > 1]
    if named:  # name a few front designs by their values, where the names leave each other room
        texts = []
        for row in np.nonzero(front)[0][:12]:
            text = ", ".join(labels.value_with_unit(c, table[c][row]) for c in named)
            texts.append(
                left.annotate(
                    text, (time_s[row], energy_kj[row]), fontsize=7, xytext=(4, 4), textcoords="offset points"
                )
            )
        _apart(fig, texts)
        left.set_title(f"front designs named by {', '.join(_words(c) for c in named)}", fontsize="small")
    title = fig.suptitle(
        f"Trade-off: {int(front.sum())} non-dominated of {int(ok.sum())} ok designs "
        "(lower lift time, energy and peak pressure are better)"
    )
    layout.fit_title(fig, title)
    return fig


def _apart(fig, texts: Sequence[Any]) -> None:
    """Of ``texts`` (annotations), those that overlap one before them removed."""
    renderer = fig.canvas.get_renderer()
    kept: list[Any] = []
    for text in texts:
        box = text.get_window_extent(renderer)
        if any(box.overlaps(other) for other in kept):
            text.remove()
        else:
            kept.append(box)


def battery_energy(bands: Mapping[str, np.ndarray], parameter: str, design_columns: Sequence[str], path: Path) -> None:
    """:func:`battery_energy_figure` as a PNG at ``path``."""
    fig = battery_energy_figure(bands, parameter, design_columns)
    _save(fig, path)
    plt.close(fig)


#: Line styles that tell apart the lines of one drive (one per value of the other design axes).
LINE_STYLES = ("-", "--", ":", "-.")


def battery_energy_figure(bands: Mapping[str, np.ndarray], parameter: str, design_columns: Sequence[str] = ()):
    """Battery energy per cycle against ``parameter`` (in its shown unit): a line per drive and
    value of the other design axes, named in words with units (the median over the operators'
    cycles, their 10th-90th percentile shaded), from :func:`energy.operator_bands`. Each drive
    in its colour of the metrics plots, its lines told apart by their style; without a drive,
    a colour per line. The energy axis is logarithmic where it spans more than a decade,
    labelled at 1, 2 and 5 of each."""
    xlabel, xscale = labels.quantity(parameter)
    x = np.asarray(bands[parameter], dtype=float) * xscale
    n = len(x)
    drives = np.asarray(bands["drive"]) if "drive" in bands else np.array([""] * n)
    others = [c for c in design_columns if c not in (parameter, "drive") and len(np.unique(bands[c])) > 1]
    fig, ax = plt.subplots(figsize=(8, 5.5))
    fig.subplots_adjust(left=0.09, right=0.97, bottom=0.1, top=0.88)  # (a fixed layout: drawn once)
    lines: dict[tuple[Any, ...], list[int]] = {}
    for row in range(n):
        lines.setdefault((drives[row], *(bands[c][row] for c in others)), []).append(row)
    if "drive" in bands:
        key = _colours({"drive": drives}, "drive", np.ones(n, bool)).key or {}
        colours = [key[labels.drive_words(line[0])] for line in lines]
    else:
        palette = plt.get_cmap("tab10" if len(lines) <= 10 else "viridis")
        colours = [palette(k if len(lines) <= 10 else k / max(len(lines) - 1, 1)) for k in range(len(lines))]
    styles: dict[Any, int] = {}
    for (line, rows), colour in zip(lines.items(), colours):
        rows = np.array(rows)[np.argsort(x[rows], kind="stable")]
        nth = styles.setdefault(line[0], 0)  # (the drive's nth line)
        styles[line[0]] += 1
        style = LINE_STYLES[nth % len(LINE_STYLES)] if "drive" in bands else "-"
        words = [labels.drive_words(line[0])] if line[0] else []
        words += [labels.value_with_unit(c, v) for c, v in zip(others, line[1:])]
        low, mid, high = (np.asarray(bands[f"battery_energy_j_p{q}"], float)[rows] * 1e-3 for q in PERCENTILES)
        label = ", ".join(words) or "battery energy"
        ax.plot(x[rows], mid, style, marker="o", markersize=3, color=colour, label=label)
        ax.fill_between(x[rows], low, high, color=colour, alpha=0.2)
    ax.set_xlabel(xlabel)
    ax.set_ylabel("battery energy per cycle [kJ]")
    low, high = ax.get_ylim()
    if low > 0 and high > 10 * low:  # (within a decade a logarithmic axis has too few ticks to read)
        ax.set_yscale("log")
        ax.yaxis.set_major_formatter(FuncFormatter(_log_label))
        ax.yaxis.set_minor_formatter(FuncFormatter(_log_label))
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(loc="best", fontsize="small", title="drive" if "drive" in bands and not others else None)
    cycles = int(np.max(bands["cycles"])) if len(bands["cycles"]) else 0
    band = f"median of {cycles} cycles, 10th-90th percentile shaded" if cycles > 1 else "one cycle per design"
    title = fig.suptitle(f"Battery energy per cycle: {band}")
    layout.fit_title(fig, title)
    return fig


def _log_label(value: float, _: Any = None) -> str:
    """A logarithmic axis' tick label at 1, 2 and 5 of each decade ("20", "0.5"), none between."""
    if value <= 0:
        return ""
    mantissa = value / 10 ** np.floor(np.log10(value) + 1e-9)
    return f"{value:g}" if any(abs(mantissa - m) < 1e-6 for m in (1.0, 2.0, 5.0)) else ""


def energy_breakdown(
    bands: Mapping[str, np.ndarray], design_columns: Sequence[str], qualifies: np.ndarray | None, path: Path
) -> None:
    """Where the battery's energy goes, a stacked bar for each drive at its best design (the
    least median battery energy per cycle, of its designs that qualify: ``qualifies``, per row
    of ``bands``; a drive none of whose designs does has no bar): the lift's work and every
    loss and work term of the ledger (in words), averaged over its cycles; the energy it took
    back is drawn below zero. Each bar is named by its drive in words and its design's values
    with units."""
    bars = _breakdown_bars(bands, design_columns, qualifies)
    fig = energy_breakdown_figure(bars, breakdown_title("drive" in bands))
    _save(fig, path)
    plt.close(fig)


def breakdown_title(drives: bool) -> str:
    """The breakdown's title, of a sweep with a drive axis or without one."""
    which = "each drive at its best design" if drives else "the best design"
    return (
        f"Where the battery's energy goes, {which} (mean over its cycles; "
        "above each bar the median battery energy per cycle)"
    )


def _breakdown_bars(
    bands: Mapping[str, np.ndarray], design_columns: Sequence[str], qualifies: np.ndarray | None = None
) -> list[tuple[str, dict[str, float], float]]:
    """The bars of :func:`energy_breakdown`: (name, energies J by the ledger's names, median
    battery energy J) for each drive's best design (of those that qualify, see best_per_drive)."""
    bars = []
    for drive, row in best_per_drive(bands, qualifies).items():
        if row is None:
            continue
        energies = {name.removesuffix("_j"): float(bands[name][row]) for name in BREAKDOWN}
        where = "\n".join(labels.value_with_unit(c, bands[c][row]) for c in design_columns if c != "drive")
        name = labels.drive_words(drive) if drive else "best design"
        bars.append((f"{name}\n{where}" if where else name, energies, float(bands["battery_energy_j_p50"][row])))
    return bars


def plot_all(table: Mapping[str, np.ndarray], point_columns: Sequence[str], folder: Path) -> list[Path]:
    """Every sweep plot into ``folder``; returns the files written: with the battery (physical
    mode), also the battery energy per cycle and its breakdown. Where it can fork
    (programs.can_fork), a child process draws some of them meanwhile, about half the work
    each (:data:`Plot`'s estimates): a figure is up to half a second of Python, on one core. A
    failure here stops the child; plots it finished before that stay, whole."""
    plots = _plots(table, point_columns, folder)
    mine, theirs = _shared(plots)
    forked = None
    with _seldom_collected():
        try:
            if theirs and can_fork():
                with contextlib.suppress(OSError):  # (a fork the system refuses: all of them here)
                    forked = Forked(lambda: _draw(theirs))
            _draw(mine if forked is not None else plots)
            if forked is not None:
                forked.wait()
        except BaseException:
            if forked is not None:
                forked.stop()
            raise
    return [plot.path for plot in plots]


class Plot(NamedTuple):
    """A plot of :func:`plot_all`: its file, what draws it, and about how long that takes, s
    (measured for 10 000 designs on a 2-core AMD EPYC; what counts is their ratios)."""

    path: Path
    draw: Callable[[], None]
    seconds: float


def _shared(plots: Sequence[Plot]) -> tuple[list[Plot], list[Plot]]:
    """``plots`` in two shares of about the same time, the longest first to the lesser share:
    this process's and a child's."""
    shares: tuple[list[Plot], list[Plot]] = ([], [])
    for plot in sorted(plots, key=lambda p: -p.seconds):
        lesser = min(shares, key=lambda share: sum(p.seconds for p in share))
        lesser.append(plot)
    return shares


@contextlib.contextmanager
def _seldom_collected(young: int = 50_000) -> Iterator[None]:
    """The garbage collector's youngest generation collected once ``young`` objects (not 700)
    were made, while the figures are drawn: matplotlib makes tens of thousands of small objects
    a figure, and the collections their count set off took 0.1-0.6 s of a 10 000-point sweep's
    five figures (1.6-1.8 s; gc.callbacks), against 0.02-0.03 s so."""
    before = gc.get_threshold()
    gc.set_threshold(young, *before[1:])
    try:
        yield
    finally:
        gc.set_threshold(*before)


def _draw(plots: Sequence[Plot]) -> None:
    for plot in plots:
        plot.draw()


def colour_column(table: Mapping[str, np.ndarray], others: Sequence[str]) -> str | None:
    """What a metrics plot colours its designs by, of the varied columns ``others`` (all but
    its x axis): the drive, else another category (a config), else the first axis the user
    varied, the operators' seed last (it tells cycles apart, not designs); None without any."""
    categorical = [c for c in others if not _numeric(table[c])]
    if "drive" in others:
        return "drive"
    if categorical:
        return categorical[0]
    designs = [c for c in others if c != "operator"]
    return (designs or list(others) or [None])[0]


def _plots(table: Mapping[str, np.ndarray], point_columns: Sequence[str], folder: Path) -> list[Plot]:
    """The plots of :func:`plot_all`, in their order."""

    def plot(name: str, seconds: float, draw: Callable[..., None], *args: Any) -> Plot:
        path = folder / name
        return Plot(path, functools.partial(draw, *args, path), seconds)

    plots = []
    varied = [c for c in point_columns if _numeric(table[c]) and len(np.unique(table[c])) > 1]
    for parameter in varied:
        others = [c for c in point_columns if c != parameter and len(np.unique(table[c])) > 1]
        colour = colour_column(table, others)
        plots.append(plot(f"metrics_vs_{parameter}.png", 0.4, metrics_against, table, parameter, colour))
    plots.append(plot("trade_off.png", 0.2, trade_off, table, point_columns))
    ok = np.asarray(table["status"]) == "ok"
    if np.isfinite(np.asarray(table["battery_energy_j"], dtype=float)[ok]).any():
        bands = operator_bands(table, point_columns)
        designs = design_columns(point_columns)
        axes = [c for c in designs if c in varied]
        if axes:
            parameter = "piston_diameter_m" if "piston_diameter_m" in axes else axes[0]
            plots.append(plot("battery_energy.png", 0.1, battery_energy, bands, parameter, designs))
        qualifies = (
            qualifying_designs(table, point_columns, np.asarray(table["qualifies"], dtype=bool))
            if "qualifies" in table
            else None
        )
        plots.append(plot("energy_breakdown.png", 0.13, energy_breakdown, bands, designs, qualifies))
    return plots
