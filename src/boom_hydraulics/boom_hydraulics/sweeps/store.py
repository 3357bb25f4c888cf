"""A sweep's folder on disk: what was asked, and each finished batch as soon as it finishes.

    OUT/sweep.json            the request (configs, axes, sample, scenario, ...)
    OUT/batches/00012.npz     the table rows of batch 12, written once it is done

A batch file appears whole or not at all (written beside, then renamed), so an
interrupted sweep keeps every batch it finished and a resumed one redoes none of them.
"""

from __future__ import annotations

import json
import sys
import zipfile
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import ConfigError
from ..files import write_bytes, write_npz

MANIFEST = "sweep.json"
FORMAT = 1


def _normal(request: dict[str, Any]) -> Any:
    """The request as it reads back from JSON (tuples become lists)."""
    return json.loads(json.dumps(request))


def stored_request(folder: Path) -> dict[str, Any] | None:
    """The request of the sweep stored in ``folder``, or None if there is none (or it is unreadable)."""
    try:
        return json.loads((folder / MANIFEST).read_text(encoding="utf-8")).get("request")
    except (OSError, ValueError, AttributeError):
        return None


class SweepStore:
    """The folder of one sweep; see the module docstring."""

    def __init__(self, folder: Path, request: dict[str, Any], resume: bool) -> None:
        """Open ``folder`` for ``request``: a new sweep, or with ``resume`` the same one begun before.

        Nothing is written until the first batch is saved.

        Raises ConfigError if the folder holds another sweep, or this one without
        ``resume`` (so that finished work is never overwritten by accident).
        """
        self.folder = folder
        self.batches = folder / "batches"
        manifest = folder / MANIFEST
        if manifest.exists():
            try:
                stored = json.loads(manifest.read_text(encoding="utf-8"))
            except (OSError, ValueError) as exc:
                raise ConfigError(f"{manifest} is unreadable ({exc}); choose another --out") from None
            done = len(self.done())
            if not resume:
                raise ConfigError(
                    f"{folder} holds a sweep already ({done} batches done); pass --resume to finish it "
                    "with the same arguments, or choose another --out"
                )
            if stored.get("request") != _normal(request):
                old, new = stored.get("request") or {}, _normal(request)
                differ = sorted(k for k in set(old) | set(new) if old.get(k) != new.get(k))
                raise ConfigError(
                    f"{folder} holds a different sweep (it differs in: {', '.join(differ)}); "
                    "resume with the arguments and config files it was started with, or choose another --out"
                )
        elif folder.exists() and any(folder.iterdir()):
            raise ConfigError(f"{folder} exists and is not a sweep folder (no {MANIFEST}); choose another --out")
        self._manifest = None if manifest.exists() else {"format": FORMAT, "request": request}

    def path(self, index: int) -> Path:
        return self.batches / f"{index:05d}.npz"

    def done(self) -> set[int]:
        """Indices of the batches whose rows are on disk."""
        if not self.batches.is_dir():
            return set()
        return {int(p.stem) for p in self.batches.glob("[0-9]*.npz") if p.stem.isdigit()}

    def save(self, index: int, rows: dict[str, np.ndarray]) -> None:
        """Store the rows of batch ``index`` (whole or not at all); the first also stores the request."""
        if self._manifest is not None:
            self.batches.mkdir(parents=True, exist_ok=True)
            write_bytes(self.folder / MANIFEST, (json.dumps(self._manifest, indent=1) + "\n").encode())
            self._manifest = None
        write_npz(self.path(index), rows)

    def load(self, index: int) -> dict[str, np.ndarray] | None:
        """The rows of batch ``index``, or None (with a warning) if its file cannot be read."""
        try:
            with np.load(self.path(index)) as data:
                rows = {name: data[name] for name in data.files}
            if "point" not in rows or "status" not in rows:
                raise ValueError("no point or status column")
            return rows
        except (OSError, ValueError, EOFError, zipfile.BadZipFile) as exc:
            print(f"boom-sweep: warning: {self.path(index)} is unreadable ({exc}); computing it again", file=sys.stderr)
            return None
