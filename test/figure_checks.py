"""What a reader of a figure notices, measured on the drawn figure: a title cut off at the
figure's edge, tick labels written over each other, names in code."""

from __future__ import annotations

import itertools
import re

from matplotlib.figure import Figure

#: A name as the code spells it: words joined by underscores (pump_controlled, valve_loss_j).
CODE_NAME = re.compile(r"[a-z0-9]+_[a-z0-9_]+")


def drawn(fig: Figure):
    """``fig`` drawn as it is written (its layout done), unless it is drawn already since it
    last changed; its renderer."""
    if fig.stale:
        fig.canvas.draw()
    return fig.canvas.get_renderer()


def titles(fig: Figure) -> list:
    """The figure's suptitle and its axes' titles that have text."""
    texts = [fig._suptitle] if fig._suptitle is not None else []
    for ax in fig.axes:
        texts += [t for t in (ax.title, ax._left_title, ax._right_title) if t.get_text()]
    return [t for t in texts if t.get_text()]


def cut_titles(fig: Figure) -> list[str]:
    """The titles that reach beyond the figure's edges."""
    renderer = drawn(fig)
    whole = fig.bbox
    cut = []
    for text in titles(fig):
        box = text.get_window_extent(renderer)
        if box.x0 < whole.x0 - 1 or box.x1 > whole.x1 + 1 or box.y1 > whole.y1 + 1 or box.y0 < whole.y0 - 1:
            cut.append(text.get_text())
    return cut


def overlapping_tick_labels(fig: Figure) -> list[tuple[str, str]]:
    """Pairs of x tick labels of one axes whose drawn boxes overlap."""
    renderer = drawn(fig)
    pairs = []
    for ax in fig.axes:
        shown = [t for t in ax.get_xticklabels() if t.get_visible() and t.get_text()]
        boxes = [(t.get_text(), t.get_window_extent(renderer)) for t in shown]
        for (a, box_a), (b, box_b) in itertools.combinations(boxes, 2):
            if box_a.overlaps(box_b):
                pairs.append((a, b))
    return pairs


def overlapping_axis_labels(fig: Figure) -> list[tuple[str, str]]:
    """Pairs of axis labels (of any axes) whose drawn boxes overlap."""
    renderer = drawn(fig)
    labels = []
    for ax in fig.axes:
        labels += [a.label for a in (ax.xaxis, ax.yaxis) if a.label.get_text()]
    boxes = [(t.get_text(), t.get_window_extent(renderer)) for t in labels]
    return [(a, b) for (a, box_a), (b, box_b) in itertools.combinations(boxes, 2) if box_a.overlaps(box_b)]


def legend_texts(fig: Figure) -> list[str]:
    """Every legend's entries, the figure's and its axes'."""
    legends = list(fig.legends) + [ax.get_legend() for ax in fig.axes if ax.get_legend() is not None]
    return [t.get_text() for legend in legends for t in legend.get_texts()]


def code_names(texts) -> list[str]:
    """Of ``texts``, those that hold a name as the code spells it."""
    return [t for t in texts if CODE_NAME.search(t)]
