"""A folder that holds fmpy and the packages it needs, and nothing else: for a Python that
runs an FMU as a host without boom_hydraulics would (``python -I -S`` with that folder
first on its path: test/fmu_host.py --path).

The packages are links to those installed in this environment: fmpy's distribution and
its requirements (not its extras), recursively, each by its top-level modules.
"""

from __future__ import annotations

import importlib.metadata as metadata
import re
from pathlib import Path

#: A requirement's distribution name, before any version or marker.
_NAME = re.compile(r"^\s*([A-Za-z0-9][A-Za-z0-9._-]*)")


def requirements(distribution: str) -> set[str]:
    """``distribution`` and every distribution it requires (extras left out), recursively."""
    found: set[str] = set()
    todo = [distribution]
    while todo:
        name = todo.pop()
        key = re.sub(r"[-_.]+", "-", name).lower()
        if key in found:
            continue
        found.add(key)
        for requirement in metadata.requires(name) or []:
            if "extra ==" in requirement:
                continue
            match = _NAME.match(requirement)
            if match:
                todo.append(match.group(1))
    return found


def top_levels(distribution: str) -> set[Path]:
    """The top-level modules and folders a distribution installed (absolute paths)."""
    dist = metadata.distribution(distribution)
    tops: set[Path] = set()
    for file in dist.files or []:
        parts = Path(file).parts
        if not parts or parts[0] == ".." or parts[0].endswith((".dist-info", ".egg-info")) or parts[0] == "__pycache__":
            continue
        tops.add(Path(str(dist.locate_file(parts[0]))).resolve())
    return tops


def fmpy_alone(folder: Path) -> Path:
    """``folder`` with links to fmpy and its requirements' modules; returns it."""
    folder.mkdir(parents=True, exist_ok=True)
    for distribution in sorted(requirements("fmpy")):
        for top in top_levels(distribution):
            link = folder / top.name
            if top.exists() and not link.exists():
                link.symlink_to(top)
    return folder
