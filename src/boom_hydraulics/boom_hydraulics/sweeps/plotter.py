"""The process that draws a sweep's plots: forked as the sweep starts, it loads matplotlib while
the sweep plans and loads its kernel (Python on one core, which leaves the other idle), then
waits for the results table and draws (sweeps.plots.plot_all, half in a child of its own)."""

from __future__ import annotations

import contextlib
import gc
import os
import pickle
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from ..programs import Forked, can_fork


class Plotter:
    """The plots of a sweep, drawn by a child forked now, before the batches (:func:`start`).
    :meth:`draw` hands it the table, and it draws while this process writes the results, the
    operators' table and the recommendation; :meth:`wait` returns the names of the plots it
    wrote, or raises what stopped it (a child killed meanwhile, by the system out of memory:
    one line). :meth:`stop` ends it (this process failed or was stopped): what it was writing
    is not kept; plots it finished stay, whole."""

    def __init__(self) -> None:
        read, write = os.pipe()
        try:
            self._forked = Forked(lambda: _drawn(read, write))
        except BaseException:
            os.close(read)
            os.close(write)
            raise
        self._table: int | None = write
        try:
            os.close(read)
        except BaseException:  # (a stop that lands here: the caller never gets hold of this one)
            self.stop()
            raise

    def draw(self, table: Mapping[str, np.ndarray], point_columns: Sequence[str], folder: Path) -> None:
        """Hand ``table`` to the child, which draws its plots into ``folder`` now
        (plots.plot_all). A child that ended before it (it failed to load matplotlib) says why
        at :meth:`wait`."""
        write, self._table = self._table, None
        if write is None:
            raise RuntimeError("Plotter.draw: the table was handed over already")
        with contextlib.suppress(BrokenPipeError), open(write, "wb") as stream:
            # (without the reasons of failed points, text the plots do not read: up to a kB a point)
            plotted = {name: column for name, column in table.items() if name != "reason"}
            pickle.dump((plotted, tuple(point_columns), folder), stream, protocol=pickle.HIGHEST_PROTOCOL)

    def wait(self) -> list[str]:
        """The names of the plots the child wrote, once it is done; its failure raised here
        (programs.Forked.wait)."""
        return list(self._forked.wait() or [])

    def stop(self) -> None:
        """End the child now, unless it is done: without a table it draws nothing."""
        if self._table is not None:
            with contextlib.suppress(OSError):
                os.close(self._table)
            self._table = None
        self._forked.stop()


def start() -> Plotter | None:
    """A :class:`Plotter`, where this process may fork (programs.can_fork; a fork the system
    refuses: None), else None: the caller draws the plots itself, after the batches."""
    if not can_fork():
        return None
    try:
        return Plotter()
    except OSError:
        return None


def _drawn(read: int, write: int) -> list[str]:
    """The child's work: load matplotlib, wait for the table (and its point columns and folder)
    on ``read``, draw every plot; the names of the files written. Without a table (the parent
    stopped first), nothing."""
    os.close(write)  # (this end is the parent's: the child sees the end of the table once it closes it)
    from . import plots

    with open(read, "rb") as stream:
        try:
            table, columns, folder = pickle.load(stream)
        except EOFError:
            return []
    gc.freeze()  # what is here now (the parent's heap, matplotlib's modules) out of the collector's walks
    return [path.name for path in plots.plot_all(table, columns, folder)]
