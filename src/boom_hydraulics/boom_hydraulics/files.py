"""Writing results the way users can trust: whole or not at all, and never over what is not ours.

The rules every tool follows:

- A tool writes only the files it names, and replaces only those. It never removes a
  folder or a file that it did not create in the same run.
- Each file is written under a temporary name beside its final one, then renamed into
  place: a reader sees the old file or the whole new one, never half of it.
- An output that is, or holds, one of the tool's inputs is refused before anything runs
  (:func:`check_apart`).
"""

from __future__ import annotations

import csv
import json
import math
import os
import re
import shutil
import sys
import tempfile
from collections.abc import Iterable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

from .errors import ConfigError

_UMASK = os.umask(0o022)  # read once: a file written here gets the mode any new file would get
os.umask(_UMASK)


def check_apart(out: Path, inputs: Iterable[Path], option: str = "--out") -> None:
    """Raise ConfigError if ``out`` is one of ``inputs`` or a folder that holds one of them."""
    target = Path(out).resolve()
    for source in inputs:
        resolved = Path(source).resolve()
        if resolved == target:
            raise ConfigError(f"{option} {out} is the input {source}; choose another output, inputs are never replaced")
        if target in resolved.parents:
            raise ConfigError(f"{option} {out} holds the input {source}; choose a folder of its own for the results")


def _missing_folders(folder: Path) -> list[Path]:
    """``folder`` and those of its parents that do not exist yet, outermost first."""
    missing = []
    for candidate in (folder, *folder.parents):
        if candidate.exists():
            break
        missing.append(candidate)
    return missing[::-1]


def make_folder(folder: Path) -> list[Path]:
    """Create ``folder`` with its parents; return the folders this call created (outermost first)."""
    if folder.exists() and not folder.is_dir():
        raise ConfigError(f"{folder} exists and is not a folder; name a folder for the results")
    created = _missing_folders(folder)
    folder.mkdir(parents=True, exist_ok=True)
    return created


def remove_created(created: Sequence[Path]) -> None:
    """Remove folders that :func:`make_folder` created, innermost first, where they are still empty."""
    for folder in reversed(created):
        try:
            folder.rmdir()
        except OSError:
            break  # not empty (someone else's files): keep it and everything above it


