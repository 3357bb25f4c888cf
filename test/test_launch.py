"""boom_sim.launch.py refuses what it cannot start before it starts anything."""

from __future__ import annotations

import importlib.util
import shutil
import subprocess

import pytest

from boom_hydraulics.errors import ConfigError
from boom_hydraulics.ros import launch_arguments


def test_rviz_that_is_not_installed_is_refused_before_anything_starts():
    with pytest.raises(ConfigError, match=r"rviz:=true, but rviz2 is not installed; .*rviz:=false"):
        launch_arguments.plan({"rviz": "true"}, "x", state_publisher_installed=False, rviz_installed=False)
    assert launch_arguments.plan({"rviz": "true"}, "x", False, rviz_installed=True).rviz
    assert not launch_arguments.plan({"rviz": "false"}, "x", False, rviz_installed=False).rviz


def test_a_malformed_rviz_flag_is_refused():
    with pytest.raises(ConfigError, match=r"launch argument rviz:='maybe': expected true or false"):
        launch_arguments.plan({"rviz": "maybe"}, "x", False, rviz_installed=True)


@pytest.mark.parametrize(
    ("text", "says"),
    [(None, "no such file"), ("a_m: [0.4\n", "malformed YAML"), ("a_m: 0.4\n", "expected '/**: ros__parameters")],
    ids=["missing", "malformed", "not-a-params-file"],
)
def test_a_params_file_the_node_would_refuse_fails_the_launch(tmp_path, text, says):
    """launch_ros only warned about a missing params_file:= and the node ran on its defaults;
    ``ros2 run`` refuses the same file (exit 2): the launch refuses it before anything starts."""
    path = tmp_path / "params.yaml"
    if text is not None:
        path.write_text(text)
    with pytest.raises(ConfigError, match=r"launch argument params_file: ") as refused:
        launch_arguments.plan({"params_file": str(path)}, "x", False)
    assert str(path) in str(refused.value) and says in str(refused.value)
    shipped = launch_arguments.plan({"params_file": "config/default.yaml"}, "x", False)
    assert shipped.params_file == "config/default.yaml"


def _rviz2_installed() -> bool:
    from ament_index_python.packages import PackageNotFoundError, get_package_share_directory

    try:
        get_package_share_directory("rviz2")
    except PackageNotFoundError:
        return False
    return True


@pytest.mark.skipif(
    importlib.util.find_spec("launch_ros") is None or shutil.which("ros2") is None,
    reason="ros2 launch is not installed in this environment (no launch_ros or ros2 on PATH)",
)
def test_ros2_launch_with_rviz_missing_fails_and_starts_no_node():
    """As a user meets it: ``ros2 launch ... rviz:=true`` without rviz2 ends, and no boom_sim ran."""
    if _rviz2_installed():
        pytest.skip("rviz2 is installed here, so rviz:=true is no error")
    result = subprocess.run(
        ["ros2", "launch", "boom_hydraulics", "boom_sim.launch.py", "rviz:=true"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    output = result.stdout + result.stderr
    assert result.returncode != 0, output
    assert "rviz2 is not installed" in output, output
    assert "boom_sim-" not in output, output  # launch names each process it started: none was


@pytest.mark.skipif(
    importlib.util.find_spec("launch_ros") is None or shutil.which("ros2") is None,
    reason="ros2 launch is not installed in this environment (no launch_ros or ros2 on PATH)",
)
def test_ros2_launch_with_a_missing_params_file_fails_and_starts_no_node(tmp_path):
    """As a user meets it: ``ros2 launch ... params_file:=missing.yaml`` ends with the reason,
    and no boom_sim ran on its defaults."""
    missing = tmp_path / "missing.yaml"
    result = subprocess.run(
        ["ros2", "launch", "boom_hydraulics", "boom_sim.launch.py", f"params_file:={missing}"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    output = result.stdout + result.stderr
    assert result.returncode != 0, output
    assert f"params_file: {missing}: no such file" in output, output
    assert "boom_sim-" not in output, output
