"""A sweep's folder on disk: what was asked, and each finished batch as soon as it finishes.

    OUT/sweep.json            the request (configs, axes, sample, scenario, ...)
    OUT/batches/00012.npz     the table rows of batch 12, written once it is done

A batch file appears whole or not at all (written beside, then renamed), so an
interrupted sweep keeps every batch it finished and a resumed one redoes none of them.

OUT may hold other files (``--out .`` is fine): the sweep reads and writes only its own
names there (:data:`OUTPUTS`, ``metrics_vs_<parameter>.png``, ``batches/``), and refuses a
folder where one of them exists without a ``sweep.json`` saying it is a sweep's, so that
nobody's file of the same name is replaced. A killed sweep (SIGKILL, power loss) can leave
hidden temporaries of those names (``.results.csv.x1y2z3w4.partial``); the next run in the
folder removes them, and only them.
"""

from __future__ import annotations

import json
import os
import re
import sys
import zipfile
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import BoomHydraulicsError, ConfigError
from ..files import process_alive, write_bytes, write_npz

MANIFEST = "sweep.json"
BATCHES = "batches"
FORMAT = 1

#: The files a sweep writes into OUT besides its plots against each parameter.
OUTPUTS = (
    MANIFEST,
    "results.csv",
    "results.npz",
    "trade_off.png",
    "battery_energy.png",
    "energy_breakdown.png",
    "operators.csv",
    "operators.npz",
    "recommendation.txt",
    "recommendation.csv",
    "recommendation.npz",
)

#: The temporary name files.atomic_path gives a file NAME while it is being written:
#: ``.NAME.`` + the writer's process id + ``-`` + mkstemp's random characters + ``.partial`` + the kept ending.
_TEMPORARY = r"\.(?P<name>{names})\.(?P<pid>[0-9]+)-[A-Za-z0-9_]+\.partial(\.npz|\.png)?"


def plot_names(columns: Iterable[str]) -> list[str]:
    """The plots a sweep over ``columns`` may write (sweeps.plots.plot_all)."""
    return [f"metrics_vs_{column}.png" for column in columns]


def _normal(request: dict[str, Any]) -> Any:
    """The request as it reads back from JSON (tuples become lists)."""
    return json.loads(json.dumps(request))


def read_manifest(folder: Path) -> dict[str, Any] | None:
    """The request stored in ``folder``'s sweep.json; None if there is no sweep.json.

    Raises BoomHydraulicsError (exit 1) if sweep.json is there but is not one this tool
    wrote: without it the stored batches cannot be told to be this sweep's.
    """
    manifest = folder / MANIFEST
    if not manifest.exists():
        return None
    try:
        document = json.loads(manifest.read_text(encoding="utf-8"))
        problem = "" if isinstance(document, dict) else "not a JSON object"
        request = document.get("request") if not problem else None
        if not problem and not (isinstance(request, dict) and isinstance(request.get("batch_size"), int)):
            problem = "it has no request with a batch_size"
    except (OSError, ValueError) as exc:
        problem = str(exc)
    except RecursionError:
        problem = "it is nested deeper than can be read"
    if problem:
        batches = len(_batch_files(folder / BATCHES))
        raise BoomHydraulicsError(
            f"{manifest} is damaged ({problem}), so the {batches} batches stored beside it cannot be matched "
            f"to a sweep; choose another --out (or, to start afresh in {folder}, remove {manifest} and "
            f"{folder / BATCHES} yourself)"
        )
    return request


def _batch_files(folder: Path) -> dict[int, Path]:
    if not folder.is_dir():
        return {}
    return {int(p.stem): p for p in folder.glob("[0-9]*.npz") if p.stem.isdigit()}


def remove_stale_temporaries(folder: Path, names: Sequence[str], ours: bool = False) -> list[Path]:
    """Remove the temporaries that a killed sweep (SIGKILL, a power cut) left of its own files in
    ``folder`` and its ``batches/``: hidden ``.NAME.PID-XXXXXXXX.partial`` files of the sweep's
    ``names`` and of batch files, written by a process that no longer runs; with ``ours``, this
    process's too (a stopped sweep, whose stop may land between a temporary's creation and the
    writer that removes it on failure); nothing else.

    files.atomic_path removes those of a file when it writes that file again; this also finds
    those of files the next run does not write (plots under --no-plots, a recommendation not
    asked for again). Returns what was removed.
    """
    own = re.compile(_TEMPORARY.format(names="|".join(re.escape(n) for n in names)))
    batch = re.compile(_TEMPORARY.format(names=r"[0-9]+\.npz"))
    removed = []
    for where, pattern in ((folder, own), (folder / BATCHES, batch)):
        if not where.is_dir():
            continue
        for path in sorted(where.iterdir()):
            match = pattern.fullmatch(path.name)
            gone = match and (not process_alive(int(match["pid"])) or (ours and int(match["pid"]) == os.getpid()))
            if gone and path.is_file() and not path.is_symlink():
                path.unlink(missing_ok=True)
                removed.append(path)
    return removed


