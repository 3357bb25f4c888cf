"""The architecture holds: only the ROS layer imports rclpy; one registry of models and of methods;
a drive is one module, which the model, the solver and the analysis never name."""

from __future__ import annotations

import ast
import pkgutil
import re
import subprocess
import sys
from pathlib import Path

import boom_hydraulics
from boom_hydraulics.analysis import labels
from boom_hydraulics.model import MODELS, Model
from boom_hydraulics.model.drives import DRIVES
from boom_hydraulics.model.parameters import METHODS, MODES, describe
from boom_hydraulics.solve.integrators import BATCHED, FIXED_STEP
from boom_hydraulics.solve.integrators import METHODS as REGISTRY

NON_ROS = sorted(
    m.name
    for m in pkgutil.walk_packages(boom_hydraulics.__path__, "boom_hydraulics.")
    if m.name != "boom_hydraulics.ros" and not m.name.startswith("boom_hydraulics.ros.")
)


def test_only_the_ros_layer_imports_rclpy():
    """Each module outside boom_hydraulics.ros, imported in a fresh interpreter one after the
    other: the first that brings in rclpy, or the ROS layer, is named."""
    code = (
        "import importlib, sys\n"
        f"for name in {NON_ROS!r}:\n"
        "    importlib.import_module(name)\n"
        "    leaked = [m for m in ('rclpy', 'boom_hydraulics.ros') if m in sys.modules]\n"
        "    if leaked:\n"
        "        print(name, 'imports', leaked[0])\n"
        "        break\n"
        "else:\n"
        "    print('clean', len(sys.modules))\n"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    assert result.stdout.startswith("clean"), result.stdout
    assert len(NON_ROS) > 30  # the walk found the tree, not an empty package


def test_every_model_offers_the_model_interface():
    assert tuple(MODELS) == MODES
    for name, model in MODELS.items():
        assert isinstance(model, Model), name
        assert len(model.STATE_NAMES) == len(model.STATE_SCALES)


def test_the_methods_come_from_one_registry():
    assert METHODS == tuple(REGISTRY) == describe("method")["choices"]
    assert set(FIXED_STEP) == {"euler", "rk4", "ros2"}  # rk45 is adaptive: no compiled path
    assert set(BATCHED) == {"euler", "rk4"}  # the explicit ones run on arrays


PACKAGE = Path(boom_hydraulics.__file__).resolve().parent
#: A registered drive's name as a word (in a string, a name or a module path).
DRIVE_WORD = re.compile(r"\b(?:" + "|".join(map(re.escape, DRIVES)) + r")\b")


def _docstrings(tree: ast.AST) -> set[int]:
    """The ids of the docstrings' nodes in ``tree`` (prose: it may name a drive as an example)."""
    bodies = (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)
    return {
        id(node.body[0].value)
        for node in ast.walk(tree)
        if isinstance(node, bodies)
        and node.body
        and isinstance(node.body[0], ast.Expr)
        and isinstance(node.body[0].value, ast.Constant)
    }


def names_of_drives(path: Path) -> list[str]:
    """Where the code of ``path`` names a registered drive: a string that holds its name (a
    docstring aside), a name or attribute spelled as it, an import of its module."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    prose = _docstrings(tree)
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Constant) and isinstance(node.value, str) and id(node) not in prose:
            named = DRIVE_WORD.search(node.value)
        elif isinstance(node, ast.Name):
            named = DRIVE_WORD.fullmatch(node.id)
        elif isinstance(node, ast.Attribute):
            named = DRIVE_WORD.fullmatch(node.attr)
        elif isinstance(node, ast.ImportFrom):
            named = DRIVE_WORD.search(" ".join([node.module or "", *(alias.name for alias in node.names)]))
        elif isinstance(node, ast.Import):
            named = DRIVE_WORD.search(" ".join(alias.name for alias in node.names))
        else:
            continue
        if named:
            found.append(f"{path.relative_to(PACKAGE)}:{node.lineno}: {named.group(0)}")
    return found


def test_a_drive_is_one_module_that_the_model_the_solver_and_the_analysis_never_name():
    """model/physical.py, the ledger, solve, analysis, sweeps, resim, the FMU and calibration
    reach a drive only through the registry (model/drives: supply, energy, energy_rate,
    stiffness, initial_state, LABEL, and the drives' flags such as VALVE): no drive's name in
    their code, no import of a drive's module. So a new drive touches model/drives and parameters only."""
    sources = [PACKAGE / "model" / "physical.py", PACKAGE / "model" / "ledger.py"]
    for floor in ("solve", "analysis", "sweeps", "resim", "fmu", "calibration"):
        sources += sorted((PACKAGE / floor).glob("*.py"))
    assert len(sources) > 60  # the folders were found
    assert [where for path in sources for where in names_of_drives(path)] == []
    # the check sees a drive where one is named: the registry
    registry = names_of_drives(PACKAGE / "model" / "drives" / "__init__.py")
    assert {where.rsplit(" ", 1)[-1] for where in registry} == set(DRIVES)


def test_a_plot_names_each_drive_by_its_own_label():
    """The legend's words for a drive come from its module (LABEL), so a new drive brings its own."""
    assert labels.DRIVE_WORDS == {name: module.LABEL for name, module in DRIVES.items()}
    assert all(labels.drive_words(name) == DRIVES[name].LABEL != name for name in DRIVES)
