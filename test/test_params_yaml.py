"""Params files as the ROS tools' Python side reads them: PyYAML (YAML 1.1) and rclpy's
``parameter_dict_from_yaml_file`` (``ros2 param load``, launch), beside rcl and our reader."""

from __future__ import annotations

import math

import pytest
import yaml
from conftest import CONFIG

from boom_hydraulics.errors import ConfigError
from boom_hydraulics.model import config
from boom_hydraulics.model.parameters import NAMES, Parameters, as_dict

rclpy_parameter = pytest.importorskip("rclpy.parameter")
from rclpy.parameter import Parameter, parameter_dict_from_yaml_file  # noqa: E402

from boom_hydraulics.ros import node_parameters  # noqa: E402

SHIPPED = sorted(p for p in CONFIG.glob("*.yaml") if p.name != "ros2_controllers.yaml")  # the controller manager's
TYPES = {
    "float": Parameter.Type.DOUBLE,
    "int": Parameter.Type.INTEGER,
    "bool": Parameter.Type.BOOL,
    "str": Parameter.Type.STRING,
    "list": Parameter.Type.DOUBLE_ARRAY,
}


def _as_rclpy_reads(path) -> dict[str, Parameter]:
    """What ``ros2 param load`` hands the node for ``path``, after the node's own typing."""
    messages = parameter_dict_from_yaml_file(str(path), use_wildcard=True)
    return {name: node_parameters.typed(Parameter.from_parameter_msg(msg)) for name, msg in messages.items()}


def _assert_same_parameters(read: dict[str, Parameter], expected: dict) -> None:
    assert set(read) == set(expected)
    for name, value in expected.items():
        p = read[name]
        assert p.type_ == TYPES[node_parameters._kind(name)], (name, p.type_, p.value)
        assert node_parameters.plain(p.value) == value, name


def test_shipped_files_are_found():
    assert {p.name for p in SHIPPED} >= {"default.yaml", "paper_fig8.yaml", "paper_fig9.yaml", "paper_fig10.yaml"}


@pytest.mark.parametrize("path", SHIPPED, ids=lambda p: p.name)
def test_yaml_1_1_reads_each_shipped_value_with_its_type(path):
    """PyYAML's safe_load (what launch and the ros2 tools use) types every value as rcl does."""
    plain = config.parameters_section(yaml.safe_load(path.read_text()), str(path))
    ros = config.read_values(path)
    assert {k: (type(v), v) for k, v in plain.items()} == {k: (type(v), v) for k, v in ros.items()}


@pytest.mark.parametrize("path", SHIPPED, ids=lambda p: p.name)
def test_rclpy_reads_each_shipped_file_back_with_types_and_values(path):
    _assert_same_parameters(_as_rclpy_reads(path), config.read_values(path))


def test_default_yaml_is_what_the_writer_writes():
    assert (CONFIG / "default.yaml").read_text() == config.default_file()


def test_the_writers_output_reads_back_alike_everywhere(tmp_path):
    """Values YAML 1.1 and rclpy's str() round trip get wrong when written naively."""
    values = {
        **as_dict(Parameters()),
        "rtol": 1e-6,
        "bulk_modulus_pa": 1.45e6,
        "supply_pressure_pa": 1e16,
        "command_times_s": [0.0, 3.0, 5.5],
        "command_values": [1e-05, 0.0, -1.0],
        "record_folder": "true",  # text that unquoted would read as a bool
    }
    path = tmp_path / "written.yaml"
    path.write_text(config.dumps(values))
    assert config.read_values(path) == values  # the CLI's reader and rcl's typing
    assert config.parameters_section(yaml.safe_load(path.read_text()), str(path)) == values
    # rclpy re-reads str(value), so text such as 'true' comes back a bool whatever the quoting: model only
    read = _as_rclpy_reads(path)
    _assert_same_parameters({k: v for k, v in read.items() if k in NAMES}, {k: values[k] for k in NAMES})


def test_a_mixed_integer_and_float_list_arrives_as_one_string_and_is_typed_back(tmp_path):
    path = tmp_path / "mixed.yaml"
    path.write_text("/**:\n  ros__parameters:\n    command_times_s: [0, 2.5]\n    payload_mass_kg: 80\n")
    raw = parameter_dict_from_yaml_file(str(path), use_wildcard=True)
    assert Parameter.from_parameter_msg(raw["command_times_s"]).type_ == Parameter.Type.STRING  # rclpy's doing
    _assert_same_parameters(_as_rclpy_reads(path), {"command_times_s": [0.0, 2.5], "payload_mass_kg": 80.0})


@pytest.mark.parametrize(
    ("name", "kind", "value"),
    [
        ("payload_mass_kg", Parameter.Type.STRING, "abc"),
        ("payload_mass_kg", Parameter.Type.STRING, "true"),
        ("mode", Parameter.Type.STRING, "1e-06"),
        ("command_values", Parameter.Type.STRING_ARRAY, ["a"]),
        ("command_values", Parameter.Type.STRING, "[0, abc]"),
    ],
)
def test_text_that_is_no_number_is_left_for_the_checks_to_refuse(name, kind, value):
    assert node_parameters.typed(Parameter(name, kind, value)).type_ == kind


