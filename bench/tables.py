"""What the benchmark scripts share: a printed table, best-of timing, and the file each run's
table is written to, with the date, the machine and the commit."""

from __future__ import annotations

import datetime
import os
import platform
import subprocess
import sys
import time
from pathlib import Path

from boom_hydraulics.files import write_bytes

ROOT = Path(__file__).resolve().parents[1]
#: Where each run's table goes, with its date and machine (docs/performance.md links it).
RESULTS = ROOT / "bench" / "results"


def table(title: str, header: list[str], rows: list[list[str]]) -> str:
    """Print the table (title, header, rule, rows in aligned columns); return what was printed."""
    widths = [max(len(h), *(len(r[i]) for r in rows)) for i, h in enumerate(header)]
    lines = [f"\n{title}", "  ".join(h.ljust(w) for h, w in zip(header, widths)), "  ".join("-" * w for w in widths)]
    lines += ["  ".join(c.ljust(w) for c, w in zip(r, widths)) for r in rows]
    text = "\n".join(lines)
    print(text)
    return text


def best_of(fn, repeat: int = 3) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def machine() -> str:
    """The machine a run was measured on: cores and processor model (Linux), Python, numba."""
    model = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                model = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return f"{os.cpu_count()} cores, {model}; Python {platform.python_version()}, numba {numba_version()}"


def numba_version() -> str:
    try:
        import numba
    except ImportError:
        return "absent"
    return numba.__version__


def commit(checkout: Path = ROOT) -> str:
    """The checkout's commit (with '+changes' when its tracked files differ), or 'unknown'."""
    try:
        head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=checkout, capture_output=True, text=True)
        dirty = subprocess.run(["git", "diff", "--quiet", "HEAD"], cwd=checkout, capture_output=True)
    except OSError:
        return "unknown"
    return head.stdout.strip() + ("+changes" if dirty.returncode else "") if head.returncode == 0 else "unknown"


def write_results(name: str, text: str, commits: str = "") -> Path:
    """The table with the date, the machine and the commit (or ``commits``, a line naming the
    checkouts measured), as bench/results/<name>-<UTC time>.md (whole or not at all): figures
    stay with the run that measured them, not in prose."""
    now = datetime.datetime.now(datetime.UTC)
    path = RESULTS / f"{name}-{now:%Y%m%d-%H%M%S}.md"
    script = Path(sys.argv[0]).name
    body = (
        f"# {script}, {now:%Y-%m-%d %H:%M} UTC\n\n"
        f"- machine: {machine()}\n- {commits or 'commit: ' + commit()}\n- command: {' '.join(sys.argv)}\n\n"
        f"```{text}\n```\n"
    )
    write_bytes(path, body.encode())
    return path


def publish_against(name: str, title: str, header: list[str], rows: list[list[str]], against: Path) -> Path:
    """Print the table of a run against the checkout ``against`` and write it with both commits
    (``write_results``): the file's path."""
    text = table(title, header, rows)
    path = write_results(name, text, f"commits: {commit()} (this) against {commit(against)}")
    print(f"written to {path.relative_to(ROOT)}")
    return path