class SweepStore:
    """The folder of one sweep; see the module docstring."""

    def __init__(self, folder: Path, resume: bool, names: Sequence[str] = OUTPUTS) -> None:
        """Open ``folder`` for a sweep that writes ``names`` there: a new sweep, or with ``resume``
        the one begun there before (its request is :attr:`stored`). Nothing is written until the
        first batch is saved, except that a killed run's temporaries of these names are removed.

        Raises ConfigError if the folder holds this or another sweep without ``resume`` (so that
        finished work is never overwritten by accident), or holds a file of one of ``names``
        (or a ``batches`` folder) but no sweep; BoomHydraulicsError if its sweep.json is damaged.
        """
        if folder.exists() and not folder.is_dir():
            raise ConfigError(f"--out {folder} is a file; name a folder for the sweep")
        self.folder = folder
        self.batches = folder / BATCHES
        self.names = tuple(names)
        self.resume = resume
        self.stored = read_manifest(folder)
        if self.stored is not None and not resume:
            raise ConfigError(
                f"{folder} holds a sweep already ({len(self.done())} batches done); pass --resume to finish it "
                "with the same arguments, or choose another --out"
            )
        if self.stored is None:
            taken = [n for n in (*self.names, BATCHES) if (folder / n).exists()]
            if taken:
                raise ConfigError(
                    f"{folder} holds {', '.join(taken)} but no {MANIFEST}, so not a sweep's; the sweep would "
                    "write there: move them, or choose another --out"
                )
        self.removed = remove_stale_temporaries(folder, self.names) if folder.is_dir() else []
        self._manifest: dict[str, Any] | None = None

    def begin(self, request: dict[str, Any]) -> None:
        """Take ``request`` as this folder's sweep. Raises ConfigError if the folder holds another."""
        if self.stored is None:
            self._manifest = {"format": FORMAT, "request": request}
            return
        new = _normal(request)
        if self.stored != new:
            old = self.stored
            differ = sorted(k for k in set(old) | set(new) if old.get(k) != new.get(k))
            raise ConfigError(
                f"{self.folder} holds a different sweep (it differs in: {', '.join(differ)}); "
                "resume with the arguments and config files it was started with, or choose another --out"
            )

    def path(self, index: int) -> Path:
        return self.batches / f"{index:05d}.npz"

    def remove_own_temporaries(self) -> list[Path]:
        """Remove what this process left half-written in the sweep's folder (a stopped sweep)."""
        return remove_stale_temporaries(self.folder, self.names, ours=True) if self.folder.is_dir() else []

    def done(self) -> set[int]:
        """Indices of the batches whose rows are on disk."""
        return set(_batch_files(self.batches))

    def save(self, index: int, rows: dict[str, np.ndarray]) -> None:
        """Store the rows of batch ``index`` (whole or not at all); the first also stores the request."""
        if self._manifest is not None:  # sweep.json first: a folder with batches/ always says whose they are
            write_bytes(self.folder / MANIFEST, (json.dumps(self._manifest, indent=1) + "\n").encode())
            self._manifest = None
            self.batches.mkdir(exist_ok=True)
        write_npz(self.path(index), rows)

    def load(self, index: int, points: Sequence[int], columns: Sequence[str]) -> dict[str, np.ndarray] | None:
        """The rows of batch ``index``, which holds ``points`` in ``columns``; None if its file cannot be
        read (it is kept as ``NNNNN.npz.damaged`` and the batch runs again).

        Raises ConfigError if the file reads but is not that batch's (another sweep's batch, say):
        it is not ours to replace, and this sweep cannot use it.
        """
        path = self.path(index)
        try:
            with np.load(path) as data:
                rows = {name: data[name] for name in data.files}
        except (OSError, ValueError, EOFError, zipfile.BadZipFile) as exc:
            kept = path.with_name(path.name + ".damaged")
            os.replace(path, kept)
            print(f"boom-sweep: warning: {path} is unreadable ({exc}); kept as {kept.name}, computing it again",
                  file=sys.stderr)  # fmt: skip
            return None
        missing = [c for c in columns if c not in rows]
        held = rows.get("point")
        if missing or held is None or not np.array_equal(np.asarray(held), np.asarray(points)):
            what = f"lacks {', '.join(missing)}" if missing else f"holds points {_span(held)}, not {_span(points)}"
            raise ConfigError(
                f"{path} is not this sweep's batch {index} (it {what}); move it out of {self.batches} "
                "and run the same command again"
            )
        return rows


def _span(points: Any) -> str:
    values = np.asarray(points).ravel().tolist()
    if not values:
        return "none"
    return f"{values[0]}..{values[-1]} ({len(values)})" if len(values) > 1 else str(values[0])
