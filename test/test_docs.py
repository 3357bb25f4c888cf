"""The documentation holds: every command it shows names a tool that exists, every relative
link reaches its file and heading, and the ROS API lists every parameter the node has."""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
SETUP = ROOT / "src" / "boom_hydraulics" / "setup.py"

FENCE = re.compile(r"^```.*?^```", re.S | re.M)
LINK = re.compile(r"!?\[[^\]]*\]\(([^)\s]+)\)")
WITH_ENV = re.compile(r"tools/with-env\s+([^\s`;]+)(?:\s+([^\s`;]+))?")
MAKE = re.compile(r"(?:^|`)make\s+([a-z][\w-]*)", re.M)  # in a code block, or `make X`


def console_scripts() -> set[str]:
    """The console scripts setup.py installs, by name."""
    return set(re.findall(r'"([\w-]+)\s*=\s*[\w.]+:\w+"', SETUP.read_text()))


def make_targets() -> set[str]:
    return set(re.findall(r"^([\w-]+):", (ROOT / "Makefile").read_text(), re.M))


def slug(heading: str) -> str:
    """GitHub's anchor of a heading: lower case, punctuation dropped, spaces to hyphens."""
    text = re.sub(r"[^\w\- ]", "", heading.strip().lower())
    return text.replace(" ", "-")


def anchors(page: Path) -> set[str]:
    found: set[str] = set()
    for line in FENCE.sub("", page.read_text()).splitlines():
        m = re.match(r"#{1,6}\s+(.*)", line)
        if m:
            base = slug(m.group(1))
            name, n = base, 0
            while name in found:
                n += 1
                name = f"{base}-{n}"
            found.add(name)
    return found


def commands() -> list[tuple[str, str, str | None]]:
    """(page, program, its first argument) of every ``tools/with-env PROGRAM ...`` shown."""
    return [(page.name, m.group(1), m.group(2)) for page in PAGES for m in WITH_ENV.finditer(page.read_text())]


def test_the_pages_exist_and_the_readme_is_short():
    names = {p.relative_to(ROOT).as_posix() for p in PAGES}
    for page in ("ros-api", "robot-stack", "cli", "sweeps", "architecture", "performance", "model"):
        assert f"docs/{page}.md" in names
    assert len((ROOT / "README.md").read_text().splitlines()) <= 200


def test_every_command_names_a_tool_that_exists():
    scripts = console_scripts()
    assert {"boom-sim", "boom_sim", "boom-sweep"} <= scripts  # the parse found setup.py's list
    shown = commands()
    assert len(shown) > 20  # the pages were read
    wrong = []
    for page, program, argument in shown:
        program = program.strip("`")
        if program.isupper():  # a placeholder, as in "tools/with-env TOOL --help"
            continue
        if program == "python":
            script = (argument or "").strip("`")
            if script == "-m" or (ROOT / script).is_file():
                continue
            wrong.append(f"{page}: tools/with-env python {script}: no such script")
        elif program not in scripts:
            wrong.append(f"{page}: tools/with-env {program}: not a console script of setup.py")
    assert not wrong, "\n".join(wrong)


def test_every_make_target_shown_exists():
    targets = make_targets()
    shown = [
        (p.name, t)
        for p in PAGES
        for text in [*FENCE.findall(p.read_text()), *re.findall(r"`[^`\n]+`", p.read_text())]
        for t in MAKE.findall(text.strip("`"))
    ]
    assert any(t == "run" for _, t in shown)
    wrong = [f"{page}: make {t}" for page, t in shown if t not in targets]
    assert not wrong, "\n".join(wrong)


def test_every_relative_link_resolves_to_a_file_and_heading():
    checked = 0
    wrong = []
    for page in PAGES:
        for target in LINK.findall(FENCE.sub("", page.read_text())):
            if re.match(r"[a-z]+:", target):  # https:, mailto:
                continue
            path, _, anchor = target.partition("#")
            dest = (page.parent / path).resolve() if path else page
            checked += 1
            if not dest.exists():
                wrong.append(f"{page.name}: {target}: no such file")
            elif anchor and (dest.suffix != ".md" or anchor not in anchors(dest)):
                wrong.append(f"{page.name}: {target}: no such heading")
    assert checked > 40
    assert not wrong, "\n".join(wrong)


def test_a_broken_link_is_caught(tmp_path):
    page = tmp_path / "page.md"
    page.write_text("# A title: here\n\n## Two\n## Two\n")
    assert anchors(page) == {"a-title-here", "two", "two-1"}
    assert "missing" not in anchors(page)


@pytest.mark.skipif(shutil.which("boom_sim") is None, reason="the workspace is not built")
def test_the_ros_api_lists_every_parameter_the_node_has():
    """Every parameter ``boom_sim --help`` prints is named in docs/ros-api.md's tables."""
    result = subprocess.run(["boom_sim", "--help"], capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    names = re.findall(r"^\s+\*?\s*([a-z][a-z0-9_]+)\s{2,}", result.stdout, re.M)
    assert "payload_mass_kg" in names and "publish_rate_hz" in names
    documented = set(re.findall(r"^\| `([a-z][a-z0-9_]+)`", (ROOT / "docs" / "ros-api.md").read_text(), re.M))
    missing = sorted(set(names) - documented)
    assert not missing, f"docs/ros-api.md does not list: {missing}"


def test_the_parameter_table_is_the_one_the_schema_writes():
    """docs/ros-api.md's parameter reference is generated (tools/ros-api-table): it cannot drift."""
    pytest.importorskip("rclpy")
    import importlib.machinery
    import importlib.util

    loader = importlib.machinery.SourceFileLoader("ros_api_table", str(ROOT / "tools" / "ros-api-table"))
    spec = importlib.util.spec_from_loader("ros_api_table", loader)
    tool = importlib.util.module_from_spec(spec)
    loader.exec_module(tool)
    page = (ROOT / "docs" / "ros-api.md").read_text()
    assert tool.with_table(page) == page, "docs/ros-api.md: run tools/with-env python tools/ros-api-table"
    assert "| `payload_mass_kg` | plant | float | `50.0` | kg |" in page