def process_alive(pid: int) -> bool:
    """True unless no process ``pid`` runs on this machine (then its temporary files are stale)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OverflowError):
        return True
    return True


def _note(message: str) -> None:
    print(f"{Path(sys.argv[0]).name or 'boom_hydraulics'}: note: {message}", file=sys.stderr)


def _stale_owner(name: str, prefix: str, suffix: str) -> int | None:
    """The process id in a temporary ``name`` that files.py made (``prefix`` PID-random ``suffix``)
    where that process is gone, else None (someone else's name, or a run still going)."""
    if not (name.startswith(prefix) and name.endswith(suffix)):
        return None
    pid, dash, tail = name[len(prefix) : len(name) - len(suffix)].partition("-")
    if not (dash and pid.isdigit() and tail and all(ch.isalnum() or ch == "_" for ch in tail)):
        return None
    return None if process_alive(int(pid)) else int(pid)


def _remove_stale_files(path: Path, suffix: str) -> None:
    """Remove the temporary files that an earlier, stopped run (SIGKILL, a power cut) left for
    ``path``: only names this module makes for that path, of processes that no longer run."""
    prefix, ending = f".{path.name}.", f".partial{suffix}"
    try:
        candidates = [entry for entry in os.scandir(path.parent) if entry.name.startswith(prefix)]
    except OSError:
        return
    for entry in candidates:
        if _stale_owner(entry.name, prefix, ending) is not None and entry.is_file(follow_symlinks=False):
            try:
                os.unlink(entry.path)
            except OSError:
                continue
            _note(f"removed {entry.path}, the unfinished {path.name} of an earlier run that was stopped")


def _remove_stale_staging(out: Path) -> None:
    """Remove the staging folders (.partial-PID-XXXX) that stopped runs left in ``out``, and name
    the ones of older versions (.partial-XXXX, no process id: they cannot be told from a live run)."""
    try:
        entries = [entry for entry in os.scandir(out) if entry.name.startswith(_STAGING)]
    except OSError:
        return
    for entry in entries:
        if not entry.is_dir(follow_symlinks=False):
            continue
        if _stale_owner(entry.name, _STAGING, "") is not None:
            shutil.rmtree(entry.path, ignore_errors=True)
            _note(f"removed {entry.path}, the unfinished results of an earlier run that was stopped")
        elif "-" not in entry.name[len(_STAGING) :]:
            _note(f"{entry.path} holds the unfinished results of an earlier run that was stopped; remove it")


def named_for(exc: OSError, target: Path, temporary: Path | None = None) -> OSError:
    """``exc`` naming ``target`` where it named ``temporary`` (or a file in it; None: whatever it
    named) or nothing at all: a user knows the file asked for, not the temporary name it is
    written under."""
    filename = exc.filename
    if filename is not None and temporary is not None:
        name = Path(filename)
        if name != temporary and temporary not in name.parents:
            return exc
        if temporary in name.parents:
            target = target / name.relative_to(temporary)
    renamed = OSError(exc.errno, exc.strerror or str(exc), str(target))
    renamed.__cause__ = exc
    return renamed


def folder_beside(out: Path) -> Path:
    """A fresh, empty folder beside ``out`` (``.NAME.xxxxxxxx.partial``, tempfile.mkdtemp's), for
    a result folder written whole and renamed onto ``out``; an OSError (a read-only or full
    disk) names ``out``, the folder the user asked for, not the temporary name."""
    out = Path(out)
    try:
        return Path(tempfile.mkdtemp(prefix=f".{out.name}.", suffix=".partial", dir=out.parent))
    except OSError as exc:
        raise named_for(exc, out) from None


#: The start of a staging folder's name (results_folder), and of nothing else.
_STAGING = ".partial-"


@contextmanager
def atomic_path(path: Path, suffix: str = "") -> Iterator[Path]:
    """A fresh temporary path beside ``path``; renamed onto ``path`` when the block succeeds,
    removed when it fails. ``suffix`` keeps an ending that a writer insists on (``.npz``).

    The temporary name holds this process's id, so that the next run for ``path`` can tell
    the file of a stopped run (removed, with a note) from that of one still writing. An
    OSError about the temporary file (a full disk, a read-only folder) names ``path``."""
    path = Path(path)
    if path.is_dir():
        raise ConfigError(f"{path} is a folder; name a file to write")
    created = make_folder(path.parent)
    _remove_stale_files(path, suffix)
    try:
        handle, name = tempfile.mkstemp(
            prefix=f".{path.name}.{os.getpid()}-", suffix=f".partial{suffix}", dir=path.parent
        )
    except OSError as exc:
        remove_created(created)
        raise named_for(exc, path) from None
    os.close(handle)
    tmp = Path(name)
    try:
        os.chmod(tmp, 0o666 & ~_UMASK)  # mkstemp makes it private
        yield tmp
        os.replace(tmp, path)
    except BaseException as exc:
        tmp.unlink(missing_ok=True)  # ours: created above
        remove_created(created)
        if isinstance(exc, OSError):
            raise named_for(exc, path, tmp) from None
        raise


@contextmanager
def results_folder(out: Path) -> Iterator[Path]:
    """A staging folder for results that go into ``out``.

    The block writes its files into the staging folder. When it succeeds, each file is
    renamed into ``out``, replacing only a file of the same name; everything else in
    ``out`` stays. When it fails, nothing reaches ``out``. The staging folder, and ``out``
    itself if this call created it and it stayed empty, are removed: both are this run's.
    Staging folders of earlier runs that were stopped (SIGKILL) are removed first, with a
    note; an OSError about a staged file names the file in ``out`` it was meant to be.
    """
    out = Path(out)
    created = make_folder(out)
    _remove_stale_staging(out)
    try:
        staging = Path(tempfile.mkdtemp(prefix=f"{_STAGING}{os.getpid()}-", dir=out))
    except OSError as exc:
        remove_created(created)
        raise named_for(exc, out) from None
    ok = False
    try:
        yield staging
        for item in sorted(staging.iterdir()):
            if not item.is_file():
                raise ConfigError(f"{item}: results are files; a folder cannot be placed into {out}")
            os.replace(item, out / item.name)
        ok = True
    except OSError as exc:
        raise named_for(exc, out, staging) from None
    finally:
        shutil.rmtree(staging, ignore_errors=True)  # created by this call
        if not ok:
            remove_created(created)


def write_csv(path: Path, header: Sequence[str], rows: Iterable[Sequence[Any]]) -> None:
    """Write a CSV whole or not at all (temporary name, then rename)."""
    with atomic_path(path) as tmp, tmp.open("w", newline="", encoding="utf-8") as handle:
        writer = csv.writer(handle)
        writer.writerow(header)
        writer.writerows(rows)


#: Rows a columnar CSV joins at once (:func:`write_csv_columns`): its text in memory stays small.
CSV_CHUNK_ROWS = 8192


def write_csv_columns(path: Path, header: Sequence[str], columns: Sequence[np.ndarray]) -> None:
    """:func:`write_csv` of a table given column by column (arrays of equal length), whole or
    not at all, in chunks of CSV_CHUNK_ROWS rows (:func:`csv_rows`)."""
    rows = len(columns[0]) if columns else 0
    chunks = range(0, rows, CSV_CHUNK_ROWS)
    _write_csv_text(path, header, (csv_rows([c[start : start + CSV_CHUNK_ROWS] for c in columns]) for start in chunks))


def write_csv_lines(path: Path, header: Sequence[str], lines: Sequence[str]) -> None:
    """:func:`write_csv` of rows given as their CSV text without the line end (:func:`csv_cells`
    of all of a row's columns, joined by commas), whole or not at all."""
    chunks = range(0, len(lines), CSV_CHUNK_ROWS)
    _write_csv_text(path, header, (_ended(lines[start : start + CSV_CHUNK_ROWS]) for start in chunks))


def _write_csv_text(path: Path, header: Sequence[str], texts: Iterable[str]) -> None:
    """The header row, then each of ``texts`` (CSV rows, line ends included), whole or not at all."""
    with atomic_path(path) as tmp, tmp.open("w", newline="", encoding="utf-8") as handle:
        csv.writer(handle).writerow(header)
        for text in texts:
            handle.write(text)


def csv_rows(columns: Sequence[np.ndarray]) -> str:
    """The rows of a table given column by column (arrays of equal length) as CSV text: the
    bytes csv.writer writes of :func:`csv_column`'s cells, joined in bulk (joining a sweep's
    table of 10 000 points and 50 columns took 0.04 s, where csv.writer's rows took 0.14 s)."""
    lines = csv_cells(columns)
    if len(columns) == 1:  # (csv.writer quotes a row that is one empty cell)
        lines = [line or '""' for line in lines]
    return _ended(lines)


def _ended(lines: Iterable[str]) -> str:
    """Rows' CSV text, each with csv.writer's line end."""
    return "".join(f"{line}\r\n" for line in lines)


def csv_cells(columns: Sequence[np.ndarray]) -> list[str]:
    """Each row's cells of the given columns (arrays of equal length, at least one) as csv.writer
    writes them, joined by commas: a part of the rows' CSV lines, which the cells of other
    columns may join on either side (by a comma)."""
    cells = [csv_column(c) if np.asarray(c).dtype.kind in "biuf" else _quoted(csv_column(c)) for c in columns]
    return list(map(",".join, zip(*cells)))


def _quoted(cells: list[str]) -> list[str]:
    """Text cells as csv.writer's default dialect writes them: quoted, with quotes doubled,
    where they hold a comma, a quote or a line break."""
    return ['"' + cell.replace('"', '""') + '"' if _NEEDS_QUOTES.search(cell) else cell for cell in cells]


_NEEDS_QUOTES = re.compile(r'[,"\r\n]')


def csv_cell(value: Any) -> str:
    """A CSV cell that reads back exactly: text as it is, flags and counts as integers, numbers by repr."""
    if isinstance(value, (str, np.str_)):
        return str(value)
    if isinstance(value, (bool, np.bool_, int, np.integer)):
        return str(int(value))
    return repr(float(value))


def csv_column(values: np.ndarray) -> list[str]:
    """:func:`csv_cell` of every value of a column, with numpy doing the conversions (a run
    streamed to CSV writes millions of cells)."""
    values = np.asarray(values)
    if values.dtype == bool or np.issubdtype(values.dtype, np.integer):
        return list(map(str, values.astype(np.int64).tolist()))
    if values.dtype.kind == "f":
        return list(map(repr, values.astype(float).tolist()))
    return [csv_cell(value) for value in values]


def json_ready(value: Any) -> Any:
    """``value`` with every NaN or infinite float as None: JSON has no NaN (JSON.parse, jq and
    Foxglove reject it), and null says "no value" to every reader."""
    if isinstance(value, Mapping):
        return {str(key): json_ready(item) for key, item in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_ready(item) for item in value]
    if isinstance(value, (np.bool_, bool)):
        return bool(value)
    if isinstance(value, (np.integer, int)):
        return int(value)
    if isinstance(value, (np.floating, float)):
        return float(value) if math.isfinite(value) else None
    return value


def json_text(value: Any) -> str:
    """Strict JSON of ``value`` (non-finite numbers as null, see :func:`json_ready`), indented."""
    return json.dumps(json_ready(value), indent=2, allow_nan=False) + "\n"


def write_bytes(path: Path, data: bytes) -> None:
    """Write ``data`` beside ``path`` first, then rename: the file is whole or absent."""
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)


def write_npz(path: Path, arrays: Mapping[str, np.ndarray], compressed: bool = False) -> None:
    """``np.savez`` of ``arrays`` to ``path`` (ending in .npz), whole or not at all."""
    with atomic_path(path, suffix=".npz") as tmp:
        (np.savez_compressed if compressed else np.savez)(tmp, **arrays)
