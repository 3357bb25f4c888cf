"""The architecture holds: only the ROS layer imports rclpy; one registry of models and of methods."""

from __future__ import annotations

import pkgutil
import subprocess
import sys

import boom_hydraulics
from boom_hydraulics.model import MODELS, Model
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