def test_scalar_text_keeps_floats_floats_in_yaml_1_1():
    for value in (1e-6, 2e-16, 1e17, 16e6, 0.001, -3.5e-9, math.inf):
        text = config.scalar_text(value)
        assert isinstance(yaml.safe_load(text), float) and yaml.safe_load(text) == value, text
        assert config.load_yaml(text) == value


def _overrides(**values) -> dict[str, Parameter]:
    return {name: Parameter(name, value=value) for name, value in values.items()}


@pytest.mark.parametrize(
    ("argv", "kept"),
    [
        (["--ros-args", "-p", "payload_mass_kg:=50.0", "-p", "payload_mass_kg:=60.0"], 60.0),  # last wins
        (["--ros-args", "-p", "payload_mass_kg:=50.0", "-p", "payload_mass_kg:=60"], 60),  # the int wins, as meant
        (["--ros-args", "-p", "payload_mass_kg:=abc", "--", "-p", "payload_mass_kg:=xyz"], "abc"),  # not a ROS arg
        (["--ros-args", "-p", "other_node:payload_mass_kg:=abc"], 50.0),  # for another node
        (["--ros-args", "-p", "payload_mass_kg:=abc", "--params-file", str(CONFIG / "default.yaml")], 50.0),
    ],
)
def test_a_p_value_rcl_uses_or_one_overridden_later_passes(argv, kept):
    node_parameters.check_known(_overrides(payload_mass_kg=kept), argv=["boom_sim", *argv])


@pytest.mark.parametrize(
    "argv",
    [
        ["--ros-args", "-p", "payload_mass_kg:=50.0", "-p", "payload_mass_kg:=abc"],
        ["--ros-args", "--params-file", str(CONFIG / "default.yaml"), "-p", "payload_mass_kg:=abc"],
        ["--ros-args", "-p", "payload_mass_kg:=50.0", "--ros-args", "-p", "/boom_sim:payload_mass_kg:=abc"],
    ],
)
def test_a_p_value_rcl_does_not_use_is_refused(argv):
    with pytest.raises(ConfigError, match=r"-p payload_mass_kg:=abc would not be used: .*rcl keeps 50\.0"):
        node_parameters.check_known(_overrides(payload_mass_kg=50.0), argv=["boom_sim", *argv])


def test_the_node_declares_every_group_but_the_scenario():
    """...with the drives' parameters and the battery's, and none of those no solver reads yet
    (UNSOLVED): declared, they would promise what the node does not run."""
    from boom_hydraulics.model.parameters import UNSOLVED, names_in

    declared = node_parameters.all_names()
    assert set(node_parameters.SCENARIO) == set(names_in("scenario")) and not set(declared) & set(names_in("scenario"))
    assert not set(declared) & set(UNSOLVED)
    assert {"drive", "supply_line_volume_m3", "battery_capacity_kwh", "battery_initial_soc"} <= set(declared)
    assert set(declared) == set(NAMES) - set(names_in("scenario")) - set(UNSOLVED) | set(
        node_parameters.NODE_PARAMETERS
    )
    usage = node_parameters.usage()
    assert "command_" not in usage.split("Model parameters")[1].split("\n\n")[0]  # the list, not the note after it
    assert "payload_mass_kg" in usage and "ignores them" in usage


def test_a_params_file_may_set_the_scenario_but_not_a_name_that_is_no_parameter():
    node_parameters.check_known(_overrides(command_value=0.5, payload_mass_kg=60.0), argv=["boom_sim"])
    with pytest.raises(ConfigError, match=r"unknown parameter 'command_valu' .*did you mean 'command_value'"):
        node_parameters.check_known(["command_valu"], argv=["boom_sim"])


def test_the_node_names_the_scenario_values_it_ignores():
    assert node_parameters.ignored_scenario(as_dict(Parameters())) == ()  # default.yaml: nothing to say
    values = {"command_value": 0.5, "command_times_s": [0.0], "payload_mass_kg": 60.0}
    assert node_parameters.ignored_scenario(values) == ("command_value",)


def test_the_reference_table_lists_every_parameter_once_with_its_group_and_range():
    from boom_hydraulics.model.parameters import UNSOLVED, group_of

    rows = node_parameters.markdown_reference().splitlines()
    assert rows[0] == "| Name | Group | Type | Default | Unit | Range | Start only | Description |"
    cells = {row.split(" | ")[0].strip("| `"): row.split(" | ") for row in rows[2:]}
    listed = [name for name in NAMES if name not in UNSOLVED]  # the drives' join once the kernels run them
    assert len(rows) - 2 == len(cells) == len(listed) + len(node_parameters.NODE_PARAMETERS)
    for name in listed:
        assert cells[name][1] == group_of(name), name
    assert cells["payload_mass_kg"][2:6] == ["float", "`50.0`", "kg", "[0, 100000]"]
    assert cells["time_step_s"][5] == "(0, 0.1]" and cells["rtol"][3] == "`1.0e-06`"  # as a params file writes it
    assert cells["method"][5] == "one of: euler, rk4, rk45, ros2"
    assert cells["record_folder"][1:7] == ["node", "str", "`bags`", "", "", "yes"]
    assert [name for name in cells if cells[name][1] == "scenario"] == list(node_parameters.SCENARIO)  # last
    assert list(cells)[-len(node_parameters.SCENARIO) :] == list(node_parameters.SCENARIO)
