"""docs/python.md holds: every ```python block on the page runs, in order, in one fresh
interpreter (as a notebook's cells do), and prints what the ```text block under it shows.

The blocks run in a temporary working folder holding a copy of ``config/`` (the page's paths
are relative to the checkout's root, where a user starts Python). Text must match line for line
(runs of spaces count as one); a number with a decimal point or an exponent must equal the one
shown to its last shown digit (8.099 takes 8.098 to 8.100: a rounding that falls the other way
on another machine), a whole number (a count) exactly; so a page whose figures the model no
longer gives fails.
"""

from __future__ import annotations

import json
import math
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGE = ROOT / "docs" / "python.md"

FENCE = re.compile(r"^```(\w*)[^\n]*\n(.*?)^```[ \t]*$", re.S | re.M)
NUMBER = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?")
#: What starts each block's output on stdout (no block prints it).
MARK = "\x1e block {} \x1e"
#: The most the page's blocks may take together on a loaded 2-core machine, s (about 20 s alone).
TIMEOUT_S = 300

#: Runs the blocks (a JSON list of code; argv[2]: the marker) in one namespace, marking where
#: each one's output starts.
RUNNER = """\
import json, sys
blocks = json.load(open(sys.argv[1], encoding="utf-8"))
namespace = {"__name__": "__main__"}
for k, code in enumerate(blocks):
    print(sys.argv[2].format(k), flush=True)
    exec(compile(code, f"docs/python.md, python block {k + 1}", "exec"), namespace)
    sys.stdout.flush()
"""


def examples(text: str) -> list[tuple[str, str]]:
    """(code, the output shown under it) of every python block of a page, in order: the output
    is the text block that follows before the next python block ('' where none does)."""
    pairs: list[list[str]] = []
    for m in FENCE.finditer(text):
        kind, body = m.group(1), m.group(2)
        if kind == "python":
            pairs.append([body, ""])
        elif kind == "text" and pairs and not pairs[-1][1]:
            pairs[-1][1] = body
    return [(code, shown) for code, shown in pairs]


def run_blocks(codes: list[str], folder: Path) -> list[str]:
    """What each of ``codes`` prints, run in order in one fresh interpreter in ``folder``."""
    (folder / "blocks.json").write_text(json.dumps(codes), encoding="utf-8")
    (folder / "runner.py").write_text(RUNNER, encoding="utf-8")
    env = dict(os.environ, MPLBACKEND="Agg", PYTHONUNBUFFERED="1")
    result = subprocess.run(
        [sys.executable, "runner.py", "blocks.json", MARK],
        cwd=folder,
        env=env,
        capture_output=True,
        text=True,
        timeout=TIMEOUT_S,
    )
    assert result.returncode == 0, f"the page's blocks failed:\n{result.stdout[-3000:]}\n{result.stderr[-3000:]}"
    parts = re.split(r"\x1e block (\d+) \x1e\n", result.stdout)
    outputs = dict(zip(map(int, parts[1::2]), parts[2::2]))
    assert sorted(outputs) == list(range(len(codes))), "a block's start was not marked"
    return [outputs[k] for k in range(len(codes))]


def last_digit(shown: str) -> float:
    """The size of the last digit ``shown`` gives: 8.099 -> 0.001, 7.147e+06 -> 1000, 201 -> 1."""
    mantissa, _, exponent = shown.lower().partition("e")
    decimals = len(mantissa.partition(".")[2])
    return 10.0 ** (int(exponent or 0) - decimals)


def differences(printed: str, shown: str) -> list[str]:
    """How ``printed`` differs from ``shown`` (empty: it matches): line for line, text equal with
    runs of spaces as one, each number within one unit of the last digit the page shows, a whole
    number exactly."""
    got, want = printed.rstrip("\n").splitlines(), shown.rstrip("\n").splitlines()
    found = []
    if len(got) != len(want):
        found.append(f"{len(got)} lines printed, {len(want)} shown")
    for k, (line, expected) in enumerate(zip(got, want), start=1):
        words = [" ".join(part.split()) for part in NUMBER.split(line)]
        expected_words = [" ".join(part.split()) for part in NUMBER.split(expected)]
        numbers, expected_numbers = NUMBER.findall(line), NUMBER.findall(expected)
        same = words == expected_words and len(numbers) == len(expected_numbers)
        for number, value in zip(numbers, expected_numbers) if same else ():
            whole = not re.search(r"[.eE]", value)
            if whole and number != value:
                same = False
            elif not math.isclose(float(number), float(value), rel_tol=0.0, abs_tol=1.0001 * last_digit(value)):
                same = False
        if not same:
            found.append(f"line {k}: printed {line!r}, shown {expected!r}")
    return found


def test_the_comparison_takes_the_shown_precision_and_nothing_looser():
    assert not differences("f 8.0993 Hz, 201 rows\n", "f 8.099 Hz, 201 rows")
    assert not differences("p 7.1474e+06 Pa", "p 7.147e+06 Pa")
    assert differences("f 8.102 Hz", "f 8.099 Hz")  # three units of the last digit off
    assert differences("p 7.16e+06 Pa", "p 7.147e+06 Pa")
    assert differences("f 8.099 kHz", "f 8.099 Hz")  # the words count
    assert differences("a\nb", "a")  # and the lines
    assert differences("1 of 15 designs", "0 of 15 designs")  # counts exactly
    assert not differences("x  =   1.5", "x = 1.5")
    assert last_digit("201") == 1.0 and last_digit("-0.25") == 0.01 and last_digit("1e-05") == 1e-05


def test_the_pairing_of_code_and_output():
    text = "```python\na = 1\n```\n\nprose\n\n```text\nout\n```\n```python\nb = 2\n```\n```sh\nx\n```\n"
    assert examples(text) == [("a = 1\n", "out\n"), ("b = 2\n", "")]


@pytest.mark.skipif(shutil.which("boom-sweep") is None, reason="the workspace is not built (the page runs boom-sweep)")
def test_every_example_on_the_page_prints_what_the_page_shows(tmp_path):
    pairs = examples(PAGE.read_text(encoding="utf-8"))
    assert len(pairs) >= 6, "the page's python blocks were not found"
    shutil.copytree(ROOT / "config", tmp_path / "config")
    printed = run_blocks([code for code, _ in pairs], tmp_path)
    wrong = []
    for k, ((code, shown), out) in enumerate(zip(pairs, printed), start=1):
        found = differences(out, shown)
        if found:
            first = code.strip().splitlines()[0]
            wrong.append(f"python block {k} ({first}):\n  " + "\n  ".join(found))
    assert not wrong, "docs/python.md shows other output than its examples print:\n" + "\n".join(wrong)


if __name__ == "__main__":  # pragma: no cover - prints what each block prints, to write the page with
    codes = [code for code, _ in examples(PAGE.read_text(encoding="utf-8"))]
    folder = Path(sys.argv[1])
    shutil.copytree(ROOT / "config", folder / "config", dirs_exist_ok=True)
    for k, out in enumerate(run_blocks(codes, folder), start=1):
        print(f"=== block {k}\n{out}", end="")
