"""The staging folders a re-simulation writes its bag in, beside ``--out``, and the clean-up
of those that killed runs left."""

from __future__ import annotations

import re
import shutil
import time
from pathlib import Path

from ..bags.recording import is_being_recorded

#: An unfinished staging folder this old, with no live bag in it, was left by a killed run (s).
STALE_AFTER_S = 60.0


def _staging_pattern(out: Path) -> re.Pattern[str]:
    """The names of the staging folders of runs to ``out``: ``.NAME.xxxxxxxx.partial`` (tempfile.mkdtemp)."""
    return re.compile(rf"\.{re.escape(out.name)}\.[A-Za-z0-9_]{{8}}\.partial")


def _left_by_a_killed_run(folder: Path) -> bool:
    """A staging folder of ours whose run is gone: no MCAP file in it is held by a live
    recorder, and it has one (or is old enough that its run would have made one)."""
    mcaps = list(folder.glob("*/*.mcap"))
    if any(is_being_recorded(f) for f in mcaps):
        return False
    return bool(mcaps) or time.time() - folder.stat().st_mtime > STALE_AFTER_S


def remove_stale_staging(out: Path) -> list[Path]:
    """Remove the staging folders that killed runs (SIGKILL, power loss) to this same ``out``
    left beside it; only folders of this tool's own pattern for ``out``. Returns them."""
    if not out.parent.is_dir():
        return []
    pattern = _staging_pattern(out)
    removed = []
    for folder in sorted(out.parent.iterdir()):
        if folder.is_dir() and not folder.is_symlink() and pattern.fullmatch(folder.name):
            if _left_by_a_killed_run(folder):
                shutil.rmtree(folder, ignore_errors=True)
                removed.append(folder)
    return removed
