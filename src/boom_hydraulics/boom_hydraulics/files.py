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
import os
import shutil
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


@contextmanager
def atomic_path(path: Path, suffix: str = "") -> Iterator[Path]:
    """A fresh temporary path beside ``path``; renamed onto ``path`` when the block succeeds,
    removed when it fails. ``suffix`` keeps an ending that a writer insists on (``.npz``)."""
    path = Path(path)
    if path.is_dir():
        raise ConfigError(f"{path} is a folder; name a file to write")
    created = make_folder(path.parent)
    handle, name = tempfile.mkstemp(prefix=f".{path.name}.", suffix=f".partial{suffix}", dir=path.parent)
    os.close(handle)
    tmp = Path(name)
    os.chmod(tmp, 0o666 & ~_UMASK)  # mkstemp makes it private
    try:
        yield tmp
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)  # ours: created above
        remove_created(created)
        raise


@contextmanager
def results_folder(out: Path) -> Iterator[Path]:
    """A staging folder for results that go into ``out``.

    The block writes its files into the staging folder. When it succeeds, each file is
    renamed into ``out``, replacing only a file of the same name; everything else in
    ``out`` stays. When it fails, nothing reaches ``out``. The staging folder, and ``out``
    itself if this call created it and it stayed empty, are removed: both are this run's.
    """
    out = Path(out)
    created = make_folder(out)
    staging = Path(tempfile.mkdtemp(prefix=".partial-", dir=out))
    ok = False
    try:
        yield staging
        for item in sorted(staging.iterdir()):
            if not item.is_file():
                raise ConfigError(f"{item}: results are files; a folder cannot be placed into {out}")
            os.replace(item, out / item.name)
        ok = True
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


def csv_cell(value: Any) -> str:
    """A CSV cell that reads back exactly: text as it is, flags and counts as integers, numbers by repr."""
    if isinstance(value, (str, np.str_)):
        return str(value)
    if isinstance(value, (bool, np.bool_, int, np.integer)):
        return str(int(value))
    return repr(float(value))


def write_bytes(path: Path, data: bytes) -> None:
    """Write ``data`` beside ``path`` first, then rename: the file is whole or absent."""
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)


def write_npz(path: Path, arrays: Mapping[str, np.ndarray], compressed: bool = False) -> None:
    """``np.savez`` of ``arrays`` to ``path`` (ending in .npz), whole or not at all."""
    with atomic_path(path, suffix=".npz") as tmp:
        (np.savez_compressed if compressed else np.savez)(tmp, **arrays)
