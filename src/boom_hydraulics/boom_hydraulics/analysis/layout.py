"""Text that fits a figure: a title wrapped onto as many lines as keep it inside the figure,
and a row of tick labels broken onto lines, or turned, until no two overlap."""

from __future__ import annotations

import re
import textwrap
from collections.abc import Sequence

from matplotlib.figure import Figure
from matplotlib.text import Text
from matplotlib.transforms import Bbox

#: The share of the figure's width a title may take.
TITLE_WIDTH = 0.96
#: Space kept between two neighbouring tick labels, pixels.
GAP_PX = 4.0
#: The angle tick labels are turned to when breaking them onto lines is not enough, degrees.
TURNED_DEG = 30.0


def _renderer(fig: Figure):
    return fig.canvas.get_renderer()


def fit_title(fig: Figure, title: Text) -> None:
    """``title`` (a suptitle, or an axes' title) wrapped at its spaces onto the fewest lines
    that keep it within :data:`TITLE_WIDTH` of ``fig``'s width (a word longer than that stays
    whole)."""
    text = " ".join(title.get_text().split())
    limit = TITLE_WIDTH * fig.bbox.width
    renderer = _renderer(fig)
    for width in range(len(text), 0, -1):
        title.set_text(textwrap.fill(text, width, break_long_words=False, break_on_hyphens=False))
        if title.get_window_extent(renderer).width <= limit:
            return


def inside(fig: Figure, box: Bbox) -> bool:
    """Whether ``box`` (display pixels) lies within ``fig``'s (a pixel's rounding aside)."""
    whole = fig.bbox
    return box.x0 >= whole.x0 - 1 and box.x1 <= whole.x1 + 1 and box.y0 >= whole.y0 - 1 and box.y1 <= whole.y1 + 1


def overlapping(boxes: Sequence[Bbox], gap_px: float = 0.0) -> bool:
    """Whether any two of ``boxes`` (a row of labels, display pixels) come closer than
    ``gap_px`` side by side where they share a height."""
    ordered = sorted((b for b in boxes if b.width > 0), key=lambda b: b.x0)
    for k, left in enumerate(ordered):
        for right in ordered[k + 1 :]:
            if right.x0 >= left.x1 + gap_px:
                break
            if right.y0 < left.y1 and left.y0 < right.y1:
                return True
    return False


def broken(text: str, width: int) -> str:
    """``text`` onto lines of at most ``width`` characters where it can break: at its spaces,
    or after an underscore or a hyphen (a file's or a bag's name)."""
    lines: list[str] = []
    for line in text.split("\n"):
        parts = [p for p in re.split(r"(?<=[ _-])", line) if p]
        current = ""
        for part in parts:
            if current and len(current.rstrip()) + len(part.rstrip()) > width:
                lines.append(current.rstrip())
                current = part
            else:
                current += part
        lines.append(current.rstrip())
    return "\n".join(lines)


def tick_labels_apart(fig: Figure, ax, texts: Sequence[str]) -> None:
    """``texts`` as ``ax``'s x tick labels (at its ticks), broken onto shorter lines until no
    two overlap; turned by :data:`TURNED_DEG` if even lines of 8 characters overlap."""
    renderer = _renderer(fig)
    longest = max((len(line) for text in texts for line in text.split("\n")), default=0)
    for width in range(longest, 7, -1):
        labels = ax.set_xticklabels([broken(text, width) for text in texts])
        if not overlapping([label.get_window_extent(renderer) for label in labels], GAP_PX):
            return
    labels = ax.set_xticklabels([broken(text, 24) for text in texts])
    for label in labels:
        label.set_rotation(TURNED_DEG)
        label.set_horizontalalignment("right")
        label.set_rotation_mode("anchor")
